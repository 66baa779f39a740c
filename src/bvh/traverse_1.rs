//! Single-ray traversal of the binary tree: the baseline the packet path and the
//! 8-wide single-ray path (`wide/walk_1.rs`, behind `Bvh::intersect_1`) are measured against,
//! and the wide path's test oracle.
//!
//! Ordered, depth first: at an interior node both children's boxes are tested; the
//! nearer is visited first and the farther pushed with its entry distance, skipped
//! when popped if a nearer hit has been found meanwhile.

use super::slot::Stack;
use super::{Bvh, STACK_SIZE, Steps};
use crate::geometry::triangle::TriangleKernel;
use crate::geometry::{Hit1, PrimKind};
use crate::math::packet::Ray1;

impl Bvh {
    /// Nearest hit below `hit.t`, recorded in `hit`.
    pub fn intersect_1_binary<T: TriangleKernel>(
        &self,
        r: &Ray1,
        hit: &mut Hit1,
        steps: &mut Steps,
    ) {
        self.binary_walked();
        if let Some(root) = self.nodes.first() {
            steps.boxes += 1;
            if root.intersect_1(r, hit.t).is_some() {
                let mut stack = Stack::<(u32, f32), STACK_SIZE>::new();
                let mut ni = 0usize;
                loop {
                    let node = &self.nodes[ni];
                    if node.is_leaf() {
                        let count = node.count() as usize;
                        steps.leaf(node.kind(), count, 1);
                        self.prims.intersect_1::<T>(
                            node.kind(),
                            node.first as usize,
                            count,
                            r,
                            hit,
                        );
                    } else {
                        let l = node.first as usize;
                        steps.boxes += 2;
                        let hl = self.nodes[l].intersect_1(r, hit.t);
                        let hr = self.nodes[l + 1].intersect_1(r, hit.t);
                        match (hl, hr) {
                            (Some(tl), Some(tr)) => {
                                let (near, far, tf) = if tl <= tr {
                                    (l, l + 1, tr)
                                } else {
                                    (l + 1, l, tl)
                                };
                                stack.push((far as u32, tf));
                                ni = near;
                                continue;
                            }
                            (Some(_), None) => {
                                ni = l;
                                continue;
                            }
                            (None, Some(_)) => {
                                ni = l + 1;
                                continue;
                            }
                            (None, None) => {}
                        }
                    }
                    // pop the next subtree still in front of the nearest hit
                    let mut next = None;
                    while let Some((n, t)) = stack.pop() {
                        if t <= hit.t {
                            next = Some(n as usize);
                            break;
                        }
                    }
                    match next {
                        Some(n) => ni = n,
                        None => break,
                    }
                }
            }
        }
        self.intersect_beside_1::<T>(r, hit, steps);
    }

    /// Whether anything lies on the ray with 0 < t < t_max.
    pub fn occluded_1_binary<T: TriangleKernel>(
        &self,
        r: &Ray1,
        t_max: f32,
        steps: &mut Steps,
    ) -> bool {
        self.binary_walked();
        if self.occluded_beside_1::<T>(r, t_max, steps) {
            return true;
        }
        if self.nodes.is_empty() {
            return false;
        }
        let mut stack = Stack::<u32, STACK_SIZE>::new();
        stack.push(0);
        while let Some(ni) = stack.pop() {
            let node = &self.nodes[ni as usize];
            steps.boxes += 1;
            if node.intersect_1(r, t_max).is_none() {
                continue;
            }
            if node.is_leaf() {
                let count = node.count() as usize;
                steps.leaf(node.kind(), count, 1);
                if self
                    .prims
                    .occluded_1::<T>(node.kind(), node.first as usize, count, r, t_max)
                {
                    return true;
                }
            } else {
                stack.push(node.first);
                stack.push(node.first + 1);
            }
        }
        false
    }

    /// The primitives beside the tree, closest hit: unbounded quadrics, then the floor
    /// (after the tree, so an exact tie keeps the tree's lower object index).
    #[inline]
    pub(crate) fn intersect_beside_1<T: TriangleKernel>(
        &self,
        r: &Ray1,
        hit: &mut Hit1,
        steps: &mut Steps,
    ) {
        let nq = self.prims.free_quadrics.len();
        if nq > 0 {
            steps.prims += nq as u64;
            steps.quadrics += nq as u64;
            self.prims
                .intersect_1::<T>(PrimKind::FreeQuadric, 0, nq, r, hit);
        }
        if self.prims.floor.is_some() {
            steps.prims += 1;
            self.prims.intersect_1::<T>(PrimKind::Floor, 0, 1, r, hit);
        }
    }

    /// Whether the floor or an unbounded quadric blocks the ray before `t_max` (tested
    /// before the tree: one plane test often settles a shadow ray).
    #[inline]
    pub(crate) fn occluded_beside_1<T: TriangleKernel>(
        &self,
        r: &Ray1,
        t_max: f32,
        steps: &mut Steps,
    ) -> bool {
        if self.prims.floor.is_some() {
            steps.prims += 1;
            if self.prims.occluded_1::<T>(PrimKind::Floor, 0, 1, r, t_max) {
                return true;
            }
        }
        let nq = self.prims.free_quadrics.len();
        if nq > 0 {
            steps.prims += nq as u64;
            steps.quadrics += nq as u64;
            if self
                .prims
                .occluded_1::<T>(PrimKind::FreeQuadric, 0, nq, r, t_max)
            {
                return true;
            }
        }
        false
    }
}
