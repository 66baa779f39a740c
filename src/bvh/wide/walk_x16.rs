//! Sixteen rays through the 8-wide tree as one frustum: the walks of `walk_x8.rs` at
//! sixteen lanes (`WidePacket` for [`RayPacket16`]), for the `avx512` kernels.
//!
//! Everything here is `#[inline(always)]` down to the 16-lane operations, and reached
//! only from functions compiled with AVX-512 enabled and called once the CPU has been
//! found to have it (`simd::Isa`): there each operation on [`F16`] is one AVX-512
//! instruction. Node tests stay eight-wide (one per node for the whole packet);
//! triangles are tested against sixteen lanes at once. Spheres and clipped quadrics,
//! the floor and the unbounded quadrics, and packets just too spread for one frustum
//! go through the 8-lane code, half by half (the spread ones by the hybrid walk); packets of mixed direction signs or
//! scattered far past the frustum's limit take all sixteen lanes' single-ray walks
//! (closest hit: stepped in turn). A lane gets what the 8-lane walks give it, bit for
//! bit: the kernels are the same generic code (`tests/lanes.rs`).
//!
//! Four such packets of the same direction signs (an 8 × 8 tile of camera rays) can
//! walk the tree as one ([`Bvh::intersect_x64`]): each node tested once for the 64
//! rays against the union of their frusta, each leaf by each packet with its own
//! frustum and lanes. Closest hits only: the any-hit walk of four shadow packets as
//! one ran 0.7–0.8 of four walks (benches/README.md).

use super::TriBlock;
use super::walk_x8::{Frustum, WidePacket, finite_lanes, shared_octant};
use crate::bvh::{Bvh, Steps};
use crate::geometry::triangle::TriangleKernel;
use crate::geometry::{PrimKind, PrimSet};
use crate::math::packet::Mask8;
use crate::simd::LaneMask;
use crate::simd::packet::{HitPacket16, RayPacket16, cat_mask, half_mask};
use crate::simd::w16::{F16, M16};
use wide::f32x8;

impl WidePacket for RayPacket16 {
    type L = F16;
    type Hit = HitPacket16;
    const LEAVES_PER_LANE: bool = true;
    #[inline(always)]
    fn rays(&self) -> [[F16; 3]; 3] {
        [self.lanes.origin, self.lanes.dir, self.lanes.inv_dir]
    }
    #[inline(always)]
    fn hit_t(hit: &HitPacket16) -> F16 {
        hit.t
    }
    #[inline(always)]
    fn triangle<T: TriangleKernel>(
        &self,
        b: &TriBlock,
        j: usize,
        act: M16,
        t_max: F16,
    ) -> (M16, F16, F16, F16) {
        T::intersect_splat_lanes(b.tri.splat_lanes(j), &self.lanes, act, t_max)
    }
    #[inline(always)]
    fn moved_triangle<T: TriangleKernel>(
        &self,
        b: &TriBlock,
        m: &T::Moved,
        j: usize,
        act: M16,
        t_max: F16,
    ) -> (M16, F16, F16, F16) {
        T::intersect_moved_lanes(&b.tri, m, j, &self.lanes, act, t_max)
    }
    #[inline(always)]
    fn record(prims: &PrimSet, hit: &mut HitPacket16, m: M16, t: F16, uv: (F16, F16), code: i32) {
        prims.record_lanes(hit, m, t, uv, code);
    }
    #[inline(always)]
    fn other_leaf<T: TriangleKernel>(
        &self,
        prims: &PrimSet,
        kind: PrimKind,
        first: usize,
        count: usize,
        act: M16,
        hit: &mut HitPacket16,
    ) {
        let mut h = hit.halves();
        for (k, hk) in h.iter_mut().enumerate() {
            let a = half_mask(act, k);
            if a.any() {
                prims.intersect_x8::<T>(kind, first, count, &self.halves[k], a, hk);
            }
        }
        *hit = HitPacket16::from_halves(h);
    }
    #[inline(always)]
    fn other_leaf_occluded<T: TriangleKernel>(
        &self,
        prims: &PrimSet,
        kind: PrimKind,
        first: usize,
        count: usize,
        left: M16,
        t_max: F16,
    ) -> M16 {
        let t = t_max.halves();
        let blocked = |k: usize| {
            let a = half_mask(left, k);
            if a.none() {
                return Mask8::NONE;
            }
            prims.occluded_x8::<T>(kind, first, count, &self.halves[k], a, t[k])
        };
        cat_mask(blocked(0), blocked(1))
    }
}

/// How a 16-lane packet goes: as one frustum (its direction signs and the frustum),
/// else `Err(scattered)`: true for the lanes' own walks, false for 8 lanes half by half.
type Route16 = Result<(u32, Frustum), bool>;

/// The direction signs every active lane of both halves shares, or `None`.
#[inline(always)]
fn octant_of(r: &RayPacket16, act: [Mask8; 2]) -> Option<u32> {
    let o = [0, 1].map(|k| {
        if act[k].none() {
            Some(None)
        } else {
            shared_octant(&r.halves[k], act[k]).map(Some)
        }
    });
    match o {
        [Some(Some(a)), Some(Some(b))] if a == b => Some(a),
        [Some(Some(a)), Some(None)] | [Some(None), Some(Some(a))] => Some(a),
        _ => None,
    }
}

impl Bvh {
    /// Closest hits of the lanes `active` of sixteen rays below `hit.t`: per lane what
    /// [`Bvh::intersect_x8`] gives it. Call only from code compiled with AVX-512.
    #[inline(always)]
    pub fn intersect_x16<T: TriangleKernel>(
        &self,
        r: &RayPacket16,
        active: M16,
        hit: &mut HitPacket16,
        steps: &mut Steps,
    ) {
        self.intersect_x16_by::<T>(r, self.frustum_x16(r, active), hit, steps);
    }

    /// [`Bvh::intersect_x16`] by the route [`Bvh::frustum_x16`] gave.
    #[inline(always)]
    fn intersect_x16_by<T: TriangleKernel>(
        &self,
        r: &RayPacket16,
        (half, fin, frustum): ([Mask8; 2], [Mask8; 2], Route16),
        hit: &mut HitPacket16,
        steps: &mut Steps,
    ) {
        // (the halves' route, `intersect_x8`, bounds its own lanes)
        if self.bounds_by_floor() && !matches!(frustum, Err(false)) {
            let mut h = hit.halves();
            for (k, hk) in h.iter_mut().enumerate() {
                self.prims.bound_by_floor_x8(&r.halves[k], half[k], hk);
            }
            *hit = HitPacket16::from_halves(h);
        }
        if frustum.as_ref().is_err_and(|&scattered| scattered) {
            self.intersect_x16_lanes::<T>(r, half, hit, steps);
            return;
        }
        if let Ok((oct, fr)) = frustum {
            let act = cat_mask(fin[0], fin[1]);
            with_const!(
                oct,
                [0, 1, 2, 3, 4, 5, 6, 7],
                self.frustum_walk_x16::<T>(r, act, &fr, hit, steps)
            );
            let mut h = hit.halves();
            for (k, hk) in h.iter_mut().enumerate() {
                if half[k].any() {
                    self.intersect_beside_x8::<T>(&r.halves[k], half[k], hk, steps);
                }
            }
            *hit = HitPacket16::from_halves(h);
            return;
        }
        let mut h = hit.halves();
        for (k, hk) in h.iter_mut().enumerate() {
            self.intersect_x8::<T>(&r.halves[k], half[k], hk, steps);
        }
        *hit = HitPacket16::from_halves(h);
    }

    /// Closest hits of four 16-lane packets (a block of 64 camera rays, say) below
    /// `hit[q].t`: when each goes as one frustum and all four share their direction
    /// signs, one walk of the tree for the four ([`Bvh::frustum_walk_n`]: each node
    /// tested once for 64 rays, each leaf with each packet's own frustum and lanes);
    /// else each packet by [`Bvh::intersect_x16`]. Per lane what `intersect_x16` gives
    /// it. Call only from code compiled with AVX-512.
    #[inline(always)]
    pub fn intersect_x64<T: TriangleKernel>(
        &self,
        r: &[RayPacket16; 4],
        active: [M16; 4],
        hit: &mut [HitPacket16; 4],
        steps: &mut Steps,
    ) {
        // (written out: a closure here would be compiled apart from the AVX-512 of its
        // caller whenever the inliner declines it, its 16-lane operations then calls)
        let routes = [
            self.frustum_x16(&r[0], active[0]),
            self.frustum_x16(&r[1], active[1]),
            self.frustum_x16(&r[2], active[2]),
            self.frustum_x16(&r[3], active[3]),
        ];
        let oct = match routes[0].2 {
            Ok((oct, _)) => oct,
            Err(_) => u32::MAX,
        };
        if !routes.iter().all(|x| matches!(x.2, Ok((o, _)) if o == oct)) {
            for (q, route) in routes.into_iter().enumerate() {
                self.intersect_x16_by::<T>(&r[q], route, &mut hit[q], steps);
            }
            return;
        }
        let subs = [0, 1, 2, 3].map(|q| match &routes[q].2 {
            Ok((_, fr)) => fr,
            Err(_) => unreachable!("every route is one frustum"),
        });
        // as `intersect_x16` does for one packet: the floor first, the tree, then what
        // lies beside it
        if self.bounds_by_floor() {
            for q in 0..4 {
                let mut h = hit[q].halves();
                for (k, hk) in h.iter_mut().enumerate() {
                    self.prims
                        .bound_by_floor_x8(&r[q].halves[k], routes[q].0[k], hk);
                }
                hit[q] = HitPacket16::from_halves(h);
            }
        }
        let act = [0, 1, 2, 3].map(|q| cat_mask(routes[q].1[0], routes[q].1[1]));
        with_const!(
            oct,
            [0, 1, 2, 3, 4, 5, 6, 7],
            self.frustum_walk_x64::<T>(r, act, subs, hit, steps)
        );
        for q in 0..4 {
            let half = routes[q].0;
            let mut h = hit[q].halves();
            for (k, hk) in h.iter_mut().enumerate() {
                if half[k].any() {
                    self.intersect_beside_x8::<T>(&r[q].halves[k], half[k], hk, steps);
                }
            }
            hit[q] = HitPacket16::from_halves(h);
        }
    }

    #[inline(always)]
    fn frustum_walk_x64<T: TriangleKernel, const OCT: u32>(
        &self,
        r: &[RayPacket16; 4],
        act: [M16; 4],
        subs: [&Frustum; 4],
        hit: &mut [HitPacket16; 4],
        steps: &mut Steps,
    ) {
        let fr = Frustum::union::<OCT>(&subs);
        let r = [&r[0], &r[1], &r[2], &r[3]];
        self.frustum_walk_n::<RayPacket16, T, OCT, 4>(r, act, &fr, subs, hit, steps);
    }

    /// The halves of `active`, their finite lanes, and when one frustum serves all the
    /// finite lanes (a tree big enough, shared direction signs, within the spread
    /// limit) their direction signs and that frustum; else `Err(scattered)`: true when
    /// the lanes' own walks serve them best (mixed signs or spread far apart:
    /// [`Bvh::lane_walks`]), false when the halves go at 8 lanes.
    #[inline(always)]
    fn frustum_x16(&self, r: &RayPacket16, active: M16) -> ([Mask8; 2], [Mask8; 2], Route16) {
        let spread = self.frustum_spread();
        let half = [half_mask(active, 0), half_mask(active, 1)];
        let fin = [0, 1].map(|k| half[k] & finite_lanes(&r.halves[k]));
        let act = cat_mask(fin[0], fin[1]);
        if spread < 0.0 || self.wide.nodes.is_empty() || act.none() {
            return (half, fin, Err(false));
        }
        let frustum = match octant_of(r, fin) {
            Some(oct) => {
                let [o, d, inv] = r.rays();
                match Frustum::new(o, d, inv, act, oct, spread, self.wide.diagonal) {
                    (fr, None) => Ok((oct, fr)),
                    (_, Some(how_far)) => Err(self.lane_walks(how_far)),
                }
            }
            // halves of different signs, each of one octant (a block across the image's
            // centre line): each half's own route; else the lanes' walks
            None => Err(self.lane_walks(f32::INFINITY)
                && !(0..2).all(|k| fin[k].none() || shared_octant(&r.halves[k], fin[k]).is_some())),
        };
        (half, fin, frustum)
    }

    /// [`Bvh::intersect_x16`] per lane: [`Bvh::intersect_lanes_of`] of both halves,
    /// sixteen walks stepped in turn.
    #[inline(always)]
    fn intersect_x16_lanes<T: TriangleKernel>(
        &self,
        r: &RayPacket16,
        half: [Mask8; 2],
        hit: &mut HitPacket16,
        steps: &mut Steps,
    ) {
        let mut h = hit.halves();
        let halves = [&r.halves[0], &r.halves[1]];
        self.intersect_lanes_of::<T, 2, 16>(halves, half, &mut h, steps);
        *hit = HitPacket16::from_halves(h);
    }

    #[inline(always)]
    fn frustum_walk_x16<T: TriangleKernel, const OCT: u32>(
        &self,
        r: &RayPacket16,
        act: M16,
        fr: &Frustum,
        hit: &mut HitPacket16,
        steps: &mut Steps,
    ) {
        self.frustum_walk::<RayPacket16, T, OCT, false>(r, act, fr, hit, steps);
    }

    /// The lanes of `active` blocked with 0 < t < t_max: per lane what
    /// [`Bvh::occluded_x8`] gives it. Call only from code compiled with AVX-512.
    #[inline(always)]
    pub fn occluded_x16<T: TriangleKernel>(
        &self,
        r: &RayPacket16,
        active: M16,
        t_max: F16,
        steps: &mut Steps,
    ) -> M16 {
        let t = t_max.halves();
        let (half, fin, frustum) = self.frustum_x16(r, active);
        if frustum.as_ref().is_err_and(|&scattered| scattered) {
            return self.occluded_x16_lanes::<T>(r, half, t, steps);
        }
        // the frustum of every finite lane (a superset of those the floor and the
        // unbounded quadrics leave: still a bound of each), else each half at 8 lanes
        if let Ok((oct, fr)) = frustum {
            let mut left = [Mask8::NONE; 2];
            for (k, l) in left.iter_mut().enumerate() {
                if half[k].any() {
                    *l = self.occluded_beside_x8::<T>(&r.halves[k], half[k], t[k], steps);
                }
            }
            let rest = cat_mask(left[0] & fin[0], left[1] & fin[1]);
            let blocked = if rest.any() {
                with_const!(
                    oct,
                    [0, 1, 2, 3, 4, 5, 6, 7],
                    self.frustum_occlusion_x16::<T>(r, rest, &fr, t_max, steps)
                )
            } else {
                M16::NONE
            };
            return active.and_not(cat_mask(left[0], left[1])) | blocked;
        }
        let mut blocked = [Mask8::NONE; 2];
        for (k, b) in blocked.iter_mut().enumerate() {
            if half[k].any() {
                *b = self.occluded_x8::<T>(&r.halves[k], half[k], t[k], steps);
            }
        }
        cat_mask(blocked[0], blocked[1])
    }

    /// [`Bvh::occluded_x16`] per lane: [`Bvh::occluded_lanes_of`] of both halves,
    /// sixteen walks one after another.
    #[inline(always)]
    fn occluded_x16_lanes<T: TriangleKernel>(
        &self,
        r: &RayPacket16,
        half: [Mask8; 2],
        t_max: [f32x8; 2],
        steps: &mut Steps,
    ) -> M16 {
        let halves = [&r.halves[0], &r.halves[1]];
        let [b0, b1] = self.occluded_lanes_of::<T, 2>(halves, half, t_max, true, steps);
        cat_mask(b0, b1)
    }

    #[inline(always)]
    fn frustum_occlusion_x16<T: TriangleKernel, const OCT: u32>(
        &self,
        r: &RayPacket16,
        act: M16,
        fr: &Frustum,
        t_max: F16,
        steps: &mut Steps,
    ) -> M16 {
        self.frustum_occlusion::<RayPacket16, T, OCT, false>(r, act, fr, t_max, steps)
    }
}
