//! The binary BVH's node.

use glam::Vec3A;
use wide::f32x8;

use super::slot::Slot;
use crate::geometry::PrimKind;
use crate::math::Aabb;
use crate::math::packet::{Cmp8, FAR_WIDEN, Mask8, Ray1, RayPacket8};
use crate::simd;

/// A node of the flat BVH array. 32 B, two per cache line, 32-byte aligned.
///
/// `slot`: a leaf of primitives of one kind, or an interior node and its split axis.
/// `first`: interior: index of the left child, the right child is `first + 1`;
/// leaf: index of its first primitive in the PrimSet array of its kind (a leaf's
/// primitives are contiguous there).
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(32))]
pub struct BvhNode {
    pub lo: [f32; 3],
    pub first: u32,
    pub hi: [f32; 3],
    pub slot: Slot,
}

const _: () = assert!(std::mem::size_of::<BvhNode>() == 32);

impl BvhNode {
    pub fn interior(b: Aabb, left: u32, axis: usize) -> BvhNode {
        let b = b.outward();
        BvhNode {
            lo: b.lo.into(),
            first: left,
            hi: b.hi.into(),
            slot: Slot::split(axis),
        }
    }

    pub fn leaf(b: Aabb, first: u32, count: u32, kind: PrimKind) -> BvhNode {
        let b = b.outward();
        BvhNode {
            lo: b.lo.into(),
            first,
            hi: b.hi.into(),
            slot: Slot::leaf(kind, count),
        }
    }

    #[inline]
    pub fn count(&self) -> u32 {
        self.slot.count()
    }
    #[inline]
    pub fn is_leaf(&self) -> bool {
        !self.slot.is_interior()
    }
    #[inline]
    pub fn axis(&self) -> usize {
        self.slot.axis()
    }
    #[inline]
    pub fn kind(&self) -> PrimKind {
        self.slot.kind()
    }
    pub fn bounds(&self) -> Aabb {
        Aabb::new(self.lo.into(), self.hi.into())
    }

    /// Slab test of one ray: the entry distance when the ray meets the box with
    /// 0 <= t and t <= t_max (far bound widened by 1 + 2γ(3)).
    #[inline]
    pub fn intersect_1(&self, r: &Ray1, t_max: f32) -> Option<f32> {
        let o = Vec3A::from(r.origin);
        let inv = Vec3A::from(r.inv_dir);
        let t0 = (Vec3A::from(self.lo) - o) * inv;
        let t1 = (Vec3A::from(self.hi) - o) * inv;
        let near = t0.min(t1).max_element().max(0.0);
        // Widened after clamping to t_max, so a box whose entry equals the current
        // hit (a coincident surface in another leaf) is still entered and the tie
        // rule (lower object index wins) sees it.
        let far = t0.max(t1).min_element().min(t_max) * FAR_WIDEN;
        (near <= far).then_some(near)
    }

    /// Slab test of a packet: the lanes of `active` that meet the box with
    /// 0 <= t <= t_max (far bound widened by 1 + 2γ(3)).
    ///
    /// `fast_min`/`fast_max` are safe here, and only here: with the slab rule (1/d
    /// finite, see `math::packet`) and finite box bounds and origins, no t is NaN, so
    /// they agree with wide's NaN-ignoring `min`/`max` on every target.
    #[inline]
    pub fn intersect_x8(&self, r: &RayPacket8, active: Mask8, t_max: f32x8) -> Mask8 {
        // the entry distances are dropped by the optimiser when unused
        self.intersect_x8_near(r, active, t_max).0
    }

    /// Slab test of a packet as [`BvhNode::intersect_x8`], also returning each lane's
    /// entry distance.
    #[inline(always)]
    pub fn intersect_x8_near(&self, r: &RayPacket8, active: Mask8, t_max: f32x8) -> (Mask8, f32x8) {
        let a = |v: crate::math::packet::Vec3x8| [v.x, v.y, v.z];
        self.intersect_lanes(a(r.origin), a(r.inv_dir), active, t_max)
    }

    /// [`BvhNode::intersect_x8_near`] at any width, on the lanes' origins and 1/d.
    #[inline(always)]
    pub fn intersect_lanes<L: simd::Lanes>(
        &self,
        origin: [L; 3],
        inv_dir: [L; 3],
        active: L::Mask,
        t_max: L,
    ) -> (L::Mask, L) {
        // a function, not a closure (see `simd::packet`)
        #[inline(always)]
        fn slab<L: simd::Lanes>(lo: f32, hi: f32, o: L, inv: L) -> (L, L) {
            let t0 = (L::splat(lo) - o) * inv;
            let t1 = (L::splat(hi) - o) * inv;
            (t0.fast_min(t1), t0.fast_max(t1))
        }
        let (nx, fx) = slab(self.lo[0], self.hi[0], origin[0], inv_dir[0]);
        let (ny, fy) = slab(self.lo[1], self.hi[1], origin[1], inv_dir[1]);
        let (nz, fz) = slab(self.lo[2], self.hi[2], origin[2], inv_dir[2]);
        let near = nx.fast_max(ny).fast_max(nz.fast_max(L::zero()));
        // widened after clamping to t_max: see `intersect_1`
        let far = fx.fast_min(fy).fast_min(fz).fast_min(t_max) * L::splat(FAR_WIDEN);
        (active & near.le(far), near)
    }

    /// [`BvhNode::intersect_x8_near`] for a packet whose active lanes all have the
    /// direction signs `NX`, `NY`, `NZ` (true: 1/d < 0): the entry plane of each slab is
    /// known, so the six min/max of the slab test go. Same result: with 1/d of one
    /// sign, (lo − o)·(1/d) and (hi − o)·(1/d) are ordered as lo and hi are (rounding is
    /// monotone), so the min and max it skips would pick exactly these.
    #[inline(always)]
    pub fn intersect_x8_oct<const NX: bool, const NY: bool, const NZ: bool>(
        &self,
        r: &RayPacket8,
        active: Mask8,
        t_max: f32x8,
    ) -> (Mask8, f32x8) {
        let pick = |neg: bool, a: usize| {
            if neg {
                (self.hi[a], self.lo[a])
            } else {
                (self.lo[a], self.hi[a])
            }
        };
        let slab = |(n, f): (f32, f32), o: f32x8, inv: f32x8| {
            ((f32x8::splat(n) - o) * inv, (f32x8::splat(f) - o) * inv)
        };
        let (nx, fx) = slab(pick(NX, 0), r.origin.x, r.inv_dir.x);
        let (ny, fy) = slab(pick(NY, 1), r.origin.y, r.inv_dir.y);
        let (nz, fz) = slab(pick(NZ, 2), r.origin.z, r.inv_dir.z);
        let near = nx.fast_max(ny).fast_max(nz.fast_max(f32x8::ZERO));
        // widened after clamping to t_max: see `intersect_1`
        let far = fx.fast_min(fy).fast_min(fz).fast_min(t_max) * f32x8::splat(FAR_WIDEN);
        (active & near.le(far), near)
    }
}
