//! Binned SAH build (Wald 2007): a flat node array, children of a node adjacent,
//! leaves of one primitive kind.
//!
//! Each split tries `BINS` bins per axis over the centroid bounds and takes the
//! cheapest by the surface area heuristic, cost = C_T + Σ A(child)/A(node) · C_I · n;
//! a range becomes a leaf when that is not cheaper than C_I · n and n <= `MAX_LEAF`.
//! A range whose centroids all coincide is halved. A leaf with several kinds is
//! split by kind. Beyond depth `MEDIAN_DEPTH` splits are halvings, so the depth stays
//! below the traversal stack size.

use glam::Vec3A;

use super::node::{Aabb, BvhNode};
use crate::geometry::{PrimKind, PrimSet};

/// Bins per axis.
const BINS: usize = 16;
/// Largest leaf (primitives).
pub const MAX_LEAF: usize = 8;
/// Cost of one box test relative to one primitive test.
pub const C_TRAVERSE: f32 = 1.0;
/// Depth past which ranges are halved instead of SAH-split.
const MEDIAN_DEPTH: usize = 48;

/// A primitive reference during the build: bounds and (kind, index) packed.
#[derive(Clone, Copy, Debug)]
struct Ref {
    lo: Vec3A,
    hi: Vec3A,
    kind: u32,
    index: u32,
}

impl Ref {
    #[inline]
    fn centroid2(&self) -> Vec3A {
        self.lo + self.hi
    }
}

#[derive(Clone, Copy)]
struct Bin {
    lo: Vec3A,
    hi: Vec3A,
    n: u32,
}

impl Bin {
    const EMPTY: Bin = Bin {
        lo: Vec3A::splat(f32::INFINITY),
        hi: Vec3A::splat(f32::NEG_INFINITY),
        n: 0,
    };
}

fn area(lo: Vec3A, hi: Vec3A) -> f32 {
    let d = (hi - lo).max(Vec3A::ZERO);
    2.0 * (d.x * d.y + d.y * d.z + d.z * d.x)
}

/// Builds the node array over the BVH kinds of `prims` and reorders those kinds'
/// arrays into leaf order. Returns the nodes (empty when there is nothing to bound).
pub fn build(prims: &mut PrimSet) -> Vec<BvhNode> {
    let mut refs =
        Vec::with_capacity(prims.spheres.len() + prims.triangles.len() + prims.quadrics.len());
    for kind in PrimKind::BVH_KINDS {
        for i in 0..prims.len(kind) {
            let b = prims.bounds(kind, i);
            refs.push(Ref {
                lo: b.lo.into(),
                hi: b.hi.into(),
                kind: kind as u32,
                index: i as u32,
            });
        }
    }
    if refs.is_empty() {
        return Vec::new();
    }
    let mut nodes = Vec::with_capacity(refs.len() / 2 + 1);
    nodes.push(BvhNode::interior(Aabb::EMPTY, 0, 0));
    // leaves as (node, start, end) in refs; their `first` is fixed after reordering
    let mut leaves: Vec<(u32, u32, u32)> = Vec::new();
    let mut tasks = vec![(0u32, 0usize, refs.len(), 0usize)];
    while let Some((ni, start, end, depth)) = tasks.pop() {
        let part = &mut refs[start..end];
        let (mut lo, mut hi) = (Vec3A::splat(f32::INFINITY), Vec3A::splat(f32::NEG_INFINITY));
        let (mut clo, mut chi) = (lo, hi);
        for r in part.iter() {
            lo = lo.min(r.lo);
            hi = hi.max(r.hi);
            let c = r.centroid2();
            clo = clo.min(c);
            chi = chi.max(c);
        }
        let bounds = Aabb::new(lo.into(), hi.into());
        let n = part.len();
        let mixed = n <= MAX_LEAF && part.iter().any(|r| r.kind != part[0].kind);
        let widest = widest_axis(chi - clo);
        let (mid, axis) = match choose_split(part, lo, hi, clo, chi, depth) {
            Split::Leaf if !mixed => {
                leaves.push((ni, start as u32, end as u32));
                let kind = PrimKind::from_u32(part[0].kind);
                nodes[ni as usize] = BvhNode::leaf(bounds, 0, n as u32, kind);
                continue;
            }
            Split::Leaf => {
                // one kind per leaf: split off the first kind
                let k = part[0].kind;
                (partition(part, |r| r.kind == k), widest)
            }
            Split::At(axis, bin, scale, base) => (
                partition(part, |r| bin_of(r.centroid2()[axis], base, scale) < bin),
                axis,
            ),
            Split::Half(axis) => {
                part.select_nth_unstable_by(n / 2, |a, b| {
                    a.centroid2()[axis].total_cmp(&b.centroid2()[axis])
                });
                (n / 2, axis)
            }
        };
        let mid = if mid == 0 || mid == n { n / 2 } else { mid };
        let left = nodes.len() as u32;
        nodes.push(BvhNode::interior(Aabb::EMPTY, 0, 0));
        nodes.push(BvhNode::interior(Aabb::EMPTY, 0, 0));
        nodes[ni as usize] = BvhNode::interior(bounds, left, axis);
        tasks.push((left + 1, start + mid, end, depth + 1));
        tasks.push((left, start, start + mid, depth + 1));
    }
    // reorder the BVH kinds into leaf order; each leaf is contiguous in its kind
    let mut p = PrimSet::default();
    leaves.sort_unstable_by_key(|l| l.1);
    for (ni, start, end) in leaves {
        let kind = PrimKind::from_u32(refs[start as usize].kind);
        nodes[ni as usize].first = p.len(kind) as u32;
        for r in &refs[start as usize..end as usize] {
            let i = r.index as usize;
            match kind {
                PrimKind::Sphere => {
                    p.spheres.push(prims.spheres[i]);
                    p.sphere_obj.push(prims.sphere_obj[i]);
                }
                PrimKind::Triangle => {
                    p.triangles.push(prims.triangles[i]);
                    p.triangle_obj.push(prims.triangle_obj[i]);
                }
                PrimKind::Quadric => {
                    p.quadrics.push(prims.quadrics[i]);
                    p.quadric_obj.push(prims.quadric_obj[i]);
                }
                PrimKind::FreeQuadric | PrimKind::Floor => unreachable!("not in the BVH"),
            }
        }
    }
    prims.spheres = p.spheres;
    prims.sphere_obj = p.sphere_obj;
    prims.triangles = p.triangles;
    prims.triangle_obj = p.triangle_obj;
    prims.quadrics = p.quadrics;
    prims.quadric_obj = p.quadric_obj;
    nodes
}

fn widest_axis(extent: Vec3A) -> usize {
    if extent.x >= extent.y && extent.x >= extent.z {
        0
    } else if extent.y >= extent.z {
        1
    } else {
        2
    }
}

enum Split {
    Leaf,
    /// Axis, first bin of the right side, bin scale, bin base.
    At(usize, usize, f32, f32),
    Half(usize),
}

#[inline]
fn bin_of(c: f32, base: f32, scale: f32) -> usize {
    (((c - base) * scale) as usize).min(BINS - 1)
}

fn choose_split(part: &[Ref], lo: Vec3A, hi: Vec3A, clo: Vec3A, chi: Vec3A, depth: usize) -> Split {
    let n = part.len();
    let extent = chi - clo;
    let widest = widest_axis(extent);
    if n <= 1 {
        return Split::Leaf;
    }
    if extent.max_element() <= 0.0 {
        return if n <= MAX_LEAF {
            Split::Leaf
        } else {
            Split::Half(widest)
        };
    }
    if depth >= MEDIAN_DEPTH {
        return Split::Half(widest);
    }
    let scale = Vec3A::splat(BINS as f32 * (1.0 - 1e-6)) / extent;
    let scale = Vec3A::select(extent.cmpgt(Vec3A::ZERO), scale, Vec3A::ZERO);
    let mut bins = [[Bin::EMPTY; BINS]; 3];
    for r in part {
        let c = r.centroid2();
        let b = ((c - clo) * scale).to_array();
        for axis in 0..3 {
            let k = (b[axis] as usize).min(BINS - 1);
            let bin = &mut bins[axis][k];
            bin.lo = bin.lo.min(r.lo);
            bin.hi = bin.hi.max(r.hi);
            bin.n += 1;
        }
    }
    let node_area = area(lo, hi).max(f32::MIN_POSITIVE);
    let mut best = (f32::INFINITY, 0, 0);
    for (axis, bins) in bins.iter().enumerate() {
        if extent[axis] <= 0.0 {
            continue;
        }
        // sweep from the right: cost of the right side of each boundary
        let mut right_cost = [0.0f32; BINS];
        let (mut rlo, mut rhi, mut rn) = (
            Vec3A::splat(f32::INFINITY),
            Vec3A::splat(f32::NEG_INFINITY),
            0u32,
        );
        for k in (1..BINS).rev() {
            rlo = rlo.min(bins[k].lo);
            rhi = rhi.max(bins[k].hi);
            rn += bins[k].n;
            right_cost[k] = if rn > 0 {
                area(rlo, rhi) * rn as f32
            } else {
                0.0
            };
        }
        let (mut llo, mut lhi, mut ln) = (
            Vec3A::splat(f32::INFINITY),
            Vec3A::splat(f32::NEG_INFINITY),
            0u32,
        );
        for k in 1..BINS {
            llo = llo.min(bins[k - 1].lo);
            lhi = lhi.max(bins[k - 1].hi);
            ln += bins[k - 1].n;
            if ln == 0 || ln as usize == n {
                continue;
            }
            let cost = area(llo, lhi) * ln as f32 + right_cost[k];
            if cost < best.0 {
                best = (cost, axis, k);
            }
        }
    }
    let split_cost = C_TRAVERSE + best.0 / node_area;
    if best.0.is_infinite() {
        return if n <= MAX_LEAF {
            Split::Leaf
        } else {
            Split::Half(widest)
        };
    }
    if n <= MAX_LEAF && split_cost >= n as f32 {
        return Split::Leaf;
    }
    let axis = best.1;
    Split::At(axis, best.2, scale[axis], clo[axis])
}

/// Moves the refs satisfying `left` to the front; returns their count.
fn partition(part: &mut [Ref], left: impl Fn(&Ref) -> bool) -> usize {
    let mut i = 0;
    let mut j = part.len();
    while i < j {
        if left(&part[i]) {
            i += 1;
        } else {
            j -= 1;
            part.swap(i, j);
        }
    }
    i
}
