//! The adaptive sampler ([`super::Sampler::Adaptive`]): a first pass of two samples per
//! pixel, then the uniform `n × n` grid inside the pixels that need it.
//!
//! The first pass traces the pixels' corners (each shared by the four pixels that meet
//! there) and their centres, each jittered inside its cell: a regular lattice aliases
//! with a regular picture (the checkerboard toward the horizon, its reflections), where
//! whole rows of samples then agree. A pixel is *busy* when its four corners and its
//! centre differ by more than the threshold in some channel. A busy pixel, or one with
//! at least [`BUSY_NEIGHBOURS`] busy neighbours (where edges are dense, features fit
//! between the samples), is sampled exactly as [`super::Sampler::Uniform`] samples it;
//! any other pixel is the mean of its five samples. Both choices read only the first
//! pass of the pixel and its neighbours, traced here the same way for any rectangle, so
//! a crop equals the same pixels of the whole frame.

use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};

use glam::DVec3;

use rayon::prelude::*;

use super::{
    Pattern, PixelOut, PixelRect, RenderStats, Run, SampleColors, SampleTracer, Samples,
    progress_bar, trace_samples,
};
use crate::parallel::{parallel, with_threads};
use crate::scene::Camera;
use crate::scene::camera::PixelGrid;

/// Pixel rows per parallel task (and sample rows of the first pass).
const BAND: usize = 4;

/// Seeds of the first pass's positions ([`Pattern::Jittered`]).
const CORNER_SEED: u64 = 0xC0C0_0A7E_5EED_0001;
const CENTRE_SEED: u64 = 0xC0C0_0A7E_5EED_0002;

/// The corners of a `width × height` frame's pixels as a sample grid: sample (x, y) is
/// the top-left corner of pixel (x, y).
pub fn corner_grid(camera: &Camera, width: u32, height: u32) -> PixelGrid {
    let g = camera.pixel_grid(width, height);
    PixelGrid {
        top_left: g.top_left - (g.du + g.dv) * 0.5,
        ..g
    }
}

type Sum<T> = <<T as SampleTracer>::Colors as SampleColors>::Sum;

/// Traces `w × h` samples of `samples` from (x0, y0), in parallel bands of rows.
fn first_pass<T: SampleTracer>(
    tracer: &T,
    samples: &Samples,
    (x0, y0): (u32, u32),
    (w, h): (usize, usize),
    add: &(dyn Fn(&RenderStats) + Sync),
) -> Vec<Sum<T>> {
    let mut out = vec![Sum::<T>::default(); w * h];
    let one = |(k, rows): (usize, &mut [Sum<T>])| {
        let (mut stats, mut scratch) = (RenderStats::default(), T::Scratch::default());
        let y = y0 + (k * BAND) as u32;
        trace_samples(tracer, samples, x0, y, w, rows, &mut scratch, &mut stats);
        add(&stats);
    };
    if parallel() {
        out.par_chunks_mut(w * BAND).enumerate().for_each(one);
    } else {
        out.chunks_mut(w * BAND).enumerate().for_each(one);
    }
    out
}

/// Renders the pixels `rect` of `frame` (the whole image) into `out`.
#[allow(clippy::too_many_arguments)]
pub(super) fn render<T: SampleTracer, P: PixelOut>(
    tracer: &T,
    camera: &Camera,
    frame: PixelRect,
    rect: PixelRect,
    n: u32,
    threshold: f32,
    out: &mut [P],
    run: Run,
) -> RenderStats {
    let width = rect.width() as usize;
    assert_eq!(out.len(), width * rect.height() as usize, "output size");
    if out.is_empty() {
        return RenderStats::default();
    }
    let (fw, fh) = (frame.width(), frame.height());
    // the rectangle and its neighbours inside the frame: their corners and centres
    let ring = PixelRect {
        x0: rect.x0.saturating_sub(1),
        x1: (rect.x1 + 1).min(frame.x1),
        y0: rect.y0.saturating_sub(1),
        y1: (rect.y1 + 1).min(frame.y1),
    };
    let (rw, rh) = (ring.width() as usize, ring.height() as usize);
    let cw = rw + 1;
    let corner_samples = Samples {
        grid: corner_grid(camera, fw, fh),
        n: 1,
        pattern: Pattern::Jittered { seed: CORNER_SEED },
    };
    let centre_samples = Samples {
        pattern: Pattern::Jittered { seed: CENTRE_SEED },
        ..Samples::new(camera, fw, fh, 1)
    };
    let total = Mutex::new(RenderStats::default());
    let add = |s: &RenderStats| total.lock().expect("no panics while holding").add(s);
    let at = (ring.x0, ring.y0);
    let corners = || first_pass(tracer, &corner_samples, at, (cw, rh + 1), &add);
    let centres = || first_pass(tracer, &centre_samples, at, (rw, rh), &add);
    let (corners, centres) = with_threads(run.threads, || {
        if parallel() {
            rayon::join(corners, centres)
        } else {
            (corners(), centres())
        }
    });
    // which pixels of the ring are busy
    let linear = |s: Sum<T>| T::Colors::linear(s, 1);
    let five = |x: usize, y: usize| {
        [
            corners[y * cw + x],
            corners[y * cw + x + 1],
            corners[(y + 1) * cw + x],
            corners[(y + 1) * cw + x + 1],
            centres[y * rw + x],
        ]
    };
    let is_busy = |i: usize| {
        let c = five(i % rw, i / rw).map(linear);
        let hi = c.iter().fold(c[0], |a, b| a.max(*b));
        let lo = c.iter().fold(c[0], |a, b| a.min(*b));
        (hi - lo).max_element() > threshold as f64
    };
    let busy: Vec<bool> = with_threads(run.threads, || {
        if parallel() {
            (0..rw * rh).into_par_iter().map(is_busy).collect()
        } else {
            (0..rw * rh).map(is_busy).collect()
        }
    });
    // the busy pixels' grids, and which of their neighbours they make refine
    let fine = Samples::new(camera, fw, fh, n);
    let nn = (n * n) as usize;
    let mean5 = |x: usize, y: usize| {
        let sum = five(x, y).into_iter().fold(Default::default(), T::Colors::add);
        T::Colors::linear(sum, 5)
    };
    let flagged: Vec<AtomicBool> = (0..rw * rh).map(|_| AtomicBool::new(false)).collect();
    let busy_band = |k: usize| {
        let (mut stats, mut scratch) = (RenderStats::default(), T::Scratch::default());
        let mut grid = vec![Sum::<T>::default(); nn];
        let mut sums = Vec::new();
        for y in k * BAND..((k + 1) * BAND).min(rh) {
            for x in (0..rw).filter(|&x| busy[y * rw + x]) {
                let (sx, sy) = (ring.x0 as usize + x, ring.y0 as usize + y);
                let (sx, sy) = ((sx * n as usize) as u32, (sy * n as usize) as u32);
                trace_samples(tracer, &fine, sx, sy, n as usize, &mut grid, &mut scratch, &mut stats);
                sums.push((y * rw + x, grid.iter().fold(Default::default(), |a, &s| T::Colors::add(a, s))));
                flag_neighbours::<T>(&grid, n as usize, (x, y), (rw, rh), threshold, &busy, &flagged, mean5);
            }
        }
        add(&stats);
        sums
    };
    let bands = rh.div_ceil(BAND);
    let refined: Vec<Vec<(usize, Sum<T>)>> = with_threads(run.threads, || {
        if parallel() {
            (0..bands).into_par_iter().map(busy_band).collect()
        } else {
            (0..bands).map(busy_band).collect()
        }
    });
    let mut grid_sums = vec![None; rw * rh];
    for (i, sum) in refined.into_iter().flatten() {
        grid_sums[i] = Some(sum);
    }
    // the pixels
    let bar = progress_bar(run.progress, rect.height());
    let one = |(k, pixels): (usize, &mut [P])| {
        let (mut stats, mut scratch) = (RenderStats::default(), T::Scratch::default());
        let mut inside = vec![Sum::<T>::default(); nn];
        for (i, px) in pixels.iter_mut().enumerate() {
            let (x, y) = (
                rect.x0 as usize + i % width,
                rect.y0 as usize + k * BAND + i / width,
            );
            let (rx, ry) = (x - ring.x0 as usize, y - ring.y0 as usize);
            let r = ry * rw + rx;
            *px = if let Some(sum) = grid_sums[r] {
                P::resolve::<T::Colors>(sum, nn as u32)
            } else if flagged[r].load(Ordering::Relaxed) {
                let (sx, sy) = ((x * n as usize) as u32, (y * n as usize) as u32);
                trace_samples(tracer, &fine, sx, sy, n as usize, &mut inside, &mut scratch, &mut stats);
                let sum = inside.iter().fold(Default::default(), |a, &s| T::Colors::add(a, s));
                P::resolve::<T::Colors>(sum, nn as u32)
            } else {
                let sum = five(rx, ry).into_iter().fold(Default::default(), T::Colors::add);
                P::resolve::<T::Colors>(sum, 5)
            };
        }
        add(&stats);
        bar.inc((pixels.len() / width) as u64);
    };
    with_threads(run.threads, || {
        if parallel() {
            out.par_chunks_mut(width * BAND).enumerate().for_each(one);
        } else {
            out.chunks_mut(width * BAND).enumerate().for_each(one);
        }
    });
    bar.finish_and_clear();
    total.into_inner().expect("no panics while holding")
}

/// Flags the neighbours of the busy pixel (x, y) of a `w × h` ring that are not busy
/// themselves and whose mean (`mean`) one of the pixel's samples next to them, in its
/// `n × n` `grid`, differs from by more than `threshold`: an edge that leaves the pixel
/// toward that neighbour.
#[allow(clippy::too_many_arguments)]
fn flag_neighbours<T: SampleTracer>(
    grid: &[Sum<T>],
    n: usize,
    (x, y): (usize, usize),
    (w, h): (usize, usize),
    threshold: f32,
    busy: &[bool],
    flagged: &[AtomicBool],
    mean: impl Fn(usize, usize) -> DVec3,
) {
    // the rows or columns of the grid that face a neighbour at offset -1, 0 or +1
    let facing = |d: usize| match d {
        0 => 0..1,
        1 => 0..n,
        _ => n - 1..n,
    };
    for qy in y.saturating_sub(1)..(y + 2).min(h) {
        for qx in x.saturating_sub(1)..(x + 2).min(w) {
            let q = qy * w + qx;
            if busy[q] || flagged[q].load(Ordering::Relaxed) {
                continue;
            }
            let m = mean(qx, qy);
            let (cols, rows) = (facing(qx + 1 - x), facing(qy + 1 - y));
            let differs = rows.flat_map(|j| cols.clone().map(move |i| j * n + i)).any(|s| {
                let c = T::Colors::linear(grid[s], 1);
                (c - m).abs().max_element() > threshold as f64
            });
            if differs {
                flagged[q].store(true, Ordering::Relaxed);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use glam::DVec3;

    use super::super::{SampleBlock, Sampler, render_frame};
    use super::*;
    use crate::render::reference::RefColors;

    /// A picture given as a function of the image plane, in pixels of the frame
    /// (pixel (i, j) covers [i, i + 1) × [j, j + 1)).
    struct Picture<F> {
        frame: PixelGrid,
        f: F,
    }

    impl<F: Fn(f64, f64) -> f64 + Sync> Picture<F> {
        fn new(width: u32, height: u32, f: F) -> Self {
            Picture {
                frame: Camera::default().pixel_grid(width, height),
                f,
            }
        }
    }

    impl<F: Fn(f64, f64) -> f64 + Sync> SampleTracer for Picture<F> {
        type Scratch = ();
        type Colors = RefColors;
        fn trace_block(
            &self,
            samples: &Samples,
            block: SampleBlock,
            _: &mut (),
            stats: &mut RenderStats,
        ) -> RefColors {
            let g = &self.frame;
            RefColors(std::array::from_fn(|k| {
                if block.bits >> k & 1 == 0 {
                    return DVec3::ZERO;
                }
                let (x, y) = (block.x + k as u32 % 4, block.y + k as u32 / 4);
                let [dx, dy] = samples.offset(x, y);
                let p = samples.grid.point(x as f64 + dx, y as f64 + dy) - g.top_left;
                let u = p.dot(g.du) / g.du.length_squared() + 0.5;
                let v = p.dot(g.dv) / g.dv.length_squared() + 0.5;
                stats.shadow_rays += 1;
                DVec3::splat((self.f)(u, v))
            }))
        }
    }

    fn render<F: Fn(f64, f64) -> f64 + Sync>(
        pic: &Picture<F>,
        (w, h): (u32, u32),
        rect: PixelRect,
        sampler: Sampler,
    ) -> (Vec<DVec3>, RenderStats) {
        let mut out = vec![DVec3::ZERO; rect.area() as usize];
        let stats = render_frame(
            pic,
            &Camera::default(),
            w,
            h,
            rect,
            sampler,
            &mut out,
            Run::default(),
        );
        (out, stats)
    }

    const ADAPTIVE: Sampler = Sampler::Adaptive {
        n: 4,
        threshold: 0.1,
    };

    #[test]
    fn a_flat_picture_costs_its_corners_only() {
        let (w, h) = (21, 13);
        let pic = Picture::new(w, h, |_, _| 0.25);
        let (out, stats) = render(&pic, (w, h), PixelRect::full(w, h), ADAPTIVE);
        assert!(out.iter().all(|p| *p == DVec3::splat(0.25)));
        // the corners and the centres
        assert_eq!(stats.primary_rays, ((w + 1) * (h + 1) + w * h) as u64);
    }

    #[test]
    fn an_edge_is_refined_to_its_coverage_and_the_rest_is_exact() {
        // white left of u = 10.3: pixel column 10 is 30 % white
        let (w, h) = (24, 9);
        let pic = Picture::new(w, h, |u, _| if u < 10.3 { 1.0 } else { 0.0 });
        let (out, stats) = render(&pic, (w, h), PixelRect::full(w, h), ADAPTIVE);
        for y in 0..h as usize {
            for x in 0..w as usize {
                let v = out[y * w as usize + x].x;
                match x {
                    // the uniform 4 × 4 grid's pixel: one column of four is white
                    10 => assert_eq!(v, 0.25, "({x}, {y})"),
                    // busy (a corner jittered across the edge) or refined: exact here
                    9 | 11 => assert!(v == 1.0 || v == 0.0, "({x}, {y}): {v}"),
                    _ => assert_eq!(v, if x < 10 { 1.0 } else { 0.0 }, "({x}, {y})"),
                }
            }
        }
        // the first pass, and at most three columns of 16 samples
        let first = ((w + 1) * (h + 1) + w * h) as u64;
        assert!(stats.primary_rays > first);
        assert!(stats.primary_rays <= first + 3 * h as u64 * 16, "{stats:?}");
    }

    #[test]
    fn stripes_between_the_corners_are_found_by_their_busy_neighbours() {
        // horizontal stripes a third of a pixel wide, in a band of rows 8 to 16: a
        // regular lattice of corners, a pixel apart, sees one colour on some rows
        let (w, h) = (16, 24);
        let stripes = |_: f64, v: f64| {
            if (8.0..16.0).contains(&v) && (v * 3.0).floor() as i64 % 2 == 0 {
                1.0
            } else {
                0.0
            }
        };
        let pic = Picture::new(w, h, stripes);
        let (out, _) = render(&pic, (w, h), PixelRect::full(w, h), ADAPTIVE);
        for y in 9..15 {
            for x in 0..w as usize {
                let v = out[y * w as usize + x].x;
                // a third or two thirds white: never all or none
                assert!((0.2..=0.8).contains(&v), "({x}, {y}): {v}");
            }
        }
        assert_eq!(out[2 * w as usize].x, 0.0);
    }

    #[test]
    fn a_crop_equals_the_same_pixels_of_the_whole_frame() {
        let (w, h) = (30, 22);
        let pic = Picture::new(w, h, |u, v| {
            let d = ((u - 14.2).powi(2) + (v - 9.7).powi(2)).sqrt();
            if d < 7.3 { 0.9 } else { 0.1 + 0.01 * u }
        });
        let whole = render(&pic, (w, h), PixelRect::full(w, h), ADAPTIVE).0;
        for (x0, x1, y0, y1) in [
            (3, 17, 5, 12),
            (0, 1, 0, 22),
            (29, 30, 21, 22),
            (8, 9, 6, 7),
        ] {
            let rect = PixelRect { x0, x1, y0, y1 };
            let part = render(&pic, (w, h), rect, ADAPTIVE).0;
            for y in y0..y1 {
                for x in x0..x1 {
                    let a = part[((y - y0) * (x1 - x0) + x - x0) as usize];
                    assert_eq!(a, whole[(y * w + x) as usize], "({x}, {y}) of {rect:?}");
                }
            }
        }
    }

    #[test]
    fn jittered_samples_stay_in_their_cells_and_do_not_repeat() {
        let s = Samples {
            pattern: Pattern::Jittered { seed: 7 },
            ..Samples::new(&Camera::default(), 9, 9, 1)
        };
        let mut seen = Vec::new();
        for y in 0..9 {
            for x in 0..9 {
                let [dx, dy] = s.offset(x, y);
                assert!((-0.5..0.5).contains(&dx) && (-0.5..0.5).contains(&dy));
                assert_eq!(s.offset(x, y), [dx, dy], "a hash of the position");
                seen.push([dx.to_bits(), dy.to_bits()]);
            }
        }
        seen.sort_unstable();
        seen.dedup();
        assert_eq!(seen.len(), 81);
        let other = Samples {
            pattern: Pattern::Jittered { seed: 8 },
            ..s
        };
        assert_ne!(other.offset(3, 4), s.offset(3, 4));
    }
}
