//! General quadric: `general A B C D E F G H I J  rx ry rz  length width height`
//! then the material.
//!
//! F(x,y,z) = Ax² + By² + Cz² + Dxy + Exz + Fyz + Gx + Hy + Iz + J = 0, clipped to the box
//! x ∈ [rx, rx+length], y ∈ [ry, ry+width], z ∈ [rz, rz+height]; a dimension of 0 does
//! not clip. Of the two roots the nearer positive one counts if its point is in the
//! box, else the farther positive one if its point is in the box (so a clipped
//! ellipsoid shows its inside). The coefficients were divided by their largest
//! magnitude at load; the normal is ∇F.
//!
//! Along a ray, F(o + t·d) = a·t² + b·t + c with a = Q(d) (the quadratic part),
//! b = ∇F(o)·d and c = F(o).

use glam::DVec3;

use glam::Vec3;
use wide::{f32x8, f64x8};

use super::{Surface8, Surface32, SurfacePoint};
use crate::bvh::Aabb;
use crate::math::Ray;
use crate::math::float::gamma;
use crate::math::packet::{Cmp8, Mask8, Ray1, RayPacket8, Vec3x8, gamma32};
use crate::scene::Quadric;

// ---------------------------------------------------------------- reference (f64)

/// The roots of a·t² + b·t + c = 0 in ascending order, computed stably
/// (q = −(b + sign(b)√Δ)/2, roots q/a and c/q); linear when a is exactly 0.
pub fn solve_quadratic(a: f64, b: f64, c: f64) -> Option<(f64, f64)> {
    if a == 0.0 {
        if b == 0.0 {
            return None;
        }
        let t = -c / b;
        return Some((t, t));
    }
    let disc = b.mul_add(b, -4.0 * a * c);
    if disc < 0.0 {
        return None;
    }
    let q = -0.5 * (b + b.signum() * disc.sqrt());
    if q == 0.0 {
        // b = 0 and Δ = 0, so c = 0: a double root at 0.
        return Some((0.0, 0.0));
    }
    let (r0, r1) = (q / a, c / q);
    Some(if r0 <= r1 { (r0, r1) } else { (r1, r0) })
}

/// Both roots (ascending) of F(o + t·d) = a·t² + b·t + c, unclipped (also the fast
/// path's floor tie arbiter, `PrimSet::floor_first`).
pub fn roots_ref(q: &Quadric, o: DVec3, d: DVec3) -> Option<(f64, f64)> {
    // coefficients of F along the ray
    let [qa, qb, qc, qd, qe, qf, ..] = q.coef;
    let a = qa * d.x * d.x
        + qb * d.y * d.y
        + qc * d.z * d.z
        + qd * d.x * d.y
        + qe * d.x * d.z
        + qf * d.y * d.z;
    let b = q.gradient(o).dot(d);
    let c = q.value(o);
    solve_quadratic(a, b, c)
}

/// Nearest t with 0 < t < t_max under the box-clipping root rule.
pub fn intersect_ref(q: &Quadric, ray: &Ray, t_max: f64) -> Option<f64> {
    // the all-zero quadric is never hit
    if q.is_degenerate() {
        return None;
    }
    // solve for both roots
    let (t0, t1) = roots_ref(q, ray.origin, ray.dir)?;
    // nearer positive root in the box, else the farther one
    [t0, t1]
        .into_iter()
        .filter(|&t| t > 0.0 && t < t_max)
        .find(|&t| q.in_box(ray.at(t)))
}

/// Surface at distance t. The error bound is measured after the fact: how far the
/// computed point can be from the surface along the normal, |F(p)| plus the rounding
/// error of evaluating F, divided by |∇F|.
pub fn surface_ref(q: &Quadric, ray: &Ray, t: f64) -> SurfacePoint {
    let point = ray.at(t);
    let grad = q.gradient(point);
    let glen = grad.length();
    let normal = if glen > 0.0 && glen.is_finite() {
        grad / glen
    } else {
        -ray.dir // singular point (a cone's apex): no normal; face the ray
    };
    let magnitude = terms(&q.coef, point.x, point.y, point.z, f64::abs);
    let dist = if glen > 0.0 && glen.is_finite() {
        2.0 * (q.value(point).abs() + gamma(12) * magnitude) / glen
    } else {
        gamma(16) * point.abs().max_element()
    };
    let err = DVec3::splat(dist) + point.abs() * gamma(1);
    SurfacePoint { point, normal, err }
}

// ------------------------------------------------- fast path (f32 rays, f64 roots)

/// A quadric of the fast path: f32 rays in, f32 distances and surfaces out, solved in
/// f64: the coefficients of F(x + base), renormalised by their largest magnitude, and
/// the clipping box (±∞ on unclipped axes).
///
/// Why f64: along a ray, c = F(o) grows as |o|² while b² − 4ac stays of the quadric's
/// own size, so in f32 the discriminant is lost to cancellation when a ray starts far
/// from a small quadric. Shadow rays from a floor hundreds of units away that passed a
/// cylinder of radius 0.03 at 12–36 % of its radius still hit it: 141 of 4096 pixels
/// off, max 30/255, in `fast` and `accurate` at 64² (an independent renderer of the spec
/// found it; `tests/extremes.rs` keeps the case). An f32 ray is exact in f64, so the
/// roots are as good as the reference's for that ray, and the surface's error bound,
/// evaluated in f64 at the hit point, measures the point's own distance from the surface
/// instead of f32's rounding of F far from the origin. Both kernels convert, compute and
/// round lane for lane alike, so packet and single ray stay bit-equal.
// Tried: an f32 pre-test on packets, dropping lanes whose f32 discriminant lies below
// zero by more than a rigorous bound on its error (same images): quadric_hyperboloid
// 1024², 1 thread, six interleaved pairs, median 0.159 -> 0.188 s. Most lines meet a
// hyperboloid of one sheet (its roots are then rejected by t or the box), so the test
// rarely saves the f64 solve it adds to.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Quadric32 {
    pub coef: [f64; 10],
    /// The clipping box, relative to base, in f64 (the root rule).
    pub box_lo: DVec3,
    pub box_hi: DVec3,
    /// Whether the box clips some axis (else the root rule's box test always passes
    /// and is skipped).
    pub clipped: bool,
    /// The clipping box rounded outwards to f32 (bounds).
    pub lo: Vec3,
    pub hi: Vec3,
    /// Bounds of the surface when it is an ellipsoid (then it can live in the BVH even
    /// when the box leaves an axis unclipped).
    pub ellipsoid: Option<Aabb>,
    /// Bounds of the surface inside a box that clips some axes, where the sections
    /// across them are bounded ([`section_bounds`]: a cylinder cut across its axis).
    pub section: Option<Aabb>,
}

/// The ten terms of F = Ax² + By² + Cz² + Dxy + Exz + Fyz + Gx + Hy + Iz + J at (x, y, z),
/// each passed through `f` and summed in this order, in any precision: F itself (`f`
/// the identity) or Σ|term| (`f` = abs), the scale of F's rounding error.
#[inline(always)]
fn terms<T: Lanes>(k: &[f64; 10], x: T, y: T, z: T, f: impl Fn(T) -> T) -> T {
    let c = |i: usize| T::k(k[i]);
    f(c(0) * x * x)
        + f(c(1) * y * y)
        + f(c(2) * z * z)
        + f(c(3) * x * y)
        + f(c(4) * x * z)
        + f(c(5) * y * z)
        + f(c(6) * x)
        + f(c(7) * y)
        + f(c(8) * z)
        + f(c(9))
}

/// Relative margin of [`ellipsoid_bounds`]' definiteness test.
const DEFINITE_MARGIN: f64 = 1e-8;

/// Bounds of {F = 0} when the quadratic part M is definite (an ellipsoid): centre
/// c = −M⁻¹g/2, half-extent along axis i √(k·(M⁻¹)ᵢᵢ) with k = −F(c), padded by a
/// relative 1e-5 against rounding. `k` holds the ten coefficients (f64).
///
/// Definite with a margin: each leading principal minor must exceed [`DEFINITE_MARGIN`]
/// times the sum of its terms' magnitudes, far above their f64 rounding error (~1e-15
/// of that sum, while the sum stays out of the subnormal range; below it the test
/// degrades to the minors' signs, and a form that slips through gets half-extents so
/// large that `BOUNDS_LIMIT` clamps them). A form within rounding of singular (a tilted pair of parallel planes
/// written with decimal coefficients: exact minors 5.2e-3, 1e-19 and −1.4e-33) could
/// otherwise get the signs of an ellipsoid, and bounds from the inverse of a nearly
/// singular matrix that the surface leaves: rays outside them never tested it, so it
/// and its shadows vanished from the fast path (an independent renderer of the spec
/// found it; `tests/extremes.rs::quadric_extremes` keeps the case). A form failing
/// the margin (a strongly elongated ellipsoid tilted off the axes may too) stays
/// unbounded, in the list beside the tree: that costs time, never a hit. The margin
/// also keeps the cancellation in the inverse (rounding ~1e-16 over at least 1e-8)
/// far inside the pad.
fn ellipsoid_bounds(k: &[f64; 10]) -> Option<Aabb> {
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
    // takes e times |g| instead: for a tilted needle (semi-axes 0.01 and 5) 1000
    // units from the frame's origin, k came out tens of percent small and the box
    // cut the needle's tip off (found by an independent renderer of the spec). Raised
    // by a bound on F's own rounding (ten terms summed: γ(12)·Σ|term|), so that far
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
/// as clipped to ±[`super::BOUNDS_LIMIT`] (where the tree clamps every bound anyway),
/// for surfaces unbounded only along that axis: an unclipped vertical cylinder gets
/// its footprint in x and y. All finite results, intersected.
fn open_axis_bounds(k: &[f64; 10], box_lo: DVec3, box_hi: DVec3) -> Option<Aabb> {
    let limit = f64::from(super::BOUNDS_LIMIT);
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
            !assumed && b.hi[i] - b.lo[i] < super::BOUNDS_LIMIT / 1024.0
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

/// Arithmetic shared by the single-ray (f64) and packet (f64x8) quadric kernels, so
/// that both evaluate the same expressions in the same order.
trait Lanes: Copy + std::ops::Add<Output = Self> + std::ops::Mul<Output = Self> {
    fn k(v: f64) -> Self;
}

impl Lanes for f64 {
    #[inline(always)]
    fn k(v: f64) -> f64 {
        v
    }
}

impl Lanes for f64x8 {
    #[inline(always)]
    fn k(v: f64) -> f64x8 {
        f64x8::splat(v)
    }
}

/// ∇F at p.
#[inline(always)]
fn gradient<T: Lanes>(k: &[f64; 10], p: [T; 3]) -> [T; 3] {
    let c = |i: usize| T::k(k[i]);
    let two = T::k(2.0);
    let [x, y, z] = p;
    [
        two * c(0) * x + c(3) * y + c(4) * z + c(6),
        two * c(1) * y + c(3) * x + c(5) * z + c(7),
        two * c(2) * z + c(4) * x + c(5) * y + c(8),
    ]
}

/// a, b and c of F(o + t·d) = a·t² + b·t + c.
#[inline(always)]
fn along<T: Lanes>(k: &[f64; 10], o: [T; 3], d: [T; 3]) -> (T, T, T) {
    let c = |i: usize| T::k(k[i]);
    let [dx, dy, dz] = d;
    let a = c(0) * dx * dx
        + c(1) * dy * dy
        + c(2) * dz * dz
        + c(3) * dx * dy
        + c(4) * dx * dz
        + c(5) * dy * dz;
    let g = gradient(k, o);
    let b = g[0] * dx + g[1] * dy + g[2] * dz;
    (a, b, terms(k, o[0], o[1], o[2], |t| t))
}

/// The eight lanes of `v` in f64 (exact).
#[inline(always)]
fn widen(v: f32x8) -> f64x8 {
    let a = v.to_array();
    f64x8::new([
        a[0] as f64,
        a[1] as f64,
        a[2] as f64,
        a[3] as f64,
        a[4] as f64,
        a[5] as f64,
        a[6] as f64,
        a[7] as f64,
    ])
}

/// The eight lanes of `v` rounded to f32 (to nearest, as `as f32`).
#[inline(always)]
fn narrow(v: f64x8) -> f32x8 {
    let a = v.to_array();
    f32x8::new([
        a[0] as f32,
        a[1] as f32,
        a[2] as f32,
        a[3] as f32,
        a[4] as f32,
        a[5] as f32,
        a[6] as f32,
        a[7] as f32,
    ])
}

impl Quadric32 {
    /// From scene data, translated so that `base` is the origin (in f64, then rounded).
    pub fn new(q: &Quadric, base: DVec3) -> Quadric32 {
        let [a, b, c, d, e, f, _, _, _, _] = q.coef;
        // F(x + base): same quadratic part, linear part ∇F(base), constant F(base)
        let g = q.gradient(base);
        let mut k = [a, b, c, d, e, f, g.x, g.y, g.z, q.value(base)];
        let scale = k.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        if scale > 0.0 {
            k.iter_mut().for_each(|v| *v /= scale);
        }
        // the box relative to base, and rounded outwards to f32 (±∞ stay ±∞)
        let exact = |i: usize| {
            if q.size[i] == 0.0 {
                (f64::NEG_INFINITY, f64::INFINITY)
            } else {
                (q.min[i] - base[i], q.min[i] + q.size[i] - base[i])
            }
        };
        let (ex, ey, ez) = (exact(0), exact(1), exact(2));
        let (x, y, z) = [ex, ey, ez]
            .map(|(lo, hi)| (f32_down(lo), f32_up(hi)))
            .into();
        Quadric32 {
            coef: k,
            box_lo: DVec3::new(ex.0, ey.0, ez.0),
            box_hi: DVec3::new(ex.1, ey.1, ez.1),
            clipped: q.size.cmpne(DVec3::ZERO).any(),
            lo: Vec3::new(x.0, y.0, z.0),
            hi: Vec3::new(x.1, y.1, z.1),
            ellipsoid: ellipsoid_bounds(&k),
            section: open_axis_bounds(
                &k,
                DVec3::new(ex.0, ey.0, ez.0),
                DVec3::new(ex.1, ey.1, ez.1),
            ),
        }
    }

    /// Finite bounds: the clipping box when every axis is clipped, else the bounds of
    /// an ellipsoid (definite quadratic part) or of bounded sections across the clipped
    /// axes, cut by the box, else none.
    pub fn bounds(&self) -> Option<Aabb> {
        let mut lo = self.lo;
        let mut hi = self.hi;
        for b in [self.ellipsoid, self.section].into_iter().flatten() {
            lo = lo.max(b.lo);
            hi = hi.min(b.hi);
        }
        (lo.is_finite() && hi.is_finite()).then(|| Aabb::new(lo.min(hi), hi))
    }

    fn in_box(&self, p: [f64; 3]) -> bool {
        !self.clipped || (0..3).all(|i| p[i] >= self.box_lo[i] && p[i] <= self.box_hi[i])
    }

    /// Nearest t with 0 < t <= t_max (inclusive: the caller breaks ties) under the
    /// box-clipping root rule; the comparisons with 0 and t_max are made on the f32 t
    /// returned.
    #[inline]
    pub fn intersect_1(&self, r: &Ray1, t_max: f32) -> Option<f32> {
        // (the all-zero quadric is dropped when the primitives are built)
        let o = r.origin.as_dvec3().to_array();
        let d = r.dir.as_dvec3().to_array();
        let (a, b, c) = along(&self.coef, o, d);
        // solve for both roots
        let (t0, t1) = if a == 0.0 {
            if b == 0.0 {
                return None;
            }
            let t = -c / b;
            (t, t)
        } else {
            let disc = b * b - 4.0 * a * c;
            if disc.is_nan() || disc < 0.0 {
                return None;
            }
            let q = -0.5 * (b + disc.sqrt().copysign(b));
            if q == 0.0 {
                (0.0, 0.0)
            } else {
                let (r0, r1) = (q / a, c / q);
                (r0.min(r1), r0.max(r1))
            }
        };
        // nearer positive root in the box, else the farther one
        [t0, t1].into_iter().find_map(|t| {
            let t32 = t as f32;
            let p = [o[0] + d[0] * t, o[1] + d[1] * t, o[2] + d[2] * t];
            (t32 > 0.0 && t32 <= t_max && self.in_box(p)).then_some(t32)
        })
    }

    /// Whether the quadric meets the ray with 0 < t < t_max.
    #[inline]
    pub fn occluded_1(&self, r: &Ray1, t_max: f32) -> bool {
        self.intersect_1(r, t_max).is_some_and(|t| t < t_max)
    }

    /// Packet twin of [`Quadric32::intersect_1`], operation for operation.
    #[inline]
    pub fn intersect_x8(&self, r: &RayPacket8, active: Mask8, t_max: f32x8) -> (Mask8, f32x8) {
        let bits = |m: f64x8| Mask8::from_bits(m.to_bitmask());
        let zero = f64x8::ZERO;
        let o = [widen(r.origin.x), widen(r.origin.y), widen(r.origin.z)];
        let d = [widen(r.dir.x), widen(r.dir.y), widen(r.dir.z)];
        let (a, b, c) = along(&self.coef, o, d);
        // solve for both roots
        let linear = a.simd_eq(zero);
        let disc = b * b - f64x8::splat(4.0) * a * c;
        let valid = active & bits((linear & !b.simd_eq(zero)) | (!linear & disc.simd_ge(zero)));
        if valid.none() {
            return (valid, f32x8::ZERO);
        }
        let q = f64x8::splat(-0.5) * (b + (disc.sqrt() | (b & f64x8::splat(-0.0))));
        let r0 = q / a;
        let r1 = c / q;
        let q0 = q.simd_eq(zero);
        let t0 = q0.select(zero, r0.min(r1));
        let t1 = q0.select(zero, r0.max(r1));
        let (t0, t1) = if linear.any() {
            let tl = -c / b;
            (linear.select(tl, t0), linear.select(tl, t1))
        } else {
            (t0, t1)
        };
        // nearer positive root in the box, else the farther one
        let in_box = |t: f64x8| {
            if !self.clipped {
                return Mask8::ALL;
            }
            let p = [o[0] + d[0] * t, o[1] + d[1] * t, o[2] + d[2] * t];
            let (lo, hi) = (self.box_lo.to_array(), self.box_hi.to_array());
            let inside =
                |i: usize| p[i].simd_ge(f64x8::splat(lo[i])) & p[i].simd_le(f64x8::splat(hi[i]));
            let m = inside(0) & inside(1) & inside(2);
            bits(m)
        };
        let zero32 = f32x8::ZERO;
        let (t0_32, t1_32) = (narrow(t0), narrow(t1));
        let ok0 = valid & t0_32.gt(zero32) & t0_32.le(t_max) & in_box(t0);
        let ok1 = valid & t1_32.gt(zero32) & t1_32.le(t_max) & in_box(t1);
        (ok0 | ok1, ok0.select(t0_32, t1_32))
    }

    /// Lanes of `active` whose ray meets the quadric with 0 < t < t_max.
    #[inline]
    pub fn occluded_x8(&self, r: &RayPacket8, active: Mask8, t_max: f32x8) -> Mask8 {
        // an any-hit query must still apply the root rule: both roots below t_max
        let (m, t) = self.intersect_x8(r, active, t_max);
        m & t.lt(t_max)
    }

    /// Surface at distance t: point, normal and error bound as in the reference,
    /// evaluated in f64 at o + t·d, then rounded to f32.
    pub fn surface_1(&self, r: &Ray1, t: f32) -> Surface32 {
        let (o, d, t) = (r.origin.as_dvec3(), r.dir.as_dvec3(), f64::from(t));
        let p = [o.x + d.x * t, o.y + d.y * t, o.z + d.z * t];
        let g = gradient(&self.coef, p);
        let glen = (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt();
        let ok = glen > 0.0 && glen.is_finite();
        let normal = if ok {
            Vec3::new(
                (g[0] / glen) as f32,
                (g[1] / glen) as f32,
                (g[2] / glen) as f32,
            )
        } else {
            -r.dir
        };
        let magnitude = terms(&self.coef, p[0], p[1], p[2], f64::abs);
        let value = terms(&self.coef, p[0], p[1], p[2], |t| t);
        let point = Vec3::new(p[0] as f32, p[1] as f32, p[2] as f32);
        let dist = if ok {
            2.0 * (value.abs() + gamma(12) * magnitude) / glen
        } else {
            f64::from(gamma32(16)) * p[0].abs().max(p[1].abs().max(p[2].abs()))
        };
        // and rounding the point to f32: half an ulp per component
        let half_ulp = f64::from(gamma32(1));
        let err = Vec3::new(
            f32_up(dist + p[0].abs() * half_ulp),
            f32_up(dist + p[1].abs() * half_ulp),
            f32_up(dist + p[2].abs() * half_ulp),
        );
        Surface32 { point, normal, err }
    }

    /// [`Quadric32::surface_1`] on eight lanes, operation for operation.
    pub fn surface_x8(&self, r: &RayPacket8, t: f32x8) -> Surface8 {
        let t = widen(t);
        let o = [widen(r.origin.x), widen(r.origin.y), widen(r.origin.z)];
        let d = [widen(r.dir.x), widen(r.dir.y), widen(r.dir.z)];
        let p = [o[0] + d[0] * t, o[1] + d[1] * t, o[2] + d[2] * t];
        let g = gradient(&self.coef, p);
        let glen = (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt();
        let ok = glen.simd_gt(f64x8::ZERO) & glen.simd_lt(f64x8::splat(f64::INFINITY));
        let ok32 = Mask8::from_bits(ok.to_bitmask());
        let normal = Vec3x8::select(
            ok32,
            Vec3x8::new(
                narrow(g[0] / glen),
                narrow(g[1] / glen),
                narrow(g[2] / glen),
            ),
            -r.dir,
        );
        let magnitude = terms(&self.coef, p[0], p[1], p[2], f64x8::abs);
        let value = terms(&self.coef, p[0], p[1], p[2], |t| t);
        let point = Vec3x8::new(narrow(p[0]), narrow(p[1]), narrow(p[2]));
        let two = f64x8::splat(2.0);
        let a = [p[0].abs(), p[1].abs(), p[2].abs()];
        let dist = ok.select(
            two * (value.abs() + f64x8::splat(gamma(12)) * magnitude) / glen,
            f64x8::splat(f64::from(gamma32(16))) * a[0].max(a[1].max(a[2])),
        );
        let half_ulp = f64x8::splat(f64::from(gamma32(1)));
        // f32_up lane by lane, in SIMD: the bounds are >= 0 (or NaN), and the next f32
        // up from a non-negative one is the next bit pattern
        let up = |e: f64x8| {
            let f = narrow(e);
            let low = Mask8::from_bits(widen(f).simd_lt(e).to_bitmask());
            let i: wide::i32x8 = wide::bytemuck::cast(f);
            low.select(wide::bytemuck::cast(i + wide::i32x8::splat(1)), f)
        };
        let err = Vec3x8::new(
            up(dist + a[0] * half_ulp),
            up(dist + a[1] * half_ulp),
            up(dist + a[2] * half_ulp),
        );
        Surface8 { point, normal, err }
    }
}

/// The largest f32 not above x.
pub fn f32_down(x: f64) -> f32 {
    let f = x as f32;
    if f as f64 > x { f.next_down() } else { f }
}

/// The smallest f32 not below x.
pub fn f32_up(x: f64) -> f32 {
    let f = x as f32;
    if (f as f64) < x { f.next_up() } else { f }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quadric(coef: [f64; 10], min: [f64; 3], size: [f64; 3]) -> Quadric {
        Quadric {
            coef,
            min: DVec3::from(min),
            size: DVec3::from(size),
        }
    }

    fn unit_sphere_clipped(size: [f64; 3], min: [f64; 3]) -> Quadric {
        quadric([1., 1., 1., 0., 0., 0., 0., 0., 0., -1.], min, size)
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
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut rand = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
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

    #[test]
    fn unclipped_sphere_quadric_hits_like_a_sphere() {
        let q = unit_sphere_clipped([0.0; 3], [0.0; 3]);
        let r = Ray::new(DVec3::new(0.0, 0.0, -5.0), DVec3::Z);
        assert_eq!(intersect_ref(&q, &r, f64::INFINITY), Some(4.0));
        let s = surface_ref(&q, &r, 4.0);
        assert!((s.normal - DVec3::NEG_Z).length() < 1e-15);
    }

    #[test]
    fn near_root_outside_box_falls_back_to_far_root() {
        // Keep only z in [0, 1]: a ray from below enters at z = −1 (clipped) and
        // leaves at z = +1 (kept), so it sees the inside of the upper half.
        let q = unit_sphere_clipped([0.0, 0.0, 1.0], [0.0, 0.0, 0.0]);
        let r = Ray::new(DVec3::new(0.0, 0.0, -5.0), DVec3::Z);
        assert_eq!(intersect_ref(&q, &r, f64::INFINITY), Some(6.0));
        // Both roots outside: miss.
        let q = unit_sphere_clipped([0.0, 0.0, 0.5], [0.0, 0.0, 2.0]);
        assert_eq!(intersect_ref(&q, &r, f64::INFINITY), None);
    }

    #[test]
    fn origin_inside_takes_the_positive_root() {
        let q = unit_sphere_clipped([0.0; 3], [0.0; 3]);
        let r = Ray::new(DVec3::new(0.5, 0.0, 0.0), DVec3::X);
        assert_eq!(intersect_ref(&q, &r, f64::INFINITY), Some(0.5));
    }

    #[test]
    fn plane_quadric_is_solved_linearly() {
        // z − 3 = 0 with coefficients A..F zero.
        let q = quadric(
            [0., 0., 0., 0., 0., 0., 0., 0., 1., -3.],
            [0.0; 3],
            [0.0; 3],
        );
        let r = Ray::new(DVec3::ZERO, DVec3::new(0.0, 0.6, 0.8));
        let t = intersect_ref(&q, &r, f64::INFINITY).unwrap();
        assert!((t - 3.75).abs() < 1e-14);
        let s = surface_ref(&q, &r, t);
        assert!((s.normal - DVec3::Z).length() < 1e-15);
    }

    #[test]
    fn cylinder_hit_by_ray_parallel_to_axis_misses_or_hits_cleanly() {
        // x² + y² = 1 around z.
        let q = quadric(
            [1., 1., 0., 0., 0., 0., 0., 0., 0., -1.],
            [0.0; 3],
            [0.0; 3],
        );
        let inside = Ray::new(DVec3::new(0.5, 0.0, -5.0), DVec3::Z);
        assert_eq!(intersect_ref(&q, &inside, f64::INFINITY), None);
        let tilted = Ray::new(
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1e-9, 0.0, 1.0).normalize(),
        );
        let t = intersect_ref(&q, &tilted, f64::INFINITY).unwrap();
        assert!((t / 1e9 - 1.0).abs() < 1e-6, "{t}");
    }

    #[test]
    fn all_zero_quadric_never_hits() {
        let q = quadric([0.0; 10], [0.0; 3], [0.0; 3]);
        let r = Ray::new(DVec3::new(0.0, 0.0, -5.0), DVec3::Z);
        assert_eq!(intersect_ref(&q, &r, f64::INFINITY), None);
    }

    #[test]
    fn tangent_ray_gives_double_root() {
        let q = unit_sphere_clipped([0.0; 3], [0.0; 3]);
        let r = Ray::new(DVec3::new(-5.0, 1.0, 0.0), DVec3::X);
        let t = intersect_ref(&q, &r, f64::INFINITY).unwrap();
        assert!((t - 5.0).abs() < 1e-6);
    }

    #[test]
    fn cone_apex_has_a_finite_normal() {
        // x² + y² − z² = 0; the apex is at the origin.
        let q = quadric(
            [1., 1., -1., 0., 0., 0., 0., 0., 0., 0.],
            [0.0; 3],
            [0.0; 3],
        );
        let r = Ray::new(DVec3::new(0.0, 0.0, -1.0), DVec3::Z);
        let s = surface_ref(&q, &r, 1.0);
        assert!(s.normal.is_finite() && s.err.is_finite());
    }
}
