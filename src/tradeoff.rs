//! `octaray tradeoff`: the speed/accuracy trade of each profile, measured.
//!
//! Each scene is rendered under each profile (wall time of `Profile::render`, prepare
//! included: the BVH build and the photon map are part of an image's cost; median of
//! [`REPS`]) and compared with the `reference` image ([`crate::render::diff`]): PSNR,
//! largest channel difference, pixels off by more than 1/255 and 8/255, everywhere and
//! outside the masks of legitimate differences (silhouettes from the reference's
//! primary-hit ids, edges where the reference jumps by more than 24/255).
//!
//! A second table shows that a scene pays only for what it contains: the per-frame
//! counters of quadric tests, spotlight cone tests and mirror rays are zero where the
//! scene has no quadric, no spotlight or recursion level 1, and the given scene is timed
//! with one feature added (a quadric or a spotlight that adds nothing to the picture)
//! or removed (recursion level 1).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use glam::DVec3;

use crate::render::diff::{ImageDiff, compare, reference_ids};
use crate::render::profile::{Profile, RenderPath};
use crate::render::{RenderSettings, RenderStats, Rendered};
use crate::scene::parse::parse_scene_file;
use crate::scene::{Material, Object, Quadric, Scene, Shape, SpotLight};

/// Timed renders per (scene, profile); the median is reported.
pub const REPS: usize = 3;

/// Timed renders per variant of the feature-cost table (small differences: more reps).
pub const FEATURE_REPS: usize = 9;

/// One measured (scene, profile).
#[derive(Clone, Debug)]
pub struct Row {
    pub scene: String,
    pub size: u32,
    pub profile: String,
    /// The path that rendered it.
    pub path: RenderPath,
    /// Median wall time of `Profile::render`, seconds.
    pub seconds: f64,
    pub stats: RenderStats,
    /// Reference time / this time.
    pub speedup: f64,
    pub diff: ImageDiff,
}

impl Row {
    pub fn mrays_per_s(&self) -> f64 {
        self.stats.total_rays() as f64 / 1e6 / self.seconds.max(1e-9)
    }
}

/// A scene variant timed for the "what a feature costs" table.
#[derive(Clone, Debug)]
pub struct FeatureRow {
    pub variant: String,
    pub profile: String,
    pub path: RenderPath,
    pub seconds: f64,
    pub stats: RenderStats,
}

#[derive(Debug, thiserror::Error)]
pub enum TradeoffError {
    #[error("{0}")]
    Input(String),
    #[error("{0}")]
    Output(#[from] crate::output::OutputError),
}

/// The scene files of `scenes/` (sorted), the default set.
pub fn default_scenes(dir: &Path) -> Result<Vec<PathBuf>, TradeoffError> {
    let entries = std::fs::read_dir(dir).map_err(|e| {
        TradeoffError::Input(format!(
            "{}: {e} (run from the repository root or name scene files)",
            dir.display()
        ))
    })?;
    let mut files: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "txt"))
        .collect();
    files.sort();
    Ok(files)
}

/// Renders `REPS` times; returns the median time and the last frame.
fn timed(profile: &Profile, scene: &Scene, s: &RenderSettings) -> (f64, Rendered) {
    timed_n(profile, scene, s, REPS)
}

/// Renders `reps` times; returns the median time and the last frame.
fn timed_n(profile: &Profile, scene: &Scene, s: &RenderSettings, reps: usize) -> (f64, Rendered) {
    let mut times = Vec::with_capacity(reps);
    let mut last = None;
    for _ in 0..reps.max(1) {
        let start = Instant::now();
        let r = profile.render(scene, s);
        times.push(start.elapsed().as_secs_f64());
        last = Some(r);
    }
    times.sort_by(f64::total_cmp);
    (times[times.len() / 2], last.expect("at least one render"))
}

/// Measures every scene under every profile at `size`; `log` gets a line per row.
pub fn measure(
    scenes: &[PathBuf],
    profiles: &[Profile],
    size: u32,
    log: &mut dyn FnMut(&Row),
) -> Result<Vec<Row>, TradeoffError> {
    let reference = Profile::by_name("reference").expect("built in");
    let s = RenderSettings::square(size);
    let mut rows = Vec::new();
    for path in scenes {
        let parsed = parse_scene_file(path).map_err(|e| TradeoffError::Input(e.to_string()))?;
        let scene = parsed.scene;
        let name = path.file_stem().map_or_else(
            || path.display().to_string(),
            |n| n.to_string_lossy().into(),
        );
        let (ref_time, ref_frame) = timed(&reference, &scene, &s);
        let ids = reference_ids(&scene, &s.camera, size, size);
        for p in profiles {
            let (seconds, frame) = if p == &reference {
                (ref_time, ref_frame.clone_frame())
            } else {
                timed(p, &scene, &s)
            };
            let row = Row {
                scene: name.clone(),
                size,
                profile: p.name.clone(),
                path: p.path,
                seconds,
                stats: frame.stats,
                speedup: ref_time / seconds.max(1e-9),
                diff: compare(&ref_frame.image, &frame.image, &ids),
            };
            log(&row);
            rows.push(row);
        }
    }
    Ok(rows)
}

trait CloneFrame {
    fn clone_frame(&self) -> Rendered;
}

impl CloneFrame for Rendered {
    fn clone_frame(&self) -> Rendered {
        Rendered {
            image: self.image.clone(),
            rect: self.rect,
            stats: self.stats,
        }
    }
}

/// The given scene with one feature added or removed, under `profile`.
pub fn feature_costs(given: &Scene, profiles: &[Profile], size: u32) -> Vec<FeatureRow> {
    let s = RenderSettings::square(size);
    let dark = Material {
        color: DVec3::splat(0.5),
        ka: 0.3,
        kd: 0.3,
        ks: 0.3,
        kr: 0.0,
        shine: 10.0,
    };
    // an unclipped cylinder x² + y² = 1 around a vertical axis 5000 units behind the
    // camera: unbounded, so every ray tests it, and no ray of this view reaches it
    let c = DVec3::new(5000.0, 5000.0, 0.0);
    let coef = [
        1.0,
        1.0,
        0.0,
        0.0,
        0.0,
        0.0,
        -2.0 * c.x,
        -2.0 * c.y,
        0.0,
        c.x * c.x + c.y * c.y - 1.0,
    ];
    let m = coef.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    let mut with_quadric = given.clone();
    with_quadric.objects.push(Object {
        shape: Shape::Quadric(Quadric {
            coef: coef.map(|v| v / m),
            min: DVec3::ZERO,
            size: DVec3::ZERO,
        }),
        material: dark,
    });
    // a spotlight pointing at the sky: every shading point tests its cone, none is lit
    let mut with_spot = given.clone();
    with_spot.spot_lights.push(SpotLight {
        position: DVec3::new(0.0, 0.0, 300.0),
        color: DVec3::ONE,
        direction: DVec3::Z,
        cutoff_deg: 10.0,
    });
    let mut level1 = given.clone();
    level1.recursion_level = 1;
    let variants = [
        ("given scene".to_string(), given),
        (
            "+ an unbounded quadric out of view".to_string(),
            &with_quadric,
        ),
        ("+ a spotlight lighting nothing".to_string(), &with_spot),
        ("recursion level 1".to_string(), &level1),
    ];
    let mut rows = Vec::new();
    for profile in profiles {
        for (variant, scene) in &variants {
            let (seconds, frame) = timed_n(profile, scene, &s, FEATURE_REPS);
            rows.push(FeatureRow {
                variant: variant.clone(),
                profile: profile.name.clone(),
                path: profile.path,
                seconds,
                stats: frame.stats,
            });
        }
    }
    rows
}

/// A feature counter; the packet path does not count quadric and cone tests yet.
fn counted(path: RenderPath, n: u64) -> String {
    match (path, COUNTED_ON_PACKET_PATH) {
        (RenderPath::Packet, false) => "–".into(),
        _ => n.to_string(),
    }
}

/// Whether the packet path fills `quadric_tests` and `cone_tests`.
const COUNTED_ON_PACKET_PATH: bool = true;

fn pct(d: &ImageDiff, n: usize) -> String {
    format!("{:.2}", d.percent(n))
}

fn psnr(d: &ImageDiff) -> String {
    if d.psnr_db.is_infinite() {
        "exact".into()
    } else {
        format!("{:.1}", d.psnr_db)
    }
}

/// Features of a scene, for the table's last column.
fn features(scene: &Scene) -> String {
    let quadrics = scene
        .objects
        .iter()
        .filter(|o| matches!(o.shape, Shape::Quadric(_)))
        .count();
    format!(
        "{quadrics} quadric, {} spot, level {}",
        scene.spot_lights.len(),
        scene.recursion_level
    )
}

/// The Markdown report.
pub fn markdown(
    rows: &[Row],
    headline: &[Row],
    costs: &[FeatureRow],
    scene_features: &[(String, String)],
    command: &str,
    plot: Option<&Path>,
) -> String {
    let mut md = String::new();
    let plot = plot.map_or_else(
        || "none written".to_string(),
        |p| format!("`{}`", p.display()),
    );
    let _ = writeln!(md, "# Speed/accuracy trade-off of the profiles\n");
    let _ = writeln!(
        md,
        "Written by `{command}` on {} threads (the machine is shared: times are indicative). \
         Time: median of {REPS} wall-clock renders of `Profile::render`, per-scene preparation \
         included (BVH build, prism photon map). Errors against `reference`: PSNR over RGB, the \
         largest channel difference (1/255), % of pixels off by more than 1/255 and 8/255, and \
         the same counted outside the masks of legitimate differences (silhouettes from the \
         reference's primary-hit ids, edges where the reference jumps by more than 24/255 to a \
         neighbour). Plot: {plot} (PSNR against time, log scale).\n",
        crate::parallel::threads()
    );
    let table = |md: &mut String, rows: &[Row]| {
        let _ = writeln!(
            md,
            "| scene | size | profile | path | time ms | Mrays/s | speed-up | PSNR dB | max | >1 % | >8 % | >1 % unmasked | >8 % unmasked | quadric tests | cone tests | mirror rays |"
        );
        let _ = writeln!(
            md,
            "|---|---|---|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|"
        );
        for r in rows {
            let d = &r.diff;
            let _ = writeln!(
                md,
                "| {} | {} | {} | {} | {:.1} | {:.2} | {:.1}× | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
                r.scene,
                r.size,
                r.profile,
                match r.path {
                    RenderPath::Reference => "reference",
                    RenderPath::Packet => "packet",
                },
                r.seconds * 1e3,
                r.mrays_per_s(),
                r.speedup,
                psnr(d),
                d.max_diff,
                pct(d, d.off1),
                pct(d, d.off8),
                pct(d, d.off1_unmasked),
                pct(d, d.off8_unmasked),
                counted(r.path, r.stats.quadric_tests),
                counted(r.path, r.stats.cone_tests),
                r.stats.reflection_rays,
            );
        }
    };
    if !headline.is_empty() {
        let _ = writeln!(md, "## The given scene at full size\n");
        table(&mut md, headline);
        md.push('\n');
    }
    let _ = writeln!(md, "## Every scene\n");
    table(&mut md, rows);
    md.push('\n');
    if !scene_features.is_empty() {
        let _ = writeln!(
            md,
            "Scene features (quadric objects, spotlights, recursion level): {}.\n",
            scene_features
                .iter()
                .map(|(s, f)| format!("{s}: {f}"))
                .collect::<Vec<_>>()
                .join("; ")
        );
    }
    if !costs.is_empty() {
        let _ = writeln!(
            md,
            "## Model only what a scene requires\n\nThe counters above are zero where a scene has no quadric, no spotlight or recursion level 1: that code does not run (\"–\": not counted on that path). What each feature costs, on the given scene at the table's size (median of {FEATURE_REPS}):\n"
        );
        let _ = writeln!(
            md,
            "| variant | profile | time ms | vs given | quadric tests | cone tests | shadow rays | mirror rays |"
        );
        let _ = writeln!(md, "|---|---|--:|--:|--:|--:|--:|--:|");
        let mut base = 1e-9;
        for (i, c) in costs.iter().enumerate() {
            if i == 0 || c.profile != costs[i - 1].profile {
                base = c.seconds.max(1e-9);
            }
            let _ = writeln!(
                md,
                "| {} | {} | {:.1} | {:+.0} % | {} | {} | {} | {} |",
                c.variant,
                c.profile,
                c.seconds * 1e3,
                100.0 * (c.seconds / base - 1.0),
                counted(c.path, c.stats.quadric_tests),
                counted(c.path, c.stats.cone_tests),
                c.stats.shadow_rays,
                c.stats.reflection_rays
            );
        }
        md.push('\n');
    }
    md
}

/// The profiles the feature-cost table is measured with.
pub const PROFILES_FOR_COSTS: &[&str] = &["reference", "fast"];

/// Everything `octaray tradeoff` does; returns the report.
pub struct Options {
    pub scenes: Vec<PathBuf>,
    pub profiles: Vec<Profile>,
    pub size: u32,
    /// Size of the given-scene headline table (0: none).
    pub headline_size: u32,
    pub markdown: Option<PathBuf>,
    pub plot: Option<PathBuf>,
    pub command: String,
}

pub fn run(opts: &Options, log: &mut dyn FnMut(&str)) -> Result<String, TradeoffError> {
    // the outputs' names and places, before minutes of measurements
    for (path, image, option) in [
        (&opts.markdown, false, "--markdown"),
        (&opts.plot, true, "--plot"),
    ] {
        if let Some(p) = path {
            crate::output::check_output(p, image)
                .map_err(|e| TradeoffError::Input(format!("{option}: {e}")))?;
        }
    }
    if let (Some(m), Some(p)) = (&opts.markdown, &opts.plot)
        && crate::output::same_file(m, p)
    {
        return Err(TradeoffError::Input(format!(
            "--markdown and --plot name the same file: {}",
            p.display()
        )));
    }
    let mut line = |r: &Row| {
        log(&format!(
            "{:<24} {:>4} {:<10} {:>9.1} ms {:>7.2} Mrays/s {:>6.1}x  PSNR {:>6}  max {:>3}  >8/255 {:>6}%  >1/255 unmasked {:>6}%",
            r.scene,
            r.size,
            r.profile,
            r.seconds * 1e3,
            r.mrays_per_s(),
            r.speedup,
            psnr(&r.diff),
            r.diff.max_diff,
            pct(&r.diff, r.diff.off8),
            pct(&r.diff, r.diff.off1_unmasked)
        ))
    };
    let given = opts
        .scenes
        .iter()
        .find(|p| p.file_stem().is_some_and(|s| s == "given"));
    let headline = match given {
        Some(g) if opts.headline_size > 0 => {
            let fast: Vec<Profile> = opts
                .profiles
                .iter()
                .filter(|p| p.name == "reference" || p.name == "fast")
                .cloned()
                .collect();
            measure(
                std::slice::from_ref(g),
                &fast,
                opts.headline_size,
                &mut line,
            )?
        }
        _ => Vec::new(),
    };
    let rows = measure(&opts.scenes, &opts.profiles, opts.size, &mut line)?;
    let mut scene_features = Vec::new();
    for p in &opts.scenes {
        let scene = parse_scene_file(p)
            .map_err(|e| TradeoffError::Input(e.to_string()))?
            .scene;
        let name = p
            .file_stem()
            .map_or_else(|| p.display().to_string(), |n| n.to_string_lossy().into());
        scene_features.push((name, features(&scene)));
    }
    let costs = match given {
        Some(g) => {
            let scene = parse_scene_file(g)
                .map_err(|e| TradeoffError::Input(e.to_string()))?
                .scene;
            let profiles: Vec<Profile> = PROFILES_FOR_COSTS
                .iter()
                .map(|n| Profile::by_name(n).expect("built in"))
                .collect();
            feature_costs(&scene, &profiles, opts.size)
        }
        None => Vec::new(),
    };
    let md = markdown(
        &rows,
        &headline,
        &costs,
        &scene_features,
        &opts.command,
        opts.plot.as_deref(),
    );
    // whole or not at all, as images (an existing file stays as it was on failure)
    if let Some(path) = &opts.markdown {
        crate::output::write_atomic(path, md.as_bytes())?;
    }
    if let Some(path) = &opts.plot {
        let mut all = headline.clone();
        all.extend(rows.iter().cloned());
        let img = plot::draw(&all);
        let fb = crate::output::Framebuffer {
            width: img.width(),
            height: img.height(),
            pixels: img.pixels().map(|p| p.0).collect(),
        };
        crate::output::write_image(&fb, path)?;
    }
    Ok(md)
}

/// The error-against-time plot, drawn with the `image` crate and a 5 × 7 pixel font.
pub mod plot {
    use image::{Rgb, RgbImage};

    use super::Row;
    use crate::render::profile::Profile;

    const W: u32 = 900;
    const H: u32 = 560;
    const LEFT: i32 = 70;
    const RIGHT: i32 = 190;
    const TOP: i32 = 40;
    const BOTTOM: i32 = 60;
    /// PSNR axis; exact images are drawn at the top.
    const PSNR_MIN: f64 = 10.0;
    const PSNR_MAX: f64 = 100.0;

    /// One colour per profile, in order of first appearance.
    const COLOURS: [[u8; 3]; 8] = [
        [0, 0, 0],
        [31, 119, 180],
        [214, 39, 40],
        [44, 160, 44],
        [148, 103, 189],
        [255, 127, 14],
        [23, 190, 207],
        [140, 86, 75],
    ];

    /// PSNR (dB) against time (log scale), one marker per (scene, size, profile).
    pub fn draw(rows: &[Row]) -> RgbImage {
        let mut img = RgbImage::from_pixel(W, H, Rgb([255, 255, 255]));
        let (x0, x1) = (LEFT, W as i32 - RIGHT);
        let (y0, y1) = (TOP, H as i32 - BOTTOM);
        let grey = Rgb([200, 200, 200]);
        let black = Rgb([0, 0, 0]);
        // time range in decades
        let ms: Vec<f64> = rows.iter().map(|r| (r.seconds * 1e3).max(1e-3)).collect();
        let lo = ms.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = ms.iter().copied().fold(0.0, f64::max);
        let (d0, d1) = if rows.is_empty() {
            (0, 3)
        } else {
            let d0 = lo.log10().floor() as i32;
            (d0, (hi.log10().ceil() as i32).max(d0 + 1))
        };
        let px = |t_ms: f64| {
            let f = (t_ms.log10() - d0 as f64) / (d1 - d0) as f64;
            x0 + (f * (x1 - x0) as f64).round() as i32
        };
        let py = |db: f64| {
            let db = if db.is_infinite() { PSNR_MAX } else { db };
            let f = (db.clamp(PSNR_MIN, PSNR_MAX) - PSNR_MIN) / (PSNR_MAX - PSNR_MIN);
            y1 - (f * (y1 - y0) as f64).round() as i32
        };
        // grid and tick labels
        for d in d0..=d1 {
            for k in 1..10 {
                let t = 10f64.powi(d) * k as f64;
                if d == d1 && k > 1 {
                    break;
                }
                let x = px(t);
                let c = if k == 1 { grey } else { Rgb([235, 235, 235]) };
                vline(&mut img, x, y0, y1, c);
            }
            let label = if d >= 0 {
                format!("{}", 10u64.pow(d as u32))
            } else {
                format!("{}", 10f64.powi(d))
            };
            text(
                &mut img,
                px(10f64.powi(d)) - 3 * label.len() as i32,
                y1 + 8,
                &label,
                black,
            );
        }
        for db in (PSNR_MIN as i32..=PSNR_MAX as i32).step_by(10) {
            let y = py(db as f64);
            hline(&mut img, x0, x1, y, grey);
            let label = if db == PSNR_MAX as i32 {
                "exact".to_string()
            } else {
                db.to_string()
            };
            text(
                &mut img,
                x0 - 8 - 6 * label.len() as i32,
                y - 3,
                &label,
                black,
            );
        }
        // the bars: 40 dB (fast) and 50 dB (accurate)
        for (db, c) in [(40.0, Rgb([214, 39, 40])), (50.0, Rgb([44, 160, 44]))] {
            let y = py(db);
            let mut x = x0;
            while x < x1 {
                hline(&mut img, x, (x + 6).min(x1), y, c);
                x += 12;
            }
        }
        hline(&mut img, x0, x1, y1, black);
        vline(&mut img, x0, y0, y1, black);
        text(
            &mut img,
            (x0 + x1) / 2 - 150,
            H as i32 - 28,
            "time per image, ms (log scale)",
            black,
        );
        text(&mut img, 8, 16, "psnr vs reference, db", black);
        text(
            &mut img,
            x0 + 150,
            14,
            "octaray tradeoff: error against time",
            black,
        );
        // markers and legend
        // built-in profiles in their canonical order, then any others
        let mut names: Vec<&str> = Vec::new();
        for r in rows {
            if !names.contains(&r.profile.as_str()) {
                names.push(&r.profile);
            }
        }
        let rank = |n: &str| {
            Profile::NAMES
                .iter()
                .position(|m| *m == n)
                .unwrap_or(usize::MAX)
        };
        names.sort_by_key(|n| rank(n));
        for r in rows {
            let i = names.iter().position(|n| *n == r.profile).unwrap_or(0);
            let c = Rgb(COLOURS[i % COLOURS.len()]);
            let (x, y) = (px(r.seconds * 1e3), py(r.diff.psnr_db));
            for dy in -3..=3i32 {
                for dx in -3..=3i32 {
                    if dx.abs() + dy.abs() <= 4 {
                        put(&mut img, x + dx, y + dy, c);
                    }
                }
            }
        }
        for (i, name) in names.iter().enumerate() {
            let c = Rgb(COLOURS[i % COLOURS.len()]);
            let (lx, ly) = (x1 + 20, y0 + 10 + 20 * i as i32);
            for dy in 0..10 {
                hline(&mut img, lx, lx + 10, ly + dy, c);
            }
            text(&mut img, lx + 16, ly + 2, name, black);
        }
        let ly = y0 + 20 + 20 * names.len() as i32;
        text(&mut img, x1 + 20, ly, "dashes: 40 and", black);
        text(&mut img, x1 + 20, ly + 10, "50 db bars", black);
        img
    }

    fn put(img: &mut RgbImage, x: i32, y: i32, c: Rgb<u8>) {
        if x >= 0 && y >= 0 && (x as u32) < img.width() && (y as u32) < img.height() {
            img.put_pixel(x as u32, y as u32, c);
        }
    }

    fn hline(img: &mut RgbImage, x0: i32, x1: i32, y: i32, c: Rgb<u8>) {
        for x in x0..=x1 {
            put(img, x, y, c);
        }
    }

    fn vline(img: &mut RgbImage, x: i32, y0: i32, y1: i32, c: Rgb<u8>) {
        for y in y0..=y1 {
            put(img, x, y, c);
        }
    }

    /// Draws `s` (lower case, digits, a little punctuation) at (x, y), 6 px per glyph.
    fn text(img: &mut RgbImage, x: i32, y: i32, s: &str, c: Rgb<u8>) {
        for (i, ch) in s.chars().enumerate() {
            let rows = glyph(ch.to_ascii_lowercase());
            for (dy, row) in rows.iter().enumerate() {
                for dx in 0..5 {
                    if row >> (4 - dx) & 1 == 1 {
                        put(img, x + 6 * i as i32 + dx, y + dy as i32, c);
                    }
                }
            }
        }
    }

    /// 5 × 7 glyphs, one byte per row (low 5 bits, left = bit 4).
    fn glyph(c: char) -> [u8; 7] {
        match c {
            '0' => [14, 17, 19, 21, 25, 17, 14],
            '1' => [4, 12, 4, 4, 4, 4, 14],
            '2' => [14, 17, 1, 2, 4, 8, 31],
            '3' => [31, 2, 4, 2, 1, 17, 14],
            '4' => [2, 6, 10, 18, 31, 2, 2],
            '5' => [31, 16, 30, 1, 1, 17, 14],
            '6' => [6, 8, 16, 30, 17, 17, 14],
            '7' => [31, 1, 2, 4, 8, 8, 8],
            '8' => [14, 17, 17, 14, 17, 17, 14],
            '9' => [14, 17, 17, 15, 1, 2, 12],
            'a' => [0, 0, 14, 1, 15, 17, 15],
            'b' => [16, 16, 22, 25, 17, 17, 30],
            'c' => [0, 0, 14, 16, 16, 17, 14],
            'd' => [1, 1, 13, 19, 17, 17, 15],
            'e' => [0, 0, 14, 17, 31, 16, 14],
            'f' => [6, 9, 8, 28, 8, 8, 8],
            'g' => [0, 15, 17, 17, 15, 1, 14],
            'h' => [16, 16, 22, 25, 17, 17, 17],
            'i' => [4, 0, 12, 4, 4, 4, 14],
            'j' => [2, 0, 6, 2, 2, 18, 12],
            'k' => [16, 16, 18, 20, 24, 20, 18],
            'l' => [12, 4, 4, 4, 4, 4, 14],
            'm' => [0, 0, 26, 21, 21, 17, 17],
            'n' => [0, 0, 22, 25, 17, 17, 17],
            'o' => [0, 0, 14, 17, 17, 17, 14],
            'p' => [0, 0, 30, 17, 30, 16, 16],
            'q' => [0, 0, 13, 19, 15, 1, 1],
            'r' => [0, 0, 22, 25, 16, 16, 16],
            's' => [0, 0, 14, 16, 14, 1, 30],
            't' => [8, 8, 28, 8, 8, 9, 6],
            'u' => [0, 0, 17, 17, 17, 19, 13],
            'v' => [0, 0, 17, 17, 17, 10, 4],
            'w' => [0, 0, 17, 17, 21, 21, 10],
            'x' => [0, 0, 17, 10, 4, 10, 17],
            'y' => [0, 0, 17, 17, 15, 1, 14],
            'z' => [0, 0, 31, 2, 4, 8, 31],
            '.' => [0, 0, 0, 0, 0, 12, 12],
            ',' => [0, 0, 0, 0, 12, 4, 8],
            ':' => [0, 12, 12, 0, 12, 12, 0],
            '-' => [0, 0, 0, 31, 0, 0, 0],
            '(' => [2, 4, 8, 8, 8, 4, 2],
            ')' => [8, 4, 2, 2, 2, 4, 8],
            '/' => [0, 1, 2, 4, 8, 16, 0],
            '%' => [24, 25, 2, 4, 8, 19, 3],
            '_' => [0, 0, 0, 0, 0, 0, 31],
            _ => [0; 7],
        }
    }
}
