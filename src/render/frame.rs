//! The frame loop: the one loop over a rectangle of pixels that every renderer and every
//! use goes through (whole frames, supersampled frames, the viewer's reduced frames,
//! crops and tiles of a frame).
//!
//! A frame's camera samples lie on the pixel centres of the `n`×-resolution grid of its
//! camera ([`Samples`]): one per pixel at `n` = 1, else the `n × n` stratified sub-pixel
//! centres. The loop splits the rectangle into bands of rows over rayon's pool and walks
//! each band in blocks of 4 × 2 samples ([`SampleBlock`]), which a [`SampleTracer`]
//! traces; a pixel's samples are summed in one fixed order (row by row, left to right),
//! so its value depends on the pixel alone, never on the rectangle, band or thread that
//! rendered it. Every random number a tracer draws derives from the scene and the
//! sample's position on the sample grid (wavelengths per sample, photons per scene).
//!
//! A [`Sampler`] picks the samples: the uniform `n × n` grid, or the adaptive sampler,
//! which traces the pixels' corners first and the `n × n` grid only inside pixels whose
//! corners disagree ([`render_frame`]); its choice for a pixel reads only the corners of
//! that pixel and of its eight neighbours, which any rectangle computes the same way.

use std::io::IsTerminal;
use std::sync::Mutex;

use glam::DVec3;
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;

use super::RenderStats;
use crate::parallel::{parallel, with_threads};
use crate::scene::Camera;
use crate::scene::camera::PixelGrid;

mod adaptive;

pub use adaptive::{WAVES, corner_grid};

/// A half-open rectangle of pixels, [x0, x1) × [y0, y1).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct PixelRect {
    pub x0: u32,
    pub x1: u32,
    pub y0: u32,
    pub y1: u32,
}

impl PixelRect {
    /// The whole of a `width × height` image.
    pub fn full(width: u32, height: u32) -> PixelRect {
        PixelRect {
            x0: 0,
            x1: width,
            y0: 0,
            y1: height,
        }
    }

    pub fn width(&self) -> u32 {
        self.x1.saturating_sub(self.x0)
    }

    pub fn height(&self) -> u32 {
        self.y1.saturating_sub(self.y0)
    }

    pub fn is_empty(&self) -> bool {
        self.width() == 0 || self.height() == 0
    }

    /// Whether `self` lies inside `outer`.
    pub fn inside(&self, outer: &PixelRect) -> bool {
        outer.x0 <= self.x0 && self.x1 <= outer.x1 && outer.y0 <= self.y0 && self.y1 <= outer.y1
    }

    /// Pixel count.
    pub fn area(&self) -> u64 {
        self.width() as u64 * self.height() as u64
    }
}

/// The camera samples of a frame: `n × n` per pixel, in the cells of the
/// `n`×-resolution grid of the same camera (at `n` = 1, the pixels): at each cell's
/// centre (the spec's pixel centres at `n` = 1), or at a point of the cell given by its
/// [`Pattern`].
#[derive(Clone, Copy, Debug)]
pub struct Samples {
    /// The sample grid (the cells' centres), in f64.
    pub grid: PixelGrid,
    /// Samples per pixel along each axis.
    pub n: u32,
    /// Where in its cell each sample lies.
    pub pattern: Pattern,
}

/// Where each sample of a [`Samples`] lies inside its cell.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Pattern {
    /// The cell's centre.
    Centres,
    /// A point of the cell given by a hash of the sample's position on the grid and
    /// `seed` (the same in every frame and rectangle): no regular lattice to alias with a
    /// regular picture.
    Jittered { seed: u64 },
}

impl Samples {
    /// The samples of a `width × height` frame of `camera`, `n × n` per pixel, at the
    /// cells' centres.
    pub fn new(camera: &Camera, width: u32, height: u32, n: u32) -> Samples {
        Samples {
            grid: camera.pixel_grid(width * n, height * n),
            n,
            pattern: Pattern::Centres,
        }
    }

    /// Whether every sample lies at its cell's centre.
    #[inline]
    pub fn centred(&self) -> bool {
        self.pattern == Pattern::Centres
    }

    /// Where sample (x, y) lies from its cell's centre, in cells: each in [−½, ½) (exact
    /// in f32).
    #[inline]
    pub fn offset(&self, x: u32, y: u32) -> [f64; 2] {
        match self.pattern {
            Pattern::Centres => [0.0, 0.0],
            Pattern::Jittered { seed } => {
                let h = crate::render::spectral::hash64(seed ^ ((y as u64) << 32 | x as u64));
                let unit = |bits: u64| (bits & 0xff_ffff) as f64 / (1u64 << 24) as f64 - 0.5;
                [unit(h >> 40), unit(h >> 8)]
            }
        }
    }

    /// The direction of the camera ray of sample (x, y).
    #[inline]
    pub fn direction(&self, x: u32, y: u32) -> glam::DVec3 {
        match self.pattern {
            Pattern::Centres => self.grid.direction(x as f64, y as f64),
            _ => {
                let [dx, dy] = self.offset(x, y);
                self.grid.direction(x as f64 + dx, y as f64 + dy)
            }
        }
    }
}

/// Up to 4 × 2 neighbouring samples: lane k is sample (x + k % 4, y + k / 4) of the
/// sample grid, for the lanes set in `bits`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SampleBlock {
    pub x: u32,
    pub y: u32,
    pub bits: u32,
}

/// What a renderer gives the frame loop: the colours of a block of camera samples.
pub trait SampleTracer: Sync {
    /// Per-band working memory (reused from block to block).
    type Scratch: Default;
    /// The colours of a block, in the renderer's own precision.
    type Colors: SampleColors;
    /// Traces the samples of `block` (lanes outside `block.bits` are black).
    fn trace_block(
        &self,
        samples: &Samples,
        block: SampleBlock,
        scratch: &mut Self::Scratch,
        stats: &mut RenderStats,
    ) -> Self::Colors;

    /// Traces two blocks, the second after the first in the frame loop's order (the
    /// next 4 × 2 block of the row, or the first of the next row): as two
    /// [`SampleTracer::trace_block`]s, unless a tracer does both at once.
    fn trace_pair(
        &self,
        samples: &Samples,
        blocks: [SampleBlock; 2],
        scratch: &mut Self::Scratch,
        stats: &mut RenderStats,
    ) -> [Self::Colors; 2] {
        let first = self.trace_block(samples, blocks[0], scratch, stats);
        [first, self.trace_block(samples, blocks[1], scratch, stats)]
    }
}

/// The colours of a block of eight samples, each channel in [0, 1].
pub trait SampleColors {
    /// A sum of samples in the renderer's precision.
    type Sum: Copy + Default + Send + Sync;
    /// Each lane quantized as a one-sample pixel.
    fn rgb8(&self) -> [[u8; 3]; 8];
    /// Lane `k` as a sum of one sample.
    fn lane(&self, k: usize) -> Self::Sum;
    /// `sum + c`.
    fn add(sum: Self::Sum, c: Self::Sum) -> Self::Sum;
    /// The pixel of `count` samples summed in `sum`, quantized.
    fn resolve(sum: Self::Sum, count: u32) -> [u8; 3];
    /// The pixel of `count` samples summed in `sum`, linear.
    fn linear(sum: Self::Sum, count: u32) -> DVec3;
}

/// The pixels the frame loop writes: 8-bit RGB (the image) or linear colour.
pub trait PixelOut: Copy + Default + Send + Sync {
    /// Each lane of a block of one-sample pixels.
    fn block<C: SampleColors>(colors: &C) -> [Self; 8];
    /// The pixel of `count` samples summed in `sum`.
    fn resolve<C: SampleColors>(sum: C::Sum, count: u32) -> Self;
}

impl PixelOut for [u8; 3] {
    #[inline]
    fn block<C: SampleColors>(colors: &C) -> [Self; 8] {
        colors.rgb8()
    }

    #[inline]
    fn resolve<C: SampleColors>(sum: C::Sum, count: u32) -> Self {
        C::resolve(sum, count)
    }
}

impl PixelOut for DVec3 {
    #[inline]
    fn block<C: SampleColors>(colors: &C) -> [Self; 8] {
        std::array::from_fn(|k| C::linear(colors.lane(k), 1))
    }

    #[inline]
    fn resolve<C: SampleColors>(sum: C::Sum, count: u32) -> Self {
        C::linear(sum, count)
    }
}

/// How a frame's pixels are sampled ([`render_frame`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Sampler {
    /// `n × n` samples per pixel at the centres of its cells; `n` = 1: the pixel centre,
    /// the spec's image.
    Uniform { n: u32 },
    /// One jittered sample per pixel first (its corners, shared with its neighbours); a
    /// pixel whose corners differ by more than `threshold` in some channel (linear,
    /// [0, 1]) is *busy* and sampled as `Uniform { n }` samples it, and so, in up to
    /// [`adaptive::WAVES`] waves, is each neighbour of a refined pixel whose corners
    /// differ by more than `threshold` from the refined pixel's samples next to it; any
    /// other pixel is the mean of its four corners.
    Adaptive { n: u32, threshold: f32 },
}

impl Sampler {
    /// The shortest stripe of rows worth rendering on its own (a tile's stripes): the
    /// adaptive sampler also traces the first pass, and follows edges, in the
    /// `WAVES - 1` rows above and below a stripe; at 16 × that, those rows add at most
    /// an eighth to the stripe's first pass. Uniform sampling reads nothing outside.
    pub fn min_stripe_rows(&self) -> u32 {
        match self {
            Sampler::Uniform { .. } => 2,
            Sampler::Adaptive { .. } => 16 * (WAVES - 1),
        }
    }

    /// The side of the sample grid inside a pixel (the uniform grid, or the adaptive
    /// sampler's refinement).
    pub fn n(&self) -> u32 {
        match *self {
            Sampler::Uniform { n } | Sampler::Adaptive { n, .. } => n,
        }
    }
}

/// Renders the pixels `rect` of a `width × height` frame of `camera` into `out` (the
/// rectangle's pixels, row-major) with `sampler`, and returns the frame's counters.
#[allow(clippy::too_many_arguments)]
pub fn render_frame<T: SampleTracer, P: PixelOut>(
    tracer: &T,
    camera: &Camera,
    width: u32,
    height: u32,
    rect: PixelRect,
    sampler: Sampler,
    out: &mut [P],
    run: Run,
) -> RenderStats {
    match sampler {
        Sampler::Uniform { n } => {
            let samples = Samples::new(camera, width, height, n);
            render_rect(tracer, &samples, rect, out, run)
        }
        Sampler::Adaptive { n, threshold } => {
            let frame = PixelRect::full(width, height);
            adaptive::render(tracer, camera, frame, rect, n, threshold, out, run)
        }
    }
}

/// How a frame is run: threads and progress.
#[derive(Clone, Copy, Debug, Default)]
pub struct Run {
    /// Worker threads; `None`: rayon's current pool.
    pub threads: Option<usize>,
    /// Draw a progress bar on stderr (when it is a terminal).
    pub progress: bool,
}

/// Pixel rows per band: two sample rows at least (one packet row) and four at least
/// (parallel granularity), so `n = 1` takes four rows, larger grids fewer.
fn band_rows(n: u32) -> u32 {
    (1..=4)
        .find(|r| (r * n).is_multiple_of(2) && r * n >= 4)
        .unwrap_or(4)
}

/// The lanes of the 4 × 2 block at (x, y) of a `width × rows` grid of samples that lie
/// inside it.
#[inline]
fn block_bits(x: usize, y: usize, width: usize, rows: usize) -> u32 {
    if x + 4 <= width && y + 2 <= rows {
        return 0xff;
    }
    (0..8)
        .filter(|&l| x + l % 4 < width && y + l / 4 < rows)
        .fold(0, |b, l| b | 1 << l)
}

/// Calls `f` on the 4 × 2 blocks covering a `width` × `rows` grid whose top-left sample
/// is (x0, y0), row by row, with each block's place in the grid.
#[inline(always)]
fn for_each_block(
    x0: u32,
    y0: u32,
    width: usize,
    rows: usize,
    mut f: impl FnMut(usize, usize, SampleBlock),
) {
    for y in (0..rows).step_by(2) {
        for x in (0..width).step_by(4) {
            let block = SampleBlock {
                x: x0 + x as u32,
                y: y0 + y as u32,
                bits: block_bits(x, y, width, rows),
            };
            f(x, y, block);
        }
    }
}

/// Traces the 4 × 2 blocks covering a `width` × `rows` grid whose top-left sample is
/// (x0, y0), in [`for_each_block`]'s order, two at a time ([`SampleTracer::trace_pair`]),
/// and hands `f` each block's place, the block and its colours.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn for_each_traced<T: SampleTracer>(
    tracer: &T,
    samples: &Samples,
    (x0, y0): (u32, u32),
    width: usize,
    rows: usize,
    scratch: &mut T::Scratch,
    stats: &mut RenderStats,
    mut f: impl FnMut(usize, usize, SampleBlock, &T::Colors),
) {
    let mut pending: Option<(usize, usize, SampleBlock)> = None;
    for_each_block(x0, y0, width, rows, |x, y, block| match pending.take() {
        None => pending = Some((x, y, block)),
        Some((px, py, first)) => {
            let [a, b] = tracer.trace_pair(samples, [first, block], scratch, stats);
            f(px, py, first, &a);
            f(x, y, block, &b);
        }
    });
    if let Some((x, y, block)) = pending {
        let c = tracer.trace_block(samples, block, scratch, stats);
        f(x, y, block, &c);
    }
}

/// Renders the pixels `rect` of the frame whose samples are `samples` into `out` (the
/// rectangle's pixels, row-major), and returns the frame's counters.
pub fn render_rect<T: SampleTracer, P: PixelOut>(
    tracer: &T,
    samples: &Samples,
    rect: PixelRect,
    out: &mut [P],
    run: Run,
) -> RenderStats {
    let width = rect.width() as usize;
    assert_eq!(out.len(), width * rect.height() as usize, "output size");
    if out.is_empty() {
        return RenderStats::default();
    }
    let band = band_rows(samples.n);
    let total = Mutex::new(RenderStats::default());
    let bar = progress_bar(run.progress, rect.height() as u64, "rows");
    let one = |(k, pixels): (usize, &mut [P])| {
        let y0 = rect.y0 + k as u32 * band;
        let stats = render_band(tracer, samples, rect.x0, y0, width, pixels);
        total.lock().expect("no panics while holding").add(&stats);
        bar.inc((pixels.len() / width) as u64);
    };
    let rows = width * band as usize;
    with_threads(run.threads, || {
        if parallel() {
            out.par_chunks_mut(rows).enumerate().for_each(one);
        } else {
            out.chunks_mut(rows).enumerate().for_each(one);
        }
    });
    bar.finish_and_clear();
    total.into_inner().expect("no panics while holding")
}

/// One band: the pixel rows `y0..` (as many as `pixels` holds) of columns
/// `x0..x0 + width`.
fn render_band<T: SampleTracer, P: PixelOut>(
    tracer: &T,
    samples: &Samples,
    x0: u32,
    y0: u32,
    width: usize,
    pixels: &mut [P],
) -> RenderStats {
    let mut stats = RenderStats::default();
    let mut scratch = T::Scratch::default();
    let rows = pixels.len() / width;
    let n = samples.n as usize;
    if n == 1 {
        let (scratch, st) = (&mut scratch, &mut stats);
        for_each_traced(
            tracer,
            samples,
            (x0, y0),
            width,
            rows,
            scratch,
            st,
            |px, py, block, c| {
                let p = P::block(c);
                if block.bits == 0xff {
                    for row in 0..2 {
                        let at = (py + row) * width + px;
                        pixels[at..at + 4].copy_from_slice(&p[4 * row..4 * row + 4]);
                    }
                } else {
                    for lane in (0..8).filter(|l| block.bits >> l & 1 == 1) {
                        pixels[(py + lane / 4) * width + px + lane % 4] = p[lane];
                    }
                }
            },
        );
        stats.primary_rays += pixels.len() as u64;
        return stats;
    }
    // every sample of the band, then each pixel's sum in one order
    let (sw, sh) = (width * n, rows * n);
    let mut band = vec![<T::Colors as SampleColors>::Sum::default(); sw * sh];
    let (sx0, sy0) = (x0 * n as u32, y0 * n as u32);
    trace_samples(
        tracer,
        samples,
        sx0,
        sy0,
        sw,
        &mut band,
        &mut scratch,
        &mut stats,
    );
    let count = (n * n) as u32;
    for (i, px) in pixels.iter_mut().enumerate() {
        let (r, x) = (i / width, i % width);
        let mut sum = Default::default();
        for b in 0..n {
            let row = &band[(r * n + b) * sw + x * n..][..n];
            for &s in row {
                sum = T::Colors::add(sum, s);
            }
        }
        *px = P::resolve::<T::Colors>(sum, count);
    }
    stats
}

/// Traces the samples of a rectangle of the sample grid, `sw` wide from sample
/// (sx0, sy0), as many rows as `out` holds, into `out` (row-major), in blocks of 4 × 2.
#[allow(clippy::too_many_arguments)]
fn trace_samples<T: SampleTracer>(
    tracer: &T,
    samples: &Samples,
    sx0: u32,
    sy0: u32,
    sw: usize,
    out: &mut [<T::Colors as SampleColors>::Sum],
    scratch: &mut T::Scratch,
    stats: &mut RenderStats,
) {
    let sh = out.len() / sw;
    for_each_traced(
        tracer,
        samples,
        (sx0, sy0),
        sw,
        sh,
        scratch,
        stats,
        |sx, sy, block, c| {
            for lane in (0..8).filter(|l| block.bits >> l & 1 == 1) {
                out[(sy + lane / 4) * sw + sx + lane % 4] = c.lane(lane);
            }
        },
    );
    stats.primary_rays += out.len() as u64;
}

/// A progress bar on stderr when `show` and stderr is a terminal, of `len` `unit`s.
fn progress_bar(show: bool, len: u64, unit: &str) -> ProgressBar {
    if !(show && std::io::stderr().is_terminal()) {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new(len);
    bar.set_style(
        ProgressStyle::with_template(&format!(
            "{{elapsed_precise}} [{{bar:40}}] {{pos}}/{{len}} {unit}, eta {{eta}}"
        ))
        .expect("valid template")
        .progress_chars("=> "),
    );
    bar
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bands_hold_whole_packet_rows() {
        for n in 1..=8 {
            let r = band_rows(n);
            assert!(
                r >= 1 && (r * n).is_multiple_of(2) && r * n >= 4,
                "n = {n}: {r} rows"
            );
        }
        assert_eq!(band_rows(1), 4);
    }

    #[test]
    fn block_bits_cover_exactly_the_grid() {
        for (w, h) in [(1, 1), (3, 1), (4, 2), (5, 3), (8, 4)] {
            let mut seen = vec![0u32; w * h];
            for y in (0..h).step_by(2) {
                for x in (0..w).step_by(4) {
                    let b = block_bits(x, y, w, h);
                    for l in (0..8).filter(|l| b >> l & 1 == 1) {
                        seen[(y + l / 4) * w + x + l % 4] += 1;
                    }
                }
            }
            assert!(seen.iter().all(|&c| c == 1), "{w}x{h}: {seen:?}");
        }
    }
}
