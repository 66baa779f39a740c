//! Structural checks of a built BVH, run after every build in debug builds.

use glam::Vec3;
use wide::f32x8;

use super::Bvh;
use super::slot::Slot;
use super::wide::walk_x8::lane_box;
use super::wide::{PREFETCH_FROM, STREAM_ANY_HIT_FROM, STREAM_FROM, TriBlock, WIDE_STACK};
use crate::geometry::{PrimKind, PrimSet};
use crate::math::aabb::Aabb;

impl Bvh {
    /// Every BVH primitive referenced by exactly one leaf; children inside their
    /// parent; leaves of one kind with in-range primitives inside their box; the tree
    /// within the traversal stack; every object index in range of the arrays; the
    /// triangles' blocks ([`triangle_store`]); and the same of the wide tree
    /// ([`Bvh::validate_wide`]).
    pub fn validate(&self) -> Result<(), String> {
        self.validate_binary()?;
        self.validate_wide()
    }

    /// The binary tree's part of [`Bvh::validate`].
    fn validate_binary(&self) -> Result<(), String> {
        let p = &self.prims;
        if p.spheres.len() != p.sphere_obj.len()
            || p.quadrics.len() != p.quadric_obj.len()
            || p.free_quadrics.len() != p.free_quadric_obj.len()
        {
            return Err("primitive and object arrays differ in length".into());
        }
        triangle_store(p)?;
        let total: usize = PrimKind::BVH_KINDS.iter().map(|&k| p.len(k)).sum();
        if (total == 0) != self.root.is_none() {
            return Err(format!("{total} primitives, root {:?}", self.root));
        }
        if self.nodes.first().is_some_and(|n| Some(*n) != self.root) {
            return Err("the root kept is not the binary tree's".into());
        }
        if self.nodes.is_empty() {
            // no tree, or the binary tree gone where every walk takes the wide one
            // (whose checks reach every primitive)
            return if total > 0 && self.packets_walk_binary() {
                Err(format!(
                    "{total} primitives but no binary tree for the packets"
                ))
            } else {
                Ok(())
            };
        }
        let mut seen = marks(p);
        let mut stack = vec![(0usize, 1usize)];
        while let Some((i, depth)) = stack.pop() {
            if depth >= super::STACK_SIZE {
                return Err(format!("node {i} at depth {depth} exceeds the stack"));
            }
            let n = &self.nodes[i];
            let b = n.bounds();
            if n.is_leaf() {
                let Some(k) = bvh_kind(n.slot) else {
                    return Err(format!("leaf {i} has non-BVH kind {:?}", n.slot.try_kind()));
                };
                let (first, count) = (n.first as usize, n.count() as usize);
                leaf_prims(p, k, first, count, &b, &mut seen[k], &format!("leaf {i}"))?;
            } else {
                let l = n.first as usize;
                if l + 1 >= self.nodes.len() || l <= i {
                    return Err(format!("node {i}: child index {l} out of order"));
                }
                for c in [l, l + 1] {
                    if !b.contains(&self.nodes[c].bounds()) {
                        return Err(format!("node {c} not inside its parent {i}"));
                    }
                    stack.push((c, depth + 1));
                }
            }
        }
        match unmarked(&seen) {
            Some((k, j)) => Err(format!("primitive {j} of kind {k} referenced by no leaf")),
            None => Ok(()),
        }
    }
}

/// The triangles of a built set: none left in `tri_corners` (nor vertices); `blocks` one after another
/// from triangle 0 (1 to 8 each, every `first` the last block's end) over one triangle
/// per object index; every padding lane a point (three equal corners: never hit); and
/// `block_at[k]` a block holding triangle 8·k.
fn triangle_store(p: &PrimSet) -> Result<(), String> {
    let n = p.triangle_obj.len();
    if !p.tri_corners.is_empty() || !p.tri_vertices.is_empty() {
        return Err(format!(
            "{} triangles listed beside their blocks",
            p.tri_corners.len()
        ));
    }
    let mut next = 0usize;
    for (b, blk) in p.blocks.iter().enumerate() {
        let (f, c) = (blk.first as usize, blk.count as usize);
        if f != next || !(1..=8).contains(&c) {
            return Err(format!(
                "triangle block {b} holds triangles {f}+{c}, not from {next}"
            ));
        }
        for l in c..8 {
            let bits = blk.tri.lane(l).v.map(|v| v.to_array().map(f32::to_bits));
            if bits[0] != bits[1] || bits[1] != bits[2] {
                return Err(format!(
                    "triangle block {b}: padding lane {l} is not a point"
                ));
            }
        }
        next += c;
    }
    if next != n {
        return Err(format!(
            "the triangle blocks hold {next} triangles, not {n}"
        ));
    }
    if p.block_at.len() != n.div_ceil(8) {
        return Err(format!(
            "{} block indices for {n} triangles",
            p.block_at.len()
        ));
    }
    for (k, &b) in p.block_at.iter().enumerate() {
        let holds = (p.blocks.get(b as usize))
            .is_some_and(|blk| (blk.first..blk.first + blk.count).contains(&(8 * k as u32)));
        if !holds {
            return Err(format!(
                "block_at[{k}] = {b}, not a block holding triangle {}",
                8 * k
            ));
        }
    }
    Ok(())
}

/// One mark per primitive of each BVH kind, none set.
fn marks(p: &PrimSet) -> Vec<Vec<u8>> {
    (PrimKind::BVH_KINDS.iter())
        .map(|&k| vec![0; p.len(k)])
        .collect()
}

/// The first primitive (index in `BVH_KINDS`, index) left unmarked.
fn unmarked(seen: &[Vec<u8>]) -> Option<(usize, usize)> {
    (seen.iter().enumerate()).find_map(|(k, s)| s.iter().position(|&c| c == 0).map(|j| (k, j)))
}

/// The index in `BVH_KINDS` of a leaf slot's kind; `None` for bits that name no kind
/// of the trees.
fn bvh_kind(slot: Slot) -> Option<usize> {
    let kind = slot.try_kind()?;
    PrimKind::BVH_KINDS.iter().position(|&b| b == kind)
}

/// A leaf of `count` primitives of kind `BVH_KINDS[k]` from `first`: in range, inside
/// the leaf's box `b`, each marked in `seen` (the kind's marks) and not marked before.
fn leaf_prims(
    p: &PrimSet,
    k: usize,
    first: usize,
    count: usize,
    b: &Aabb,
    seen: &mut [u8],
    at: &str,
) -> Result<(), String> {
    let kind = PrimKind::BVH_KINDS[k];
    if first + count > p.len(kind) {
        return Err(format!("{at}: range {first}+{count} out of bounds"));
    }
    for (j, x) in seen.iter_mut().enumerate().skip(first).take(count) {
        if !b.contains(&p.bounds(kind, j)) {
            return Err(format!("{at}: primitive {j} outside the box"));
        }
        if std::mem::replace(x, 1) != 0 {
            return Err(format!("{at}: primitive {j} of kind {k} reached twice"));
        }
    }
    Ok(())
}

/// Box `j` of a wide node's (or a leaf-box entry's) bounds.
fn slot_box(bounds: &[f32x8; 6], j: usize) -> Aabb {
    lane_box(bounds, j).bounds()
}

/// The same bits (a slot's box copied, not recomputed).
fn same_box(a: &Aabb, b: &Aabb) -> bool {
    let bits = |v: Vec3| v.to_array().map(f32::to_bits);
    bits(a.lo) == bits(b.lo) && bits(a.hi) == bits(b.hi)
}

impl Bvh {
    /// The wide tree's part of [`Bvh::validate`], what its walks rely on:
    /// - the wide nodes form a tree from node 0, each reached once, children after
    ///   their parent, within the walks' stack ([`WIDE_STACK`]);
    /// - each node has a slot, its slots are filled from 0 without gaps, and an empty
    ///   slot is `WideNode::empty`'s (its box `Aabb::EMPTY` exactly, which never hits;
    ///   interior, child 0); a child node's boxes lie inside its slot's box;
    /// - a leaf slot names a kind of the tree; a triangle leaf of n triangles owns the
    ///   ⌈n/8⌉ blocks of `PrimSet::blocks` from its child index, each reached once,
    ///   holding triangles `first`, `first + 1`, ... (in range) of the slot's span;
    /// - `leaf_boxes` has one entry per block; a lane's leaf box lies in its slot's box
    ///   and holds its triangle's box; a padding lane's is empty; in a block of one
    ///   binary leaf (`one_leaf`) every lane's leaf box is the slot's;
    /// - a leaf of another kind holds in-range primitives inside its slot's box;
    /// - every primitive of the tree's kinds is reached exactly once;
    /// - the size switches (`prefetches`, `stream_steps`, `stream_any_hit_steps`) follow
    ///   [`Bvh::walked_bytes`].
    pub fn validate_wide(&self) -> Result<(), String> {
        let (w, p) = (&self.wide, &self.prims);
        if p.blocks.len() != w.leaf_boxes.len() {
            return Err(format!(
                "wide tree: {} triangle blocks but {} leaf-box entries",
                p.blocks.len(),
                w.leaf_boxes.len()
            ));
        }
        if self.root.is_none() {
            return if w.nodes.is_empty() && p.blocks.is_empty() {
                Ok(())
            } else {
                Err("wide tree without a binary tree".into())
            };
        }
        if w.nodes.is_empty() {
            return Err("binary tree without a wide tree".into());
        }
        let walked = self.walked_bytes();
        let switches = [
            ("prefetches", w.prefetches, walked > PREFETCH_FROM),
            ("stream_steps", w.stream_steps, walked >= STREAM_FROM),
            (
                "stream_any_hit_steps",
                w.stream_any_hit_steps,
                walked >= STREAM_ANY_HIT_FROM,
            ),
        ];
        for (name, is, want) in switches {
            if is != want {
                return Err(format!(
                    "wide tree: {name} is {is} for {walked} bytes walked"
                ));
            }
        }
        let mut seen = marks(p);
        let mut node_seen = vec![false; w.nodes.len()];
        let mut block_seen = vec![false; p.blocks.len()];
        let mut stack = vec![(0usize, 1usize)];
        while let Some((i, depth)) = stack.pop() {
            if std::mem::replace(&mut node_seen[i], true) {
                return Err(format!("wide node {i} reached twice"));
            }
            if 7 * depth + 1 > WIDE_STACK {
                return Err(format!("wide node {i} at depth {depth} exceeds the stack"));
            }
            let node = &w.nodes[i];
            let empty: [bool; 8] =
                std::array::from_fn(|s| same_box(&slot_box(&node.bounds, s), &Aabb::EMPTY));
            let used = empty.iter().take_while(|&&e| !e).count();
            for (s, &e) in empty.iter().enumerate().skip(used) {
                let r = node.get(s);
                if !e {
                    return Err(format!("wide node {i}: slot {s} filled after an empty one"));
                }
                if !r.slot.is_interior() || r.child != 0 {
                    return Err(format!("wide node {i}: empty slot {s} names a child"));
                }
            }
            if used == 0 {
                return Err(format!("wide node {i} has no slot"));
            }
            for s in 0..used {
                let r = node.get(s);
                let b = slot_box(&node.bounds, s);
                let at = format!("wide node {i} slot {s}");
                if r.slot.is_interior() {
                    let c = r.child as usize;
                    if c <= i || c >= w.nodes.len() {
                        return Err(format!("{at}: child node {c} out of order"));
                    }
                    for j in 0..8 {
                        let cb = slot_box(&w.nodes[c].bounds, j);
                        if !same_box(&cb, &Aabb::EMPTY) && !b.contains(&cb) {
                            return Err(format!("{at}: child {c} slot {j} outside its box"));
                        }
                    }
                    stack.push((c, depth + 1));
                    continue;
                }
                let Some(k) = bvh_kind(r.slot) else {
                    let kind = r.slot.try_kind();
                    return Err(format!("{at}: leaf of no kind of the tree ({kind:?})"));
                };
                let count = r.slot.count() as usize;
                if PrimKind::BVH_KINDS[k] != PrimKind::Triangle {
                    leaf_prims(p, k, r.child as usize, count, &b, &mut seen[k], &at)?;
                    continue;
                }
                let b0 = r.child as usize;
                let nb = count.div_ceil(8);
                if b0 + nb > p.blocks.len() {
                    return Err(format!("{at}: blocks {b0}+{nb} out of bounds"));
                }
                let first = p.blocks[b0].first as usize;
                for q in 0..nb {
                    let bi = b0 + q;
                    if std::mem::replace(&mut block_seen[bi], true) {
                        return Err(format!("{at}: block {bi} reached twice"));
                    }
                    let want = (first + 8 * q, (count - 8 * q).min(8));
                    let (blk, boxes) = (&p.blocks[bi], &w.leaf_boxes[bi]);
                    triangle_block(p, blk, boxes, want, &b, &mut seen[k])
                        .map_err(|e| format!("{at}: block {bi}{e}"))?;
                }
            }
        }
        if let Some(i) = node_seen.iter().position(|&x| !x) {
            return Err(format!("wide node {i} not reached"));
        }
        if let Some(b) = block_seen.iter().position(|&x| !x) {
            return Err(format!("triangle block {b} not reached"));
        }
        match unmarked(&seen) {
            Some((k, j)) => Err(format!("wide tree: primitive {j} of kind {k} not reached")),
            None => Ok(()),
        }
    }
}

/// A triangle block of a leaf slot whose box is `b`: it holds triangles `want`
/// (first, count) of `p`, in range; each lane's leaf box (`boxes`) lies between its triangle's box and `b`, is `b` itself in
/// a block of one binary leaf, and is empty in a padding lane; each triangle marked in
/// `seen` for the first time. The error says what, after the block's name.
fn triangle_block(
    p: &PrimSet,
    blk: &TriBlock,
    boxes: &[f32x8; 6],
    want: (usize, usize),
    b: &Aabb,
    seen: &mut [u8],
) -> Result<(), String> {
    let (f, n) = (blk.first as usize, blk.count as usize);
    if (f, n) != want || f + n > p.len(PrimKind::Triangle) {
        return Err(format!(" holds triangles {f}+{n}, not the slot's"));
    }
    for l in 0..8 {
        let lb = slot_box(boxes, l);
        if l >= n {
            if !same_box(&lb, &Aabb::EMPTY) {
                return Err(format!(": padding lane {l} has a box"));
            }
            continue;
        }
        if !lb.contains(&p.bounds(PrimKind::Triangle, f + l)) || !b.contains(&lb) {
            return Err(format!(
                " lane {l}: leaf box not between its triangle's and its slot's"
            ));
        }
        if blk.one_leaf && !same_box(&lb, b) {
            return Err(format!(
                " lane {l}: one binary leaf, but not the slot's box"
            ));
        }
        if std::mem::replace(&mut seen[f + l], 1) != 0 {
            return Err(format!(": triangle {} reached twice", f + l));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::bench::torus;
    use crate::bvh::slot::Slot;
    use crate::bvh::wide::WideNode;
    use crate::geometry::PrimSet;

    /// Lane `j` of `v` set to `x`.
    fn set_lane(v: &mut f32x8, j: usize, x: f32) {
        let mut a = v.to_array();
        a[j] = x;
        *v = f32x8::new(a);
    }

    /// A mesh that loses every triangle as degenerate, with nothing else to bound,
    /// builds an empty tree and leaves none of its vertices behind.
    #[test]
    fn a_mesh_of_degenerate_triangles_alone_leaves_nothing_behind() {
        let text = "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n";
        let mesh = crate::scene::obj::parse_obj(text, "d.obj").unwrap();
        let prims = crate::bvh::bench::mesh_prims(mesh);
        assert!(!prims.tri_vertices.is_empty() && prims.tri_corners.is_empty());
        let bvh = Bvh::build(prims);
        assert!(bvh.nodes.is_empty());
        assert_eq!(bvh.validate(), Ok(()));
        assert!(bvh.prims.tri_vertices.is_empty());
    }

    type Breaker = Box<dyn Fn(&mut Bvh)>;

    #[test]
    fn a_built_tree_passes_and_each_broken_wide_invariant_is_named() {
        let good = Bvh::build(PrimSet::from_triangles(torus(40, 24)));
        assert_eq!(good.validate(), Ok(()));
        let (w, blocks) = (&good.wide, &good.prims.blocks);
        let merged = (blocks.iter())
            .position(|b| !b.one_leaf)
            .expect("a merged block");
        let short = (blocks.iter())
            .position(|b| b.count < 8 && b.count > 1)
            .expect("a block with padding lanes");
        // a node with two interior slots, one with an empty slot, one with a leaf
        let slots = |f: &dyn Fn(&WideNode, usize) -> bool| {
            (0..w.nodes.len())
                .flat_map(|i| (0..8).map(move |s| (i, s)))
                .filter(|&(i, s)| f(&w.nodes[i], s))
                .collect::<Vec<_>>()
        };
        let interior = slots(&|n, s| n.slot[s].is_interior() && n.child[s] != 0);
        let (i2, [a, b]) = (0..w.nodes.len())
            .find_map(|i| {
                let s: Vec<usize> = (interior.iter())
                    .filter(|x| x.0 == i)
                    .map(|x| x.1)
                    .collect();
                (s.len() >= 2).then(|| (i, [s[0], s[1]]))
            })
            .expect("a node over two nodes");
        let (ie, se) = *slots(&|n, s| same_box(&slot_box(&n.bounds, s), &Aabb::EMPTY))
            .first()
            .expect("an empty slot");
        let (il, sl) = *slots(&|n, s| n.slot[s].holds(PrimKind::Triangle))
            .first()
            .expect("a triangle leaf slot");
        let cases: Vec<(&str, Breaker)> = vec![
            (
                "leaf-box entries",
                Box::new(|t| {
                    t.wide.leaf_boxes.pop();
                }),
            ),
            (
                "prefetches",
                Box::new(|t| t.wide.prefetches = !t.wide.prefetches),
            ),
            (
                "stream_steps",
                Box::new(|t| t.wide.stream_steps = !t.wide.stream_steps),
            ),
            (
                "slot 1 filled after an empty one",
                Box::new(|t| {
                    let n = &mut t.wide.nodes[0];
                    for (k, v) in n.bounds.iter_mut().enumerate() {
                        let x = if k % 2 == 0 {
                            f32::INFINITY
                        } else {
                            f32::NEG_INFINITY
                        };
                        set_lane(v, 0, x);
                    }
                    (n.slot[0], n.child[0]) = (Slot::INTERIOR, 0);
                }),
            ),
            (
                "names a child",
                Box::new(move |t| t.wide.nodes[ie].child[se] = 1),
            ),
            (
                "out of order",
                Box::new(move |t| t.wide.nodes[i2].child[a] = i2 as u32),
            ),
            (
                "reached twice",
                Box::new(move |t| {
                    // slot b a copy of slot a: its box and its child
                    let n = &mut t.wide.nodes[i2];
                    for v in n.bounds.iter_mut() {
                        let x = v.to_array()[a];
                        set_lane(v, b, x);
                    }
                    n.child[b] = n.child[a];
                }),
            ),
            (
                "not reached",
                Box::new(|t| t.wide.nodes.push(WideNode::empty())),
            ),
            (
                "outside its box",
                Box::new(move |t| {
                    // slot a's box shrunk to its high x face
                    let hi = t.wide.nodes[i2].bounds[1].to_array()[a];
                    set_lane(&mut t.wide.nodes[i2].bounds[0], a, hi);
                }),
            ),
            (
                "no kind of the tree",
                Box::new(move |t| {
                    let n = t.wide.nodes[il].slot[sl].count();
                    t.wide.nodes[il].slot[sl] = Slot::leaf(PrimKind::Floor, n);
                }),
            ),
            (
                "out of bounds",
                Box::new(move |t| t.wide.nodes[il].child[sl] = t.prims.blocks.len() as u32),
            ),
            (
                "is not a point",
                Box::new(move |t| {
                    let v = &mut t.prims.blocks[short].tri.v[1][0];
                    let x = v.to_array()[7];
                    set_lane(v, 7, x + 1.0);
                }),
            ),
            (
                "holds triangles",
                Box::new(move |t| t.prims.blocks[short].first += 1),
            ),
            (
                "not between its triangle's and its slot's",
                Box::new(move |t| {
                    // lane 0's box shrunk to its high x face
                    let hi = t.wide.leaf_boxes[merged][1].to_array()[0];
                    set_lane(&mut t.wide.leaf_boxes[merged][0], 0, hi);
                }),
            ),
            (
                "padding lane",
                Box::new(move |t| {
                    let b = &mut t.wide.leaf_boxes[short];
                    for v in b.iter_mut() {
                        let x = v.to_array()[0];
                        set_lane(v, 7, x);
                    }
                }),
            ),
            (
                "one binary leaf",
                Box::new(move |t| t.prims.blocks[merged].one_leaf = true),
            ),
        ];
        for (want, break_it) in cases {
            let mut bvh = good.clone();
            break_it(&mut bvh);
            let e = bvh.validate().expect_err(want);
            assert!(e.contains(want), "expected {want:?}, got {e:?}");
        }
    }
}
