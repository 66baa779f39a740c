//! An 8-wide BVH collapsed from the binary SAH tree.
//!
//! - [`collapse`]: the binary node array into nodes of up to eight children, triangle
//!   leaves into SoA blocks of eight.
//! - [`walk_1`]: one ray against the eight boxes of a node at once, a leaf's triangles
//!   eight at a time (every single-ray query, `Bvh::intersect_1`/`occluded_1`).
//! - [`walk_x8`]: a coherent packet as one frustum, Embree-style.
//!
//! The slot boxes are the binary nodes' boxes, bit for bit, so a slot's slab test gives
//! the same answer the binary traversal gets for that subtree; a merged leaf's
//! triangles keep their binary leaf's box ([`TriBlock`]), so every walk reports what the
//! binary walks report.
//!
//! Contract (as `bvh/mod.rs`): hit iff 0 < t < t_max, NaN never hits (a ray with a
//! non-finite origin, direction or 1/d skips the tree, where it would meet nothing,
//! `tests/wide_bvh.rs`), exact ties as `PrimSet::record_1`,
//! the unbounded quadrics and the floor after the tree. Step counters: `boxes` counts
//! wide node tests, `prims` the primitives of the leaves reached (real triangles, not
//! padding lanes), `quadrics` the quadric tests.

pub mod collapse;
pub mod walk_1;
#[cfg(target_arch = "x86_64")]
pub(crate) mod walk_x16;
pub mod walk_x8;

use wide::f32x8;

use super::memory::prefetch_lines;
use super::slot::{Slot, SlotRef};
use super::{Bvh, STACK_SIZE};
use crate::geometry::PrimKind;
pub use crate::geometry::triangle::TriBlock;

/// Largest binary subtree (in primitives of one kind) collapsed into one leaf.
pub const MERGE_MAX: u32 = 16;

/// A node of the 8-wide tree. 256 B = four cache lines, 64-byte aligned.
///
/// `bounds[2a]` / `bounds[2a + 1]`: the low / high bounds of the eight child boxes on
/// axis a (x, y, z), lane i = slot i. Empty slots have lo = +∞, hi = −∞: with the near
/// plane picked by the sign of the direction (never min/max), their entry is +∞ and
/// their exit −∞, so they never hit. Slots are filled from 0 without gaps.
/// `slot[i]` interior: `child[i]` is the index of its [`WideNode`]; a leaf:
/// `child[i]` is its first [`TriBlock`] for triangles, its first primitive of its kind
/// in the `PrimSet` otherwise.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
pub struct WideNode {
    pub bounds: [f32x8; 6],
    pub child: [u32; 8],
    pub slot: [Slot; 8],
}

const _: () = assert!(std::mem::size_of::<WideNode>() == 256);

impl WideNode {
    /// Slot `s` and its child.
    #[inline(always)]
    pub fn get(&self, s: usize) -> SlotRef {
        SlotRef {
            child: self.child[s],
            slot: self.slot[s],
        }
    }

    /// A node of eight empty slots.
    pub fn empty() -> WideNode {
        let lo = f32x8::splat(f32::INFINITY);
        let hi = f32x8::splat(f32::NEG_INFINITY);
        WideNode {
            bounds: [lo, hi, lo, hi, lo, hi],
            child: [0; 8],
            slot: [Slot::INTERIOR; 8],
        }
    }
}

/// The 8-wide tree over the same primitives as the binary one; its triangle leaves
/// name blocks of `PrimSet::blocks`, the primitive codes it reports index `PrimSet`.
#[derive(Clone, Debug, Default)]
pub struct WideBvh {
    pub nodes: Vec<WideNode>,
    /// Per block (the same index), each lane's binary leaf box, in the layout of
    /// [`WideNode::bounds`] (padding lanes empty). Apart from the blocks: the frustum
    /// walks read them for every block they reach (which triangles some lane may
    /// hit), the single-ray walks only for a hit that misses its triangle's own box
    /// (`walk_1::BoxRay::leaf_lanes`), so the blocks they walk lie closer.
    pub leaf_boxes: Vec<[f32x8; 6]>,
    /// Length of the diagonal of the root box (0 when empty): the packet walk's origin
    /// spread limit scales with it (`walk_x8::Frustum::new`).
    pub diagonal: f32,
    /// Whether the single-ray walks prefetch the children they are about to visit:
    /// only in trees larger than [`PREFETCH_FROM`] (a smaller tree stays in the cache,
    /// and the prefetches would be instructions and mispredicted loop exits for
    /// nothing). The frustum walks always prefetch the children they push.
    pub prefetches: bool,
    /// Whether a stream's closest-hit walks are stepped in turn (`Bvh::intersect_stream`):
    /// in trees of at least [`STREAM_FROM`] bytes walked; in smaller ones they run one
    /// after another.
    pub stream_steps: bool,
    /// The same for a stream's any-hit walks, from [`STREAM_ANY_HIT_FROM`].
    pub stream_any_hit_steps: bool,
}

/// Size of the walked arrays (wide nodes and triangle blocks) from which the
/// single-ray walks prefetch children: incoherent single rays on tori of 6 000
/// triangles (0.3 MiB walked) run faster without, from 10 000 (0.6 MiB) with
/// (`benches/README.md`; measured with the leaf boxes inside the blocks, of which the
/// walks read the same five lines: the sizes here leave the leaf boxes out, and each
/// limit puts the same trees on the same side).
pub const PREFETCH_FROM: usize = 480 << 10;

/// Size of the walked arrays from which a stream's closest-hit walks are stepped in turn.
/// Incoherent rays, stepped stream over one walk after another (`mode=1`): tori of 6k,
/// 20k and 40k triangles (up to 2.4 MB walked) 0.92, 0.87 and 0.94; torus100k (6.4 MB)
/// 1.09; over the better of `mode=1` and `mode=16`, torus1m 1.12 (`benches/README.md`).
/// On a host with 2 MiB of L2 per core.
pub const STREAM_FROM: usize = 3840 << 10;

/// [`STREAM_FROM`] for any-hit walks, which mostly end early: incoherent shadow rays
/// on tori of 100k, 300k, 700k and 1M triangles ran 0.94, 1.00, 1.13 and 1.25 of one
/// walk after another.
pub const STREAM_ANY_HIT_FROM: usize = 15 << 20;

/// Depth limit of the wide traversal stacks: the wide tree is never deeper than the
/// binary one (< [`STACK_SIZE`]), and a node leaves at most 7 entries on the stack.
pub(super) const WIDE_STACK: usize = 7 * STACK_SIZE + 1;

impl Bvh {
    /// Asks for a child's node or first triangle block (`boxes`: and its leaf boxes) to
    /// be brought into the cache: the slab test reads the box lines, then the child or
    /// triangle lines, each a miss of its own on incoherent rays without this. Without
    /// `boxes` (the single-ray walks), the address is picked, not branched on by the
    /// child's kind (its node's four lines, or its block's five; a leaf of another kind
    /// gets a block's address that no walk reads, and a prefetch never faults): torus100k
    /// incoherent `1s` 4.97–5.04 → 5.21–5.33 Mrays/s, 5 interleaved rounds.
    #[inline(always)]
    pub(super) fn prefetch(&self, r: SlotRef, boxes: bool) {
        #[cfg(target_arch = "x86_64")]
        if !boxes {
            use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
            let c = r.child as usize;
            let interior = r.slot.is_interior();
            let node = self.wide.nodes.as_ptr().wrapping_add(c).cast::<i8>();
            let block = self.prims.blocks.as_ptr().wrapping_add(c).cast::<i8>();
            let p = if interior { node } else { block };
            // a node's four lines (the first again), a block's five
            let fifth = if interior { 0 } else { 256 };
            // SAFETY: SSE is part of x86-64; a prefetch never faults or writes, whatever
            // the address. (Written out here: through a helper taking the address and
            // the offset, the walks ran 0.95 of this.)
            unsafe {
                _mm_prefetch::<_MM_HINT_T0>(p);
                _mm_prefetch::<_MM_HINT_T0>(p.wrapping_add(64));
                _mm_prefetch::<_MM_HINT_T0>(p.wrapping_add(128));
                _mm_prefetch::<_MM_HINT_T0>(p.wrapping_add(192));
                _mm_prefetch::<_MM_HINT_T0>(p.wrapping_add(fifth));
            }
            return;
        }
        if r.slot.is_interior() {
            if let Some(n) = self.wide.nodes.get(r.child as usize) {
                prefetch_lines(n);
            }
        } else if r.slot.holds(PrimKind::Triangle)
            && let Some(b) = self.prims.blocks.get(r.child as usize)
        {
            prefetch_lines(b);
            if boxes && let Some(lb) = self.wide.leaf_boxes.get(r.child as usize) {
                prefetch_lines(lb);
            }
        }
    }

    /// The single-ray closest-hit walk's [`Bvh::prefetch`] of the children `bits` of
    /// `node`, in a loop of its own: only in trees that need it ([`WideBvh::prefetches`]).
    /// (The other walks prefetch in their push pass.)
    #[inline(always)]
    pub(super) fn prefetch_children_1(&self, node: &WideNode, mut bits: u32) {
        if self.wide.prefetches {
            while bits != 0 {
                let s = bits.trailing_zeros() as usize;
                bits &= bits - 1;
                self.prefetch(node.get(s), false);
            }
        }
    }

    /// Bytes of the arrays the single-ray walks read: the wide nodes and the triangle
    /// blocks (not their leaf boxes).
    pub fn walked_bytes(&self) -> usize {
        walked_bytes(&self.wide.nodes, &self.prims.blocks)
    }
}

/// [`Bvh::walked_bytes`] of these arrays.
pub(super) fn walked_bytes(nodes: &[WideNode], blocks: &[TriBlock]) -> usize {
    std::mem::size_of_val(nodes) + std::mem::size_of_val(blocks)
}

impl WideBvh {
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
                if valid && n.slot[s].is_interior() {
                    stack.push((n.child[s] as usize, d + 1));
                }
            }
        }
        best
    }

    /// Of a node's hit children (`first`, then the slots in `bits`), pushes all but the
    /// nearest by entry distance `near` onto `stack`, farthest first (keys: the
    /// distance's bits, >= 0 so ordered as integers, then the slot; insertion sort, at
    /// most 8), and returns the nearest, to visit next. Shared by the single-ray and the
    /// frustum packet walks. `prefetch`: the tree (and whether with the blocks' leaf
    /// boxes) whose [`Bvh::prefetch`] each child gets as the pass meets it (the
    /// frustum walks), or `None` (the single-ray walk prefetches its hit children in a
    /// loop of their own, before: folded in here it ran 0.98–0.99).
    #[inline(always)]
    pub(super) fn push_ordered(
        node: &WideNode,
        near: f32x8,
        first: usize,
        mut bits: u32,
        prefetch: Option<(&Bvh, bool)>,
        stack: &mut super::slot::Stack<Pending, WIDE_STACK>,
    ) -> SlotRef {
        let nd = near.to_array();
        let key = |s: usize| ((nd[s].to_bits() & 0x7fff_ffff) as u64) << 32 | s as u64;
        let fetch = |s: usize| {
            if let Some((w, boxes)) = prefetch {
                w.prefetch(node.get(s), boxes);
            }
        };
        fetch(first);
        if bits & (bits - 1) == 0 {
            // two: the nearer next, the other pushed (the same order as the keys give)
            let second = bits.trailing_zeros() as usize;
            fetch(second);
            let (near_s, far_s) = if key(second) < key(first) {
                (second, first)
            } else {
                (first, second)
            };
            stack.push(Pending {
                to: node.get(far_s),
                near: f32::from_bits(nd[far_s].to_bits() & 0x7fff_ffff),
            });
            return node.get(near_s);
        }
        let mut keys = [0u64; 8];
        keys[0] = key(first);
        let mut n = 1;
        while bits != 0 {
            let s = bits.trailing_zeros() as usize;
            bits &= bits - 1;
            fetch(s);
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
            stack.push(Pending {
                to: node.get((k & 0xff) as usize),
                near: f32::from_bits((k >> 32) as u32),
            });
        }
        node.get((keys[n - 1] & 0xff) as usize)
    }

    /// Pushes a node's hit children `bits` for an any-hit walk: the interior child met
    /// farthest away (entry distance `near`) after the other interior children, to be
    /// visited first of them; the leaves with `leaves_last` after every interior child
    /// (tested first: the single-ray walks), else as met among the interior ones (the
    /// frustum walks, which measured the same either way). No sort, one pass over the
    /// slots. A shadow ray leaves a surface: the subtrees around its origin hold that
    /// surface, which it has left, and a blocker lies farther on (figures in
    /// benches/README.md: the order changes no answer, only how soon a walk ends).
    /// `prefetch`: the tree (and whether with the blocks' leaf boxes) whose
    /// [`Bvh::prefetch`] each pushed child gets in the same pass, or `None`.
    #[inline(always)]
    pub(super) fn push_any_hit(
        node: &WideNode,
        near: f32x8,
        mut bits: u32,
        leaves_last: bool,
        prefetch: Option<(&Bvh, bool)>,
        stack: &mut super::slot::Stack<SlotRef, WIDE_STACK>,
    ) {
        let nd = near.to_array();
        let (mut far, mut far_t) = (None, f32::NEG_INFINITY);
        let mut leaves = 0u32;
        while bits != 0 {
            let s = bits.trailing_zeros() as usize;
            bits &= bits - 1;
            let child = node.get(s);
            if let Some((w, boxes)) = prefetch {
                w.prefetch(child, boxes);
            }
            if !child.slot.is_interior() && leaves_last {
                leaves |= 1 << s;
            } else if child.slot.is_interior() && nd[s] > far_t {
                if let Some(f) = far {
                    stack.push(node.get(f));
                }
                (far, far_t) = (Some(s), nd[s]);
            } else {
                stack.push(child);
            }
        }
        if let Some(f) = far {
            stack.push(node.get(f));
        }
        while leaves != 0 {
            let s = leaves.trailing_zeros() as usize;
            leaves &= leaves - 1;
            stack.push(node.get(s));
        }
    }
}

/// A child left on the stack of an ordered walk, with the entry distance it was met at
/// (skipped when popped behind the nearest hit).
#[derive(Clone, Copy, Debug)]
pub(super) struct Pending {
    pub to: SlotRef,
    pub near: f32,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::slot::Stack;

    /// Pops everything: the children in the order an any-hit walk visits them.
    fn visits(leaves_last: bool) -> Vec<u32> {
        let mut node = WideNode::empty();
        // slots 0–5: interior, leaf, interior, interior, leaf, interior; child = slot
        for s in 0..6 {
            node.child[s] = s as u32;
            node.slot[s] = if s == 1 || s == 4 {
                Slot::leaf(PrimKind::Triangle, 3)
            } else {
                Slot::INTERIOR
            };
        }
        let near = f32x8::new([0.5, 9.0, 2.0, 7.0, 1.0, 3.0, 0.0, 0.0]);
        // slot 5 missed
        let mut stack = Stack::<SlotRef, WIDE_STACK>::new();
        WideBvh::push_any_hit(&node, near, 0b01_1111, leaves_last, None, &mut stack);
        std::iter::from_fn(|| stack.pop().map(|r| r.child)).collect()
    }

    #[test]
    fn an_any_hit_walk_visits_the_farthest_interior_child_first() {
        // interior 0, 2, 3 met at 0.5, 2 and 7, leaves 1 and 4
        let sorted = |v: &[u32]| {
            let mut v = v.to_vec();
            v.sort();
            v
        };
        let v = visits(true);
        assert_eq!(sorted(&v[..2]), [1, 4], "the leaves first: {v:?}");
        assert_eq!(v[2], 3, "then the farthest interior child: {v:?}");
        assert_eq!(sorted(&v), [0, 1, 2, 3, 4]);
        let v = visits(false);
        assert_eq!(v[0], 3, "the farthest interior child first: {v:?}");
        assert_eq!(sorted(&v), [0, 1, 2, 3, 4]);
    }
}
