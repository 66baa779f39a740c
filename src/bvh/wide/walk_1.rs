//! One ray through the 8-wide tree: the eight child boxes of a node in one slab test,
//! the hit children visited nearest first (closest hit), a leaf's triangles eight at a
//! time with the 1×8 kernel of the frame's triangle test (equal lane by lane to its
//! single-ray kernel). Spheres and clipped quadrics in leaves go through
//! `PrimSet::intersect_1`/`occluded_1` one by one.

use wide::f32x8;

use super::{Pending, TriBlock, WIDE_STACK, WideBvh, WideNode};
use crate::bvh::slot::{SlotRef, Stack};
use crate::bvh::{Bvh, Steps};
use crate::geometry::triangle::TriangleKernel;
use crate::geometry::{Hit1, PrimKind, prim_code};
use crate::math::packet::{Cmp8, FAR_WIDEN, Mask8, Ray1};

/// One ray prepared for the wide walk: the ray, its slab-test and its triangle-test forms.
struct WideRay<'a, T: TriangleKernel> {
    r: &'a Ray1,
    boxes: BoxRay,
    tris: T::Ray1x8,
}

impl<T: TriangleKernel> WideRay<'_, T> {
    #[inline]
    fn new(r: &Ray1) -> WideRay<'_, T> {
        WideRay {
            r,
            boxes: BoxRay::new(r),
            tris: T::prepare(r),
        }
    }
}

/// Calls `f` with eight empty stacks, each its own local, left uninitialised and never
/// moved (an array of them was written out with zeros: kilobytes per packet). Sixteen
/// stacks of the closest-hit walk take about 130 KB of the thread's stack (threads
/// here have the default 2 MiB).
#[inline(always)]
fn with_stacks<E: Copy, R>(f: impl FnOnce([&mut Stack<E, WIDE_STACK>; 8]) -> R) -> R {
    let (mut s0, mut s1, mut s2, mut s3) = (Stack::new(), Stack::new(), Stack::new(), Stack::new());
    let (mut s4, mut s5, mut s6, mut s7) = (Stack::new(), Stack::new(), Stack::new(), Stack::new());
    f([
        &mut s0, &mut s1, &mut s2, &mut s3, &mut s4, &mut s5, &mut s6, &mut s7,
    ])
}

/// [`with_stacks`] for sixteen walks.
#[inline(always)]
fn with_stacks16<E: Copy, R>(f: impl FnOnce([&mut Stack<E, WIDE_STACK>; 16]) -> R) -> R {
    with_stacks(|[a0, a1, a2, a3, a4, a5, a6, a7]| {
        with_stacks(|[b0, b1, b2, b3, b4, b5, b6, b7]| {
            f([
                a0, a1, a2, a3, a4, a5, a6, a7, b0, b1, b2, b3, b4, b5, b6, b7,
            ])
        })
    })
}

/// Steps the walks `live` (bit k: walk k) in turn, one step each per round, until
/// `step(k)` has returned false (walk k ended) for every one.
#[inline(always)]
fn in_turn(mut live: u32, mut step: impl FnMut(usize) -> bool) {
    while live != 0 {
        let mut bits = live;
        while bits != 0 {
            let k = bits.trailing_zeros() as usize;
            bits &= bits - 1;
            if !step(k) {
                live &= !(1 << k);
            }
        }
    }
}

/// [`Bvh::step_1`]'s and [`Bvh::occluded_step_1`]'s `KZ` for walks whose ray's
/// permutation is read at run time (walks of different rays stepped in turn): the
/// triangle kernel loads each vertex vector at its axis's offset
/// ([`Triangle8::intersect_1x8`](crate::geometry::triangle::Triangle8::intersect_1x8)),
/// where a jump at each leaf to a copy of the leaf per permutation mispredicted about
/// once a ray (figures in `benches/README.md`).
const ANY_KZ: usize = 3;

/// One ray's walk in progress (what `walk_1` keeps in locals), for walks stepped in
/// turn.
struct Walk<'a, T: TriangleKernel> {
    wr: WideRay<'a, T>,
    cur: SlotRef,
}

/// One ray prepared for the slab tests of a [`WideNode`].
struct BoxRay {
    origin: [f32x8; 3],
    inv_dir: [f32x8; 3],
    /// Index in `WideNode::bounds` of the near and far plane per axis (by the sign of
    /// 1/d: lo when positive).
    near: [usize; 3],
    far: [usize; 3],
}

impl BoxRay {
    #[inline]
    fn new(r: &Ray1) -> BoxRay {
        let neg = [0, 1, 2].map(|a| (r.inv_dir[a] < 0.0) as usize);
        BoxRay {
            origin: [0, 1, 2].map(|a| f32x8::splat(r.origin[a])),
            inv_dir: [0, 1, 2].map(|a| f32x8::splat(r.inv_dir[a])),
            near: [0, 1, 2].map(|a| 2 * a + neg[a]),
            far: [0, 1, 2].map(|a| 2 * a + 1 - neg[a]),
        }
    }

    /// The lanes of `m` (triangles of block `b` the ray hits in front of `t_max`) whose
    /// binary leaf box the ray meets by [`BoxRay::test`], as the binary walk requires
    /// to reach them. A block of one binary leaf: all of them (every lane's box is the
    /// slot's, which the ray has passed with a t_max >= this one). Else first the
    /// triangles' own boxes, the min and max of the corners just read for the hit,
    /// clamped to ±[`BOUNDS_LIMIT`](crate::geometry::BOUNDS_LIMIT) as the build clamps
    /// every primitive's box: a leaf box contains its triangles' clamped boxes (their
    /// union, rounded outward, `Aabb::outward`), and the slab test is monotone under
    /// containment, so a lane that passes its triangle's box passes its leaf box. Only a
    /// lane that misses its triangle's box (a hit at the box's edge, within rounding)
    /// reads the leaf boxes (`leaf`, `WideBvh::leaf_boxes` of the block), three lines
    /// that the walk would otherwise fetch at nearly every hit.
    #[inline(always)]
    fn leaf_lanes(&self, b: &TriBlock, leaf: &[f32x8; 6], m: Mask8, t_max: f32) -> Mask8 {
        let v = &b.tri.v;
        // clamped as `PrimSet::bounds` clamps the boxes the leaf boxes are the union of
        // (clamping is monotone, so it keeps the containment)
        let lim = f32x8::splat(crate::geometry::BOUNDS_LIMIT);
        let clamp = |x: f32x8| x.fast_max(-lim).fast_min(lim);
        let own = [0, 1, 2].map(|a| {
            let (p, q, r) = (v[0][a], v[1][a], v[2][a]);
            [
                clamp(p.fast_min(q).fast_min(r)),
                clamp(p.fast_max(q).fast_max(r)),
            ]
        });
        let own = [
            own[0][0], own[0][1], own[1][0], own[1][1], own[2][0], own[2][1],
        ];
        // (a block of one leaf passes whole: its flag picked, not branched on, after a
        // test it does not need)
        let whole = Mask8::from_bits(u32::from(b.one_leaf).wrapping_neg() & 0xff);
        let pass = m & (self.test(&own, t_max).0 | whole);
        if pass.bits() == m.bits() {
            return m;
        }
        pass | (m & self.test(leaf, t_max).0)
    }

    /// The slab test of `BvhNode::intersect_1` on the eight slots: bit i of the mask is
    /// set when slot i is met with 0 <= t and t <= t_max (far bound widened by
    /// 1 + 2γ(3)); the entry distances. With finite origins and 1/d (the slab rule)
    /// nothing here is NaN, so `fast_min`/`fast_max` are exact min/max, and picking the
    /// near plane by the sign of 1/d gives the same value as the binary test's min.
    #[inline]
    fn test(&self, bounds: &[f32x8; 6], t_max: f32) -> (Mask8, f32x8) {
        let t = |plane: usize, a: usize| (bounds[plane] - self.origin[a]) * self.inv_dir[a];
        let near = t(self.near[0], 0)
            .fast_max(t(self.near[1], 1))
            .fast_max(t(self.near[2], 2).fast_max(f32x8::ZERO));
        let far = t(self.far[0], 0)
            .fast_min(t(self.far[1], 1))
            .fast_min(t(self.far[2], 2).fast_min(f32x8::splat(t_max)))
            * f32x8::splat(FAR_WIDEN);
        (near.le(far), near)
    }
}

/// The rays that enter the tree (bit k: `rays[k]`, see [`finite`]).
#[inline]
fn live_walks(rays: &[Ray1]) -> u32 {
    (rays.iter().enumerate())
        .filter(|(_, r)| finite(r))
        .fold(0, |live, (k, _)| live | 1 << k)
}

/// Whether the ray enters the tree: a NaN or infinite origin or direction never hits
/// a bounded primitive (their kernels give NaN), and would make the slab test NaN,
/// which `fast_min`/`fast_max` may turn into a hit of every slot, empty ones included
/// (a direction infinite on every axis has a finite 1/d, of zeros).
#[inline]
fn finite(r: &Ray1) -> bool {
    r.origin.is_finite() && r.dir.is_finite() && r.inv_dir.is_finite()
}

impl Bvh {
    /// Nearest hit below `hit.t`, recorded in `hit` (the 8-wide tree, then the
    /// unbounded quadrics and the floor).
    pub fn intersect_1<T: TriangleKernel>(&self, r: &Ray1, hit: &mut Hit1, steps: &mut Steps) {
        self.intersect_wide_1::<T>(r, hit, steps);
        self.intersect_beside_1::<T>(r, hit, steps);
    }

    /// The tree part of [`Bvh::intersect_1`].
    #[inline]
    pub(crate) fn intersect_wide_1<T: TriangleKernel>(
        &self,
        r: &Ray1,
        hit: &mut Hit1,
        steps: &mut Steps,
    ) {
        if !self.wide.nodes.is_empty() && finite(r) {
            let wr = WideRay::<T>::new(r);
            with_const!(wr.r.kz, [0, 1, 2], self.walk_1::<T>(&wr, hit, steps))
        }
    }

    /// The tree part of [`Bvh::intersect_1`] for a ray whose largest direction
    /// component is axis `KZ` (the triangle kernel's permutation, fixed here once per
    /// ray instead of per block): [`Bvh::step_1`] until no subtree is left.
    #[inline(always)]
    fn walk_1<T: TriangleKernel, const KZ: usize>(
        &self,
        wr: &WideRay<T>,
        hit: &mut Hit1,
        steps: &mut Steps,
    ) {
        let mut stack = Stack::<Pending, WIDE_STACK>::new();
        let mut cur = SlotRef::ROOT;
        while self.step_1::<T, KZ>(wr, &mut cur, &mut stack, hit, steps) {}
    }

    /// The tree part of [`Bvh::intersect_1`] for up to sixteen rays at once: each ray's
    /// walk of [`Bvh::walk_1`] on its own, stepped in turn, one node or leaf each, so
    /// that one ray's node and triangle fetches are in flight while the others compute
    /// (a single walk waits on each fetch: every next node's address is in the one
    /// before). Each ray gets exactly its own walk's hit.
    pub(crate) fn intersect_wide_interleaved<T: TriangleKernel>(
        &self,
        rays: &[Ray1],
        hits: &mut [Hit1],
        steps: &mut Steps,
    ) {
        if rays.len() > 8 {
            with_stacks16(|s| self.interleaved_with::<T, 16>(rays, hits, steps, s));
        } else {
            with_stacks(|s| self.interleaved_with::<T, 8>(rays, hits, steps, s));
        }
    }

    /// [`Bvh::intersect_wide_interleaved`] of up to `N` rays with `N` stacks.
    #[inline(always)]
    fn interleaved_with<T: TriangleKernel, const N: usize>(
        &self,
        rays: &[Ray1],
        hits: &mut [Hit1],
        steps: &mut Steps,
        stacks: [&mut Stack<Pending, WIDE_STACK>; N],
    ) {
        assert!(rays.len() <= N && rays.len() == hits.len(), "up to N rays");
        if self.wide.nodes.is_empty() || rays.is_empty() {
            return;
        }
        // every slot holds a walk, those past the rays a copy of the last (an array of
        // `Option`s was written out whole, 4 KB, to say `None`)
        let mut walks: [Walk<T>; N] = std::array::from_fn(|k| Walk {
            wr: WideRay::new(&rays[k.min(rays.len() - 1)]),
            cur: SlotRef::ROOT,
        });
        let live = live_walks(rays);
        in_turn(live, |k| {
            let w = &mut walks[k];
            self.step_1::<T, ANY_KZ>(&w.wr, &mut w.cur, stacks[k], &mut hits[k], steps)
        });
    }

    /// Nearest hit of each ray of a stream: `hits[i]` gets what [`Bvh::intersect_1`]
    /// gives `rays[i]` (its `t` bounds the search as there). Sixteen walks of the wide
    /// tree are in flight, stepped in turn one node or leaf each, and a walk that ends
    /// hands its slot to the next ray, so that sixteen rays' fetches overlap from the
    /// stream's first ray to its last (a packet's stepped lanes end one by one, the last
    /// alone). For rays that share little (`benches/README.md`: incoherent rays,
    /// `mode=1s`); in a tree small enough to stay in the caches
    /// (`WideBvh::stream_steps` false) the rays walk one after another. Panics when
    /// `hits` and `rays` differ in length.
    pub fn intersect_stream<T: TriangleKernel>(
        &self,
        rays: &[Ray1],
        hits: &mut [Hit1],
        steps: &mut Steps,
    ) {
        assert_eq!(rays.len(), hits.len(), "a hit per ray");
        if !self.wide.stream_steps {
            for (r, h) in rays.iter().zip(hits.iter_mut()) {
                self.intersect_1::<T>(r, h, steps);
            }
            return;
        }
        if !self.wide.nodes.is_empty() {
            with_stacks16(|s| self.intersect_stream_with::<T, 16>(rays, hits, steps, s));
        }
        for (r, h) in rays.iter().zip(hits.iter_mut()) {
            self.intersect_beside_1::<T>(r, h, steps);
        }
    }

    /// The tree part of [`Bvh::intersect_stream`] with `N` walks in flight.
    #[inline(always)]
    fn intersect_stream_with<T: TriangleKernel, const N: usize>(
        &self,
        rays: &[Ray1],
        hits: &mut [Hit1],
        steps: &mut Steps,
        stacks: [&mut Stack<Pending, WIDE_STACK>; N],
    ) {
        const { assert!(N <= 32, "a walk per bit of a u32") };
        let mut todo = (0..rays.len()).filter(|&i| finite(&rays[i]));
        let Some(first) = todo.next() else { return };
        // slot k walks ray `ray[k]`; slots past the stream's rays hold a copy of the
        // first and are not live
        let mut ray = [first; N];
        let mut live = 1u32;
        for (k, i) in (1..N).zip(todo.by_ref()) {
            ray[k] = i;
            live |= 1 << k;
        }
        let mut walks: [Walk<T>; N] = std::array::from_fn(|k| Walk {
            wr: WideRay::new(&rays[ray[k]]),
            cur: SlotRef::ROOT,
        });
        in_turn(live, |k| {
            let w = &mut walks[k];
            if self.step_1::<T, ANY_KZ>(&w.wr, &mut w.cur, stacks[k], &mut hits[ray[k]], steps) {
                return true;
            }
            // the walk ended with its stack empty: the slot takes the next ray
            let Some(i) = todo.next() else { return false };
            ray[k] = i;
            *w = Walk {
                wr: WideRay::new(&rays[i]),
                cur: SlotRef::ROOT,
            };
            true
        });
    }

    /// Whether each ray of a stream meets anything with 0 < t < `t_max[i]`: `blocked[i]`
    /// gets what [`Bvh::occluded_1`] gives `rays[i]`. The floor and the unbounded
    /// quadrics first, then the tree for the rays they leave unblocked, as
    /// [`Bvh::intersect_stream`]: sixteen any-hit walks in flight, a slot taking the next
    /// ray when its walk ends (in trees from `WideBvh::stream_any_hit_steps` on; below,
    /// one ray after another). Panics when the three slices differ in length.
    pub fn occluded_stream<T: TriangleKernel>(
        &self,
        rays: &[Ray1],
        t_max: &[f32],
        blocked: &mut [bool],
        steps: &mut Steps,
    ) {
        assert!(
            rays.len() == t_max.len() && rays.len() == blocked.len(),
            "a t_max and an answer per ray"
        );
        if !self.wide.stream_any_hit_steps {
            for ((r, &t), b) in rays.iter().zip(t_max).zip(blocked.iter_mut()) {
                *b = self.occluded_1::<T>(r, t, steps);
            }
            return;
        }
        for ((r, &t), b) in rays.iter().zip(t_max).zip(blocked.iter_mut()) {
            *b = self.occluded_beside_1::<T>(r, t, steps);
        }
        if !self.wide.nodes.is_empty() {
            with_stacks16(|s| self.occluded_stream_with::<T, 16>(rays, t_max, blocked, steps, s));
        }
    }

    /// The tree part of [`Bvh::occluded_stream`] with `N` walks in flight.
    #[inline(always)]
    fn occluded_stream_with<T: TriangleKernel, const N: usize>(
        &self,
        rays: &[Ray1],
        t_max: &[f32],
        blocked: &mut [bool],
        steps: &mut Steps,
        mut stacks: [&mut Stack<SlotRef, WIDE_STACK>; N],
    ) {
        const { assert!(N <= 32, "a walk per bit of a u32") };
        // the next ray the floor and the quadrics left for the tree (`blocked` is
        // written only for rays already taken)
        let mut next = 0;
        let mut take = |blocked: &[bool]| {
            let i = (next..rays.len()).find(|&i| !blocked[i] && finite(&rays[i]))?;
            next = i + 1;
            Some(i)
        };
        let Some(first) = take(blocked) else { return };
        let mut ray = [first; N];
        let mut live = 1u32;
        for (k, slot) in ray.iter_mut().enumerate().skip(1) {
            let Some(i) = take(blocked) else { break };
            *slot = i;
            live |= 1 << k;
        }
        let mut walks: [WideRay<T>; N] = std::array::from_fn(|k| WideRay::new(&rays[ray[k]]));
        for s in &mut stacks {
            s.push(SlotRef::ROOT);
        }
        in_turn(live, |k| {
            let i = ray[k];
            let Some(answer) =
                self.occluded_step_1::<T, ANY_KZ>(&walks[k], stacks[k], t_max[i], steps)
            else {
                return true;
            };
            blocked[i] = answer;
            // a walk that found a blocker leaves the rest of its stack
            stacks[k].clear();
            let Some(j) = take(blocked) else { return false };
            ray[k] = j;
            walks[k] = WideRay::new(&rays[j]);
            stacks[k].push(SlotRef::ROOT);
            true
        });
    }

    /// One step of a ray's closest-hit walk: the node or leaf at `cur`, then the next
    /// subtree still in front of the nearest hit; false when none is left. `KZ`: the
    /// ray's triangle permutation (0–2, fixed per ray), or [`ANY_KZ`] to read it at
    /// run time (walks of different rays stepped in turn).
    #[inline(always)]
    fn step_1<T: TriangleKernel, const KZ: usize>(
        &self,
        wr: &WideRay<T>,
        cur: &mut SlotRef,
        stack: &mut Stack<Pending, WIDE_STACK>,
        hit: &mut Hit1,
        steps: &mut Steps,
    ) -> bool {
        let w = &self.wide;
        if cur.slot.is_interior() {
            let node = &w.nodes[cur.child as usize];
            steps.boxes += 1;
            let (m, near) = wr.boxes.test(&node.bounds, hit.t);
            let mut bits = m.bits();
            self.prefetch_children_1(node, bits);
            if bits != 0 {
                let first = bits.trailing_zeros() as usize;
                bits &= bits - 1;
                *cur = if bits == 0 {
                    node.get(first)
                } else {
                    // two or more: nearest next, the others pushed farthest first
                    WideBvh::push_ordered(node, near, first, bits, None, stack)
                };
                return true;
            }
        } else {
            self.leaf_intersect_1::<T, KZ>(*cur, wr, hit, steps);
        }
        // pop the next subtree still in front of the nearest hit
        while let Some(p) = stack.pop() {
            if p.near <= hit.t {
                *cur = p.to;
                return true;
            }
        }
        false
    }

    /// A leaf of the closest-hit walk: triangles here, inlined into the walk (called,
    /// it stored the ray's vectors again at every leaf: 8 % of the walk's instructions
    /// on incoherent rays), other kinds out of line.
    #[inline(always)]
    fn leaf_intersect_1<T: TriangleKernel, const KZ: usize>(
        &self,
        leaf: SlotRef,
        wr: &WideRay<T>,
        hit: &mut Hit1,
        steps: &mut Steps,
    ) {
        if !leaf.slot.holds(PrimKind::Triangle) {
            self.leaf_other_1::<T>(leaf, wr.r, hit, steps);
            return;
        }
        let count = leaf.slot.count() as usize;
        steps.leaf(PrimKind::Triangle, count, 1);
        let first = leaf.child as usize;
        let w = &self.wide;
        let end = first + count.div_ceil(8);
        for (b, leaf) in self.prims.blocks[first..end]
            .iter()
            .zip(&w.leaf_boxes[first..end])
        {
            // the leaf boxes only for lanes that hit (`BoxRay::leaf_lanes`)
            let (m, t, u, v) = T::intersect_1x8::<KZ>(&b.tri, &wr.tris, Mask8::ALL, hit.t);
            if m.none() {
                continue;
            }
            let mut bits = wr.boxes.leaf_lanes(b, leaf, m, hit.t).bits();
            let (t, u, v) = (t.to_array(), u.to_array(), v.to_array());
            while bits != 0 {
                let l = bits.trailing_zeros() as usize;
                bits &= bits - 1;
                let code = prim_code(PrimKind::Triangle, b.first as usize + l);
                self.prims.record_1(hit, t[l], u[l], v[l], code);
            }
        }
    }

    /// A leaf of spheres or clipped quadrics, out of the triangle walk's loop.
    #[cold]
    #[inline(never)]
    fn leaf_other_1<T: TriangleKernel>(
        &self,
        leaf: SlotRef,
        r: &Ray1,
        hit: &mut Hit1,
        steps: &mut Steps,
    ) {
        let (kind, count) = (leaf.slot.kind(), leaf.slot.count() as usize);
        steps.leaf(kind, count, 1);
        self.prims
            .intersect_1::<T>(kind, leaf.child as usize, count, r, hit);
    }

    /// Whether anything lies on the ray with 0 < t < t_max (the floor, the unbounded
    /// quadrics, then the 8-wide tree, unordered; stops at the first blocker).
    pub fn occluded_1<T: TriangleKernel>(&self, r: &Ray1, t_max: f32, steps: &mut Steps) -> bool {
        self.occluded_beside_1::<T>(r, t_max, steps) || self.occluded_wide_1::<T>(r, t_max, steps)
    }

    /// The tree part of [`Bvh::occluded_1`].
    #[inline]
    pub(crate) fn occluded_wide_1<T: TriangleKernel>(
        &self,
        r: &Ray1,
        t_max: f32,
        steps: &mut Steps,
    ) -> bool {
        if self.wide.nodes.is_empty() || !finite(r) {
            return false;
        }
        let wr = WideRay::<T>::new(r);
        with_const!(
            wr.r.kz,
            [0, 1, 2],
            self.occluded_walk_1::<T>(&wr, t_max, steps)
        )
    }

    /// The tree part of [`Bvh::occluded_1`], the permutation fixed as in `walk_1`:
    /// [`Bvh::occluded_step_1`] until the walk ends.
    #[inline(always)]
    fn occluded_walk_1<T: TriangleKernel, const KZ: usize>(
        &self,
        wr: &WideRay<T>,
        t_max: f32,
        steps: &mut Steps,
    ) -> bool {
        let mut stack = Stack::<SlotRef, WIDE_STACK>::new();
        stack.push(SlotRef::ROOT);
        loop {
            if let Some(blocked) = self.occluded_step_1::<T, KZ>(wr, &mut stack, t_max, steps) {
                return blocked;
            }
        }
    }

    /// One step of the any-hit walk, the entry on top of `stack`: a node, whose hit
    /// children are pushed ([`WideBvh::push_any_hit`]: the farthest interior child
    /// visited first of those, its leaves last, tested next), or a leaf, tested.
    /// `Some(answer)` when the walk has ended. `KZ` as [`Bvh::step_1`]'s.
    #[inline(always)]
    fn occluded_step_1<T: TriangleKernel, const KZ: usize>(
        &self,
        wr: &WideRay<T>,
        stack: &mut Stack<SlotRef, WIDE_STACK>,
        t_max: f32,
        steps: &mut Steps,
    ) -> Option<bool> {
        let w = &self.wide;
        let Some(cur) = stack.pop() else {
            return Some(false);
        };
        if cur.slot.is_interior() {
            let node: &WideNode = &w.nodes[cur.child as usize];
            steps.boxes += 1;
            let (m, near) = wr.boxes.test(&node.bounds, t_max);
            let bits = m.bits();
            let prefetch = w.prefetches.then_some((self, false));
            WideBvh::push_any_hit(node, near, bits, true, prefetch, stack);
        } else if self.leaf_occluded_1::<T, KZ>(cur, wr, t_max, steps) {
            return Some(true);
        }
        stack.is_empty().then_some(false)
    }

    #[inline]
    fn leaf_occluded_1<T: TriangleKernel, const KZ: usize>(
        &self,
        leaf: SlotRef,
        wr: &WideRay<T>,
        t_max: f32,
        steps: &mut Steps,
    ) -> bool {
        let (kind, count) = (leaf.slot.kind(), leaf.slot.count() as usize);
        steps.leaf(kind, count, 1);
        let first = leaf.child as usize;
        if kind != PrimKind::Triangle {
            return self.prims.occluded_1::<T>(kind, first, count, wr.r, t_max);
        }
        let w = &self.wide;
        let end = first + count.div_ceil(8);
        (self.prims.blocks[first..end].iter())
            .zip(&w.leaf_boxes[first..end])
            .any(|(b, leaf)| {
                let m = T::occluded_1x8::<KZ>(&b.tri, &wr.tris, Mask8::ALL, t_max);
                m.any() && wr.boxes.leaf_lanes(b, leaf, m, t_max).any()
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::triangle::{Triangle8, Triangle32};
    use glam::Vec3;

    /// A triangle in the plane z = 0 over [x0, x1] × [y0, y1].
    fn flat(x0: f32, x1: f32, y0: f32, y1: f32) -> Triangle32 {
        Triangle32 {
            v: [
                Vec3::new(x0, y0, 0.0),
                Vec3::new(x1, y0, 0.0),
                Vec3::new(x0, y1, 0.0),
            ],
        }
    }

    /// Lane boxes, lane i = `boxes[i]` ([lo, hi] per axis), the rest empty.
    fn lane_boxes(boxes: &[[[f32; 2]; 3]]) -> [f32x8; 6] {
        let mut b = [[f32::INFINITY; 8], [f32::NEG_INFINITY; 8]].repeat(3);
        for (i, bx) in boxes.iter().enumerate() {
            for a in 0..3 {
                b[2 * a][i] = bx[a][0];
                b[2 * a + 1][i] = bx[a][1];
            }
        }
        [0, 1, 2, 3, 4, 5].map(|k| f32x8::new(b[k]))
    }

    #[test]
    fn a_hit_lane_counts_where_the_ray_meets_its_leaf_box_whatever_its_own_box_says() {
        // the ray runs down the z axis from z = 1
        let r = Ray1::new(Vec3::new(0.0, 0.0, 1.0), Vec3::new(0.0, 0.0, -1.0));
        let boxes = BoxRay::new(&r);
        let tris = [
            flat(-1.0, 1.0, -1.0, 1.0), // lane 0: its own box met
            flat(5.0, 6.0, 5.0, 6.0),   // lane 1: its own box missed, its leaf box met
            flat(5.0, 6.0, 5.0, 6.0),   // lane 2: both missed
            flat(-1.0, 1.0, -1.0, 1.0), // lane 3: met, but not in the mask
        ];
        let leaf = lane_boxes(&[
            [[-1.0, 1.0], [-1.0, 1.0], [0.0, 0.0]],
            [[-2.0, 6.0], [-2.0, 6.0], [-1.0, 0.0]],
            [[4.0, 7.0], [4.0, 7.0], [-1.0, 1.0]],
            [[-1.0, 1.0], [-1.0, 1.0], [0.0, 0.0]],
        ]);
        let block = |one_leaf| TriBlock {
            tri: Triangle8::new(&tris),
            first: 0,
            count: tris.len() as u32,
            one_leaf,
        };
        let m = Mask8::from_bits(0b0111);
        assert_eq!(
            boxes
                .leaf_lanes(&block(false), &leaf, m, f32::INFINITY)
                .bits(),
            0b0011
        );
        // t_max before the boxes: none
        assert_eq!(boxes.leaf_lanes(&block(false), &leaf, m, 0.5).bits(), 0);
        // a block of one binary leaf: the slot's box, already passed
        assert_eq!(boxes.leaf_lanes(&block(true), &leaf, m, 0.5).bits(), 0b0111);
    }

    /// Checks on built trees that `leaf_lanes` keeps exactly the lanes of `m` that pass
    /// their leaf box, for every real lane of every merged block, hit or not; returns
    /// how many blocks it checked.
    fn leaf_lanes_match_leaf_boxes(bvh: &Bvh, rays: &[Ray1]) -> usize {
        let mut merged = 0;
        for r in rays {
            let boxes = BoxRay::new(r);
            let w = &bvh.wide;
            for (b, leaf) in (bvh.prims.blocks.iter())
                .zip(&w.leaf_boxes)
                .filter(|(b, _)| !b.one_leaf)
            {
                merged += 1;
                let m = Mask8::from_bits((1u32 << b.count) - 1);
                for t_max in [f32::INFINITY, 1.0, 0.25] {
                    let want = m & boxes.test(leaf, t_max).0;
                    let got = boxes.leaf_lanes(b, leaf, m, t_max);
                    assert_eq!(got.bits(), want.bits(), "{r:?} block {}", b.first);
                }
            }
        }
        merged
    }

    #[test]
    fn leaf_lanes_equal_the_leaf_box_test_on_built_trees() {
        use crate::bvh::bench::{incoherent_rays, torus};
        use crate::geometry::PrimSet;
        let bvh = Bvh::build(PrimSet::from_triangles(torus(40, 24)));
        let set = incoherent_rays(300, 7);
        let rays: Vec<Ray1> = (set.origin.iter().zip(&set.dir))
            .map(|(&o, &d)| Ray1::new(o, d))
            .collect();
        assert!(leaf_lanes_match_leaf_boxes(&bvh, &rays) > 0);
        // a triangle beyond ±BOUNDS_LIMIT (2^44), whose leaf box is clamped, merged with
        // one near the origin; the ray meets the triangle past the clamped box
        let (c, s) = (Vec3::new(2.0e13, 2.4e13, 0.0), 1.0e9);
        let far = Triangle32 {
            v: [
                c + Vec3::new(s, -s, -s),
                c + Vec3::new(-s, s, -s),
                c + Vec3::new(0.0, 0.0, s),
            ],
        };
        let near = Triangle32 {
            v: flat(-1.0, 1.0, -1.0, 1.0)
                .v
                .map(|p| p + Vec3::new(0.0, 0.0, 5.0)),
        };
        let bvh = Bvh::build(PrimSet::from_triangles(vec![far, near]));
        let r = Ray1::new(Vec3::ZERO, Vec3::new(1.0, 1.2, 0.0).normalize());
        assert!(leaf_lanes_match_leaf_boxes(&bvh, &[r]) > 0);
    }
}
