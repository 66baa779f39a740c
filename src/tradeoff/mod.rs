//! `octaray tradeoff`: the speed/accuracy trade of each profile, measured.
//!
//! Each scene is rendered under each profile (wall time of `Profile::render`, prepare
//! included: the BVH build and the photon map are part of an image's cost; median of
//! [`REPS`]) and compared twice:
//! - with the true picture ([`truth`]: each pixel's area average, from the reference
//!   path's dense grid, cached on disk): PSNR, largest channel error, pixels off by
//!   more than 8/255 — the error a user sees, aliasing included;
//! - with the `reference` image, the spec's one sample per pixel
//!   ([`crate::render::diff`]): PSNR, largest channel difference, pixels off by more
//!   than 8/255 outside the masks of legitimate differences (silhouettes from the
//!   reference's primary-hit ids, edges where the reference jumps by more than 24/255)
//!   — whether a profile computes the spec's picture.
//!
//! The profiles after `reference` form a ladder: each should be slower and closer to
//! the true picture than the one before; the report says where a scene breaks that, and
//! [`plot`] draws each scene's line through them.
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
use crate::scene::{Camera, Material, Object, Quadric, Scene, Shape, SpotLight};

pub mod plot;
pub mod truth;

use truth::{Source, TruthError, TruthKey};

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
    /// Against the spec's one-sample image (the `reference` profile).
    pub diff: ImageDiff,
    /// Against the true picture.
    pub truth: TruthError,
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

/// How the true picture of a measured scene was obtained.
#[derive(Clone, Debug)]
pub struct TruthNote {
    pub scene: String,
    pub size: u32,
    /// Per axis.
    pub samples: u32,
    pub source: Source,
}

impl TruthNote {
    /// One line for the log and the report.
    pub fn line(&self) -> String {
        let (n, s) = (self.samples, self.size);
        let what = format!(
            "true picture of {} at {s}x{s} ({n}x{n} reference samples per pixel)",
            self.scene
        );
        match &self.source {
            Source::Cached(p) => format!("{what}: read from {}", p.display()),
            Source::Rendered(t, Ok(p)) => {
                format!(
                    "{what}: rendered in {:.1} s, cached at {}",
                    t.as_secs_f64(),
                    p.display()
                )
            }
            Source::Rendered(t, Err(e)) => {
                format!(
                    "{what}: rendered in {:.1} s, not cached ({e})",
                    t.as_secs_f64()
                )
            }
        }
    }
}

/// What a measurement renders: the image size, the camera and where true pictures are
/// cached.
#[derive(Clone, Debug)]
pub struct Setup {
    pub size: u32,
    pub camera: Camera,
    pub truth_cache: PathBuf,
    /// Samples per pixel along each axis of the true picture.
    pub truth_samples: u32,
}

/// A scene's name in tables: its file stem.
fn scene_name(path: &Path) -> String {
    path.file_stem().map_or_else(
        || path.display().to_string(),
        |n| n.to_string_lossy().into(),
    )
}

/// Measures every scene under every profile; `log` gets a line per true picture and
/// per row.
pub fn measure(
    scenes: &[PathBuf],
    profiles: &[Profile],
    setup: &Setup,
    log: &mut dyn FnMut(&str),
) -> Result<(Vec<Row>, Vec<TruthNote>), TradeoffError> {
    let reference = Profile::by_name("reference").expect("built in");
    let size = setup.size;
    let s = RenderSettings {
        camera: setup.camera,
        ..RenderSettings::square(size)
    };
    let (mut rows, mut notes) = (Vec::new(), Vec::new());
    for path in scenes {
        let parsed = parse_scene_file(path).map_err(|e| TradeoffError::Input(e.to_string()))?;
        let scene = parsed.scene;
        let name = scene_name(path);
        let key = TruthKey {
            scene: &scene,
            camera: setup.camera,
            width: size,
            height: size,
            samples: setup.truth_samples,
        };
        log(&format!("{name} {size}x{size}: the true picture..."));
        let (truth, source) = truth::load_or_render(&key, &setup.truth_cache);
        let note = TruthNote {
            scene: name.clone(),
            size,
            samples: setup.truth_samples,
            source,
        };
        log(&note.line());
        notes.push(note);
        let (ref_time, ref_frame) = timed(&reference, &scene, &s);
        let ids = reference_ids(&scene, &setup.camera, size, size);
        for p in profiles {
            let (seconds, frame) = if p == &reference {
                (ref_time, ref_frame.clone())
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
                truth: truth::error(&frame.image, &truth),
            };
            log(&row_line(&row));
            rows.push(row);
        }
    }
    Ok((rows, notes))
}

/// The rows of one scene that form its ladder: the packet-path profiles, in the order
/// measured.
pub fn ladder<'a>(rows: &'a [Row], scene: &str, size: u32) -> Vec<&'a Row> {
    rows.iter()
        .filter(|r| r.scene == scene && r.size == size && r.path == RenderPath::Packet)
        .collect()
}

/// Where a scene's ladder is not monotone (a step that is not both slower and closer
/// to the true picture), one phrase per such step.
pub fn ladder_breaks(ladder: &[&Row]) -> Vec<String> {
    ladder
        .windows(2)
        .filter_map(|w| {
            let (a, b) = (w[0], w[1]);
            let slower = b.seconds > a.seconds;
            let closer = b.truth.psnr_db > a.truth.psnr_db;
            (!(slower && closer)).then(|| {
                let mut why = Vec::new();
                if !slower {
                    why.push(format!(
                        "not slower ({:.1} ms after {:.1} ms)",
                        b.seconds * 1e3,
                        a.seconds * 1e3
                    ));
                }
                if !closer {
                    why.push(format!(
                        "not closer ({:.1} dB after {:.1} dB)",
                        b.truth.psnr_db, a.truth.psnr_db
                    ));
                }
                format!("{} → {}: {}", a.profile, b.profile, why.join(", "))
            })
        })
        .collect()
}

/// A row as one log line.
fn row_line(r: &Row) -> String {
    format!(
        "{:<24} {:>4} {:<10} {:>9.1} ms {:>7.2} Mrays/s  true: {:>5.1} dB max {:>5.1} >8/255 {:>6.2}%  spec: {:>6} dB >8/255 unmasked {:>6}%",
        r.scene,
        r.size,
        r.profile,
        r.seconds * 1e3,
        r.mrays_per_s(),
        r.truth.psnr_db,
        r.truth.max,
        r.truth.over8_pct,
        psnr(&r.diff),
        pct(&r.diff, r.diff.off8_unmasked)
    )
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

/// Everything the Markdown report shows.
pub struct Report<'a> {
    pub rows: &'a [Row],
    /// The given scene at full size.
    pub headline: &'a [Row],
    pub costs: &'a [FeatureRow],
    /// (scene, its features).
    pub scene_features: &'a [(String, String)],
    pub truths: &'a [TruthNote],
    pub command: &'a str,
    pub plot: Option<&'a Path>,
}

/// The Markdown report.
pub fn markdown(r: &Report) -> String {
    let mut md = String::new();
    let plot = r.plot.map_or_else(
        || "none written".to_string(),
        |p| format!("`{}`", p.display()),
    );
    let _ = writeln!(md, "# Speed/accuracy trade-off of the profiles\n");
    let n = r.truths.first().map_or(truth::TRUTH_SAMPLES, |t| t.samples);
    let threads = crate::parallel::threads();
    let _ = writeln!(
        md,
        "Written by `{}` on {threads} threads (the machine is shared: times are indicative). \
         Time: median of {REPS} wall-clock renders of `Profile::render`, per-scene preparation \
         included (BVH build, prism photon map).\n\n\
         **true**: against the true picture, each pixel's area average ({n}×{n} stratified \
         samples per pixel on the reference path, linear, not quantized): PSNR over RGB, the \
         largest channel error and % of pixels off by more than 8/255 in some channel. This \
         is the error a user sees, aliasing included.\n\n\
         **spec**: against `reference`, the spec's one-sample image: PSNR, the largest channel \
         difference and % of pixels off by more than 8/255 outside the masks of legitimate \
         differences (silhouettes from the reference's primary-hit ids, edges where the \
         reference jumps by more than 24/255 to a neighbour). Supersampled profiles differ \
         from it by design.\n\n\
         Plot: {plot} (PSNR against the true picture versus time, one line per scene through \
         its profiles).\n",
        r.command
    );
    let table = |md: &mut String, rows: &[Row]| {
        let _ = writeln!(
            md,
            "| scene | size | profile | path | time ms | Mrays/s | speed-up | true PSNR dB | true max | true >8 % | spec PSNR dB | spec max | spec >8 % unmasked | quadric tests | cone tests | mirror rays |"
        );
        let _ = writeln!(
            md,
            "|---|---|---|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|"
        );
        for r in rows {
            let d = &r.diff;
            let _ = writeln!(
                md,
                "| {} | {} | {} | {} | {:.1} | {:.2} | {:.1}× | {:.1} | {:.0} | {:.2} | {} | {} | {} | {} | {} | {} |",
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
                r.truth.psnr_db,
                r.truth.max,
                r.truth.over8_pct,
                psnr(d),
                d.max_diff,
                pct(d, d.off8_unmasked),
                counted(r.path, r.stats.quadric_tests),
                counted(r.path, r.stats.cone_tests),
                r.stats.reflection_rays,
            );
        }
    };
    if !r.headline.is_empty() {
        let _ = writeln!(md, "## The given scene at full size\n");
        table(&mut md, r.headline);
        md.push('\n');
    }
    let _ = writeln!(md, "## Every scene\n");
    table(&mut md, r.rows);
    md.push('\n');
    ladder_section(&mut md, r.headline, r.rows);
    if !r.truths.is_empty() {
        let _ = writeln!(md, "True pictures:\n");
        for t in r.truths {
            let _ = writeln!(md, "- {}", t.line());
        }
        md.push('\n');
    }
    if !r.scene_features.is_empty() {
        let _ = writeln!(
            md,
            "Scene features (quadric objects, spotlights, recursion level): {}.\n",
            r.scene_features
                .iter()
                .map(|(s, f)| format!("{s}: {f}"))
                .collect::<Vec<_>>()
                .join("; ")
        );
    }
    if !r.costs.is_empty() {
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
        for (i, c) in r.costs.iter().enumerate() {
            if i == 0 || c.profile != r.costs[i - 1].profile {
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

/// Each scene's (and size's) ladder: monotone, or where it breaks.
fn ladder_section(md: &mut String, headline: &[Row], rows: &[Row]) {
    let all: Vec<Row> = headline.iter().chain(rows).cloned().collect();
    let mut seen: Vec<(&str, u32)> = Vec::new();
    let mut lines = Vec::new();
    for r in &all {
        if seen.contains(&(r.scene.as_str(), r.size)) {
            continue;
        }
        seen.push((&r.scene, r.size));
        let ladder = ladder(&all, &r.scene, r.size);
        if ladder.len() < 2 {
            continue;
        }
        let names: Vec<&str> = ladder.iter().map(|r| r.profile.as_str()).collect();
        let breaks = ladder_breaks(&ladder);
        lines.push(if breaks.is_empty() {
            format!("- {} {}: monotone ({})", r.scene, r.size, names.join(" → "))
        } else {
            format!(
                "- {} {}: **not monotone**: {}",
                r.scene,
                r.size,
                breaks.join("; ")
            )
        });
    }
    if lines.is_empty() {
        return;
    }
    let _ = writeln!(
        md,
        "## The ladder\n\nThe packet-path profiles in the order measured, each to be slower and closer to the true picture than the one before:\n"
    );
    for l in lines {
        let _ = writeln!(md, "{l}");
    }
    md.push('\n');
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
    pub camera: Camera,
    /// Where true pictures are cached ([`truth::default_cache_dir`]).
    pub truth_cache: PathBuf,
    /// Samples per pixel along each axis of the true pictures.
    pub truth_samples: u32,
    pub markdown: Option<PathBuf>,
    /// The plot, an SVG file.
    pub plot: Option<PathBuf>,
    pub command: String,
}

pub fn run(opts: &Options, log: &mut dyn FnMut(&str)) -> Result<String, TradeoffError> {
    // the outputs' names and places, before minutes of measurements
    for (path, option) in [(&opts.markdown, "--markdown"), (&opts.plot, "--plot")] {
        if let Some(p) = path {
            crate::output::check_output(p, false)
                .map_err(|e| TradeoffError::Input(format!("{option}: {e}")))?;
        }
    }
    if let Some(p) = &opts.plot
        && !p.extension().is_some_and(|e| e.eq_ignore_ascii_case("svg"))
    {
        return Err(TradeoffError::Input(format!(
            "--plot: {}: the plot is an SVG file (name it .svg)",
            p.display()
        )));
    }
    if let (Some(m), Some(p)) = (&opts.markdown, &opts.plot)
        && crate::output::same_file(m, p)
    {
        return Err(TradeoffError::Input(format!(
            "--markdown and --plot name the same file: {}",
            p.display()
        )));
    }
    let setup = |size| Setup {
        size,
        camera: opts.camera,
        truth_cache: opts.truth_cache.clone(),
        truth_samples: opts.truth_samples,
    };
    let given = opts
        .scenes
        .iter()
        .find(|p| p.file_stem().is_some_and(|s| s == "given"));
    let (headline, mut truths) = match given {
        Some(g) if opts.headline_size > 0 => measure(
            std::slice::from_ref(g),
            &opts.profiles,
            &setup(opts.headline_size),
            log,
        )?,
        _ => Default::default(),
    };
    let (rows, more) = measure(&opts.scenes, &opts.profiles, &setup(opts.size), log)?;
    truths.extend(more);
    let mut scene_features = Vec::new();
    for p in &opts.scenes {
        let scene = parse_scene_file(p)
            .map_err(|e| TradeoffError::Input(e.to_string()))?
            .scene;
        scene_features.push((scene_name(p), features(&scene)));
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
    let md = markdown(&Report {
        rows: &rows,
        headline: &headline,
        costs: &costs,
        scene_features: &scene_features,
        truths: &truths,
        command: &opts.command,
        plot: opts.plot.as_deref(),
    });
    // whole or not at all (an existing file stays as it was on failure)
    if let Some(path) = &opts.markdown {
        crate::output::write_atomic(path, md.as_bytes())?;
    }
    if let Some(path) = &opts.plot {
        let mut all = headline.clone();
        all.extend(rows.iter().cloned());
        crate::output::write_atomic(path, plot::svg(&all).as_bytes())?;
    }
    Ok(md)
}
