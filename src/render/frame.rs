//! Frame driver: splits the image into bands of rows and renders them on rayon's pool,
//! with an optional progress bar.

use std::io::IsTerminal;
use std::sync::{Mutex, OnceLock};
use std::time::Instant;

use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;

use super::{RenderSettings, RenderStats, Rendered};
use crate::output::Framebuffer;

/// Renders `settings.width × settings.height` pixels in bands of `band` rows. `render_band`
/// gets the first row's index and the band's pixels (row-major) and returns its counters.
pub fn render_bands<F>(settings: &RenderSettings, band: u32, render_band: F) -> Rendered
where
    F: Fn(u32, &mut [[u8; 3]]) -> RenderStats + Sync,
{
    let start = Instant::now();
    let mut image = Framebuffer::new(settings.width, settings.height);
    let total = Mutex::new(RenderStats::default());
    let bar = if settings.progress && std::io::stderr().is_terminal() {
        let bar = ProgressBar::new(settings.height as u64);
        bar.set_style(
            ProgressStyle::with_template(
                "{elapsed_precise} [{bar:40}] {pos}/{len} rows, eta {eta}",
            )
            .expect("valid template")
            .progress_chars("=> "),
        );
        bar
    } else {
        ProgressBar::hidden()
    };
    let work = |pixels: &mut [[u8; 3]]| {
        let rows = settings.width as usize * band as usize;
        let one = |(k, band_pixels): (usize, &mut [[u8; 3]])| {
            let stats = render_band(k as u32 * band, band_pixels);
            total.lock().expect("no panics while holding").add(&stats);
            bar.inc((band_pixels.len() / settings.width as usize) as u64);
        };
        if parallel() {
            pixels.par_chunks_mut(rows).enumerate().for_each(one);
        } else {
            pixels.chunks_mut(rows).enumerate().for_each(one);
        }
    };
    with_threads(settings.threads, || work(&mut image.pixels));
    bar.finish_and_clear();
    let mut stats = total.into_inner().expect("no panics while holding");
    stats.elapsed = start.elapsed();
    Rendered { image, stats }
}

/// Runs `f` on `threads` worker threads: rayon's current pool when it has that many
/// (the command line sizes the global pool by `--threads`) or none is asked for, else
/// a pool of its own. Should that pool fail to start (a process limit), `f` runs on
/// the current pool: the same result, other threads.
pub fn with_threads<R: Send>(threads: Option<usize>, f: impl FnOnce() -> R + Send) -> R {
    match threads {
        Some(n) if n != self::threads() => {
            match rayon::ThreadPoolBuilder::new().num_threads(n).build() {
                Ok(pool) => pool.install(f),
                Err(_) => f(),
            }
        }
        _ => f(),
    }
}

/// Whether rayon's global pool runs: `Some` once [`start_pool`] or [`parallel`] has
/// tried to start it.
static POOL: OnceLock<bool> = OnceLock::new();

/// Starts rayon's global pool with `threads` workers (the command line's `--threads`),
/// before any parallel loop. One thread needs no worker: should it not start, the
/// parallel loops run on the calling thread.
pub fn start_pool(threads: usize) -> Result<(), rayon::ThreadPoolBuildError> {
    let started = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build_global();
    let _ = POOL.set(started.is_ok());
    if threads == 1 { Ok(()) } else { started }
}

/// Whether a parallel loop may run on rayon's pools: on a worker of one, or when the
/// global pool runs, which is started here at the first such loop (where rayon would
/// start it). Where its threads cannot start (a process or container limit), rayon
/// would panic at every parallel loop: they run on the calling thread instead, and
/// [`serial`] tells.
pub fn parallel() -> bool {
    rayon::current_thread_index().is_some()
        || *POOL.get_or_init(|| rayon::ThreadPoolBuilder::new().build_global().is_ok())
}

/// Whether parallel loops have been running on the calling thread because the worker
/// threads could not start.
pub fn serial() -> bool {
    POOL.get() == Some(&false)
}

/// The threads parallel loops run on here: the current pool's, or 1 where its threads
/// could not start ([`parallel`]).
pub fn threads() -> usize {
    if parallel() {
        rayon::current_num_threads()
    } else {
        1
    }
}
