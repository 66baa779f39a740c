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

mod bounds;

use super::{Surface8, Surface32, SurfacePoint};
use crate::math::Aabb;
use crate::math::Ray;
use crate::math::float::{f32_down, f32_up, gamma};
use crate::math::packet::{Cmp8, Mask8, Ray1, RayPacket8, Vec3x8, gamma32};
use crate::scene::Quadric;
use bounds::{ellipsoid_bounds, open_axis_bounds};

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
/// from a small quadric (shadow rays from a distant floor passing a thin cylinder hit
/// it; `tests/extremes.rs` keeps the case). An f32 ray is exact in f64, so the
/// roots are as good as the reference's for that ray, and the surface's error bound,
/// evaluated in f64 at the hit point, measures the point's own distance from the surface
/// instead of f32's rounding of F far from the origin. Both kernels convert, compute and
/// round lane for lane alike, so packet and single ray stay bit-equal.
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
    /// across them are bounded (`bounds::section_bounds`: a cylinder cut across its axis).
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

/// Arithmetic shared by the single-ray (f64) and packet (f64x8) quadric kernels, so
/// that both evaluate the same expressions in the same order.
trait Lanes:
    Copy
    + std::ops::Add<Output = Self>
    + std::ops::Sub<Output = Self>
    + std::ops::Mul<Output = Self>
    + std::ops::Div<Output = Self>
    + std::ops::Neg<Output = Self>
{
    /// Per-lane booleans.
    type Mask: Copy
        + std::ops::BitAnd<Output = Self::Mask>
        + std::ops::BitOr<Output = Self::Mask>
        + std::ops::Not<Output = Self::Mask>;
    fn k(v: f64) -> Self;
    fn sqrt(self) -> Self;
    /// `self` (>= 0) with the sign of `s`.
    fn signed_as(self, s: Self) -> Self;
    fn min(self, o: Self) -> Self;
    fn max(self, o: Self) -> Self;
    fn eq(self, o: Self) -> Self::Mask;
    fn ge(self, o: Self) -> Self::Mask;
    fn select(m: Self::Mask, a: Self, b: Self) -> Self;
    fn any(m: Self::Mask) -> bool;
}

impl Lanes for f64 {
    type Mask = bool;
    #[inline(always)]
    fn k(v: f64) -> f64 {
        v
    }
    #[inline(always)]
    fn sqrt(self) -> f64 {
        f64::sqrt(self)
    }
    #[inline(always)]
    fn signed_as(self, s: f64) -> f64 {
        self.copysign(s)
    }
    #[inline(always)]
    fn min(self, o: f64) -> f64 {
        f64::min(self, o)
    }
    #[inline(always)]
    fn max(self, o: f64) -> f64 {
        f64::max(self, o)
    }
    #[inline(always)]
    fn eq(self, o: f64) -> bool {
        self == o
    }
    #[inline(always)]
    fn ge(self, o: f64) -> bool {
        self >= o
    }
    #[inline(always)]
    fn select(m: bool, a: f64, b: f64) -> f64 {
        if m { a } else { b }
    }
    #[inline(always)]
    fn any(m: bool) -> bool {
        m
    }
}

impl Lanes for f64x8 {
    type Mask = f64x8;
    #[inline(always)]
    fn k(v: f64) -> f64x8 {
        f64x8::splat(v)
    }
    #[inline(always)]
    fn sqrt(self) -> f64x8 {
        f64x8::sqrt(self)
    }
    #[inline(always)]
    fn signed_as(self, s: f64x8) -> f64x8 {
        self | (s & f64x8::splat(-0.0))
    }
    #[inline(always)]
    fn min(self, o: f64x8) -> f64x8 {
        f64x8::min(self, o)
    }
    #[inline(always)]
    fn max(self, o: f64x8) -> f64x8 {
        f64x8::max(self, o)
    }
    #[inline(always)]
    fn eq(self, o: f64x8) -> f64x8 {
        self.simd_eq(o)
    }
    #[inline(always)]
    fn ge(self, o: f64x8) -> f64x8 {
        self.simd_ge(o)
    }
    #[inline(always)]
    fn select(m: f64x8, a: f64x8, b: f64x8) -> f64x8 {
        m.select(a, b)
    }
    #[inline(always)]
    fn any(m: f64x8) -> bool {
        m.any()
    }
}

/// The roots of a·t² + b·t + c = 0 (ascending; a double root −c/b when linear) and
/// where they exist: the fast kernels' one solver, at one and at eight lanes.
/// Stable: q = −(b + sign(b)√Δ)/2, roots q/a and c/q; linear only when a is exactly 0
/// (the stable pair already handles a tiny a). `None` where no lane has a root.
#[inline(always)]
fn roots<T: Lanes>(a: T, b: T, c: T) -> Option<(T::Mask, T, T)> {
    let zero = T::k(0.0);
    let linear = a.eq(zero);
    let disc = b * b - T::k(4.0) * a * c;
    let valid = (linear & !b.eq(zero)) | (!linear & disc.ge(zero));
    if !T::any(valid) {
        return None;
    }
    let q = T::k(-0.5) * (b + disc.sqrt().signed_as(b));
    let (r0, r1) = (q / a, c / q);
    // b = 0 and Δ = 0, so c = 0: a double root at 0
    let q0 = q.eq(zero);
    let t0 = T::select(q0, zero, r0.min(r1));
    let t1 = T::select(q0, zero, r0.max(r1));
    if T::any(linear) {
        let tl = -c / b;
        return Some((valid, T::select(linear, tl, t0), T::select(linear, tl, t1)));
    }
    Some((valid, t0, t1))
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
        let (_, t0, t1) = roots(a, b, c)?;
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
        let o = [widen(r.origin.x), widen(r.origin.y), widen(r.origin.z)];
        let d = [widen(r.dir.x), widen(r.dir.y), widen(r.dir.z)];
        let (a, b, c) = along(&self.coef, o, d);
        // solve for both roots
        let Some((exists, t0, t1)) = roots(a, b, c) else {
            return (Mask8::NONE, f32x8::ZERO);
        };
        let valid = active & bits(exists);
        if valid.none() {
            return (valid, f32x8::ZERO);
        }
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
