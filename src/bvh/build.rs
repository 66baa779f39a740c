//! Binned SAH build (Wald 2007): a flat node array, children of a node adjacent,
//! leaves of one primitive kind.
//!
//! Each split tries `BINS` bins per axis over the centroid bounds and takes the
//! cheapest by the surface area heuristic, cost = C_T + Σ A(child)/A(node) · C_I · n;
//! a range becomes a leaf when that is not cheaper than C_I · n and n <= `MAX_LEAF`.
//! A range whose centroids all coincide is halved. A leaf with several kinds is
//! split by kind. Beyond depth `MEDIAN_DEPTH` splits are halvings, so the depth stays
//! below the traversal stack size.
//!
//! Work per node: one binning pass and one in-place partition pass over 32-byte
//! references (bounds with index and kind in the spare lanes). Above `SAMPLE`
//! references the partition computes both children's bounds and centroid bounds on
//! the way (the range streams from memory once); at or below, it is branchless and
//! the bounds are a second pass over the (cached) range. Ranges of two skip the bins.
//! Primitives are reordered into leaf order once, at the end, by one gather. Each pair
//! of children sits on one 64-byte cache line (node 1 may be an unreachable pad for
//! that). The large arrays are in huge pages (kernel page-fault work was ~20 % of a
//! perf profile of build and collapse before).

use glam::Vec4;
use wide::{f32x4, i32x4};

use super::node::{Aabb, BvhNode};
use super::wide::huge_vec;
use crate::geometry::{PrimKind, PrimSet};

/// Bins per axis.
const BINS: usize = 16;
/// Largest leaf (primitives).
pub const MAX_LEAF: usize = 8;
/// Cost of one box test relative to one primitive test.
pub const C_TRAVERSE: f32 = 1.0;
/// References binned per split at most (larger ranges are sampled evenly).
const SAMPLE: usize = 4096;
/// Depth past which ranges are halved instead of SAH-split.
const MEDIAN_DEPTH: usize = 48;

/// A primitive reference during the build, 32 bytes: `lo.w` holds the index's bits,
/// `hi.w` the kind's. Centroids are `lo + hi` (twice the centre; only the x, y, z
/// lanes are ever read).
#[derive(Clone, Copy, Debug)]
#[repr(C)]
struct Ref {
    lo: Vec4,
    hi: Vec4,
}

impl Ref {
    #[inline]
    fn index(&self) -> usize {
        self.lo.w.to_bits() as usize
    }
    #[inline]
    fn kind(&self) -> u32 {
        self.hi.w.to_bits()
    }
    #[inline]
    fn centroid2(&self) -> Vec4 {
        self.lo + self.hi
    }
}

/// Bounds and centroid bounds of a range (x, y, z lanes only).
#[derive(Clone, Copy, Debug)]
struct Bounds {
    lo: Vec4,
    hi: Vec4,
    clo: Vec4,
    chi: Vec4,
}

impl Bounds {
    const EMPTY: Bounds = Bounds {
        lo: Vec4::INFINITY,
        hi: Vec4::NEG_INFINITY,
        clo: Vec4::INFINITY,
        chi: Vec4::NEG_INFINITY,
    };

    #[inline]
    fn add(&mut self, r: &Ref) {
        self.lo = self.lo.min(r.lo);
        self.hi = self.hi.max(r.hi);
        let c = r.centroid2();
        self.clo = self.clo.min(c);
        self.chi = self.chi.max(c);
    }

    fn of(part: &[Ref]) -> Bounds {
        let mut b = Bounds::EMPTY;
        for r in part {
            b.add(r);
        }
        b
    }

    fn aabb(&self) -> Aabb {
        Aabb::new(self.lo.truncate(), self.hi.truncate())
    }
}

/// Half the surface area of a box (x, y, z lanes).
#[inline]
fn half_area(lo: Vec4, hi: Vec4) -> f32 {
    let d = hi - lo;
    d.x * d.y + d.y * d.z + d.z * d.x
}

/// Builds the node array over the BVH kinds of `prims` and reorders those kinds'
/// arrays into leaf order. Returns the nodes (empty when there is nothing to bound).
pub fn build(prims: &mut PrimSet) -> Vec<BvhNode> {
    let total: usize = PrimKind::BVH_KINDS.iter().map(|&k| prims.len(k)).sum();
    if total == 0 {
        return Vec::new();
    }
    // the large arrays of the build in huge pages (`huge_vec`): a fresh 4 KiB page
    // costs a fault here; touching 120 MB took 85–130 ms in 4 KiB pages, 15–25 ms
    // in 2 MiB ones (scratch test, this machine). Build of torus1m, thread CPU time,
    // best of 5: references 51 -> 23 Mcycles, the reorder below 141 -> 69.
    let mut refs = huge_vec(total);
    let mut root = Bounds::EMPTY;
    for kind in PrimKind::BVH_KINDS {
        for i in 0..prims.len(kind) {
            let b = prims.bounds(kind, i);
            let r = Ref {
                lo: b.lo.extend(f32::from_bits(i as u32)),
                hi: b.hi.extend(f32::from_bits(kind as u32)),
            };
            root.add(&r);
            refs.push(r);
        }
    }
    // at most 2·total − 1 nodes and one pad: never reallocated, so the pad below
    // keeps every pair of children on one 64-byte cache line
    let mut nodes = huge_vec(2 * total);
    nodes.push(BvhNode::interior(Aabb::EMPTY, 0, 0));
    if (nodes.as_ptr() as usize / std::mem::size_of::<BvhNode>()).is_multiple_of(2) {
        // pairs start at even indices; the pad (index 1) is unreachable from the
        // root and has no area (no SAH cost)
        nodes.push(BvhNode::interior(Aabb::EMPTY, 0, 0));
    }
    // leaves are found in order of `start` (depth first, left before right) and
    // cover the references in order, so a leaf's primitives will start at the count
    // of its kind in the leaves before it
    let mut next = [0u32; 8]; // by kind code (PrimKind as u32 < 8)
    #[cfg(debug_assertions)]
    let mut covered = 0usize;
    let mut tasks = Vec::with_capacity(2 * MEDIAN_DEPTH);
    tasks.push((0u32, 0usize, total, 0usize, root));
    while let Some((ni, start, end, depth, b)) = tasks.pop() {
        let part = &mut refs[start..end];
        let n = part.len();
        let mixed = n <= MAX_LEAF && part.iter().any(|r| r.kind() != part[0].kind());
        let (mid, axis, lb, rb) = match choose_split(part, &b, depth) {
            Split::Leaf if !mixed => {
                #[cfg(debug_assertions)]
                {
                    assert_eq!(covered, start, "leaves out of reference order");
                    covered = end;
                }
                let k = part[0].kind();
                let first = next[k as usize];
                next[k as usize] += n as u32;
                let kind = PrimKind::from_u32(k);
                nodes[ni as usize] = BvhNode::leaf(b.aabb(), first, n as u32, kind);
                continue;
            }
            Split::Leaf => {
                // one kind per leaf: split off the first kind
                let k = part[0].kind();
                let (mid, lb, rb) = partition(part, |r| r.kind() == k);
                (mid, widest_axis(b.chi - b.clo), lb, rb)
            }
            Split::At(axis, bin, scale, base) => {
                // c's bin (as in `bin_split`: (c − base) · scale truncated, at most
                // the last bin) is below `bin` ⟺ (c − base) · scale < bin: the
                // product is >= 0 (base is the least centroid) and `bin` is at most
                // the last bin, so neither the truncation nor the clamp changes the
                // comparison (was a saturating float-to-int cast per reference)
                let bin = bin as f32;
                let left = |r: &Ref| (r.centroid2()[axis] - base) * scale < bin;
                // Tried: the branchless partition on every range: thread CPU time of
                // the torus1m build 408, 431, 389 ms on ranges <= SAMPLE only; 449,
                // 468, 466 on all (SAH 52.26, the tree changes slightly).
                let (mid, lb, rb) = if n <= SAMPLE {
                    partition_branchless(part, left)
                } else {
                    partition(part, left)
                };
                (mid, axis, lb, rb)
            }
            Split::Half(axis) => {
                part.select_nth_unstable_by(n / 2, |a, b| {
                    a.centroid2()[axis].total_cmp(&b.centroid2()[axis])
                });
                let (l, r) = part.split_at(n / 2);
                (n / 2, axis, Bounds::of(l), Bounds::of(r))
            }
        };
        let (mid, lb, rb) = if mid == 0 || mid == n {
            let (l, r) = part.split_at(n / 2);
            (n / 2, Bounds::of(l), Bounds::of(r))
        } else {
            (mid, lb, rb)
        };
        let left = nodes.len() as u32;
        nodes.push(BvhNode::interior(Aabb::EMPTY, 0, 0));
        nodes.push(BvhNode::interior(Aabb::EMPTY, 0, 0));
        nodes[ni as usize] = BvhNode::interior(b.aabb(), left, axis);
        tasks.push((left + 1, start + mid, end, depth + 1, rb));
        tasks.push((left, start, start + mid, depth + 1, lb));
    }
    // reorder the BVH kinds into leaf order: each kind's new array is its
    // references' primitives in reference order, one gather (was a push per
    // primitive, leaf by leaf, after a pass over a list of the leaves)
    use PrimKind::{Quadric, Sphere};
    // the triangles are of one kind or the other, per scene (profile `triangle_test`)
    let tri = if prims.moller {
        PrimKind::TriangleMoller
    } else {
        PrimKind::Triangle
    };
    prims.spheres = gather(&refs, Sphere, &prims.spheres);
    prims.sphere_obj = gather(&refs, Sphere, &prims.sphere_obj);
    prims.triangles = gather(&refs, tri, &prims.triangles);
    prims.triangle_obj = gather(&refs, tri, &prims.triangle_obj);
    prims.quadrics = gather(&refs, Quadric, &prims.quadrics);
    prims.quadric_obj = gather(&refs, Quadric, &prims.quadric_obj);
    nodes
}

fn widest_axis(extent: Vec4) -> usize {
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

/// Per-axis bins: bounds and counts.
struct Bins<const B: usize> {
    lo: [[Vec4; B]; 3],
    hi: [[Vec4; B]; 3],
    n: [[u32; B]; 3],
}

impl<const B: usize> Bins<B> {
    fn new() -> Self {
        Bins {
            lo: [[Vec4::INFINITY; B]; 3],
            hi: [[Vec4::NEG_INFINITY; B]; 3],
            n: [[0; B]; 3],
        }
    }

    #[inline]
    fn add(&mut self, r: &Ref, k: [i32; 4]) {
        for (axis, &k) in k.iter().take(3).enumerate() {
            let k = k as usize;
            self.lo[axis][k] = self.lo[axis][k].min(r.lo);
            self.hi[axis][k] = self.hi[axis][k].max(r.hi);
            self.n[axis][k] += 1;
        }
    }
}

fn choose_split(part: &[Ref], b: &Bounds, depth: usize) -> Split {
    let n = part.len();
    let extent = b.chi - b.clo;
    let widest = widest_axis(extent);
    if n <= 1 {
        return Split::Leaf;
    }
    if extent.truncate().max_element() <= 0.0 {
        return if n <= MAX_LEAF {
            Split::Leaf
        } else {
            Split::Half(widest)
        };
    }
    if depth >= MEDIAN_DEPTH {
        return Split::Half(widest);
    }
    if n == 2 {
        return pair_split(part, b);
    }
    // nb = min(n, B) bins are used: the smaller B, the fewer bins are cleared
    if n <= 4 {
        bin_split::<4>(part, b)
    } else if n <= MAX_LEAF {
        bin_split::<MAX_LEAF>(part, b)
    } else {
        bin_split::<BINS>(part, b)
    }
}

/// `bin_split` of two references, without bins: on every
/// axis where the centroids differ they fall in bins 0 and 1, so the one candidate is
/// one reference per side, at the same cost on every such axis, and the first such
/// axis wins. Same result as `bin_split::<MAX_LEAF>`, bit for bit.
fn pair_split(part: &[Ref], b: &Bounds) -> Split {
    let extent = b.chi - b.clo;
    let (l, r) = (&part[0], &part[1]);
    let cost = half_area(l.lo, l.hi) + half_area(r.lo, r.hi);
    let node_area = half_area(b.lo, b.hi).max(f32::MIN_POSITIVE);
    if C_TRAVERSE + cost / node_area >= 2.0 {
        return Split::Leaf;
    }
    let axis = (0..3).find(|&a| extent[a] > 0.0).expect("centroids differ");
    let scale = 2.0f32 * (1.0 - 1e-6) / extent[axis];
    Split::At(axis, 1, scale, b.clo[axis])
}

/// The cheapest SAH split over min(n, B) bins per axis, or a leaf.
#[inline]
fn bin_split<const B: usize>(part: &[Ref], b: &Bounds) -> Split {
    let n = part.len();
    let extent = b.chi - b.clo;
    let widest = widest_axis(extent);
    // no more bins than primitives: the many small ranges (half the calls are final
    // leaves of a few primitives) sweep a few bins
    let nb = n.min(B);
    let scale = Vec4::splat(nb as f32 * (1.0 - 1e-6)) / extent;
    let scale = Vec4::select(extent.cmpgt(Vec4::ZERO), scale, Vec4::ZERO);
    let base = b.clo;
    // the bin on each axis: (c − base) · scale truncated, at most nb − 1 (never
    // negative: base is the least centroid). One SIMD truncation for three axes.
    let top = i32x4::splat(nb as i32 - 1);
    let (base4, scale4) = (f32x4::from(base.to_array()), f32x4::from(scale.to_array()));
    let bin = |r: &Ref| {
        let c = f32x4::from(r.centroid2().to_array());
        ((c - base4) * scale4).fast_trunc_int().min(top).to_array()
    };
    let mut bins = Bins::<B>::new();
    // large ranges are binned on an even sample of about SAMPLE references: the
    // costs compare the same, and these passes stream the whole reference array
    let stride = (n / SAMPLE).max(1);
    let mut sampled = 0usize;
    for r in part.iter().step_by(stride) {
        bins.add(r, bin(r));
        sampled += 1;
    }
    let mut best = (f32::INFINITY, 0, 0);
    for axis in 0..3 {
        if extent[axis] <= 0.0 {
            continue;
        }
        let (blo, bhi, bn) = (&bins.lo[axis], &bins.hi[axis], &bins.n[axis]);
        // sweep from the right: cost of the right side of each boundary
        let mut right_cost = [0.0f32; B];
        let (mut rlo, mut rhi, mut rn) = (Vec4::INFINITY, Vec4::NEG_INFINITY, 0u32);
        for k in (1..nb).rev() {
            rlo = rlo.min(blo[k]);
            rhi = rhi.max(bhi[k]);
            rn += bn[k];
            right_cost[k] = if rn > 0 {
                half_area(rlo, rhi) * rn as f32
            } else {
                0.0
            };
        }
        let (mut llo, mut lhi, mut ln) = (Vec4::INFINITY, Vec4::NEG_INFINITY, 0u32);
        for k in 1..nb {
            llo = llo.min(blo[k - 1]);
            lhi = lhi.max(bhi[k - 1]);
            ln += bn[k - 1];
            if ln == 0 || ln as usize == sampled {
                continue;
            }
            let cost = half_area(llo, lhi) * ln as f32 + right_cost[k];
            if cost < best.0 {
                best = (cost, axis, k);
            }
        }
    }
    if best.0.is_infinite() {
        return if n <= MAX_LEAF {
            Split::Leaf
        } else {
            Split::Half(widest)
        };
    }
    let node_area = half_area(b.lo, b.hi).max(f32::MIN_POSITIVE);
    let split_cost = C_TRAVERSE + best.0 / node_area;
    if n <= MAX_LEAF && split_cost >= n as f32 {
        return Split::Leaf;
    }
    let axis = best.1;
    Split::At(axis, best.2, scale[axis], base[axis])
}

/// Moves the refs satisfying `left` to the front; returns their count and the
/// bounds of both sides.
#[inline]
fn partition(part: &mut [Ref], left: impl Fn(&Ref) -> bool) -> (usize, Bounds, Bounds) {
    let (mut lb, mut rb) = (Bounds::EMPTY, Bounds::EMPTY);
    let mut i = 0;
    let mut j = part.len();
    loop {
        while i < j && left(&part[i]) {
            lb.add(&part[i]);
            i += 1;
        }
        while i < j && !left(&part[j - 1]) {
            j -= 1;
            rb.add(&part[j]);
        }
        if i + 1 >= j {
            break;
        }
        // part[i] belongs right, part[j − 1] left
        part.swap(i, j - 1);
        lb.add(&part[i]);
        i += 1;
        j -= 1;
        rb.add(&part[j]);
    }
    (i, lb, rb)
}

/// The primitives of `kind` in the order of their references.
fn gather<T: Copy>(refs: &[Ref], kind: PrimKind, from: &[T]) -> Vec<T> {
    let mut v = huge_vec(from.len());
    if from.len() == refs.len() {
        // one kind only
        v.extend(refs.iter().map(|r| from[r.index()]));
    } else {
        let k = kind as u32;
        v.extend(
            refs.iter()
                .filter(|r| r.kind() == k)
                .map(|r| from[r.index()]),
        );
    }
    v
}

/// Moves the refs satisfying `left` to the front without a branch on `left` (Lomuto:
/// each ref swaps with the one just past the left side, which then grows by one if
/// the ref belongs left; on ranges that fit the cache the swaps cost less than the
/// mispredicted branches), then bounds both sides; returns the left count and the
/// bounds. Torus1m build, thread CPU time, interleaved with the
/// branching `partition` on every range: 455/458, 439/449, 358/473 ms.
#[inline]
fn partition_branchless(part: &mut [Ref], left: impl Fn(&Ref) -> bool) -> (usize, Bounds, Bounds) {
    let mut j = 0;
    for i in 0..part.len() {
        let r = part[i];
        let is_left = left(&r);
        part[i] = part[j];
        part[j] = r;
        j += is_left as usize;
    }
    (j, Bounds::of(&part[..j]), Bounds::of(&part[j..]))
}
