//! Values that would make the work unbounded or leave the f32 frame's range: counts
//! computed so they cannot overflow, clamps with a warning, limits named.

use octaray::render::caustic::{CausticSettings, pairs_warning};
use octaray::render::reference::Reference;
use octaray::scene::Scene;
use octaray::scene::parse::parse_scene;

fn scene(text: &str) -> Scene {
    parse_scene(text, "inline").unwrap().scene
}

/// `scenes/prism.txt` with its spotlight's colour replaced by `color`.
fn bright_prism(color: &str) -> Scene {
    let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/prism.txt"))
        .unwrap()
        .replace("\n25 25 25\n", &format!("\n{color}\n"));
    assert!(text.contains(color));
    scene(&text)
}

/// A light of any finite colour: photons × power overflowed to infinity, a count
/// became u64::MAX and the job list grew until the allocation failed (SIGABRT).
/// The counts are now computed in a power unit of the brightest light: at most the
/// photons asked for.
#[test]
fn the_brightest_light_cannot_overflow_the_photon_count() {
    for color in [
        "1e308 1e308 1e308",
        "1.7976931348623157e308 0 0",
        "1e-300 0 1e-300",
    ] {
        let s = bright_prism(color);
        let settings = CausticSettings {
            photons: 20_000,
            ..CausticSettings::default()
        };
        let r = Reference::with_caustics(&s, &settings);
        let map = r.caustics().expect("the spotlight reaches the prism");
        assert!(
            (1..=20_000).contains(&map.stats.emitted),
            "{color}: {} emitted",
            map.stats.emitted
        );
    }
}

/// The share of one pair does not depend on the unit: the given prism at 25 and at
/// 25 · 2¹⁰⁰⁰ emits the same number of photons.
#[test]
fn counts_are_the_same_in_any_power_unit() {
    let settings = CausticSettings::default();
    let emitted = |s: &Scene| {
        Reference::with_caustics(s, &settings)
            .caustics()
            .unwrap()
            .stats
            .emitted
    };
    let scaled = 25.0 * 2f64.powi(1000);
    assert_eq!(
        emitted(&bright_prism("25 25 25")),
        emitted(&bright_prism(&format!("{scaled:e} {scaled:e} {scaled:e}")))
    );
}

/// More (light, glass object) pairs than photons: every pair had one photon at least,
/// so the work grew with lights × glass objects (10 000 lights and 10 000 prisms in a
/// 1 MB file: 10⁸ pairs, 25 GB). Now at most twice the photons asked for are emitted,
/// and the command line warns.
#[test]
fn more_light_glass_pairs_than_photons_are_clamped_with_a_warning() {
    let prisms = 60;
    let lights = 50;
    let mut text = format!("1 8 {prisms}\n");
    for k in 0..prisms {
        let x = f64::from(k) * 10.0;
        text += &format!(
            "prism {x} 0 0  {} 0 0  {x} 3 0  {x} 0 3  {} 0 3  {x} 3 3  1 1 1 0 0 0 0 1  1 1.5 0\n",
            x + 3.0,
            x + 3.0
        );
    }
    text += &format!("{lights}\n");
    for k in 0..lights {
        text += &format!("{} 50 60  1 1 1\n", f64::from(k) * 12.0);
    }
    text += "0\n";
    let s = scene(&text);
    let photons = 1000;
    let settings = CausticSettings {
        photons,
        ..CausticSettings::default()
    };
    let map = Reference::with_caustics(&s, &settings);
    let emitted = map.caustics().unwrap().stats.emitted;
    assert!(emitted <= 2 * u64::from(photons), "{emitted} emitted");
    let warning = pairs_warning(&s, photons).expect("a warning");
    assert!(
        warning.contains("3000 light-glass pairs share 1000 caustic photons"),
        "{warning}"
    );
    // with photons enough for every pair, no warning and every pair emits
    assert_eq!(pairs_warning(&s, 3000), None);
    let settings = CausticSettings {
        photons: 3000,
        ..CausticSettings::default()
    };
    let emitted = Reference::with_caustics(&s, &settings)
        .caustics()
        .unwrap()
        .stats
        .emitted;
    assert!(emitted >= 3000, "{emitted}");
    // the library call is held to the profiles' limit too (MAX_PHOTONS > 3000 pairs)
    assert_eq!(pairs_warning(&s, u32::MAX), None);
}

/// Photon powers beyond f32's range saturate in the density estimate: a light of
/// 1e308 put infinity into the map's f32 columns, and infinity times the zero weight of
/// a photon outside the radius made the estimate NaN, so the caustic vanished.
#[test]
fn a_caustic_beyond_f32_range_saturates_instead_of_vanishing() {
    let s = bright_prism("1e308 1e308 1e308");
    let r = Reference::with_caustics(&s, &CausticSettings::default());
    let map = r.caustics().unwrap();
    let mut lit = 0;
    for k in 0..=20 {
        // along the spectrum on the floor, red end to violet end (scenes/prism.txt)
        let t = f64::from(k) / 20.0;
        let p = glam::DVec3::new(22.4 + 15.2 * t, 37.9 - 15.8 * t, 0.0);
        let e = map.irradiance(p, glam::DVec3::Z);
        assert!(!e.is_nan(), "NaN at {p}");
        lit += usize::from(e.max_element() > 1e30);
    }
    assert!(lit >= 10, "{lit} of 21 points lit");
}

/// `octaray render` of `scene` at 8 × 8 with `profile`: its exit code and stderr.
fn render_cli(scene: &str, profile: &str) -> (Option<i32>, String) {
    let dir = std::env::temp_dir().join(format!(
        "octaray-limits-{}-{}",
        std::process::id(),
        scene.len()
    ));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("s.txt"), scene).unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_octaray"))
        .current_dir(&dir)
        .args([
            "render",
            "s.txt",
            "--size",
            "8",
            "-o",
            "s.bmp",
            "--profile",
            profile,
        ])
        .output()
        .unwrap();
    let _ = std::fs::remove_dir_all(&dir);
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// One object of `shape` (e.g. "sphere\n0 0 0\n5") with a red material, one light.
fn one_object(shape: &str) -> String {
    format!("3\n64\n1\n{shape}\n1 0 0\n0.4 0.2 0.2 0.2\n10\n1\n70 70 70 1 1 1\n0\n")
}

/// Objects reaching past the f32 frame's range are named: a sphere of radius 2e19
/// around the camera rendered as the floor on the f32 paths (its squared radius is
/// infinite in f32) and as the sphere's inside on the reference; a sphere of radius
/// 9e14 at 1e15 and a triangle at 8e12 vanished; none was warned about.
#[test]
fn objects_beyond_the_f32_range_are_named() {
    for shape in [
        "sphere\n100 100 50\n2e19",
        "sphere\n-1e15 -1e15 50\n9e14",
        "triangle\n-8e12 0 -8e12\n0 -8e12 -8e12\n-8e12 -8e12 8e12",
    ] {
        let (code, stderr) = render_cli(&one_object(shape), "fast");
        assert_eq!(code, Some(0), "{stderr}");
        let kind = shape.lines().next().unwrap();
        assert!(
            stderr.contains(&format!(
                "warning: {kind} 1 reaches farther from the camera than f32's range (2^42"
            )),
            "{shape}: {stderr}"
        );
    }
    // within the range, no warning: a sphere of radius 1e12 around the camera
    let (code, stderr) = render_cli(&one_object("sphere\n100 100 50\n1e12"), "fast");
    assert_eq!(code, Some(0), "{stderr}");
    assert!(!stderr.contains("warning"), "{stderr}");
}
