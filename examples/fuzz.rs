//! The long fuzz run: the engine of `tests/fuzz.rs` (structure-aware mutations of scene,
//! OBJ and profile text through the parser and a tiny render) over many cases, in
//! worker processes so that a case that aborts or hangs is a finding, not the end of
//! the run.
//!
//! ```text
//! cargo run --release --example fuzz -- [--cases N] [--seed S] [--from I] [--jobs J]
//!                                       [--time-limit SECONDS] [--memory-limit MIB]
//!                                       [--out DIR]
//! ```
//!
//! Defaults: 1 000 000 cases from 0, seed 1, one worker per core, 10 s and 512 MiB per
//! case (a process may hold twice that before its allocations fail), findings under
//! `target/fuzz-findings/`. Each worker takes every J-th case, prints each case's
//! number as it begins and each finding; should it die (an abort, a failed allocation,
//! a case over its time: the watchdog ends it with exit code 3), the last case it began
//! is the finding and a new worker goes on after it. A finding is written out as
//! files `octaray render` runs (`scene.txt`, `m.obj`, `profile.toml`, `render.sh`,
//! `finding.txt`). The summary gives cases per second and the findings.

#[path = "../tests/fuzz/engine.rs"]
mod engine;

use std::io::{BufRead, BufReader, Write};
use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::sync::atomic::Ordering::Relaxed;
use std::time::{Duration, Instant};

struct Args {
    cases: u64,
    seed: u64,
    from: u64,
    jobs: u64,
    time_limit: u64,
    memory_mib: usize,
    out: PathBuf,
    /// A worker: (jobs, which).
    child: Option<(u64, u64)>,
}

fn args() -> Args {
    let mut a = Args {
        cases: 1_000_000,
        seed: 1,
        from: 0,
        jobs: std::thread::available_parallelism().map_or(1, |n| n.get() as u64),
        time_limit: 10,
        memory_mib: 512,
        out: PathBuf::from("target/fuzz-findings"),
        child: None,
    };
    let mut it = std::env::args().skip(1);
    let usage = |what: &str| -> ! {
        eprintln!(
            "fuzz: {what}\nusage: fuzz [--cases N] [--seed S] [--from I] [--jobs J] \
             [--time-limit SECONDS] [--memory-limit MIB] [--out DIR]"
        );
        std::process::exit(2)
    };
    while let Some(flag) = it.next() {
        let mut value = || {
            it.next()
                .unwrap_or_else(|| usage(&format!("{flag}: a value")))
        };
        let mut number = || {
            let v = value();
            v.parse::<u64>()
                .unwrap_or_else(|_| usage(&format!("{flag}: not a number: {v}")))
        };
        match flag.as_str() {
            "--cases" => a.cases = number(),
            "--seed" => a.seed = number(),
            "--from" => a.from = number(),
            "--jobs" => a.jobs = number().max(1),
            "--time-limit" => a.time_limit = number().max(1),
            "--memory-limit" => a.memory_mib = number().max(16) as usize,
            "--out" => a.out = PathBuf::from(value()),
            "--child" => {
                let jobs = number();
                a.child = Some((jobs, number()));
            }
            other => usage(&format!("unknown option {other}")),
        }
    }
    a
}

/// A worker: cases `from..from + cases` of its share, a line per case begun
/// (`c INDEX`) and per finding (`f INDEX MESSAGE`), `done RENDERED REFUSED PEAK` at
/// the end.
fn child(a: &Args, jobs: u64, which: u64) {
    let memory = a.memory_mib << 20;
    engine::MEMORY_LIMIT.store(2 * memory, Relaxed);
    engine::watch(Duration::from_secs(a.time_limit));
    let dir = std::env::temp_dir().join(format!("octaray-fuzz-{}", std::process::id()));
    let end = a.from + a.cases;
    let first = a.from + (which + jobs - a.from % jobs) % jobs;
    let out = std::io::stdout();
    let stats = engine::run_cases(
        a.seed,
        (first..end).step_by(jobs as usize),
        &dir,
        engine::Budget::default(),
        memory,
        |event| {
            let _ = match event {
                engine::Event::Begin(i) => writeln!(out.lock(), "c {i}"),
                engine::Event::Finding(i, f) => {
                    writeln!(out.lock(), "f {i} {}", f.replace('\n', " "))
                }
            };
        },
    );
    let _ = std::fs::remove_dir_all(&dir);
    let _ = writeln!(
        out.lock(),
        "done {} {} {}",
        stats.rendered,
        stats.refused,
        stats.peak
    );
}

/// What the workers of one share reported.
#[derive(Default)]
struct Share {
    /// Cases begun (those of a worker that died included).
    begun: u64,
    rendered: u64,
    refused: u64,
    peak: usize,
    findings: Vec<(u64, String)>,
}

/// Runs the workers of share `which` until its cases are done, restarting after a
/// case that ends its worker.
fn supervise(a: &Args, which: u64) -> Share {
    let exe = std::env::current_exe().expect("the fuzzer's own path");
    let mut share = Share::default();
    let mut from = a.from;
    let end = a.from + a.cases;
    while from < end {
        let mut child = Command::new(&exe)
            .args(["--child", &a.jobs.to_string(), &which.to_string()])
            .args(["--seed", &a.seed.to_string(), "--from", &from.to_string()])
            .args(["--cases", &(end - from).to_string()])
            .args(["--time-limit", &a.time_limit.to_string()])
            .args(["--memory-limit", &a.memory_mib.to_string()])
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("a worker starts");
        let stderr = child.stderr.take().expect("piped");
        let errors = std::thread::spawn(move || {
            // the last lines only: a worker's panics print here
            let mut tail: Vec<String> = Vec::new();
            for line in BufReader::new(stderr).lines().map_while(Result::ok) {
                tail.push(line);
                if tail.len() > 20 {
                    tail.remove(0);
                }
            }
            tail
        });
        let mut last = None;
        let mut done = false;
        let mut begun = 0;
        for line in BufReader::new(child.stdout.take().expect("piped"))
            .lines()
            .map_while(Result::ok)
        {
            let mut words = line.splitn(3, ' ');
            match (words.next(), words.next(), words.next()) {
                (Some("c"), Some(i), _) => {
                    last = i.parse::<u64>().ok();
                    begun += 1;
                }
                (Some("f"), Some(i), Some(f)) => {
                    share.findings.push((i.parse().unwrap_or(0), f.to_string()))
                }
                (Some("done"), Some(r), Some(rest)) => {
                    let mut rest = rest.split(' ');
                    share.rendered += r.parse::<u64>().unwrap_or(0);
                    share.refused += rest.next().and_then(|v| v.parse().ok()).unwrap_or(0);
                    let peak = rest.next().and_then(|v| v.parse().ok()).unwrap_or(0);
                    share.peak = share.peak.max(peak);
                    done = true;
                }
                _ => {}
            }
        }
        share.begun += begun;
        let status = child.wait().expect("the worker ends");
        let tail = errors.join().unwrap_or_default();
        if done && status.success() {
            break;
        }
        // the worker died on the case it began last
        let Some(i) = last else {
            share
                .findings
                .push((from, format!("worker failed before a case: {status}")));
            break;
        };
        share
            .findings
            .push((i, format!("worker ended ({status}): {}", tail.join(" | "))));
        from = i + 1;
    }
    share
}

fn main() {
    let a = args();
    if let Some((jobs, which)) = a.child {
        child(&a, jobs, which);
        return;
    }
    let start = Instant::now();
    eprintln!(
        "fuzz: cases {}..{} of seed {}, {} workers, {} s and {} MiB per case",
        a.from,
        a.from + a.cases,
        a.seed,
        a.jobs,
        a.time_limit,
        a.memory_mib
    );
    let shares: Vec<Share> = std::thread::scope(|s| {
        let handles: Vec<_> = (0..a.jobs)
            .map(|which| {
                let a = &a;
                s.spawn(move || supervise(a, which))
            })
            .collect();
        handles
            .into_iter()
            .map(|h| h.join().expect("a supervisor"))
            .collect()
    });
    let secs = start.elapsed().as_secs_f64();
    let begun: u64 = shares.iter().map(|s| s.begun).sum();
    let rendered: u64 = shares.iter().map(|s| s.rendered).sum();
    let refused: u64 = shares.iter().map(|s| s.refused).sum();
    let peak = shares.iter().map(|s| s.peak).max().unwrap_or(0);
    let mut findings: Vec<(u64, String)> = shares.into_iter().flat_map(|s| s.findings).collect();
    findings.sort();
    for (i, f) in &findings {
        let dir = a.out.join(format!("{}-{i}", a.seed));
        let saved = engine::save(&engine::case(a.seed, *i), &dir)
            .and_then(|()| std::fs::write(dir.join("finding.txt"), format!("{f}\n")));
        println!(
            "finding: case {i}: {f}{}",
            match saved {
                Ok(()) => format!(" ({})", dir.display()),
                Err(e) => format!(" (not saved: {e})"),
            }
        );
    }
    println!(
        "{begun} cases ({rendered} rendered, {refused} refused) in {secs:.1} s: {:.0} cases/s \
         on {} workers; largest case peak {:.1} MiB; {} findings",
        begun as f64 / secs,
        a.jobs,
        peak as f64 / f64::from(1 << 20),
        findings.len()
    );
    if !findings.is_empty() {
        std::process::exit(1);
    }
}
