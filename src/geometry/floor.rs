//! The fixed checkerboard floor: z = 0, −500 <= x, y <= 500 (see [`crate::scene::Floor`]).

use glam::DVec3;

use super::SurfacePoint;
use crate::math::Ray;
use crate::math::float::gamma;
use crate::scene::Floor;

// ---------------------------------------------------------------- reference (f64)

/// Nearest t with 0 < t < t_max where the ray meets the finite floor.
pub fn intersect_ref(ray: &Ray, t_max: f64) -> Option<f64> {
    // rays parallel to the plane never hit it (this also keeps 0/0 out)
    if ray.dir.z == 0.0 {
        return None;
    }
    // distance to the plane z = 0
    let t = -ray.origin.z / ray.dir.z;
    if !(t > 0.0 && t < t_max) {
        return None;
    }
    // reject points outside the square
    let p = ray.at(t);
    Floor::contains(p.x, p.y).then_some(t)
}

/// Surface at distance t; z is set to exactly 0, so only x and y carry error.
pub fn surface_ref(ray: &Ray, t: f64) -> SurfacePoint {
    let p = ray.at(t);
    let e = (ray.origin.abs() + (ray.dir * t).abs()) * gamma(3);
    SurfacePoint {
        point: DVec3::new(p.x, p.y, 0.0),
        normal: DVec3::Z,
        err: DVec3::new(e.x, e.y, 0.0),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hits_from_above_and_below_and_misses_outside() {
        let down = Ray::new(DVec3::new(3.0, 4.0, 10.0), DVec3::NEG_Z);
        assert_eq!(intersect_ref(&down, f64::INFINITY), Some(10.0));
        let up = Ray::new(DVec3::new(3.0, 4.0, -10.0), DVec3::Z);
        assert_eq!(intersect_ref(&up, f64::INFINITY), Some(10.0));
        let outside = Ray::new(DVec3::new(600.0, 0.0, 10.0), DVec3::NEG_Z);
        assert_eq!(intersect_ref(&outside, f64::INFINITY), None);
        let edge = Ray::new(DVec3::new(500.0, -500.0, 10.0), DVec3::NEG_Z);
        assert_eq!(intersect_ref(&edge, f64::INFINITY), Some(10.0));
    }

    #[test]
    fn parallel_and_on_plane_rays_miss() {
        let flat = Ray::new(DVec3::new(0.0, 0.0, 1.0), DVec3::X);
        assert_eq!(intersect_ref(&flat, f64::INFINITY), None);
        let on = Ray::new(DVec3::ZERO, DVec3::new(0.0, 0.6, 0.8));
        assert_eq!(intersect_ref(&on, f64::INFINITY), None);
    }

    #[test]
    fn checkerboard_tiles_alternate() {
        assert_eq!(Floor::color_at(-499.0, -499.0), DVec3::ONE);
        assert_eq!(Floor::color_at(-479.0, -499.0), DVec3::ZERO);
        assert_eq!(Floor::color_at(-479.0, -479.0), DVec3::ONE);
        assert_eq!(Floor::color_at(1.0, 1.0), DVec3::ONE); // i = j = 25
        assert_eq!(Floor::color_at(-1.0, 1.0), DVec3::ZERO);
    }
}
