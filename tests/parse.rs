//! Scene-file parsing: every class of bad input is rejected with file:line:col and the
//! field, and the valid variants of the format load.

use std::path::PathBuf;
use std::process::Command;

mod common;

use common::{ChildGuard, Scratch};
use octaray::scene::parse::{ParseError, parse_scene, parse_scene_bytes, parse_scene_file};
use octaray::scene::{Scene, Shape};

/// A copy of the octaray binary in `dir` that any user may run (tests that run it as
/// another user: the build directory may not be open to others). Copied by `cp`, not
/// in this process: a write descriptor open here while another test thread forks a
/// child is inherited by that child until it execs, and running the copy then fails
/// with "Text file busy".
#[cfg(unix)]
fn exe_for_anyone(dir: &std::path::Path) -> PathBuf {
    use std::os::unix::fs::PermissionsExt;
    let exe = dir.join("octaray");
    let copied = Command::new("cp")
        .arg(env!("CARGO_BIN_EXE_octaray"))
        .arg(&exe)
        .status()
        .expect("cp runs");
    assert!(copied.success());
    std::fs::set_permissions(&exe, std::fs::Permissions::from_mode(0o755)).unwrap();
    exe
}

/// A small valid scene; tests corrupt one token of it at a time.
const BASE: &str = "\
2
64
2
sphere
0 0 10
5
1 0 0
0.4 0.2 0.2 0.2
10
general
1 1 1 0 0 0 0 0 0 -100
0 0 0 0 0 20
0 1 0
0.4 0.2 0.1 0.3
5
1
70 70 70
1 1 1
1
100 100 200
0 1 0
0 0 -1
12
";

fn err(text: &str) -> ParseError {
    match parse_scene(text, "t.txt") {
        Err(e) => e,
        Ok(p) => panic!("accepted bad input:\n{text}\n{:?}", p.scene),
    }
}

/// BASE with its 1-based line `line_no` replaced by `new`.
fn with_line(line_no: usize, new: &str) -> String {
    BASE.lines()
        .enumerate()
        .map(|(i, l)| if i + 1 == line_no { new } else { l })
        .collect::<Vec<_>>()
        .join("\n")
}

fn assert_err(text: &str, line: usize, col: usize, field: &str, msg_part: &str) {
    let e = err(text);
    assert_eq!((e.line, e.col), (line, col), "position of {e}");
    assert_eq!(e.field, field, "field of {e}");
    assert!(e.message.contains(msg_part), "message of {e}");
    assert!(
        e.to_string()
            .starts_with(&format!("t.txt:{line}:{col}: {field}: "))
    );
}

#[test]
fn base_scene_is_valid() {
    let p = parse_scene(BASE, "t.txt").unwrap();
    assert_eq!(p.scene.objects.len(), 2);
    assert_eq!(p.scene.spot_lights.len(), 1);
    assert!(p.warnings.is_empty(), "{:?}", p.warnings);
}

#[test]
fn nan_inf_and_overflow_are_rejected() {
    assert_err(&with_line(6, "nan"), 6, 1, "sphere 1: radius", "finite");
    assert_err(
        &with_line(5, "0 inf 10"),
        5,
        3,
        "sphere 1: center.y",
        "finite",
    );
    assert_err(
        &with_line(5, "0 0 1e400"),
        5,
        5,
        "sphere 1: center.z",
        "finite",
    );
    assert_err(
        &with_line(18, "-Infinity 1 1"),
        18,
        1,
        "point light 1: color.r",
        "finite",
    );
}

#[test]
fn word_where_a_number_belongs() {
    assert_err(
        &with_line(8, "0.4 0.2 abc 0.2"),
        8,
        9,
        "sphere 1: specular coefficient",
        "'abc'",
    );
}

#[test]
fn missing_number_is_caught_at_the_next_token() {
    // The sphere loses its shine; the next token is the keyword `general`.
    assert_err(&with_line(9, ""), 10, 1, "sphere 1: shine", "'general'");
}

#[test]
fn missing_number_at_end_of_file() {
    let text = BASE.trim_end().strip_suffix("12").unwrap();
    let e = err(text);
    assert_eq!(e.field, "spot light 1: cutoff angle");
    assert!(e.message.contains("end of file"), "{e}");
}

#[test]
fn extra_number_is_caught_where_a_keyword_belongs() {
    assert_err(&with_line(9, "10 7"), 9, 4, "object 2: kind", "'7'");
}

#[test]
fn unknown_object_kind() {
    assert_err(
        &with_line(4, "cube"),
        4,
        1,
        "object 1: kind",
        "unknown object kind 'cube'",
    );
}

#[test]
fn non_positive_radius() {
    assert_err(
        &with_line(6, "-5"),
        6,
        1,
        "sphere 1: radius",
        "must be > 0, got -5",
    );
    assert_err(&with_line(6, "0"), 6, 1, "sphere 1: radius", "must be > 0");
}

#[test]
fn negative_clip_dimension() {
    assert_err(
        &with_line(12, "0 0 0 0 -1 20"),
        12,
        9,
        "general 1: box width",
        ">= 0",
    );
}

#[test]
fn negative_colour_or_coefficient() {
    assert_err(&with_line(7, "1 -0.5 0"), 7, 3, "sphere 1: color.g", ">= 0");
    assert_err(
        &with_line(8, "0.4 -0.2 0.2 0.2"),
        8,
        5,
        "sphere 1: diffuse coefficient",
        ">= 0",
    );
}

#[test]
fn zero_spot_direction() {
    assert_err(
        &with_line(22, "0 0 0"),
        22,
        1,
        "spot light 1: direction",
        "non-zero",
    );
}

/// A spotlight direction only has to be finite and non-zero (spec §1): lengths whose
/// square overflows or underflows f64 are valid, and give the same unit direction.
#[test]
fn spot_directions_of_extreme_length() {
    let unit = |line: &str| {
        parse_scene(&with_line(22, line), "inline")
            .unwrap_or_else(|e| panic!("{line}: {e}"))
            .scene
            .spot_lights[0]
            .direction
    };
    for line in ["0 0 -1e200", "0 0 -1e-200", "0 0 -5e-324", "0 0 -1.7e308"] {
        assert_eq!(unit(line), glam::DVec3::NEG_Z, "{line}");
    }
    let d = unit("3e-310 0 -4e-310");
    assert!(
        (d - glam::DVec3::new(0.6, 0.0, -0.8)).length() < 1e-12,
        "{d}"
    );
}

#[test]
fn cutoff_outside_0_to_180() {
    assert_err(
        &with_line(23, "181"),
        23,
        1,
        "spot light 1: cutoff angle",
        "0..=180",
    );
    assert_err(
        &with_line(23, "-1"),
        23,
        1,
        "spot light 1: cutoff angle",
        "0..=180",
    );
    for ok in ["0", "90", "180"] {
        assert!(parse_scene(&with_line(23, ok), "t.txt").is_ok());
    }
}

#[test]
fn pixels_and_counts_must_be_integers_in_range() {
    assert_err(&with_line(2, "0"), 2, 1, "pixels", "1..=");
    assert_err(&with_line(2, "64.5"), 2, 1, "pixels", "integer");
    assert_err(
        &with_line(2, "99999999999999999999999"),
        2,
        1,
        "pixels",
        "integer",
    );
    assert_err(&with_line(1, "-1"), 1, 1, "recursion_level", "0..=");
    assert_err(&with_line(3, "two"), 3, 1, "n_objects", "'two'");
}

#[test]
fn pixels_above_the_render_limit_load_but_render_only_smaller() {
    // the format allows any pixels >= 1; octaray renders at most MAX_PIXELS per side
    let big = with_line(2, "20000");
    let p = parse_scene(&big, "t.txt").expect("a valid scene");
    assert_eq!(p.scene.pixels, 20000);
    let e = p
        .too_large
        .expect("flagged as too large to render at its own size");
    assert_eq!((e.line, e.col, e.field.as_str()), (2, 1, "pixels"));
    assert!(e.message.contains("--size"), "{e}");
    assert!(parse_scene(BASE, "t.txt").unwrap().too_large.is_none());
    let dir = Scratch::new("big");
    let file = dir.join("big.txt");
    std::fs::write(&file, &big).unwrap();
    let run = |extra: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_octaray"))
            .arg("render")
            .arg(&file)
            .args(extra)
            .arg("-o")
            .arg(dir.join("out.bmp"))
            .output()
            .unwrap()
    };
    let refused = run(&[]);
    assert_eq!(refused.status.code(), Some(2));
    let msg = String::from_utf8_lossy(&refused.stderr);
    assert!(msg.contains("big.txt:2:1: pixels: 20000"), "{msg}");
    assert!(!dir.join("out.bmp").exists(), "nothing written");
    let smaller = run(&["--size", "16"]);
    assert!(smaller.status.success(), "{smaller:?}");
    assert!(dir.join("out.bmp").exists());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn empty_and_whitespace_files() {
    for text in ["", "   \n\n  // only a comment\n"] {
        let e = err(text);
        assert_eq!(e.field, "recursion_level");
        assert!(e.message.contains("end of file"), "{e}");
    }
}

#[test]
fn binary_and_non_utf8_files() {
    let e = parse_scene_bytes(b"2\n64\n\x00\x01\x02", "b.bin").unwrap_err();
    assert_eq!((e.line, e.col), (3, 1));
    assert!(e.message.contains("not a text scene file"), "{e}");
    let e = parse_scene_bytes(b"2 \xff\xfe", "b.bin").unwrap_err();
    assert_eq!((e.line, e.col), (1, 3));
    assert!(e.message.contains("not a text scene file"), "{e}");
    // positions count lines as the tokenizer does (a lone CR ends one)
    let e = parse_scene_bytes(b"2\r64\r\x00", "b.bin").unwrap_err();
    assert_eq!((e.line, e.col), (3, 1));
    // a control byte before the first invalid UTF-8 sequence (an ELF header)
    let e = parse_scene_bytes(b"\x7fELF\x02\x01\x01\x00\xff\xfe", "b.bin").unwrap_err();
    assert_eq!((e.line, e.col), (1, 1));
    assert!(e.message.contains("not a text scene file"), "{e}");
}

#[test]
fn stray_bytes_in_comments_and_the_ignored_rest_are_ignored() {
    // a cp1252 degree sign in the trailing prose, in a comment; a NUL and Ctrl-Z after
    // the scene: the spec ignores all of these places
    let given = std::fs::read(scene_path("given.txt")).unwrap();
    let mut trailer = given.clone();
    trailer.extend_from_slice(b"\ncutoff angle (in \xb0)\n\x00\x1a");
    let p = parse_scene_bytes(&trailer, "t.txt").unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(p.scene.spot_lights.len(), 1);
    let mut comment = b"4 // level \xb0 four\n".to_vec();
    comment.extend_from_slice(&given[2..]);
    let q = parse_scene_bytes(&comment, "t.txt").unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(q.scene, p.scene);
    // one inside a number the scene needs is still an error at that token
    let e = parse_scene_bytes(b"2\n6\xb04\n0 0 0", "t.txt").unwrap_err();
    assert_eq!((e.line, e.col, e.field.as_str()), (2, 1, "pixels"), "{e}");
}

#[test]
fn byte_order_mark_and_old_mac_line_ends() {
    let bom = format!("\u{feff}{BASE}");
    assert_eq!(
        parse_scene(&bom, "t.txt").unwrap().scene,
        parse_scene(BASE, "t.txt").unwrap().scene
    );
    // CR alone ends a line: errors name the right line, comments end there
    let cr = with_line(6, "-5 // radius").replace('\n', "\r");
    let e = parse_scene(&cr, "t.txt").unwrap_err();
    assert_eq!(
        (e.line, e.col, e.field.as_str()),
        (6, 1, "sphere 1: radius"),
        "{e}"
    );
}

#[test]
fn prose_opening_with_a_number_word_is_not_a_spotlight_count() {
    let text = "1 4 0 1  70 70 70  1 1 1\nInfinity and beyond\n";
    let p = parse_scene(text, "t.txt").unwrap_or_else(|e| panic!("{e}"));
    assert!(p.scene.spot_lights.is_empty());
    assert!(
        p.warnings
            .iter()
            .any(|w| w.contains("'Infinity' is not a spotlight count"))
    );
    for word in ["NaN", "inf"] {
        assert!(
            parse_scene(&text.replace("Infinity", word), "t.txt").is_ok(),
            "{word}"
        );
    }
    // a number-shaped count out of range is still an error
    let e = err(&text.replace("Infinity", "1e400"));
    assert_eq!(e.field, "n_spot_lights");
}

#[test]
fn given_scene_loads_with_its_trailing_prose() {
    let text = std::fs::read_to_string(scene_path("given.txt")).unwrap();
    let p = parse_scene(&text, "given.txt").unwrap();
    let s = p.scene;
    assert_eq!((s.recursion_level, s.pixels), (4, 768));
    assert_eq!(s.objects.len(), 8);
    assert_eq!(s.point_lights.len(), 4);
    assert_eq!(s.spot_lights.len(), 1);
    assert_eq!(s.spot_lights[0].cutoff_deg, 12.0);
    assert_eq!(s, Scene::given());
}

#[test]
fn file_without_spotlight_block_notes_it() {
    let text = BASE.split("\n1\n100 100 200").next().unwrap();
    let p = parse_scene(text, "t.txt").unwrap();
    assert!(p.scene.spot_lights.is_empty());
    assert!(
        p.warnings.iter().any(|w| w.contains("no spotlights")),
        "{:?}",
        p.warnings
    );
    // A word after the point lights: no spotlights, the rest ignored.
    let text = format!("{text}\nInput explanation 5 6 7");
    let p = parse_scene(&text, "t.txt").unwrap();
    assert!(p.scene.spot_lights.is_empty());
    assert!(
        p.warnings.iter().any(|w| w.contains("'Input'")),
        "{:?}",
        p.warnings
    );
}

#[test]
fn comments_case_and_layout_do_not_matter() {
    let squashed = BASE.split_whitespace().collect::<Vec<_>>().join(" ");
    let commented = BASE
        .replace("sphere", "SpHeRe // a sphere, with a comment")
        .replace("general\n", "GENERAL// glued comment\n");
    let a = parse_scene(BASE, "a").unwrap().scene;
    assert_eq!(parse_scene(&squashed, "b").unwrap().scene, a);
    assert_eq!(parse_scene(&commented, "c").unwrap().scene, a);
}

#[test]
fn degenerate_primitives_load_with_a_warning() {
    let text = "1 8 2 triangle 0 0 0 1 1 1 2 2 2 1 0 0 0.4 0.2 0.2 0.2 5 \
                general 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 1 0 0 0.4 0.2 0.2 0.2 5 0 0";
    let p = parse_scene(text, "d.txt").unwrap();
    assert_eq!(p.scene.objects.len(), 2);
    assert!(
        p.warnings
            .iter()
            .any(|w| w.contains("triangle 1 has zero area"))
    );
    assert!(
        p.warnings
            .iter()
            .any(|w| w.contains("general 1 has all-zero"))
    );
}

#[test]
fn quadric_coefficients_are_normalised() {
    let text = BASE.replace("1 1 1 0 0 0 0 0 0 -100", "1e20 1e20 1e20 0 0 0 0 0 0 -1e22");
    let p = parse_scene(&text, "t.txt").unwrap();
    let Shape::Quadric(q) = &p.scene.objects[1].shape else {
        panic!("not a quadric")
    };
    assert_eq!(q.coef[9], -1.0);
    assert!((q.coef[0] - 0.01).abs() < 1e-15);
}

#[test]
fn prism_block_parses() {
    let text = "2 8 1 prism 0 0 0 1 0 0 0 1 0  0 0 1 1 0 1 0 1 1 \
                1 1 1 0.1 0.1 0.1 0.1 10 0.9 1.5046 0.0042 0 0";
    let p = parse_scene(text, "p.txt").unwrap();
    let Shape::Prism { glass, .. } = &p.scene.objects[0].shape else {
        panic!("not a prism")
    };
    assert_eq!(
        (glass.kt, glass.cauchy_a, glass.cauchy_b),
        (0.9, 1.5046, 0.0042)
    );
}

fn scene_path(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("scenes")
        .join(name)
}

#[test]
fn every_committed_scene_parses() {
    for entry in std::fs::read_dir(scene_path("")).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "txt") {
            let text = std::fs::read(&path).unwrap();
            parse_scene_bytes(&text, &path.display().to_string()).unwrap_or_else(|e| panic!("{e}"));
        }
    }
}

/// The binary: bad input exits 2 with file:line:col on stderr and writes nothing.
#[test]
fn cli_rejects_bad_scene_with_exit_2_and_no_output() {
    let dir = Scratch::new("cli-bad");
    let scene = dir.join("bad.txt");
    std::fs::write(&scene, with_line(6, "-5")).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_octaray"))
        .current_dir(&dir)
        .args(["render", "bad.txt", "--size", "8"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("bad.txt:6:1: sphere 1: radius: must be > 0, got -5"),
        "{stderr}"
    );
    assert!(!stderr.contains("panicked"), "{stderr}");
    let files: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(
        files,
        vec![std::ffi::OsString::from("bad.txt")],
        "no output written"
    );

    // A missing file is bad input too.
    let out = Command::new(env!("CARGO_BIN_EXE_octaray"))
        .current_dir(&dir)
        .args(["render", "nope.txt"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("nope.txt"));
}

/// Inputs that are not regular files are refused before they are opened (a FIFO
/// would block the open forever, /dev/zero fill gigabytes), and a bad
/// output is refused before the render, with exit code 2 and the option named.
#[cfg(unix)]
#[test]
fn special_files_and_bad_outputs_are_refused_up_front() {
    let dir = Scratch::new("special");
    let run = |args: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_octaray"))
            .current_dir(&dir)
            .args(args)
            .output()
            .unwrap()
    };
    for args in [
        &["render", "/dev/zero", "--size", "8"][..],
        &[
            "render",
            "--profile",
            "/dev/zero",
            "--size",
            "8",
            "-o",
            "x.bmp",
        ],
        &["render", ".", "--size", "8"],
        &["render", "--size", "8", "-o", "x.jpg"],
        &["render", "--size", "8", "-o", "no/such/dir/x.bmp"],
        &["render", "--size", "8", "-o", "."],
    ] {
        let out = run(args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(!stderr.contains("panicked"), "{args:?}: {stderr}");
    }
    assert!(
        String::from_utf8_lossy(&run(&["render", "--size", "8", "-o", "x.jpg"]).stderr)
            .contains("--output: x.jpg: unsupported image extension")
    );
    // nothing written, no temporary file left
    assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 0);
    // a pipe is a file to read: the scene from stdin
    let mut child = Command::new(env!("CARGO_BIN_EXE_octaray"))
        .current_dir(&dir)
        .args(["render", "/dev/stdin", "--size", "8", "-o", "piped.bmp"])
        .stdin(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let text = std::fs::read(scene_path("one_sphere.txt")).unwrap();
    std::io::Write::write_all(&mut child.stdin.take().unwrap(), &text).unwrap();
    let out = child.wait_with_output().unwrap();
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(dir.join("piped.bmp").is_file());
}

/// An OBJ file may start with a byte-order mark (it once swallowed the first `v`
/// line, shifting every index) and carry non-UTF-8 bytes in comments; a mesh with no
/// faces loads with a warning.
#[test]
fn obj_files_with_a_bom_or_stray_bytes_load_whole() {
    use octaray::scene::mesh_cache::load_obj;
    let dir = Scratch::new("objbom");
    let body = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
    let bom = dir.join("bom.obj");
    std::fs::write(&bom, [&b"\xef\xbb\xbf"[..], body].concat()).unwrap();
    let m = load_obj(&bom).unwrap();
    assert_eq!((m.vertices().len(), m.triangles().len()), (3, 1));
    assert_eq!(m.vertices()[0], glam::DVec3::ZERO);
    let stray = dir.join("stray.obj");
    std::fs::write(&stray, [&b"# caf\xe9 \xb0C\n"[..], body].concat()).unwrap();
    assert_eq!(load_obj(&stray).unwrap().triangles().len(), 1);
    std::fs::write(dir.join("empty.obj"), b"v 0 0 0\n").unwrap();
    let scene = dir.join("s.txt");
    std::fs::write(
        &scene,
        "1 8 1 mesh empty.obj  1 0 0  0.4 0.5 0 0  1  0  0\n",
    )
    .unwrap();
    let parsed = parse_scene_file(&scene).unwrap();
    assert!(
        parsed.warnings.iter().any(|w| w.contains("no triangles")),
        "{:?}",
        parsed.warnings
    );
}

/// Where worker threads cannot start (a process or container limit: `prlimit --nproc`,
/// as another user when root, whom the limit does not bind), `render` without
/// `--threads` renders on its one thread, with a warning, and writes the same image;
/// so does `--threads 1`, without one; with `--threads 2` it stops with exit 1 and
/// says why.
#[cfg(target_os = "linux")]
#[test]
fn a_limit_on_threads_renders_on_one_thread() {
    use std::os::unix::fs::PermissionsExt;
    let dir = Scratch::new("nproc");
    std::fs::set_permissions(&dir, std::fs::Permissions::from_mode(0o777)).unwrap();
    let exe = exe_for_anyone(&dir);
    let free = Command::new(&exe)
        .args(["render", "--size", "16", "-o"])
        .arg(dir.join("free.bmp"))
        .output()
        .unwrap();
    assert!(free.status.success(), "{free:?}");
    let root = Command::new("id").arg("-u").output().unwrap().stdout == b"0\n";
    let limited = |threads: &[&str], out: &str| {
        let mut c = Command::new("prlimit");
        c.arg("--nproc=1");
        // (a uid of its own: the limit counts every process of the user, and the
        // sticky-directory test below runs octaray as `nobody` at the same time, which
        // made this exec fail with EAGAIN in one CI run; one per test process, so that
        // two test runs on one machine do not share it either)
        if root {
            let uid = 60000 + std::process::id() % 5000;
            c.arg("setpriv")
                .arg(format!("--reuid={uid}"))
                .arg(format!("--regid={uid}"))
                .arg("--clear-groups");
        }
        c.arg(&exe)
            .args(["render", "--size", "16"])
            .args(threads)
            .arg("-o")
            .arg(dir.join(out))
            .output()
            .expect("prlimit (util-linux) runs")
    };
    let out = limited(&[], "limited.bmp");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{stderr}");
    assert!(stderr.contains("ran on one thread"), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert_eq!(
        std::fs::read(dir.join("limited.bmp")).unwrap(),
        std::fs::read(dir.join("free.bmp")).unwrap()
    );
    // one thread needs no worker: the calling thread is enough
    let out = limited(&["--threads", "1"], "one.bmp");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{stderr}");
    assert!(!stderr.contains("warning"), "{stderr}");
    assert_eq!(
        std::fs::read(dir.join("one.bmp")).unwrap(),
        std::fs::read(dir.join("free.bmp")).unwrap()
    );
    let out = limited(&["--threads", "2"], "two.bmp");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("cannot start 2 worker threads"), "{stderr}");
    assert!(!stderr.contains("ran on one thread"), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
}

/// `-o` onto a file that may be written but not replaced (another user's file in a
/// sticky directory; a bind-mounted file behaves alike): the image is written in place
/// and the file stays its owner's. Needs two
/// users, so runs as root (CI), the render as `nobody`.
#[cfg(target_os = "linux")]
#[test]
fn files_that_cannot_be_replaced_are_written_in_place() {
    use std::os::unix::fs::{MetadataExt, PermissionsExt};
    if Command::new("id").arg("-u").output().unwrap().stdout != b"0\n" {
        return;
    }
    let dir = Scratch::new("sticky");
    std::fs::set_permissions(&dir, std::fs::Permissions::from_mode(0o1777)).unwrap();
    let exe = exe_for_anyone(&dir);
    let free = dir.join("free.bmp");
    let out = Command::new(&exe)
        .args(["render", "--size", "16", "-o"])
        .arg(&free)
        .output()
        .unwrap();
    assert!(out.status.success(), "{out:?}");
    let target = dir.join("shared.bmp");
    std::fs::write(&target, b"old").unwrap();
    std::fs::set_permissions(&target, std::fs::Permissions::from_mode(0o666)).unwrap();
    let out = Command::new("setpriv")
        .args(["--reuid=65534", "--regid=65534", "--clear-groups"])
        .arg(&exe)
        .args(["render", "--size", "16", "-o"])
        .arg(&target)
        .output()
        .expect("setpriv (util-linux) runs");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{stderr}");
    assert_eq!(
        std::fs::read(&target).unwrap(),
        std::fs::read(&free).unwrap()
    );
    assert_eq!(std::fs::metadata(&target).unwrap().uid(), 0);
    let leftovers = std::fs::read_dir(&dir)
        .unwrap()
        .filter(|e| {
            e.as_ref()
                .unwrap()
                .file_name()
                .to_string_lossy()
                .starts_with('.')
        })
        .count();
    assert_eq!(leftovers, 0);
}

/// The bits of a signal mask (`SigCgt`: caught, `SigIgn`: ignored) of a running process.
#[cfg(target_os = "linux")]
fn signal_mask(pid: u32, field: &str) -> u64 {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap_or_default();
    status
        .lines()
        .find_map(|l| l.strip_prefix(field))
        .and_then(|v| u64::from_str_radix(v.trim(), 16).ok())
        .unwrap_or(0)
}

/// Waits (up to 20 s) until process `pid` catches `signal`: its handler is installed.
#[cfg(target_os = "linux")]
fn wait_until_caught(pid: u32, signal: u32) {
    let start = std::time::Instant::now();
    while signal_mask(pid, "SigCgt:") & (1 << (signal - 1)) == 0 {
        assert!(
            start.elapsed().as_secs() < 20,
            "pid {pid} never caught {signal}"
        );
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
}

/// A command that runs `program` with SIGINT, SIGTERM and SIGHUP at their default
/// action. A process inherits the signals its parent ignores, and a non-interactive
/// shell starts its background jobs (`cmd &`, as CI runners may start the test run)
/// with SIGINT ignored, which octaray rightly keeps ignored. GNU `env` resets them and
/// execs `program` in the same process.
#[cfg(target_os = "linux")]
fn with_default_signals(program: impl AsRef<std::ffi::OsStr>) -> Command {
    let mut command = Command::new("env");
    command.arg("--default-signal=INT,TERM,HUP").arg(program);
    command
}

/// An interrupted render (SIGINT, SIGTERM, SIGHUP) removes its temporary files and ends
/// by the same signal, as if it had not been caught (a shell shows 130, 143, 129: the
/// `ctrlc` handler used to exit 130 for all three); a signal the process was started
/// ignoring (`nohup`) stays ignored (the old handler caught SIGHUP regardless).
#[cfg(target_os = "linux")]
#[test]
fn interrupted_renders_end_by_their_signal_and_ignored_ones_stay_ignored() {
    use std::os::unix::process::ExitStatusExt;
    use std::process::Stdio;
    let dir = Scratch::new("signals");
    let exe = env!("CARGO_BIN_EXE_octaray");
    // (a render of seconds, ended within milliseconds of its start)
    let slow = [
        "render",
        "--profile",
        "reference",
        "--size",
        "3000",
        "--threads",
        "1",
    ];
    for (name, signal) in [("INT", 2), ("TERM", 15), ("HUP", 1)] {
        // (stopped when the test fails before it ends)
        let mut child = ChildGuard(
            with_default_signals(exe)
                .args(slow)
                .arg("-o")
                .arg(dir.join("x.bmp"))
                .stderr(Stdio::null())
                .spawn()
                .unwrap(),
        );
        wait_until_caught(child.0.id(), signal);
        let sent = Command::new("kill")
            .arg(format!("-{name}"))
            .arg(child.0.id().to_string())
            .status()
            .unwrap();
        assert!(sent.success());
        let status = child.0.wait().unwrap();
        assert_eq!(
            status.signal(),
            Some(signal as i32),
            "SIG{name}: {status:?}"
        );
        let left: Vec<_> = std::fs::read_dir(&dir).unwrap().collect();
        assert!(left.is_empty(), "SIG{name} left {left:?}");
    }
    // started by nohup: SIGHUP is ignored, the render goes on and writes its image
    let kept = dir.join("kept.bmp");
    let mut child = with_default_signals("nohup")
        .arg(exe)
        .args([
            "render",
            "--profile",
            "reference",
            "--size",
            "600",
            "--threads",
            "1",
        ])
        .arg("-o")
        .arg(&kept)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("nohup (coreutils) runs");
    // env execs nohup, which execs octaray: once SIGTERM is caught, octaray's start-up
    // is done
    wait_until_caught(child.id(), 15);
    assert_ne!(
        signal_mask(child.id(), "SigIgn:") & 1,
        0,
        "nohup ignores SIGHUP"
    );
    assert_eq!(
        signal_mask(child.id(), "SigCgt:") & 1,
        0,
        "SIGHUP is not caught"
    );
    let sent = Command::new("kill")
        .args(["-HUP", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(sent.success());
    let status = child.wait().unwrap();
    assert!(status.success(), "{status:?}");
    assert!(kept.is_file());
}
