//! The adaptive sampler ([`super::Sampler::Adaptive`]): one sample per pixel first, then
//! the uniform `n × n` grid inside the pixels that need it, found in waves.
//!
//! The first pass traces the pixels' corners, each shared by the four pixels that meet
//! there and jittered inside its cell: a regular lattice aliases with a regular picture
//! (the checkerboard toward the horizon, its reflections), where whole rows of samples
//! then agree. A pixel is *busy* when its four corners differ by more than the threshold
//! in some channel. The first wave samples the busy pixels as [`super::Sampler::Uniform`]
//! samples them; each later wave samples the pixels next to the last wave's whose own
//! corners agree but differ by more than the threshold from one of the last wave's
//! samples facing them: an edge or a thin feature that leaves a refined pixel toward its
//! neighbour, followed until it fades or [`WAVES`] waves are done. Any other pixel is the
//! mean of its corners.
//!
//! A pixel's result reads only the first pass of the pixels up to `WAVES - 1` away (the
//! waves that can reach it), traced here the same way for any rectangle, so a crop
//! equals the same pixels of the whole frame.

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

/// Pixel rows per parallel task of the first pass and of the output.
const BAND: usize = 4;

/// Waves of refinement: the busy pixels, then up to `WAVES - 1` steps along what they
/// found. A pixel's result depends on the pixels up to `WAVES - 1` away.
pub const WAVES: u32 = 4;

/// Refined pixels per parallel task of a wave.
const WAVE_CHUNK: usize = 16;

/// Seed of the corners' positions ([`Pattern::Jittered`]).
const CORNER_SEED: u64 = 0xC0C0_0A7E_5EED_0001;

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

/// What a task of a wave found: the refined pixels' sums, and the next wave's pixels.
struct WaveOut<S> {
    sums: Vec<(usize, S)>,
    next: Vec<usize>,
}

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
    // the rectangle and the pixels whose waves can reach it
    let reach = WAVES - 1;
    let ring = PixelRect {
        x0: rect.x0.saturating_sub(reach),
        x1: (rect.x1 + reach).min(frame.x1),
        y0: rect.y0.saturating_sub(reach),
        y1: (rect.y1 + reach).min(frame.y1),
    };
    let (rw, rh) = (ring.width() as usize, ring.height() as usize);
    let cw = rw + 1;
    let corner_samples = Samples {
        grid: corner_grid(camera, fw, fh),
        n: 1,
        pattern: Pattern::Jittered { seed: CORNER_SEED },
    };
    let total = Mutex::new(RenderStats::default());
    let add = |s: &RenderStats| total.lock().expect("no panics while holding").add(s);
    let corners = with_threads(run.threads, || {
        first_pass(
            tracer,
            &corner_samples,
            (ring.x0, ring.y0),
            (cw, rh + 1),
            &add,
        )
    });
    let four = |x: usize, y: usize| {
        let c = y * cw + x;
        [
            corners[c],
            corners[c + 1],
            corners[c + cw],
            corners[c + cw + 1],
        ]
    };
    // an unrefined pixel: the sum of its four corners
    let corner_sum = |x: usize, y: usize| {
        four(x, y)
            .into_iter()
            .fold(Default::default(), T::Colors::add)
    };
    let mean = |x: usize, y: usize| T::Colors::linear(corner_sum(x, y), 4);
    // the busy pixels of ring row y, as ring indices
    let busy_in_row = |y: usize| {
        let linear = |row: usize| -> Vec<DVec3> {
            corners[row * cw..][..cw]
                .iter()
                .map(|&s| T::Colors::linear(s, 1))
                .collect()
        };
        let (above, below) = (linear(y), linear(y + 1));
        (0..rw)
            .filter(|&x| {
                let hi = above[x].max(above[x + 1]).max(below[x].max(below[x + 1]));
                let lo = above[x].min(above[x + 1]).min(below[x].min(below[x + 1]));
                (hi - lo).max_element() > threshold as f64
            })
            .map(|x| y * rw + x)
            .collect::<Vec<usize>>()
    };
    let busy: Vec<usize> = with_threads(run.threads, || {
        if parallel() {
            (0..rh).into_par_iter().flat_map_iter(busy_in_row).collect()
        } else {
            (0..rh).flat_map(busy_in_row).collect()
        }
    });
    // the waves: each pixel of a wave sampled n × n, its sum kept
    let fine = Samples::new(camera, fw, fh, n);
    let nn = (n * n) as usize;
    let taken: Vec<AtomicBool> = (0..rw * rh).map(|_| AtomicBool::new(false)).collect();
    for &i in &busy {
        taken[i].store(true, Ordering::Relaxed);
    }
    let mut refined: Vec<Option<Sum<T>>> = vec![None; rw * rh];
    // pixels from the ring pixel (x, y) to the rectangle (0 inside)
    let ring_distance = |x: usize, y: usize| {
        let (x, y) = ((ring.x0 as usize + x) as i64, (ring.y0 as usize + y) as i64);
        let out_x = (rect.x0 as i64 - x).max(x + 1 - rect.x1 as i64).max(0);
        let out_y = (rect.y0 as i64 - y).max(y + 1 - rect.y1 as i64).max(0);
        out_x.max(out_y) as usize
    };
    let mut wave = busy;
    // progress: the pixels refined so far of those known to refine
    let bar = progress_bar(run.progress, 0, "pixels refined");
    for k in 0..WAVES as usize {
        bar.inc_length(wave.len() as u64);
        // a pixel of the next wave matters only if it can still reach the rectangle
        let reaches = |x: usize, y: usize| ring_distance(x, y) + k + 2 <= WAVES as usize;
        // a task's scratch and sample grid, reused over its chunks
        let init = || (T::Scratch::default(), vec![Sum::<T>::default(); nn]);
        let chunk = |(scratch, grid): &mut (T::Scratch, Vec<Sum<T>>), ids: &[usize]| {
            let mut stats = RenderStats::default();
            let (mut sums, mut next) = (Vec::with_capacity(ids.len()), Vec::new());
            for &i in ids {
                let (x, y) = (i % rw, i / rw);
                let (sx, sy) = (ring.x0 as usize + x, ring.y0 as usize + y);
                let (sx, sy) = ((sx * n as usize) as u32, (sy * n as usize) as u32);
                trace_samples(tracer, &fine, sx, sy, n as usize, grid, scratch, &mut stats);
                sums.push((
                    i,
                    grid.iter()
                        .fold(Default::default(), |a, &s| T::Colors::add(a, s)),
                ));
                if k + 1 < WAVES as usize {
                    let facing = Facing {
                        grid,
                        n: n as usize,
                        at: (x, y),
                        ring: (rw, rh),
                    };
                    facing.differing::<T::Colors>(threshold, &taken, &mean, &reaches, &mut next);
                }
            }
            add(&stats);
            bar.inc(ids.len() as u64);
            WaveOut { sums, next }
        };
        let done: Vec<WaveOut<Sum<T>>> = with_threads(run.threads, || {
            if parallel() {
                wave.par_chunks(WAVE_CHUNK).map_init(init, chunk).collect()
            } else {
                let mut state = init();
                wave.chunks(WAVE_CHUNK)
                    .map(|ids| chunk(&mut state, ids))
                    .collect()
            }
        });
        wave = Vec::new();
        for out in done {
            for (i, sum) in out.sums {
                refined[i] = Some(sum);
            }
            wave.extend(out.next);
        }
        if wave.is_empty() {
            break;
        }
        wave.sort_unstable();
    }
    bar.finish_and_clear();
    // the pixels
    let one = |(k, pixels): (usize, &mut [P])| {
        for (j, row) in pixels.chunks_mut(width).enumerate() {
            let y = rect.y0 as usize + k * BAND + j - ring.y0 as usize;
            let x0 = (rect.x0 - ring.x0) as usize;
            for (x, px) in (x0..).zip(row) {
                *px = match refined[y * rw + x] {
                    Some(sum) => P::resolve::<T::Colors>(sum, nn as u32),
                    None => P::resolve::<T::Colors>(corner_sum(x, y), 4),
                };
            }
        }
    };
    with_threads(run.threads, || {
        if parallel() {
            out.par_chunks_mut(width * BAND).enumerate().for_each(one);
        } else {
            out.chunks_mut(width * BAND).enumerate().for_each(one);
        }
    });
    total.into_inner().expect("no panics while holding")
}

/// The `n × n` samples of a refined pixel at `at` of a `ring`-sized rectangle.
struct Facing<'a, S> {
    grid: &'a [S],
    n: usize,
    at: (usize, usize),
    ring: (usize, usize),
}

impl<S: Copy> Facing<'_, S> {
    /// Adds to `next`, and marks taken, each neighbour not yet taken (and that `reaches`
    /// the rendered rectangle in the waves left) that one of the
    /// samples facing it (the grid's row, column or corner next to it) differs from by
    /// more than `threshold` in some channel, the neighbour given by its `mean`.
    fn differing<C: SampleColors<Sum = S>>(
        &self,
        threshold: f32,
        taken: &[AtomicBool],
        mean: &impl Fn(usize, usize) -> DVec3,
        reaches: &impl Fn(usize, usize) -> bool,
        next: &mut Vec<usize>,
    ) {
        let ((x, y), (w, h), n) = (self.at, self.ring, self.n);
        // the grid's rows or columns that face a neighbour at offset -1, 0 or +1
        let facing = |d: usize| match d {
            0 => 0..1,
            1 => 0..n,
            _ => n - 1..n,
        };
        for qy in y.saturating_sub(1)..(y + 2).min(h) {
            for qx in x.saturating_sub(1)..(x + 2).min(w) {
                let q = qy * w + qx;
                if taken[q].load(Ordering::Relaxed) || !reaches(qx, qy) {
                    continue;
                }
                let m = mean(qx, qy);
                let (cols, rows) = (facing(qx + 1 - x), facing(qy + 1 - y));
                let differs = rows
                    .flat_map(|j| cols.clone().map(move |i| j * n + i))
                    .any(|s| {
                        (C::linear(self.grid[s], 1) - m).abs().max_element() > threshold as f64
                    });
                if differs && !taken[q].swap(true, Ordering::Relaxed) {
                    next.push(q);
                }
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
        // the corners
        assert_eq!(stats.primary_rays, ((w + 1) * (h + 1)) as u64);
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
        let first = ((w + 1) * (h + 1)) as u64;
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
    fn a_line_is_followed_from_its_busy_pixels_for_waves_minus_one_pixels() {
        // a horizontal line half a pixel wide through pixel row 10 (v in [10.25, 10.75)):
        // each corner of the row falls on it with chance 1/4, so busy pixels (some but
        // not all corners on it) are scattered along it. The grid's rows at v = 10.375
        // and 10.625 are on it: a refined pixel of the row is 0.5.
        let (w, h) = (64, 21);
        let on_line = |v: f64| (10.25..10.75).contains(&v);
        let pic = Picture::new(w, h, |_, v| if on_line(v) { 1.0 } else { 0.0 });
        let (out, stats) = render(&pic, (w, h), PixelRect::full(w, h), ADAPTIVE);
        let corner = Samples {
            grid: corner_grid(&Camera::default(), w, h),
            n: 1,
            pattern: Pattern::Jittered { seed: CORNER_SEED },
        };
        let on = |x: u32, y: u32| on_line(y as f64 + corner.offset(x, y)[1]) as u32;
        let busy: Vec<i64> = (0..w)
            .filter(|&x| (1..4).contains(&(on(x, 10) + on(x + 1, 10) + on(x, 11) + on(x + 1, 11))))
            .map(i64::from)
            .collect();
        let reach = i64::from(WAVES - 1);
        let mut followed = 0;
        for x in 0..i64::from(w) {
            let v = out[10 * w as usize + x as usize].x;
            let near = busy
                .iter()
                .map(|b| (b - x).abs())
                .min()
                .expect("busy pixels");
            if near <= reach {
                assert_eq!(v, 0.5, "pixel {x}, {near} from a busy pixel");
                followed += u32::from(near > 0);
            } else {
                assert_eq!(
                    v, 0.0,
                    "pixel {x}, {near} from a busy pixel: beyond the waves"
                );
            }
        }
        assert!(followed > 0, "the waves refined pixels that were not busy");
        // nothing away from the line is refined
        for y in (0..h as usize).filter(|y| !(9..=11).contains(y)) {
            assert!(
                out[y * w as usize..][..w as usize]
                    .iter()
                    .all(|p| p.x == 0.0)
            );
        }
        let first = ((w + 1) * (h + 1)) as u64;
        assert!(stats.primary_rays <= first + 3 * w as u64 * 16, "{stats:?}");
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
