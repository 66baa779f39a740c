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
    pub fn outward(self) -> Aabb {
        let out = |v: f32, up: bool| {
            if !v.is_finite() {
                return v;
            }
            let step = if up { v.next_up() } else { v.next_down() };
            let gap = if up { v + FACE_GAP } else { v - FACE_GAP };
            if up { step.max(gap) } else { step.min(gap) }
        };
        Aabb::new(
            Vec3::from(self.lo.to_array().map(|v| out(v, false))),
            Vec3::from(self.hi.to_array().map(|v| out(v, true))),
        )
    }
}

/// The least distance by which a node's box clears the bounds it holds ([`Aabb::outward`]):
/// 2⁻⁵⁰ ≈ 8.9e-16, beyond one f32 step where coordinates are near 0 (the camera's own
/// planes in its frame).
pub const FACE_GAP: f32 = 8.881_784e-16;
