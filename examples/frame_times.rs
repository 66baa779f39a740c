//! In-process frame times of the packet path: renders a scene N times on one thread, or
//! on THREADS (the renderer built once, as the viewer does) and prints the best and median.
//! A steadier figure than whole-process timings on a shared machine, and what
//! `valgrind --tool=callgrind` runs to count instructions per frame (benches/README.md).
//!
//! `cargo run --release --example frame_times -- SCENE [RUNS=20] [SIZE=768] [THREADS=1]`

use octaray::render::RenderSettings;
use octaray::render::packet::PacketRenderer;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let Some(path) = args.get(1) else {
        eprintln!("usage: frame_times SCENE [RUNS] [SIZE] [THREADS]");
        std::process::exit(2);
    };
    let number = |i: usize, default: u32| {
        args.get(i).map_or(default, |s| {
            s.parse().unwrap_or_else(|_| {
                eprintln!("frame_times: not a number: {s}");
                std::process::exit(2)
            })
        })
    };
    let (runs, size) = (number(2, 20).max(1) as usize, number(3, 768).max(1));
    let threads = number(4, 1).max(1) as usize;
    let scene = match octaray::scene::parse::parse_scene_file(std::path::Path::new(path)) {
        Ok(parsed) => parsed.scene,
        Err(e) => {
            eprintln!("{e}");
            std::process::exit(2);
        }
    };
    let mut settings = RenderSettings::square(size);
    settings.threads = Some(threads);
    let renderer = PacketRenderer::new(&scene, settings.camera.eye);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .use_current_thread()
        .build()
        .expect("a pool on the current thread");
    let mut times: Vec<f64> = (0..runs)
        .map(|_| {
            let start = std::time::Instant::now();
            let frame = pool.install(|| renderer.render(&settings));
            std::hint::black_box(&frame.image);
            start.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    let first = times[0];
    times.sort_by(f64::total_cmp);
    println!(
        "{path} {size}x{size}, {threads} thread(s), {runs} frames: best {:.2} ms, median {:.2} ms, first {first:.2} ms",
        times[0],
        times[runs / 2]
    );
}
