//! The live viewer: a minifb window that ray traces the scene continuously while the
//! assignment's keys fly the camera ([`flycam`]).
//!
//! Three threads, none of which waits for another:
//! - the **event loop** (the caller's thread) polls the window, moves the camera, submits a
//!   frame to the render worker whenever it is idle, and presents the latest finished
//!   frame, scaled up to the window;
//! - the **render worker** renders one preview frame at a time with the profile's
//!   renderer (which spreads it over rayon's pool);
//! - the **capture worker** renders captures (key 0) at the scene's full resolution and
//!   writes them with [`write_next_output`], in the order they were asked for.
//!
//! Resolution ([`Refiner`]): while the camera moves, each frame is rendered at the largest
//! fraction 1/d of the window's resolution expected to take at most [`MOVING_FRAME_S`]; once
//! the camera is still, d halves every frame until the full resolution is reached. A frame
//! in flight is not cancelled (renderers take no cancellation token), so a key pressed
//! during the full-resolution pass shows after that pass: at most one full frame late.
//!
//! [`benchmark`] runs the same policy along a scripted flight without a window
//! (`octaray view --frames 120`).
//!
//! [`Recorder`] (`--record PATH.txt`) appends the camera of every frame drawn as a camera
//! path line ([`crate::scene::camera_path`]), so that a flight can be rendered offline.
//!
//! Without a display (Debian packages xvfb, xdotool, imagemagick), as in
//! `tests/viewer_x11.rs` and for `docs/viewer.png`:
//! ```text
//! Xvfb :77 -screen 0 800x800x24 -nolisten tcp -noreset &
//! export DISPLAY=:77
//! octaray view --out-dir /tmp & sleep 3
//! xdotool windowfocus --sync "$(xdotool search --name '^octaray' | head -1)"
//! xdotool key 0                      # capture: /tmp/Output_11.bmp
//! xdotool keydown 1; sleep 0.5       # hold "look left": reduced resolution
//! import -window root moving.png; xdotool keyup 1
//! xdotool key Escape
//! ```
//! (minifb ignores events sent with `xdotool key --window`: focus the window instead.)

pub mod flycam;

use std::cell::RefCell;
use std::collections::VecDeque;
use std::fmt;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::rc::Rc;
use std::str::FromStr;
use std::sync::{Arc, mpsc};
use std::thread;
use std::time::{Duration, Instant};

use glam::DVec3;
use minifb::{Key, Window, WindowOptions};

use crate::output::{Framebuffer, write_next_output};
use crate::render::prepared::{Prepared, frame_origin};
use crate::render::profile::Profile;
use crate::render::{RenderSettings, RenderStats};
use crate::scene::{Camera, Scene};
use flycam::{FlyCam, Motion};

/// The profile the viewer uses when none is named: the first of these that exists.
/// Switching the viewer's default is this one line.
pub const PREFERRED_PROFILES: &[&str] = &["fast", "reference"];

/// The viewer's default profile name.
pub fn default_profile_name() -> &'static str {
    PREFERRED_PROFILES
        .iter()
        .copied()
        .find(|name| Profile::by_name(name).is_some())
        .unwrap_or_else(Profile::default_name)
}

/// Render time a moving frame aims for (40 fps, leaving headroom for the 30 fps bar).
pub const MOVING_FRAME_S: f64 = 1.0 / 40.0;
/// The coarsest preview: 1/16 of the window's resolution along each axis.
pub const MAX_DIVISOR: u32 = 16;

/// The keys, as the title bar lists them.
pub const KEY_HELP: &str = "arrows/PgUp/PgDn move, 1-6 turn, Shift fast, 0 capture, Esc quit";

/// A window size, `WxH` on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Size {
    pub width: u32,
    pub height: u32,
}

impl FromStr for Size {
    type Err = String;

    fn from_str(s: &str) -> Result<Size, String> {
        let bad = || format!("expected WIDTHxHEIGHT like 768x768, got '{s}'");
        let (w, h) = s.split_once(['x', 'X']).ok_or_else(bad)?;
        let dim = |t: &str| {
            t.trim()
                .parse::<u32>()
                .ok()
                .filter(|&v| (1..=crate::scene::parse::MAX_PIXELS).contains(&i64::from(v)))
                .ok_or_else(|| {
                    format!(
                        "'{t}' is not a size in 1..={} pixels",
                        crate::scene::parse::MAX_PIXELS
                    )
                })
        };
        Ok(Size {
            width: dim(w)?,
            height: dim(h)?,
        })
    }
}

impl fmt::Display for Size {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}x{}", self.width, self.height)
    }
}

/// Everything the viewer needs.
#[derive(Clone)]
pub struct ViewConfig {
    pub scene: Arc<Scene>,
    /// Shown in the title bar (its file name).
    pub scene_name: String,
    /// Renders the full-resolution frames of a still camera.
    pub profile: Profile,
    /// Renders the frames below full resolution (moving, and the refinement passes
    /// before full resolution): the `preview` profile by default.
    pub moving_profile: Profile,
    /// Renders captures (key 0) at the scene's resolution (`octaray render`'s image).
    pub capture_profile: Profile,
    /// Initial window size.
    pub size: Size,
    /// Where captures go.
    pub out_dir: PathBuf,
    /// The initial camera.
    pub camera: Camera,
}

#[derive(Debug, thiserror::Error)]
pub enum ViewerError {
    #[error("cannot open a window (is DISPLAY set?): {0}")]
    Window(String),
    #[error("cannot start the viewer's {0} thread: {1}")]
    Thread(&'static str, std::io::Error),
}

/// Maps a key to the camera motion it drives (the assignment's keys; the number-pad
/// digits work like the top-row ones).
pub fn motion_for_key(key: Key) -> Option<Motion> {
    Some(match key {
        Key::Up => Motion::Forward,
        Key::Down => Motion::Backward,
        Key::Left => Motion::Left,
        Key::Right => Motion::Right,
        Key::PageUp => Motion::Up,
        Key::PageDown => Motion::Down,
        Key::Key1 | Key::NumPad1 => Motion::LookLeft,
        Key::Key2 | Key::NumPad2 => Motion::LookRight,
        Key::Key3 | Key::NumPad3 => Motion::LookUp,
        Key::Key4 | Key::NumPad4 => Motion::LookDown,
        Key::Key5 | Key::NumPad5 => Motion::TiltClockwise,
        Key::Key6 | Key::NumPad6 => Motion::TiltCounterclockwise,
        _ => return None,
    })
}

fn is_capture_key(key: Key) -> bool {
    matches!(key, Key::Key0 | Key::NumPad0)
}

fn is_shift(key: Key) -> bool {
    matches!(key, Key::LeftShift | Key::RightShift)
}

/// The preview image size for a window of `w × h` at divisor `d` (at least 1 × 1).
pub fn preview_size(w: u32, h: u32, d: u32) -> (u32, u32) {
    let d = d.max(1);
    (w.div_ceil(d).max(1), h.div_ceil(d).max(1))
}

/// Picks preview resolutions from the measured cost of recent frames.
#[derive(Clone, Debug, Default)]
pub struct Refiner {
    /// Smoothed render seconds per pixel; `None` before the first frame.
    secs_per_pixel: Option<f64>,
}

impl Refiner {
    /// The divisor for a moving frame of a `w × h` window: the smallest d whose frame is
    /// expected to render within [`MOVING_FRAME_S`], or [`MAX_DIVISOR`]. Before any frame
    /// has been measured, 4.
    pub fn moving_divisor(&self, w: u32, h: u32) -> u32 {
        let Some(spp) = self.secs_per_pixel else {
            return 4.min(MAX_DIVISOR);
        };
        (1..=MAX_DIVISOR)
            .find(|&d| {
                let (pw, ph) = preview_size(w, h, d);
                pw as f64 * ph as f64 * spp <= MOVING_FRAME_S
            })
            .unwrap_or(MAX_DIVISOR)
    }

    /// The next divisor while the camera is still.
    pub fn refine(d: u32) -> u32 {
        (d / 2).max(1)
    }

    /// Records a finished frame of `pixels` pixels that took `elapsed`.
    pub fn observe(&mut self, pixels: u64, elapsed: Duration) {
        let spp = elapsed.as_secs_f64() / pixels.max(1) as f64;
        self.secs_per_pixel = Some(match self.secs_per_pixel {
            None => spp,
            Some(old) => 0.6 * old + 0.4 * spp,
        });
    }
}

/// A preview frame to render.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Job {
    camera: Camera,
    /// Window size.
    width: u32,
    height: u32,
    divisor: u32,
}

/// What the idle render worker should do next, given the last job it was given: the
/// current camera at a moving frame's resolution if the camera or the window changed since,
/// else the same view at twice the resolution, else nothing (full resolution is on screen).
fn next_job(
    last: Option<&Job>,
    camera: &Camera,
    size: (u32, u32),
    refiner: &Refiner,
) -> Option<Job> {
    match last {
        Some(job) if job.camera == *camera && (job.width, job.height) == size => (job.divisor > 1)
            .then(|| Job {
                divisor: Refiner::refine(job.divisor),
                ..*job
            }),
        _ => Some(Job {
            camera: *camera,
            width: size.0,
            height: size.1,
            divisor: refiner.moving_divisor(size.0, size.1),
        }),
    }
}

/// A finished preview frame.
struct Frame {
    job: Job,
    image: Framebuffer,
    stats: RenderStats,
}

/// A prepared profile whose f32 frame follows the camera ([`Prepared::follow`]), and the
/// nearest hit of its last frame.
struct View<'a> {
    prepared: Prepared<'a>,
    nearest: f64,
}

impl<'a> View<'a> {
    fn new(profile: &Profile, scene: &'a Scene, eye: DVec3) -> View<'a> {
        View {
            prepared: profile.prepare(scene, frame_origin(scene, eye)),
            nearest: f64::INFINITY,
        }
    }

    fn render(&mut self, job: &Job) -> Frame {
        self.prepared.follow(job.camera.eye, self.nearest);
        let frame = render_job(&self.prepared, job);
        self.nearest = frame.stats.nearest_hit;
        frame
    }
}

fn render_job(prepared: &Prepared, job: &Job) -> Frame {
    let (w, h) = preview_size(job.width, job.height, job.divisor);
    let settings = RenderSettings {
        width: w,
        height: h,
        camera: job.camera,
        crop: None,
        threads: None,
        progress: false,
    };
    let rendered = prepared.render(&settings);
    Frame {
        job: *job,
        image: rendered.image,
        stats: rendered.stats,
    }
}

/// Scales `image` up (nearest pixel) into a `w × h` window buffer of 0RGB words.
fn present_into(image: &Framebuffer, w: usize, h: usize, buffer: &mut Vec<u32>) {
    buffer.clear();
    buffer.resize(w * h, 0);
    if image.width == 0 || image.height == 0 || w == 0 || h == 0 {
        return;
    }
    let (iw, ih) = (image.width as usize, image.height as usize);
    let columns: Vec<usize> = (0..w).map(|x| (x * iw / w).min(iw - 1)).collect();
    for (y, row) in buffer.chunks_exact_mut(w).enumerate() {
        let src = &image.pixels[(y * ih / h).min(ih - 1) * iw..][..iw];
        for (out, &sx) in row.iter_mut().zip(&columns) {
            let [r, g, b] = src[sx];
            *out = (r as u32) << 16 | (g as u32) << 8 | b as u32;
        }
    }
}

/// A worker thread: where its jobs go, where its results come back, and its handle.
type Worker<J, R> = (mpsc::Sender<J>, mpsc::Receiver<R>, thread::JoinHandle<()>);

/// The render worker: takes jobs one at a time, sends finished frames back. Ends when
/// the job sender is dropped.
fn spawn_render_worker(
    scene: Arc<Scene>,
    profile: Profile,
    moving_profile: Profile,
) -> Result<Worker<Job, Frame>, ViewerError> {
    let (job_tx, job_rx) = mpsc::channel::<Job>();
    let (frame_tx, frame_rx) = mpsc::channel::<Frame>();
    let handle = thread::Builder::new()
        .name("octaray-preview".into())
        .spawn(move || {
            // per-scene data (BVH, photon map) once, not per frame, in an f32 frame
            // that follows the camera when it has flown far
            let profiles = [&profile, &moving_profile];
            let mut views: [Option<View>; 2] = [None, None];
            let mut checked = false;
            for job in job_rx {
                let k = (job.divisor > 1) as usize;
                let view =
                    views[k].get_or_insert_with(|| View::new(profiles[k], &scene, job.camera.eye));
                let frame = view.render(&job);
                let prepared = &view.prepared;
                if frame_tx.send(frame).is_err() {
                    break;
                }
                // once, after the first frame has built the packet renderer
                if !checked && let Some(d) = prepared.detail_below_f32() {
                    use std::io::Write as _;
                    let name = &prepared.profile().name;
                    let _ = writeln!(std::io::stderr(), "{}", d.warning(&scene, name));
                }
                checked = true;
            }
        })
        .map_err(|e| ViewerError::Thread("render", e))?;
    Ok((job_tx, frame_rx, handle))
}

/// What became of a capture.
struct CaptureDone {
    result: Result<PathBuf, String>,
    elapsed: Duration,
}

/// Renders `camera` at the scene's resolution with `profile` and writes it under the next
/// free `Output_1N.bmp` in `out_dir`.
pub fn capture(
    scene: &Scene,
    profile: &Profile,
    camera: Camera,
    out_dir: &Path,
) -> Result<PathBuf, String> {
    let settings = RenderSettings {
        camera,
        ..RenderSettings::for_scene(scene)
    };
    let rendered = profile.render(scene, &settings);
    write_next_output(&rendered.image, out_dir).map_err(|e| e.to_string())
}

/// The capture worker: renders and writes captures in the order they were asked for.
fn spawn_capture_worker(
    scene: Arc<Scene>,
    profile: Profile,
    out_dir: PathBuf,
) -> Result<Worker<Camera, CaptureDone>, ViewerError> {
    let (cam_tx, cam_rx) = mpsc::channel::<Camera>();
    let (done_tx, done_rx) = mpsc::channel::<CaptureDone>();
    let handle = thread::Builder::new()
        .name("octaray-capture".into())
        .spawn(move || {
            for camera in cam_rx {
                let start = Instant::now();
                let result = capture(&scene, &profile, camera, &out_dir);
                let done = CaptureDone {
                    result,
                    elapsed: start.elapsed(),
                };
                // (a closed stderr is no reason to fail: written, not `eprintln!`)
                let mut err = std::io::stderr();
                let _ = match &done.result {
                    Ok(path) => writeln!(
                        err,
                        "octaray: captured {} ({:.2} s), eye {}",
                        path.display(),
                        done.elapsed.as_secs_f64(),
                        fmt_vec(camera.eye)
                    ),
                    Err(e) => writeln!(err, "octaray: capture failed: {e}"),
                };
                // The window may be gone already; the capture is on disk either way.
                let _ = done_tx.send(done);
            }
        })
        .map_err(|e| ViewerError::Thread("capture", e))?;
    Ok((cam_tx, done_rx, handle))
}

/// Appends the camera of each frame drawn to a camera path file (`--record`), once per
/// camera: a still camera's refinement passes add nothing.
pub struct Recorder {
    file: std::fs::File,
    path: PathBuf,
    last: Option<Camera>,
    failed: bool,
}

impl Recorder {
    /// Opens `path` for appending (created if missing; a new file starts with a comment
    /// naming the fields).
    pub fn open(path: &Path) -> std::io::Result<Recorder> {
        if path.is_dir() {
            return Err(std::io::Error::new(
                std::io::ErrorKind::InvalidInput,
                "is a directory",
            ));
        }
        let mut file = std::fs::OpenOptions::new()
            .append(true)
            .create(true)
            .open(path)?;
        if file.metadata()?.len() == 0 {
            file.write_all(
                b"// octaray camera path: eye x y z, look-at x y z, up x y z, vertical fov (degrees)\n",
            )?;
        }
        Ok(Recorder {
            file,
            path: path.to_path_buf(),
            last: None,
            failed: false,
        })
    }

    /// Appends `camera` unless it is the last one recorded. A failed write is reported
    /// once on stderr and ends the recording (the flight goes on).
    pub fn record(&mut self, camera: &Camera) {
        if self.failed || self.last == Some(*camera) {
            return;
        }
        self.last = Some(*camera);
        let line = crate::scene::camera_path::format_line(camera) + "\n";
        if let Err(e) = self.file.write_all(line.as_bytes()) {
            self.failed = true;
            let _ = writeln!(
                std::io::stderr(),
                "octaray: --record: {}: {e}; recording stopped",
                self.path.display()
            );
        }
    }
}

fn fmt_vec(v: DVec3) -> String {
    format!("({:.1}, {:.1}, {:.1})", v.x, v.y, v.z)
}

/// Frames per second over the last second of finished frames.
#[derive(Default)]
struct FpsMeter {
    times: VecDeque<Instant>,
}

impl FpsMeter {
    fn tick(&mut self, now: Instant) {
        self.times.push_back(now);
        while self
            .times
            .front()
            .is_some_and(|t| now.duration_since(*t) > Duration::from_secs(1))
        {
            self.times.pop_front();
        }
    }

    fn fps(&self) -> Option<f64> {
        let (first, last) = (self.times.front()?, self.times.back()?);
        let span = last.duration_since(*first).as_secs_f64();
        (self.times.len() >= 2 && span > 0.0).then(|| (self.times.len() - 1) as f64 / span)
    }
}

/// Key events as minifb reports them, every press and release in order (polling key
/// levels once per loop would lose a tap whose press and release arrive together).
#[derive(Clone, Default)]
struct KeyEvents(Rc<RefCell<Vec<(Key, bool)>>>);

impl minifb::InputCallback for KeyEvents {
    fn add_char(&mut self, _uni_char: u32) {}

    fn set_key_state(&mut self, key: Key, state: bool) {
        self.0.borrow_mut().push((key, state));
    }
}

/// Opens the window and runs until Esc or the window is closed. Pending captures are
/// finished before returning. With `record`, the camera of every frame drawn is
/// appended to a camera path.
pub fn run(config: &ViewConfig, mut record: Option<Recorder>) -> Result<(), ViewerError> {
    let mut window = Window::new(
        "octaray",
        config.size.width as usize,
        config.size.height as usize,
        WindowOptions {
            resize: true,
            ..WindowOptions::default()
        },
    )
    .map_err(|e| ViewerError::Window(e.to_string()))?;
    window.set_target_fps(120);
    let events = KeyEvents::default();
    window.set_input_callback(Box::new(events.clone()));

    let (job_tx, frame_rx, render_thread) = spawn_render_worker(
        config.scene.clone(),
        config.profile.clone(),
        config.moving_profile.clone(),
    )?;
    let (capture_tx, capture_rx, capture_thread) = spawn_capture_worker(
        config.scene.clone(),
        config.capture_profile.clone(),
        config.out_dir.clone(),
    )?;

    let scene_label = Path::new(&config.scene_name).file_name().map_or_else(
        || config.scene_name.clone(),
        |n| n.to_string_lossy().into_owned(),
    );
    let mut flycam = FlyCam::new(config.camera);
    let mut refiner = Refiner::default();
    let mut fps = FpsMeter::default();
    let mut shift = false;
    let mut was_active = window.is_active();
    let mut busy = false;
    let mut submitted: Option<Job> = None;
    let mut shown: Option<Frame> = None;
    let mut buffer: Vec<u32> = Vec::new();
    let mut buffer_size = (0, 0);
    let mut captures_pending = 0usize;
    let mut capture_status = String::new();
    let mut title = String::new();
    let mut last_title = Instant::now() - Duration::from_secs(1);
    let mut last_tick = Instant::now();

    'frames: while window.is_open() {
        // Input.
        let now = Instant::now();
        let dt = now.duration_since(last_tick).as_secs_f64().min(0.25);
        last_tick = now;
        let pending: Vec<(Key, bool)> = std::mem::take(&mut *events.0.borrow_mut());
        for (key, down) in pending {
            if is_shift(key) {
                shift = down;
            } else if let Some(motion) = motion_for_key(key) {
                if down {
                    flycam.press(motion, shift);
                } else {
                    flycam.release(motion);
                }
            } else if down && key == Key::Escape {
                break 'frames;
            } else if down && is_capture_key(key) && capture_tx.send(flycam.camera).is_ok() {
                captures_pending += 1;
            }
        }
        let active = window.is_active();
        if was_active && !active {
            // Key releases go to whichever window has the focus now.
            flycam.release_all();
            shift = false;
        }
        was_active = active;
        flycam.advance(dt, shift);

        // Finished work.
        while let Ok(frame) = frame_rx.try_recv() {
            busy = false;
            let (w, h) = (frame.image.width as u64, frame.image.height as u64);
            refiner.observe(w * h, frame.stats.elapsed);
            fps.tick(Instant::now());
            if let Some(r) = record.as_mut() {
                r.record(&frame.job.camera);
            }
            shown = Some(frame);
            buffer_size = (0, 0); // present it
        }
        while let Ok(done) = capture_rx.try_recv() {
            captures_pending = captures_pending.saturating_sub(1);
            capture_status = match done.result {
                Ok(path) => format!(
                    "saved {} ({:.2} s)",
                    path.display(),
                    done.elapsed.as_secs_f64()
                ),
                Err(e) => format!("capture FAILED: {e}"),
            };
        }

        // Next frame, if the worker is idle: the current camera, coarse if it moved,
        // finer if it did not.
        let (ww, wh) = window.get_size();
        let (ww, wh) = (ww.max(1) as u32, wh.max(1) as u32);
        if !busy {
            let next = next_job(submitted.as_ref(), &flycam.camera, (ww, wh), &refiner);
            if let Some(job) = next {
                if job_tx.send(job).is_err() {
                    break 'frames; // the worker died; its panic is reported on join
                }
                busy = true;
                submitted = Some(job);
            }
        }

        // Title, a few times a second.
        if now.duration_since(last_title) > Duration::from_millis(250) {
            last_title = now;
            let c = &flycam.camera;
            let mut t = format!("octaray - {} - {}", scene_label, config.profile.name);
            match &shown {
                Some(f) if !busy && f.job.divisor == 1 => {
                    let secs = f.stats.elapsed.as_secs_f64().max(1e-9);
                    t += &format!(
                        " - still, full res in {:.0} ms, {:.1} Mrays/s",
                        secs * 1e3,
                        f.stats.total_rays() as f64 / 1e6 / secs
                    );
                }
                Some(f) => {
                    let secs = f.stats.elapsed.as_secs_f64().max(1e-9);
                    let rate = fps.fps().map_or_else(|| "-".into(), |r| format!("{r:.1}"));
                    t += &format!(
                        " - {rate} fps, {:.1} Mrays/s, 1/{} res",
                        f.stats.total_rays() as f64 / 1e6 / secs,
                        f.job.divisor
                    );
                }
                None => t += " - rendering",
            }
            t += &format!(" - eye {} look {}", fmt_vec(c.eye), fmt_look(c.look));
            if captures_pending > 0 {
                t += &format!(" - capturing ({captures_pending})...");
            } else if !capture_status.is_empty() {
                t += &format!(" - {capture_status}");
            }
            t += &format!(" - {KEY_HELP}");
            if t != title {
                window.set_title(&t);
                title = t;
            }
        }

        // Present.
        let size = (ww as usize, wh as usize);
        let presented = match &shown {
            Some(frame) if size != buffer_size => {
                present_into(&frame.image, size.0, size.1, &mut buffer);
                buffer_size = size;
                window.update_with_buffer(&buffer, size.0, size.1).is_ok()
            }
            _ => false,
        };
        if !presented {
            window.update();
        }
    }

    drop(window);
    drop(job_tx);
    drop(capture_tx);
    if captures_pending > 0 {
        let _ = writeln!(
            std::io::stderr(),
            "octaray: finishing {captures_pending} capture(s)..."
        );
    }
    // A panic in a worker has been printed already; the captures before it are on disk.
    let _ = capture_thread.join();
    // The preview worker is not waited for: its frame in flight is no longer wanted, and it
    // ends when it finds the frame receiver gone (or with the process).
    drop(render_thread);
    Ok(())
}

fn fmt_look(v: DVec3) -> String {
    format!("({:.2}, {:.2}, {:.2})", v.x, v.y, v.z)
}

/// The benchmark's flight: an orbit of the scene's origin, 3° per frame (the rate of a
/// held turn key), radius 141 (the default eye's distance from the z axis), bobbing
/// between heights 30 and 70, looking at (0, 0, 10).
pub fn flight_camera(frame: u32) -> Camera {
    let start = 45f64.to_radians();
    let theta = start + (3.0 * frame as f64).to_radians();
    let r = 100.0 * std::f64::consts::SQRT_2;
    let eye = DVec3::new(
        r * theta.cos(),
        r * theta.sin(),
        50.0 + 20.0 * (2.0 * theta).sin(),
    );
    Camera::look_at(eye, DVec3::new(0.0, 0.0, 10.0), DVec3::Z, 80.0)
        .expect("the orbit never looks straight down")
}

/// One line of the benchmark's table.
#[derive(Clone, Debug)]
pub struct BenchLine {
    pub label: String,
    pub frames: u32,
    pub seconds: f64,
    pub rays: u64,
    /// Smallest and largest divisor used.
    pub divisors: (u32, u32),
}

impl BenchLine {
    pub fn fps(&self) -> f64 {
        self.frames as f64 / self.seconds.max(1e-9)
    }
}

/// What [`benchmark`] measured.
#[derive(Clone, Debug)]
pub struct BenchReport {
    pub size: Size,
    pub profile: String,
    pub threads: usize,
    pub lines: Vec<BenchLine>,
    /// Seconds from the last moving frame to the full-resolution frame (worst of the
    /// stops measured), and the divisors of the passes in between.
    pub stop_to_full: f64,
    pub stop_passes: Vec<u32>,
}

impl fmt::Display for BenchReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "viewer benchmark: {}, profile {}, {} threads, flight: orbit of the origin at 3 deg/frame",
            self.size, self.profile, self.threads
        )?;
        writeln!(
            f,
            "  {:<34} {:>7} {:>9} {:>10} {:>10} {:>11}",
            "mode", "frames", "seconds", "fps", "ms/frame", "Mrays/s"
        )?;
        for l in &self.lines {
            writeln!(
                f,
                "  {:<34} {:>7} {:>9.3} {:>10.1} {:>10.2} {:>11.2}",
                l.label,
                l.frames,
                l.seconds,
                l.fps(),
                1e3 * l.seconds / l.frames.max(1) as f64,
                l.rays as f64 / 1e6 / l.seconds.max(1e-9)
            )?;
        }
        let passes: Vec<String> = self.stop_passes.iter().map(|d| format!("1/{d}")).collect();
        let passes = if passes.is_empty() {
            "none: moving frames are already full resolution".to_string()
        } else {
            format!("passes {}", passes.join(", "))
        };
        write!(
            f,
            "  stop -> full resolution: {:.3} s ({passes}; worst of 3 stops)",
            self.stop_to_full
        )
    }
}

/// Renders `frames` frames along [`flight_camera`] twice — at full resolution, then with
/// the viewer's moving-resolution policy — and measures how long the viewer takes to reach
/// full resolution after stopping. Frames are scaled up to the window as the viewer does;
/// no window is opened. `record` gets the cameras of the first flight.
pub fn benchmark(
    scene: &Scene,
    profile: &Profile,
    size: Size,
    frames: u32,
    mut record: Option<&mut Recorder>,
) -> BenchReport {
    let mut buffer = Vec::new();
    let (w, h) = (size.width, size.height);
    let mut view = View::new(profile, scene, flight_camera(0).eye);
    let mut refiner = Refiner::default();
    let mut fly = |label: &str, adaptive: bool, refiner: &mut Refiner| {
        let mut rays = 0;
        let mut divisors = (u32::MAX, 0);
        let start = Instant::now();
        for i in 0..frames {
            let divisor = if adaptive {
                refiner.moving_divisor(w, h)
            } else {
                1
            };
            let job = Job {
                camera: flight_camera(i),
                width: w,
                height: h,
                divisor,
            };
            let frame = view.render(&job);
            present_into(&frame.image, w as usize, h as usize, &mut buffer);
            if let (false, Some(r)) = (adaptive, record.as_deref_mut()) {
                r.record(&job.camera);
            }
            let (pw, ph) = preview_size(w, h, divisor);
            refiner.observe(pw as u64 * ph as u64, frame.stats.elapsed);
            rays += frame.stats.total_rays();
            divisors = (divisors.0.min(divisor), divisors.1.max(divisor));
        }
        BenchLine {
            label: label.to_string(),
            frames,
            seconds: start.elapsed().as_secs_f64(),
            rays,
            divisors,
        }
    };
    let full = fly("moving, full resolution", false, &mut refiner);
    let mut adaptive = fly("moving, adaptive", true, &mut refiner);
    adaptive.label = format!(
        "moving, adaptive (1/{}..1/{} res)",
        adaptive.divisors.0, adaptive.divisors.1
    );

    // Stops: the camera halts right after a moving frame at the divisor the policy
    // picks; the viewer then refines d/2, d/4, ..., 1 at the still camera. Measured from
    // the moving frame on screen to the full-resolution frame on screen. (In the window, a
    // moving frame still in flight when the camera stops adds at most one moving frame,
    // about MOVING_FRAME_S.)
    let mut stop_to_full: f64 = 0.0;
    let mut stop_passes = Vec::new();
    for k in 0..3 {
        let camera = flight_camera(frames + 40 * k);
        let mut d = refiner.moving_divisor(w, h);
        let mut passes = Vec::new();
        let start = Instant::now();
        while d > 1 {
            d = Refiner::refine(d);
            let job = Job {
                camera,
                width: w,
                height: h,
                divisor: d,
            };
            let frame = view.render(&job);
            present_into(&frame.image, w as usize, h as usize, &mut buffer);
            passes.push(d);
        }
        stop_to_full = stop_to_full.max(start.elapsed().as_secs_f64());
        stop_passes = passes;
    }
    BenchReport {
        size,
        profile: profile.name.clone(),
        threads: crate::parallel::threads(),
        lines: vec![full, adaptive],
        stop_to_full,
        stop_passes,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_map_to_the_assignments_motions() {
        let cases = [
            (Key::Up, Motion::Forward),
            (Key::Down, Motion::Backward),
            (Key::Left, Motion::Left),
            (Key::Right, Motion::Right),
            (Key::PageUp, Motion::Up),
            (Key::PageDown, Motion::Down),
            (Key::Key1, Motion::LookLeft),
            (Key::Key2, Motion::LookRight),
            (Key::Key3, Motion::LookUp),
            (Key::Key4, Motion::LookDown),
            (Key::Key5, Motion::TiltClockwise),
            (Key::Key6, Motion::TiltCounterclockwise),
            (Key::NumPad5, Motion::TiltClockwise),
        ];
        for (key, motion) in cases {
            assert_eq!(motion_for_key(key), Some(motion), "{key:?}");
        }
        for key in [Key::Key0, Key::Escape, Key::LeftShift, Key::A] {
            assert_eq!(motion_for_key(key), None, "{key:?}");
        }
        assert!(is_capture_key(Key::Key0) && is_capture_key(Key::NumPad0));
    }

    #[test]
    fn size_parses_and_rejects() {
        assert_eq!(
            "768x512".parse::<Size>(),
            Ok(Size {
                width: 768,
                height: 512
            })
        );
        for bad in ["768", "0x10", "x", "10x-1", "axb", "10x10x10"] {
            assert!(bad.parse::<Size>().is_err(), "{bad}");
        }
    }

    #[test]
    fn refiner_coarsens_for_slow_frames_and_halves_to_one() {
        let mut r = Refiner::default();
        assert_eq!(r.moving_divisor(768, 768), 4);
        // 1 µs per pixel: 768² would take 0.59 s; 1/5 res (154²) takes 24 ms.
        r.observe(1_000_000, Duration::from_secs(1));
        assert_eq!(r.moving_divisor(768, 768), 5);
        // Very cheap frames: full resolution.
        let mut fast = Refiner::default();
        fast.observe(1_000_000, Duration::from_millis(1));
        assert_eq!(fast.moving_divisor(768, 768), 1);
        // Very slow frames: the coarsest.
        let mut slow = Refiner::default();
        slow.observe(1, Duration::from_secs(1));
        assert_eq!(slow.moving_divisor(768, 768), MAX_DIVISOR);
        let chain: Vec<u32> =
            std::iter::successors(Some(5), |&d| (d > 1).then(|| Refiner::refine(d))).collect();
        assert_eq!(chain, [5, 2, 1]);
    }

    #[test]
    fn moving_renders_coarse_and_stillness_refines_to_full() {
        let mut refiner = Refiner::default();
        // 0.1 µs per pixel: 768² takes 59 ms, 1/2 res 15 ms.
        refiner.observe(1_000_000, Duration::from_millis(100));
        let mut fly = FlyCam::new(Camera::default());
        let size = (768, 768);
        let first = next_job(None, &fly.camera, size, &refiner).expect("a first frame");
        assert_eq!(first.divisor, 2);
        // Still: full resolution next, then nothing more to do.
        let full = next_job(Some(&first), &fly.camera, size, &refiner).expect("refinement");
        assert_eq!((full.divisor, full.camera), (1, first.camera));
        assert_eq!(next_job(Some(&full), &fly.camera, size, &refiner), None);
        // A key press: back to a coarse frame of the new view.
        fly.press(Motion::LookUp, false);
        let moved = next_job(Some(&full), &fly.camera, size, &refiner).expect("a new view");
        assert_eq!((moved.divisor, moved.camera), (2, fly.camera));
        // A resized window counts as a change too.
        let resized = next_job(Some(&full), &full.camera, (800, 600), &refiner).expect("resize");
        assert_eq!(
            (resized.width, resized.height, resized.divisor),
            (800, 600, 2)
        );
    }

    #[test]
    fn preview_is_scaled_up_by_nearest_pixel() {
        let mut img = Framebuffer::new(2, 1);
        img.pixels = vec![[255, 0, 0], [0, 0, 255]];
        let mut buf = Vec::new();
        present_into(&img, 4, 2, &mut buf);
        let red = 0xff0000;
        let blue = 0x0000ff;
        assert_eq!(buf, [red, red, blue, blue, red, red, blue, blue]);
        assert_eq!(preview_size(768, 768, 5), (154, 154));
        assert_eq!(preview_size(3, 1, 16), (1, 1));
    }

    #[test]
    fn flight_stays_orthonormal_and_moves() {
        let a = flight_camera(0);
        let b = flight_camera(1);
        assert!(flycam::frame_error(&a) < 1e-14);
        assert!((a.eye - b.eye).length() > 1.0);
    }
}
