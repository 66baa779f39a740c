//! Sphere: `sphere cx cy cz radius` then the material.
//!
//! Numerics (Ray Tracing Gems ch. 7): the discriminant is computed as r² − |f − (f·d)d|²
//! rather than b² − c, which cancels catastrophically for spheres far from the ray
//! origin; the roots as q and c/q with q = −(b + sign(b)√Δ).

use glam::DVec3;

use super::SurfacePoint;
use crate::math::Ray;
use crate::math::float::gamma;

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
