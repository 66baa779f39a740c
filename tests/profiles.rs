//! Profiles: every `profiles/*.toml` loads, bad files are refused with file:line:column
//! and the key, the frame-level knobs do what they say, and the accuracy bars of the profiles
//! hold on small renders of every scene in `scenes/` (no timing here: see
//! `octaray tradeoff`).

use std::path::PathBuf;
use std::process::Command;

use octaray::render::RenderSettings;
use octaray::render::diff::{compare, reference_ids};
use octaray::render::prepared::upscale_bilinear;
use octaray::render::profile::{Profile, ProfileError, RenderPath};
use octaray::render::reference;
use octaray::scene::parse::parse_scene_file;
use octaray::scene::{Camera, Scene};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn profile_files() -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(root().join("profiles"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    files.sort();
    files
}

fn scenes() -> Vec<(String, Scene)> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(root().join("scenes"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "txt"))
        .collect();
    files.sort();
    files
        .iter()
        .map(|p| {
            let name = p.file_stem().unwrap().to_string_lossy().into_owned();
            let scene = parse_scene_file(p).unwrap_or_else(|e| panic!("{e}")).scene;
            (name, scene)
        })
        .collect()
}

/// A profile of the defaults plus `text`.
fn custom(text: &str) -> Profile {
    Profile::from_toml("custom", text, "custom.toml").unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn every_profile_file_loads_and_is_built_in() {
    let files = profile_files();
    let mut names: Vec<String> = Vec::new();
    for f in &files {
        let p = Profile::from_file(f).unwrap_or_else(|e| panic!("{e}"));
        let name = f.file_stem().unwrap().to_string_lossy().into_owned();
        assert_eq!(p.name, name);
        assert_eq!(
            Some(&p),
            Profile::by_name(&name).as_ref(),
            "{name}: the built-in copy differs from the file"
        );
        names.push(name);
    }
    let mut builtin: Vec<String> = Profile::NAMES.iter().map(|s| s.to_string()).collect();
    builtin.sort();
    assert_eq!(names, builtin);
    assert_eq!(
        Profile::by_name(Profile::default_name()).unwrap().name,
        "fast"
    );
    assert_eq!(
        Profile::by_name("reference").unwrap().path,
        RenderPath::Reference
    );
    // A name and a path both load.
    assert_eq!(
        Profile::load(root().join("profiles/preview.toml").to_str().unwrap()).unwrap(),
        Profile::by_name("preview").unwrap()
    );
    assert!(matches!(
        Profile::load("no-such-profile"),
        Err(ProfileError::Unknown(_))
    ));
}

/// An empty file is every default: the packet path, pixel centres, full resolution.
#[test]
fn defaults() {
    let p = Profile::from_toml("empty", "", "empty.toml").unwrap();
    assert_eq!(p.path, RenderPath::Packet);
    assert_eq!(p.samples_per_pixel, 1);
    assert_eq!(p.resolution_scale, 1.0);
    assert_eq!(p.max_recursion, None);
    assert!(p.packet.shadow_any_hit);
}

fn error(text: &str) -> String {
    match Profile::from_toml("bad", text, "profiles/bad.toml") {
        Ok(p) => panic!("accepted {text:?} as {p:?}"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn bad_files_name_file_line_column_and_key() {
    let cases: &[(&str, &str, &str)] = &[
        // (file, position, words that must appear)
        (
            "path = \"packet\"\n# comment\nsampels = 4\n",
            "profiles/bad.toml:3:1:",
            "sampels",
        ),
        (
            "path = \"packet\"\nsamples_per_pixel = 3\n",
            "profiles/bad.toml:2:",
            "samples_per_pixel",
        ),
        ("path = \"gpu\"\n", "profiles/bad.toml:1:", "path"),
        (
            "resolution_scale = 2.0\n",
            "profiles/bad.toml:1:",
            "resolution_scale",
        ),
        (
            "\n\nresolution_scale = \"half\"\n",
            "profiles/bad.toml:3:",
            "resolution_scale",
        ),
        (
            "ray_offset = \"epsilon:-1\"\n",
            "profiles/bad.toml:1:",
            "ray_offset",
        ),
        (
            "ray_offset = \"sometimes\"\n",
            "profiles/bad.toml:1:",
            "ray_offset",
        ),
        (
            "single_ray_lanes = 9\n",
            "profiles/bad.toml:1:",
            "single_ray_lanes",
        ),
        (
            "max_recursion = -1\n",
            "profiles/bad.toml:1:",
            "max_recursion",
        ),
        ("path = \"packet\n", "profiles/bad.toml:1:", ""),
    ];
    for (text, position, key) in cases {
        let e = error(text);
        assert!(e.starts_with(position), "{text:?}: {e}");
        assert!(e.contains(key), "{text:?}: {e}");
    }
}

#[test]
fn cli_refuses_a_bad_profile_with_exit_code_2() {
    let dir = std::env::temp_dir().join(format!("octaray-profiles-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let bad = dir.join("bad.toml");
    std::fs::write(&bad, "path = \"packet\"\nfast_math = true\n").unwrap();
    for args in [
        vec!["render", "--size", "8", "--profile", bad.to_str().unwrap()],
        vec!["render", "--size", "8", "--profile", "no-such-profile"],
        vec![
            "tradeoff",
            "--size",
            "8",
            "--profiles",
            bad.to_str().unwrap(),
        ],
        vec!["tradeoff", "--size", "8", "no-such-scene.txt"],
    ] {
        let out = Command::new(env!("CARGO_BIN_EXE_octaray"))
            .args(&args)
            .current_dir(&dir)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
        if args.contains(&bad.to_str().unwrap()) {
            assert!(
                stderr.contains("bad.toml:2:1") && stderr.contains("fast_math"),
                "{stderr}"
            );
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// The prepared reference is the reference: byte for byte, frame after frame.
#[test]
fn prepared_reference_renders_exactly_the_reference() {
    let scene = Scene::given();
    let p = Profile::by_name("reference").unwrap();
    let prepared = p.prepare(&scene, Camera::default().eye);
    for eye in [[100.0, 100.0, 50.0], [80.0, -60.0, 30.0]] {
        let mut s = RenderSettings::square(64);
        s.camera =
            Camera::from_look(eye.into(), -glam::DVec3::from(eye), glam::DVec3::Z, 70.0).unwrap();
        let want = reference::render(&scene, &s).image;
        assert_eq!(prepared.render(&s).image, want);
        assert_eq!(p.render(&scene, &s).image, want);
    }
}

/// A prepared packet profile gives the same frame as a fresh one for the camera it
/// was built at, and renders other cameras close to the reference.
#[test]
fn prepared_packet_reuses_its_bvh() {
    let scene = Scene::given();
    let p = Profile::by_name("fast").unwrap();
    let prepared = p.prepare(&scene, Camera::default().eye);
    let s = RenderSettings::square(64);
    assert_eq!(prepared.render(&s).image, p.render(&scene, &s).image);
    let mut moved = RenderSettings::square(64);
    moved.camera = Camera::from_look(
        [90.0, 90.0, 45.0].into(),
        glam::DVec3::new(-1.0, -1.0, -0.2),
        glam::DVec3::Z,
        80.0,
    )
    .unwrap();
    let img = prepared.render(&moved).image;
    let want = reference::render(&scene, &moved).image;
    let d = compare(&want, &img, &reference_ids(&scene, &moved.camera, 64, 64));
    assert!(d.psnr_db >= 40.0, "{d:?}");
}

/// n × n samples per pixel average the n×-resolution image in linear colour: within one
/// step of the 8-bit box filter of that image (which rounded each sample first).
#[test]
fn supersampling_averages_the_finer_grid() {
    let scene = Scene::given();
    for path in ["reference", "packet"] {
        let p = custom(&format!("path = \"{path}\"\nsamples_per_pixel = 4"));
        let ss = p.render(&scene, &RenderSettings::square(48)).image;
        let fine = custom(&format!("path = \"{path}\""))
            .render(&scene, &RenderSettings::square(96))
            .image;
        let mut worst = 0;
        for y in 0..48usize {
            for x in 0..48usize {
                for c in 0..3 {
                    let sum: u32 = [(0, 0), (1, 0), (0, 1), (1, 1)]
                        .iter()
                        .map(|(a, b)| fine.pixels[(2 * y + b) * 96 + 2 * x + a][c] as u32)
                        .sum();
                    let boxed = sum as f64 / 4.0;
                    let d = (ss.pixels[y * 48 + x][c] as f64 - boxed).abs();
                    worst = worst.max((d * 2.0).round() as u32);
                }
            }
        }
        assert!(worst <= 2, "{path}: off by {} steps", worst as f64 / 2.0);
    }
}

/// `resolution_scale` renders smaller and upscales to the requested size.
#[test]
fn resolution_scale_upscales_a_smaller_frame() {
    let scene = Scene::given();
    let half = custom("path = \"reference\"\nresolution_scale = 0.5");
    let img = half.render(&scene, &RenderSettings::square(64));
    assert_eq!((img.image.width, img.image.height), (64, 64));
    assert_eq!(img.stats.primary_rays, 32 * 32);
    let small = reference::render(&scene, &RenderSettings::square(32)).image;
    assert_eq!(img.image, upscale_bilinear(&small, 64, 64));
}

/// `max_recursion = 1` stops every mirror ray, on both paths; the scene's own level
/// is used otherwise.
#[test]
fn max_recursion_caps_mirror_rays() {
    let scene = Scene::given();
    assert!(scene.recursion_level > 1);
    for path in ["reference", "packet"] {
        let capped = custom(&format!("path = \"{path}\"\nmax_recursion = 1"));
        let free = custom(&format!("path = \"{path}\""));
        let a = capped.render(&scene, &RenderSettings::square(48)).stats;
        let b = free.render(&scene, &RenderSettings::square(48)).stats;
        assert_eq!(a.reflection_rays, 0, "{path}");
        assert!(b.reflection_rays > 0, "{path}");
    }
}

/// The spec's bars on every scene in scenes/, at 160 × 160: `fast` PSNR >= 40 dB and
/// <= 1 % of pixels off by more than 8/255 against the reference, and at most 0.1 % off
/// by more than 2/255 outside the masks of legitimate differences.
#[test]
fn accuracy_bars_on_every_scene() {
    let size = 160;
    let fast = Profile::by_name("fast").unwrap();
    let reference = Profile::by_name("reference").unwrap();
    let s = RenderSettings::square(size);
    for (name, scene) in scenes() {
        let want = reference.render(&scene, &s).image;
        let ids = reference_ids(&scene, &s.camera, size, size);
        let f = compare(&want, &fast.render(&scene, &s).image, &ids);
        println!(
            "{name}: fast {:.1} dB, {:.3} % > 8/255, {:.3} % > 2/255 unmasked",
            f.psnr_db,
            f.percent(f.off8),
            f.percent(f.off2_unmasked)
        );
        assert!(f.psnr_db >= 40.0, "{name} fast: {f:?}");
        assert!(f.percent(f.off8) <= 1.0, "{name} fast: {f:?}");
        assert!(f.percent(f.off2_unmasked) <= 0.1, "{name} fast: {f:?}");
    }
}

/// Each packet-path knob changes the code that runs, shown by a counter or an image it
/// changes: closest-hit shadow queries give the any-hit image with more node tests;
/// ray-by-ray tracing of every packet gives the same image with other node tests; a
/// fixed ray offset is close at the scene's scale and visibly wrong when far too
/// large; the Möller test lets rays through edges shared by triangles where the
/// watertight test does not.
#[test]
fn packet_knobs_are_real() {
    let scene = Scene::given();
    let s = RenderSettings::square(96);
    let want = reference::render(&scene, &s).image;
    let ids = reference_ids(&scene, &s.camera, 96, 96);
    let base = custom("").render(&scene, &s);
    let closest = custom("shadow_any_hit = false").render(&scene, &s);
    let d = compare(&base.image, &closest.image, &ids);
    assert!(d.psnr_db >= 60.0, "closest-hit shadows: {d:?}");
    assert!(
        closest.stats.node_tests > base.stats.node_tests,
        "closest-hit shadows test more nodes: {} vs {}",
        closest.stats.node_tests,
        base.stats.node_tests
    );
    let lanes = custom("single_ray_lanes = 8").render(&scene, &s);
    assert_eq!(lanes.image, base.image, "ray by ray: the same picture");
    assert_ne!(
        lanes.stats.node_tests, base.stats.node_tests,
        "ray by ray: other node tests"
    );
    let eps = custom("ray_offset = \"epsilon:1e-3\"")
        .render(&scene, &s)
        .image;
    let d = compare(&want, &eps, &ids);
    assert!(d.psnr_db >= 40.0, "epsilon 1e-3: {d:?}");
    let huge = custom("ray_offset = \"epsilon:3\"")
        .render(&scene, &s)
        .image;
    let d = compare(&want, &huge, &ids);
    assert!(
        d.psnr_db < 40.0,
        "epsilon 3 should visibly move shadows: {d:?}"
    );
    // the plain triangle test: the given scene within tolerance, and light through the
    // diagonal of a quad whose pixel rays run exactly along it
    let mt = custom("triangle_test = \"moller\"")
        .render(&scene, &s)
        .image;
    let d = compare(&want, &mt, &ids);
    assert!(d.psnr_db >= 40.0, "moller: {d:?}");
    // a tilted grid of quads whose corners are where pixel rays meet the plane: every
    // other pixel ray runs exactly along a shared edge
    let camera = octaray::scene::Camera::from_look(
        glam::DVec3::new(5.25, 5.25, 40.0),
        glam::DVec3::NEG_Z,
        glam::DVec3::Y,
        14.0,
    )
    .unwrap();
    let side = 33;
    let grid = camera.pixel_grid(side, side);
    let normal = glam::DVec3::new(-0.37, -0.26, 1.0);
    let on_plane = |i: i32, j: i32| {
        let d = grid.direction(i as f64, j as f64);
        let t = (glam::DVec3::new(0.0, 0.0, 5.0) - grid.eye).dot(normal) / d.dot(normal);
        grid.eye + d * t
    };
    let mut text = String::new();
    let mut count = 0;
    for j in (-2..side as i32 + 2).step_by(2) {
        for i in (-2..side as i32 + 2).step_by(2) {
            let [a, b, c, d] =
                [(i, j), (i + 2, j), (i + 2, j + 2), (i, j + 2)].map(|(i, j)| on_plane(i, j));
            for t in [[a, b, c], [a, c, d]] {
                text += "triangle";
                for v in t {
                    text += &format!(" {:e} {:e} {:e}", v.x, v.y, v.z);
                }
                text += " 0 1 0  1 0 0 0 1\n";
                count += 1;
            }
        }
    }
    let quad = octaray::scene::parse::parse_scene(&format!("1 {side} {count}\n{text}0 0"), "grid")
        .unwrap()
        .scene;
    let mut down = RenderSettings::square(side);
    down.camera = camera;
    // the grid fills the view in green: a pixel without green saw through it
    let leaks = |p: &str| {
        let img = custom(p).render(&quad, &down).image;
        img.pixels.iter().filter(|c| c[1] < 200).count()
    };
    assert_eq!(leaks(""), 0, "the watertight test holds at shared edges");
    assert!(
        leaks("triangle_test = \"moller\"") > 0,
        "the plain test leaks at shared edges"
    );
    let e = error("path = \"packet\"\ntriangle_test = \"plain\"\n");
    assert!(
        e.starts_with("profiles/bad.toml:2:") && e.contains("triangle_test"),
        "{e}"
    );
}

/// A scene runs only the code it needs: no quadric tests without quadrics, no cone
/// tests without spotlights, no mirror rays at recursion level 1 — on both paths.
#[test]
fn counters_are_zero_for_absent_features() {
    let scenes = scenes();
    let get = |n: &str| &scenes.iter().find(|(name, _)| name == n).unwrap().1;
    let s = RenderSettings::square(64);
    for profile in ["reference", "fast"] {
        let p = Profile::by_name(profile).unwrap();
        let given = p.render(get("given"), &s).stats;
        assert!(
            given.quadric_tests > 0 && given.cone_tests > 0,
            "{profile}: {given:?}"
        );
        assert!(given.reflection_rays > 0, "{profile}");
        let spots = p.render(get("spotlights"), &s).stats;
        assert_eq!(
            spots.quadric_tests, 0,
            "{profile}: spotlights.txt has no quadric"
        );
        assert!(spots.cone_tests > 0, "{profile}");
        let cone = p.render(get("quadric_cone"), &s).stats;
        assert_eq!(
            cone.cone_tests, 0,
            "{profile}: quadric_cone.txt has no spotlight"
        );
        let one = get("one_sphere");
        assert_eq!(one.recursion_level, 1);
        assert_eq!(p.render(one, &s).stats.reflection_rays, 0, "{profile}");
    }
}
