//! Packet traversal: eight rays walk the tree together with an active mask.
//!
//! Ordered, depth first: at an interior node both children's boxes are tested against
//! the lanes that met the node; with both met, the child on the near side of the split
//! axis (by the packet's direction sign on that axis) is visited next and the other
//! pushed with its lane mask and the least entry distance of those lanes. A popped
//! subtree is skipped when that distance lies behind every active lane's nearest hit.
//!
//! Packets whose active lanes share their direction signs (nearly all coherent ones)
//! run a copy of the loop specialised to their octant, with the slab test's entry and
//! exit planes known in advance (`BvhNode::intersect_x8_oct`).

use wide::{f32x8, i32x8};

use super::node::BvhNode;
use super::slot::Stack;
use super::wide::walk_x8::{
    FRUSTUM_SPREAD, LANES_SPREAD, WIDE_PACKET_MIN_NODES, finite_lanes, shared_octant,
};
use super::{Bvh, STACK_SIZE, Steps};
use crate::geometry::triangle::TriangleKernel;
use crate::geometry::{Hit1, PrimKind};
use crate::math::packet::{FAR_WIDEN, HitPacket8, Mask8, Ray1, RayPacket8};

/// A packet slab test: lanes of `active` meeting the box below `t_max`, entry distances.
trait BoxTest {
    fn test(node: &BvhNode, r: &RayPacket8, active: Mask8, t_max: f32x8) -> (Mask8, f32x8);
}

/// Lanes of any direction signs.
struct AnyOctant;
impl BoxTest for AnyOctant {
    #[inline(always)]
    fn test(node: &BvhNode, r: &RayPacket8, active: Mask8, t_max: f32x8) -> (Mask8, f32x8) {
        node.intersect_x8_near(r, active, t_max)
    }
}

/// Every active lane with the direction signs NX, NY, NZ (true: negative).
struct Octant<const NX: bool, const NY: bool, const NZ: bool>;
impl<const NX: bool, const NY: bool, const NZ: bool> BoxTest for Octant<NX, NY, NZ> {
    #[inline(always)]
    fn test(node: &BvhNode, r: &RayPacket8, active: Mask8, t_max: f32x8) -> (Mask8, f32x8) {
        node.intersect_x8_oct::<NX, NY, NZ>(r, active, t_max)
    }
}

/// A subtree left for later: node, mask of the lanes that met its box, their least
/// entry distance.
#[derive(Clone, Copy)]
struct Subtree {
    node: u32,
    lanes: u32,
    near: f32,
}

/// Starts loading what `node` leads to: its children (one cache line, see `build`)
/// or, for a leaf, the block of its first triangle (by `PrimSet::block_at`, which
/// names that block or one just before it). No branch: the address is picked, and a
/// prefetch of an address outside the arrays (a leaf of another kind) is harmless.
///
/// Node loads are the packet walk's critical path: the tree of torus100k (3.5 MB)
/// lives in L3 at best, and each level waits for the last.
#[inline(always)]
fn prefetch(bvh: &Bvh, node: &BvhNode) {
    #[cfg(target_arch = "x86_64")]
    {
        let i = node.first as usize;
        let p: *const i8 = if node.is_leaf() {
            let at = bvh.prims.block_at.get(i >> 3).copied().unwrap_or(0);
            bvh.prims.blocks.as_ptr().wrapping_add(at as usize).cast()
        } else {
            bvh.nodes.as_ptr().wrapping_add(i).cast()
        };
        // SAFETY: a prefetch is a hint that never faults, whatever the address.
        unsafe { std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>(p) };
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (bvh, node);
}

/// Largest `t` over the lanes of `m`, widened as the slab test widens its far bound:
/// a subtree entered beyond it by every lane cannot hold a hit (nor a tie).
#[inline(always)]
fn cull_limit(t: f32x8, m: Mask8) -> f32 {
    fold_lanes(t, m, f32::NEG_INFINITY, f32::max) * FAR_WIDEN
}

/// Least entry distance over the lanes of `m`.
#[inline(always)]
fn least_near(near: f32x8, m: Mask8) -> f32 {
    fold_lanes(near, m, f32::INFINITY, f32::min)
}

/// `op` over the lanes of `m` (`empty` for the others), as a tree of halves.
#[inline(always)]
fn fold_lanes(v: f32x8, m: Mask8, empty: f32, op: fn(f32, f32) -> f32) -> f32 {
    let t = m.select(v, f32x8::splat(empty)).to_array();
    let m4 = [
        op(t[0], t[4]),
        op(t[1], t[5]),
        op(t[2], t[6]),
        op(t[3], t[7]),
    ];
    op(op(m4[0], m4[2]), op(m4[1], m4[3]))
}

/// The active lanes of `H` packets as (packet, lane) in order, and their count (at most
/// `N` = 8·H).
#[inline(always)]
fn lanes_of<const H: usize, const N: usize>(active: [Mask8; H]) -> ([(usize, usize); N], usize) {
    let mut at = [(0, 0); N];
    let mut n = 0;
    for (k, m) in active.iter().enumerate() {
        let mut bits = m.bits();
        while bits != 0 {
            at[n] = (k, bits.trailing_zeros() as usize);
            bits &= bits - 1;
            n += 1;
        }
    }
    (at, n)
}

/// Trees of at least this many wide nodes trace the lanes of an incoherent packet
/// (mixed direction signs) one by one through the wide single-ray walk instead of
/// walking the binary tree as a packet, which would fetch the nodes of eight unrelated
/// rays. (Only trees that the frustum walk serves get here: it must not be below
/// [`WIDE_PACKET_MIN_NODES`]. In these trees no packet walks the binary tree: those
/// just past the frustum's limit take the hybrid walk of [`Bvh::intersect_x8_wide`].)
pub const LANES_MIN_NODES: usize = WIDE_PACKET_MIN_NODES;
const _: () = assert!(LANES_MIN_NODES >= WIDE_PACKET_MIN_NODES);

impl Bvh {
    /// Nearest hit of each active lane, below the lane's current `hit.t`, recorded in
    /// `hit`. Coherent packets (lanes sharing their direction signs, within
    /// [`FRUSTUM_SPREAD`]) walk the 8-wide tree as one frustum (`wide/walk_x8.rs`); in
    /// trees of at least [`LANES_MIN_NODES`] wide nodes, packets of mixed signs or
    /// spread past [`LANES_SPREAD`] take the 8-wide single-ray walk per lane
    /// ([`Bvh::intersect_x8_lanes`]), and those between the two limits the hybrid walk
    /// of the 8-wide tree ([`Bvh::intersect_x8_wide`]); in smaller trees packets
    /// walk the binary tree ([`Bvh::intersect_x8_binary`]).
    pub fn intersect_x8<T: TriangleKernel>(
        &self,
        r: &RayPacket8,
        active: Mask8,
        hit: &mut HitPacket8,
        steps: &mut Steps,
    ) {
        self.intersect_x8_spread::<T>(r, active, self.frustum_spread(), hit, steps);
    }

    /// Whether closest-hit packets are bounded by the floor before the walk
    /// ([`PrimSet::bound_by_floor_x8`](crate::geometry::PrimSet::bound_by_floor_x8)): a
    /// scene with a floor and a tree to skip.
    #[inline]
    pub(crate) fn bounds_by_floor(&self) -> bool {
        self.prims.floor.is_some() && self.root.is_some()
    }

    /// Whether lanes `how_far` apart (as [`Frustum::new`](super::wide::walk_x8) measures
    /// them; ∞ for mixed direction signs) take their own single-ray walks of the wide
    /// tree (closest hit: stepped in turn): past [`LANES_SPREAD`], in a tree of at least
    /// [`LANES_MIN_NODES`] wide nodes.
    #[inline]
    pub(crate) fn lane_walks(&self, how_far: f32) -> bool {
        how_far > LANES_SPREAD && self.wide.nodes.len() >= LANES_MIN_NODES
    }

    /// The coherence limit of the wide packet walk in this tree: [`FRUSTUM_SPREAD`], or
    /// −1 (never) for a tree of fewer than [`WIDE_PACKET_MIN_NODES`] wide nodes, where
    /// building the frustum costs more than the few binary steps it saves.
    #[inline]
    pub(crate) fn frustum_spread(&self) -> f32 {
        if self.wide.nodes.len() >= WIDE_PACKET_MIN_NODES {
            FRUSTUM_SPREAD
        } else {
            -1.0
        }
    }

    /// [`Bvh::intersect_x8`] with the coherence limit `spread` instead of
    /// [`FRUSTUM_SPREAD`], whatever the tree's size (tests: ∞ sends every packet whose
    /// lanes share their signs through the wide walk; a negative one none).
    pub fn intersect_x8_spread<T: TriangleKernel>(
        &self,
        r: &RayPacket8,
        active: Mask8,
        spread: f32,
        hit: &mut HitPacket8,
        steps: &mut Steps,
    ) {
        if active.none() {
            return;
        }
        if self.bounds_by_floor() {
            self.prims.bound_by_floor_x8(r, active, hit);
        }
        if spread >= 0.0 && !self.wide.nodes.is_empty() {
            let act = self.enter_x8(r, active & finite_lanes(r), hit.t);
            if act.none() {
                self.intersect_beside_x8::<T>(r, active, hit, steps);
                return;
            }
            // the frustum or the hybrid walk; else how far apart the lanes lie
            let how_far = match shared_octant(r, act) {
                Some(oct) => match self.intersect_x8_wide::<T>(r, act, oct, spread, hit, steps) {
                    Ok(()) => {
                        self.intersect_beside_x8::<T>(r, active, hit, steps);
                        return;
                    }
                    Err(how_far) => how_far,
                },
                None => f32::INFINITY,
            };
            if self.lane_walks(how_far) {
                self.intersect_x8_lanes::<T>(r, active, hit, steps);
                return;
            }
        }
        self.intersect_x8_binary::<T>(r, active, hit, steps);
    }

    /// The lanes of `active` (finite) that enter the root's box before `t_max`: only
    /// they can meet anything in the tree (the root's test is the binary walk's first,
    /// and every walk reports what the binary walk reports), so a frustum walk takes
    /// those alone (a tighter frustum) and none when there are none (shadow and mirror
    /// rays from a floor around the mesh). Called with a wide tree only (which has a
    /// binary root); not counted in `Steps::boxes` (wide node tests).
    #[inline(always)]
    pub(crate) fn enter_x8(&self, r: &RayPacket8, active: Mask8, t_max: f32x8) -> Mask8 {
        let root = self.root.as_ref().expect("a tree with a root");
        root.intersect_x8(r, active, t_max)
    }

    /// [`Bvh::intersect_x8`] per lane: each lane of `active` gets what
    /// [`Bvh::intersect_1`] gives it, the lanes' walks of the wide tree stepped in turn
    /// (incoherent packets here, and the renderer's packets of too few lanes).
    pub fn intersect_x8_lanes<T: TriangleKernel>(
        &self,
        r: &RayPacket8,
        active: Mask8,
        hit: &mut HitPacket8,
        steps: &mut Steps,
    ) {
        let mut h = [*hit];
        self.intersect_lanes_of::<T, 1, 8>([r], [active], &mut h, steps);
        *hit = h[0];
    }

    /// Each active lane of `H` packets (one, or the halves of a 16-lane packet; `N` =
    /// 8·H) gets what [`Bvh::intersect_1`] gives it: the lanes' walks of the wide tree
    /// stepped in turn, all `N` at once, then each lane's unbounded quadrics and floor
    /// (`intersect_1`'s order).
    #[inline(always)]
    pub(crate) fn intersect_lanes_of<T: TriangleKernel, const H: usize, const N: usize>(
        &self,
        r: [&RayPacket8; H],
        active: [Mask8; H],
        hit: &mut [HitPacket8; H],
        steps: &mut Steps,
    ) {
        let (at, n) = lanes_of::<H, N>(active);
        if n == 0 {
            return;
        }
        let mut t = (*hit).map(|h| h.t.to_array());
        let mut prim = (*hit).map(|h| h.prim.to_array());
        let mut u = (*hit).map(|h| h.u.to_array());
        let mut v = (*hit).map(|h| h.v.to_array());
        let rays: [Ray1; N] = std::array::from_fn(|i| {
            let (k, l) = at[i.min(n - 1)];
            r[k].ray(l)
        });
        let mut hits: [Hit1; N] = std::array::from_fn(|i| {
            let (k, l) = at[i.min(n - 1)];
            Hit1 {
                t: t[k][l],
                prim: prim[k][l],
                u: u[k][l],
                v: v[k][l],
            }
        });
        self.intersect_wide_interleaved::<T>(&rays[..n], &mut hits[..n], steps);
        for ((&(k, l), ray), h) in at[..n].iter().zip(&rays).zip(&mut hits) {
            self.intersect_beside_1::<T>(ray, h, steps);
            (t[k][l], prim[k][l], u[k][l], v[k][l]) = (h.t, h.prim, h.u, h.v);
        }
        for (k, h) in hit.iter_mut().enumerate() {
            *h = HitPacket8 {
                t: f32x8::new(t[k]),
                prim: i32x8::new(prim[k]),
                u: f32x8::new(u[k]),
                v: f32x8::new(v[k]),
            };
        }
    }

    /// [`Bvh::intersect_x8`] through the binary tree only: every packet in trees too
    /// small for the 8-wide walks, the benches' `mode=8b`, and the tests' oracle of the
    /// other packet walks.
    pub fn intersect_x8_binary<T: TriangleKernel>(
        &self,
        r: &RayPacket8,
        active: Mask8,
        hit: &mut HitPacket8,
        steps: &mut Steps,
    ) {
        if active.none() {
            return;
        }
        self.binary_walked();
        if !self.nodes.is_empty() {
            // the octant shared by every active lane, if any (1/d carries the sign of
            // the direction, −0 included)
            let oct = shared_octant(r, active);
            let s = match oct {
                Some(0) => self.walk_x8::<T, Octant<false, false, false>>(r, active, hit, 0),
                Some(1) => self.walk_x8::<T, Octant<true, false, false>>(r, active, hit, 1),
                Some(2) => self.walk_x8::<T, Octant<false, true, false>>(r, active, hit, 2),
                Some(3) => self.walk_x8::<T, Octant<true, true, false>>(r, active, hit, 3),
                Some(4) => self.walk_x8::<T, Octant<false, false, true>>(r, active, hit, 4),
                Some(5) => self.walk_x8::<T, Octant<true, false, true>>(r, active, hit, 5),
                Some(6) => self.walk_x8::<T, Octant<false, true, true>>(r, active, hit, 6),
                Some(_) => self.walk_x8::<T, Octant<true, true, true>>(r, active, hit, 7),
                None => self.walk_x8::<T, AnyOctant>(r, active, hit, r.octant),
            };
            steps.boxes += s.boxes;
            steps.prims += s.prims;
            steps.quadrics += s.quadrics;
        }
        self.intersect_beside_x8::<T>(r, active, hit, steps);
    }

    /// The tree part of [`Bvh::intersect_x8`]; `octant`: the direction sign bits that
    /// order the children (bit k: negative along axis k). Counts in a local `Steps`.
    #[inline(always)]
    fn walk_x8<T: TriangleKernel, B: BoxTest>(
        &self,
        r: &RayPacket8,
        active: Mask8,
        hit: &mut HitPacket8,
        octant: u32,
    ) -> Steps {
        let nodes = &self.nodes[..];
        let mut steps = Steps {
            boxes: 1,
            ..Steps::default()
        };
        let (mut m, _) = B::test(&nodes[0], r, active, hit.t);
        if m.none() {
            return steps;
        }
        let mut limit = cull_limit(hit.t, active);
        let mut stack = Stack::<Subtree, STACK_SIZE>::new();
        let mut ni = 0usize;
        loop {
            let node = &nodes[ni];
            if node.is_leaf() {
                let count = node.count() as usize;
                steps.leaf(node.kind(), count, m.count());
                self.prims
                    .intersect_x8::<T>(node.kind(), node.first as usize, count, r, m, hit);
                limit = cull_limit(hit.t, active);
            } else {
                let l = node.first as usize;
                steps.boxes += 2;
                let (c0, c1) = (&nodes[l], &nodes[l + 1]);
                // the grandchildren, whichever way the walk goes next
                prefetch(self, c0);
                prefetch(self, c1);
                let (m0, n0) = B::test(c0, r, m, hit.t);
                let (m1, n1) = B::test(c1, r, m, hit.t);
                match (m0.any(), m1.any()) {
                    (true, true) => {
                        // near child next, the far one pushed
                        let (near, mn, far, mf, nf) = if octant >> node.axis() & 1 == 0 {
                            (l, m0, l + 1, m1, n1)
                        } else {
                            (l + 1, m1, l, m0, n0)
                        };
                        stack.push(Subtree {
                            node: far as u32,
                            lanes: mf.bits(),
                            near: least_near(nf, mf),
                        });
                        ni = near;
                        m = mn;
                        continue;
                    }
                    (true, false) => {
                        ni = l;
                        m = m0;
                        continue;
                    }
                    (false, true) => {
                        ni = l + 1;
                        m = m1;
                        continue;
                    }
                    (false, false) => {}
                }
            }
            // pop the next subtree some lane may still enter before its nearest hit
            loop {
                let Some(p) = stack.pop() else {
                    return steps;
                };
                if p.near <= limit {
                    ni = p.node as usize;
                    m = Mask8::from_bits(p.lanes);
                    break;
                }
            }
        }
    }

    /// The unbounded quadrics, then the floor.
    #[inline]
    pub(crate) fn intersect_beside_x8<T: TriangleKernel>(
        &self,
        r: &RayPacket8,
        active: Mask8,
        hit: &mut HitPacket8,
        steps: &mut Steps,
    ) {
        let nq = self.prims.free_quadrics.len();
        if nq > 0 {
            steps.prims += nq as u64;
            steps.quadrics += (nq * active.count() as usize) as u64;
            self.prims
                .intersect_x8::<T>(PrimKind::FreeQuadric, 0, nq, r, active, hit);
        }
        if self.prims.floor.is_some() {
            steps.prims += 1;
            self.prims.intersect_floor_x8(r, active, hit);
        }
    }

    /// The lanes of `active` whose ray is blocked by anything with 0 < t < t_max
    /// (any hit: a lane leaves the query at its first blocker). Coherent packets walk
    /// the 8-wide tree, as in [`Bvh::intersect_x8`].
    pub fn occluded_x8<T: TriangleKernel>(
        &self,
        r: &RayPacket8,
        active: Mask8,
        t_max: f32x8,
        steps: &mut Steps,
    ) -> Mask8 {
        self.occluded_x8_spread::<T>(r, active, self.frustum_spread(), t_max, steps)
    }

    /// [`Bvh::occluded_x8`] with the coherence limit `spread` (as
    /// [`Bvh::intersect_x8_spread`]).
    pub fn occluded_x8_spread<T: TriangleKernel>(
        &self,
        r: &RayPacket8,
        active: Mask8,
        spread: f32,
        t_max: f32x8,
        steps: &mut Steps,
    ) -> Mask8 {
        if spread < 0.0 || self.wide.nodes.is_empty() {
            return self.occluded_x8_with::<T>(r, active, t_max, None, steps);
        }
        match shared_octant(r, active & finite_lanes(r)) {
            Some(octant) => {
                self.occluded_x8_with::<T>(r, active, t_max, Some((octant, spread)), steps)
            }
            None if self.lane_walks(f32::INFINITY) => {
                self.occluded_x8_lanes::<T>(r, active, t_max, steps)
            }
            None => self.occluded_x8_with::<T>(r, active, t_max, None, steps),
        }
    }

    /// [`Bvh::occluded_x8`] per lane: each lane of `active` gets what
    /// [`Bvh::occluded_1`] gives it, the lanes' walks one after another (incoherent
    /// packets here, and the renderer's packets of too few lanes).
    pub fn occluded_x8_lanes<T: TriangleKernel>(
        &self,
        r: &RayPacket8,
        active: Mask8,
        t_max: f32x8,
        steps: &mut Steps,
    ) -> Mask8 {
        self.occluded_lanes_of::<T, 1>([r], [active], [t_max], true, steps)[0]
    }

    /// The active lanes of `H` packets (one, or the halves of a 16-lane packet)
    /// blocked, each what [`Bvh::occluded_1`] answers for it, one lane after another:
    /// with `beside` `occluded_1` itself (the floor and unbounded quadrics, then the
    /// tree), without only its tree part (the caller has tested the rest). (Unlike
    /// the closest-hit walks': stepped in turn, they ran 0.77× as fast on torus100k and
    /// 1.03× on torus1m; an any-hit walk visits its farthest child first and most end
    /// early, benches/README.md.)
    #[inline(always)]
    pub(crate) fn occluded_lanes_of<T: TriangleKernel, const H: usize>(
        &self,
        r: [&RayPacket8; H],
        active: [Mask8; H],
        t_max: [f32x8; H],
        beside: bool,
        steps: &mut Steps,
    ) -> [Mask8; H] {
        let tm = t_max.map(|t| t.to_array());
        let mut blocked = [0u32; H];
        for (k, m) in active.iter().enumerate() {
            let mut bits = m.bits();
            while bits != 0 {
                let l = bits.trailing_zeros() as usize;
                bits &= bits - 1;
                let (ray, t) = (r[k].ray(l), tm[k][l]);
                let hit = if beside {
                    self.occluded_1::<T>(&ray, t, steps)
                } else {
                    self.occluded_wide_1::<T>(&ray, t, steps)
                };
                blocked[k] |= (hit as u32) << l;
            }
        }
        blocked.map(Mask8::from_bits)
    }

    /// [`Bvh::occluded_x8`] through the binary tree only (the benches' `mode=8b`).
    pub fn occluded_x8_binary<T: TriangleKernel>(
        &self,
        r: &RayPacket8,
        active: Mask8,
        t_max: f32x8,
        steps: &mut Steps,
    ) -> Mask8 {
        self.occluded_x8_with::<T>(r, active, t_max, None, steps)
    }

    /// The lanes of `active` not blocked by the floor or the unbounded quadrics (with
    /// 0 < t < t_max): tested first, one cheap test that often settles a shadow ray.
    #[inline]
    pub(crate) fn occluded_beside_x8<T: TriangleKernel>(
        &self,
        r: &RayPacket8,
        active: Mask8,
        t_max: f32x8,
        steps: &mut Steps,
    ) -> Mask8 {
        let mut left = active;
        if self.prims.floor.is_some() {
            steps.prims += 1;
            left = left.and_not(
                self.prims
                    .occluded_x8::<T>(PrimKind::Floor, 0, 1, r, left, t_max),
            );
        }
        let nq = self.prims.free_quadrics.len();
        if nq > 0 && left.any() {
            steps.prims += nq as u64;
            steps.quadrics += (nq * left.count() as usize) as u64;
            left = left.and_not(self.prims.occluded_x8::<T>(
                PrimKind::FreeQuadric,
                0,
                nq,
                r,
                left,
                t_max,
            ));
        }
        left
    }

    /// The any-hit query: the list beside the tree, then, when `wide_octant` (the
    /// lanes' direction signs, the spread limit) is given, the wide tree as one frustum
    /// if the packet is coherent enough, else the lanes' own wide walks when they lie
    /// far apart ([`Bvh::lane_walks`]), else the hybrid walk
    /// ([`Bvh::occluded_x8_wide`]); without it, the binary tree as a packet.
    #[inline(always)]
    fn occluded_x8_with<T: TriangleKernel>(
        &self,
        r: &RayPacket8,
        active: Mask8,
        t_max: f32x8,
        wide_octant: Option<(u32, f32)>,
        steps: &mut Steps,
    ) -> Mask8 {
        let mut left = self.occluded_beside_x8::<T>(r, active, t_max, steps);
        // `None`: the wide tree not walked as a packet (the binary walk); `Err`: the
        // lanes too far apart for a packet (their own walks)
        let packet = match wide_octant {
            Some((octant, spread)) if left.any() => {
                let enter = self.enter_x8(r, left & finite_lanes(r), t_max);
                Some(if enter.none() {
                    Ok(Mask8::NONE)
                } else {
                    self.occluded_x8_wide::<T>(r, enter, octant, spread, t_max, steps)
                })
            }
            _ => None,
        };
        if let Some(Ok(blocked)) = packet {
            left = left.and_not(blocked);
        } else if let Some(Err(_)) = packet {
            let [blocked] = self.occluded_lanes_of::<T, 1>([r], [left], [t_max], false, steps);
            left = left.and_not(blocked);
        } else if left.any() && self.root.is_some() {
            self.binary_walked();
            let mut stack = Stack::<u32, STACK_SIZE>::new();
            stack.push(0);
            while let Some(ni) = stack.pop() {
                let node = &self.nodes[ni as usize];
                steps.boxes += 1;
                let m = node.intersect_x8(r, left, t_max);
                if m.none() {
                    continue;
                }
                if node.is_leaf() {
                    let count = node.count() as usize;
                    steps.leaf(node.kind(), count, m.count());
                    let blocked = self.prims.occluded_x8::<T>(
                        node.kind(),
                        node.first as usize,
                        count,
                        r,
                        m,
                        t_max,
                    );
                    left = left.and_not(blocked);
                    if left.none() {
                        break;
                    }
                } else {
                    let far_first = r.octant >> node.axis() & 1;
                    stack.push(node.first + (1 - far_first));
                    stack.push(node.first + far_first);
                }
            }
        }
        active.and_not(left)
    }
}
