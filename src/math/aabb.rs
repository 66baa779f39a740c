//! Axis-aligned boxes in f32.

use glam::Vec3;

/// An axis-aligned box; empty when lo > hi.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    pub lo: Vec3,
    pub hi: Vec3,
}

impl Aabb {
    pub const EMPTY: Aabb = Aabb {
        lo: Vec3::splat(f32::INFINITY),
        hi: Vec3::splat(f32::NEG_INFINITY),
    };

    pub fn new(lo: Vec3, hi: Vec3) -> Aabb {
        Aabb { lo, hi }
    }

    pub fn union(self, o: Aabb) -> Aabb {
        Aabb::new(self.lo.min(o.lo), self.hi.max(o.hi))
    }

    pub fn contains(&self, o: &Aabb) -> bool {
        self.lo.cmple(o.lo).all() && self.hi.cmpge(o.hi).all()
    }

    /// Surface area (0 for an empty box).
    pub fn area(&self) -> f32 {
        let d = (self.hi - self.lo).max(Vec3::ZERO);
        2.0 * (d.x * d.y + d.y * d.z + d.z * d.x)
    }

    pub fn centroid(&self) -> Vec3 {
        (self.lo + self.hi) * 0.5
    }

    /// The box moved out past every face by at least one f32 step and [`FACE_GAP`], as
    /// the tree's nodes store it. A ray lying exactly in a face plane (a zero direction
    /// component, its origin on the face: a camera level with the top of a clipped
    /// cylinder, the centre row of an odd-sized image) met that face at t = 0 as its
    /// exit (1/d is +2¹⁰⁰ for +0) and missed the box, though the surface's points on
    /// the face count (the quadric's box test is inclusive). Inside the gap, the
    /// face imposes no bound on such a ray; a ray in the moved face plane itself meets
    /// nothing inside. Empty and infinite coordinates stay as they are.
    ///
    /// Every node of a build takes this (2 M on a million triangles): its steps are bit
    /// arithmetic chosen by selects (`f32::next_up` and `next_down` branch on NaN,
    /// infinities and zeros).
    #[inline]
    pub fn outward(self) -> Aabb {
        let out = |v: f32, up: bool| {
            // one step away from zero in the direction `up`, or toward it (a finite v;
            // ±0 steps to the least subnormal of that direction)
            let b = v.to_bits();
            let away = (b >> 31 == 0) == up;
            let step = if v == 0.0 {
                f32::from_bits(if up { 1 } else { 0x8000_0001 })
            } else {
                f32::from_bits(if away {
                    b.wrapping_add(1)
                } else {
                    b.wrapping_sub(1)
                })
            };
            let gap = if up { v + FACE_GAP } else { v - FACE_GAP };
            let moved = if up { step.max(gap) } else { step.min(gap) };
            if v.is_finite() { moved } else { v }
        };
        Aabb::new(
            Vec3::new(
                out(self.lo.x, false),
                out(self.lo.y, false),
                out(self.lo.z, false),
            ),
            Vec3::new(
                out(self.hi.x, true),
                out(self.hi.y, true),
                out(self.hi.z, true),
            ),
        )
    }
}

/// The least distance by which a node's box clears the bounds it holds ([`Aabb::outward`]):
/// 2⁻⁵⁰ ≈ 8.9e-16, beyond one f32 step where coordinates are near 0 (the camera's own
/// planes in its frame).
pub const FACE_GAP: f32 = 8.881_784e-16;

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::{Aabb, FACE_GAP};

    /// `outward` moves each face as `f32::next_up`/`next_down` and [`FACE_GAP`] do, bit
    /// for bit: zeros, subnormals, the gap's own scale, ordinary and the largest
    /// values, infinities and NaN.
    #[test]
    fn outward_steps_as_next_up_and_next_down() {
        let reference = |v: f32, up: bool| {
            if !v.is_finite() {
                return v;
            }
            let step = if up { v.next_up() } else { v.next_down() };
            let gap = if up { v + FACE_GAP } else { v - FACE_GAP };
            if up { step.max(gap) } else { step.min(gap) }
        };
        let mut values = vec![
            0.0,
            f32::from_bits(1),
            f32::from_bits(2),
            f32::MIN_POSITIVE,
            FACE_GAP,
            FACE_GAP * 0.5,
            FACE_GAP * 3.0,
            1e-8,
            0.3,
            1.0,
            2.0,
            1e30,
            f32::MAX,
            f32::INFINITY,
            f32::NAN,
        ];
        values.extend(values.clone().iter().map(|v| -v));
        let mut checked = 0;
        for &x in &values {
            for &y in &values {
                let b = Aabb::new(Vec3::new(x, y, 1.5), Vec3::new(y, x, -2.5)).outward();
                let want = |v: f32, up: bool| reference(v, up).to_bits();
                assert_eq!(
                    [b.lo.x, b.lo.y, b.lo.z].map(f32::to_bits),
                    [want(x, false), want(y, false), want(1.5, false)],
                    "lo {x:e} {y:e}"
                );
                assert_eq!(
                    [b.hi.x, b.hi.y, b.hi.z].map(f32::to_bits),
                    [want(y, true), want(x, true), want(-2.5, true)],
                    "hi {y:e} {x:e}"
                );
                checked += 1;
            }
        }
        assert_eq!(checked, 30 * 30);
    }
}
