//! Sphere: `sphere cx cy cz radius` then the material.
//!
//! Numerics (Ray Tracing Gems ch. 7): the discriminant is computed as r² − |f − (f·d)d|²
//! rather than b² − c, which cancels catastrophically for spheres far from the ray
//! origin; the roots as q and c/q with q = −(b + sign(b)√Δ).

use glam::DVec3;

use glam::Vec3;
use wide::f32x8;

use super::{Surface8, Surface32, SurfacePoint};
use crate::math::Aabb;
use crate::math::Ray;
use crate::math::float::gamma;
use crate::math::packet::{Cmp8, Mask8, Ray1, RayPacket8, Vec3x8, gamma32};

// ---------------------------------------------------------------- reference (f64)

/// Nearest t with 0 < t < t_max where the ray meets the sphere.
pub fn intersect_ref(center: DVec3, radius: f64, ray: &Ray, t_max: f64) -> Option<f64> {
    // vector from the centre to the origin
    let f = ray.origin - center;
    // project it onto the ray: b = f·d (d is unit)
    let b = f.dot(ray.dir);
    // discriminant as r² − |f − b·d|², factored to keep the subtraction exact-ish
    let l = (f - ray.dir * b).length();
    let disc = (radius - l) * (radius + l);
    // reject rays that pass outside
    if disc < 0.0 {
        return None;
    }
    // stable roots: q = −(b + sign(b)√Δ), t = q and c/q
    let c = (f.length() - radius) * (f.length() + radius);
    let q = -(b + b.signum() * disc.sqrt());
    if q == 0.0 {
        return None; // origin on the sphere and ray tangent to it: no positive root
    }
    let (t0, t1) = {
        let (r0, r1) = (c / q, q);
        if r0 <= r1 { (r0, r1) } else { (r1, r0) }
    };
    // pick the nearest root in (0, t_max)
    [t0, t1].into_iter().find(|&t| t > 0.0 && t < t_max)
}

/// Both roots (ascending) of the sphere along o + t·d, d of any length: a·t² + 2b·t + c
/// with Δ/4 = a·r² − |f × d|² (no cancellation for spheres far from the origin). The
/// floor tie's arbiter on the fast path (`PrimSet::floor_first`).
pub fn roots_ref(center: DVec3, radius: f64, o: DVec3, d: DVec3) -> Option<(f64, f64)> {
    let f = o - center;
    let a = d.length_squared();
    let b = f.dot(d);
    let disc = a * radius * radius - f.cross(d).length_squared();
    if disc.is_nan() || disc < 0.0 || a == 0.0 {
        return None;
    }
    let q = -(b + disc.sqrt().copysign(b));
    if q == 0.0 {
        return None;
    }
    let fl = f.length();
    let (r0, r1) = (q / a, (fl - radius) * (fl + radius) / q);
    Some(if r0 <= r1 { (r0, r1) } else { (r1, r0) })
}

/// Surface at distance t: the hit point re-projected onto the sphere.
pub fn surface_ref(center: DVec3, radius: f64, ray: &Ray, t: f64) -> SurfacePoint {
    let v = ray.at(t) - center;
    let normal = v.normalize();
    let v = normal * radius;
    let point = center + v;
    // Re-projection leaves ~5 roundings relative to |v|; adding the centre rounds
    // again relative to |point|.
    let err = (v.abs() + center.abs()) * gamma(6);
    SurfacePoint { point, normal, err }
}

// ---------------------------------------------------------------- fast path (f32)

/// A sphere in the fast path's f32 frame (coordinates relative to the frame origin).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sphere32 {
    pub center: Vec3,
    pub radius: f32,
}

impl Sphere32 {
    /// From scene data, relative to `base`.
    pub fn new(center: DVec3, radius: f64, base: DVec3) -> Sphere32 {
        Sphere32 {
            center: (center - base).as_vec3(),
            radius: radius as f32,
        }
    }

    /// Bounds, padded by a relative 4 ulp so f32 rounding cannot shrink them.
    pub fn bounds(&self) -> Aabb {
        let pad =
            Vec3::splat(self.radius) + (self.center.abs() + self.radius) * (4.0 * f32::EPSILON);
        Aabb::new(self.center - pad, self.center + pad)
    }

    /// Nearest t with 0 < t <= t_max (inclusive: the caller breaks exact ties).
    #[inline]
    pub fn intersect_1(&self, r: &Ray1, t_max: f32) -> Option<f32> {
        // vector from the centre to the origin
        let f = r.origin - self.center;
        // project it onto the ray: b = f·d (d is unit)
        let b = f.dot(r.dir);
        // discriminant as r² − |f − b·d|², factored to keep the subtraction exact-ish
        let l = (f - r.dir * b).length();
        let disc = (self.radius - l) * (self.radius + l);
        // reject rays that pass outside
        if disc.is_nan() || disc < 0.0 {
            return None;
        }
        // stable roots: q = −(b + sign(b)√Δ), t = q and c/q
        let fl = f.length();
        let c = (fl - self.radius) * (fl + self.radius);
        let q = -(b + disc.sqrt().copysign(b));
        if q == 0.0 {
            return None;
        }
        let (r0, r1) = (c / q, q);
        let (t0, t1) = if r0 <= r1 { (r0, r1) } else { (r1, r0) };
        // pick the nearest root in (0, t_max]
        let t = if t0 > 0.0 { t0 } else { t1 };
        (t > 0.0 && t <= t_max).then_some(t)
    }

    /// Whether the sphere meets the ray with 0 < t < t_max.
    #[inline]
    pub fn occluded_1(&self, r: &Ray1, t_max: f32) -> bool {
        self.intersect_1(r, t_max).is_some_and(|t| t < t_max)
    }

    /// Packet twin of [`Sphere32::intersect_1`]: lanes of `active` with a hit in
    /// (0, t_max], and their t.
    #[inline]
    pub fn intersect_x8(&self, r: &RayPacket8, active: Mask8, t_max: f32x8) -> (Mask8, f32x8) {
        let rad = f32x8::splat(self.radius);
        // vector from the centre to the origin
        let f = r.origin - Vec3x8::splat(self.center);
        // project it onto the ray: b = f·d (d is unit)
        let b = f.dot(r.dir);
        // discriminant as r² − |f − b·d|², factored to keep the subtraction exact-ish
        let l = (f - r.dir * b).length();
        let disc = (rad - l) * (rad + l);
        // reject rays that pass outside
        let valid = active & disc.ge(f32x8::ZERO);
        if valid.none() {
            return (valid, t_max);
        }
        // stable roots: q = −(b + sign(b)√Δ), t = q and c/q
        let fl = f.length();
        let c = (fl - rad) * (fl + rad);
        let sign = b & f32x8::splat(-0.0);
        let q = -(b + (disc.sqrt() | sign));
        let r0 = c / q;
        let t0 = r0.min(q);
        let t1 = r0.max(q);
        // pick the nearest root in (0, t_max]
        let t = t0.gt(f32x8::ZERO).select(t0, t1);
        let valid = valid & t.gt(f32x8::ZERO) & t.le(t_max) & !q.eq8(f32x8::ZERO);
        (valid, t)
    }

    /// Lanes of `active` whose ray meets the sphere with 0 < t < t_max.
    #[inline]
    pub fn occluded_x8(&self, r: &RayPacket8, active: Mask8, t_max: f32x8) -> Mask8 {
        let (m, t) = self.intersect_x8(r, active, t_max);
        m & t.lt(t_max)
    }

    /// Surface at distance t: the hit point re-projected onto the sphere.
    pub fn surface_1(&self, r: &Ray1, t: f32) -> Surface32 {
        let v = r.at(t) - self.center;
        let normal = v.normalize_or(-r.dir);
        let v = normal * self.radius;
        let point = self.center + v;
        let err = (v.abs() + self.center.abs()) * gamma32(6);
        Surface32 { point, normal, err }
    }

    /// [`Sphere32::surface_1`] on eight lanes, operation for operation.
    pub fn surface_x8(&self, r: &RayPacket8, t: f32x8) -> Surface8 {
        let c = Vec3x8::splat(self.center);
        let v = r.origin + r.dir * t - c;
        // glam's normalize_or: 1/|v| finite and positive, else the fallback
        let rcp = f32x8::splat(1.0) / v.length();
        let ok = rcp.lt(f32x8::splat(f32::INFINITY)) & rcp.gt(f32x8::ZERO);
        let normal = Vec3x8::select(ok, v * rcp, -r.dir);
        let v = normal * f32x8::splat(self.radius);
        let point = c + v;
        let err = (v.abs() + c.abs()) * f32x8::splat(gamma32(6));
        Surface8 { point, normal, err }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ray(o: [f64; 3], d: [f64; 3]) -> Ray {
        Ray::new(DVec3::from(o), DVec3::from(d).normalize())
    }

    #[test]
    fn head_on_hit_gives_distance_and_outward_normal() {
        let r = ray([0.0, 0.0, -10.0], [0.0, 0.0, 1.0]);
        let t = intersect_ref(DVec3::ZERO, 2.0, &r, f64::INFINITY).unwrap();
        assert_eq!(t, 8.0);
        let s = surface_ref(DVec3::ZERO, 2.0, &r, t);
        assert!((s.normal - DVec3::NEG_Z).length() < 1e-15);
    }

    #[test]
    fn origin_inside_hits_far_side() {
        let r = ray([0.5, 0.0, 0.0], [1.0, 0.0, 0.0]);
        let t = intersect_ref(DVec3::ZERO, 2.0, &r, f64::INFINITY).unwrap();
        assert!((t - 1.5).abs() < 1e-15);
    }

    #[test]
    fn behind_and_beyond_t_max_miss() {
        let r = ray([0.0, 0.0, 10.0], [0.0, 0.0, 1.0]);
        assert_eq!(intersect_ref(DVec3::ZERO, 2.0, &r, f64::INFINITY), None);
        let r = ray([0.0, 0.0, -10.0], [0.0, 0.0, 1.0]);
        assert_eq!(intersect_ref(DVec3::ZERO, 2.0, &r, 7.9), None);
    }

    #[test]
    fn tangent_rays_at_one_plus_minus_tiny() {
        for k in 3..=12 {
            let e = 10f64.powi(-k);
            let inside = ray([-10.0, 1.0 - e, 0.0], [1.0, 0.0, 0.0]);
            let outside = ray([-10.0, 1.0 + e, 0.0], [1.0, 0.0, 0.0]);
            assert!(
                intersect_ref(DVec3::ZERO, 1.0, &inside, f64::INFINITY).is_some(),
                "k={k}"
            );
            assert!(
                intersect_ref(DVec3::ZERO, 1.0, &outside, f64::INFINITY).is_none(),
                "k={k}"
            );
        }
    }

    #[test]
    fn far_away_unit_sphere_is_hit_accurately() {
        // The textbook b² − c form loses this in f32; here we check f64 keeps t exact-ish.
        let c = DVec3::new(1e4, 0.0, 0.0);
        let r = ray([0.0, 0.3, 0.0], [1.0, 0.0, 0.0]);
        let t = intersect_ref(c, 1.0, &r, f64::INFINITY).unwrap();
        let expect = 1e4 - (1.0f64 - 0.09).sqrt();
        assert!((t - expect).abs() < 1e-10, "{t} vs {expect}");
    }
}
