//! The fixed checkerboard floor: z = 0, −500 <= x, y <= 500 (see [`crate::scene::Floor`]).

use glam::DVec3;

use glam::Vec3;
use wide::{f32x8, f64x4};

use super::{Surface8, Surface32, SurfacePoint};
use crate::math::Ray;
use crate::math::float::gamma;
use crate::math::packet::{Cmp8, Mask8, Ray1, RayPacket8, Vec3x8, gamma32};
use crate::scene::Floor;

// ---------------------------------------------------------------- reference (f64)

/// A closest-hit query tests the floor last; where an object was hit, with that hit's t
/// scaled by this as `t_max`: the floor wins only if it is closer than the object by
/// more than 64 f64 ulps, relative (see
/// `geometry::FLOOR_TIE`, the f32 twin).
pub const TIE: f64 = 1.0 - 64.0 * f64::EPSILON;

/// How far (f64) a floor point found at distance `t` along a unit ray from an origin
/// of largest coordinate `origin` may lie from a tile line and still be taken as on
/// it ([`crate::scene::Floor::color_at_within`]): 16 ulps of |o| + t, which covers the
/// rounding of the hit and of the ray itself (a camera's pixel direction carries a
/// few ulps relative to its length, so a coordinate the ray hardly moves along, such
/// as x on a centre column looking along y, can be off by ulps of t, not of x).
pub fn tile_tolerance(origin: f64, t: f64) -> f64 {
    16.0 * f64::EPSILON * (origin + t)
}

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

/// Tile colour at distance t along `ray`: a coordinate within [`tile_tolerance`] of a
/// tile line counts as on it ([`Floor::color_at_within`]). The reference's floor
/// colour, and the fast path's for camera rays near a tile line.
pub fn color_ref(ray: &Ray, t: f64) -> DVec3 {
    let p = ray.at(t);
    let e = tile_tolerance(ray.origin.abs().max_element(), t);
    Floor::color_at_within(p.x, p.y, e, e)
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

// ---------------------------------------------------------------- fast path (f32)

/// The floor in the fast path's f32 frame: the plane z = `z`, x in [x0, x1], y in [y0, y1],
/// in the frame whose origin is the world point `base`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Floor32 {
    pub z: f32,
    pub x0: f32,
    pub x1: f32,
    pub y0: f32,
    pub y1: f32,
    pub base: DVec3,
}

impl Floor32 {
    /// The scene's floor relative to `base`.
    pub fn new(base: DVec3) -> Floor32 {
        let h = Floor::HALF_WIDTH;
        Floor32 {
            z: (-base.z) as f32,
            x0: (-h - base.x) as f32,
            x1: (h - base.x) as f32,
            y0: (-h - base.y) as f32,
            y1: (h - base.y) as f32,
            base,
        }
    }

    /// Nearest t with 0 < t <= t_max where the ray meets the finite floor.
    #[inline]
    pub fn intersect_1(&self, r: &Ray1, t_max: f32) -> Option<f32> {
        // rays parallel to the plane never hit it (this also keeps 0/0 out)
        if r.dir.z == 0.0 {
            return None;
        }
        // distance to the plane
        let t = (self.z - r.origin.z) / r.dir.z;
        if !(t > 0.0 && t <= t_max) {
            return None;
        }
        // reject points outside the square
        let p = r.at(t);
        (p.x >= self.x0 && p.x <= self.x1 && p.y >= self.y0 && p.y <= self.y1).then_some(t)
    }

    #[inline]
    pub fn occluded_1(&self, r: &Ray1, t_max: f32) -> bool {
        self.intersect_1(r, t_max).is_some_and(|t| t < t_max)
    }

    /// Packet twin of [`Floor32::intersect_1`].
    #[inline]
    pub fn intersect_x8(&self, r: &RayPacket8, active: Mask8, t_max: f32x8) -> (Mask8, f32x8) {
        // rays parallel to the plane never hit it (this also keeps 0/0 out)
        let valid = active & !r.dir.z.eq8(f32x8::ZERO);
        // distance to the plane
        let t = (f32x8::splat(self.z) - r.origin.z) / r.dir.z;
        let valid = valid & t.gt(f32x8::ZERO) & t.le(t_max);
        if valid.none() {
            return (valid, t);
        }
        // reject points outside the square
        let x = r.origin.x + r.dir.x * t;
        let y = r.origin.y + r.dir.y * t;
        let inside = x.ge(f32x8::splat(self.x0))
            & x.le(f32x8::splat(self.x1))
            & y.ge(f32x8::splat(self.y0))
            & y.le(f32x8::splat(self.y1));
        (valid & inside, t)
    }

    #[inline]
    pub fn occluded_x8(&self, r: &RayPacket8, active: Mask8, t_max: f32x8) -> Mask8 {
        let (m, t) = self.intersect_x8(r, active, t_max);
        m & t.lt(t_max)
    }

    /// Surface at distance t; z is set exactly to the plane, so only x and y carry error.
    pub fn surface_1(&self, r: &Ray1, t: f32) -> Surface32 {
        let p = r.at(t);
        let e = (r.origin.abs() + (r.dir * t).abs()) * gamma32(3);
        Surface32 {
            point: Vec3::new(p.x, p.y, self.z),
            normal: Vec3::Z,
            err: Vec3::new(e.x, e.y, 0.0),
        }
    }

    /// Packet twin of [`Floor32::surface_1`], lane for lane the same operations.
    #[inline]
    pub fn surface_x8(&self, r: &RayPacket8, t: f32x8) -> Surface8 {
        let d = r.dir * t;
        let p = r.origin + d;
        let e = (r.origin.abs() + d.abs()) * f32x8::splat(gamma32(3));
        let (zero, one) = (f32x8::ZERO, f32x8::splat(1.0));
        Surface8 {
            point: Vec3x8::new(p.x, p.y, f32x8::splat(self.z)),
            normal: Vec3x8::new(zero, zero, one),
            err: Vec3x8::new(e.x, e.y, zero),
        }
    }

    /// Lanes whose point (x, y) of the frame lies on a white tile: [`Floor::color_at`]
    /// four lanes at a time in f64, with the same tile indices, whose parity is exact
    /// while they are below 2^53 (every point of the floor).
    #[inline]
    pub fn white_x8(&self, x: f32x8, y: f32x8) -> Mask8 {
        let (x, y) = (x.to_array(), y.to_array());
        let tile = |v: [f32; 4], b: f64| {
            let w = f64x4::new(v.map(|c| c as f64)) + f64x4::splat(b);
            ((w + f64x4::splat(Floor::HALF_WIDTH)) / f64x4::splat(Floor::TILE)).floor()
        };
        let mut bits = 0;
        for h in 0..2 {
            let quad = |a: &[f32; 8]| [a[4 * h], a[4 * h + 1], a[4 * h + 2], a[4 * h + 3]];
            // i + j is an exact integer: tiles of the finite floor are a few hundred
            let s = tile(quad(&x), self.base.x) + tile(quad(&y), self.base.y);
            let odd = s - f64x4::splat(2.0) * (s * f64x4::splat(0.5)).floor();
            bits |= odd.simd_eq(f64x4::ZERO).to_bitmask() << (4 * h);
        }
        Mask8::from_bits(bits)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn checker_lanes_match_color_at_at_tile_edges_and_off_origin() {
        // points on, just beside and between tile edges, in frames far from the origin
        let mut seed = 7u64;
        let mut rnd = move || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 40) as f64 / (1u64 << 24) as f64
        };
        for base in [
            DVec3::ZERO,
            DVec3::new(123.25, -77.5, 9.0),
            DVec3::new(-480.0, 499.0, 0.0),
        ] {
            let floor = Floor32::new(base);
            for _ in 0..200 {
                let mut xs = [0.0f32; 8];
                let mut ys = [0.0f32; 8];
                for k in 0..8 {
                    let edge = |r: f64| (r * 50.0).floor() * 20.0 - 500.0;
                    let (x, y) = if k % 2 == 0 {
                        (edge(rnd()), edge(rnd()) + (rnd() - 0.5) * 1e-3)
                    } else {
                        (rnd() * 1000.0 - 500.0, rnd() * 1000.0 - 500.0)
                    };
                    xs[k] = (x - base.x) as f32;
                    ys[k] = (y - base.y) as f32;
                }
                let white = floor.white_x8(f32x8::new(xs), f32x8::new(ys));
                for k in 0..8 {
                    let c = Floor::color_at(xs[k] as f64 + base.x, ys[k] as f64 + base.y);
                    assert_eq!(
                        white.lane(k),
                        c == DVec3::ONE,
                        "({}, {}) + {base}",
                        xs[k],
                        ys[k]
                    );
                }
            }
        }
    }

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
    fn points_within_their_error_of_a_tile_line_are_on_it() {
        // x = 20 lies in tile 26 (odd with j = 25: black); 20 − 1e-9 in tile 25
        assert_eq!(Floor::color_at(20.0, 1.0), DVec3::ZERO);
        assert_eq!(Floor::color_at(20.0 - 1e-9, 1.0), DVec3::ONE);
        assert_eq!(
            Floor::color_at_within(20.0 - 1e-9, 1.0, 1e-8, 0.0),
            DVec3::ZERO
        );
        assert_eq!(
            Floor::color_at_within(20.0 - 1e-9, 1.0, 1e-10, 0.0),
            DVec3::ONE
        );
        // the far edge y = 500 is in tile 50 (the spec's floor), also from just below
        assert_eq!(
            Floor::color_at_within(1.0, 500.0 - 1e-12, 0.0, 1e-11),
            Floor::color_at(1.0, 500.0)
        );
        assert_ne!(Floor::color_at(1.0, 500.0), Floor::color_at(1.0, 499.0));
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
