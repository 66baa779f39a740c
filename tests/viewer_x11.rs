//! The viewer through a real X server: starts Xvfb, opens `octaray view` on it, types keys
//! with xdotool as a user would, and checks the captures on disk against `octaray render`.
//!
//! Needs the Debian packages `xvfb` and `xdotool` (.ci/run installs them); without them the
//! test prints why and passes without asserting anything.

use std::fs;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::thread::sleep;
use std::time::{Duration, Instant};

mod common;

use common::ChildGuard;
use octaray::output::Framebuffer;
use octaray::scene::{Camera, Scene};
use octaray::viewer::flycam::{self, Motion};

const BIN: &str = env!("CARGO_BIN_EXE_octaray");
/// The scene's resolution in this test (the given scene, made small to render quickly).
const PIXELS: u32 = 96;

fn on_path(tool: &str) -> bool {
    std::env::var_os("PATH")
        .is_some_and(|paths| std::env::split_paths(&paths).any(|dir| dir.join(tool).is_file()))
}

fn wait_for(what: &str, timeout: Duration, mut done: impl FnMut() -> bool) {
    let start = Instant::now();
    while !done() {
        assert!(start.elapsed() < timeout, "timed out waiting for {what}");
        sleep(Duration::from_millis(50));
    }
}

/// Starts Xvfb on a display number it picks itself (`-displayfd`, so concurrent runs never
/// share a server); returns the guard and the DISPLAY value once the server is ready.
fn start_xvfb() -> (ChildGuard, String) {
    let mut child = Command::new("Xvfb")
        .args([
            "-displayfd",
            "1",
            "-screen",
            "0",
            "640x480x24",
            "-nolisten",
            "tcp",
            // Without it the server resets when its last client leaves; a client that
            // connects during the reset (the viewer, right after an xdotool call) fails.
            "-noreset",
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("starting Xvfb");
    let stdout = child.stdout.take().expect("Xvfb's stdout");
    let guard = ChildGuard(child);
    let mut line = String::new();
    BufReader::new(stdout)
        .read_line(&mut line)
        .expect("reading Xvfb's display number");
    let n: u32 = line
        .trim()
        .parse()
        .unwrap_or_else(|_| panic!("Xvfb did not start (printed {line:?})"));
    (guard, format!(":{n}"))
}

/// Prints the viewer's stderr if the test fails.
struct LogOnPanic(PathBuf);

impl Drop for LogOnPanic {
    fn drop(&mut self) {
        if std::thread::panicking() {
            let log = fs::read_to_string(&self.0).unwrap_or_default();
            eprintln!("--- viewer stderr ---\n{log}---");
        }
    }
}

fn xdotool(display: &str, args: &[&str]) -> Output {
    Command::new("xdotool")
        .args(args)
        .env("DISPLAY", display)
        .output()
        .expect("running xdotool")
}

/// Presses and releases one key in the focused window. (minifb ignores synthetic events
/// sent with `key --window`, so the window must have the focus.)
fn key(display: &str, name: &str) {
    let out = xdotool(display, &["key", name]);
    assert!(out.status.success(), "xdotool key {name}: {out:?}");
}

fn render(scene: &Path, profile: &str, camera: &Camera, out: &Path) -> Framebuffer {
    let v = |p: glam::DVec3| format!("{:?},{:?},{:?}", p.x, p.y, p.z);
    let status = Command::new(BIN)
        .arg("render")
        .arg(scene)
        .args(["--profile", profile, "--eye", &v(camera.eye)])
        .arg("--output")
        .arg(out)
        .stderr(Stdio::null())
        .status()
        .expect("running octaray render");
    assert!(status.success());
    Framebuffer::load(out).expect("reading the rendered image")
}

fn load_when_present(path: &Path) -> Framebuffer {
    // Captures appear whole (temp file, then a hard link to the final name).
    wait_for(
        &path.display().to_string(),
        Duration::from_secs(300),
        || path.exists(),
    );
    Framebuffer::load(path).expect("reading the capture")
}

/// One session of the viewer with `profile`, capturing into `out`: 0, Up, 0, Esc (or 0,
/// Esc without `moves`). Each capture must equal `octaray render` with the same camera
/// and profile, byte for byte (both paths are deterministic), and the second must differ
/// from the first. `--record` writes the cameras of the frames drawn: the start, then
/// (with `moves`) the camera one step forward.
fn session(display: &str, scene: &Path, profile: &str, out: &Path, moves: bool) {
    let log = fs::File::create(out.join("viewer.log")).expect("a log file");
    let _log_on_panic = LogOnPanic(out.join("viewer.log"));
    let mut viewer = ChildGuard(
        Command::new(BIN)
            .arg("view")
            .arg(scene)
            .args(["--profile", profile, "--size", "200x150", "--out-dir"])
            .arg(out)
            .arg("--record")
            .arg(out.join("flight.txt"))
            .env("DISPLAY", display)
            .stdout(Stdio::null())
            .stderr(log)
            .spawn()
            .expect("starting octaray view"),
    );

    let mut window = String::new();
    wait_for("the viewer's window", Duration::from_secs(60), || {
        if let Ok(Some(status)) = viewer.0.try_wait() {
            panic!("the viewer exited with {status} before its window appeared");
        }
        let found = xdotool(display, &["search", "--name", "^octaray"]);
        window = String::from_utf8_lossy(&found.stdout)
            .lines()
            .next()
            .unwrap_or("")
            .to_string();
        !window.is_empty()
    });
    let focus = xdotool(display, &["windowfocus", "--sync", &window]);
    assert!(focus.status.success(), "xdotool windowfocus: {focus:?}");

    // The viewer starts from `octaray render`'s default camera, built the same way.
    let d = Camera::default();
    let start = Camera::from_look(d.eye, d.look, d.up, d.fov_y_deg).expect("default camera");

    // 0 captures the current view at the scene's size and the profile's quality.
    key(display, "0");
    let first = load_when_present(&out.join("Output_11.bmp"));
    assert_eq!((first.width, first.height), (PIXELS, PIXELS));
    let want = render(scene, profile, &start, &out.join("render_start.bmp"));
    assert!(
        first == want,
        "{profile}: capture differs from `octaray render` with the same camera and profile"
    );

    if !moves {
        key(display, "Escape");
        wait_for("the viewer to quit on Esc", Duration::from_secs(60), || {
            matches!(viewer.0.try_wait(), Ok(Some(_)))
        });
        assert!(!out.join("Output_12.bmp").exists());
        assert_eq!(recorded_eyes(out), [start.eye]);
        return;
    }

    // One tap of Up moves exactly one step forward; the next capture shows it.
    key(display, "Up");
    key(display, "0");
    let second = load_when_present(&out.join("Output_12.bmp"));
    assert_eq!((second.width, second.height), (PIXELS, PIXELS));
    assert!(
        second != first,
        "{profile}: moving forward did not change the picture"
    );
    let mut moved = start;
    flycam::apply(&mut moved, Motion::Forward, 1.0);
    let want = render(scene, profile, &moved, &out.join("render_moved.bmp"));
    assert!(
        second == want,
        "{profile}: capture after Up differs from `octaray render --eye {}`",
        moved.eye
    );

    // The title bar says where the capture went.
    let mut title = String::new();
    wait_for(
        "the title to name the capture",
        Duration::from_secs(30),
        || {
            let name = xdotool(display, &["getwindowname", &window]);
            title = String::from_utf8_lossy(&name.stdout).to_string();
            title.contains("Output_12.bmp")
        },
    );
    eprintln!("{profile}: window title: {title}");

    // Esc quits cleanly.
    key(display, "Escape");
    let start_exit = Instant::now();
    let status = loop {
        if let Some(status) = viewer.0.try_wait().expect("polling the viewer") {
            break status;
        }
        assert!(
            start_exit.elapsed() < Duration::from_secs(60),
            "the viewer did not quit on Esc"
        );
        sleep(Duration::from_millis(50));
    };
    assert!(status.success(), "viewer exited with {status}");
    // No other files were written by the viewer than the two captures.
    assert!(!out.join("Output_13.bmp").exists());
    assert_eq!(recorded_eyes(out), [start.eye, moved.eye]);
}

/// The eyes of the cameras `--record` wrote to `out/flight.txt`.
fn recorded_eyes(out: &Path) -> Vec<glam::DVec3> {
    let path = octaray::scene::camera_path::read_camera_path(&out.join("flight.txt"))
        .expect("the recorded camera path");
    path.iter().map(|c| c.eye).collect()
}

#[test]
fn keys_in_a_real_window_capture_and_move_the_view() {
    let missing: Vec<&str> = ["Xvfb", "xdotool"]
        .into_iter()
        .filter(|t| !on_path(t))
        .collect();
    if !missing.is_empty() {
        eprintln!(
            "skipped: {} not installed (apt-get install xvfb xdotool); nothing was checked",
            missing.join(" and ")
        );
        return;
    }

    let dir = std::env::temp_dir().join(format!("octaray-viewer-x11-{}", std::process::id()));
    let _ = fs::remove_dir_all(&dir);
    fs::create_dir_all(&dir).expect("a temporary directory");
    // The given scene at a small resolution: line 2 of the file is `pixels`.
    let mut lines: Vec<&str> = Scene::GIVEN.lines().collect();
    assert_eq!(
        lines[1].trim(),
        "768",
        "the given scene's second line is its size"
    );
    let pixels = PIXELS.to_string();
    lines[1] = &pixels;
    let scene = dir.join("scene.txt");
    fs::write(&scene, lines.join("\n")).expect("writing the scene");

    let (_xvfb, display) = start_xvfb();
    eprintln!("Xvfb on {display}");
    // The oracle, then the viewer's default path.
    for profile in ["reference", "fast"] {
        let out = dir.join(profile);
        fs::create_dir_all(&out).expect("an output directory");
        session(&display, &scene, profile, &out, true);
    }
    // Glass is drawn like everything else: the prism scene's first frame through the
    // packet path (its per-wavelength packets and photon map) equals `octaray render`.
    let prism = fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/prism.txt"))
        .expect("scenes/prism.txt");
    let mut data = 0;
    let small: Vec<String> = prism
        .lines()
        .map(|l| {
            let t = l.trim();
            if t.is_empty() || t.starts_with("//") {
                return l.to_string();
            }
            data += 1;
            // the second data line is the image size
            if data == 2 {
                pixels.clone()
            } else {
                l.to_string()
            }
        })
        .collect();
    let prism_scene = dir.join("prism.txt");
    fs::write(&prism_scene, small.join("\n")).expect("writing the prism scene");
    let out = dir.join("prism");
    fs::create_dir_all(&out).expect("an output directory");
    session(&display, &prism_scene, "fast", &out, false);
    let _ = fs::remove_dir_all(&dir);
}
