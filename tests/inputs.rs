//! Inputs of any size and content: memory bounded by what the scene uses, sizes
//! checked before reading, every quoted token escaped, messages without fake
//! positions, `-` for standard input.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

mod common;

use common::Scratch;
use octaray::scene::parse::{MAX_TOKEN, parse_scene, parse_scene_file, parse_scene_reader};

/// An empty directory of this test process, removed when dropped.
fn scratch_dir(tag: &str) -> Scratch {
    Scratch::new(&format!("in-{tag}"))
}

/// A valid five-token scene: level 1, 8 pixels, no objects, no lights of either kind.
const FIVE_TOKENS: &str = "1 8 0 0 0\n";

/// Runs octaray in `dir` under an address-space limit of `limit` bytes (`prlimit`,
/// util-linux), with `stdin` written to its standard input by a thread of its own
/// (write errors ignored: a process that stops reading closes the pipe).
#[cfg(target_os = "linux")]
fn run_limited(
    dir: &Path,
    limit: u64,
    args: &[&str],
    stdin: impl FnOnce(&mut dyn Write) + Send + 'static,
) -> Output {
    let mut child = Command::new("prlimit")
        .arg(format!("--as={limit}"))
        .arg(env!("CARGO_BIN_EXE_octaray"))
        .args(args)
        .current_dir(dir)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("prlimit (util-linux) runs");
    let mut pipe = child.stdin.take().unwrap();
    let writer = std::thread::spawn(move || stdin(&mut pipe));
    let out = child.wait_with_output().unwrap();
    writer.join().unwrap();
    out
}

/// `n` bytes of text that the format ignores, written in 1 MiB pieces.
fn ignored_tail(w: &mut dyn Write, n: usize) {
    let piece = "words the format ignores 12 34 56\n"
        .repeat(1 << 15)
        .into_bytes();
    let mut left = n;
    while left > 0 {
        let k = left.min(piece.len());
        if w.write_all(&piece[..k]).is_err() {
            return;
        }
        left -= k;
    }
}

/// The scene is read as a stream: a five-token scene followed by 300 MB of text that
/// the format ignores renders under a 1 GiB address-space limit. (The tokenizer held
/// every token, 16 bytes per byte of file: 300 MB tried to allocate 8 GiB and aborted.)
#[cfg(target_os = "linux")]
#[test]
fn the_ignored_rest_of_a_scene_costs_no_memory() {
    let dir = scratch_dir("tail");
    let out = run_limited(
        &dir,
        1 << 30,
        &["render", "-", "--threads", "1", "-o", "tail.bmp"],
        |w| {
            let _ = w.write_all(FIVE_TOKENS.as_bytes());
            ignored_tail(w, 300 << 20);
        },
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{stderr}");
    assert!(dir.join("tail.bmp").is_file());
}

/// The same through the library: a reader of 64 MiB after the scene is read to its
/// end (the size limit counts it) and none of it kept.
#[test]
fn a_stream_is_read_to_its_end() {
    struct Tail<'a> {
        head: &'a [u8],
        left: usize,
        read: &'a std::cell::Cell<usize>,
    }
    impl std::io::Read for Tail<'_> {
        fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
            if !self.head.is_empty() {
                let n = self.head.len().min(buf.len());
                buf[..n].copy_from_slice(&self.head[..n]);
                self.head = &self.head[n..];
                return Ok(n);
            }
            let n = self.left.min(buf.len());
            buf[..n].fill(b' ');
            self.left -= n;
            self.read.set(self.read.get() + n);
            Ok(n)
        }
    }
    let read = std::cell::Cell::new(0);
    let tail = Tail {
        head: FIVE_TOKENS.as_bytes(),
        left: 64 << 20,
        read: &read,
    };
    let p = parse_scene_reader(tail, "t.txt").unwrap();
    assert_eq!((p.scene.recursion_level, p.scene.pixels), (1, 8));
    assert_eq!(read.get(), 64 << 20);
}

/// `-` is standard input; messages call it `<stdin>`.
#[cfg(unix)]
#[test]
fn a_dash_reads_the_scene_from_standard_input() {
    let dir = scratch_dir("dash");
    let run = |text: &'static str| {
        let mut child = Command::new(env!("CARGO_BIN_EXE_octaray"))
            .args(["render", "-", "--size", "8", "-o", "dash.bmp"])
            .current_dir(&dir)
            .stdin(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let _ = child.stdin.take().unwrap().write_all(text.as_bytes());
        child.wait_with_output().unwrap()
    };
    let out = run(FIVE_TOKENS);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(dir.join("dash.bmp").is_file());
    let out = run("1 8 x");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("<stdin>:1:5: n_objects: expected an integer, found 'x'"),
        "{stderr}"
    );
}

/// A file that cannot be read has no position: `file: field: message`, not `file:0:0:`.
#[test]
fn an_unreadable_file_is_not_placed_at_0_0() {
    let e = parse_scene_file(Path::new("no/such/scene.txt")).unwrap_err();
    let shown = e.to_string();
    assert!(
        shown.starts_with("no/such/scene.txt: file: cannot read: "),
        "{shown}"
    );
    assert!(!shown.contains(":0:"), "{shown}");
    // and a mesh that cannot be read is named at its token, without a line 0
    let e = parse_scene("1 8 1 mesh none.obj 1 1 1 0 0 0 0 0 0 0", "dir/s.txt").unwrap_err();
    assert_eq!((e.line, e.col), (1, 12), "{e}");
    assert!(e.message.starts_with("dir/none.obj: cannot read: "), "{e}");
}

/// Every token quoted in a message is escaped: escape sequences cannot reach the
/// terminal, invisible characters show.
#[test]
fn quoted_tokens_are_escaped() {
    // a zero-width space and a byte-order mark inside numbers
    let e = parse_scene("2\n6\u{200b}4\n0 0 0", "t.txt").unwrap_err();
    assert_eq!(
        e.to_string(),
        "t.txt:2:1: pixels: expected an integer, found '6\\u{200b}4'"
    );
    let e = parse_scene("2 64 1 sphere 0 0 \u{feff}0.3", "t.txt").unwrap_err();
    assert!(e.message.ends_with("found '\\u{feff}0.3'"), "{}", e.message);
    // an object kind with a bidirectional override
    let e = parse_scene("2 64 1 \u{202e}erehps", "t.txt").unwrap_err();
    assert!(e.message.contains("'\\u{202e}erehps'"), "{}", e.message);
    // an escape sequence in the prose after the point lights: a note, escaped
    let p = parse_scene("1 8 0 0 \u{1b}[2Jcleared", "t.txt").unwrap();
    assert!(
        p.warnings
            .iter()
            .any(|w| w.contains("'\\u{1b}[2Jcleared' is not a spotlight count")),
        "{:?}",
        p.warnings
    );
    assert!(!p.warnings.iter().any(|w| w.contains('\u{1b}')));
}

/// A token longer than [`MAX_TOKEN`] is refused where it is read, and messages show
/// only its start.
#[test]
fn a_token_longer_than_the_limit_is_refused_and_cut_in_messages() {
    let long = "1".repeat(MAX_TOKEN + 1);
    let e = parse_scene(&format!("2 {long} 0 0 0"), "t.txt").unwrap_err();
    assert_eq!((e.line, e.col, e.field.as_str()), (1, 3, "pixels"), "{e}");
    assert!(
        e.message
            .contains("a token of 4097 bytes (more than the 4096 a token may have)"),
        "{e}"
    );
    assert!(e.message.len() < 300, "{e}");
    // at the limit it is an ordinary token
    let pad = format!("{}8", "0".repeat(MAX_TOKEN - 1));
    let p = parse_scene(&format!("1 {pad} 0 0 0"), "t.txt").unwrap();
    assert_eq!(p.scene.pixels, 8);
}

/// A reader that hands out at most `k` bytes per read.
struct Trickle<'a>(&'a [u8], usize);

impl std::io::Read for Trickle<'_> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.0.len().min(buf.len()).min(self.1);
        buf[..n].copy_from_slice(&self.0[..n]);
        self.0 = &self.0[n..];
        Ok(n)
    }
}

/// The stream is read in pieces: a character, a CRLF or a `//` split between two
/// reads reads as one, and results (scene, warnings, error and its position) do not
/// depend on how the bytes arrive.
#[test]
fn results_do_not_depend_on_how_the_stream_is_cut() {
    let texts: [&[u8]; 8] = [
        b"2\r\n64\r\n1 sphere 0 0 10 // c\xc3\xa9ntre\r\n5 1 0 0 0.4 0.2 0.2 0.2 10 0 0",
        b"\xef\xbb\xbf2 64 0 1 1 2 3 1 1 1\rprose \xe2\x80\x8b",
        b"2 64 1 sph\xc3\xa8re",
        b"2 64 1 sphere 0 0 \xe2\x80\x8b0.3",
        b"2\n6\xb04\n0 0 0",
        b"2\r64\r\x00",
        b"2 64 0 0 \xe2\x80",
        b"2//x\n64//y\r0/z",
    ];
    for text in texts {
        let whole = format!(
            "{:?}",
            parse_scene_reader(text, "t.txt").map(|p| (p.scene, p.warnings))
        );
        for k in 1..5 {
            let cut = format!(
                "{:?}",
                parse_scene_reader(Trickle(text, k), "t.txt").map(|p| (p.scene, p.warnings))
            );
            assert_eq!(
                cut,
                whole,
                "{} in pieces of {k}",
                String::from_utf8_lossy(text)
            );
        }
    }
}

/// Profile errors are plain: the key, the allowed values and what was found, at
/// file:line:column; never the TOML deserializer's words (`invalid type: integer
/// ... as i128, expected u32`, ``key `'photons'`: duplicate key``, ``unknown field ``,
/// expected one of ...``).
#[test]
fn profile_errors_name_the_key_and_the_allowed_values() {
    use octaray::render::profile::Profile;
    let error = |text: &str| match Profile::from_toml("p", text, "p.toml") {
        Ok(p) => panic!("accepted {text:?} as {p:?}"),
        Err(e) => e.to_string(),
    };
    let cases = [
        (
            "photons = 18446744073709551616",
            "p.toml:1:11: key `photons`: expected an integer from 0 to 10000000, found 18446744073709551616",
        ),
        (
            "photons = 1\n'photons' = 2",
            "p.toml:2:1: key `photons`: set twice",
        ),
        (
            "\"\" = 1",
            "p.toml:1:1: an empty key: unknown key; the keys are path, samples_per_pixel, sampler, threshold, \
             resolution_scale, max_recursion, photons, single_ray_lanes, triangle_test, \
             ray_offset, shadow_any_hit",
        ),
        (
            "path = \"fast\"",
            "p.toml:1:8: key `path`: expected \"reference\" or \"packet\", found \"fast\"",
        ),
        (
            "samples_per_pixel = 2.5",
            "p.toml:1:21: key `samples_per_pixel`: expected a square number of samples from 1 \
             to 64 (1, 4, 9, 16, 25, 36, 49 or 64), found 2.5",
        ),
        (
            "shadow_any_hit = 1",
            "p.toml:1:18: key `shadow_any_hit`: expected true or false, found 1",
        ),
        (
            "\n[fast]\nphotons = 1",
            "p.toml:2:2: key `fast`: unknown key; the keys are",
        ),
        (
            r#""\u001b[2J" = 1"#,
            "p.toml:1:1: key `\\u{1b}[2J`: unknown key",
        ),
    ];
    for (text, want) in cases {
        let e = error(text);
        assert!(e.starts_with(want), "{text:?}:\n{e}\nwant\n{want}");
        for internal in [
            "invalid type",
            "i128",
            "expected u32",
            "unknown field",
            "duplicate key",
        ] {
            assert!(!e.contains(internal), "{text:?}: {e}");
        }
    }
}

/// A mesh of 1 MiB or more is stored under `$XDG_CACHE_HOME/octaray/mesh` by the first
/// render and read from there by the next (the same image, the cache file left as it
/// was); with `OCTARAY_MESH_CACHE=off` nothing is stored.
#[cfg(unix)]
#[test]
fn large_meshes_are_cached_where_the_environment_says() {
    use std::os::unix::fs::MetadataExt;
    let dir = scratch_dir("meshcache");
    // a 120 × 120 grid of quads in the plane z = 0 under the default camera
    let mut obj = String::new();
    for i in 0..=120 {
        for j in 0..=120 {
            let (x, y) = (i as f64 * 0.5 - 30.0, j as f64 * 0.5 - 30.0);
            obj += &format!("v {x:.17} {y:.17} {:.17}\n", 0.001 * (i * j % 7) as f64);
        }
    }
    for i in 0..120 {
        for j in 0..120 {
            let a = i * 121 + j + 1;
            obj += &format!("f {a} {} {} {}\n", a + 121, a + 122, a + 1);
        }
    }
    assert!(obj.len() >= 1 << 20, "{}", obj.len());
    std::fs::write(dir.join("m.obj"), &obj).unwrap();
    std::fs::write(
        dir.join("s.txt"),
        "1 8 1 mesh m.obj  0.2 0.6 0.9  0.2 0.7 0 0  1  1 0 0 40 1 1 1 0\n",
    )
    .unwrap();
    let render = |out: &str, xdg: &str, off: bool| {
        let mut c = Command::new(env!("CARGO_BIN_EXE_octaray"));
        c.args([
            "render", "s.txt", "--size", "24", "--eye", "0,0,40", "-o", out,
        ])
        .current_dir(&dir)
        .env("XDG_CACHE_HOME", dir.join(xdg))
        .env_remove("OCTARAY_MESH_CACHE");
        if off {
            c.env("OCTARAY_MESH_CACHE", "off");
        }
        let o = c.output().unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        std::fs::read(dir.join(out)).unwrap()
    };
    let cached = |xdg: &str| -> Vec<PathBuf> {
        match std::fs::read_dir(dir.join(xdg).join("octaray").join("mesh")) {
            Ok(d) => d.map(|e| e.unwrap().path()).collect(),
            Err(_) => Vec::new(),
        }
    };
    let first = render("a.bmp", "xdg", false);
    let files = cached("xdg");
    assert_eq!(files.len(), 1, "{files:?}");
    let before = std::fs::metadata(&files[0]).unwrap();
    assert_eq!(render("b.bmp", "xdg", false), first);
    let after = std::fs::metadata(&files[0]).unwrap();
    // (a rewrite would be a new file, renamed into place)
    assert_eq!(
        (after.ino(), after.mtime_nsec()),
        (before.ino(), before.mtime_nsec())
    );
    assert_eq!(render("c.bmp", "xdg-off", true), first);
    assert!(!dir.join("xdg-off").exists());
    assert!(first.len() > 24 * 24 * 3);
}
