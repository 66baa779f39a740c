//! Frame driver: splits the image into bands of rows and renders them on rayon's pool,
//! with an optional progress bar.

use std::io::IsTerminal;
use std::sync::Mutex;
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
        pixels
            .par_chunks_mut(settings.width as usize * band as usize)
            .enumerate()
            .for_each(|(k, band_pixels)| {
                let stats = render_band(k as u32 * band, band_pixels);
                total.lock().expect("no panics while holding").add(&stats);
                bar.inc((band_pixels.len() / settings.width as usize) as u64);
            });
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
        Some(n) if n != rayon::current_num_threads() => {
            match rayon::ThreadPoolBuilder::new().num_threads(n).build() {
                Ok(pool) => pool.install(f),
                Err(_) => f(),
            }
        }
        _ => f(),
    }
}
