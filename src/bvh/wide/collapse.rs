//! The collapse of the binary tree into the 8-wide one.
//!
//! Greedy: a node's two children are taken, then the openable child with the largest
//! surface area is replaced by its two children until there are eight or only leaves
//! left; O(n), every binary node is opened at most once. A binary subtree of at most
//! [`MERGE_MAX`] primitives of one kind, contiguous in that kind's array, becomes one
//! leaf: full blocks of [`Triangle8`] for triangles instead of several nearly empty
//! ones. A node with room left then opens such merged leaves too (largest area first)
//! where the two halves take no more blocks than the whole: tighter boxes at no cost
//! in blocks.

use wide::f32x8;

use super::{
    MERGE_MAX, PREFETCH_FROM, STREAM_ANY_HIT_FROM, STREAM_FROM, TriBlock, WideBvh, WideNode,
};
use crate::bvh::STACK_SIZE;
use crate::bvh::memory::{huge_vec, prefetch_lines};
use crate::bvh::node::BvhNode;
use crate::bvh::slot::Slot;
use crate::geometry::triangle::Triangle8;
use crate::geometry::{PrimKind, PrimSet};

/// Subtree summary of a binary node, 8 B: its primitives are `first..first + count` of
/// one kind (a leaf `slot`), or `slot` is `None` (mixed kinds or not contiguous). Bit
/// 31 of `first_split`: the two children's runs take no more triangle blocks than this
/// one (always for other kinds, never for a binary leaf); bits 0..31: `first`.
#[derive(Clone, Copy)]
struct Span {
    first_split: u32,
    slot: Option<Slot>,
}

impl Span {
    const MIXED: Span = Span {
        first_split: 0,
        slot: None,
    };
    const SPLIT: u32 = 1 << 31;

    #[inline]
    fn count(self) -> u32 {
        self.slot.map_or(0, Slot::count)
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
    pub fn collapse(nodes: &[BvhNode], prims: &PrimSet) -> WideBvh {
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
        let mut span = vec![Span::MIXED; nodes.len()];
        for i in (0..nodes.len()).rev() {
            let n = &nodes[i];
            span[i] = if n.is_leaf() {
                debug_assert!(n.first < Span::SPLIT);
                Span {
                    first_split: n.first,
                    slot: Some(n.slot),
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
                match (a.slot, b.slot) {
                    (Some(sa), Some(sb))
                        if sa.kind() == sb.kind()
                            && lo.first() + lo.count() == hi.first()
                            && count <= Slot::MAX_COUNT =>
                    {
                        let free = sa.kind() != PrimKind::Triangle
                            || a.count().div_ceil(8) + b.count().div_ceil(8) <= count.div_ceil(8);
                        Span {
                            first_split: lo.first() | if free { Span::SPLIT } else { 0 },
                            slot: Some(Slot::leaf(sa.kind(), count)),
                        }
                    }
                    _ => Span::MIXED,
                }
            };
        }
        // a binary node becomes a leaf slot when it is a leaf or a small enough run
        let as_leaf = |i: usize| -> bool {
            let s = span[i];
            s.slot.is_some() && (nodes[i].is_leaf() || s.count() <= MERGE_MAX)
        };
        // top-down: the wide nodes; triangle leaf slots get their block index now and
        // their blocks below. Reserved beyond need (virtual memory only), so never moved.
        w.nodes = huge_vec(nodes.len() / 4 + 1);
        w.nodes.push(WideNode::empty());
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
            s.slot.is_none()
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
            let mut node = WideNode::empty();
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
                    w.nodes.push(WideNode::empty());
                    node.slot[slot] = Slot::INTERIOR;
                    node.child[slot] = ci;
                    let l = b.first;
                    work.push((ci, [l, l + 1, 0, 0, 0, 0, 0, 0], 2));
                } else {
                    let s = span[k as usize];
                    let leaf = s.slot.expect("a leaf slot is one run of one kind");
                    node.slot[slot] = leaf;
                    node.child[slot] = if leaf.holds(PrimKind::Triangle) {
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
        w.prefetches = w.walked_bytes() > PREFETCH_FROM;
        w.stream_steps = w.walked_bytes() >= STREAM_FROM;
        w.stream_any_hit_steps = w.walked_bytes() >= STREAM_ANY_HIT_FROM;
        w
    }

    /// Packs the triangles of leaf slot `t` into blocks of 8, each lane with the box of
    /// the binary leaf its triangle came from.
    fn push_blocks(&mut self, nodes: &[BvhNode], prims: &PrimSet, t: TriSlot) {
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
}
