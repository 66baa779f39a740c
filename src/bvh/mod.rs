//! The bounding volume hierarchy of the fast path, and the short list beside it.
//!
//! [`Bvh`] owns a [`PrimSet`]: its bounded kinds (spheres, triangles, quadrics with
//! finite bounds) sit in a binned-SAH tree ([`build`]); quadrics without finite bounds
//! and the floor are tested after the tree, in that order, on every query. Queries come in two widths with the same contract:
//! [`Bvh::intersect_x8`]/[`Bvh::occluded_x8`] for packets and
//! [`Bvh::intersect_1`]/[`Bvh::occluded_1`] for single rays, which walk an 8-wide tree
//! collapsed from the binary one ([`wide`]); the binary single-ray walk stays as
//! [`Bvh::intersect_1_binary`]/[`Bvh::occluded_1_binary`] (benches, test oracle).
//!
//! Edge rules: a hit counts iff 0 < t < t_max; an exact tie in t goes to the lower
//! object index (file order), then the lower primitive, the floor last
//! (`PrimSet::record_1`); shadow (any-hit) queries stop at the first blocker. Every
//! query is generic over the triangle test (`TriangleKernel`).

/// `$recv.$method::<T, K>(args)` (or `::<T, C, K>` for a constant `C` given) for the
/// constant `K` among `$n...` equal to `$k`: picks the const instance of a walk (a
/// direction octant, a permutation axis) once per query. Every value of `$k` must be
/// listed.
macro_rules! with_const {
    ($k:expr, [$($n:literal),+], $recv:ident.$method:ident::<$t:ident> $args:tt) => {
        match $k {
            $($n => $recv.$method::<$t, $n> $args,)+
            _ => unreachable!("no const instance for this value"),
        }
    };
    ($k:expr, [$($n:literal),+], $recv:ident.$method:ident::<$t:ident, $c:literal> $args:tt) => {
        match $k {
            $($n => $recv.$method::<$t, $c, $n> $args,)+
            _ => unreachable!("no const instance for this value"),
        }
    };
}

pub mod bench;
pub mod build;
pub mod memory;
pub mod node;
pub mod slot;
pub mod traverse_1;
pub mod traverse_x8;
pub mod validate;
pub mod wide;

pub use node::BvhNode;
pub use slot::Slot;

use crate::geometry::{PrimKind, PrimSet};
use wide::walk_x8::WIDE_PACKET_MIN_NODES;

/// Depth limit of the traversal stacks; the builder keeps the tree below it (SAH
/// splits to depth 48, then halvings: at most 48 + 28 levels for 2²⁸ primitives).
pub const STACK_SIZE: usize = 96;

/// Traversal counters (design item 11): box tests and primitive tests.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Steps {
    pub boxes: u64,
    pub prims: u64,
    /// Ray–quadric tests, per ray (per active lane in packets): zero in a scene
    /// without quadrics (`RenderStats::quadric_tests`).
    pub quadrics: u64,
}

impl Steps {
    /// Counts a leaf of `count` primitives of `kind` met by `lanes` rays: primitive
    /// tests per query, quadric tests per ray.
    #[inline(always)]
    pub fn leaf(&mut self, kind: PrimKind, count: usize, lanes: u32) {
        self.prims += count as u64;
        if kind == PrimKind::Quadric {
            self.quadrics += (count * lanes as usize) as u64;
        }
    }
}

/// A BVH over a primitive set, with the unbounded primitives beside it.
#[derive(Clone, Debug)]
pub struct Bvh {
    /// The binary tree. Kept where packets walk it (a wide tree of fewer than
    /// [`WIDE_PACKET_MIN_NODES`] nodes) or when asked for ([`Bvh::build_with_binary`]:
    /// the benches' binary modes, the tests' oracle); else empty, every query then
    /// through the wide tree. It goes inside the collapse, before the blocks are
    /// written ([`wide::WideBvh::collapse`]).
    pub nodes: Vec<BvhNode>,
    /// The binary tree's root, kept with or without the tree: its box is every packet
    /// walk's first test ([`Bvh::enter_x8`]). `None` for a tree of nothing.
    pub root: Option<BvhNode>,
    pub prims: PrimSet,
    /// The same tree collapsed to 8 children per node, for single rays.
    pub wide: wide::WideBvh,
}

impl Bvh {
    /// Builds the tree (binned SAH) over the bounded primitives of `prims`,
    /// reordering them into leaf order (the triangles into blocks of eight,
    /// `PrimSet::blocks`), and keeps the binary tree only where packets walk it.
    /// Validated in debug builds.
    pub fn build(prims: PrimSet) -> Bvh {
        Self::build_keeping(prims, false)
    }

    /// [`Bvh::build`], keeping the binary tree whatever the wide tree's size, for its
    /// walks (`intersect_1_binary`, `intersect_x8_binary` and their any-hit twins).
    pub fn build_with_binary(prims: PrimSet) -> Bvh {
        Self::build_keeping(prims, true)
    }

    fn build_keeping(mut prims: PrimSet, keep_binary: bool) -> Bvh {
        let (nodes, order) = build::build(&mut prims);
        let root = nodes.first().copied();
        // (a debug build keeps the binary tree until it is validated)
        let keep = keep_binary || cfg!(debug_assertions);
        let (wide, nodes) = wide::WideBvh::collapse(nodes, &mut prims, order, keep);
        #[allow(unused_mut)]
        let mut bvh = Bvh {
            nodes,
            root,
            prims,
            wide,
        };
        #[cfg(debug_assertions)]
        {
            if let Err(e) = bvh.validate() {
                panic!("BVH invariant broken: {e}");
            }
            if !keep_binary && !bvh.packets_walk_binary() {
                bvh.nodes = Vec::new();
            }
        }
        bvh
    }

    /// Whether packets walk the binary tree ([`Bvh::intersect_x8`]): in a tree whose
    /// wide one is too small for the packet walks.
    pub fn packets_walk_binary(&self) -> bool {
        self.wide.nodes.len() < WIDE_PACKET_MIN_NODES
    }

    /// Panics unless the binary tree is here for its walks (a tree of nothing has none
    /// to walk).
    #[inline]
    fn binary_walked(&self) {
        assert!(
            !self.nodes.is_empty() || self.root.is_none(),
            "the binary walks need the binary tree (Bvh::build_with_binary)"
        );
    }
}

/// Size, depth and SAH cost of a binary tree.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BinaryStats {
    pub nodes: usize,
    /// Of the deepest leaf (root = 1).
    pub depth: usize,
    /// Σ over nodes of A(node)/A(root) times C_T for an interior node and C_I · n for
    /// a leaf (C_I = 1).
    pub sah_cost: f64,
}

impl BinaryStats {
    pub fn of(nodes: &[BvhNode]) -> BinaryStats {
        let Some(root) = nodes.first() else {
            return BinaryStats::default();
        };
        let ra = root.bounds().area().max(f32::MIN_POSITIVE) as f64;
        let sah_cost = nodes
            .iter()
            .map(|n| {
                let w = n.bounds().area() as f64 / ra;
                if n.is_leaf() {
                    w * n.count() as f64
                } else {
                    w * build::C_TRAVERSE as f64
                }
            })
            .sum();
        fn depth(nodes: &[BvhNode], i: usize) -> usize {
            let n = &nodes[i];
            if n.is_leaf() {
                1
            } else {
                1 + depth(nodes, n.first as usize).max(depth(nodes, n.first as usize + 1))
            }
        }
        BinaryStats {
            nodes: nodes.len(),
            depth: depth(nodes, 0),
            sah_cost,
        }
    }
}
