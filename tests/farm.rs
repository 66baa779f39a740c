//! Rendering beyond one process, through the command line: tiles and crops assembled
//! into the one-process render byte for byte, camera paths rendered frame by frame as
//! `--eye --look-at --up --fov` renders them, `--skip-existing`, the viewer's
//! `--record`, and bad input refused with exit code 2 and nothing written.

use std::fs;
use std::path::Path;
use std::process::{Command, Output};

mod common;

use common::Scratch;
use octaray::output::Framebuffer;
use octaray::output::tile::read_meta;
use octaray::scene::camera_path::{PathCamera, read_camera_path};

const BIN: &str = env!("CARGO_BIN_EXE_octaray");

fn scene(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenes")
        .join(name)
        .display()
        .to_string()
}

fn dir(tag: &str) -> Scratch {
    Scratch::new(&format!("farm-{tag}"))
}

fn run(args: &[&str]) -> Output {
    Command::new(BIN)
        .args(args)
        .output()
        .expect("running octaray")
}

fn ok(args: &[&str]) {
    let out = run(args);
    assert!(
        out.status.success(),
        "octaray {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// Runs `args`, which must fail with exit code 2 and a message containing `says`.
fn refused(args: &[&str], says: &str) -> String {
    let out = run(args);
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(2), "octaray {args:?}: {err}");
    assert!(
        err.contains(says),
        "octaray {args:?}: expected '{says}' in: {err}"
    );
    assert!(!err.contains("panicked"), "{err}");
    err
}

fn p(path: &Path) -> &str {
    path.to_str().unwrap()
}

/// Renders `render_args` whole and as `n` tiles, assembles the tiles (in reverse order),
/// and checks the assembled PNG against the whole one byte for byte (the same pixels
/// and the same record of the settings), and the BMP too.
fn tiles_equal_the_whole(tag: &str, render_args: &[&str], n: u32) {
    let d = dir(tag);
    let whole = d.join("whole.png");
    let mut args = vec!["render"];
    args.extend_from_slice(render_args);
    ok(&[&args[..], &["-o", p(&whole)]].concat());
    let mut tiles = Vec::new();
    for i in (0..n).rev() {
        let tile = d.join(format!("tile_{i}.png"));
        let spec = format!("{i}/{n}");
        ok(&[&args[..], &["--tile", &spec, "-o", p(&tile)]].concat());
        let meta = read_meta(&tile).unwrap();
        assert_eq!(meta.tile, Some((i, n)));
        tiles.push(tile);
    }
    let assembled = d.join("assembled.png");
    let tile_args: Vec<&str> = tiles.iter().map(|t| p(t)).collect();
    ok(&[&["assemble"][..], &tile_args, &["-o", p(&assembled)]].concat());
    let (a, w) = (
        Framebuffer::load(&assembled).unwrap(),
        Framebuffer::load(&whole).unwrap(),
    );
    assert_eq!((a.width, a.height), (w.width, w.height), "{tag}");
    let off = a
        .pixels
        .iter()
        .zip(&w.pixels)
        .filter(|(x, y)| x != y)
        .count();
    assert_eq!(off, 0, "{tag}: {off} pixels differ");
    assert!(
        fs::read(&assembled).unwrap() == fs::read(&whole).unwrap(),
        "{tag}: the assembled PNG's bytes differ from the whole render's"
    );
    let bmp = d.join("assembled.bmp");
    ok(&[&["assemble"][..], &tile_args, &["-o", p(&bmp)]].concat());
    assert_eq!(Framebuffer::load(&bmp).unwrap(), w, "{tag}: BMP");
}

#[test]
fn given_scene_1024x576_in_4_tiles() {
    tiles_equal_the_whole("given4", &["--size", "1024x576"], 4);
}

#[test]
fn given_scene_512x288_supersampled_4x4_in_3_tiles() {
    let d = dir("ss16-profile");
    let profile = d.join("ss16.toml");
    fs::write(&profile, "samples_per_pixel = 16\n").unwrap();
    tiles_equal_the_whole("ss16", &["--size", "512x288", "--profile", p(&profile)], 3);
}

#[test]
fn prism_scene_384_in_3_tiles() {
    tiles_equal_the_whole("prism3", &[&scene("prism.txt"), "--size", "384"], 3);
}

/// 16 tiles of a 4K frame: the given scene at recursion level 1 with the fast profile
/// (cheap enough for the test profile; the tiling does not depend on the shading).
#[test]
fn a_4k_frame_in_16_tiles() {
    let d = dir("4k-scene");
    let text = octaray::scene::Scene::GIVEN.replacen('4', "1", 1);
    assert!(
        text.trim_start().starts_with('1'),
        "the first number is the level"
    );
    let file = d.join("given_level1.txt");
    fs::write(&file, text).unwrap();
    tiles_equal_the_whole("4k16", &[p(&file), "--size", "3840x2160"], 16);
}

/// The reference path, and `preview` (resolution_scale 0.5: a tile's stripes are cut
/// from one crop around them), with odd sizes and more tiles.
#[test]
fn tiles_hold_on_the_reference_and_reduced_resolution_profiles() {
    tiles_equal_the_whole(
        "reference",
        &["--size", "97x61", "--profile", "reference"],
        5,
    );
    tiles_equal_the_whole(
        "preview",
        &[
            &scene("mirrors.txt"),
            "--size",
            "203x117",
            "--profile",
            "preview",
        ],
        7,
    );
}

#[test]
fn crops_assemble_with_tiles_and_record_their_rectangles() {
    let d = dir("crops");
    let base = ["render", "--size", "120x80"];
    let whole = d.join("whole.png");
    ok(&[&base[..], &["-o", p(&whole)]].concat());
    let parts = ["0,120,0,30", "0,50,30,80", "50,120,30,80"];
    let mut files = Vec::new();
    for (k, crop) in parts.iter().enumerate() {
        let f = d.join(format!("c{k}.png"));
        ok(&[&base[..], &["--crop", crop, "-o", p(&f)]].concat());
        let meta = read_meta(&f).unwrap();
        assert_eq!(meta.rect_text(), *crop);
        assert_eq!((meta.frame, meta.tile), ((120, 80), None));
        files.push(f);
    }
    let out = d.join("out.png");
    let names: Vec<&str> = files.iter().map(|f| p(f)).collect();
    ok(&[&["assemble"][..], &names, &["-o", p(&out)]].concat());
    assert_eq!(fs::read(&out).unwrap(), fs::read(&whole).unwrap());
}

#[test]
fn bad_pieces_are_refused_and_nothing_is_written() {
    let d = dir("bad-pieces");
    let out = d.join("x.png");
    let o = p(&out);
    refused(&["render", "--tile", "4/4", "-o", o], "--tile");
    refused(&["render", "--tile", "0/0", "-o", o], "--tile");
    refused(&["render", "--tile", "1", "-o", o], "--tile");
    refused(
        &["render", "--size", "9x3", "--tile", "1/4", "-o", o],
        "--tile 1/4: 4 tiles",
    );
    refused(
        &["render", "--size", "64", "--crop", "0,65,0,10", "-o", o],
        "--crop: 0,65,0,10 lies outside the 64x64 frame",
    );
    refused(&["render", "--crop", "5,5,0,10", "-o", o], "--crop");
    refused(&["render", "--crop", "0,5,9,2", "-o", o], "--crop");
    refused(&["render", "--crop", "1,2,3", "-o", o], "--crop");
    refused(
        &["render", "--tile", "0/2", "--crop", "0,1,0,1", "-o", o],
        "--crop",
    );
    assert!(
        fs::read_dir(&d).unwrap().next().is_none(),
        "something was written"
    );
}

#[test]
fn assemble_refuses_missing_overlapping_and_foreign_tiles_by_name() {
    let d = dir("assemble-bad");
    let tile = |name: &str, i: u32, n: u32, extra: &[&str]| {
        let f = d.join(format!("{name}.png"));
        let spec = format!("{i}/{n}");
        let size = if extra.contains(&"--size") {
            &[][..]
        } else {
            &["--size", "64x40"][..]
        };
        ok(&[&["render", "--tile", &spec, "-o", p(&f)][..], size, extra].concat());
        f
    };
    let (t0, t1, t2) = (
        tile("t0", 0, 3, &[]),
        tile("t1", 1, 3, &[]),
        tile("t2", 2, 3, &[]),
    );
    let out = d.join("out.png");
    let o = p(&out);
    let e = refused(&["assemble", p(&t0), p(&t2), "-o", o], "missing: tile 1/3");
    assert!(e.contains("uncovered"), "{e}");
    let other = tile("half", 1, 2, &[]);
    let e = refused(
        &["assemble", p(&t0), p(&t1), p(&t2), p(&other), "-o", o],
        "overlaps",
    );
    assert!(e.contains(p(&other)), "{e}");
    refused(
        &["assemble", p(&t0), p(&t1), p(&t2), p(&t1), "-o", o],
        "given twice",
    );
    let moved = tile("moved", 1, 3, &["--eye", "100,100,51"]);
    let e = refused(
        &["assemble", p(&t0), p(&moved), p(&t2), "-o", o],
        "another scene or other settings",
    );
    assert!(
        e.contains(p(&moved)) && e.contains("camera: eye [100.0, 100.0, 51.0]"),
        "{e}"
    );
    let profile = tile("reference", 1, 3, &["--profile", "reference"]);
    let e = refused(
        &["assemble", p(&t0), p(&profile), p(&t2), "-o", o],
        "another scene or other settings",
    );
    assert!(e.contains("path Reference"), "{e}");
    let scene_tile = tile("mirrors", 1, 3, &[&scene("mirrors.txt")]);
    let e = refused(
        &["assemble", p(&t0), p(&scene_tile), p(&t2), "-o", o],
        "another scene",
    );
    assert!(e.contains("this piece: scene: fnv1a128:"), "{e}");
    let big = tile("taller", 1, 3, &["--size", "64x41"]);
    refused(
        &["assemble", p(&t0), p(&big), p(&t2), "-o", o],
        "a piece of a 64x41 frame",
    );
    let missing = d.join("missing.png");
    refused(
        &["assemble", p(&t0), p(&missing), "-o", o],
        "missing.png: cannot read",
    );
    let bmp = d.join("t.bmp");
    ok(&["render", "--size", "64x40", "--tile", "1/3", "-o", p(&bmp)]);
    refused(
        &["assemble", p(&t0), p(&bmp), p(&t2), "-o", o],
        "t.bmp: not a readable PNG file",
    );
    let plain = d.join("plain.png");
    fs::write(&plain, b"not an image").unwrap();
    refused(
        &["assemble", p(&plain), "-o", o],
        "plain.png: not a readable PNG file",
    );
    refused(
        &["assemble", p(&t0), p(&t1), p(&t2), "-o", p(&t1)],
        "is one of the tiles",
    );
    refused(
        &[
            "assemble",
            p(&t0),
            p(&t1),
            p(&t2),
            "-o",
            &format!("{o}.jpg"),
        ],
        "--output",
    );
    assert!(!out.exists(), "an output was written");
    // and the three tiles do make the frame
    ok(&["assemble", p(&t2), p(&t0), p(&t1), "-o", o]);
}

/// `x,y,z` as the command line takes it, exactly.
fn v3(v: glam::DVec3) -> String {
    format!("{:?},{:?},{:?}", v.x, v.y, v.z)
}

/// The bytes of `render_args` rendered with camera `c` of a path as
/// `--eye --look-at --up --fov` in one process, written to `out`.
fn one_process_render(render_args: &[&str], c: &PathCamera, out: &Path) -> Vec<u8> {
    let (eye, at, up, fov) = (
        v3(c.eye),
        v3(c.look_at),
        v3(c.up),
        format!("{:?}", c.fov_y_deg),
    );
    ok(&[
        render_args,
        &[
            "--eye",
            &eye,
            "--look-at",
            &at,
            "--up",
            &up,
            "--fov",
            &fov,
            "-o",
            p(out),
        ],
    ]
    .concat());
    fs::read(out).unwrap()
}

/// A frame of a camera path equals `render --eye --look-at --up --fov` of its line:
/// the same file, byte for byte (pixels and the record of the settings).
#[test]
fn camera_path_frames_equal_one_process_renders() {
    let d = dir("path");
    let path = d.join("path.txt");
    fs::write(
        &path,
        "// eye  look-at  up  fov\r\n\
         100 100 50  0 0 10  0 0 1  80\r\n\
         \r\n\
         -90.5 40 35.25  0 0 10  0 0.1 1  60 // a comment\r\n\
         0.1 -120 70  10 0 5  0 0 1  45\r\n",
    )
    .unwrap();
    let cameras = read_camera_path(&path).unwrap();
    assert_eq!(cameras.len(), 3);
    let frames = d.join("f_%04d.png");
    for scene_args in [vec![], vec![scene("prism.txt")]] {
        let mut args: Vec<&str> = vec!["render"];
        args.extend(scene_args.iter().map(String::as_str));
        args.extend(["--size", "96x54"]);
        ok(&[
            &args[..],
            &[
                "--camera-path",
                p(&path),
                "--frames",
                "0..2",
                "-o",
                p(&frames),
            ],
        ]
        .concat());
        for (k, c) in cameras.iter().enumerate() {
            let one = one_process_render(&args, c, &d.join(format!("one_{k}.png")));
            let frame = d.join(format!("f_{k:04}.png"));
            assert!(
                fs::read(&frame).unwrap() == one,
                "{scene_args:?}: frame {k} differs from the one-process render"
            );
        }
        // frames differ from each other (the cameras moved)
        assert_ne!(
            fs::read(d.join("f_0000.png")).unwrap(),
            fs::read(d.join("f_0001.png")).unwrap()
        );
    }
}

/// A camera path over a mesh of f32 vertices prepares the scene once for the frames
/// whose eyes keep the f32 frame at the world origin (`frame_origin`), and anew where
/// an eye moves it; every frame still equals its one-process render byte for byte.
#[test]
fn camera_path_frames_keep_one_preparation_while_the_frame_origin_stays() {
    let d = dir("kept");
    // a 40 × 40 grid of quads around the origin, coordinates exact in f32
    let mut obj = String::new();
    for i in 0..=40 {
        for j in 0..=40 {
            let z = 0.25 * ((i * j) % 3) as f64;
            obj += &format!(
                "v {} {} {z}\n",
                i as f64 * 0.5 - 10.0,
                j as f64 * 0.5 - 10.0
            );
        }
    }
    for i in 0..40 {
        for j in 0..40 {
            let a = i * 41 + j + 1;
            obj += &format!("f {a} {} {} {}\n", a + 41, a + 42, a + 1);
        }
    }
    fs::write(d.join("m.obj"), &obj).unwrap();
    let scene_file = d.join("s.txt");
    fs::write(
        &scene_file,
        "2 8 1 mesh m.obj  0.2 0.6 0.9  0.2 0.7 0.3 0.2  8  1 3 -4 6 1 1 1 0\n",
    )
    .unwrap();
    // frames 0 and 1 near the mesh keep the world origin; frame 2, low over its
    // corner, takes the f32 frame at its eye; frame 3 is back near the middle
    let path = d.join("path.txt");
    fs::write(
        &path,
        "0 -6 4  0 0 0  0 0 1  60\n\
         1 -6 4.5  0 0 0  0 0 1  60\n\
         9 9 0.75  0 0 0  0 0 1  60\n\
         -1 -6 4  0 0 0  0 0 1  60\n",
    )
    .unwrap();
    let frames = d.join("f_%d.bmp");
    let args = ["render", p(&scene_file), "--size", "64x48"];
    let out = run(&[&args[..], &["--camera-path", p(&path), "-o", p(&frames)]].concat());
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "{err}");
    let line = |k: usize| {
        err.lines()
            .find(|l| l.contains(&format!(": frame {k} (")))
            .unwrap_or_else(|| panic!("no summary of frame {k} in: {err}"))
            .to_string()
    };
    assert!(line(0).contains("(prepare "), "{}", line(0));
    assert!(line(1).contains("(prepared with frame 0,"), "{}", line(1));
    assert!(line(2).contains("(prepare "), "{}", line(2));
    assert!(line(3).contains("(prepare "), "{}", line(3));
    for (k, c) in read_camera_path(&path).unwrap().iter().enumerate() {
        let one = one_process_render(&args, c, &d.join(format!("one_{k}.bmp")));
        assert!(
            fs::read(d.join(format!("f_{k}.bmp"))).unwrap() == one,
            "frame {k} differs from the one-process render"
        );
    }
}

#[test]
fn skip_existing_leaves_finished_frames_alone() {
    let d = dir("skip");
    let path = d.join("path.txt");
    fs::write(
        &path,
        "100 100 50 0 0 10 0 0 1 80\n90 100 50 0 0 10 0 0 1 80\n80 100 50 0 0 10 0 0 1 80\n",
    )
    .unwrap();
    let pattern = d.join("f_%d.bmp");
    let mine = d.join("f_1.bmp");
    fs::write(&mine, b"finished").unwrap();
    let args = [
        "render",
        "--size",
        "32",
        "--camera-path",
        p(&path),
        "-o",
        p(&pattern),
    ];
    let out = run(&[&args[..], &["--skip-existing"]].concat());
    assert!(out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("f_1.bmp exists, left alone"));
    assert_eq!(fs::read(&mine).unwrap(), b"finished");
    assert!(
        Framebuffer::load(&d.join("f_0.bmp")).is_ok()
            && Framebuffer::load(&d.join("f_2.bmp")).is_ok()
    );
    // without it, frames are replaced
    ok(&[&args[..], &["--frames", "1"]].concat());
    assert!(Framebuffer::load(&mine).is_ok());
    // a single render resumes the same way
    let single = d.join("single.png");
    fs::write(&single, b"done").unwrap();
    ok(&[
        "render",
        "--size",
        "32",
        "--skip-existing",
        "-o",
        p(&single),
    ]);
    assert_eq!(fs::read(&single).unwrap(), b"done");
}

#[test]
fn bad_paths_ranges_and_patterns_are_refused_and_nothing_is_written() {
    let d = dir("bad-path");
    let path = d.join("path.txt");
    fs::write(
        &path,
        "100 100 50 0 0 10 0 0 1 80\n// two\n90 100 50 0 0 10 0 0 1 80\n",
    )
    .unwrap();
    let bad = d.join("bad.txt");
    fs::write(
        &bad,
        "100 100 50 0 0 10 0 0 1 80\r\n90 100 50 0 0 10 0 0 x 80\r\n",
    )
    .unwrap();
    let out = d.join("f_%03d.png");
    let (pa, o) = (p(&path), p(&out));
    refused(
        &["render", "--camera-path", pa, "--frames", "0..2", "-o", o],
        "--frames",
    );
    refused(
        &["render", "--camera-path", pa, "--frames", "3", "-o", o],
        "2 cameras, frames 0..1",
    );
    refused(
        &["render", "--camera-path", pa, "--frames", "1..0", "-o", o],
        "reversed",
    );
    refused(
        &["render", "--camera-path", pa, "--frames", "a..b", "-o", o],
        "--frames",
    );
    refused(
        &["render", "--camera-path", p(&bad), "-o", o],
        &format!(
            "{}:2:22: camera 2: up z: expected a number, found 'x'",
            p(&bad)
        ),
    );
    refused(
        &["render", "--camera-path", pa, "-o", p(&d.join("f.png"))],
        "has no frame number",
    );
    refused(
        &[
            "render",
            "--camera-path",
            pa,
            "-o",
            p(&d.join("f_%d_%d.png")),
        ],
        "more than one",
    );
    refused(&["render", "--camera-path", pa], "-o PATTERN");
    refused(
        &["render", "--camera-path", pa, "--eye", "1,2,3", "-o", o],
        "--eye",
    );
    refused(&["render", "--frames", "0..1", "-o", o], "--camera-path");
    refused(
        &["render", "--camera-path", p(&d.join("none.txt")), "-o", o],
        "none.txt:0:0: file: cannot read",
    );
    let empty = d.join("empty.txt");
    fs::write(&empty, "// nothing\n").unwrap();
    refused(
        &["render", "--camera-path", p(&empty), "-o", o],
        "no cameras",
    );
    refused(
        &[
            "render",
            "--camera-path",
            pa,
            "-o",
            p(&d.join("no/f_%d.png")),
        ],
        "--output",
    );
    let names: Vec<_> = fs::read_dir(&d)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names.len(), 3, "something was written: {names:?}");
}

/// `view --frames N --record PATH` records the scripted flight's cameras (appending);
/// a recorded line renders as `--eye --look-at --up --fov` of it.
#[test]
fn the_viewer_records_the_flight_it_draws() {
    let d = dir("record");
    let rec = d.join("flight.txt");
    let view = [
        "view",
        "--frames",
        "3",
        "--size",
        "24x16",
        "--record",
        p(&rec),
    ];
    ok(&view);
    let cameras = read_camera_path(&rec).unwrap();
    assert_eq!(cameras.len(), 3);
    for (k, c) in cameras.iter().enumerate() {
        let flight = octaray::viewer::flight_camera(k as u32);
        assert_eq!(c.eye, flight.eye, "frame {k}");
        assert!((c.camera().look - flight.look).length() < 1e-12);
        assert_eq!((c.up, c.fov_y_deg), (flight.up, flight.fov_y_deg));
    }
    ok(&view);
    assert_eq!(read_camera_path(&rec).unwrap().len(), 6, "appended");
    let text = fs::read_to_string(&rec).unwrap();
    assert_eq!(text.matches("// octaray camera path").count(), 1);
    let frame = d.join("f_%d.png");
    ok(&[
        "render",
        "--size",
        "40x30",
        "--camera-path",
        p(&rec),
        "--frames",
        "4",
        "-o",
        p(&frame),
    ]);
    let c = cameras[1];
    let one = d.join("one.png");
    let fov = format!("{:?}", c.fov_y_deg);
    ok(&[
        "render",
        "--size",
        "40x30",
        "--eye",
        &v3(c.eye),
        "--look-at",
        &v3(c.look_at),
        "--up",
        &v3(c.up),
        "--fov",
        &fov,
        "-o",
        p(&one),
    ]);
    assert!(fs::read(d.join("f_4.png")).unwrap() == fs::read(&one).unwrap());
    refused(&["view", "--frames", "1", "--record", p(&d)], "--record");
}
