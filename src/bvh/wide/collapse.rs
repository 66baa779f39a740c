//! The collapse of the binary tree into the 8-wide one.
//!
//! By the surface area heuristic, optimally over the binary tree's cuts ([`plan`]): each
//! wide node's slots are the binary subtrees whose choice costs least, leaves and wide
//! nodes weighed by their surface area, O(64 n) for n binary nodes. A binary subtree of
//! at most [`MERGE_MAX`] primitives of one kind, contiguous in that kind's array, may be
//! one leaf: full blocks of [`Triangle8`] for triangles instead of several nearly empty
//! ones, each lane keeping its binary leaf's box; the plan weighs such a merged leaf's
//! blocks against the tighter boxes of its parts.

use wide::f32x8;

use super::walk_x8::WIDE_PACKET_MIN_NODES;
use super::{
    MERGE_MAX, PREFETCH_FROM, STREAM_ANY_HIT_FROM, STREAM_FROM, TriBlock, WideBvh, WideNode,
    walked_bytes,
};
use crate::bvh::STACK_SIZE;
use crate::bvh::memory::{huge_vec, prefetch_lines};
use crate::bvh::node::BvhNode;
use crate::bvh::slot::Slot;
use crate::geometry::triangle::{Triangle8, Triangle32};
use crate::geometry::{PrimKind, PrimSet};

/// Subtree summary of a binary node, 8 B: its primitives are `first..first + count` of
/// one kind (a leaf `slot`), or `slot` is `None` (mixed kinds or not contiguous).
#[derive(Clone, Copy)]
struct Span {
    first: u32,
    slot: Option<Slot>,
}

impl Span {
    const MIXED: Span = Span {
        first: 0,
        slot: None,
    };

    #[inline]
    fn count(self) -> u32 {
        self.slot.map_or(0, Slot::count)
    }
}

/// Cost of one 8-wide node test, per unit of the node's surface area, in the collapse's
/// surface area heuristic.
const C_NODE: f32 = 1.0;
/// Cost of one leaf block (eight triangles at once, or one primitive of another kind),
/// per unit of the leaf's surface area. 0.6 against 1.0, over the greedy collapse
/// (5 interleaved rounds, medians, the best mode of each cell of `benches/meshes.sh`):
/// 0.99–1.08 against 0.97–1.12 in every cell, and 177 668 triangle blocks on torus1m
/// against 193 568 (the greedy's 160 895): the cheaper the blocks, the more merged leaves
/// stay whole.
const C_BLOCK: f32 = 0.6;
/// `plan[i][0]` of a binary node that becomes a leaf slot.
const LEAF: u8 = 0;

/// The blocks a leaf slot's walk tests: eight triangles a block, one other primitive.
#[inline]
fn blocks(leaf: Slot) -> u32 {
    if leaf.holds(PrimKind::Triangle) {
        leaf.count().div_ceil(8)
    } else {
        leaf.count()
    }
}

/// The collapse's choices, per binary node `i`, that minimise the surface area cost of
/// the wide tree (the optimal collapse of Ylitie, Karras and Laine, "Efficient
/// Incoherent Ray Traversal on GPUs Through Compressed Wide BVHs", 2017, with this
/// tree's leaves): `plan[i][0]` is [`LEAF`] when subtree `i` in one slot is a leaf, else
/// the slots of the wide node it becomes given to its left child (the right child gets
/// the rest of 8); `plan[i][k - 1]`, k in 2..=8, is 0 when subtree `i` given k slots
/// takes one, else the slots given to its left child. `leaf_slot(i)`: the slot of
/// subtree `i` as one leaf, `None` when it cannot be one. One walk of the binary tree in
/// post order, each subtree's eight costs kept on a stack until its parent takes them
/// (a few kilobytes, not 32 bytes a node).
fn plan(nodes: &[BvhNode], leaf_slot: impl Fn(usize) -> Option<Slot>) -> Vec<[u8; 8]> {
    let mut plan = vec![[0u8; 8]; nodes.len()];
    // c[k - 1]: least cost of a subtree in at most k slots, for the subtrees done whose
    // parent is not (a left child's below its right sibling's)
    let mut costs: Vec<[f32; 8]> = Vec::with_capacity(2 * STACK_SIZE);
    // (binary node, whether its children are done)
    let mut todo: Vec<(u32, bool)> = Vec::with_capacity(2 * STACK_SIZE);
    todo.push((0, false));
    while let Some((i, children_done)) = todo.pop() {
        let n = &nodes[i as usize];
        if !n.is_leaf() && !children_done {
            todo.extend([(i, true), (n.first + 1, false), (n.first, false)]);
            continue;
        }
        let i = i as usize;
        let area = n.bounds().area();
        let as_leaf = leaf_slot(i);
        let leaf = as_leaf.map_or(f32::INFINITY, |l| C_BLOCK * blocks(l) as f32 * area);
        if n.is_leaf() {
            costs.push([leaf; 8]);
            continue;
        }
        let cr = costs.pop().expect("the right child's costs");
        let cl = costs.pop().expect("the left child's costs");
        // the children over k slots, k = 2..=8 (a split always exists: an opened node
        // is never a leaf slot, whatever the costs, NaN included; selects, not branches:
        // which split wins is data, not a pattern)
        let (mut c, mut p) = split_costs(&cl, &cr);
        // one slot: a leaf, or a wide node over its children's best eight slots
        let node = C_NODE * area + c[7];
        p[0] = if as_leaf.is_some() && leaf <= node {
            LEAF
        } else {
            p[7]
        };
        c[0] = leaf.min(node);
        for k in 2..=8 {
            if c[0] <= c[k - 1] {
                c[k - 1] = c[0];
                p[k - 1] = 0;
            }
        }
        costs.push(c);
        plan[i] = p;
    }
    plan
}

/// The least cost of a binary node's two children over k slots (lane k − 1, k = 2..=8)
/// and the slots given to the left child for it, the fewest on a tie; `cl`, `cr`: the
/// children's least costs in at most 1..=8 slots. Lane 0 (one slot cannot hold two
/// children) is ∞ and 1. All seven splits of every k at once, in the order and with the
/// additions of a loop over k and then j (`tests`), so the plan is the same bit for bit.
#[inline]
fn split_costs(cl: &[f32; 8], cr: &[f32; 8]) -> ([f32; 8], [u8; 8]) {
    // behind eight ∞, so that lane m of `right[8 - j..]` is cr[m − j], or ∞ for m < j
    let mut right = [f32::INFINITY; 16];
    right[8..].copy_from_slice(cr);
    let mut best = f32x8::splat(f32::INFINITY);
    let mut at = f32x8::splat(1.0);
    for j in 1..8 {
        // k = m + 1 slots: j to the left child, k − j to the right
        let shifted: [f32; 8] = right[8 - j..16 - j].try_into().expect("8 lanes");
        let v = f32x8::splat(cl[j - 1]) + f32x8::new(shifted);
        let better = v.simd_lt(best);
        best = better.select(v, best);
        at = better.select(f32x8::splat(j as f32), at);
    }
    (best.to_array(), at.to_array().map(|j| j as u8))
}

/// The slots of the wide node that binary node `x` becomes (`plan[x][0]` is a split):
/// the slot roots of its children by the plan, in order, and their count.
fn wide_slots(nodes: &[BvhNode], plan: &[[u8; 8]], x: u32) -> ([u32; 8], usize) {
    fn roots(nodes: &[BvhNode], plan: &[[u8; 8]], x: u32, k: usize, out: &mut ([u32; 8], usize)) {
        match plan[x as usize][k - 1] {
            j if k == 1 || j == 0 => {
                out.0[out.1] = x;
                out.1 += 1;
            }
            j => {
                let l = nodes[x as usize].first;
                roots(nodes, plan, l, j as usize, out);
                roots(nodes, plan, l + 1, k - j as usize, out);
            }
        }
    }
    let j = plan[x as usize][0] as usize;
    debug_assert!((1..8).contains(&j), "a wide node's split");
    let l = nodes[x as usize].first;
    let mut out = ([0u32; 8], 0);
    roots(nodes, plan, l, j, &mut out);
    roots(nodes, plan, l + 1, 8 - j, &mut out);
    out
}

/// A triangle leaf slot waiting for its blocks: its binary node, primitive span, and
/// the wide node and slot that name its first block.
#[derive(Clone, Copy)]
struct TriSlot {
    node: u32,
    first: u32,
    count: u32,
    wide: u32,
    slot: u32,
}

impl WideBvh {
    /// Collapses the binary tree `nodes` over `prims` (in leaf order, but for the
    /// triangles, whose leaf order is `order`: [`build`](crate::bvh::build::build)) into
    /// the wide tree, and packs the triangles into their blocks
    /// ([`PrimSet::pack_triangles`]), the one copy of them the trees keep. Returns the
    /// binary tree too when `keep_binary` or when the wide tree is too small for the
    /// packet walks ([`WIDE_PACKET_MIN_NODES`]: its packets walk the binary tree), else
    /// an empty one: it goes as soon as the blocks' leaf boxes are taken from it, before
    /// the blocks are written, so that the two never take memory at once.
    ///
    /// Five passes: subtree spans bottom-up (one sweep over the binary nodes); the
    /// [`plan`] (one walk in post order); the wide nodes top-down by the plan, which
    /// counts the triangle blocks; the leaf boxes of the blocks in leaf order; the
    /// blocks, each triangle read once from `prims` ([`PrimSet::triangle`]). Each array
    /// is written once at exactly its size (no growth, no copy).
    pub fn collapse(
        nodes: Vec<BvhNode>,
        prims: &mut PrimSet,
        order: Vec<u32>,
        keep_binary: bool,
    ) -> (WideBvh, Vec<BvhNode>) {
        let mut w = WideBvh::default();
        if nodes.is_empty() {
            // no triangle, but perhaps a mesh's vertices, all its triangles dropped
            prims.pack_triangles(Vec::new());
            return (w, nodes);
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
                Span {
                    first: n.first,
                    slot: Some(n.slot),
                }
            } else {
                let l = n.first as usize;
                let (a, b) = (span[l], span[l + 1]);
                let (lo, hi) = if a.first <= b.first { (a, b) } else { (b, a) };
                let count = a.count() + b.count();
                match (a.slot, b.slot) {
                    (Some(sa), Some(sb))
                        if sa.kind() == sb.kind()
                            && lo.first + lo.count() == hi.first
                            && count <= Slot::MAX_COUNT =>
                    {
                        Span {
                            first: lo.first,
                            slot: Some(Slot::leaf(sa.kind(), count)),
                        }
                    }
                    _ => Span::MIXED,
                }
            };
        }
        // a binary node can be a leaf slot when it is a leaf or a small enough run
        let plan = plan(&nodes, |i| {
            (span[i].slot).filter(|s| nodes[i].is_leaf() || s.count() <= MERGE_MAX)
        });
        // top-down: the wide nodes; triangle leaf slots get their block index now and
        // their blocks below. Reserved beyond need (at most one wide node per interior
        // binary node; virtual memory only), so never moved.
        w.nodes = huge_vec(nodes.len() / 2 + 1);
        w.nodes.push(WideNode::empty());
        let mut tri_slots: Vec<TriSlot> = Vec::with_capacity(nodes.len() / 8 + 1);
        let mut n_blocks = 0u32;
        // (wide node to fill, its slots' binary nodes, how many)
        let mut work: Vec<(u32, [u32; 8], usize)> = Vec::with_capacity(8 * STACK_SIZE);
        let root = if plan[0][0] == LEAF {
            ([0; 8], 1)
        } else {
            wide_slots(&nodes, &plan, 0)
        };
        work.push((0, root.0, root.1));
        while let Some((wi, kids, n)) = work.pop() {
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
                if plan[k as usize][0] != LEAF {
                    let ci = w.nodes.len() as u32;
                    w.nodes.push(WideNode::empty());
                    node.slot[slot] = Slot::INTERIOR;
                    node.child[slot] = ci;
                    let (kids, n) = wide_slots(&nodes, &plan, k);
                    work.push((ci, kids, n));
                } else {
                    let s = span[k as usize];
                    let leaf = s.slot.expect("a leaf slot is one run of one kind");
                    node.slot[slot] = leaf;
                    node.child[slot] = if leaf.holds(PrimKind::Triangle) {
                        // its first block once the slots are in leaf order, below
                        tri_slots.push(TriSlot {
                            node: k,
                            first: s.first,
                            count: s.count(),
                            wide: wi,
                            slot: slot as u32,
                        });
                        n_blocks += blocks(leaf);
                        0
                    } else {
                        s.first
                    };
                }
            }
            node.bounds = lanes.map(f32x8::new);
            w.nodes[wi as usize] = node;
        }
        drop(span);
        drop(plan);
        // the blocks in leaf order: a triangle's block then follows from its index
        // (`PrimSet::triangle`), and the slots' blocks are written one after another
        tri_slots.sort_unstable_by_key(|t| t.first);
        let mut b0 = 0;
        for t in &tri_slots {
            w.nodes[t.wide as usize].child[t.slot as usize] = b0;
            b0 += t.count.div_ceil(8);
        }
        // the leaf boxes, the last use of the binary tree
        w.leaf_boxes = huge_vec(n_blocks as usize);
        let mut one_leaf = Vec::with_capacity(tri_slots.len());
        for (i, &t) in tri_slots.iter().enumerate() {
            // a few slots ahead, their binary node, and a merged subtree's nodes: the
            // builder allocates a subtree depth first, so its 2·leaves − 2 descendants
            // follow `first` contiguously (a hint only: another order costs time, not
            // results)
            if let Some(a) = tri_slots.get(i + 4) {
                prefetch_lines(&nodes[a.node as usize]);
            }
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
            one_leaf.push(w.push_leaf_boxes(&nodes, t));
        }
        debug_assert_eq!(w.leaf_boxes.len(), n_blocks as usize);
        let kept = if keep_binary || w.nodes.len() < WIDE_PACKET_MIN_NODES {
            nodes
        } else {
            drop(nodes);
            Vec::new()
        };
        let mut blocks = huge_vec(n_blocks as usize);
        for (i, (&t, &one_leaf)) in tri_slots.iter().zip(&one_leaf).enumerate() {
            // a few slots ahead, their triangles' corner indices
            if let Some(a) = tri_slots.get(i + 4) {
                let (f, c) = (a.first as usize, a.count as usize);
                for &k in order.get(f..f + c).unwrap_or_default() {
                    if let Some(t) = prims.tri_corners.get(k as usize) {
                        prefetch_lines(t);
                    }
                }
            }
            // and two ahead, their corners (whose indices are in the cache by then)
            if let Some(a) = tri_slots.get(i + 2) {
                let (f, c) = (a.first as usize, a.count as usize);
                for &k in order.get(f..f + c).unwrap_or_default() {
                    for &j in prims.tri_corners.get(k as usize).into_iter().flatten() {
                        if let Some(v) = prims.tri_vertices.get(j as usize) {
                            prefetch_lines(v);
                        }
                    }
                }
            }
            push_blocks(prims, &order, t, one_leaf, &mut blocks);
        }
        debug_assert_eq!(blocks.len(), n_blocks as usize);
        drop(order);
        prims.pack_triangles(blocks);
        let walked = walked_bytes(&w.nodes, &prims.blocks);
        w.prefetches = walked > PREFETCH_FROM;
        w.stream_steps = walked >= STREAM_FROM;
        w.stream_any_hit_steps = walked >= STREAM_ANY_HIT_FROM;
        (w, kept)
    }

    /// Pushes the leaf boxes of leaf slot `t`'s blocks onto `leaf_boxes`: each lane's
    /// box of the binary leaf its triangle comes from. Returns whether the slot is one
    /// binary leaf (every lane then has the slot's own box).
    fn push_leaf_boxes(&mut self, nodes: &[BvhNode], t: TriSlot) -> bool {
        const EMPTY: [[f32; 8]; 6] = [
            [f32::INFINITY; 8],
            [f32::NEG_INFINITY; 8],
            [f32::INFINITY; 8],
            [f32::NEG_INFINITY; 8],
            [f32::INFINITY; 8],
            [f32::NEG_INFINITY; 8],
        ];
        const MERGED_BLOCKS: usize = MERGE_MAX.div_ceil(8) as usize;
        let count = t.count as usize;
        let root = &nodes[t.node as usize];
        if root.is_leaf() {
            for k in 0..count.div_ceil(8) {
                let lanes = (count - 8 * k).min(8);
                let mut b = EMPTY;
                for a in 0..3 {
                    b[2 * a][..lanes].fill(root.lo[a]);
                    b[2 * a + 1][..lanes].fill(root.hi[a]);
                }
                self.leaf_boxes.push(b.map(f32x8::new));
            }
            return true;
        }
        // a merged subtree (count <= MERGE_MAX): each lane gets its leaf's box
        let mut lanes = [EMPTY; MERGED_BLOCKS];
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
        for b in &lanes[..count.div_ceil(8)] {
            self.leaf_boxes.push(b.map(f32x8::new));
        }
        false
    }
}

/// Packs the triangles of leaf slot `t` (`order` names them in `prims`) into blocks
/// of 8 on `blocks`; `one_leaf`: whether the slot is one binary leaf.
fn push_blocks(
    prims: &PrimSet,
    order: &[u32],
    t: TriSlot,
    one_leaf: bool,
    blocks: &mut Vec<TriBlock>,
) {
    let (first, count) = (t.first as usize, t.count as usize);
    for (k, chunk) in order[first..first + count].chunks(8).enumerate() {
        let tris: [Triangle32; 8] =
            std::array::from_fn(|l| prims.triangle(chunk[l.min(chunk.len() - 1)] as usize));
        blocks.push(TriBlock {
            tri: Triangle8::new(&tris[..chunk.len()]),
            first: t.first + 8 * k as u32,
            count: chunk.len() as u32,
            one_leaf,
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::build;
    use crate::geometry::sphere::Sphere32;
    use crate::geometry::triangle::Triangle32;
    use crate::math::test_rng::Xorshift;
    use glam::{DVec3, Vec3};
    use std::collections::HashMap;

    /// `n` small triangles in clusters of a few, and `spheres` spheres among them (so that
    /// some subtrees mix kinds), from a fixed seed.
    fn prims(seed: u64, n: usize, spheres: usize) -> PrimSet {
        let mut rng = Xorshift(seed.wrapping_mul(0x9e37_79b9_7f4a_7c15));
        let mut r = move || rng.f32();
        let mut centre = Vec3::ZERO;
        let tris = (0..n)
            .map(|i| {
                if i % 5 == 0 {
                    centre = Vec3::new(r(), r(), r()) * 10.0;
                }
                let c = centre + Vec3::new(r(), r(), r());
                let e = 0.05 + r() * 0.5;
                Triangle32 {
                    v: [
                        c,
                        c + Vec3::new(e, r() * e, 0.0),
                        c + Vec3::new(0.0, e, r() * e),
                    ],
                }
            })
            .collect();
        let mut p = PrimSet::from_triangles(tris);
        for k in 0..spheres {
            let c = DVec3::new(r() as f64, r() as f64, r() as f64) * 10.0;
            p.spheres
                .push(Sphere32::new(c, 0.1 + r() as f64 * 0.3, DVec3::ZERO));
            p.sphere_obj.push(1 + k as u32);
        }
        p
    }

    /// The cost the plan minimises, of the wide tree built: C_NODE times the area of
    /// every wide node, C_BLOCK times blocks times area for every leaf slot.
    fn wide_cost(w: &WideBvh) -> f64 {
        let area = |b: &[[f32; 8]; 6], s: usize| {
            let [lo, hi] = [0, 1].map(|e| Vec3::new(b[e][s], b[2 + e][s], b[4 + e][s]));
            crate::math::aabb::Aabb { lo, hi }.area() as f64
        };
        let mut cost = 0.0;
        let mut todo = vec![(0usize, None::<f64>)];
        while let Some((i, own)) = todo.pop() {
            let node = &w.nodes[i];
            let b = node.bounds.map(|v| v.to_array());
            let used: Vec<usize> = (0..8).filter(|&s| b[0][s] <= b[1][s]).collect();
            assert!(!used.is_empty(), "wide node {i} has no slot");
            // the root's own box: the union of its slots
            let root_area = || {
                let lo = used.iter().fold(Vec3::INFINITY, |m, &s| {
                    m.min(Vec3::new(b[0][s], b[2][s], b[4][s]))
                });
                let hi = used.iter().fold(Vec3::NEG_INFINITY, |m, &s| {
                    m.max(Vec3::new(b[1][s], b[3][s], b[5][s]))
                });
                crate::math::aabb::Aabb { lo, hi }.area() as f64
            };
            let one_leaf_root = i == 0 && used.len() == 1 && !node.slot[used[0]].is_interior();
            if !one_leaf_root {
                assert!(used.len() >= 2, "wide node {i} has {} slot", used.len());
                cost += C_NODE as f64 * own.unwrap_or_else(root_area);
            }
            for &s in &used {
                let slot = node.slot[s];
                if slot.is_interior() {
                    todo.push((node.child[s] as usize, Some(area(&b, s))));
                } else {
                    cost += C_BLOCK as f64 * blocks(slot) as f64 * area(&b, s);
                }
            }
        }
        cost
    }

    /// The least cost over every collapse of the binary tree, by enumerating each wide
    /// node's cuts (sets of at most eight subtrees covering its two children) outright.
    fn least_cost(nodes: &[BvhNode]) -> f64 {
        // (kind, first, count) of a subtree when one contiguous run of one kind
        fn run(nodes: &[BvhNode], i: usize) -> Option<(PrimKind, u32, u32)> {
            let n = &nodes[i];
            if n.is_leaf() {
                return Some((n.slot.kind(), n.first, n.count()));
            }
            let l = n.first as usize;
            let (a, b) = (run(nodes, l)?, run(nodes, l + 1)?);
            let (lo, hi) = if a.1 <= b.1 { (a, b) } else { (b, a) };
            (a.0 == b.0 && lo.1 + lo.2 == hi.1 && a.2 + b.2 <= Slot::MAX_COUNT).then_some((
                a.0,
                lo.1,
                a.2 + b.2,
            ))
        }
        // every cut of subtree i into at most eight subtrees, each as (its number of
        // subtrees, the sum of their least costs)
        type Memo = (HashMap<usize, f64>, HashMap<usize, Vec<(usize, f64)>>);
        // the cuts of both children of binary node i together, at most eight subtrees
        fn children_cuts(nodes: &[BvhNode], i: usize, memo: &mut Memo) -> Vec<(usize, f64)> {
            let l = nodes[i].first as usize;
            let (ca, cb) = (cuts(nodes, l, memo), cuts(nodes, l + 1, memo));
            (ca.iter())
                .flat_map(|&(na, sa)| cb.iter().map(move |&(nb, sb)| (na + nb, sa + sb)))
                .filter(|&(n, _)| n <= 8)
                .collect()
        }
        fn cuts(nodes: &[BvhNode], i: usize, memo: &mut Memo) -> Vec<(usize, f64)> {
            if let Some(c) = memo.1.get(&i) {
                return c.clone();
            }
            let mut out = vec![(1, best(nodes, i, memo))];
            if !nodes[i].is_leaf() {
                out.extend(children_cuts(nodes, i, memo));
            }
            memo.1.insert(i, out.clone());
            out
        }
        fn best(nodes: &[BvhNode], i: usize, memo: &mut Memo) -> f64 {
            if let Some(&c) = memo.0.get(&i) {
                return c;
            }
            let n = &nodes[i];
            let area = n.bounds().area() as f64;
            let mut c = f64::INFINITY;
            if let Some((kind, _, count)) = run(nodes, i)
                && (n.is_leaf() || count <= MERGE_MAX)
            {
                c = C_BLOCK as f64 * blocks(Slot::leaf(kind, count)) as f64 * area;
            }
            if !n.is_leaf() {
                // a wide node: the least cost of its slots over the cuts of its children
                let slots =
                    (children_cuts(nodes, i, memo).iter()).fold(f64::INFINITY, |m, c| m.min(c.1));
                c = c.min(C_NODE as f64 * area + slots);
            }
            memo.0.insert(i, c);
            c
        }
        best(nodes, 0, &mut (HashMap::new(), HashMap::new()))
    }

    /// `split_costs` by the loop it stands for: k, then j, strictly less.
    fn split_costs_by_loop(cl: &[f32; 8], cr: &[f32; 8]) -> ([f32; 8], [u8; 8]) {
        let mut c = [f32::INFINITY; 8];
        let mut p = [1u8; 8];
        for k in 2..=8 {
            for j in 1..k {
                let v = cl[j - 1] + cr[k - j - 1];
                if v < c[k - 1] {
                    (c[k - 1], p[k - 1]) = (v, j as u8);
                }
            }
        }
        (c, p)
    }

    #[test]
    fn split_costs_are_the_loops_bit_for_bit() {
        let mut rng = Xorshift(7);
        // few distinct values (ties), ∞ and NaN among them
        let values = [0.0, 0.5, 1.0, 1.5, 2.0, 3.0, f32::INFINITY, f32::NAN];
        for round in 0..20_000 {
            let mut pick = |_| {
                if round % 2 == 0 {
                    values[(rng.next_u64() % values.len() as u64) as usize]
                } else {
                    rng.f32() * 10.0
                }
            };
            let cl: [f32; 8] = std::array::from_fn(&mut pick);
            let cr: [f32; 8] = std::array::from_fn(&mut pick);
            let (c, p) = split_costs(&cl, &cr);
            let (c0, p0) = split_costs_by_loop(&cl, &cr);
            assert_eq!(c.map(f32::to_bits), c0.map(f32::to_bits), "{cl:?} {cr:?}");
            assert_eq!(p, p0, "{cl:?} {cr:?}");
        }
    }

    /// The collapse builds a wide tree of the least cost the plan's heuristic allows,
    /// found here by enumerating every wide node's cuts instead (mixed kinds, merged
    /// leaves, leaves of one binary leaf), and every wide node has at least two slots.
    #[test]
    fn the_collapse_is_the_least_cost_wide_tree() {
        for (seed, n, spheres) in [
            (1, 40, 0),
            (2, 120, 0),
            (3, 90, 12),
            (4, 160, 20),
            (5, 9, 0),
            (6, 3, 2),
        ] {
            let mut p = prims(seed, n, spheres);
            let (nodes, order) = build::build(&mut p);
            let (w, nodes) = WideBvh::collapse(nodes, &mut p, order, true);
            let (got, least) = (wide_cost(&w), least_cost(&nodes));
            assert!(least.is_finite() && least > 0.0, "seed {seed}: {least}");
            assert!(
                (got - least).abs() <= 1e-4 * least.max(1e-9),
                "seed {seed}: the wide tree costs {got}, the least cost is {least}"
            );
        }
    }
}
