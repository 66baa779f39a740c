//! Bounds of a clipped quadric's surface for the BVH: an ellipsoid's, or the sections
//! across clipped axes where they are bounded (a cylinder or cone cut in height, a
//! plane clipped along itself), conservative in f32 after f64 rounding bounds.

use glam::{DVec3, Vec3};

use super::terms;
use crate::geometry::BOUNDS_LIMIT;
use crate::math::Aabb;
use crate::math::float::{f32_down, f32_up};

/// Relative margin of [`ellipsoid_bounds`]' definiteness test.
const DEFINITE_MARGIN: f64 = 1e-8;

/// Bounds of {F = 0} when the quadratic part M is definite (an ellipsoid): centre
/// c = −M⁻¹g/2, half-extent along axis i √(k·(M⁻¹)ᵢᵢ) with k = −F(c), padded by a
/// relative 1e-5 against rounding. `k` holds the ten coefficients (f64).
///
/// Definite with a margin: each leading principal minor must exceed [`DEFINITE_MARGIN`]
/// times the sum of its terms' magnitudes, far above their f64 rounding error. A form
/// within rounding of singular (a tilted pair of parallel planes written with decimal
/// coefficients) could otherwise get the signs of an ellipsoid, and bounds from a
/// nearly singular inverse that the surface leaves (`tests/extremes.rs::
/// quadric_extremes`). A form failing the margin stays unbounded, beside the tree:
/// that costs time, never a hit. The margin also keeps the inverse's cancellation far
/// inside the pad.
pub(super) fn ellipsoid_bounds(k: &[f64; 10]) -> Option<Aabb> {
    let [a, b, c, d, e, f, g, h, i, _] = *k;
    let m = glam::DMat3::from_cols(
        DVec3::new(a, d / 2.0, e / 2.0),
        DVec3::new(d / 2.0, b, f / 2.0),
        DVec3::new(e / 2.0, f / 2.0, c),
    );
    let (hd, he, hf) = (d / 2.0, e / 2.0, f / 2.0);
    let m2 = a * b - hd * hd;
    let s2 = (a * b).abs() + hd * hd;
    let m3 = a * (b * c - hf * hf) - hd * (hd * c - hf * he) + he * (hd * hf - b * he);
    let s3 = (a * b * c).abs()
        + (a * hf * hf).abs()
        + (hd * hd * c).abs()
        + 2.0 * (hd * hf * he).abs()
        + (he * he * b).abs();
    let sign = if !(m2 > DEFINITE_MARGIN * s2 && m3.abs() > DEFINITE_MARGIN * s3) {
        return None;
    } else if a > 0.0 && m3 > 0.0 {
        1.0
    } else if a < 0.0 && m3 < 0.0 {
        -1.0
    } else {
        return None;
    };
    let m = m * sign;
    let g = DVec3::new(g, h, i) * sign;
    let inv = m.inverse();
    let centre = -(inv * g) / 2.0;
    // k = −F(c), evaluated as F itself: ∇F(c) = 0, so an error e in the centre (the
    // solve's, ~cond(M)·ε·|c|) changes it only by eᵀMe. The shortcut −(j + g·c/2)
    // takes e times |g| instead, and cut the tip off a tilted needle far from the
    // frame's origin. Raised by a bound on F's own rounding (ten terms summed: γ(12)·Σ|term|), so that far
    // from the origin, where the terms dwarf k, the box grows instead of shrinking.
    let (x, y, z) = (centre.x, centre.y, centre.z);
    let rounding = 12.0 * f64::EPSILON * terms(k, x, y, z, f64::abs);
    let kk = -sign * terms(k, x, y, z, |t| t) + rounding;
    if kk.is_nan() || kk <= 0.0 {
        return None;
    }
    let half =
        DVec3::new(inv.x_axis.x, inv.y_axis.y, inv.z_axis.z).map(|v| (kk * v).max(0.0).sqrt());
    if !(half.is_finite() && centre.is_finite()) {
        return None;
    }
    let pad = (half + centre.abs()) * 1e-5;
    let lo = centre - half - pad;
    let hi = centre + half + pad;
    rounded_out(lo, hi)
}

/// The stationary point of t ↦ q·t² + l·t, where it lies inside (lo, hi).
fn stationary(q: f64, l: f64, lo: f64, hi: f64) -> Option<f64> {
    let t = -l / (2.0 * q);
    (q != 0.0 && t > lo && t < hi).then_some(t)
}

/// Where q₀₀·w₀² + 2·q₀₁·w₀·w₁ + q₁₁·w₁² + l₀·w₀ + l₁·w₁ can take its extremes on the
/// rectangle [lo, hi]: its four corners (first), then its stationary points along the
/// edges and inside that lie in it.
fn rectangle_extremes(q: [f64; 3], l: [f64; 2], lo: [f64; 2], hi: [f64; 2]) -> Vec<[f64; 2]> {
    let [q00, q01, q11] = q;
    let [l0, l1] = l;
    let mut out = vec![
        [lo[0], lo[1]],
        [lo[0], hi[1]],
        [hi[0], lo[1]],
        [hi[0], hi[1]],
    ];
    for w0 in [lo[0], hi[0]] {
        // along the edge w0 fixed: q₁₁·w₁² + (l₁ + 2·q₀₁·w₀)·w₁ + …
        if let Some(t) = stationary(q11, l1 + 2.0 * q01 * w0, lo[1], hi[1]) {
            out.push([w0, t]);
        }
    }
    for w1 in [lo[1], hi[1]] {
        if let Some(t) = stationary(q00, l0 + 2.0 * q01 * w1, lo[0], hi[0]) {
            out.push([t, w1]);
        }
    }
    // inside: 2·Q·w = −l
    let det = q00 * q11 - q01 * q01;
    if det != 0.0 {
        let w0 = (-l0 * q11 + l1 * q01) / (2.0 * det);
        let w1 = (-l1 * q00 + l0 * q01) / (2.0 * det);
        if w0 > lo[0] && w0 < hi[0] && w1 > lo[1] && w1 < hi[1] {
            out.push([w0, w1]);
        }
    }
    out
}

/// `lo`..`hi` rounded outwards to f32; `None` unless finite.
fn rounded_out(lo: DVec3, hi: DVec3) -> Option<Aabb> {
    (lo.is_finite() && hi.is_finite()).then(|| {
        Aabb::new(
            Vec3::new(f32_down(lo.x), f32_down(lo.y), f32_down(lo.z)),
            Vec3::new(f32_up(hi.x), f32_up(hi.y), f32_up(hi.z)),
        )
    })
}

/// Bounds of {F = 0} inside a box that clips one or two axes and leaves the others
/// open, when the quadratic part restricted to the open axes U is definite: a cylinder,
/// cone, paraboloid or hyperboloid cut across its axis, the usual clipped quadric of a
/// scene file, which otherwise had no finite bounds and was tested by every ray beside
/// the tree. `box_lo`/`box_hi` in the frame of `k`, ±∞ on open axes.
///
/// Fixing the clipped coordinates w leaves a section in U (an ellipse, or two points
/// for one open axis): centre u*(w) = −½·M_UU⁻¹·(2·M_UC·w + g_U), affine in w, and
/// (u − u*)ᵀ·M_UU·(u − u*) = k(w), with k(w) = −F(u*(w), w) quadratic in w. So u_i stays
/// within u*_i(w) ± √(k(w)·(M_UU⁻¹)_ii): bounded by u* at the corners of the clipped
/// range and by the largest k over it, found among its corners and the stationary
/// points of k along its edges and inside ([`rectangle_extremes`]). k is evaluated as
/// F itself at the section's centre, as [`ellipsoid_bounds`] does (∇_U F = 0 there),
/// raised by F's rounding bound, and the result padded by the same relative 1e-5.
fn section_bounds(k: &[f64; 10], box_lo: DVec3, box_hi: DVec3) -> Option<Aabb> {
    let [a, b, c, d, e, f, _, _, _, _] = *k;
    let m = [
        [a, d / 2.0, e / 2.0],
        [d / 2.0, b, f / 2.0],
        [e / 2.0, f / 2.0, c],
    ];
    let g = [k[6], k[7], k[8]];
    let is_clipped = |i: usize| box_lo[i].is_finite() && box_hi[i].is_finite();
    let clipped: Vec<usize> = (0..3).filter(|&i| is_clipped(i)).collect();
    let open: Vec<usize> = (0..3).filter(|&i| !is_clipped(i)).collect();
    if clipped.is_empty() || open.is_empty() {
        return None;
    }
    // M_UU⁻¹ (row-major, n × n), for M_UU definite with a margin
    let inv: Vec<f64> = if let [u] = open[..] {
        let muu = m[u][u];
        if muu == 0.0 {
            return linear_section_bounds(k, &m, u, &clipped, box_lo, box_hi);
        }
        vec![1.0 / muu]
    } else {
        let (u, v) = (open[0], open[1]);
        let (p, q, r) = (m[u][u], m[u][v], m[v][v]);
        let det = p * r - q * q;
        // (false for NaN too)
        let definite = det > DEFINITE_MARGIN * ((p * r).abs() + q * q);
        if !definite {
            return None;
        }
        vec![r / det, -q / det, -q / det, p / det]
    };
    let n = open.len();
    // the section's centre for clipped coordinates w (in `clipped` order)
    let centre = |w: &[f64]| -> DVec3 {
        let mut p = DVec3::ZERO;
        for (ci, &axis) in clipped.iter().enumerate() {
            p[axis] = w[ci];
        }
        let rhs: Vec<f64> = open
            .iter()
            .map(|&u| {
                let coupled: f64 = clipped.iter().zip(w).map(|(&cx, &wc)| m[u][cx] * wc).sum();
                -(2.0 * coupled + g[u]) / 2.0
            })
            .collect();
        for (ui, &u) in open.iter().enumerate() {
            p[u] = (0..n).map(|uj| inv[ui * n + uj] * rhs[uj]).sum();
        }
        p
    };
    // k(w) = −F at the centre, with F's sign made that of a positive-definite M_UU,
    // raised by a bound on F's own rounding
    let sign = if inv[0] > 0.0 { 1.0 } else { -1.0 };
    let k_at = |w: &[f64]| {
        let p = centre(w);
        let rounding = 12.0 * f64::EPSILON * terms(k, p.x, p.y, p.z, f64::abs);
        -sign * terms(k, p.x, p.y, p.z, |t| t) + rounding
    };
    // k as a quadratic in w: k(w) = wᵀQw + qᵀw + q₀ (its vertices locate the candidates)
    let cdim = clipped.len();
    let coupling = |ci: usize, cj: usize| -> f64 {
        // ¼·B1ᵀ·M_UU⁻¹·B1 with B1 = 2·M_UC
        let mut s = 0.0;
        for ui in 0..n {
            for uj in 0..n {
                s += m[open[ui]][clipped[ci]] * inv[ui * n + uj] * m[open[uj]][clipped[cj]];
            }
        }
        sign * (s - m[clipped[ci]][clipped[cj]])
    };
    let linear = |ci: usize| -> f64 {
        let mut s = 0.0;
        for ui in 0..n {
            for uj in 0..n {
                s += m[open[ui]][clipped[ci]] * inv[ui * n + uj] * g[open[uj]];
            }
        }
        sign * (s - g[clipped[ci]])
    };
    let lo = |ci: usize| box_lo[clipped[ci]];
    let hi = |ci: usize| box_hi[clipped[ci]];
    // the clipped range's corners (where u* is extreme), then the other points where
    // k can be largest
    let (corners, mut candidates): (Vec<Vec<f64>>, Vec<Vec<f64>>) = if cdim == 1 {
        let inside = stationary(coupling(0, 0), linear(0), lo(0), hi(0));
        (
            vec![vec![lo(0)], vec![hi(0)]],
            inside.map(|t| vec![t]).into_iter().collect(),
        )
    } else {
        let q = [coupling(0, 0), coupling(0, 1), coupling(1, 1)];
        let extremes =
            rectangle_extremes(q, [linear(0), linear(1)], [lo(0), lo(1)], [hi(0), hi(1)]);
        let points: Vec<Vec<f64>> = extremes.iter().map(|w| w.to_vec()).collect();
        (points[..4].to_vec(), points[4..].to_vec())
    };
    candidates.extend(corners.iter().cloned());
    let k_max = candidates.iter().map(|w| k_at(w)).fold(0.0f64, f64::max);
    let (mut low, mut high) = (box_lo, box_hi);
    for (ui, &u) in open.iter().enumerate() {
        let half = (k_max * sign * inv[ui * n + ui]).max(0.0).sqrt();
        let (c_lo, c_hi) = corners
            .iter()
            .map(|w| centre(w)[u])
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), c| {
                (l.min(c), h.max(c))
            });
        // the centre's own rounding, where its terms cancel (a tilted cylinder far
        // along its axis: terms of 1e6 summing to a centre near 0)
        let magnitude = corners
            .iter()
            .map(|w| {
                (0..n)
                    .map(|uj| {
                        let coupled: f64 = clipped
                            .iter()
                            .zip(w)
                            .map(|(&cx, &wc)| (m[open[uj]][cx] * wc).abs())
                            .sum();
                        (inv[ui * n + uj] * (coupled + g[open[uj]].abs() / 2.0)).abs()
                    })
                    .sum::<f64>()
            })
            .fold(0.0f64, f64::max);
        let pad = (half + c_lo.abs().max(c_hi.abs())) * 1e-5 + 64.0 * f64::EPSILON * magnitude;
        low[u] = c_lo - half - pad;
        high[u] = c_hi + half + pad;
    }
    rounded_out(low, high)
}

/// [`section_bounds`] where the one open axis `u` enters F linearly and alone: no u²
/// and no cross term with the clipped axes (a plane clipped on the two axes along it,
/// as a wall or a mirror is written, or a parabolic cylinder cut across its axis). Then
/// F = g_u·u + c(w), and u = −c(w)/g_u over the clipped rectangle, c quadratic in w:
/// bounded by c at the rectangle's corners and at its stationary points along the
/// edges and inside; c is F itself at u = 0, raised by F's rounding bound, and the
/// result padded by the same relative 1e-5 as the other bounds.
fn linear_section_bounds(
    k: &[f64; 10],
    m: &[[f64; 3]; 3],
    u: usize,
    clipped: &[usize],
    box_lo: DVec3,
    box_hi: DVec3,
) -> Option<Aabb> {
    let gu = k[6 + u];
    let [c0, c1] = clipped[..] else {
        return None;
    };
    if gu == 0.0 || m[u][c0] != 0.0 || m[u][c1] != 0.0 {
        return None;
    }
    let (lo0, hi0, lo1, hi1) = (box_lo[c0], box_hi[c0], box_lo[c1], box_hi[c1]);
    // c(w) = Q00·w0² + 2·Q01·w0·w1 + Q11·w1² + l0·w0 + l1·w1 + …
    let (q00, q01, q11) = (m[c0][c0], m[c0][c1], m[c1][c1]);
    let (l0, l1) = (k[6 + c0], k[6 + c1]);
    let candidates = rectangle_extremes([q00, q01, q11], [l0, l1], [lo0, lo1], [hi0, hi1]);
    let (mut u_lo, mut u_hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for [w0, w1] in candidates {
        let mut p = DVec3::ZERO;
        p[c0] = w0;
        p[c1] = w1;
        let value = -terms(k, p.x, p.y, p.z, |t| t) / gu;
        let rounding = 12.0 * f64::EPSILON * terms(k, p.x, p.y, p.z, f64::abs) / gu.abs();
        u_lo = u_lo.min(value - rounding);
        u_hi = u_hi.max(value + rounding);
    }
    let pad = (u_hi - u_lo + u_lo.abs().max(u_hi.abs())) * 1e-5;
    let (mut low, mut high) = (box_lo, box_hi);
    low[u] = u_lo - pad;
    high[u] = u_hi + pad;
    rounded_out(low, high)
}

/// [`section_bounds`] for the box's own clipping and, with one further open axis taken
/// as clipped to ±[`BOUNDS_LIMIT`] (where the tree clamps every bound anyway),
/// for surfaces unbounded only along that axis: an unclipped vertical cylinder gets
/// its footprint in x and y. All finite results, intersected.
pub(super) fn open_axis_bounds(k: &[f64; 10], box_lo: DVec3, box_hi: DVec3) -> Option<Aabb> {
    let limit = f64::from(BOUNDS_LIMIT);
    let open: Vec<usize> = (0..3)
        .filter(|&i| !(box_lo[i].is_finite() && box_hi[i].is_finite()))
        .collect();
    let mut out: Option<Aabb> = None;
    // the box as it is, and each open axis on its own taken as clipped (an unclipped
    // axis plane, unbounded along two axes, would get a slab as large as the limit: in
    // the tree it slowed scenes/quadric_plane.txt by a third, 5.4 -> 7.3 ms, so it
    // stays beside it)
    for subset in (0..(1u32 << open.len())).filter(|s| s.count_ones() <= 1) {
        let (mut lo, mut hi) = (box_lo, box_hi);
        for (bit, &axis) in open.iter().enumerate() {
            if subset & (1 << bit) != 0 {
                lo[axis] = -limit;
                hi[axis] = limit;
            }
        }
        let Some(b) = section_bounds(k, lo, hi) else {
            continue;
        };
        // only a footprint along an axis not taken as clipped is worth a box: one far
        // below the limit (an unclipped cone or saddle gets bounds near the limit on
        // every axis, which cull nothing: it stays beside the tree)
        let footprint = (0..3).any(|i| {
            let assumed = open
                .iter()
                .position(|&a| a == i)
                .is_some_and(|bit| subset & (1 << bit) != 0);
            !assumed && b.hi[i] - b.lo[i] < BOUNDS_LIMIT / 1024.0
        });
        if footprint {
            out = Some(match out {
                Some(o) => Aabb::new(o.lo.max(b.lo), o.hi.min(b.hi)),
                None => b,
            });
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::quadric::{Quadric32, along};
    use crate::math::test_rng::Xorshift;
    use crate::scene::Quadric;

    fn quadric(coef: [f64; 10], min: [f64; 3], size: [f64; 3]) -> Quadric {
        Quadric {
            coef,
            min: DVec3::from(min),
            size: DVec3::from(size),
        }
    }

    /// The section bounds of `coef` clipped to [min, min + size] (size 0: open), in
    /// the quadric's own frame.
    fn section(coef: [f64; 10], min: [f64; 3], size: [f64; 3]) -> Option<Aabb> {
        Quadric32::new(&quadric(coef, min, size), DVec3::ZERO).bounds()
    }

    fn assert_near(b: Option<Aabb>, lo: [f32; 3], hi: [f32; 3]) {
        let b = b.expect("bounded");
        let close = |x: Vec3, y: Vec3| (x - y).abs().max_element() < 1e-3;
        assert!(
            close(b.lo, Vec3::from(lo)) && close(b.hi, Vec3::from(hi)),
            "{b:?}"
        );
    }

    #[test]
    fn quadrics_cut_across_their_axis_are_bounded() {
        // a cylinder x² + y² = 1, cut at z in [0, 5]
        let cyl = [1., 1., 0., 0., 0., 0., 0., 0., 0., -1.];
        assert_near(
            section(cyl, [0., 0., 0.], [0., 0., 5.]),
            [-1., -1., 0.],
            [1., 1., 5.],
        );
        // the cone x² + y² = z², cut at z in [1, 3]; the paraboloid z = x² + y², z ≤ 4
        let cone = [1., 1., -1., 0., 0., 0., 0., 0., 0., 0.];
        assert_near(
            section(cone, [0., 0., 1.], [0., 0., 2.]),
            [-3., -3., 1.],
            [3., 3., 3.],
        );
        let bowl = [1., 1., 0., 0., 0., 0., 0., 0., -1., 0.];
        assert_near(
            section(bowl, [0., 0., 0.], [0., 0., 4.]),
            [-2., -2., 0.],
            [2., 2., 4.],
        );
        // x² − y² + z² = 1 cut at x, y in [−2, 2]: z² ≤ 1 + 4 (two open-axis roots)
        let saddle = [1., -1., 1., 0., 0., 0., 0., 0., 0., -1.];
        let r = 5f32.sqrt();
        assert_near(
            section(saddle, [-2., -2., 0.], [4., 4., 0.]),
            [-2., -2., -r],
            [2., 2., r],
        );
        // a cylinder along x, cut at z or not at all: its footprint in y and z, and the
        // tree's limit along x
        let x_cyl = [0., 1., 1., 0., 0., 0., 0., 0., 0., -1.];
        let limit = crate::geometry::BOUNDS_LIMIT;
        for size in [[0., 0., 2.], [0.; 3]] {
            assert_near(
                section(x_cyl, [0., 0., -1.], size),
                [-limit, -1., -1.],
                [limit, 1., 1.],
            );
        }
        // an unclipped plane stays unbounded (beside the tree); clipped along itself (a
        // wall), a plane is bounded across it: x + 2y − 4 = 0 for y in [0, 3], z in
        // [0, 1]: x in [−2, 4]
        let plane = [0., 0., 0., 0., 0., 0., 0., 0., 1., -1.];
        assert_eq!(section(plane, [0.; 3], [0.; 3]), None);
        let wall = [0., 0., 0., 0., 0., 0., 1., 2., 0., -4.];
        assert_near(
            section(wall, [0., 0., 0.], [0., 3., 1.]),
            [-2., 0., 0.],
            [4., 3., 1.],
        );
        // z = y² − x², cut at x, y in [−1, 2]: z in [−4, 4]
        let saddle = [-1., 1., 0., 0., 0., 0., 0., 0., -1., 0.];
        assert_near(
            section(saddle, [-1., -1., 0.], [3., 3., 0.]),
            [-1., -1., -4.],
            [2., 2., 4.],
        );
    }

    /// Points of random quadrics cut on one or two axes or none, found by solving F
    /// along random lines in f64, all lie in their section bounds (in the frame of a camera at the
    /// origin or far away); and most such quadrics get bounds.
    #[test]
    fn section_bounds_hold_every_surface_point() {
        let mut rng = Xorshift(0x9e37_79b9_7f4a_7c15);
        let mut rand = move || rng.f64() * 2.0 - 1.0;
        let (mut bounded, mut points) = (0, 0);
        for trial in 0..400 {
            let mut coef = [0.0; 10];
            coef.iter_mut().for_each(|c| *c = rand() * 3.0);
            // a third of them cylinders and cones along an axis: zero cross terms
            if trial % 3 == 0 {
                coef[3..6].iter_mut().for_each(|c| *c = 0.0);
            }
            // cut on one or two axes, or (every fifth) on none
            let axes = if trial % 5 == 4 { 0 } else { 1 + trial % 2 };
            let mut min = [0.0; 3];
            let mut size = [0.0; 3];
            for i in 0..axes {
                let axis = (trial / 2 + i) % 3;
                min[axis] = rand() * 4.0;
                size[axis] = 0.1 + rand().abs() * 5.0;
            }
            // every seventh: the open axes enter F linearly (no square, no cross term:
            // a plane clipped along itself, a parabolic cylinder cut across its axis)
            if trial % 7 == 6 {
                // the coefficients of x², y², z² and of the cross terms xy, xz, yz
                let (square, cross) = ([0, 1, 2], [[3, 4], [3, 5], [4, 5]]);
                for a in (0..3).filter(|&a| size[a] == 0.0) {
                    coef[square[a]] = 0.0;
                    cross[a].iter().for_each(|&c| coef[c] = 0.0);
                }
            }
            let q = quadric(coef, min, size);
            // in the frame of a camera at the origin, or 1e5 away (every third)
            let base = if trial % 3 == 1 {
                DVec3::new(3e5, -2e5, 1e5)
            } else {
                DVec3::ZERO
            };
            let Some(b) = Quadric32::new(&q, base).bounds() else {
                continue;
            };
            bounded += 1;
            let (lo, hi) = (b.lo.as_dvec3() + base, b.hi.as_dvec3() + base);
            for _ in 0..300 {
                // a random line through the clipped slab, far out along the open axes
                let mut o = DVec3::ZERO;
                let mut d = DVec3::ZERO;
                for i in 0..3 {
                    o[i] = if size[i] > 0.0 {
                        min[i] + size[i] * (rand() + 1.0) / 2.0
                    } else {
                        rand() * 1e3
                    };
                    d[i] = if size[i] > 0.0 { rand() * 1e-3 } else { rand() };
                }
                let (a2, b1, c0) = along(&q.coef, o.to_array(), d.to_array());
                let disc = b1 * b1 - 4.0 * a2 * c0;
                if a2 == 0.0 || disc < 0.0 {
                    continue;
                }
                let qq = -0.5 * (b1 + disc.sqrt().copysign(b1));
                for t in [qq / a2, c0 / qq] {
                    let p = o + d * t;
                    let inside = (0..3)
                        .all(|i| size[i] == 0.0 || (p[i] >= min[i] && p[i] <= min[i] + size[i]));
                    if !inside || !p.is_finite() {
                        continue;
                    }
                    points += 1;
                    assert!(
                        p.cmpge(lo).all() && p.cmple(hi).all(),
                        "trial {trial}: {p} outside {lo}..{hi} ({coef:?}, {min:?}, {size:?})"
                    );
                }
            }
        }
        assert!(bounded > 100, "{bounded} of 400 bounded");
        assert!(points > 10_000, "{points} points checked");
    }
}
