//! The `octaray` command line: parses arguments, calls the library, maps errors to
//! exit codes (2 for bad input, 1 for failures while writing).

use octaray::simd::Isa;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use clap::{Args, Parser, Subcommand};
use glam::DVec3;

use octaray::farm::FramePattern;
use octaray::farm::Piece;
use octaray::farm::digest::FrameDigest;
use octaray::output::tile::TileMeta;
use octaray::output::{
    check_output, check_output_dir, is_png, same_file, write_image, write_next_output, write_tile,
};
use octaray::render::profile::Profile;
use octaray::render::{PixelRect, RenderSettings};
use octaray::scene::parse::{
    MAX_PIXELS, Parsed, parse_scene, parse_scene_file, parse_scene_reader,
};
use octaray::scene::{Camera, Scene};
use octaray::viewer;

/// A line to stderr; a closed or full stderr is no reason to fail (`eprintln!`
/// panics on it, exit 101).
macro_rules! say {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stderr(), $($t)*);
    }};
}

/// A line to stdout: as [`say`] (a closed pipe, `| head -c0`, or /dev/full).
macro_rules! out {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stdout(), $($t)*);
    }};
}

#[derive(Parser, Debug)]
#[command(
    name = "octaray",
    version,
    about = "A CPU ray tracer for the CSE410 scene format. With no command: render the built-in scene."
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Render a scene file to BMP or PNG: the whole frame, a piece of it (--tile,
    /// --crop) or the frames of a camera path (--camera-path).
    Render(RenderArgs),
    /// Put the PNG pieces of a frame (render --tile/--crop -o NAME.png) back together.
    Assemble(AssembleArgs),
    /// Trace benchmark on an OBJ mesh: load, BVH build, closest-hit and shadow (any-hit)
    /// rays on the packet and single-ray paths, the work the Embree comparison of
    /// benches/embree/ measures.
    BenchTrace(BenchTraceArgs),
    /// Fly through a scene in a window, ray traced live (keys in the title bar).
    View(ViewArgs),
    /// Measure each profile: time, and error against the true picture (each pixel's area
    /// average) and against the spec's one-sample image. Without scene files: every
    /// scenes/*.txt, written to profiles/TRADEOFF.md and profiles/tradeoff.svg; with scene
    /// files: to stdout, and to --markdown/--plot if given.
    Tradeoff(TradeoffArgs),
}

#[derive(Args, Debug)]
struct TradeoffArgs {
    /// Scene files [default: every scenes/*.txt, the project's own table].
    scenes: Vec<PathBuf>,
    /// Image side in pixels.
    #[arg(long, default_value_t = 256, value_parser = clap::value_parser!(u32).range(8..=4096))]
    size: u32,
    /// Side of the extra given-scene table (every profile; 0: none).
    #[arg(long, default_value_t = 768, value_parser = clap::value_parser!(u32).range(0..=4096))]
    given_size: u32,
    /// Profiles, comma-separated names or paths to .toml files; after `reference`, the
    /// ladder in order (each should be slower and closer to the true picture).
    #[arg(
        long,
        default_value = "reference,preview,fast,quality,accurate",
        value_delimiter = ','
    )]
    profiles: Vec<String>,
    /// Markdown report [default: profiles/TRADEOFF.md without scene files, else none:
    /// the report goes to stdout] ("-": none).
    #[arg(long)]
    markdown: Option<PathBuf>,
    /// Plot of the error against time, an .svg file [default: profiles/tradeoff.svg
    /// without scene files, else none] ("-": none).
    #[arg(long)]
    plot: Option<PathBuf>,
    /// Directory of cached true pictures [default: $XDG_CACHE_HOME/octaray/truth, or
    /// ~/.cache/octaray/truth].
    #[arg(long)]
    truth_cache: Option<PathBuf>,
    /// Samples per pixel along each axis of the true picture (the reference path; 16:
    /// 256 per pixel).
    #[arg(long, default_value_t = octaray::tradeoff::truth::TRUTH_SAMPLES, value_parser = clap::value_parser!(u32).range(8..=32))]
    truth_samples: u32,
    #[command(flatten)]
    camera: CameraArgs,
}

fn run_tradeoff(args: &TradeoffArgs) -> Result<(), Failure> {
    let profiles = args
        .profiles
        .iter()
        .map(|p| load_profile("--profiles", p))
        .collect::<Result<Vec<_>, _>>()?;
    let own = args.scenes.is_empty();
    let scenes = if own {
        octaray::tradeoff::default_scenes(Path::new("scenes"))
            .map_err(|e| Failure::input(e.to_string()))?
    } else {
        args.scenes.clone()
    };
    // the project's own table lands in profiles/; a user's only where asked
    let out = |given: &Option<PathBuf>, own_default: &str| match given {
        Some(p) if p.as_os_str() == "-" => None,
        Some(p) => Some(p.clone()),
        None => own.then(|| PathBuf::from(own_default)),
    };
    let camera = camera_of(&args.camera)?;
    let opts = octaray::tradeoff::Options {
        scenes,
        profiles,
        size: args.size,
        headline_size: args.given_size,
        camera,
        truth_cache: args
            .truth_cache
            .clone()
            .unwrap_or_else(octaray::tradeoff::truth::default_cache_dir),
        truth_samples: args.truth_samples,
        markdown: out(&args.markdown, "profiles/TRADEOFF.md"),
        plot: out(&args.plot, "profiles/tradeoff.svg"),
        command: std::iter::once("octaray".to_string())
            .chain(std::env::args().skip(1))
            .collect::<Vec<_>>()
            .join(" "),
    };
    let md = octaray::tradeoff::run(&opts, &mut |line| say!("{line}")).map_err(|e| match e {
        octaray::tradeoff::TradeoffError::Input(m) => Failure::input(m),
        e => Failure {
            code: 1,
            message: e.to_string(),
        },
    })?;
    out!("{md}");
    for (what, path) in [("report", &opts.markdown), ("plot", &opts.plot)] {
        if let Some(p) = path {
            say!("{what} written to {}", p.display());
        }
    }
    Ok(())
}

#[derive(Args, Debug)]
struct ViewArgs {
    /// Scene file (`-`: standard input); without it, the assignment's given scene
    /// built into the binary.
    scene: Option<PathBuf>,
    /// Render profile for the window and captures: a name (reference, preview, fast,
    /// quality, accurate; looked up in ./profiles/, else built in) or a path to a .toml
    /// file.
    /// [default: fast]
    #[arg(long)]
    profile: Option<String>,
    /// Profile of the frames below full resolution (while moving, and the refinement
    /// passes): a name or a path to a .toml file.
    #[arg(long, default_value = "preview")]
    preview_profile: String,
    /// Window size.
    #[arg(long, default_value = "768x768")]
    size: viewer::Size,
    /// Directory for captures (key 0): Output_11.bmp, Output_12.bmp, ...
    #[arg(long, default_value = ".")]
    out_dir: PathBuf,
    /// Benchmark: render N frames along a scripted flight without a window and print fps.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=1_000_000))]
    frames: Option<u32>,
    /// Append the camera of every frame drawn to this camera path file (one line per
    /// camera: eye, look-at, up, fov), for `octaray render --camera-path`.
    #[arg(long, value_name = "PATH.txt")]
    record: Option<PathBuf>,
    /// Instruction set of the packet kernels, for the window and captures: auto,
    /// avx2 or avx512, as `octaray render --isa` (default: OCTARAY_ISA, else auto).
    #[arg(long, value_name = "auto|avx2|avx512")]
    isa: Option<String>,
}

#[derive(Args, Debug, Default)]
struct RenderArgs {
    /// Scene file (`-`: standard input); without it, the assignment's given scene
    /// built into the binary.
    scene: Option<PathBuf>,
    /// Output file (.bmp or .png, replaced atomically); default: the next free Output_1N.bmp.
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Image size: a side in pixels (square) or WIDTHxHEIGHT such as 3840x2160
    /// (default: the scene's `pixels`, square). The field of view is vertical.
    #[arg(long, value_parser = parse_render_size)]
    size: Option<viewer::Size>,
    #[command(flatten)]
    camera: CameraArgs,
    /// Render profile: a name (reference, preview, fast, quality, accurate; looked up
    /// in ./profiles/, else built in) or a path to a .toml file.
    #[arg(long, default_value = Profile::default_name())]
    profile: String,
    /// Worker threads [default: one per core].
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=1024))]
    threads: Option<u32>,
    /// Render only tile I of N (I from 0): every N-th of N x m stripes of rows (up to 16
    /// per tile; 48 rows high at least under an adaptive profile), so that tiles take
    /// about the same time. A PNG tile records where it belongs, for `octaray assemble`.
    #[arg(long, value_name = "I/N", value_parser = octaray::farm::parse_tile, conflicts_with = "crop")]
    tile: Option<(u32, u32)>,
    /// Render only the pixels [X0,X1) x [Y0,Y1) of the frame (recorded in a PNG, as --tile).
    #[arg(long, value_name = "X0,X1,Y0,Y1", value_parser = octaray::farm::parse_crop)]
    crop: Option<PixelRect>,
    /// Render the frames of a camera path (one camera a line: eye, look-at, up, fov)
    /// to the names of `-o PATTERN` (printf-style, e.g. 'frames/f_%04d.png').
    #[arg(
        long,
        value_name = "PATH.txt",
        conflicts_with_all = ["eye", "look_at", "up", "fov", "tile", "crop"]
    )]
    camera_path: Option<PathBuf>,
    /// Frames A to B of the camera path (from 0, inclusive), or one frame A [default: all].
    #[arg(long, value_name = "A..B", value_parser = octaray::farm::parse_frames, requires = "camera_path")]
    frames: Option<(u32, u32)>,
    /// Leave outputs that exist alone (a requeued job resumes where it stopped).
    #[arg(long, requires = "output")]
    skip_existing: bool,
    /// Instruction set of the packet kernels: auto (the widest this CPU runs), avx2
    /// (8-lane packets) or avx512 (camera rays in 16-lane packets); the image is the
    /// same under each. Default: the OCTARAY_ISA environment variable, else auto
    /// (OCTARAY_ISA, when set, must name one of these for every command).
    #[arg(long, value_name = "auto|avx2|avx512")]
    isa: Option<String>,
}

#[derive(Args, Debug)]
struct AssembleArgs {
    /// The pieces: PNG files written by `octaray render --tile I/N` (or --crop) `-o NAME.png`,
    /// in any order.
    #[arg(required = true, value_name = "TILE")]
    tiles: Vec<PathBuf>,
    /// The frame: .png (recording its settings, as a whole render does) or .bmp; replaced
    /// atomically.
    #[arg(short, long)]
    output: PathBuf,
}

#[derive(Args, Debug)]
struct BenchTraceArgs {
    /// OBJ mesh: the standard tori torus100k.obj and torus1m.obj are written by
    /// benches/embree/gen_data.py (benches/embree/run.sh writes them to
    /// /tmp/embree-peer/data).
    mesh: PathBuf,
    /// Worker threads.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=1024))]
    threads: u32,
    /// Trace repetitions (the best is reported).
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(1..=1000))]
    reps: u32,
    /// Instruction set of the kernels: auto (the widest this CPU runs), avx2 (8-lane
    /// packets) or avx512 (adds the 16-lane packets, mode=16 and mode=64); default: the
    /// OCTARAY_ISA environment variable, else auto (OCTARAY_ISA, when set, must name
    /// one of these for every command).
    #[arg(long, value_name = "auto|avx2|avx512")]
    isa: Option<String>,
    /// Trace the rays of DIR/primary.rays and DIR/incoherent.rays, the Embree harness's
    /// files (benches/embree/gen_data.py writes them beside the meshes), instead of
    /// generating the same distributions here: every line then traces the very rays
    /// Embree traces, and hit fractions and mean t compare ray for ray.
    #[arg(long, value_name = "DIR")]
    rays: Option<PathBuf>,
}

/// The instruction set chosen by `--isa`, else by `OCTARAY_ISA`, else the widest the
/// CPU runs; an unknown name or one this CPU cannot run is an input error naming where
/// it came from.
fn chosen_isa(flag: Option<&str>) -> Result<Isa, Failure> {
    match flag {
        Some(name) => Isa::parse(name).map_err(|e| Failure::input(format!("--isa: {e}"))),
        None => Isa::from_env()
            .map(|i| i.unwrap_or_else(Isa::detect))
            .map_err(|e| Failure::input(format!("{}: {e}", octaray::simd::isa::ENV))),
    }
}

fn run_bench_trace(args: &BenchTraceArgs) -> Result<(), Failure> {
    let isa = chosen_isa(args.isa.as_deref())?;
    octaray::bvh::bench::run(
        &args.mesh,
        args.rays.as_deref(),
        isa,
        args.threads as usize,
        args.reps as usize,
        &mut std::io::stdout(),
        &mut std::io::stderr(),
    )
    .map(|_| ())
    .map_err(|e| Failure::input(e.to_string()))
}

fn parse_vec3(s: &str) -> Result<DVec3, String> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    if parts.len() != 3 {
        return Err(format!("expected X,Y,Z, got '{s}'"));
    }
    let mut v = [0.0; 3];
    for (out, p) in v.iter_mut().zip(&parts) {
        *out = p
            .parse::<f64>()
            .ok()
            .filter(|x| x.is_finite())
            .ok_or_else(|| format!("'{p}' is not a finite number"))?;
    }
    Ok(DVec3::from(v))
}

fn parse_fov(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) if v > 0.0 && v < 180.0 => Ok(v),
        _ => Err(format!(
            "expected a field of view in (0, 180) degrees, got '{s}'"
        )),
    }
}

/// A failure and its exit code.
struct Failure {
    code: u8,
    message: String,
}

impl Failure {
    fn input(message: impl Into<String>) -> Failure {
        Failure {
            code: 2,
            message: message.into(),
        }
    }
}

fn load(path: Option<&Path>) -> Result<(Parsed, String), Failure> {
    let (parsed, name) = match path {
        // `-`: standard input
        Some(p) if p.as_os_str() == "-" => (
            parse_scene_reader(std::io::stdin().lock(), "<stdin>"),
            "<stdin>".to_string(),
        ),
        Some(p) => (parse_scene_file(p), p.display().to_string()),
        None => (
            parse_scene(Scene::GIVEN, "<built-in given scene>"),
            "<built-in given scene>".to_string(),
        ),
    };
    let parsed = parsed.map_err(|e| Failure::input(e.to_string()))?;
    for w in &parsed.warnings {
        say!("{w}");
    }
    Ok((parsed, name))
}

/// `--profile NAME|PATH` (or another `option`); errors (file:line:column, key) exit
/// with code 2.
fn load_profile(option: &str, spec: &str) -> Result<Profile, Failure> {
    Profile::load(spec).map_err(|e| Failure::input(format!("{option}: {e}")))
}

/// `--eye`, `--look-at`, `--up` and `--fov` (of `render` and `tradeoff`).
#[derive(Args, Debug, Clone, Copy)]
struct CameraArgs {
    /// Eye position [default: 100,100,50].
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    eye: Option<DVec3>,
    /// Point to look at [default: look along (-1,-1,0)].
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    look_at: Option<DVec3>,
    /// Up hint [default: 0,0,1].
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    up: Option<DVec3>,
    /// Vertical field of view in degrees.
    #[arg(long, default_value_t = DEFAULT_FOV, value_parser = parse_fov)]
    fov: f64,
}

/// `--fov` when none is given (the assignment's camera).
const DEFAULT_FOV: f64 = 80.0;

impl Default for CameraArgs {
    fn default() -> Self {
        CameraArgs {
            eye: None,
            look_at: None,
            up: None,
            fov: DEFAULT_FOV,
        }
    }
}

fn camera(args: &RenderArgs) -> Result<Camera, Failure> {
    camera_of(&args.camera)
}

/// The camera of `--eye`, `--look-at`, `--up` and `--fov`.
fn camera_of(args: &CameraArgs) -> Result<Camera, Failure> {
    let CameraArgs {
        eye,
        look_at,
        up,
        fov,
    } = *args;
    let default = Camera::default();
    let eye = eye.unwrap_or(default.eye);
    let up = up.unwrap_or(default.up);
    let camera = match look_at {
        Some(target) => Camera::look_at(eye, target, up, fov),
        None => Camera::from_look(eye, default.look, up, fov),
    };
    camera.ok_or_else(|| {
        let look = look_at.map_or(default.look, |t| t - eye);
        Failure::input(if !look.is_finite() {
            "--eye/--look-at: the view direction overflows (the points are too far apart)"
        } else if look == DVec3::ZERO {
            "--eye/--look-at: the view direction is zero (the eye is the point looked at)"
        } else {
            "--up: parallel to the view direction (or zero)"
        })
    })
}

/// `--size N` (square) or `--size WxH`.
fn parse_render_size(s: &str) -> Result<viewer::Size, String> {
    if s.contains(['x', 'X']) {
        return s.parse();
    }
    let n: u32 = s
        .trim()
        .parse()
        .ok()
        .filter(|&v| (1..=MAX_PIXELS).contains(&i64::from(v)))
        .ok_or_else(|| {
            format!("'{s}' is not a size in 1..={MAX_PIXELS} pixels (or WIDTHxHEIGHT)")
        })?;
    Ok(viewer::Size {
        width: n,
        height: n,
    })
}

/// The scene of `render` with its name and the image size: `--size`, else the scene's
/// `pixels` (refused where that is over the limit).
fn load_sized(args: &RenderArgs) -> Result<(Scene, String, viewer::Size), Failure> {
    let (parsed, name) = load(args.scene.as_deref())?;
    if let (None, Some(e)) = (args.size, &parsed.too_large) {
        return Err(Failure::input(e.to_string()));
    }
    let scene = parsed.scene;
    let size = args.size.unwrap_or(viewer::Size {
        width: scene.pixels,
        height: scene.pixels,
    });
    Ok((scene, name, size))
}

fn run_render(args: &RenderArgs) -> Result<(), Failure> {
    if args.camera_path.is_some() {
        return run_frames(args);
    }
    // where the image goes, before the render's time is spent
    match &args.output {
        Some(path) => {
            check_output(path, true).map_err(|e| Failure::input(format!("--output: {e}")))?
        }
        None => check_output_dir(Path::new(".")).map_err(|e| {
            Failure::input(format!(
                "cannot write the image in the current directory: {e}"
            ))
        })?,
    }
    if let (true, Some(path)) = (args.skip_existing, &args.output)
        && exists(path)
    {
        say!(
            "octaray: {} exists, left alone (--skip-existing)",
            path.display()
        );
        return Ok(());
    }
    let (scene, name, size) = load_sized(args)?;
    let settings = RenderSettings {
        width: size.width,
        height: size.height,
        camera: camera(args)?,
        crop: None,
        threads: args.threads.map(|t| t as usize),
        progress: true,
    };
    let mut profile = load_profile("--profile", &args.profile)?;
    profile.packet.isa = chosen_isa(args.isa.as_deref())?;
    let rects = piece(args, size, profile.sampler().min_stripe_rows())?;
    warn_caustic_pairs(&scene, &profile);
    if rects.is_some() && !args.output.as_deref().is_some_and(is_png) {
        say!(
            "octaray: warning: only a .png piece records where it belongs (for `octaray assemble`)"
        );
    }
    let full = [PixelRect::full(size.width, size.height)];
    let frame = render_frame(
        &scene,
        &profile,
        &settings,
        rects.as_deref().unwrap_or(&full),
    );
    let start = std::time::Instant::now();
    let written = match &args.output {
        Some(path) => write_frame(&frame.piece, path, &scene, &profile, &settings, args.tile),
        None => write_next_output(&frame.piece.image, Path::new(".")).map_err(|e| Failure {
            code: 1,
            message: e.to_string(),
        }),
    }?;
    say!(
        "{name}: {}, profile {}, isa {}, {} threads: {} -> {}",
        describe_piece(&settings, &frame.piece, args.tile),
        args.profile,
        profile.packet.isa,
        threads_used(args.threads),
        frame.summary(start.elapsed().as_secs_f64()),
        written.display()
    );
    Ok(())
}

/// Whether anything of that name exists (a dangling symbolic link counts).
fn exists(path: &Path) -> bool {
    std::fs::symlink_metadata(path).is_ok()
}

fn threads_used(threads: Option<u32>) -> String {
    threads.map_or_else(
        || octaray::parallel::threads().to_string(),
        |t| t.to_string(),
    )
}

/// The rectangles of `--tile` (stripes `min_rows` high at least) or `--crop` in a frame
/// of `size` (`None`: the whole frame).
fn piece(
    args: &RenderArgs,
    size: viewer::Size,
    min_rows: u32,
) -> Result<Option<Vec<PixelRect>>, Failure> {
    let (w, h) = (size.width, size.height);
    if let Some((i, n)) = args.tile {
        return octaray::farm::tile_rects(i, n, (w, h), min_rows)
            .map(Some)
            .map_err(|e| Failure::input(format!("--tile {i}/{n}: {e}")));
    }
    args.crop
        .map(|crop| octaray::farm::check_crop(crop, w, h).map(|r| vec![r]))
        .transpose()
        .map_err(|e| Failure::input(format!("--crop: {e}")))
}

/// `1920x1080`, `1920x1080, crop 0,100,0,50` or `1920x1080, tile 3/8 (16 stripes, 135 rows)`.
fn describe_piece(settings: &RenderSettings, piece: &Piece, tile: Option<(u32, u32)>) -> String {
    let mut out = format!("{}x{}", settings.width, settings.height);
    match (tile, &piece.rects[..]) {
        (Some((i, n)), rects) => {
            let stripes = if rects.len() == 1 {
                "stripe"
            } else {
                "stripes"
            };
            out += &format!(
                ", tile {i}/{n} ({} {stripes}, {} rows)",
                rects.len(),
                piece.image.height
            )
        }
        (None, [r]) if *r != PixelRect::full(settings.width, settings.height) => {
            out += &format!(", crop {},{},{},{}", r.x0, r.x1, r.y0, r.y1)
        }
        _ => {}
    }
    out
}

/// A rendered frame (or piece) and where its time went.
struct Frame {
    piece: Piece,
    /// Building the BVH and photon map for the frame's eye (for a frame that keeps an
    /// earlier frame's, only choosing its f32 frame).
    prepare_s: f64,
    render_s: f64,
    /// The frame of a camera path whose preparation this one used, when not its own.
    kept_from: Option<u32>,
}

impl Frame {
    /// Times (and `write_s`, encoding and writing the image) and rays.
    fn summary(&self, write_s: f64) -> String {
        let s = &self.piece.stats;
        let secs = self.prepare_s + self.render_s;
        let prepare = match self.kept_from {
            Some(k) => format!("prepared with frame {k}"),
            None => format!("prepare {:.3} s", self.prepare_s),
        };
        format!(
            "{secs:.3} s ({prepare}, render {:.3} s; write {write_s:.3} s), {:.2} M rays ({} primary, {} shadow, {} reflection), {:.2} Mrays/s",
            self.render_s,
            s.total_rays() as f64 / 1e6,
            s.primary_rays,
            s.shadow_rays,
            s.reflection_rays,
            s.total_rays() as f64 / 1e6 / secs.max(1e-9),
        )
    }
}

/// Prepares `scene` in the f32 frame `frame_origin` picks for the camera's eye (as every
/// one-process render does, so that pieces equal the whole frame) and renders the
/// rectangles `rects` of the frame `settings` describes.
fn render_frame(
    scene: &octaray::scene::Scene,
    profile: &Profile,
    settings: &RenderSettings,
    rects: &[PixelRect],
) -> Frame {
    render_kept(scene, profile, settings, rects, &mut None, 0)
}

/// A scene prepared for a frame of a camera path, and that frame's number.
type Kept<'a> = Option<(octaray::render::prepared::Prepared<'a>, u32)>;

/// [`render_frame`] of frame `frame` of a camera path with the preparation of an earlier
/// frame, `kept`, when it is what this frame's would be: the packet path's in the same
/// f32 frame (`frame_origin`: a mesh of f32 vertices near the world origin keeps the
/// world origin along a whole path), or the reference's, which has none. Otherwise the
/// scene is prepared anew and kept in its place, the old one dropped first (one prepared
/// scene in memory at a time).
fn render_kept<'a>(
    scene: &'a octaray::scene::Scene,
    profile: &Profile,
    settings: &RenderSettings,
    rects: &[PixelRect],
    kept: &mut Kept<'a>,
    frame: u32,
) -> Frame {
    let start = std::time::Instant::now();
    let origin = octaray::render::prepared::frame_origin(scene, settings.camera.eye);
    let kept_from = match kept {
        Some((p, k)) if p.origin().is_none_or(|o| o == origin) => Some(*k),
        _ => {
            *kept = None;
            *kept = Some((profile.prepare(scene, origin), frame));
            None
        }
    };
    let (prepared, _) = kept.as_ref().expect("prepared above");
    let prepare_s = start.elapsed().as_secs_f64();
    let piece = octaray::farm::render_piece(prepared, settings, rects);
    let render_s = start.elapsed().as_secs_f64() - prepare_s;
    if kept_from.is_none() {
        warn_f32_detail(scene, prepared);
    }
    Frame {
        piece,
        prepare_s,
        render_s,
        kept_from,
    }
}

/// Writes a frame or piece to `path`; a PNG records the frame size, the piece's rectangle
/// and the digest of the scene and settings ([`octaray::output::tile`]).
fn write_frame(
    piece: &Piece,
    path: &Path,
    scene: &octaray::scene::Scene,
    profile: &Profile,
    settings: &RenderSettings,
    tile: Option<(u32, u32)>,
) -> Result<PathBuf, Failure> {
    let written = if is_png(path) {
        let d = FrameDigest::new(
            scene,
            &settings.camera,
            settings.width,
            settings.height,
            profile,
        );
        let meta = TileMeta {
            frame: (settings.width, settings.height),
            rects: piece
                .rects
                .iter()
                .map(|r| [r.x0, r.x1, r.y0, r.y1])
                .collect(),
            tile,
            digest: d.digest,
            settings: d.settings,
        };
        write_tile(&piece.image, path, &meta)
    } else {
        write_image(&piece.image, path)
    };
    written.map(|()| path.to_path_buf()).map_err(|e| Failure {
        code: 1,
        message: e.to_string(),
    })
}

/// `render --camera-path PATH.txt [--frames A..B] -o PATTERN`: each frame prepared at its
/// own eye and rendered as `render --eye --look-at --up --fov` of its line renders it.
/// Everything is checked before the first frame.
fn run_frames(args: &RenderArgs) -> Result<(), Failure> {
    let path_file = args
        .camera_path
        .as_deref()
        .expect("called with a camera path");
    let pattern_text = args
        .output
        .as_deref()
        .ok_or_else(|| {
            Failure::input("--camera-path: give the frames' names with -o PATTERN, e.g. -o 'frames/f_%04d.png'")
        })?
        .to_string_lossy()
        .into_owned();
    let pattern =
        FramePattern::parse(&pattern_text).map_err(|e| Failure::input(format!("--output: {e}")))?;
    let cameras = octaray::scene::camera_path::read_camera_path(path_file)
        .map_err(|e| Failure::input(e.to_string()))?;
    let whole = (0, cameras.len().saturating_sub(1) as u32);
    let (first, last) = octaray::farm::check_frames(args.frames.unwrap_or(whole), cameras.len())
        .map_err(|e| Failure::input(format!("--frames: {}: {e}", path_file.display())))?;
    check_output(&pattern.name(first), true)
        .map_err(|e| Failure::input(format!("--output: {e}")))?;
    let (scene, name, size) = load_sized(args)?;
    let mut profile = load_profile("--profile", &args.profile)?;
    profile.packet.isa = chosen_isa(args.isa.as_deref())?;
    let mut kept: Kept = None;
    for k in first..=last {
        let out = pattern.name(k);
        if args.skip_existing && exists(&out) {
            say!(
                "frame {k}: {} exists, left alone (--skip-existing)",
                out.display()
            );
            continue;
        }
        let camera = &cameras[k as usize];
        let settings = RenderSettings {
            width: size.width,
            height: size.height,
            camera: camera.camera(),
            crop: None,
            threads: args.threads.map(|t| t as usize),
            progress: true,
        };
        let full = [PixelRect::full(size.width, size.height)];
        let frame = render_kept(&scene, &profile, &settings, &full, &mut kept, k);
        let start = std::time::Instant::now();
        write_frame(&frame.piece, &out, &scene, &profile, &settings, None)?;
        say!(
            "{name}: frame {k} ({}:{}), {}x{}, profile {}, isa {}, {} threads: {} -> {}",
            path_file.display(),
            camera.line,
            size.width,
            size.height,
            args.profile,
            profile.packet.isa,
            threads_used(args.threads),
            frame.summary(start.elapsed().as_secs_f64()),
            out.display()
        );
    }
    Ok(())
}

/// `assemble TILE... -o OUT`: refuses (exit 2, naming the tile) pieces that are no tiles,
/// of other frames or settings, overlapping or leaving pixels uncovered.
fn run_assemble(args: &AssembleArgs) -> Result<(), Failure> {
    check_output(&args.output, true).map_err(|e| Failure::input(format!("--output: {e}")))?;
    if let Some(t) = args.tiles.iter().find(|t| same_file(t, &args.output)) {
        return Err(Failure::input(format!(
            "--output: {} is one of the tiles",
            t.display()
        )));
    }
    let start = std::time::Instant::now();
    let assembled = octaray::output::assemble::assemble(&args.tiles)
        .map_err(|e| Failure::input(format!("assemble: {e}")))?;
    let out = &args.output;
    let written = if is_png(out) {
        write_tile(&assembled.image, out, &assembled.meta)
    } else {
        write_image(&assembled.image, out)
    };
    written.map_err(|e| Failure {
        code: 1,
        message: e.to_string(),
    })?;
    say!(
        "assembled {} tiles into {}x{} in {:.3} s -> {}",
        args.tiles.len(),
        assembled.image.width,
        assembled.image.height,
        start.elapsed().as_secs_f64(),
        out.display()
    );
    Ok(())
}

/// The warning where a scene has more light-glass pairs than caustic photons.
fn warn_caustic_pairs(scene: &Scene, profile: &Profile) {
    if let Some(w) = octaray::render::caustic::pairs_warning(scene, profile.photons) {
        say!("{w}");
    }
}

/// The warning where the packet path's f32 loses the scene's smallest object: where the
/// fast path cannot hold, say so and name the profile that does.
fn warn_f32_detail(scene: &octaray::scene::Scene, prepared: &octaray::render::prepared::Prepared) {
    if let Some(d) = prepared.detail_below_f32() {
        say!("{}", d.warning(scene, &prepared.profile().name));
    }
}

fn run_view(args: &ViewArgs) -> Result<(), Failure> {
    let (parsed, name) = load(args.scene.as_deref())?;
    // captures are rendered at the scene's own size
    if let Some(e) = &parsed.too_large {
        return Err(Failure::input(e.to_string()));
    }
    let profile_name: &str = match &args.profile {
        Some(name) => name,
        None => viewer::default_profile_name(),
    };
    let isa = chosen_isa(args.isa.as_deref())?;
    let mut profile = load_profile("--profile", profile_name)?;
    profile.packet.isa = isa;
    warn_caustic_pairs(&parsed.scene, &profile);
    if let Some(frames) = args.frames {
        let mut record = open_record(args)?;
        let report = viewer::benchmark(&parsed.scene, &profile, args.size, frames, record.as_mut());
        out!("{name}: {report}");
        return Ok(());
    }
    if !args.out_dir.is_dir() {
        return Err(Failure::input(format!(
            "--out-dir: {} is not a directory",
            args.out_dir.display()
        )));
    }
    // The same camera `octaray render` uses by default, built the same way, so that a
    // capture before any key is pressed is the same image.
    let default = Camera::default();
    let camera = Camera::from_look(default.eye, default.look, default.up, default.fov_y_deg)
        .ok_or_else(|| Failure::input("camera: degenerate default camera"))?;
    let config = viewer::ViewConfig {
        scene: std::sync::Arc::new(parsed.scene),
        scene_name: name,
        capture_profile: profile.clone(),
        moving_profile: {
            let mut p = load_profile("--preview-profile", &args.preview_profile)?;
            p.packet.isa = isa;
            p
        },
        profile,
        size: args.size,
        out_dir: args.out_dir.clone(),
        camera,
    };
    let record = open_record(args)?;
    viewer::run(&config, record).map_err(|e| Failure {
        code: 1,
        message: e.to_string(),
    })
}

/// `view --record PATH.txt`, opened for appending once every other argument is checked.
fn open_record(args: &ViewArgs) -> Result<Option<viewer::Recorder>, Failure> {
    let Some(path) = args.record.as_deref() else {
        return Ok(None);
    };
    viewer::Recorder::open(path)
        .map(Some)
        .map_err(|e| Failure::input(format!("--record: {}: {e}", path.display())))
}

/// Makes an interrupted run (SIGINT, SIGTERM, SIGHUP) remove its temporary files and
/// then end by that signal, as if it had not been caught (a shell shows 130 for
/// Ctrl-C, 143 for SIGTERM), and with `--threads` sizes rayon's global pool, so that
/// the option bounds every parallel part (the frame, the photon pass, the image
/// encoder); a pool that cannot start then (a process limit) is an error, not a panic
/// in the first parallel loop. (Without `--threads` rayon starts its pool itself, lazily.)
fn start(threads: Option<u32>) -> Result<(), Failure> {
    catch_interrupts();
    // Without `--threads` rayon starts its pool at the first parallel loop, after the
    // scene is read (started here, its idle workers would spin through the serial start).
    // (there, should its threads not start, the frame runs on this thread alone)
    let Some(n) = threads else { return Ok(()) };
    octaray::parallel::start_pool(n as usize).map_err(|e| Failure {
        code: 1,
        message: format!("cannot start {n} worker threads: {e}"),
    })
}

/// Catches SIGINT, SIGTERM and SIGHUP on a thread of its own, which removes the
/// temporary files and then ends the process by the same signal. The signals are
/// caught only once that thread runs: where no thread can start (a process limit),
/// they would be caught with nothing behind them and the process would ignore
/// Ctrl-C, so there the default action stays (stop at once, no clean-up).
fn catch_interrupts() {
    use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
    let (send, receive) = std::sync::mpsc::channel::<signal_hook::iterator::Signals>();
    let watcher = std::thread::Builder::new()
        .name("signals".into())
        .spawn(move || {
            let Ok(mut signals) = receive.recv() else {
                return;
            };
            if let Some(signal) = signals.forever().next() {
                let _held = octaray::output::remove_temporaries();
                // the default action of these signals ends the process here
                let _ = signal_hook::low_level::emulate_default_handler(signal);
                std::process::exit(128 + signal);
            }
        });
    // a signal ignored by whoever started the process (`nohup`, a shell's background
    // job) stays ignored
    let ignored = ignored_signals();
    let caught = [SIGINT, SIGTERM, SIGHUP]
        .into_iter()
        .filter(|s| !ignored(*s));
    if watcher.is_ok()
        && let Ok(signals) = signal_hook::iterator::Signals::new(caught)
    {
        let _ = send.send(signals);
    }
}

/// Which signals this process was started ignoring: the `SigIgn` mask of
/// `/proc/self/status` (Linux; elsewhere none are taken as ignored).
fn ignored_signals() -> impl Fn(i32) -> bool {
    let mask = std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|status| {
            let line = status.lines().find_map(|l| l.strip_prefix("SigIgn:"))?;
            u64::from_str_radix(line.trim(), 16).ok()
        })
        .unwrap_or(0);
    move |signal| (1..=64).contains(&signal) && mask & (1 << (signal - 1)) != 0
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let threads = match &cli.command {
        Some(Command::Render(a)) => a.threads,
        Some(Command::BenchTrace(a)) => Some(a.threads),
        _ => None,
    };
    // an unusable OCTARAY_ISA is refused before anything reads it
    let isa_env = chosen_isa(None).map(|_| ());
    let result = isa_env
        .and_then(|()| start(threads))
        .and_then(|()| match cli.command {
            Some(Command::Render(args)) => run_render(&args),
            Some(Command::Assemble(args)) => run_assemble(&args),
            Some(Command::BenchTrace(args)) => run_bench_trace(&args),
            Some(Command::View(args)) => run_view(&args),
            Some(Command::Tradeoff(args)) => run_tradeoff(&args),
            None => run_render(&RenderArgs {
                profile: Profile::default_name().into(),
                ..RenderArgs::default()
            }),
        });
    if result.is_ok() && threads != Some(1) && octaray::parallel::serial() {
        say!(
            "octaray: warning: worker threads could not start (a process limit?); ran on one thread"
        );
    }
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(f) => {
            say!("octaray: {}", f.message);
            ExitCode::from(f.code)
        }
    }
}
