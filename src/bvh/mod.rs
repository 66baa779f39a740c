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

/// `$recv.$method::<T, K>(args)` for the constant `K` among `$n...` equal to `$k`:
/// picks the const instance of a walk (a direction octant, a permutation axis) once
/// per query. Every value of `$k` must be listed.
macro_rules! with_const {
    ($k:expr, [$($n:literal),+], $recv:ident.$method:ident::<$t:ident> $args:tt) => {
        match $k {
            $($n => $recv.$method::<$t, $n> $args,)+
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
    pub nodes: Vec<BvhNode>,
    pub prims: PrimSet,
    /// The same tree collapsed to 8 children per node, for single rays.
    pub wide: wide::WideBvh,
}

impl Bvh {
    /// Builds the tree (binned SAH) over the bounded primitives of `prims`,
    /// reordering them into leaf order (the triangles into blocks of eight,
    /// `PrimSet::blocks`). Validated in debug builds.
    pub fn build(mut prims: PrimSet) -> Bvh {
        let (nodes, order) = build::build(&mut prims);
        let wide = wide::WideBvh::collapse(&nodes, &mut prims, order);
        let bvh = Bvh { nodes, prims, wide };
        #[cfg(debug_assertions)]
        if let Err(e) = bvh.validate() {
            panic!("BVH invariant broken: {e}");
        }
        bvh
    }

    /// The SAH cost of the tree: Σ over nodes of A(node)/A(root) times
    /// C_T for an interior node and C_I · n for a leaf (C_I = 1).
    pub fn sah_cost(&self) -> f64 {
        let Some(root) = self.nodes.first() else {
            return 0.0;
        };
        let ra = root.bounds().area().max(f32::MIN_POSITIVE) as f64;
        self.nodes
            .iter()
            .map(|n| {
                let w = n.bounds().area() as f64 / ra;
                if n.is_leaf() {
                    w * n.count() as f64
                } else {
                    w * build::C_TRAVERSE as f64
                }
            })
            .sum()
    }

    /// Depth of the deepest leaf (root = 1).
    pub fn depth(&self) -> usize {
        fn go(b: &Bvh, i: usize) -> usize {
            let n = &b.nodes[i];
            if n.is_leaf() {
                1
            } else {
                1 + go(b, n.first as usize).max(go(b, n.first as usize + 1))
            }
        }
        if self.nodes.is_empty() {
            0
        } else {
            go(self, 0)
        }
    }
}
