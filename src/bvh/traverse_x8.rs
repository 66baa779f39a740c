//! Packet traversal: eight rays walk the tree together with an active mask.
//!
//! Ordered, depth first: at an interior node the child on the near side of the split
//! axis (by the sign of the first active lane's direction) is visited first. A node's
//! box is tested when it is popped, against the lanes still active and each lane's
//! current nearest hit, so subtrees behind every lane's hit are skipped.

use wide::f32x8;

use super::{Bvh, STACK_SIZE, Steps};
use crate::geometry::PrimKind;
use crate::math::packet::{HitPacket8, Mask8, RayPacket8};

impl Bvh {
    /// Nearest hit of each active lane, below the lane's current `hit.t`, recorded in `hit`.
    pub fn intersect_x8(
        &self,
        r: &RayPacket8,
        active: Mask8,
        hit: &mut HitPacket8,
        steps: &mut Steps,
    ) {
        if active.none() {
            return;
        }
        if !self.nodes.is_empty() {
            let mut stack = [0u32; STACK_SIZE];
            let mut sp = 1;
            while sp > 0 {
                sp -= 1;
                let node = &self.nodes[stack[sp] as usize];
                steps.boxes += 1;
                let m = node.intersect_x8(r, active, hit.t);
                if m.none() {
                    continue;
                }
                if node.is_leaf() {
                    let count = node.count() as usize;
                    steps.prims += count as u64;
                    if node.kind() == PrimKind::Quadric {
                        steps.quadrics += (count * m.count() as usize) as u64;
                    }
                    self.prims
                        .intersect_x8(node.kind(), node.first as usize, count, r, m, hit);
                } else {
                    let far_first = r.octant >> node.axis() & 1;
                    stack[sp] = node.first + (1 - far_first);
                    stack[sp + 1] = node.first + far_first;
                    sp += 2;
                }
            }
        }
        self.intersect_beside_x8(r, active, hit, steps);
    }

    /// The unbounded quadrics, then the floor.
    #[inline]
    fn intersect_beside_x8(
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
                .intersect_x8(PrimKind::FreeQuadric, 0, nq, r, active, hit);
        }
        if self.prims.floor.is_some() {
            steps.prims += 1;
            self.prims
                .intersect_x8(PrimKind::Floor, 0, 1, r, active, hit);
        }
    }

    /// The lanes of `active` whose ray is blocked by anything with 0 < t < t_max
    /// (any hit: a lane leaves the query at its first blocker).
    pub fn occluded_x8(
        &self,
        r: &RayPacket8,
        active: Mask8,
        t_max: f32x8,
        steps: &mut Steps,
    ) -> Mask8 {
        let mut left = active;
        // the floor and the unbounded list first: one cheap test that often settles it
        if self.prims.floor.is_some() {
            steps.prims += 1;
            left = left.and_not(
                self.prims
                    .occluded_x8(PrimKind::Floor, 0, 1, r, left, t_max),
            );
        }
        let nq = self.prims.free_quadrics.len();
        if nq > 0 && left.any() {
            steps.prims += nq as u64;
            steps.quadrics += (nq * left.count() as usize) as u64;
            left =
                left.and_not(
                    self.prims
                        .occluded_x8(PrimKind::FreeQuadric, 0, nq, r, left, t_max),
                );
        }
        if !self.nodes.is_empty() && left.any() {
            let mut stack = [0u32; STACK_SIZE];
            let mut sp = 1;
            while sp > 0 {
                sp -= 1;
                let node = &self.nodes[stack[sp] as usize];
                steps.boxes += 1;
                let m = node.intersect_x8(r, left, t_max);
                if m.none() {
                    continue;
                }
                if node.is_leaf() {
                    let count = node.count() as usize;
                    steps.prims += count as u64;
                    if node.kind() == PrimKind::Quadric {
                        steps.quadrics += (count * m.count() as usize) as u64;
                    }
                    let blocked = self.prims.occluded_x8(
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
                    stack[sp] = node.first + (1 - far_first);
                    stack[sp + 1] = node.first + far_first;
                    sp += 2;
                }
            }
        }
        active.and_not(left)
    }
}
