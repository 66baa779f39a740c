//! Packet traversal of the 8-wide tree for packets whose active lanes share their
//! direction signs (nearly every camera and shadow packet), after Embree's coherent
//! packet walk.
//!
//! The packet walks the tree as one "fat ray": a [`Frustum`] bounds every lane's slab
//! distances by interval arithmetic over the lanes' origins and 1/d, so one 8-wide
//! test per node (the eight slots at once, as for a single ray) says which children
//! some lane may enter and gives a lower bound of their entry distances; the children
//! are visited nearest first, and a popped subtree is skipped when that bound lies
//! behind every active lane's nearest hit. Nothing is decided per lane above the
//! leaves but one thing: the 16-lane any-hit walk pushes a leaf only when some lane's
//! own slab test meets its box ([`entered_slots`]). Packets past the frustum's limit
//! whose lanes still share their signs (a curved mirror's, `FRUSTUM_SPREAD` to
//! `LANES_SPREAD`) take the hybrid walk: the same walk and frustum, each slot the
//! frustum meets, interior or leaf, then tested per lane, so a subtree is entered only
//! where some lane's own test enters it ([`Bvh::intersect_x8_wide`]). In a leaf, the frustum test of a
//! triangle block's per-lane binary leaf boxes (`WideBvh::leaf_boxes`) picks the
//! triangles to test (all of them in a block of one binary leaf, whose box the frustum
//! has passed); each is tested against the whole packet with the packet kernel
//! (`TriangleKernel::intersect_splat_x8`, the binary packet walk's, or at 16 lanes its
//! twin `intersect_splat_lanes`), and a lane's hit counts only when the lane also
//! passes that triangle's binary leaf box (the single-ray wide walk's rule, see
//! [`TriBlock`]), so a lane reports what the binary walks report for it.
//!
//! Why the bound is exact enough to be safe: for one axis and plane p, lane i computes
//! t_i = fl(fl(p − o_i) · r_i) (r = 1/d). Rounding is monotone, so with o_i in
//! [o_lo, o_hi] and r_i in [r_lo, r_hi] of one sign, fl(p − o_i) lies between
//! fl(p − o_hi) and fl(p − o_lo), and t_i between the rounded products of the interval
//! ends; the frustum computes those ends with the same operations. Hence its entry
//! bound is <= every lane's entry and its exit bound >= every lane's exit, and a box a
//! lane meets is met by the frustum (superset of lanes, never fewer).
//!
//! Contract as `bvh/mod.rs`; lanes with a non-finite origin or 1/d skip the tree (as
//! single rays do in `walk_1.rs`). Step counters: `boxes` counts wide node tests,
//! `prims` the triangles tested (each against the packet).

use wide::f32x8;

use super::{Pending, TriBlock, WIDE_STACK, WideBvh};
use crate::bvh::node::BvhNode;
use crate::bvh::slot::{SlotRef, Stack};
use crate::bvh::{Bvh, Steps};
use crate::geometry::PrimSet;
use crate::geometry::triangle::TriangleKernel;
use crate::geometry::{PrimKind, prim_code};
use crate::math::packet::{Cmp8, FAR_WIDEN, HitPacket8, Mask8, RayPacket8, Vec3x8};
use crate::simd;
use crate::simd::packet::{all_same, dot3, max_in, min_in};

/// Largest spread of a packet served by the frustum walk (radians between lane
/// directions; origins: this fraction of the tree's diagonal); wider packets take the
/// hybrid walk ([`Bvh::intersect_x8_wide`]), whose per-lane slot tests cull better
/// than one wide frustum. The frustum walk and the binary packet walk (then in the
/// hybrid's place) broke even near 0.023 (benches/README.md); this keeps a margin.
pub const FRUSTUM_SPREAD: f32 = 0.015;

/// Spread (as [`FRUSTUM_SPREAD`]) past which a packet's lanes take their own single-ray
/// walks of the wide tree (closest hit: stepped in turn; any hit: one after another)
/// instead of the hybrid walk: lanes that far apart share few nodes (random shadow
/// rays of one light), while packets just past the frustum limit (a silhouette, a
/// curved mirror) still share most of their paths (figures: benches/README.md).
pub const LANES_SPREAD: f32 = 16.0 * FRUSTUM_SPREAD;

/// Fewest wide nodes for which packets take the wide walk at all (`Bvh::intersect_x8`):
/// in smaller trees building the frustum costs more than the few binary steps it saves.
pub const WIDE_PACKET_MIN_NODES: usize = 16;

/// Interval bounds of a packet's rays, splatted, for the slab test of eight boxes at once.
/// The entry and exit planes of each axis follow from the direction signs, a constant
/// of the walks (`OCT` of [`Frustum::test`]).
pub(crate) struct Frustum {
    /// Per axis: the origin bound subtracted from the entry plane (o_hi when 1/d > 0,
    /// o_lo otherwise) and from the exit plane (the other one).
    o_near: [f32x8; 3],
    o_far: [f32x8; 3],
    /// The origin of every lane of the packet's `act`, when they all have the same bits
    /// (a camera's packets), splatted.
    origin: Option<[f32x8; 3]>,
    /// Per axis: least and largest 1/d over the lanes.
    r_lo: [f32x8; 3],
    r_hi: [f32x8; 3],
}

impl Frustum {
    /// The frustum of the lanes `act` (non-empty, finite, all with the direction signs
    /// of `octant`: bit k set when 1/d < 0 on axis k) of a packet of any width, given
    /// its origins `o`, unit directions `d` and 1/d `inv`, and `Some(how far)` when the
    /// lanes are too far apart for the frustum walk to serve them: their directions
    /// more than `spread` radians from the first lane's (unit directions), or their
    /// origins spread over more than `spread` times `size` (the tree's diagonal) on an
    /// axis; `how far` is the larger of the angle's chord (√(2 − 2 cos θ), the angle
    /// itself at these sizes) and the origins' extent over `size`. The frustum bounds
    /// the lanes however far apart they lie (the hybrid walk's, past the limit).
    #[inline(always)]
    pub(super) fn new<L: simd::Lanes>(
        o: [L; 3],
        d: [L; 3],
        inv: [L; 3],
        act: L::Mask,
        octant: u32,
        spread: f32,
        size: f32,
    ) -> (Frustum, Option<f32>) {
        use simd::LaneMask as _;
        let neg = [0, 1, 2].map(|a| (octant >> a & 1) as usize);
        let first = act.bits().trailing_zeros() as usize;
        // one origin for every lane (a camera's packets): it is both bounds, no six
        // reductions (no closures over lanes: see `simd::packet`); the same bits, not
        // only the same value, since a block is moved to it (−0 and +0 move a vertex of
        // −0 to different zeros)
        let o0 = [o[0].lane(first), o[1].lane(first), o[2].lane(first)];
        let one_origin =
            all_same(o[0], o0[0], act) && all_same(o[1], o0[1], act) && all_same(o[2], o0[2], act);
        let (o_lo, o_hi) = if one_origin {
            (o0, o0)
        } else {
            (
                [min_in(o[0], act), min_in(o[1], act), min_in(o[2], act)],
                [max_in(o[0], act), max_in(o[1], act), max_in(o[2], act)],
            )
        };
        let d0 = [
            L::splat(d[0].lane(first)),
            L::splat(d[1].lane(first)),
            L::splat(d[2].lane(first)),
        ];
        let cos = min_in(dot3(d, d0), act);
        let (r_lo, r_hi) = (
            [
                min_in(inv[0], act),
                min_in(inv[1], act),
                min_in(inv[2], act),
            ],
            [
                max_in(inv[0], act),
                max_in(inv[1], act),
                max_in(inv[2], act),
            ],
        );
        let ext = (o_hi[0] - o_lo[0])
            .max(o_hi[1] - o_lo[1])
            .max(o_hi[2] - o_lo[2]);
        // (1 − cos θ ≈ θ²/2)
        let past = (cos < 1.0 - 0.5 * spread * spread || ext > spread * size)
            .then(|| (2.0 * (1.0 - cos)).max(0.0).sqrt().max(ext / size));
        let s = f32x8::splat;
        let fr = Frustum {
            o_near: [0, 1, 2].map(|a| s(if neg[a] == 0 { o_hi[a] } else { o_lo[a] })),
            o_far: [0, 1, 2].map(|a| s(if neg[a] == 0 { o_lo[a] } else { o_hi[a] })),
            origin: one_origin.then(|| o0.map(s)),
            r_lo: r_lo.map(s),
            r_hi: r_hi.map(s),
        };
        (fr, past)
    }

    /// The eight boxes of `bounds` (layout of `WideNode::bounds`) that some lane of
    /// direction signs `OCT` (bit k: 1/d < 0 on axis k, the octant of [`Frustum::new`])
    /// may meet with 0 <= t <= t_max (far bound widened by 1 + 2γ(3) as in the per-lane
    /// test), as bits, and a lower bound of the lanes' entry distances. Empty slots
    /// (lo = +∞, hi = −∞) give entry +∞ and exit −∞: never met. No NaN arises (finite
    /// origins, finite non-zero 1/d), so `fast_min`/`fast_max` are exact.
    #[inline(always)]
    pub(super) fn test<const OCT: u32>(&self, bounds: &[f32x8; 6], t_max: f32) -> (u32, f32x8) {
        // entry plane of axis a: lo when 1/d > 0 (a constant index, no lookup)
        let near = |a: usize| 2 * a + (OCT >> a & 1) as usize;
        // min(d·r_lo, d·r_hi) is d·r_lo when d >= +0 and d·r_hi when d <= −0 (r_lo and
        // r_hi share their sign, rounding is monotone, ±0 products are equal): one
        // product picked by the sign bit of d, bit for bit the same; max the other way
        let entry = |a: usize| {
            let d = bounds[near(a)] - self.o_near[a];
            d * by_sign(d, self.r_hi[a], self.r_lo[a])
        };
        let exit = |a: usize| {
            let d = bounds[near(a) ^ 1] - self.o_far[a];
            d * by_sign(d, self.r_lo[a], self.r_hi[a])
        };
        let near = entry(0)
            .fast_max(entry(1))
            .fast_max(entry(2).fast_max(f32x8::ZERO));
        let far = exit(0)
            .fast_min(exit(1))
            .fast_min(exit(2).fast_min(f32x8::splat(t_max)))
            * f32x8::splat(FAR_WIDEN);
        (near.le(far).bits(), near)
    }

    /// The frustum of the lanes of every frustum of `fs` (each of direction signs
    /// `OCT`), for node tests only: each bound the outer one of theirs, so a box that
    /// some lane of some frustum may meet passes it. No shared origin: the leaves are
    /// tested with each packet's own frustum.
    #[inline(always)]
    pub(super) fn union<const OCT: u32>(fs: &[&Frustum]) -> Frustum {
        let mut u = Frustum {
            o_near: fs[0].o_near,
            o_far: fs[0].o_far,
            origin: None,
            r_lo: fs[0].r_lo,
            r_hi: fs[0].r_hi,
        };
        for f in &fs[1..] {
            for a in 0..3 {
                // the entry plane's origin bound is o_hi when 1/d > 0 (the largest
                // over the lanes), else o_lo; the exit plane's the other one
                if OCT >> a & 1 == 0 {
                    u.o_near[a] = u.o_near[a].fast_max(f.o_near[a]);
                    u.o_far[a] = u.o_far[a].fast_min(f.o_far[a]);
                } else {
                    u.o_near[a] = u.o_near[a].fast_min(f.o_near[a]);
                    u.o_far[a] = u.o_far[a].fast_max(f.o_far[a]);
                }
                u.r_lo[a] = u.r_lo[a].fast_min(f.r_lo[a]);
                u.r_hi[a] = u.r_hi[a].fast_max(f.r_hi[a]);
            }
        }
        u
    }

    /// The triangles of block `b` whose binary leaf some lane may enter, as bits: all of
    /// them in a block of one binary leaf (its box is the slot's, which the walk's
    /// frustum has passed: this one, or under [`Bvh::frustum_walk_n`] the union of it
    /// and others, so a few more candidates), else those whose leaf box passes
    /// [`Frustum::test`] (`leaf`: the block's `WideBvh::leaf_boxes`). A candidate's hit
    /// still counts only for the lanes that pass its leaf box by their own test.
    #[inline(always)]
    fn block_candidates<const OCT: u32>(&self, b: &TriBlock, leaf: &[f32x8; 6], t_hi: f32) -> u32 {
        if b.one_leaf {
            (1 << b.count) - 1
        } else {
            self.test::<OCT>(leaf, t_hi).0
        }
    }
}

/// `neg` in the lanes where the sign bit of `d` is set (−0 included), `pos` elsewhere.
#[inline(always)]
fn by_sign(d: f32x8, neg: f32x8, pos: f32x8) -> f32x8 {
    // one `vblendvps`, which reads only the sign bits of its mask (`simd::w8`)
    <f32x8 as simd::Lanes>::select_by_sign(d, neg, pos)
}

/// Lanes whose origin, direction and 1/d are finite (the others never hit a bounded
/// primitive and would make the slab tests NaN: a direction infinite on every axis has
/// a finite 1/d of zeros, and (±∞ − o)·0 of an empty slot is NaN).
#[inline(always)]
pub(crate) fn finite_lanes(r: &RayPacket8) -> Mask8 {
    let fin = |v: f32x8| (v * f32x8::ZERO).eq8(f32x8::ZERO); // ±∞ · 0 and NaN · 0: NaN
    fin(r.origin.x)
        & fin(r.origin.y)
        & fin(r.origin.z)
        & fin(r.dir.x)
        & fin(r.dir.y)
        & fin(r.dir.z)
        & fin(r.inv_dir.x)
        & fin(r.inv_dir.y)
        & fin(r.inv_dir.z)
}

/// The direction signs shared by every lane of `act` (bit k: 1/d < 0 on axis k; 1/d
/// carries the sign of d, −0 included), or `None` when the lanes differ.
#[inline(always)]
pub(crate) fn shared_octant(r: &RayPacket8, act: Mask8) -> Option<u32> {
    let a = act.bits();
    let mut oct = 0;
    for (k, inv) in [r.inv_dir.x, r.inv_dir.y, r.inv_dir.z]
        .into_iter()
        .enumerate()
    {
        let s = inv.to_bitmask() & a;
        if s == a {
            oct |= 1 << k;
        } else if s != 0 {
            return None;
        }
    }
    Some(oct)
}

/// Lane `j` of eight boxes in the layout of `WideNode::bounds` (a node's slot `j`, or
/// the binary leaf box of a block's triangle `j`) as a binary node: its packet slab
/// test is the one the binary packet walk runs on that box, bit for bit.
#[inline(always)]
pub(crate) fn lane_box(bounds: &[f32x8; 6], j: usize) -> BvhNode {
    let c = |k: usize| bounds[k].as_array()[j];
    BvhNode {
        lo: [c(0), c(2), c(4)],
        first: 0,
        hi: [c(1), c(3), c(5)],
        slot: crate::bvh::slot::Slot::INTERIOR,
    }
}

/// Of the slots `bits` of `node` (those the frustum meets), all but the triangle
/// leaves, and with `interior` the interior slots, that no lane of `act` meets by its
/// own slab test (the binary walk's test of the slot's box, [`lane_box`]): a lane that
/// misses a slot's box misses every box below it (each box holds its children's, and
/// the test is monotone in the planes), and a triangle's hit counts only for lanes that
/// pass its leaf box. (Spheres and quadrics have no such per-lane box test in the leaf,
/// so their leaves are kept.) The frustum of origins spread over a surface (shadow
/// rays) meets many small leaves between the lanes that no lane meets; the frustum of
/// a spread packet, many subtrees.
#[inline(always)]
fn entered_slots<P: WidePacket>(
    r: &P,
    node: &super::WideNode,
    bits: u32,
    act: Mask<P>,
    t_max: P::L,
    interior: bool,
) -> u32 {
    use simd::LaneMask as _;
    let [o, _, inv] = r.rays();
    let (mut keep, mut scan) = (bits, bits);
    while scan != 0 {
        let s = scan.trailing_zeros() as usize;
        scan &= scan - 1;
        let slot = node.slot[s];
        if (slot.holds(PrimKind::Triangle) || interior && slot.is_interior())
            && lane_box(&node.bounds, s)
                .intersect_lanes(o, inv, act, t_max)
                .0
                .none()
        {
            keep &= !(1 << s);
        }
    }
    keep
}

/// A packet the frustum walks trace: eight lanes ([`RayPacket8`]) or sixteen
/// ([`RayPacket16`], the `avx512` kernels). What differs between the widths is here;
/// the walks are one code.
///
/// [`RayPacket16`]: crate::simd::packet::RayPacket16
pub(crate) trait WidePacket {
    type L: simd::Lanes;
    type Hit;
    /// Whether the any-hit walk tests each triangle leaf the frustum meets against
    /// every lane before it is pushed ([`entered_slots`]): it pays at sixteen lanes,
    /// whose frustum spans twice the origins of eight (benches/README.md).
    const LEAVES_PER_LANE: bool;
    /// Origins, unit directions and 1/d of the lanes.
    fn rays(&self) -> [[Self::L; 3]; 3];
    /// The lanes' nearest hit so far.
    fn hit_t(hit: &Self::Hit) -> Self::L;
    /// Triangle `j` of block `b` against the lanes `act`: hits with 0 < t <= t_max.
    fn triangle<T: TriangleKernel>(
        &self,
        b: &TriBlock,
        j: usize,
        act: Mask<Self>,
        t_max: Self::L,
    ) -> (Mask<Self>, Self::L, Self::L, Self::L);
    /// [`WidePacket::triangle`] when every lane of `act` has, bit for bit, the origin
    /// block `b` was moved to (`m`, [`TriangleKernel::move_block`]).
    fn moved_triangle<T: TriangleKernel>(
        &self,
        b: &TriBlock,
        m: &T::Moved,
        j: usize,
        act: Mask<Self>,
        t_max: Self::L,
    ) -> (Mask<Self>, Self::L, Self::L, Self::L);
    /// Records hits of primitive `code` (as [`PrimSet::record_x8`]).
    fn record(
        prims: &PrimSet,
        hit: &mut Self::Hit,
        m: Mask<Self>,
        t: Self::L,
        uv: (Self::L, Self::L),
        code: i32,
    );
    /// A leaf of spheres or clipped quadrics (closest hit).
    fn other_leaf<T: TriangleKernel>(
        &self,
        prims: &PrimSet,
        kind: PrimKind,
        first: usize,
        count: usize,
        act: Mask<Self>,
        hit: &mut Self::Hit,
    );
    /// A leaf of spheres or clipped quadrics (any hit): the lanes of `left` blocked.
    fn other_leaf_occluded<T: TriangleKernel>(
        &self,
        prims: &PrimSet,
        kind: PrimKind,
        first: usize,
        count: usize,
        left: Mask<Self>,
        t_max: Self::L,
    ) -> Mask<Self>;
}

/// A packet's lane mask.
pub(crate) type Mask<P> = <<P as WidePacket>::L as simd::Lanes>::Mask;

impl WidePacket for RayPacket8 {
    type L = f32x8;
    type Hit = HitPacket8;
    const LEAVES_PER_LANE: bool = false;
    #[inline(always)]
    fn rays(&self) -> [[f32x8; 3]; 3] {
        [self.origin, self.dir, self.inv_dir].map(|v| [v.x, v.y, v.z])
    }
    #[inline(always)]
    fn hit_t(hit: &HitPacket8) -> f32x8 {
        hit.t
    }
    #[inline(always)]
    fn triangle<T: TriangleKernel>(
        &self,
        b: &TriBlock,
        j: usize,
        act: Mask8,
        t_max: f32x8,
    ) -> (Mask8, f32x8, f32x8, f32x8) {
        let v = b
            .tri
            .splat_lanes::<f32x8>(j)
            .map(|p| Vec3x8::new(p[0], p[1], p[2]));
        T::intersect_splat_x8(v, self, act, t_max)
    }
    #[inline(always)]
    fn moved_triangle<T: TriangleKernel>(
        &self,
        b: &TriBlock,
        m: &T::Moved,
        j: usize,
        act: Mask8,
        t_max: f32x8,
    ) -> (Mask8, f32x8, f32x8, f32x8) {
        T::intersect_moved_lanes(&b.tri, m, j, &simd::packet::RayLanes::of(self), act, t_max)
    }
    #[inline(always)]
    fn record(
        prims: &PrimSet,
        hit: &mut HitPacket8,
        m: Mask8,
        t: f32x8,
        uv: (f32x8, f32x8),
        code: i32,
    ) {
        prims.record_x8(hit, m, t, uv, code);
    }
    #[inline(always)]
    fn other_leaf<T: TriangleKernel>(
        &self,
        prims: &PrimSet,
        kind: PrimKind,
        first: usize,
        count: usize,
        act: Mask8,
        hit: &mut HitPacket8,
    ) {
        prims.intersect_x8::<T>(kind, first, count, self, act, hit);
    }
    #[inline(always)]
    fn other_leaf_occluded<T: TriangleKernel>(
        &self,
        prims: &PrimSet,
        kind: PrimKind,
        first: usize,
        count: usize,
        left: Mask8,
        t_max: f32x8,
    ) -> Mask8 {
        prims.occluded_x8::<T>(kind, first, count, self, left, t_max)
    }
}

impl Bvh {
    /// The tree part of [`Bvh::intersect_x8`] through the 8-wide tree, for the lanes
    /// `active` (finite, see [`finite_lanes`]) when they share the direction signs
    /// `octant` (see [`shared_octant`]): the frustum walk when they lie within `spread`
    /// (see [`Frustum::new`]); past it, the hybrid walk, each slot the frustum meets then
    /// tested per lane ([`entered_slots`]), so that a subtree is entered only where some
    /// lane's own slab test enters it: the lanes of a spread packet (a curved mirror's)
    /// share no tight frustum, but still most of their nodes. `Err(how far)` (nothing
    /// done) when they lie so far apart that their own walks serve them
    /// ([`Bvh::lane_walks`]).
    pub(crate) fn intersect_x8_wide<T: TriangleKernel>(
        &self,
        r: &RayPacket8,
        active: Mask8,
        octant: u32,
        spread: f32,
        hit: &mut HitPacket8,
        steps: &mut Steps,
    ) -> Result<(), f32> {
        let w = &self.wide;
        if w.nodes.is_empty() || active.none() {
            return Ok(());
        }
        let [o, d, inv] = r.rays();
        let (fr, past) = Frustum::new(o, d, inv, active, octant, spread, w.diagonal);
        // the walk specialised to the direction signs (fixed entry and exit planes)
        match past {
            None => with_const!(
                octant,
                [0, 1, 2, 3, 4, 5, 6, 7],
                self.frustum_walk_x8::<T, false>(r, active, &fr, hit, steps)
            ),
            Some(how_far) if self.lane_walks(how_far) => return Err(how_far),
            Some(_) => with_const!(
                octant,
                [0, 1, 2, 3, 4, 5, 6, 7],
                self.frustum_walk_x8::<T, true>(r, active, &fr, hit, steps)
            ),
        }
        Ok(())
    }

    /// [`Bvh::frustum_walk`] of eight lanes, compiled once per octant (and with
    /// `PER_LANE`, the hybrid walk of [`Bvh::intersect_x8_wide`]).
    fn frustum_walk_x8<T: TriangleKernel, const PER_LANE: bool, const OCT: u32>(
        &self,
        r: &RayPacket8,
        act: Mask8,
        fr: &Frustum,
        hit: &mut HitPacket8,
        steps: &mut Steps,
    ) {
        self.frustum_walk::<RayPacket8, T, OCT, PER_LANE>(r, act, fr, hit, steps);
    }

    /// The frustum walk of a packet (lanes `act`) of direction signs `OCT`, at any width;
    /// with `PER_LANE`, each slot the frustum meets also tested per lane
    /// ([`entered_slots`], the hybrid walk of [`Bvh::intersect_x8_wide`]).
    #[inline(always)]
    pub(crate) fn frustum_walk<
        P: WidePacket,
        T: TriangleKernel,
        const OCT: u32,
        const PER_LANE: bool,
    >(
        &self,
        r: &P,
        act: Mask<P>,
        fr: &Frustum,
        hit: &mut P::Hit,
        steps: &mut Steps,
    ) {
        let w = &self.wide;
        // the largest nearest hit of the lanes: nothing entered beyond it can be nearer
        let mut t_hi = max_in(P::hit_t(hit), act);
        let mut stack = Stack::<Pending, WIDE_STACK>::new();
        let mut cur = SlotRef::ROOT;
        'walk: loop {
            if cur.slot.is_interior() {
                let node = &w.nodes[cur.child as usize];
                steps.boxes += 1;
                let (mut bits, near) = fr.test::<OCT>(&node.bounds, t_hi);
                if PER_LANE {
                    bits = entered_slots(r, node, bits, act, P::hit_t(hit), true);
                }
                if bits != 0 {
                    let first = bits.trailing_zeros() as usize;
                    bits &= bits - 1;
                    if bits == 0 {
                        cur = node.get(first);
                        continue 'walk;
                    }
                    // two or more: nearest next, the others pushed farthest first, each
                    // prefetched as it is met (only here, where children are pushed)
                    let prefetch = Some((self, true));
                    cur = WideBvh::push_ordered(node, near, first, bits, prefetch, &mut stack);
                    continue 'walk;
                }
            } else {
                t_hi = self.leaf_intersect::<P, T, OCT>(cur, r, act, fr, t_hi, hit, steps);
            }
            // pop the next subtree some lane may still enter before its nearest hit
            loop {
                let Some(p) = stack.pop() else {
                    break 'walk;
                };
                if p.near <= t_hi * FAR_WIDEN {
                    cur = p.to;
                    break;
                }
            }
        }
    }

    /// [`Bvh::frustum_walk`] of `N` packets of direction signs `OCT` as one: each node
    /// tested once, against `fr` (a frustum of every packet's lanes, [`Frustum::union`]),
    /// each leaf reached with each packet's own frustum `sub[k]` and lanes `act[k]`,
    /// and a popped subtree skipped when its entry bound lies behind every lane's
    /// nearest hit. Per lane what `frustum_walk` gives it: the leaves are the same code
    /// with the packet's own largest hit, and a subtree is skipped only when the union's
    /// entry bound (at most any lane's own entry) exceeds the largest hit of every lane
    /// (at least each lane's current one), so no leaf that holds a lane's closest hit is
    /// skipped. (The leaves a packet's own walk visits may differ: the children are
    /// ordered by the union's bounds.)
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    pub(crate) fn frustum_walk_n<
        P: WidePacket,
        T: TriangleKernel,
        const OCT: u32,
        const N: usize,
    >(
        &self,
        r: [&P; N],
        act: [Mask<P>; N],
        fr: &Frustum,
        sub: [&Frustum; N],
        hit: &mut [P::Hit; N],
        steps: &mut Steps,
    ) {
        use simd::LaneMask as _;
        let w = &self.wide;
        // each packet's largest nearest hit, and theirs
        // (a loop, not `from_fn`: no closure touches a 16-lane value, `simd::packet`)
        let mut t_k = [f32::NEG_INFINITY; N];
        for (t, (h, &a)) in t_k.iter_mut().zip(hit.iter().zip(&act)) {
            *t = max_in(P::hit_t(h), a);
        }
        let largest = |t: &[f32; N]| t.iter().fold(f32::NEG_INFINITY, |a, &b| a.max(b));
        let mut t_hi = largest(&t_k);
        let mut stack = Stack::<Pending, WIDE_STACK>::new();
        let mut cur = SlotRef::ROOT;
        'walk: loop {
            if cur.slot.is_interior() {
                let node = &w.nodes[cur.child as usize];
                steps.boxes += 1;
                let (mut bits, near) = fr.test::<OCT>(&node.bounds, t_hi);
                if bits != 0 {
                    let first = bits.trailing_zeros() as usize;
                    bits &= bits - 1;
                    if bits == 0 {
                        cur = node.get(first);
                        continue 'walk;
                    }
                    let prefetch = Some((self, true));
                    cur = WideBvh::push_ordered(node, near, first, bits, prefetch, &mut stack);
                    continue 'walk;
                }
            } else {
                for k in 0..N {
                    if act[k].any() {
                        t_k[k] = self.leaf_intersect::<P, T, OCT>(
                            cur,
                            r[k],
                            act[k],
                            sub[k],
                            t_k[k],
                            &mut hit[k],
                            steps,
                        );
                    }
                }
                t_hi = largest(&t_k);
            }
            loop {
                let Some(p) = stack.pop() else {
                    break 'walk;
                };
                if p.near <= t_hi * FAR_WIDEN {
                    cur = p.to;
                    break;
                }
            }
        }
    }

    /// A leaf of the wide packet walk; the lanes' largest nearest hit after it (`t_hi`,
    /// the one before it, when no lane's hit changed).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn leaf_intersect<P: WidePacket, T: TriangleKernel, const OCT: u32>(
        &self,
        leaf: SlotRef,
        r: &P,
        act: Mask<P>,
        fr: &Frustum,
        t_hi: f32,
        hit: &mut P::Hit,
        steps: &mut Steps,
    ) -> f32 {
        use simd::LaneMask as _;
        let (kind, count) = (leaf.slot.kind(), leaf.slot.count() as usize);
        let first = leaf.child as usize;
        if kind != PrimKind::Triangle {
            steps.leaf(kind, count, act.count());
            r.other_leaf::<T>(&self.prims, kind, first, count, act, hit);
            return max_in(P::hit_t(hit), act);
        }
        // the lanes' largest nearest hit is read only by the next block's candidates and
        // by the caller: reduced there, not after every hit recorded (a 16-lane reduction
        // is a chain of eight steps)
        let (mut t_hi, mut dirty) = (t_hi, false);
        let w = &self.wide;
        let end = first + count.div_ceil(8);
        for (b, leaf) in self.prims.blocks[first..end]
            .iter()
            .zip(&w.leaf_boxes[first..end])
        {
            if dirty {
                (t_hi, dirty) = (max_in(P::hit_t(hit), act), false);
            }
            let mut bits = fr.block_candidates::<OCT>(b, leaf, t_hi);
            // one origin (a camera's packet) and a candidate: the block's vertices
            // translated to it once, eight triangles at a time
            let moved = fr
                .origin
                .filter(|_| bits != 0)
                .map(|o| T::move_block(&b.tri, o));
            while bits != 0 {
                let j = bits.trailing_zeros() as usize;
                bits &= bits - 1;
                steps.prims += 1;
                let (m, t, u, v) = match &moved {
                    Some(mv) => r.moved_triangle::<T>(b, mv, j, act, P::hit_t(hit)),
                    None => r.triangle::<T>(b, j, act, P::hit_t(hit)),
                };
                if m.none() {
                    continue;
                }
                // only lanes that pass the triangle's binary leaf box (module doc); the
                // rays fetched here, where a lane hit (most candidates hit none)
                let [o, _, inv] = r.rays();
                let m = lane_box(leaf, j)
                    .intersect_lanes(o, inv, m, P::hit_t(hit))
                    .0;
                if m.none() {
                    continue;
                }
                let code = prim_code(PrimKind::Triangle, b.first as usize + j);
                P::record(&self.prims, hit, m, t, (u, v), code);
                dirty = true;
            }
        }
        if dirty {
            t_hi = max_in(P::hit_t(hit), act);
        }
        t_hi
    }

    /// The tree part of [`Bvh::occluded_x8`] through the 8-wide tree: the lanes of
    /// `active` (finite, sharing the direction signs `octant`) blocked with 0 < t < t_max,
    /// by the frustum walk or past `spread` the hybrid walk, as in
    /// [`Bvh::intersect_x8_wide`]; `Err(how far)` (nothing done) when the lanes' own walks
    /// serve them.
    pub(crate) fn occluded_x8_wide<T: TriangleKernel>(
        &self,
        r: &RayPacket8,
        active: Mask8,
        octant: u32,
        spread: f32,
        t_max: f32x8,
        steps: &mut Steps,
    ) -> Result<Mask8, f32> {
        let w = &self.wide;
        if w.nodes.is_empty() || active.none() {
            return Ok(Mask8::NONE);
        }
        let [o, d, inv] = r.rays();
        let (fr, past) = Frustum::new(o, d, inv, active, octant, spread, w.diagonal);
        Ok(match past {
            None => with_const!(
                octant,
                [0, 1, 2, 3, 4, 5, 6, 7],
                self.frustum_occlusion_x8::<T, false>(r, active, &fr, t_max, steps)
            ),
            Some(how_far) if self.lane_walks(how_far) => return Err(how_far),
            Some(_) => with_const!(
                octant,
                [0, 1, 2, 3, 4, 5, 6, 7],
                self.frustum_occlusion_x8::<T, true>(r, active, &fr, t_max, steps)
            ),
        })
    }

    /// [`Bvh::frustum_occlusion`] of eight lanes, compiled once per octant (and with
    /// `PER_LANE`, the hybrid walk of [`Bvh::occluded_x8_wide`]).
    fn frustum_occlusion_x8<T: TriangleKernel, const PER_LANE: bool, const OCT: u32>(
        &self,
        r: &RayPacket8,
        act: Mask8,
        fr: &Frustum,
        t_max: f32x8,
        steps: &mut Steps,
    ) -> Mask8 {
        self.frustum_occlusion::<RayPacket8, T, OCT, PER_LANE>(r, act, fr, t_max, steps)
    }

    /// The any-hit frustum walk of a packet (lanes `act`) of direction signs `OCT`, at
    /// any width: the lanes blocked with 0 < t < t_max. With `PER_LANE`, each slot the
    /// frustum meets also tested per lane ([`entered_slots`]).
    #[inline(always)]
    pub(crate) fn frustum_occlusion<
        P: WidePacket,
        T: TriangleKernel,
        const OCT: u32,
        const PER_LANE: bool,
    >(
        &self,
        r: &P,
        act: Mask<P>,
        fr: &Frustum,
        t_max: P::L,
        steps: &mut Steps,
    ) -> Mask<P> {
        use simd::{LaneMask as _, Lanes as _};
        let w = &self.wide;
        let t_hi = max_in(t_max, act);
        let mut left = act;
        let mut stack = Stack::<SlotRef, WIDE_STACK>::new();
        stack.push(SlotRef::ROOT);
        while let Some(cur) = stack.pop() {
            if cur.slot.is_interior() {
                let node = &w.nodes[cur.child as usize];
                steps.boxes += 1;
                let (mut bits, near) = fr.test::<OCT>(&node.bounds, t_hi);
                if PER_LANE || P::LEAVES_PER_LANE {
                    bits = entered_slots(r, node, bits, left, t_max, PER_LANE);
                }
                WideBvh::push_any_hit(node, near, bits, false, Some((self, true)), &mut stack);
                continue;
            }
            let (kind, count) = (cur.slot.kind(), cur.slot.count() as usize);
            let first = cur.child as usize;
            if kind != PrimKind::Triangle {
                steps.leaf(kind, count, left.count());
                let blocked =
                    r.other_leaf_occluded::<T>(&self.prims, kind, first, count, left, t_max);
                left = left.and_not(blocked);
            } else {
                let w = &self.wide;
                let end = first + count.div_ceil(8);
                for (b, leaf) in self.prims.blocks[first..end]
                    .iter()
                    .zip(&w.leaf_boxes[first..end])
                {
                    let mut bits = fr.block_candidates::<OCT>(b, leaf, t_hi);
                    while bits != 0 && left.any() {
                        let j = bits.trailing_zeros() as usize;
                        bits &= bits - 1;
                        steps.prims += 1;
                        let (m, t, _, _) = r.triangle::<T>(b, j, left, t_max);
                        let m = m & t.lt(t_max);
                        if m.any() {
                            let [o, _, inv] = r.rays();
                            let blocked = lane_box(leaf, j).intersect_lanes(o, inv, m, t_max).0;
                            left = left.and_not(blocked);
                        }
                    }
                }
            }
            if left.none() {
                break;
            }
        }
        act.and_not(left)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::test_rng::Xorshift;
    use glam::Vec3;

    /// A coordinate for the tests: often a box face itself or a zero of either sign.
    fn pick(rng: &mut Xorshift, faces: [f32; 2]) -> f32 {
        match rng.next_u64() % 6 {
            0 => faces[0],
            1 => faces[1],
            2 => 0.0,
            3 => -0.0,
            _ => rng.f32() * 4.0 - 2.0,
        }
    }

    /// Boxes (slot 3 of a node; flat ones too) against packets whose lanes all have
    /// the direction signs `OCT` (a zero component of either sign among them, origins
    /// on the faces, rays aimed at corners), random active lanes and t_max:
    /// the slot's box read back (`lane_box`) gives each lane what the binary walk's
    /// test of that box gives it.
    fn slot_box_test_is_the_binary_test<const OCT: u32>(rng: &mut Xorshift) -> usize {
        let mut met = 0;
        for _ in 0..400 {
            let lo = Vec3::from_array(std::array::from_fn(|_| rng.f32() * 2.0 - 1.0));
            let size = Vec3::from_array(std::array::from_fn(|_| {
                if rng.next_u64().is_multiple_of(5) {
                    0.0
                } else {
                    rng.f32()
                }
            }));
            let hi = lo + size;
            let mut node = super::super::WideNode::empty();
            let s = 3;
            for a in 0..3 {
                let mut l = node.bounds[2 * a].to_array();
                let mut h = node.bounds[2 * a + 1].to_array();
                (l[s], h[s]) = (lo[a], hi[a]);
                (node.bounds[2 * a], node.bounds[2 * a + 1]) = (f32x8::new(l), f32x8::new(h));
            }
            let lane = |rng: &mut Xorshift| {
                let o = Vec3::from_array(std::array::from_fn(|a| pick(rng, [lo[a], hi[a]])));
                let d = Vec3::from_array(std::array::from_fn(|a| {
                    let m = if rng.next_u64().is_multiple_of(4) {
                        0.0
                    } else {
                        rng.f32() + 1e-3
                    };
                    if OCT >> a & 1 == 1 { -m } else { m }
                }));
                if rng.next_u64().is_multiple_of(2) {
                    // aimed at a corner: entry and exit meet there, up to rounding
                    let c = Vec3::from_array(std::array::from_fn(|a| {
                        if rng.next_u64().is_multiple_of(2) {
                            lo[a]
                        } else {
                            hi[a]
                        }
                    }));
                    return (c - d * (rng.f32() * 3.0), d);
                }
                (o, d)
            };
            let rays: [(Vec3, Vec3); 8] = std::array::from_fn(|_| lane(rng));
            let p = RayPacket8::new(
                Vec3x8::from_lanes(&rays.map(|r| r.0)),
                Vec3x8::from_lanes(&rays.map(|r| r.1)),
                Mask8::ALL,
            );
            assert_eq!(shared_octant(&p, Mask8::ALL), Some(OCT));
            let act = Mask8::from_bits((rng.next_u64() as u32 & 0xff) | 1);
            let t_max = f32x8::new(std::array::from_fn(|_| {
                if rng.next_u64().is_multiple_of(3) {
                    f32::INFINITY
                } else {
                    rng.f32() * 3.0
                }
            }));
            let [o, _, inv] = p.rays();
            let got = lane_box(&node.bounds, s)
                .intersect_lanes(o, inv, act, t_max)
                .0;
            let binary = BvhNode {
                lo: lo.to_array(),
                first: 0,
                hi: hi.to_array(),
                slot: crate::bvh::slot::Slot::INTERIOR,
            };
            let want = binary.intersect_lanes(o, inv, act, t_max).0;
            assert_eq!(got.bits(), want.bits(), "box {lo} {hi}, rays {rays:?}");
            met += got.bits().count_ones() as usize;
        }
        met
    }

    #[test]
    fn a_slots_lane_test_is_the_binary_walks_test_of_its_box() {
        let mut rng = Xorshift(0x5eed_1e55);
        let met = [
            slot_box_test_is_the_binary_test::<0>(&mut rng),
            slot_box_test_is_the_binary_test::<1>(&mut rng),
            slot_box_test_is_the_binary_test::<2>(&mut rng),
            slot_box_test_is_the_binary_test::<3>(&mut rng),
            slot_box_test_is_the_binary_test::<4>(&mut rng),
            slot_box_test_is_the_binary_test::<5>(&mut rng),
            slot_box_test_is_the_binary_test::<6>(&mut rng),
            slot_box_test_is_the_binary_test::<7>(&mut rng),
        ];
        // both answers occur in every octant
        assert!(met.iter().all(|&m| m > 100 && m < 400 * 8 - 100), "{met:?}");
    }
}
