//! Whole-image tests of the reference path.
//!
//! 1. Analytic pixels: camera, floor, Phong terms and spot cones checked against values
//!    computed here by hand, independently of the renderer's code.
//! 2. Golden images: every scene in `scenes/` rendered small and compared with the
//!    committed PNG in `tests/golden/`. Tolerance: at most 0.05 % of pixels may differ,
//!    and by at most 1/255 except at those pixels (libm's pow/atan2 may round
//!    differently on another platform, which can flip a hard shadow or cone edge).
//!    Regenerate with `OCTARAY_BLESS=1 cargo test --test golden` after an intended
//!    change, and look at the images before committing them.
//! 3. The default command renders the built-in scene headless and never overwrites.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use glam::DVec3;
use octaray::output::{Framebuffer, write_image};
use octaray::render::{RenderSettings, reference};
use octaray::scene::parse::{parse_scene, parse_scene_file};
use octaray::scene::{Camera, Scene};

fn render(scene: &Scene, size: u32) -> Framebuffer {
    let mut settings = RenderSettings::for_scene(scene);
    settings.width = size;
    settings.height = size;
    reference::render(scene, &settings).image
}

fn scene(text: &str) -> Scene {
    parse_scene(text, "inline").unwrap().scene
}

#[test]
fn floor_without_lights_shows_ambient_checkerboard() {
    // Computed here: ray through each pixel, where it meets z = 0, which tile.
    let s = scene("1 33 0 0 0");
    let fb = render(&s, 33);
    let cam = Camera::default();
    let d = 250.0 / 40f64.to_radians().tan();
    let mut checked = 0;
    for j in 0..33 {
        for i in 0..33 {
            let px = cam.eye + cam.look * d - cam.right * 250.0
                + cam.up * 250.0
                + cam.right * (500.0 / 33.0) * (i as f64 + 0.5)
                - cam.up * (500.0 / 33.0) * (j as f64 + 0.5);
            let dir = (px - cam.eye).normalize();
            let expect = if dir.z < 0.0 {
                let t = -cam.eye.z / dir.z;
                let p = cam.eye + dir * t;
                if p.x.abs() <= 500.0 && p.y.abs() <= 500.0 {
                    let tile = ((p.x + 500.0) / 20.0).floor() + ((p.y + 500.0) / 20.0).floor();
                    if tile.rem_euclid(2.0) == 0.0 { 102 } else { 0 }
                } else {
                    0
                }
            } else {
                0
            };
            assert_eq!(fb.get(i, j), [expect; 3], "pixel ({i}, {j})");
            checked += (expect == 102) as u32;
        }
    }
    assert!(
        checked > 50,
        "the floor is visible ({checked} white pixels)"
    );
}

/// A sphere straight ahead of the default camera, lit from the eye: at the centre pixel
/// N = L = V, so N·L = 1 and R·V = 1 and the colour is c·(ka + kd + ks).
#[test]
fn phong_terms_at_the_centre_pixel() {
    let centre = DVec3::new(100.0, 100.0, 50.0) + Camera::default().look * 100.0;
    let text = format!(
        "1 65 1 sphere {} {} {} 20  1 0.5 0.25  0.2 0.5 0.3 0.5  7  1  100 100 50  1 1 1  0",
        centre.x, centre.y, centre.z
    );
    let fb = render(&scene(&text), 65);
    // 255 · (1, 0.5, 0.25) · (0.2 + 0.5 + 0.3) = (255, 127.5, 63.75)
    assert_eq!(fb.get(32, 32), [255, 128, 64]);
    // Without the light only ambient remains: 255 · 0.2 · c = (51, 25.5, 12.75).
    let dark = text.replace("  1  100 100 50  1 1 1  0", "  0  0");
    assert_eq!(render(&scene(&dark), 65).get(32, 32), [51, 26, 13]);
    // A spotlight at the eye aimed away from the sphere contributes nothing; aimed at
    // it, it equals the point light.
    let spot = |dir: &str| {
        text.replace(
            "  1  100 100 50  1 1 1  0",
            &format!("  0  1 100 100 50  1 1 1  {dir}  5"),
        )
    };
    assert_eq!(render(&scene(&spot("1 1 0")), 65).get(32, 32), [51, 26, 13]);
    assert_eq!(
        render(&scene(&spot("-1 -1 0")), 65).get(32, 32),
        [255, 128, 64]
    );
}

/// Level 1 shows no reflections; level 2 adds kr times the reflected colour.
#[test]
fn recursion_level_counts_bounces() {
    let base = "1 48 1 sphere 0 0 20 20  0.2 0.2 1  0.3 0.5 0.3 0.8 20  1  60 -20 100  1 1 1  0";
    let one = render(&scene(base), 48);
    let two = render(&scene(&base.replacen('1', "2", 1)), 48);
    let zero = render(&scene(&base.replacen('1', "0", 1)), 48);
    assert_eq!(zero, one, "levels 0 and 1 both mean no reflection");
    let brighter = one
        .pixels
        .iter()
        .zip(&two.pixels)
        .filter(|(a, b)| a.iter().zip(b.iter()).any(|(x, y)| y > x))
        .count();
    let darker = one
        .pixels
        .iter()
        .zip(&two.pixels)
        .filter(|(a, b)| a.iter().zip(b.iter()).any(|(x, y)| y < x))
        .count();
    assert!(brighter > 20, "reflections add light ({brighter} pixels)");
    assert_eq!(darker, 0, "reflection only adds (kr >= 0, colours >= 0)");
}

/// Golden size per scene: small enough for a quick test, large enough to show detail.
const GOLDEN_SIZE: u32 = 96;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn compare(actual: &Framebuffer, golden: &Framebuffer) -> Result<(), String> {
    if (actual.width, actual.height) != (golden.width, golden.height) {
        return Err("size differs".into());
    }
    let mut off = 0usize;
    let mut worst = 0u8;
    for (a, g) in actual.pixels.iter().zip(&golden.pixels) {
        let d = a.iter().zip(g).map(|(x, y)| x.abs_diff(*y)).max().unwrap();
        if d > 0 {
            off += 1;
        }
        if d > 1 {
            worst = worst.max(d);
        }
    }
    let limit = actual.pixels.len() / 2000;
    if off > limit {
        return Err(format!(
            "{off} pixels differ (limit {limit}); worst {worst}/255"
        ));
    }
    Ok(())
}

#[test]
fn golden_images_of_every_scene() {
    let bless = std::env::var_os("OCTARAY_BLESS").is_some();
    let mut names = Vec::new();
    for entry in std::fs::read_dir(root().join("scenes")).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "txt") {
            names.push(path);
        }
    }
    names.sort();
    assert!(names.len() >= 10, "scenes/ holds the feature scenes");
    let mut failures = Vec::new();
    for path in &names {
        let s = parse_scene_file(path).unwrap().scene;
        let fb = render(&s, GOLDEN_SIZE);
        let stem = path.file_stem().unwrap().to_string_lossy();
        let golden = root().join("tests/golden").join(format!("{stem}.png"));
        if bless {
            write_image(&fb, &golden).unwrap();
            continue;
        }
        match Framebuffer::load(&golden) {
            Ok(g) => {
                if let Err(e) = compare(&fb, &g) {
                    let dump = std::env::temp_dir().join(format!("octaray-golden-{stem}.png"));
                    write_image(&fb, &dump).unwrap();
                    failures.push(format!("{stem}: {e} (actual image: {})", dump.display()));
                }
            }
            Err(e) => failures.push(format!("{stem}: no golden image {}: {e}", golden.display())),
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn golden_comparison_detects_a_change() {
    let s = parse_scene_file(&root().join("scenes/one_sphere.txt"))
        .unwrap()
        .scene;
    let fb = render(&s, GOLDEN_SIZE);
    let mut changed = fb.clone();
    for p in changed.pixels.iter_mut().take(50) {
        p[0] ^= 0x40;
    }
    assert!(compare(&fb, &fb).is_ok());
    assert!(compare(&changed, &fb).is_err());
}

fn run_default(dir: &Path) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_octaray"))
        .current_dir(dir)
        .output()
        .unwrap()
}

/// `octaray` with no arguments renders the built-in given scene to Output_11.bmp, then
/// Output_12.bmp, never touching an existing file, with no window.
#[test]
fn default_command_renders_the_given_scene_headless() {
    let dir = common::Scratch::new("default");
    let out = run_default(&dir);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let first = Framebuffer::load(&dir.join("Output_11.bmp")).unwrap();
    assert_eq!((first.width, first.height), (768, 768));
    // It is the given scene from the default camera (spot-check against a small render
    // is impossible at another size, so compare a downscaled region: the top rows are
    // sky, the bottom row is floor).
    assert!(first.pixels[..768 * 100].iter().all(|p| *p == [0, 0, 0]));
    assert!(first.pixels[767 * 768..].iter().any(|p| *p != [0, 0, 0]));
    std::fs::write(dir.join("Output_12.bmp"), b"a user's file").unwrap();
    let out = run_default(&dir);
    assert!(out.status.success());
    assert_eq!(
        std::fs::read(dir.join("Output_12.bmp")).unwrap(),
        b"a user's file"
    );
    let second = Framebuffer::load(&dir.join("Output_13.bmp")).unwrap();
    assert_eq!(second, first, "deterministic");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("768x768") && stderr.contains("Output_13.bmp"),
        "{stderr}"
    );
}

fn cli_render(dir: &Path, args: &[&str], out: &str) -> Framebuffer {
    let o = Command::new(env!("CARGO_BIN_EXE_octaray"))
        .current_dir(dir)
        .args(["render", "-o", out])
        .args(args)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    Framebuffer::load(&dir.join(out)).unwrap()
}

/// `--size WxH` renders a non-square frame with a vertical field of view: a 96×48
/// frame's middle 48 columns are the 48×48 square frame, on the reference and the
/// fast path, and the two paths agree.
#[test]
fn cli_renders_non_square_frames() {
    let dir = common::Scratch::new("wxh");
    for profile in ["reference", "fast"] {
        let p = ["--profile", profile];
        let wide = cli_render(&dir, &[&p[..], &["--size", "96x48"]].concat(), "w.png");
        let square = cli_render(&dir, &[&p[..], &["--size", "48"]].concat(), "s.png");
        assert_eq!((wide.width, wide.height), (96, 48), "{profile}");
        assert_eq!((square.width, square.height), (48, 48), "{profile}");
        let mut off = 0;
        for y in 0..48 {
            for x in 0..48 {
                let (a, b) = (wide.pixels[y * 96 + 24 + x], square.pixels[y * 48 + x]);
                off += usize::from((0..3).any(|c| a[c].abs_diff(b[c]) > 1));
            }
        }
        assert!(off <= 2, "{profile}: {off} pixels of the centre differ");
        let tall = cli_render(&dir, &[&p[..], &["--size", "20X40"]].concat(), "t.bmp");
        assert_eq!((tall.width, tall.height), (20, 40), "{profile}");
    }
    let r = cli_render(
        &dir,
        &["--profile", "reference", "--size", "96x48"],
        "r.png",
    );
    let f = cli_render(&dir, &["--profile", "fast", "--size", "96x48"], "f.png");
    let off = common::pixels_off(&r.pixels, &f.pixels, 2);
    assert!(off * 100 <= r.pixels.len(), "{off} pixels off by > 2/255");
}
