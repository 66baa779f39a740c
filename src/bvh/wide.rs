//! An 8-wide BVH collapsed from the binary SAH tree, for single rays.
//!
//! [`WideBvh::collapse`] turns the binary node array into nodes of up to eight children
//! (greedy: a node's two children are taken, then the interior child with the largest
//! surface area is replaced by its two children until there are eight or only leaves
//! left; O(n), every binary node is opened at most once). A binary subtree of at most
//! [`MERGE_MAX`] primitives of one kind, contiguous in that kind's array, becomes one
//! leaf: full blocks of [`Triangle8`] for triangles instead of several nearly empty ones.
//! A node with room left then opens such merged leaves too (largest area first) where
//! the two halves take no more blocks than the whole: tighter boxes at no cost in
//! blocks. Without this, 2210 of torus100k's 3711 wide nodes had two slots, each a
//! leaf of 9 to 16 triangles (two blocks) that every ray meeting it tested whole.
//! The slot boxes are the binary nodes' boxes, bit for bit, so a slot's slab test gives
//! the same answer the binary traversal gets for that subtree.
//!
//! One ray is tested against the eight boxes of a node at once ([`WideNode`], SoA, f32x8),
//! the hit children are visited nearest first (closest hit) and a leaf's triangles eight
//! at a time with the watertight 1×8 kernel ([`Triangle8::intersect_1x8`], equal lane by
//! lane to [`Triangle32::intersect_1`]). Spheres and clipped quadrics in leaves go
//! through [`PrimSet::intersect_1`]/[`PrimSet::occluded_1`] one by one.
//!
//! Contract (as `bvh/mod.rs`): hit iff 0 < t < t_max, NaN never hits (a ray with a
//! non-finite origin or direction skips the tree), an exact tie in t goes to the lower
//! object index, the unbounded quadrics and the floor after the tree. Step counters:
//! `boxes` counts **wide node tests** (one per node visited, each of up to 8 boxes),
//! `prims` the primitives of the leaves reached (real triangles, not padding lanes),
//! `quadrics` the quadric tests.
//!
//! [`Triangle32::intersect_1`]: crate::geometry::triangle::Triangle32::intersect_1

use std::mem::MaybeUninit;

use wide::f32x8;

use super::{Bvh, STACK_SIZE, Steps};
use crate::geometry::triangle::{TriRay8, Triangle8};
use crate::geometry::{Hit1, PrimKind, PrimSet, prim_code};
use crate::math::packet::{Cmp8, FAR_WIDEN, Mask8, Ray1};

/// Largest binary subtree (in primitives of one kind) collapsed into one leaf.
// Tried (bench-trace torus100k, 1 thread, back to back, mode=1 incoherent / primary,
// before the blocks had leaf boxes and before prefetching):
// 8: 2.07 / 5.81 Mrays/s; 4: 1.93 / 5.62; 1 (binary leaves only): 1.37 / 5.76.
// With leaf boxes, prefetching and huge pages, four interleaved pairs at load ~2.4,
// mode=1 alone: 16: incoherent 2.86, 2.97, 2.77, 2.73 / primary 6.05, 6.49, 6.62,
// 6.70; 8: 2.56, 2.33, 3.09, 2.28 / 6.48, 6.24, 6.21, 5.32. Whole bench-trace, three
// interleaved pairs at load ~1.5: 16: incoherent 3.45, 3.55, 3.32 / primary 6.74, 6.70,
// 6.61; 8: 3.09, 3.48, 3.48 / 6.96, 7.03, 7.00. So 16 trades ~5 % of coherent single
// rays for ~3 % of incoherent ones (the bar); revisit with a quieter machine.
// Session 6, 8 against 16, interleaved pairs, median ratios: incoherent mode=1 1.07 (8
// pairs) then 1.00 (12 pairs); primary mode=1 0.93 (4); primary mode=8 0.92 (8). Kept.
pub const MERGE_MAX: u32 = 16;

/// Slot `meta` of an interior child (and of an empty slot, whose box never hits).
pub(super) const INTERIOR: u32 = 0;
pub(super) const COUNT_MASK: u32 = (1 << 28) - 1;

// Tried (session 7): a 128-byte copy of each node for the single-ray walk, child boxes
// quantised to 8 bits per plane against a power-of-two scale (conservative, checked
// per plane at build; hits stay exact through the blocks' lane boxes). Same hits,
// 6.5 instead of 6.3 node tests per ray, and slower: bench-trace torus100k
// incoherent mode=1, 1 thread, 6 interleaved pairs, 2.08 vs 2.45 Mrays/s. The
// dequantisation lengthens the load-to-decision chain of every node test, and the
// walk waits on that chain more than on the bytes it fetches.
/// A node of the 8-wide tree. 256 B = four cache lines, 64-byte aligned.
///
/// `bounds[2a]` / `bounds[2a + 1]`: the low / high bounds of the eight child boxes on
/// axis a (x, y, z), lane i = slot i. Empty slots have lo = +∞, hi = −∞: with the near
/// plane picked by the sign of the direction (never min/max), their entry is +∞ and
/// their exit −∞, so they never hit. Slots are filled from 0 without gaps.
/// `meta[i]` == 0: interior child, `child[i]` is the index of its [`WideNode`];
/// otherwise a leaf: bits 0..28 the primitive count, bits 28..31 the [`PrimKind`];
/// `child[i]` is the first [`TriBlock`] for triangles, the first primitive of its kind
/// in the [`PrimSet`] otherwise.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
pub struct WideNode {
    pub bounds: [f32x8; 6],
    pub child: [u32; 8],
    pub meta: [u32; 8],
}

const _: () = assert!(std::mem::size_of::<WideNode>() == 256);

/// Up to eight triangles of one leaf, SoA, with the index of the first in
/// `PrimSet::triangles` (lane i is triangle `first + i`; lanes >= `count` are padding
/// that never hits), and per lane the box of the binary leaf the triangle came from
/// (same layout as [`WideNode::bounds`]; padding lanes empty). 512 B = eight cache lines.
///
/// A lane's hit counts only when the ray also passes its binary leaf's box: then a
/// merged leaf reports exactly the triangles the binary walk reaches (the slab test is
/// monotone under box containment, so passing the leaf's box implies passing every
/// ancestor's). Without it, the larger merged box let the wide walk find hits the
/// binary and packet walks miss (a ray lying in a box face with a ±0 direction
/// component, see `math::packet`), so packet lanes and single rays differed. A block
/// of one binary leaf (`one_leaf`) has the slot's own box in every lane, already passed.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
pub struct TriBlock {
    pub tri: Triangle8,
    // Tried: `first`, `count`, `one_leaf` before `bounds`, in the fifth line that
    // `prefetch` brings with the triangles: bench-trace torus100k incoherent mode=1,
    // 1 thread, six interleaved pairs, median 2.18 vs 2.23 Mrays/s; cachegrind D1
    // misses 32.34 M both.
    pub bounds: [f32x8; 6],
    pub first: u32,
    pub count: u32,
    /// All lanes come from one binary leaf, whose box is the slot's: the single-ray
    /// walk then skips the lane boxes (three cache lines) on a hit, the frustum packet
    /// walk their frustum test.
    pub one_leaf: bool,
}

const _: () = assert!(std::mem::size_of::<TriBlock>() == 512);

/// The 8-wide tree over the same primitives as the binary one (it owns copies of the
/// triangles in blocks; the primitive codes it reports index `PrimSet`).
#[derive(Clone, Debug, Default)]
pub struct WideBvh {
    pub nodes: Vec<WideNode>,
    pub blocks: Vec<TriBlock>,
    /// Length of the diagonal of the root box (0 when empty): the packet walk's origin
    /// spread limit scales with it (`wide_x8::Frustum::new`), so it is computed once
    /// here, not per packet (a square root per packet was 1.2 % of a perf profile of
    /// bench-trace torus100k primary mode=8).
    pub diagonal: f32,
}

/// Depth limit of the wide traversal stacks: the wide tree is never deeper than the
/// binary one (< [`STACK_SIZE`]), and a node leaves at most 7 entries on the stack.
pub(super) const WIDE_STACK: usize = 7 * STACK_SIZE + 1;

/// Subtree summary of a binary node, 8 B: its primitives are `first..first + count` of
/// one kind (`count | kind << 28` in `meta`), or `meta` == [`Span::MIXED`]. Bit 31 of
/// `first_split`: the two children's runs take no more triangle blocks than this one
/// (always for other kinds, never for a binary leaf); bits 0..31: `first`.
#[derive(Clone, Copy)]
struct Span {
    first_split: u32,
    meta: u32,
}

impl Span {
    const MIXED: u32 = u32::MAX;
    const SPLIT: u32 = 1 << 31;

    #[inline]
    fn count(self) -> u32 {
        self.meta & COUNT_MASK
    }

    #[inline]
    fn first(self) -> u32 {
        self.first_split & !Span::SPLIT
    }

    #[inline]
    fn free_split(self) -> bool {
        self.first_split & Span::SPLIT != 0
    }
}

/// A triangle leaf slot waiting for its blocks: its binary node and primitive span.
#[derive(Clone, Copy)]
struct TriSlot {
    node: u32,
    first: u32,
    count: u32,
}

impl WideBvh {
    /// Collapses the binary tree `nodes` over `prims` (in leaf order) into the wide tree.
    ///
    /// Three passes: subtree spans bottom-up (one sweep over the binary nodes); the wide
    /// nodes top-down, which counts the triangle blocks; the blocks, written once into
    /// an array of exactly that size (no growth, no copy).
    pub fn collapse(nodes: &[super::BvhNode], prims: &PrimSet) -> WideBvh {
        let mut w = WideBvh::default();
        if nodes.is_empty() {
            return w;
        }
        w.diagonal = {
            let d = nodes[0].bounds();
            (d.hi - d.lo).length()
        };
        // bottom-up: which subtrees are one contiguous run of one kind (children follow
        // their parent in the array, so a reverse sweep sees children first)
        let mut span = vec![
            Span {
                first_split: 0,
                meta: Span::MIXED,
            };
            nodes.len()
        ];
        for i in (0..nodes.len()).rev() {
            let n = &nodes[i];
            span[i] = if n.is_leaf() {
                debug_assert!(n.first < Span::SPLIT);
                Span {
                    first_split: n.first,
                    meta: n.meta,
                }
            } else {
                let l = n.first as usize;
                let (a, b) = (span[l], span[l + 1]);
                let (lo, hi) = if a.first() <= b.first() {
                    (a, b)
                } else {
                    (b, a)
                };
                let count = a.count() + b.count();
                if a.meta != Span::MIXED
                    && b.meta != Span::MIXED
                    && a.meta >> 28 == b.meta >> 28
                    && lo.first() + lo.count() == hi.first()
                    && count <= COUNT_MASK
                {
                    let free = a.meta >> 28 != PrimKind::Triangle as u32
                        || a.count().div_ceil(8) + b.count().div_ceil(8) <= count.div_ceil(8);
                    Span {
                        first_split: lo.first() | if free { Span::SPLIT } else { 0 },
                        meta: count | (a.meta >> 28) << 28,
                    }
                } else {
                    Span {
                        first_split: 0,
                        meta: Span::MIXED,
                    }
                }
            };
        }
        // a binary node becomes a leaf slot when it is a leaf or a small enough run
        let as_leaf = |i: usize| -> bool {
            let s = span[i];
            s.meta != Span::MIXED && (nodes[i].is_leaf() || s.count() <= MERGE_MAX)
        };
        // top-down: the wide nodes; triangle leaf slots get their block index now and
        // their blocks below. Reserved beyond need (virtual memory only), so never moved.
        w.nodes = huge_vec(nodes.len() / 4 + 1);
        w.nodes.push(Self::empty_node());
        let mut tri_slots: Vec<TriSlot> = Vec::with_capacity(nodes.len() / 8 + 1);
        let mut n_blocks = 0u32;
        // (wide node to fill, its binary children)
        let mut work: Vec<(u32, [u32; 8], usize)> = Vec::with_capacity(8 * STACK_SIZE);
        let root = if as_leaf(0) {
            ([0; 8], 1)
        } else {
            let l = nodes[0].first;
            ([l, l + 1, 0, 0, 0, 0, 0, 0], 2)
        };
        work.push((0, root.0, root.1));
        // a slot may be opened when it is interior, or a merged leaf whose two halves
        // take no more triangle blocks than it does (tighter boxes for free)
        let can_open = |i: usize| -> bool {
            let s = span[i];
            s.meta == Span::MIXED
                || if nodes[i].is_leaf() {
                    false
                } else {
                    s.count() > MERGE_MAX || s.free_split()
                }
        };
        while let Some((wi, mut kids, mut n)) = work.pop() {
            // open the openable child with the largest surface area while there is room
            // (on equal areas the last such slot, as `Iterator::max_by`)
            let mut area = [f32::NEG_INFINITY; 8];
            let mut open = [false; 8];
            let mut can = [false; 8];
            // the children of an openable slot are likely read next: start loading them
            // (the binary nodes and spans are tens of MB on large meshes, so each read
            // here is a cache miss)
            let ahead = |k: usize| {
                let c = nodes[k].first as usize;
                if let (Some(n), Some(s)) = (nodes.get(c), span.get(c)) {
                    prefetch_lines(n);
                    prefetch_lines(s);
                }
            };
            // (areas only matter for openable slots)
            for s in 0..n {
                open[s] = !as_leaf(kids[s] as usize);
                can[s] = can_open(kids[s] as usize);
                if can[s] {
                    area[s] = nodes[kids[s] as usize].bounds().area();
                    ahead(kids[s] as usize);
                }
            }
            while n < 8 {
                let mut best = usize::MAX;
                for s in 0..n {
                    if can[s] && (best == usize::MAX || area[s].total_cmp(&area[best]).is_ge()) {
                        best = s;
                    }
                }
                if best == usize::MAX {
                    break;
                }
                let l = nodes[kids[best] as usize].first;
                for (s, k) in [(best, l), (n, l + 1)] {
                    kids[s] = k;
                    open[s] = !as_leaf(k as usize);
                    can[s] = can_open(k as usize);
                    if can[s] {
                        area[s] = nodes[k as usize].bounds().area();
                        ahead(k as usize);
                    }
                }
                n += 1;
            }
            let mut node = Self::empty_node();
            let mut lanes = [[0.0f32; 8]; 6];
            for (s, lane) in lanes.iter_mut().enumerate() {
                *lane = node.bounds[s].to_array();
            }
            for (slot, &k) in kids[..n].iter().enumerate() {
                let b = &nodes[k as usize];
                for a in 0..3 {
                    lanes[2 * a][slot] = b.lo[a];
                    lanes[2 * a + 1][slot] = b.hi[a];
                }
                if open[slot] {
                    let ci = w.nodes.len() as u32;
                    w.nodes.push(Self::empty_node());
                    node.meta[slot] = INTERIOR;
                    node.child[slot] = ci;
                    let l = b.first;
                    work.push((ci, [l, l + 1, 0, 0, 0, 0, 0, 0], 2));
                } else {
                    let s = span[k as usize];
                    node.meta[slot] = s.meta;
                    node.child[slot] = if s.meta >> 28 == PrimKind::Triangle as u32 {
                        tri_slots.push(TriSlot {
                            node: k,
                            first: s.first(),
                            count: s.count(),
                        });
                        let b0 = n_blocks;
                        n_blocks += s.count().div_ceil(8);
                        b0
                    } else {
                        s.first()
                    };
                }
            }
            node.bounds = lanes.map(f32x8::new);
            w.nodes[wi as usize] = node;
        }
        drop(span);
        w.blocks = huge_vec(n_blocks as usize);
        for (i, &t) in tri_slots.iter().enumerate() {
            // a few slots ahead: their binary node (its subtree's boxes) and triangles
            if let Some(a) = tri_slots.get(i + 4) {
                prefetch_lines(&nodes[a.node as usize]);
                let (f, c) = (a.first as usize, a.count as usize);
                if let Some(tris) = prims.triangles.get(f..f + c) {
                    // every cache line of them (a line holds at least one whole triangle
                    // or the start of one)
                    let per_line = (64 / std::mem::size_of_val(&tris[0])).max(1);
                    for t in tris.iter().step_by(per_line) {
                        prefetch_lines(t);
                    }
                }
            }
            // two slots ahead, a merged subtree's nodes: the builder allocates a subtree
            // depth first, so its 2·leaves − 2 descendants follow `first` contiguously
            // (a hint only: another order costs time, not results)
            if let Some(a) = tri_slots.get(i + 2) {
                let r = &nodes[a.node as usize];
                if !r.is_leaf() {
                    let lo = r.first as usize;
                    let hi = (lo + 2 * a.count as usize - 2).min(nodes.len());
                    // 32-byte nodes: every other one starts a cache line
                    for n in nodes[lo.min(hi)..hi].iter().step_by(2) {
                        prefetch_lines(n);
                    }
                }
            }
            w.push_blocks(nodes, prims, t);
        }
        debug_assert_eq!(w.blocks.len(), n_blocks as usize);
        w
    }

    fn empty_node() -> WideNode {
        let lo = f32x8::splat(f32::INFINITY);
        let hi = f32x8::splat(f32::NEG_INFINITY);
        WideNode {
            bounds: [lo, hi, lo, hi, lo, hi],
            child: [0; 8],
            meta: [INTERIOR; 8],
        }
    }

    /// Packs the triangles of leaf slot `t` into blocks of 8, each lane with the box of
    /// the binary leaf its triangle came from.
    fn push_blocks(&mut self, nodes: &[super::BvhNode], prims: &PrimSet, t: TriSlot) {
        const EMPTY: [[f32; 8]; 6] = [
            [f32::INFINITY; 8],
            [f32::NEG_INFINITY; 8],
            [f32::INFINITY; 8],
            [f32::NEG_INFINITY; 8],
            [f32::INFINITY; 8],
            [f32::NEG_INFINITY; 8],
        ];
        const MERGED_BLOCKS: usize = MERGE_MAX.div_ceil(8) as usize;
        let (first, count) = (t.first as usize, t.count as usize);
        let tris = &prims.triangles[first..first + count];
        let root = &nodes[t.node as usize];
        let mut lanes = [EMPTY; MERGED_BLOCKS];
        if !root.is_leaf() {
            // a merged subtree (count <= MERGE_MAX): each lane gets its leaf's box
            let mut stack = [0u32; 2 * MERGE_MAX as usize];
            let mut sp = 0;
            let mut i = t.node;
            loop {
                let n = &nodes[i as usize];
                if n.is_leaf() {
                    let f = (n.first - t.first) as usize;
                    for l in f..f + n.count() as usize {
                        for a in 0..3 {
                            lanes[l / 8][2 * a][l % 8] = n.lo[a];
                            lanes[l / 8][2 * a + 1][l % 8] = n.hi[a];
                        }
                    }
                    if sp == 0 {
                        break;
                    }
                    sp -= 1;
                    i = stack[sp];
                } else {
                    stack[sp] = n.first + 1;
                    sp += 1;
                    i = n.first;
                }
            }
        }
        for (k, chunk) in tris.chunks(8).enumerate() {
            let bounds = if root.is_leaf() {
                // one binary leaf: every lane has its box
                let mut b = EMPTY;
                for a in 0..3 {
                    b[2 * a][..chunk.len()].fill(root.lo[a]);
                    b[2 * a + 1][..chunk.len()].fill(root.hi[a]);
                }
                b
            } else {
                lanes[k]
            };
            self.blocks.push(TriBlock {
                tri: Triangle8::new(chunk),
                bounds: bounds.map(f32x8::new),
                first: t.first + 8 * k as u32,
                count: chunk.len() as u32,
                one_leaf: root.is_leaf(),
            });
        }
    }

    /// Asks for the whole of a child's node or first triangle block to be brought into
    /// the cache at once: the slab test reads the box lines, then the child or triangle
    /// lines, each a miss of its own on incoherent rays without this.
    #[inline(always)]
    pub(super) fn prefetch_children(&self, node: &WideNode, mut bits: u32) {
        while bits != 0 {
            let s = bits.trailing_zeros() as usize;
            bits &= bits - 1;
            self.prefetch(node.child[s], node.meta[s]);
        }
    }

    /// Prefetches one child: its node, or its first triangle block.
    // Tried (bench-trace torus100k incoherent mode=1, 1 thread, interleaved, medians):
    // also the second block of a two-block leaf: 2.37 vs 2.40 Mrays/s (8 pairs);
    // prefetching after the children are sorted, nearest first, all of them or only
    // the nearest and the next two on the stack: 2.15 / 2.17 vs 2.31 (7 rounds): the
    // prefetches need the lead they get here. The whole block, leaf boxes included
    // (torus100k has no block of one binary leaf, so every block with a hit lane reads
    // its boxes): 2.63 vs 2.61 (10 pairs).
    #[inline(always)]
    fn prefetch(&self, child: u32, meta: u32) {
        if meta == INTERIOR {
            if let Some(n) = self.nodes.get(child as usize) {
                prefetch_lines(n);
            }
        } else if meta >> 28 == PrimKind::Triangle as u32
            && let Some(b) = self.blocks.get(child as usize)
        {
            prefetch_lines(&b.tri);
        }
    }

    /// Depth of the deepest leaf slot (root node = 1); 0 when empty.
    pub fn depth(&self) -> usize {
        if self.nodes.is_empty() {
            return 0;
        }
        let mut best = 0;
        let mut stack = vec![(0usize, 1usize)];
        while let Some((i, d)) = stack.pop() {
            best = best.max(d);
            let n = &self.nodes[i];
            for s in 0..8 {
                let valid = n.bounds[0].to_array()[s] <= n.bounds[1].to_array()[s];
                if valid && n.meta[s] == INTERIOR {
                    stack.push((n.child[s] as usize, d + 1));
                }
            }
        }
        best
    }
}

/// One ray prepared for the wide walk: the ray, its slab-test and its triangle-test forms.
struct WideRay<'a> {
    r: &'a Ray1,
    boxes: BoxRay,
    tris: TriRay8,
}

impl WideRay<'_> {
    #[inline]
    fn new(r: &Ray1) -> WideRay<'_> {
        WideRay {
            r,
            boxes: BoxRay::new(r),
            tris: TriRay8::new(r),
        }
    }
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

    /// The slab test of `BvhNode::intersect_1` on the eight slots: bit i of the mask is
    /// set when slot i is met with 0 <= t and t <= t_max (far bound widened by
    /// 1 + 2γ(3)); the entry distances. With finite origins and 1/d (the slab rule)
    /// nothing here is NaN, so `fast_min`/`fast_max` are exact min/max, and picking the
    /// near plane by the sign of 1/d gives the same value as the binary test's min.
    // Tried: the walks specialised to the direction octant (`const OCT`, constant
    // planes instead of `near`/`far`, as `wide_x8::Frustum::test`; dispatch once per
    // ray). valgrind --tool=callgrind, bench-trace torus100k incoherent mode=1 --reps 1,
    // `timed_trace`: 1336.8 -> 1183.4 M instructions (-11.5 %), yet slower: 1 thread,
    // ten interleaved pairs, median 2.39 -> 2.20 Mrays/s (base ahead in 9 of 10), eight
    // copies of the walk and its inlined leaf for rays of random octants. With the
    // leaf shared (`#[inline(never)]`, planes looked up): 1321.5 M, 2.25 vs 2.24 (8 pairs).
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

/// An empty vector with room for `cap` elements whose 2 MiB-aligned part Linux is
/// asked to back with transparent huge pages (`madvise(MADV_HUGEPAGE)`, before the
/// pages are touched), so incoherent rays walking megabytes of nodes and blocks miss
/// the TLB less. Embree does the same by default on Linux. Small arrays, other
/// systems: an ordinary vector. Filled in place, so the build copies nothing.
// Measured: bench-trace torus100k incoherent mode=1 alone, 1 thread, interleaved at
// load ~7: 1.12, 1.05, 1.30 Mrays/s with, 0.91, 0.99, 0.89 without.
pub(crate) fn huge_vec<T: Copy>(cap: usize) -> Vec<T> {
    #[cfg(target_os = "linux")]
    {
        const HUGE: usize = 2 << 20;
        const MADV_HUGEPAGE: i32 = 14;
        unsafe extern "C" {
            fn madvise(addr: *mut std::ffi::c_void, len: usize, advice: i32) -> i32;
        }
        let size = std::mem::size_of::<T>().max(1);
        if cap * size >= 2 * HUGE {
            let mut out: Vec<T> = Vec::with_capacity(cap + HUGE / size);
            let start = out.as_mut_ptr() as usize;
            let end = start + out.capacity() * size;
            let lo = start.next_multiple_of(HUGE);
            let hi = end / HUGE * HUGE;
            if hi > lo {
                // SAFETY: [lo, hi) lies inside `out`'s allocation; MADV_HUGEPAGE only
                // advises the kernel about it and changes no contents. A failure (THP
                // off) leaves ordinary pages.
                unsafe { madvise(lo as *mut std::ffi::c_void, hi - lo, MADV_HUGEPAGE) };
            }
            return out;
        }
    }
    Vec::with_capacity(cap)
}

/// Prefetches every cache line of `*p` (no-op off x86-64).
#[inline(always)]
pub(super) fn prefetch_lines<T>(p: &T) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
        let base = (p as *const T).cast::<i8>();
        for off in (0..std::mem::size_of::<T>()).step_by(64) {
            // SAFETY: SSE is part of x86-64; a prefetch never faults or writes.
            unsafe { _mm_prefetch::<_MM_HINT_T0>(base.wrapping_add(off)) };
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = p;
}

/// Whether the ray enters the tree: a NaN or infinite origin or direction never hits
/// a bounded primitive (their kernels give NaN), and would make the slab test NaN,
/// which `fast_min`/`fast_max` may turn into a hit of every slot, empty ones included.
#[inline]
fn finite(r: &Ray1) -> bool {
    r.origin.is_finite() && r.inv_dir.is_finite()
}

/// Of a node's hit children (`first`, then the slots in `bits`), pushes all but the
/// nearest by entry distance `near` onto the traversal stack, farthest first (keys: the
/// distance's bits, >= 0 so ordered as integers, then the slot; insertion sort, at most
/// 8), and returns the nearest, to visit next. Shared by the single-ray and the
/// frustum packet walks.
// Tried for the single-ray walk: branch-free, all eight keys (misses zeroed) through a
// 19-comparator sorting network and all seven entries written: bench-trace torus100k
// incoherent mode=1, 1 thread, eight interleaved pairs, median 1.98 vs 2.36 Mrays/s.
// A special case for exactly two hit children (one comparison, one push): 2.38 vs
// 2.38 (12 pairs, session 6).
#[inline(always)]
pub(super) fn push_ordered(
    node: &WideNode,
    near: f32x8,
    first: usize,
    mut bits: u32,
    refs: &mut [MaybeUninit<u64>; WIDE_STACK],
    dists: &mut [MaybeUninit<f32>; WIDE_STACK],
    sp: &mut usize,
) -> u64 {
    let nd = near.to_array();
    let key = |s: usize| ((nd[s].to_bits() & 0x7fff_ffff) as u64) << 32 | s as u64;
    let mut keys = [0u64; 8];
    keys[0] = key(first);
    let mut n = 1;
    while bits != 0 {
        let s = bits.trailing_zeros() as usize;
        bits &= bits - 1;
        // insertion, descending
        let k = key(s);
        let mut j = n;
        while j > 0 && keys[j - 1] < k {
            keys[j] = keys[j - 1];
            j -= 1;
        }
        keys[j] = k;
        n += 1;
    }
    for &k in &keys[..n - 1] {
        let s = (k & 0xff) as usize;
        refs[*sp] = MaybeUninit::new(pack(node.child[s], node.meta[s]));
        dists[*sp] = MaybeUninit::new(f32::from_bits((k >> 32) as u32));
        *sp += 1;
    }
    let s = (keys[n - 1] & 0xff) as usize;
    pack(node.child[s], node.meta[s])
}

/// A stack entry: slot `child` and `meta` packed (meta in the high half).
#[inline]
pub(super) fn pack(child: u32, meta: u32) -> u64 {
    child as u64 | (meta as u64) << 32
}

/// Records a hit as `PrimSet::record_1` does: nearer wins, an exact tie goes to the
/// lower object index (the earlier candidate on equal objects).
#[inline]
fn record(prims: &PrimSet, hit: &mut Hit1, t: f32, u: f32, v: f32, code: i32) {
    if t < hit.t || (t == hit.t && hit.is_hit() && prims.object(code) < prims.object(hit.prim)) {
        *hit = Hit1 {
            t,
            prim: code,
            u,
            v,
        };
    }
}

impl Bvh {
    /// Nearest hit below `hit.t`, recorded in `hit` (the 8-wide tree, then the
    /// unbounded quadrics and the floor).
    pub fn intersect_1(&self, r: &Ray1, hit: &mut Hit1, steps: &mut Steps) {
        self.intersect_wide_1(r, hit, steps);
        self.intersect_beside_1(r, hit, steps);
    }

    /// The tree part of [`Bvh::intersect_1`].
    #[inline]
    pub(super) fn intersect_wide_1(&self, r: &Ray1, hit: &mut Hit1, steps: &mut Steps) {
        if !self.wide.nodes.is_empty() && finite(r) {
            let wr = WideRay::new(r);
            with_const!(wr.tris.axes[2], [0, 1, 2], self.walk_1(&wr, hit, steps))
        }
    }

    /// The tree part of [`Bvh::intersect_1`] for a ray whose largest direction
    /// component is axis `KZ` (the triangle kernel's permutation, fixed here once per
    /// ray instead of per block).
    // Measured against the run-time permutation (bench-trace torus100k, 1 thread,
    // interleaved pairs, medians): primary mode=1 5.51 -> 5.94 Mrays/s (+6 %, 6 pairs),
    // incoherent mode=1 2.21 -> 2.38 and 2.15 -> 2.30 (two runs of 8 pairs; per-pair
    // ratios 0.84-1.22, so within the noise); cachegrind, the whole
    // incoherent run: 2.62 G -> 2.57 G instructions.
    #[inline(always)]
    fn walk_1<const KZ: usize>(&self, wr: &WideRay, hit: &mut Hit1, steps: &mut Steps) {
        let w = &self.wide;
        let br = &wr.boxes;
        // Uninitialised: zeroing the two arrays (8 KB) was 12 % of bench-trace's
        // profile (perf, memset) and 30 % of this walk's own time. Entries below
        // `sp` are always written before they are read.
        let mut refs = [MaybeUninit::<u64>::uninit(); WIDE_STACK];
        let mut dists = [MaybeUninit::<f32>::uninit(); WIDE_STACK];
        let mut sp = 0usize;
        let mut cur = pack(0, INTERIOR);
        'walk: loop {
            let (child, meta) = (cur as u32, (cur >> 32) as u32);
            if meta == INTERIOR {
                let node = &w.nodes[child as usize];
                steps.boxes += 1;
                let (m, near) = br.test(&node.bounds, hit.t);
                let mut bits = m.bits();
                w.prefetch_children(node, bits);
                if bits != 0 {
                    let first = bits.trailing_zeros() as usize;
                    bits &= bits - 1;
                    if bits == 0 {
                        cur = pack(node.child[first], node.meta[first]);
                        continue 'walk;
                    }
                    // two or more: nearest next, the others pushed farthest first
                    cur = push_ordered(node, near, first, bits, &mut refs, &mut dists, &mut sp);
                    continue 'walk;
                }
            } else {
                self.leaf_intersect_1::<KZ>(child, meta, wr, hit, steps);
            }
            // pop the next subtree still in front of the nearest hit
            loop {
                if sp == 0 {
                    break 'walk;
                }
                sp -= 1;
                // SAFETY: entries 0..sp (before the decrement) were written above.
                let (d, rf) = unsafe { (dists[sp].assume_init(), refs[sp].assume_init()) };
                if d <= hit.t {
                    cur = rf;
                    break;
                }
            }
        }
    }

    #[inline]
    fn leaf_intersect_1<const KZ: usize>(
        &self,
        child: u32,
        meta: u32,
        wr: &WideRay,
        hit: &mut Hit1,
        steps: &mut Steps,
    ) {
        let count = meta & COUNT_MASK;
        let kind = PrimKind::from_u32(meta >> 28);
        steps.leaf(kind, count as usize, 1);
        if kind != PrimKind::Triangle {
            self.prims
                .intersect_1(kind, child as usize, count as usize, wr.r, hit);
            return;
        }
        let nb = count.div_ceil(8) as usize;
        for b in &self.wide.blocks[child as usize..child as usize + nb] {
            // the leaf boxes only for lanes that hit: three lines fewer to fetch per block
            // Tried: leaf boxes first, as the kernel's active mask: their load was the walk's
            // hottest instruction (perf annotate: 15.6 % of its samples); bench-trace
            // torus100k incoherent mode=1, 1 thread, interleaved runs at load 7: 2.70,
            // 2.78, 2.75 Mrays/s against 2.76, 2.87, 2.78 for this order.
            let (m, t, u, v) = b.tri.intersect_1x8_kz::<KZ>(&wr.tris, Mask8::ALL, hit.t);
            if m.none() {
                continue;
            }
            // a block of one binary leaf: every lane's box is the slot's, which the ray
            // has passed (with a t_max >= hit.t, and a hit lies in front of hit.t)
            // Measured: bench-trace torus100k mode=1, one process alternating with and
            // without this 16 times at load 4.6-5.5, wall min / q1 / median: incoherent
            // 386 / 585 / 713 ms against 449 / 652 / 766; primary 160 / 192 / 203
            // against 177 / 194 / 203; same hits and sum of t.
            // Tried: skipping the lane boxes for every ray without a zero direction
            // component (the slab test is conservative for them, so only knife-edge
            // answers could change): torus100k incoherent mode=1, 10 interleaved pairs,
            // median 2.68 vs 2.62 Mrays/s, no gain; the boxes stay for all rays.
            let mut bits = if b.one_leaf {
                m.bits()
            } else {
                (m & wr.boxes.test(&b.bounds, hit.t).0).bits()
            };
            if bits == 0 {
                continue;
            }
            let (t, u, v) = (t.to_array(), u.to_array(), v.to_array());
            if bits & (bits - 1) != 0 {
                // several lanes: keep those at the smallest t, in lane (= index) order
                let tmin = (0..8)
                    .filter(|&l| bits >> l & 1 == 1)
                    .fold(f32::INFINITY, |a, l| a.min(t[l]));
                for (l, &tl) in t.iter().enumerate() {
                    if tl != tmin {
                        bits &= !(1 << l);
                    }
                }
            }
            while bits != 0 {
                let l = bits.trailing_zeros() as usize;
                bits &= bits - 1;
                let code = prim_code(PrimKind::Triangle, b.first as usize + l);
                record(&self.prims, hit, t[l], u[l], v[l], code);
            }
        }
    }

    /// Whether anything lies on the ray with 0 < t < t_max (the floor, the unbounded
    /// quadrics, then the 8-wide tree, unordered; stops at the first blocker).
    pub fn occluded_1(&self, r: &Ray1, t_max: f32, steps: &mut Steps) -> bool {
        self.occluded_beside_1(r, t_max, steps) || self.occluded_wide_1(r, t_max, steps)
    }

    /// The tree part of [`Bvh::occluded_1`].
    #[inline]
    pub(super) fn occluded_wide_1(&self, r: &Ray1, t_max: f32, steps: &mut Steps) -> bool {
        if self.wide.nodes.is_empty() || !finite(r) {
            return false;
        }
        let wr = WideRay::new(r);
        with_const!(
            wr.tris.axes[2],
            [0, 1, 2],
            self.occluded_walk_1(&wr, t_max, steps)
        )
    }

    /// The tree part of [`Bvh::occluded_1`], the permutation fixed as in `walk_1`.
    #[inline(always)]
    fn occluded_walk_1<const KZ: usize>(
        &self,
        wr: &WideRay,
        t_max: f32,
        steps: &mut Steps,
    ) -> bool {
        let w = &self.wide;
        let br = &wr.boxes;
        // uninitialised for the same reason as in `walk_1`
        let mut stack = [MaybeUninit::<u32>::uninit(); WIDE_STACK];
        stack[0] = MaybeUninit::new(0);
        let mut sp = 1;
        while sp > 0 {
            sp -= 1;
            // SAFETY: entries 0..sp (before the decrement) were written.
            let ni = unsafe { stack[sp].assume_init() };
            let node = &w.nodes[ni as usize];
            steps.boxes += 1;
            let mut bits = br.test(&node.bounds, t_max).0.bits();
            w.prefetch_children(node, bits);
            while bits != 0 {
                let s = bits.trailing_zeros() as usize;
                bits &= bits - 1;
                let meta = node.meta[s];
                if meta == INTERIOR {
                    stack[sp] = MaybeUninit::new(node.child[s]);
                    sp += 1;
                } else if self.leaf_occluded_1::<KZ>(node.child[s], meta, wr, t_max, steps) {
                    return true;
                }
            }
        }
        false
    }

    #[inline]
    fn leaf_occluded_1<const KZ: usize>(
        &self,
        child: u32,
        meta: u32,
        wr: &WideRay,
        t_max: f32,
        steps: &mut Steps,
    ) -> bool {
        let count = meta & COUNT_MASK;
        let kind = PrimKind::from_u32(meta >> 28);
        steps.leaf(kind, count as usize, 1);
        if kind != PrimKind::Triangle {
            return self
                .prims
                .occluded_1(kind, child as usize, count as usize, wr.r, t_max);
        }
        let nb = count.div_ceil(8) as usize;
        self.wide.blocks[child as usize..child as usize + nb]
            .iter()
            .any(|b| {
                let m = b.tri.occluded_1x8_kz::<KZ>(&wr.tris, Mask8::ALL, t_max);
                m.any() && (b.one_leaf || (m & wr.boxes.test(&b.bounds, t_max).0).any())
            })
    }
}
