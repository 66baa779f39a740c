//! The samplers and the true picture: the adaptive sampler's knobs (and their errors),
//! what it refines, the true picture's cache, and where `octaray tradeoff` writes.

use std::path::{Path, PathBuf};
use std::process::Command;

use octaray::render::RenderSettings;
use octaray::render::profile::{Profile, Sampler, SamplerKind};
use octaray::scene::{Camera, Scene};
use octaray::tradeoff::truth::{self, Source, TruthKey};

fn error(text: &str) -> String {
    match Profile::from_toml("bad", text, "profiles/bad.toml") {
        Ok(p) => panic!("accepted {text:?} as {p:?}"),
        Err(e) => e.to_string(),
    }
}

fn temp_dir(tag: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("octaray-sampling-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn octaray(args: &[&str], dir: &Path) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_octaray"))
        .args(args)
        .current_dir(dir)
        .output()
        .unwrap()
}

#[test]
fn the_sampler_knobs_load() {
    let p = Profile::from_toml(
        "q",
        "sampler = \"adaptive\"\nsamples_per_pixel = 16\nthreshold = 0.1\n",
        "q.toml",
    )
    .unwrap();
    assert_eq!(p.sampler, SamplerKind::Adaptive);
    assert_eq!(
        p.sampler(),
        Sampler::Adaptive {
            n: 4,
            threshold: 0.1
        }
    );
    let u = Profile::from_toml("u", "samples_per_pixel = 9\n", "u.toml").unwrap();
    assert_eq!(u.sampler(), Sampler::Uniform { n: 3 });
    let q = Profile::by_name("quality").unwrap();
    assert!(matches!(q.sampler(), Sampler::Adaptive { n: 4, .. }));
    assert_eq!(
        Profile::by_name("fast").unwrap().sampler(),
        Sampler::Uniform { n: 1 }
    );
}

#[test]
fn bad_sampler_knobs_name_file_line_column_and_key() {
    let cases: &[(&str, &str, &str)] = &[
        (
            "sampler = \"stochastic\"\n",
            "profiles/bad.toml:1:11:",
            "sampler",
        ),
        (
            "sampler = \"adaptive\"\nsamples_per_pixel = 16\nthreshold = 1.5\n",
            "profiles/bad.toml:3:",
            "threshold",
        ),
        (
            "sampler = \"adaptive\"\nsamples_per_pixel = 16\nthreshold = -0.01\n",
            "profiles/bad.toml:3:",
            "threshold",
        ),
        (
            "samples_per_pixel = 16\n\nthreshold = 0.1\n",
            "profiles/bad.toml:3:13:",
            "threshold",
        ),
        (
            "# adaptive without a grid to refine to\nsampler = \"adaptive\"\n",
            "profiles/bad.toml:2:11:",
            "sampler",
        ),
        (
            "sampler = \"adaptive\"\nsamples_per_pixel = 16\nthreshold = \"low\"\n",
            "profiles/bad.toml:3:",
            "threshold",
        ),
    ];
    for (text, position, key) in cases {
        let e = error(text);
        assert!(e.starts_with(position), "{text:?}: {e}");
        assert!(e.contains(key), "{text:?}: {e}");
    }
}

#[test]
fn cli_refuses_a_bad_sampler_with_exit_code_2() {
    let dir = temp_dir("cli");
    for (name, text, at) in [
        (
            "unknown.toml",
            "path = \"packet\"\nsampler = \"sobol\"\n",
            "unknown.toml:2:11",
        ),
        (
            "range.toml",
            "sampler = \"adaptive\"\nsamples_per_pixel = 4\nthreshold = 7\n",
            "range.toml:3:13",
        ),
    ] {
        std::fs::write(dir.join(name), text).unwrap();
        for args in [
            vec!["render", "--size", "8", "--profile", name],
            vec!["tradeoff", "--size", "8", "--profiles", name],
        ] {
            let out = octaray(&args, &dir);
            let stderr = String::from_utf8_lossy(&out.stderr);
            assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
            assert!(stderr.contains(at), "{args:?}: {stderr}");
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// A pixel the adaptive sampler refines is uniform 4 × 4's pixel; the others cost two
/// samples, so `quality` traces far fewer camera rays.
#[test]
fn quality_refines_to_uniform_4x4_and_traces_fewer_rays() {
    let scene = Scene::given();
    let s = RenderSettings::square(192);
    let quality = Profile::by_name("quality").unwrap().render(&scene, &s);
    let uniform = Profile::from_toml("u4", "samples_per_pixel = 16", "u4.toml")
        .unwrap()
        .render(&scene, &s);
    let fast = Profile::by_name("fast").unwrap().render(&scene, &s);
    let same = (quality.image.pixels.iter())
        .zip(&uniform.image.pixels)
        .filter(|(a, b)| a == b)
        .count();
    let n = quality.image.pixels.len();
    // every refined pixel, and the flat ones (sky, tile interiors)
    assert!(same > n / 2, "{same} of {n}");
    let (q, u) = (quality.stats.primary_rays, uniform.stats.primary_rays);
    assert!(q < u / 2, "{q} camera rays against {u}");
    assert!(
        q > fast.stats.primary_rays * 2,
        "{q}: the first pass and refinements"
    );
}

/// A crop of an adaptive frame equals the same pixels of the whole frame even where the
/// crop's border cuts through refined regions (the first pass covers its neighbours).
#[test]
fn adaptive_crops_equal_the_whole_frame_on_the_reference_path_too() {
    let scene = Scene::given();
    let p = Profile::from_toml(
        "a",
        "path = \"reference\"\nsampler = \"adaptive\"\nsamples_per_pixel = 4\nthreshold = 0.02",
        "a.toml",
    )
    .unwrap();
    let prepared = p.prepare(&scene, Camera::default().eye);
    let mut s = RenderSettings::square(40);
    let whole = prepared.render(&s);
    let crop = octaray::render::PixelRect {
        x0: 11,
        x1: 29,
        y0: 17,
        y1: 26,
    };
    s.crop = Some(crop);
    let part = prepared.render(&s);
    for y in crop.y0..crop.y1 {
        for x in crop.x0..crop.x1 {
            assert_eq!(
                part.image.get(x - crop.x0, y - crop.y0),
                whole.image.get(x, y),
                "({x}, {y})"
            );
        }
    }
}

#[test]
fn the_true_picture_is_cached_by_scene_size_and_camera() {
    let dir = temp_dir("truth");
    let scene = Scene::given();
    let key = TruthKey {
        scene: &scene,
        camera: Camera::default(),
        width: 12,
        height: 10,
        samples: 8,
    };
    let (first, source) = truth::load_or_render(&key, &dir);
    let Source::Rendered(_, Ok(path)) = source else {
        panic!("rendered and stored: {source:?}");
    };
    assert!(path.starts_with(&dir) && path.exists());
    let (second, source) = truth::load_or_render(&key, &dir);
    assert!(matches!(source, Source::Cached(p) if p == path));
    assert_eq!(first.pixels.len(), 120);
    for (a, b) in first.pixels.iter().zip(&second.pixels) {
        // stored as f32
        assert!((*a - *b).abs().max_element() < 1e-6);
    }
    // another camera, size, grid or scene is another picture
    let moved = TruthKey {
        camera: Camera::from_look(
            glam::DVec3::new(90.0, 100.0, 50.0),
            glam::DVec3::new(-1.0, -1.0, 0.0),
            glam::DVec3::Z,
            80.0,
        )
        .unwrap(),
        ..key.clone()
    };
    let mut other = scene.clone();
    other.recursion_level = 2;
    let digests = [
        key.digest(),
        moved.digest(),
        TruthKey {
            width: 13,
            ..key.clone()
        }
        .digest(),
        TruthKey {
            samples: 9,
            ..key.clone()
        }
        .digest(),
        TruthKey {
            scene: &other,
            ..key.clone()
        }
        .digest(),
    ];
    for (i, a) in digests.iter().enumerate() {
        for b in &digests[i + 1..] {
            assert_ne!(a, b);
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// `octaray tradeoff my_scene.txt` reports to stdout and writes only where asked: never
/// the project's profiles/.
#[test]
fn tradeoff_on_a_users_scene_writes_where_asked() {
    let dir = temp_dir("tradeoff");
    let given = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes/given.txt");
    std::fs::copy(&given, dir.join("my_scene.txt")).unwrap();
    let cache = dir.join("cache");
    let base = [
        "tradeoff",
        "my_scene.txt",
        "--size",
        "12",
        "--truth-samples",
        "8",
        "--truth-cache",
        cache.to_str().unwrap(),
        "--profiles",
        "reference,fast,quality",
    ];
    let out = octaray(&base, &dir);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(stdout.contains("| my_scene | 12 | quality |"), "{stdout}");
    assert!(!dir.join("profiles").exists(), "wrote into ./profiles");
    let entries: Vec<_> = std::fs::read_dir(&dir).unwrap().collect();
    assert_eq!(
        entries.len(),
        2,
        "only the scene and the cache: {entries:?}"
    );
    // where asked
    let mut args = base.to_vec();
    args.extend(["--markdown", "report.md", "--plot", "plot.svg"]);
    let out = octaray(&args, &dir);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let md = std::fs::read_to_string(dir.join("report.md")).unwrap();
    assert!(
        md.contains("true PSNR dB") && md.contains("## The ladder"),
        "{md}"
    );
    let svg = std::fs::read_to_string(dir.join("plot.svg")).unwrap();
    assert!(svg.starts_with("<svg") && svg.contains("my_scene 12²"));
    // a plot that is not SVG is refused before anything is measured
    let mut args = base.to_vec();
    args.extend(["--plot", "plot.png"]);
    let out = octaray(&args, &dir);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--plot"));
    let _ = std::fs::remove_dir_all(&dir);
}
