//! The plain Möller–Trumbore triangle test (Möller and Trumbore 1997), the profile knob
//! `triangle_test = "moller"`: fewer operations than the watertight test
//! ([`super::triangle`]), but each triangle rounds its barycentrics on its own, so a
//! ray through an edge shared by two triangles can miss both (`tests/extremes.rs`
//! measures the leak). The same [`Triangle32`]s and blocks, another instantiation of
//! [`TriangleKernel`].
//!
//! Barycentrics are returned as (b1, b2), the weights of vertices 1 and 2, so
//! [`Triangle32::surface_1`] applies unchanged.

use glam::Vec3;
use wide::f32x8;

use super::triangle::{Hits8, Triangle8, Triangle32, TriangleKernel};
use crate::math::packet::{Mask8, Ray1, RayPacket8, Vec3x8};
use crate::simd;
use crate::simd::packet::{RayLanes, cross3, dot3, sub3};

/// The Möller–Trumbore test as a [`TriangleKernel`].
#[derive(Clone, Copy, Debug, Default)]
pub struct Moller;

/// One ray splatted for [`Moller::intersect_1x8`].
#[derive(Clone, Copy, Debug)]
pub struct MollerRay8 {
    origin: Vec3x8,
    dir: Vec3x8,
}

impl TriangleKernel for Moller {
    type Ray1x8 = MollerRay8;

    #[inline(always)]
    fn prepare(r: &Ray1) -> MollerRay8 {
        MollerRay8 {
            origin: Vec3x8::splat(r.origin),
            dir: Vec3x8::splat(r.dir),
        }
    }

    #[inline(always)]
    fn intersect_1(tri: &Triangle32, r: &Ray1, t_max: f32) -> Option<(f32, f32, f32)> {
        intersect_1(tri, r, t_max)
    }

    #[inline(always)]
    fn intersect_splat_x8(v: [Vec3x8; 3], r: &RayPacket8, active: Mask8, t_max: f32x8) -> Hits8 {
        lanes(v, r.origin, r.dir, active, t_max)
    }

    #[inline(always)]
    fn intersect_splat_lanes<L: simd::Lanes>(
        v: [[L; 3]; 3],
        r: &RayLanes<L>,
        active: L::Mask,
        t_max: L,
    ) -> (L::Mask, L, L, L) {
        any_width(v, r.origin, r.dir, active, t_max)
    }

    /// Nothing to move: the test subtracts the origin from one vertex only.
    type Moved = ();

    #[inline(always)]
    fn move_block(_: &Triangle8, _: [f32x8; 3]) {}

    #[inline(always)]
    fn intersect_moved_lanes<L: simd::Lanes>(
        b: &Triangle8,
        _: &(),
        j: usize,
        r: &RayLanes<L>,
        active: L::Mask,
        t_max: L,
    ) -> (L::Mask, L, L, L) {
        Self::intersect_splat_lanes(b.splat_lanes(j), r, active, t_max)
    }

    #[inline(always)]
    fn intersect_1x8<const KZ: usize>(
        b: &Triangle8,
        r: &MollerRay8,
        active: Mask8,
        t_max: f32,
    ) -> Hits8 {
        let v = b.v.map(|p| Vec3x8::new(p[0], p[1], p[2]));
        lanes(v, r.origin, r.dir, active, f32x8::splat(t_max))
    }
}

/// Eight tests at once, lane i: triangle `v[..]` lane i against ray (o, d) lane i
/// (the packet kernel splats the triangle, the 1×8 kernel the ray).
#[inline(always)]
fn lanes(v: [Vec3x8; 3], o: Vec3x8, d: Vec3x8, active: Mask8, t_max: f32x8) -> Hits8 {
    let a = |p: Vec3x8| [p.x, p.y, p.z];
    any_width(v.map(a), a(o), a(d), active, t_max)
}

/// [`lanes`] at any width: the operations of [`intersect_1`] in its order.
#[inline(always)]
fn any_width<L: simd::Lanes>(
    v: [[L; 3]; 3],
    o: [L; 3],
    d: [L; 3],
    active: L::Mask,
    t_max: L,
) -> (L::Mask, L, L, L) {
    let (zero, one) = (L::zero(), L::splat(1.0));
    let [v0, v1, v2] = v;
    let (e1, e2) = (sub3(v1, v0), sub3(v2, v0));
    let p = cross3(d, e2);
    let det = dot3(e1, p);
    let inv = one / det;
    let s = sub3(o, v0);
    let b1 = dot3(s, p) * inv;
    let q = cross3(s, e1);
    let b2 = dot3(d, q) * inv;
    let t = dot3(e2, q) * inv;
    // NaN (det = 0) fails every comparison
    let m = active
        & !det.eq(zero)
        & b1.ge(zero)
        & b1.le(one)
        & b2.ge(zero)
        & (b1 + b2).le(one)
        & t.gt(zero)
        & t.le(t_max);
    (m, t, b1, b2)
}

/// Hit with 0 < t <= t_max: (t, b1, b2). A determinant of exactly 0 (the ray in the
/// triangle's plane) misses.
#[inline]
pub fn intersect_1(tri: &Triangle32, r: &Ray1, t_max: f32) -> Option<(f32, f32, f32)> {
    let [v0, v1, v2] = tri.v;
    let (e1, e2) = (v1 - v0, v2 - v0);
    let p = r.dir.cross(e2);
    let det = e1.dot(p);
    if det == 0.0 {
        return None;
    }
    let inv = 1.0 / det;
    let s = r.origin - v0;
    let b1 = s.dot(p) * inv;
    if !(0.0..=1.0).contains(&b1) {
        return None;
    }
    let q: Vec3 = s.cross(e1);
    let b2 = r.dir.dot(q) * inv;
    if !(b2 >= 0.0 && b1 + b2 <= 1.0) {
        return None;
    }
    let t = e2.dot(q) * inv;
    (t > 0.0 && t <= t_max).then_some((t, b1, b2))
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    fn tri() -> Triangle32 {
        Triangle32::new(
            &[
                DVec3::new(0.0, 0.0, 0.0),
                DVec3::new(4.0, 0.0, 0.0),
                DVec3::new(0.0, 4.0, 0.0),
            ],
            DVec3::ZERO,
        )
    }

    #[test]
    fn hits_inside_misses_outside_and_agrees_with_the_watertight_test() {
        let t = tri();
        for (x, y, hit) in [
            (1.0, 1.0, true),
            (3.0, 0.5, true),
            (3.0, 3.0, false),
            (-0.5, 1.0, false),
        ] {
            let r = Ray1::new(Vec3::new(x, y, 5.0), Vec3::NEG_Z);
            let mt = intersect_1(&t, &r, f32::INFINITY);
            let wt = t.intersect_1(&r, f32::INFINITY);
            assert_eq!(mt.is_some(), hit, "({x}, {y})");
            assert_eq!(wt.is_some(), hit, "({x}, {y})");
            if let (Some(a), Some(b)) = (mt, wt) {
                assert!((a.0 - 5.0).abs() < 1e-6 && (a.0 - b.0).abs() < 1e-5);
                assert!((a.1 - b.1).abs() < 1e-6 && (a.2 - b.2).abs() < 1e-6);
                assert!((a.1 - x / 4.0).abs() < 1e-6 && (a.2 - y / 4.0).abs() < 1e-6);
            }
        }
        // in the triangle's plane: no hit, no NaN
        let r = Ray1::new(Vec3::new(-1.0, 1.0, 0.0), Vec3::X);
        assert!(intersect_1(&t, &r, f32::INFINITY).is_none());
    }

    #[test]
    fn packet_equals_single_ray_per_lane() {
        let t = tri();
        let o: [Vec3; 8] = std::array::from_fn(|k| Vec3::new(k as f32 * 0.7 - 1.0, 1.0, 3.0));
        let d: [Vec3; 8] =
            std::array::from_fn(|k| Vec3::new(0.1 * k as f32, -0.2, -1.0).normalize());
        let r = RayPacket8::from_lanes(&o, &d);
        let (m, tt, b1, b2) = Moller::intersect_x8(&t, &r, Mask8::ALL, f32x8::splat(f32::INFINITY));
        for k in 0..8 {
            let one = intersect_1(&t, &r.ray(k), f32::INFINITY);
            assert_eq!(m.lane(k), one.is_some(), "lane {k}");
            if let Some((a, u, v)) = one {
                assert_eq!(
                    (a, u, v),
                    (tt.as_array()[k], b1.as_array()[k], b2.as_array()[k])
                );
            }
        }
    }

    #[test]
    fn block_lanes_equal_single_rays_per_triangle() {
        // eight triangles around one ray, some hit, some missed, one in its plane
        let tris: Vec<Triangle32> = (0..8)
            .map(|k| {
                let s = 0.5 + k as f64 * 0.4;
                let z = if k == 7 { 3.0 } else { -(k as f64) };
                Triangle32::new(
                    &[
                        DVec3::new(-s, -s, z),
                        DVec3::new(s + 0.1, -s, z + 0.2),
                        DVec3::new(-s, s, z - 0.1),
                    ],
                    DVec3::ZERO,
                )
            })
            .collect();
        let b = Triangle8::new(&tris);
        for d in [
            Vec3::new(0.3, 0.2, -1.0),
            Vec3::new(-0.5, 0.9, -0.4),
            Vec3::new(1.0, 0.0, 0.0),
        ] {
            let r = Ray1::new(Vec3::new(0.2, -0.1, 3.0), d.normalize());
            let prepared = Moller::prepare(&r);
            let (m, t, u, v) = Moller::intersect_1x8::<2>(&b, &prepared, Mask8::ALL, 50.0);
            for (k, tri) in tris.iter().enumerate() {
                let one = intersect_1(tri, &r, 50.0);
                assert_eq!(m.lane(k), one.is_some(), "{d}: triangle {k}");
                if let Some(h) = one {
                    assert_eq!(h, (t.as_array()[k], u.as_array()[k], v.as_array()[k]));
                }
            }
        }
    }
}
