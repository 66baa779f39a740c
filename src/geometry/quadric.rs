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
use wide::f32x8;

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

/// Nearest t with 0 < t < t_max under the box-clipping root rule.
pub fn intersect_ref(q: &Quadric, ray: &Ray, t_max: f64) -> Option<f64> {
    // the all-zero quadric is never hit
    if q.is_degenerate() {
        return None;
    }
    // coefficients of F along the ray
    let [qa, qb, qc, qd, qe, qf, ..] = q.coef;
    let d = ray.dir;
    let a = qa * d.x * d.x
        + qb * d.y * d.y
        + qc * d.z * d.z
        + qd * d.x * d.y
        + qe * d.x * d.z
        + qf * d.y * d.z;
    let b = q.gradient(ray.origin).dot(d);
    let c = q.value(ray.origin);
    // solve for both roots
    let (t0, t1) = solve_quadratic(a, b, c)?;
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
    let magnitude = terms(q.coef, point.x, point.y, point.z, f64::abs);
    let dist = if glen > 0.0 && glen.is_finite() {
        2.0 * (q.value(point).abs() + gamma(12) * magnitude) / glen
    } else {
        gamma(16) * point.abs().max_element()
    };
    let err = DVec3::splat(dist) + point.abs() * gamma(1);
    SurfacePoint { point, normal, err }
}

// ---------------------------------------------------------------- fast path (f32)

/// A quadric in the fast path's f32 frame: coefficients of F(x + base), renormalised
/// by their largest magnitude, and the clipping box (±∞ on unclipped axes).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Quadric32 {
    pub coef: [f32; 10],
    pub lo: Vec3,
    pub hi: Vec3,
    /// Bounds of the surface when it is an ellipsoid (then it can live in the BVH even
    /// when the box leaves an axis unclipped).
    pub ellipsoid: Option<Aabb>,
}

/// The ten terms of F = Ax² + By² + Cz² + Dxy + Exz + Fyz + Gx + Hy + Iz + J at (x, y, z),
/// each passed through `f` and summed in this order, in any precision: F itself (`f`
/// the identity) or Σ|term| (`f` = abs), the scale of F's rounding error.
#[inline(always)]
fn terms<T>(k: [T; 10], x: T, y: T, z: T, f: impl Fn(T) -> T) -> T
where
    T: Copy + std::ops::Add<Output = T> + std::ops::Mul<Output = T>,
{
    let [a, b, c, d, e, g, h, i, l, j] = k;
    f(a * x * x)
        + f(b * y * y)
        + f(c * z * z)
        + f(d * x * y)
        + f(e * x * z)
        + f(g * y * z)
        + f(h * x)
        + f(i * y)
        + f(l * z)
        + f(j)
}

/// Bounds of {F = 0} when the quadratic part M is definite (an ellipsoid): centre
/// c = −M⁻¹g/2, half-extent along axis i √(k·(M⁻¹)ᵢᵢ) with k = −F(c), padded by a
/// relative 1e-5 against rounding. `k` holds the ten coefficients (f64).
fn ellipsoid_bounds(k: &[f64; 10]) -> Option<Aabb> {
    let [a, b, c, d, e, f, g, h, i, j] = *k;
    let m = glam::DMat3::from_cols(
        DVec3::new(a, d / 2.0, e / 2.0),
        DVec3::new(d / 2.0, b, f / 2.0),
        DVec3::new(e / 2.0, f / 2.0, c),
    );
    // definite: leading principal minors all positive (or, for −M, alternating)
    let m1 = a;
    let m2 = a * b - d * d / 4.0;
    let m3 = m.determinant();
    let sign = if m1 > 0.0 && m2 > 0.0 && m3 > 0.0 {
        1.0
    } else if m1 < 0.0 && m2 > 0.0 && m3 < 0.0 {
        -1.0
    } else {
        return None;
    };
    let m = m * sign;
    let g = DVec3::new(g, h, i) * sign;
    let inv = m.inverse();
    let centre = -(inv * g) / 2.0;
    let kk = -(j * sign + g.dot(centre) / 2.0);
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
    Some(Aabb::new(
        Vec3::new(f32_down(lo.x), f32_down(lo.y), f32_down(lo.z)),
        Vec3::new(f32_up(hi.x), f32_up(hi.y), f32_up(hi.z)),
    ))
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
        let axis = |i: usize| {
            if q.size[i] == 0.0 {
                (f32::NEG_INFINITY, f32::INFINITY)
            } else {
                (
                    f32_down(q.min[i] - base[i]),
                    f32_up(q.min[i] + q.size[i] - base[i]),
                )
            }
        };
        let (x, y, z) = (axis(0), axis(1), axis(2));
        Quadric32 {
            coef: k.map(|v| v as f32),
            lo: Vec3::new(x.0, y.0, z.0),
            hi: Vec3::new(x.1, y.1, z.1),
            ellipsoid: ellipsoid_bounds(&k),
        }
    }

    /// Finite bounds: the clipping box when every axis is clipped, else the bounds of
    /// an ellipsoid (definite quadratic part) cut by the box, else none.
    pub fn bounds(&self) -> Option<Aabb> {
        let mut lo = self.lo;
        let mut hi = self.hi;
        if let Some(e) = self.ellipsoid {
            lo = lo.max(e.lo);
            hi = hi.min(e.hi);
        }
        (lo.is_finite() && hi.is_finite()).then(|| Aabb::new(lo.min(hi), hi))
    }

    fn value(&self, p: Vec3) -> f32 {
        terms(self.coef, p.x, p.y, p.z, |t| t)
    }

    fn gradient(&self, p: Vec3) -> Vec3 {
        let [a, b, c, d, e, f, g, h, i, _] = self.coef;
        Vec3::new(
            2.0 * a * p.x + d * p.y + e * p.z + g,
            2.0 * b * p.y + d * p.x + f * p.z + h,
            2.0 * c * p.z + e * p.x + f * p.y + i,
        )
    }

    fn in_box(&self, p: Vec3) -> bool {
        p.cmpge(self.lo).all() && p.cmple(self.hi).all()
    }

    /// Nearest t with 0 < t <= t_max (inclusive: the caller breaks ties) under the
    /// box-clipping root rule.
    #[inline]
    pub fn intersect_1(&self, r: &Ray1, t_max: f32) -> Option<f32> {
        // (the all-zero quadric is dropped when the primitives are built)
        // coefficients of F along the ray
        let [qa, qb, qc, qd, qe, qf, ..] = self.coef;
        let d = r.dir;
        let a = qa * d.x * d.x
            + qb * d.y * d.y
            + qc * d.z * d.z
            + qd * d.x * d.y
            + qe * d.x * d.z
            + qf * d.y * d.z;
        let b = self.gradient(r.origin).dot(d);
        let c = self.value(r.origin);
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
        [t0, t1]
            .into_iter()
            .find(|&t| t > 0.0 && t <= t_max && self.in_box(r.at(t)))
    }

    /// Whether the quadric meets the ray with 0 < t < t_max.
    #[inline]
    pub fn occluded_1(&self, r: &Ray1, t_max: f32) -> bool {
        self.intersect_1(r, t_max).is_some_and(|t| t < t_max)
    }

    /// Packet twin of [`Quadric32::intersect_1`].
    #[inline]
    pub fn intersect_x8(&self, r: &RayPacket8, active: Mask8, t_max: f32x8) -> (Mask8, f32x8) {
        let k = self.coef.map(f32x8::splat);
        let zero = f32x8::ZERO;
        let two = f32x8::splat(2.0);
        // coefficients of F along the ray
        let (d, o) = (r.dir, r.origin);
        let a = k[0] * d.x * d.x
            + k[1] * d.y * d.y
            + k[2] * d.z * d.z
            + k[3] * d.x * d.y
            + k[4] * d.x * d.z
            + k[5] * d.y * d.z;
        let grad = Vec3x8::new(
            two * k[0] * o.x + k[3] * o.y + k[4] * o.z + k[6],
            two * k[1] * o.y + k[3] * o.x + k[5] * o.z + k[7],
            two * k[2] * o.z + k[4] * o.x + k[5] * o.y + k[8],
        );
        let b = grad.dot(d);
        let c = k[0] * o.x * o.x
            + k[1] * o.y * o.y
            + k[2] * o.z * o.z
            + k[3] * o.x * o.y
            + k[4] * o.x * o.z
            + k[5] * o.y * o.z
            + k[6] * o.x
            + k[7] * o.y
            + k[8] * o.z
            + k[9];
        // solve for both roots
        let linear = a.eq8(zero);
        let disc = b * b - f32x8::splat(4.0) * a * c;
        let valid = active & ((linear & !b.eq8(zero)) | (!linear & disc.ge(zero)));
        if valid.none() {
            return (valid, zero);
        }
        let q = f32x8::splat(-0.5) * (b + (disc.sqrt() | (b & f32x8::splat(-0.0))));
        let r0 = q / a;
        let r1 = c / q;
        let q0 = q.eq8(zero);
        let t0 = q0.select(zero, r0.min(r1));
        let t1 = q0.select(zero, r0.max(r1));
        let tl = -c / b;
        let t0 = linear.select(tl, t0);
        let t1 = linear.select(tl, t1);
        // nearer positive root in the box, else the farther one
        let in_box = |t: f32x8| {
            let p = Vec3x8::new(o.x + d.x * t, o.y + d.y * t, o.z + d.z * t);
            p.x.ge(f32x8::splat(self.lo.x))
                & p.y.ge(f32x8::splat(self.lo.y))
                & p.z.ge(f32x8::splat(self.lo.z))
                & p.x.le(f32x8::splat(self.hi.x))
                & p.y.le(f32x8::splat(self.hi.y))
                & p.z.le(f32x8::splat(self.hi.z))
        };
        let ok0 = valid & t0.gt(zero) & t0.le(t_max) & in_box(t0);
        let ok1 = valid & t1.gt(zero) & t1.le(t_max) & in_box(t1);
        (ok0 | ok1, ok0.select(t0, t1))
    }

    /// Lanes of `active` whose ray meets the quadric with 0 < t < t_max.
    #[inline]
    pub fn occluded_x8(&self, r: &RayPacket8, active: Mask8, t_max: f32x8) -> Mask8 {
        // an any-hit query must still apply the root rule: both roots below t_max
        let (m, t) = self.intersect_x8(r, active, t_max);
        m & t.lt(t_max)
    }

    /// Surface at distance t; the error bound as in the reference, in f32.
    pub fn surface_1(&self, r: &Ray1, t: f32) -> Surface32 {
        let point = r.at(t);
        let grad = self.gradient(point);
        let glen = grad.length();
        let ok = glen > 0.0 && glen.is_finite();
        let normal = if ok { grad / glen } else { -r.dir };
        let magnitude = terms(self.coef, point.x, point.y, point.z, f32::abs);
        let dist = if ok {
            2.0 * (self.value(point).abs() + gamma32(12) * magnitude) / glen
        } else {
            gamma32(16) * point.abs().max_element()
        };
        // the hit point o + t·d itself is off by about one rounding per component
        let err = Vec3::splat(dist) + (point.abs() + (r.dir * t).abs()) * gamma32(3);
        Surface32 { point, normal, err }
    }

    /// [`Quadric32::surface_1`] on eight lanes, operation for operation.
    pub fn surface_x8(&self, r: &RayPacket8, t: f32x8) -> Surface8 {
        let k = self.coef.map(f32x8::splat);
        let [a, b, c, d, e, f, g, h, i, _] = k;
        let dt = r.dir * t;
        let point = r.origin + dt;
        let (x, y, z) = (point.x, point.y, point.z);
        let two = f32x8::splat(2.0);
        let grad = Vec3x8::new(
            two * a * x + d * y + e * z + g,
            two * b * y + d * x + f * z + h,
            two * c * z + e * x + f * y + i,
        );
        let glen = grad.length();
        let ok = glen.gt(f32x8::ZERO) & glen.lt(f32x8::splat(f32::INFINITY));
        let normal = Vec3x8::select(
            ok,
            Vec3x8::new(grad.x / glen, grad.y / glen, grad.z / glen),
            -r.dir,
        );
        let magnitude = terms(k, x, y, z, f32x8::abs);
        let value = terms(k, x, y, z, |t| t);
        let p = point.abs();
        let dist = ok.select(
            two * (value.abs() + f32x8::splat(gamma32(12)) * magnitude) / glen,
            f32x8::splat(gamma32(16)) * p.x.max(p.y.max(p.z)),
        );
        let err = Vec3x8::new(dist, dist, dist) + (p + dt.abs()) * f32x8::splat(gamma32(3));
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
