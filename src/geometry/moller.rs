//! The plain Möller–Trumbore triangle test (Möller and Trumbore 1997), the profile knob
//! `triangle_test = "moller"`: fewer operations than the watertight test
//! ([`super::triangle`]), but each triangle rounds its barycentrics on its own, so a
//! ray through an edge shared by two triangles can miss both (robustness.md: 6.3 % of
//! rays aimed at a quad's diagonal here; `tests/extremes.rs` measures the leak). The
//! primitives are the same [`Triangle32`]s; the kind code [`super::PrimKind::TriangleMoller`]
//! picks this kernel per BVH leaf, chosen once per scene.
//!
//! Barycentrics are returned as (b1, b2), the weights of vertices 1 and 2, so the
//! watertight path's [`Triangle32::surface_1`] applies unchanged.

use glam::Vec3;
use wide::f32x8;

use super::triangle::Triangle32;
use crate::math::packet::{Cmp8, Mask8, Ray1, RayPacket8, Vec3x8};

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

#[inline]
pub fn occluded_1(tri: &Triangle32, r: &Ray1, t_max: f32) -> bool {
    intersect_1(tri, r, t_max).is_some_and(|h| h.0 < t_max)
}

/// Packet twin of [`intersect_1`]: lanes with a hit in (0, t_max], t, b1, b2.
#[inline]
pub fn intersect_x8(
    tri: &Triangle32,
    r: &RayPacket8,
    active: Mask8,
    t_max: f32x8,
) -> (Mask8, f32x8, f32x8, f32x8) {
    let zero = f32x8::ZERO;
    let [v0, v1, v2] = tri.v;
    let (e1, e2) = (Vec3x8::splat(v1 - v0), Vec3x8::splat(v2 - v0));
    let p = r.dir.cross(e2);
    let det = e1.dot(p);
    let inv = f32x8::splat(1.0) / det;
    let s = r.origin - Vec3x8::splat(v0);
    let b1 = s.dot(p) * inv;
    let q = s.cross(e1);
    let b2 = r.dir.dot(q) * inv;
    let t = e2.dot(q) * inv;
    // NaN (det = 0) fails every comparison
    let m = active
        & !det.eq8(zero)
        & b1.ge(zero)
        & b1.le(f32x8::splat(1.0))
        & b2.ge(zero)
        & (b1 + b2).le(f32x8::splat(1.0))
        & t.gt(zero)
        & t.le(t_max);
    (m, t, b1, b2)
}

#[inline]
pub fn occluded_x8(tri: &Triangle32, r: &RayPacket8, active: Mask8, t_max: f32x8) -> Mask8 {
    let (m, t, _, _) = intersect_x8(tri, r, active, t_max);
    m & t.lt(t_max)
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
        let (m, tt, b1, b2) = intersect_x8(&t, &r, Mask8::ALL, f32x8::splat(f32::INFINITY));
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
}
