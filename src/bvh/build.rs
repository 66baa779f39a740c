//! Binned SAH build (Wald 2007): a flat node array, children of a node adjacent,
//! leaves of one primitive kind.
//!
//! Each split tries `bin_count(n)` bins per axis (Embree's 4 + n/20, at most `BINS`)
//! over the centroid bounds and takes the cheapest by the surface area heuristic,
//! cost = C_T + Σ A(child)/A(node) · C_I · n; a range becomes a leaf when that is not
//! cheaper than C_I · n and n <= `MAX_LEAF`. A range whose centroids all coincide is
//! halved. A leaf with several kinds is split by kind. Beyond depth `MEDIAN_DEPTH`
//! splits are halvings, so the depth stays below the traversal stack size.
//!
//! Work per node: one binning pass and one in-place partition pass over 32-byte
//! references (a box as [lo, −hi] in 8 lanes, index and kind in the spare ones).
//! Ranges below 2 · `SAMPLE` bin every reference, so the children's boxes come from
//! the SAH sweep and the partition is branchless (the centroid bounds are a second
//! pass over the cached range); larger ranges bin a sample and their partition
//! computes both children's bounds on the way (the range streams from memory once).
//! Ranges of at most `SMALL` references of one kind skip the bins: every split into
//! two sets is tried.
//! Primitives are reordered into leaf order once, at the end, by one gather. Each pair
//! of children sits on one 64-byte cache line (node 1 may be an unreachable pad for
//! that). The large arrays are in huge pages (fewer page faults while they fill).

use glam::Vec4;
use rayon::prelude::*;
use wide::{f32x4, f32x8, i32x4};

use super::memory::huge_vec;
use super::node::BvhNode;
use crate::geometry::{PrimKind, PrimSet};
use crate::math::Aabb;

/// Bins per axis at most (Embree's count); a range of n references uses
/// `bin_count(n)` of them.
const BINS: usize = 32;
/// Largest leaf (primitives).
pub const MAX_LEAF: usize = 8;
/// Cost of one box test relative to one primitive test.
pub const C_TRAVERSE: f32 = 1.0;
/// References binned per split at most (larger ranges are sampled evenly).
const SAMPLE: usize = 4096;
/// Depth past which ranges are halved instead of SAH-split.
const MEDIAN_DEPTH: usize = 48;

/// The bits of 1.0: the index and the kind of a reference are stored as the floats
/// whose bits are this plus them, so every lane of a reference is a normal number
/// (no denormal ever enters the arithmetic on whole boxes).
const ONE: u32 = 0x3f80_0000;
const SIGN: u32 = 0x8000_0000;

/// A box as eight lanes `[lo.x, lo.y, lo.z, _, −hi.x, −hi.y, −hi.z, _]`: the union of
/// two is one `min`.
type Box8 = f32x8;
const EMPTY8: Box8 = f32x8::splat(f32::INFINITY);

/// A primitive reference during the build, 32 bytes: its box as a [`Box8`], with
/// the index in lane 3 and the kind in lane 7 (see [`ONE`]).
#[derive(Clone, Copy, Debug)]
#[repr(C, align(32))]
struct Ref([f32; 8]);

impl Ref {
    fn new(b: &Aabb, index: usize, kind: u32) -> Ref {
        debug_assert!(index < (1 << 30));
        Ref([
            b.lo.x,
            b.lo.y,
            b.lo.z,
            f32::from_bits(ONE + index as u32),
            -b.hi.x,
            -b.hi.y,
            -b.hi.z,
            f32::from_bits((ONE + kind) | SIGN),
        ])
    }
    #[inline]
    fn index(&self) -> usize {
        (self.0[3].to_bits() - ONE) as usize
    }
    #[inline]
    fn kind(&self) -> u32 {
        (self.0[7].to_bits() & !SIGN) - ONE
    }
    #[inline]
    fn boxed(&self) -> Box8 {
        f32x8::from(self.0)
    }
    /// Twice the centre (x, y, z lanes).
    #[inline]
    fn centroid2(&self) -> Vec4 {
        Vec4::from_slice(&self.0[..4]) - Vec4::from_slice(&self.0[4..])
    }
    /// Twice the centre on one axis.
    #[inline]
    fn centroid2_on(&self, axis: usize) -> f32 {
        self.0[axis] - self.0[axis + 4]
    }
    /// Twice the centre as a box of no extent.
    #[inline]
    fn centroid_box(&self) -> Box8 {
        let a = self.0;
        f32x8::from(a) - f32x8::from([a[4], a[5], a[6], a[7], a[0], a[1], a[2], a[3]])
    }
}

/// The lower and upper corner of a [`Box8`] (x, y, z lanes).
#[inline]
fn corners(b: Box8) -> (Vec4, Vec4) {
    let a = b.to_array();
    (Vec4::from_slice(&a[..4]), -Vec4::from_slice(&a[4..]))
}

/// Half the surface area of a [`Box8`] (infinite when empty).
#[inline]
fn half_area(b: Box8) -> f32 {
    let a = b.to_array();
    // minus the extents
    let d = Vec4::from_slice(&a[..4]) + Vec4::from_slice(&a[4..]);
    d.x * d.y + d.y * d.z + d.z * d.x
}

/// Bounds and centroid bounds of a range.
#[derive(Clone, Copy, Debug)]
struct Bounds {
    geo: Box8,
    cen: Box8,
}

impl Bounds {
    const EMPTY: Bounds = Bounds {
        geo: EMPTY8,
        cen: EMPTY8,
    };

    #[inline]
    fn add(&mut self, r: &Ref) {
        self.geo = self.geo.fast_min(r.boxed());
        self.cen = self.cen.fast_min(r.centroid_box());
    }

    fn of(part: &[Ref]) -> Bounds {
        let mut b = Bounds::EMPTY;
        for r in part {
            b.add(r);
        }
        b
    }

    fn union(self, o: Bounds) -> Bounds {
        Bounds {
            geo: self.geo.fast_min(o.geo),
            cen: self.cen.fast_min(o.cen),
        }
    }

    /// The centroid bounds of `part`, the bounds `geo` (known).
    fn with_geo(part: &[Ref], geo: Box8) -> Bounds {
        let mut cen = EMPTY8;
        for r in part {
            cen = cen.fast_min(r.centroid_box());
        }
        Bounds { geo, cen }
    }

    fn aabb(&self) -> Aabb {
        let (lo, hi) = corners(self.geo);
        Aabb::new(lo.truncate(), hi.truncate())
    }

    /// The extent of the centroids (x, y, z lanes).
    fn centroid_extent(&self) -> Vec4 {
        let (lo, hi) = corners(self.cen);
        hi - lo
    }

    fn centroid_lo(&self) -> Vec4 {
        corners(self.cen).0
    }
}

/// Builds the node array over the BVH kinds of `prims` and reorders those kinds'
/// arrays into leaf order, but for the triangles themselves: returns the nodes (empty
/// when there is nothing to bound) and the triangles' leaf order (`order[k]`: the index
/// in `prims.tri_corners` of the k-th), from which the collapse packs them into blocks
/// (`WideBvh::collapse`) without a copy in between.
///
/// On more than one worker thread, the subtrees of large ranges are built in parallel
/// (each in an array of its own, joined in the serial build's order at the end): the
/// nodes, their order and the primitive order are those of the serial build.
pub fn build(prims: &mut PrimSet) -> (Vec<BvhNode>, Vec<u32>) {
    let total: usize = PrimKind::BVH_KINDS.iter().map(|&k| prims.len(k)).sum();
    if total == 0 {
        return (Vec::new(), Vec::new());
    }
    let parallel =
        total > PARALLEL_REFS && crate::parallel::parallel() && rayon::current_num_threads() > 1;
    // the large arrays of the build in huge pages (`huge_vec`): a fresh 4 KiB page
    // costs a fault here; touching 120 MB took 85–130 ms in 4 KiB pages, 15–25 ms
    // in 2 MiB ones (scratch test, this machine). Build of torus1m, thread CPU time,
    // best of 5: references 51 -> 23 Mcycles, the reorder below 141 -> 69.
    let mut refs = huge_vec(total);
    for kind in PrimKind::BVH_KINDS {
        let n = prims.len(kind);
        let make = |i: usize| Ref::new(&prims.bounds(kind, i), i, kind as u32);
        if parallel {
            refs.par_extend((0..n).into_par_iter().map(make));
        } else {
            refs.extend((0..n).map(make));
        }
    }
    // (a union of boxes is a `min` of lanes: the same in any order)
    let root = if parallel {
        refs.par_chunks(SAMPLE)
            .map(Bounds::of)
            .reduce(|| Bounds::EMPTY, Bounds::union)
    } else {
        Bounds::of(&refs)
    };
    // at most 2·total − 1 nodes and one pad: never reallocated, so the pad below
    // keeps every pair of children on one 64-byte cache line
    let mut nodes = huge_vec(2 * total);
    nodes.push(BvhNode::interior(Aabb::EMPTY, 0, 0));
    if (nodes.as_ptr() as usize / std::mem::size_of::<BvhNode>()).is_multiple_of(2) {
        // pairs start at even indices; the pad (index 1) is unreachable from the
        // root and has no area (no SAH cost)
        nodes.push(BvhNode::interior(Aabb::EMPTY, 0, 0));
    }
    if parallel {
        let tree = par_subtree(&mut refs, root, 0);
        let mut base = [0; 8];
        tree.place(0, &mut nodes, &mut base);
    } else {
        let mut leaves = Leaves::new(0);
        serial_subtree(&mut refs, 0, root, 0, &mut nodes, &mut leaves);
    }
    // reorder the BVH kinds into leaf order: each kind's new array is its
    // references' primitives in reference order, one gather; the triangles only their
    // indices (the collapse gathers the triangles straight into their blocks)
    use PrimKind::{Quadric, Sphere, Triangle};
    fn by_kind<T: Copy + Send + Sync>(refs: &[Ref], k: PrimKind, v: &[T], par: bool) -> Vec<T> {
        gather(refs, k, v.len(), |i| v[i], par)
    }
    prims.spheres = by_kind(&refs, Sphere, &prims.spheres, parallel);
    prims.sphere_obj = by_kind(&refs, Sphere, &prims.sphere_obj, parallel);
    let n = prims.triangle_obj.len();
    let order = gather(&refs, Triangle, n, |i| i as u32, parallel);
    prims.triangle_obj = by_kind(&refs, Triangle, &prims.triangle_obj, parallel);
    prims.quadrics = by_kind(&refs, Quadric, &prims.quadrics, parallel);
    prims.quadric_obj = by_kind(&refs, Quadric, &prims.quadric_obj, parallel);
    (nodes, order)
}

/// Builds with more references than this use the worker threads.
const PARALLEL_REFS: usize = 1 << 15;
/// Ranges of at most this many references are one parallel task (built serially).
const TASK_REFS: usize = 1 << 14;

/// What the builder does with a range.
enum Step {
    /// One leaf.
    Leaf,
    /// A subtree of at most [`SMALL`] references of one kind ([`small_subtree`]).
    Small,
    /// Two children: the first `mid` references (bounds `lb`) and the rest (`rb`),
    /// split on `axis`.
    Split {
        mid: usize,
        axis: usize,
        lb: Bounds,
        rb: Bounds,
    },
}

/// The step for the range `part` (bounds `b`) at `depth`; a split has partitioned it.
fn step(part: &mut [Ref], b: &Bounds, depth: usize) -> Step {
    let n = part.len();
    let mixed = n <= MAX_LEAF && part.iter().any(|r| r.kind() != part[0].kind());
    if n <= SMALL && !mixed {
        return Step::Small;
    }
    let (mid, axis, lb, rb) = match choose_split(part, b, depth) {
        Split::Leaf if !mixed => return Step::Leaf,
        Split::Leaf => {
            // one kind per leaf: split off the first kind
            let k = part[0].kind();
            let (mid, lb, rb) = partition(part, |r| r.kind() == k);
            (mid, widest_axis(b.centroid_extent()), lb, rb)
        }
        Split::At(s) => {
            // c's bin (as in `bin_split`: (c − base) · scale truncated, at most
            // the last bin) is below `bin` ⟺ (c − base) · scale < bin: the
            // product is >= 0 (base is the least centroid) and `bin` is at most
            // the last bin, so neither the truncation nor the clamp changes the
            // comparison (was a saturating float-to-int cast per reference)
            let (axis, bin, base, scale) = (s.axis, s.bin as f32, s.base, s.scale);
            let left = |r: &Ref| (r.centroid2_on(axis) - base) * scale < bin;
            let (mid, lb, rb) = match s.sides {
                Some((lgeo, rgeo)) => {
                    let mid = partition_branchless(part, left);
                    let (l, r) = part.split_at(mid);
                    (mid, Bounds::with_geo(l, lgeo), Bounds::with_geo(r, rgeo))
                }
                None => partition(part, left),
            };
            (mid, axis, lb, rb)
        }
        Split::Half(axis) => {
            part.select_nth_unstable_by(n / 2, |a, b| {
                a.centroid2_on(axis).total_cmp(&b.centroid2_on(axis))
            });
            let (l, r) = part.split_at(n / 2);
            (n / 2, axis, Bounds::of(l), Bounds::of(r))
        }
    };
    if mid == 0 || mid == n {
        let (l, r) = part.split_at(n / 2);
        let (lb, rb) = (Bounds::of(l), Bounds::of(r));
        return Step::Split {
            mid: n / 2,
            axis,
            lb,
            rb,
        };
    }
    Step::Split { mid, axis, lb, rb }
}

/// Builds the subtree over `refs` (bounds `root`, at `depth`) whose root is node `ni`
/// of `nodes`, appending its other nodes: a node's children are a pair appended when
/// it is split, and the left subtree is built before the right one (depth first).
/// `start` is the index of `refs[0]` among all references (checks only).
fn serial_subtree(
    refs: &mut [Ref],
    ni: usize,
    root: Bounds,
    depth: usize,
    nodes: &mut Vec<BvhNode>,
    leaves: &mut Leaves,
) {
    let mut tasks = Vec::with_capacity(2 * MEDIAN_DEPTH);
    tasks.push((ni as u32, 0usize, refs.len(), depth, root));
    while let Some((ni, start, end, depth, b)) = tasks.pop() {
        let part = &mut refs[start..end];
        match step(part, &b, depth) {
            Step::Small => {
                small_subtree(part, b.geo, ni as usize, start, nodes, leaves);
            }
            Step::Leaf => {
                nodes[ni as usize] = leaves.leaf(part, start, b.geo);
            }
            Step::Split { mid, axis, lb, rb } => {
                let left = nodes.len() as u32;
                nodes.push(BvhNode::interior(Aabb::EMPTY, 0, 0));
                nodes.push(BvhNode::interior(Aabb::EMPTY, 0, 0));
                nodes[ni as usize] = BvhNode::interior(b.aabb(), left, axis);
                tasks.push((left + 1, start + mid, end, depth + 1, rb));
                tasks.push((left, start, start + mid, depth + 1, lb));
            }
        }
    }
}

/// A subtree built on the worker threads.
enum Subtree {
    /// Built serially, in an array of its own: its root at 0, an unused pad at 1 and
    /// from 2 on the nodes the serial build appends for it, with child indices into
    /// this array and leaf primitive offsets from 0; `counts`: its primitives by kind.
    Block {
        nodes: Vec<BvhNode>,
        counts: [u32; 8],
    },
    /// An interior node (its child index still unset) and its two subtrees.
    Split {
        node: BvhNode,
        children: Box<(Subtree, Subtree)>,
    },
}

/// The subtree over `refs` (bounds `root`, at `depth`): ranges larger than
/// [`TASK_REFS`] are split here and their children built in parallel.
fn par_subtree(refs: &mut [Ref], root: Bounds, depth: usize) -> Subtree {
    if refs.len() > TASK_REFS
        && let Step::Split { mid, axis, lb, rb } = step(refs, &root, depth)
    {
        let (l, r) = refs.split_at_mut(mid);
        let children = rayon::join(
            || par_subtree(l, lb, depth + 1),
            || par_subtree(r, rb, depth + 1),
        );
        return Subtree::Split {
            node: BvhNode::interior(root.aabb(), 0, axis),
            children: Box::new(children),
        };
    }
    // (a range above TASK_REFS is always split, a leaf holds at most MAX_LEAF; a
    // step that splits nothing leaves the range as it was, for the serial build)
    let mut nodes = Vec::with_capacity(2 * refs.len());
    nodes.push(BvhNode::interior(Aabb::EMPTY, 0, 0));
    nodes.push(BvhNode::interior(Aabb::EMPTY, 0, 0));
    let mut leaves = Leaves::new(0);
    serial_subtree(refs, 0, root, depth, &mut nodes, &mut leaves);
    Subtree::Block {
        nodes,
        counts: leaves.next,
    }
}

impl Subtree {
    /// Puts this subtree's root at node `ni` and appends its other nodes to `nodes`
    /// in the serial build's order; `base`: the primitives of each kind in the leaves
    /// before it.
    fn place(self, ni: usize, nodes: &mut Vec<BvhNode>, base: &mut [u32; 8]) {
        match self {
            Subtree::Block { nodes: own, counts } => {
                // own[j] for j >= 2 goes to off + j − 2
                let off = nodes.len() as u32;
                let moved = |mut n: BvhNode| {
                    if n.is_leaf() {
                        n.first += base[n.kind() as usize];
                    } else {
                        n.first = n.first + off - 2;
                    }
                    n
                };
                nodes[ni] = moved(own[0]);
                nodes.extend(own[2..].iter().map(|&n| moved(n)));
                for (b, c) in base.iter_mut().zip(counts) {
                    *b += c;
                }
            }
            Subtree::Split { mut node, children } => {
                let left = nodes.len();
                nodes.push(BvhNode::interior(Aabb::EMPTY, 0, 0));
                nodes.push(BvhNode::interior(Aabb::EMPTY, 0, 0));
                node.first = left as u32;
                nodes[ni] = node;
                let (l, r) = *children;
                l.place(left, nodes, base);
                r.place(left + 1, nodes, base);
            }
        }
    }
}

/// Leaf primitive offsets: leaves are made in reference order, so a leaf's
/// primitives start at the count of its kind in the leaves before it.
struct Leaves {
    /// By kind code (PrimKind as u32 < 8).
    next: [u32; 8],
    #[cfg(debug_assertions)]
    covered: usize,
}

impl Leaves {
    /// No leaves yet; the first will start at reference `start`.
    fn new(start: usize) -> Leaves {
        #[cfg(not(debug_assertions))]
        let _ = start;
        Leaves {
            next: [0; 8],
            #[cfg(debug_assertions)]
            covered: start,
        }
    }

    /// The leaf over `part` (one kind), which starts at reference `start`.
    #[inline]
    fn leaf(&mut self, part: &[Ref], start: usize, geo: Box8) -> BvhNode {
        #[cfg(debug_assertions)]
        {
            assert_eq!(self.covered, start, "leaves out of reference order");
            self.covered = start + part.len();
        }
        #[cfg(not(debug_assertions))]
        let _ = start;
        let k = part[0].kind();
        let first = self.next[k as usize];
        self.next[k as usize] += part.len() as u32;
        let (lo, hi) = corners(geo);
        BvhNode::leaf(
            Aabb::new(lo.truncate(), hi.truncate()),
            first,
            part.len() as u32,
            PrimKind::from_bits(k).expect("a reference's kind"),
        )
    }
}

/// Ranges of at most this many references (of one kind) are split exhaustively.
const SMALL: usize = 4;

/// The subtree of a range of 1 ..= `SMALL` references of one kind, bounds `geo`, at
/// node `ni`: each node takes the cheapest of all 2^(n−1) − 1 partitions into two
/// non-empty sets (not only those by a plane), or is a leaf when that is not cheaper
/// (the SAH rule of `bin_split`); the references are reordered so the left set comes
/// first. The split axis kept for the packet walk's near-first order is that of the
/// largest distance between the children's centres, the lower child on the left.
fn small_subtree(
    part: &mut [Ref],
    geo: Box8,
    ni: usize,
    start: usize,
    nodes: &mut Vec<BvhNode>,
    leaves: &mut Leaves,
) {
    let n = part.len();
    debug_assert!((1..=SMALL).contains(&n));
    if n == 1 {
        nodes[ni] = leaves.leaf(part, start, geo);
        return;
    }
    let full = (1usize << n) - 1;
    // the box and half area of every subset
    let mut sub = [EMPTY8; 1 << SMALL];
    let mut area = [0.0f32; 1 << SMALL];
    for m in 1..=full {
        sub[m] = sub[m & (m - 1)].fast_min(part[m.trailing_zeros() as usize].boxed());
        area[m] = half_area(sub[m]);
    }
    // the partitions: the sets with reference 0 against the rest
    let mut best = (f32::INFINITY, 0usize);
    for m in (1..full).step_by(2) {
        let c = m ^ full;
        let cost = area[m] * m.count_ones() as f32 + area[c] * c.count_ones() as f32;
        if cost < best.0 {
            best = (cost, m);
        }
    }
    let node_area = area[full].max(f32::MIN_POSITIVE);
    if C_TRAVERSE + best.0 / node_area >= n as f32 {
        nodes[ni] = leaves.leaf(part, start, geo);
        return;
    }
    let (mut l, mut r) = (best.1, best.1 ^ full);
    // the centres' distance (twice)
    let (cl, cr) = (corners(sub[l]), corners(sub[r]));
    let d = (cr.0 + cr.1) - (cl.0 + cl.1);
    let axis = widest_axis(d.abs());
    if d[axis] < 0.0 {
        std::mem::swap(&mut l, &mut r);
    }
    // reorder: the left set first, each set in its order
    let mut tmp = [part[0]; SMALL];
    tmp[..n].copy_from_slice(part);
    let mut j = 0;
    for set in [l, r] {
        for (i, t) in tmp.iter().enumerate().take(n) {
            if set >> i & 1 != 0 {
                part[j] = *t;
                j += 1;
            }
        }
    }
    let mid = l.count_ones() as usize;
    let left = nodes.len();
    nodes.push(BvhNode::interior(Aabb::EMPTY, 0, 0));
    nodes.push(BvhNode::interior(Aabb::EMPTY, 0, 0));
    let (lo, hi) = corners(geo);
    nodes[ni] = BvhNode::interior(Aabb::new(lo.truncate(), hi.truncate()), left as u32, axis);
    let (lp, rp) = part.split_at_mut(mid);
    small_subtree(lp, sub[l], left, start, nodes, leaves);
    small_subtree(rp, sub[r], left + 1, start + mid, nodes, leaves);
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

/// A split by bins: the references whose centroid (twice the centre) on `axis`
/// falls in a bin below `bin` go left; the bin of c is (c − base) · scale truncated.
struct BinSplit {
    axis: usize,
    bin: usize,
    scale: f32,
    base: f32,
    /// The bounds of both sides, when every reference was binned.
    sides: Option<(Box8, Box8)>,
}

enum Split {
    Leaf,
    At(BinSplit),
    Half(usize),
}

/// Bins used for a range of `n` references: Embree's 4 + n/20, at most `BINS`.
#[inline]
fn bin_count(n: usize) -> usize {
    (4 + n / 20).min(BINS)
}

/// Per-axis bins: bounds and counts.
struct Bins<const B: usize> {
    b: [[Box8; B]; 3],
    n: [[u32; B]; 3],
}

impl<const B: usize> Bins<B> {
    #[inline]
    fn new() -> Self {
        Bins {
            b: [[EMPTY8; B]; 3],
            n: [[0; B]; 3],
        }
    }

    #[inline]
    fn add(&mut self, r: &Ref, k: [i32; 4]) {
        let rb = r.boxed();
        for (axis, &k) in k.iter().take(3).enumerate() {
            let k = k as usize;
            self.b[axis][k] = self.b[axis][k].fast_min(rb);
            self.n[axis][k] += 1;
        }
    }
}

fn choose_split(part: &[Ref], b: &Bounds, depth: usize) -> Split {
    let n = part.len();
    let extent = b.centroid_extent();
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
    // bin_count(n) bins are used: the smaller B, the fewer bins are cleared
    if n <= 4 {
        bin_split::<4>(part, b, n)
    } else if n <= MAX_LEAF {
        bin_split::<MAX_LEAF>(part, b, n)
    } else if n <= 80 {
        bin_split::<8>(part, b, bin_count(n))
    } else if n <= 240 {
        bin_split::<16>(part, b, bin_count(n))
    } else {
        bin_split::<BINS>(part, b, bin_count(n))
    }
}

/// `bin_split` of two references, without bins: on every
/// axis where the centroids differ they fall in bins 0 and 1, so the one candidate is
/// one reference per side, at the same cost on every such axis, and the first such
/// axis wins. Same result as binning the pair, bit for bit. (Ranges of one kind up to
/// `SMALL` are split exhaustively before; this serves pairs of two kinds.)
fn pair_split(part: &[Ref], b: &Bounds) -> Split {
    let extent = b.centroid_extent();
    let (l, r) = (&part[0], &part[1]);
    let cost = half_area(l.boxed()) + half_area(r.boxed());
    let node_area = half_area(b.geo).max(f32::MIN_POSITIVE);
    if C_TRAVERSE + cost / node_area >= 2.0 {
        return Split::Leaf;
    }
    let axis = (0..3).find(|&a| extent[a] > 0.0).expect("centroids differ");
    let scale = 2.0f32 * (1.0 - 1e-6) / extent[axis];
    let (l, r) = if l.centroid2_on(axis) < r.centroid2_on(axis) {
        (l, r)
    } else {
        (r, l)
    };
    Split::At(BinSplit {
        axis,
        bin: 1,
        scale,
        base: b.centroid_lo()[axis],
        sides: Some((l.boxed(), r.boxed())),
    })
}

/// The cheapest SAH split over `nb` <= B bins per axis, or a leaf.
#[inline]
fn bin_split<const B: usize>(part: &[Ref], b: &Bounds, nb: usize) -> Split {
    let n = part.len();
    let extent = b.centroid_extent();
    let widest = widest_axis(extent);
    debug_assert!(nb <= B);
    let scale = Vec4::splat(nb as f32 * (1.0 - 1e-6)) / extent;
    let scale = Vec4::select(extent.cmpgt(Vec4::ZERO), scale, Vec4::ZERO);
    let base = b.centroid_lo();
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
    // (cost, axis, bin, left box, right box)
    let mut best = (f32::INFINITY, 0, 0, EMPTY8, EMPTY8);
    for axis in 0..3 {
        if extent[axis] <= 0.0 {
            continue;
        }
        let (bb, bn) = (&bins.b[axis], &bins.n[axis]);
        // sweep from the right: cost and box of the right side of each boundary
        let mut right_cost = [0.0f32; B];
        let mut right_box = [EMPTY8; B];
        let (mut rb, mut rn) = (EMPTY8, 0u32);
        for k in (1..nb).rev() {
            rb = rb.fast_min(bb[k]);
            rn += bn[k];
            right_box[k] = rb;
            right_cost[k] = if rn > 0 {
                half_area(rb) * rn as f32
            } else {
                0.0
            };
        }
        let (mut lb, mut ln) = (EMPTY8, 0u32);
        for k in 1..nb {
            lb = lb.fast_min(bb[k - 1]);
            ln += bn[k - 1];
            if ln == 0 || ln as usize == sampled {
                continue;
            }
            let cost = half_area(lb) * ln as f32 + right_cost[k];
            if cost < best.0 {
                best = (cost, axis, k, lb, right_box[k]);
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
    let node_area = half_area(b.geo).max(f32::MIN_POSITIVE);
    let split_cost = C_TRAVERSE + best.0 / node_area;
    if n <= MAX_LEAF && split_cost >= n as f32 {
        return Split::Leaf;
    }
    let axis = best.1;
    Split::At(BinSplit {
        axis,
        bin: best.2,
        scale: scale[axis],
        base: base[axis],
        sides: (stride == 1).then_some((best.3, best.4)),
    })
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

/// The primitives of `kind` in the order of their references: `get(i)` for the
/// reference to primitive `i` of the `n` of that kind.
fn gather<T: Copy + Send + Sync>(
    refs: &[Ref],
    kind: PrimKind,
    n: usize,
    get: impl Fn(usize) -> T + Send + Sync,
    parallel: bool,
) -> Vec<T> {
    let mut v = huge_vec(n);
    if n == refs.len() && parallel {
        v.par_extend(refs.par_iter().map(|r| get(r.index())));
    } else if n == refs.len() {
        // one kind only
        v.extend(refs.iter().map(|r| get(r.index())));
    } else {
        let k = kind as u32;
        v.extend(
            refs.iter()
                .filter(|r| r.kind() == k)
                .map(|r| get(r.index())),
        );
    }
    v
}

/// Moves the refs satisfying `left` to the front without a branch on `left` (Lomuto:
/// each ref swaps with the one just past the left side, which then grows by one if
/// the ref belongs left; on ranges that fit the cache the swaps cost less than the
/// mispredicted branches); returns the left count.
#[inline]
fn partition_branchless(part: &mut [Ref], left: impl Fn(&Ref) -> bool) -> usize {
    let mut j = 0;
    for i in 0..part.len() {
        let r = part[i];
        let is_left = left(&r);
        part[i] = part[j];
        part[j] = r;
        j += is_left as usize;
    }
    j
}

#[cfg(test)]
mod tests {
    use glam::DVec3;

    use super::*;
    use crate::geometry::sphere::Sphere32;

    /// The nodes without the pad (node 1, present or not by the address of the
    /// array), child indices shifted to match.
    fn without_pad(nodes: &[BvhNode]) -> Vec<BvhNode> {
        let padded = nodes.len() > 1 && (nodes[0].is_leaf() || nodes[0].first == 2);
        if !padded {
            return nodes.to_vec();
        }
        let mut out = vec![nodes[0]];
        out.extend_from_slice(&nodes[2..]);
        for n in &mut out {
            if !n.is_leaf() {
                n.first -= 1;
            }
        }
        out
    }

    /// A torus of triangles with spheres strewn over it (two kinds, so leaves and
    /// primitive offsets by kind are exercised).
    fn prims() -> PrimSet {
        let mut p = PrimSet::from_triangles(crate::bvh::bench::torus(250, 160));
        for k in 0..3000 {
            let a = k as f64 * 0.37;
            let c = DVec3::new(a.cos() * 1.2, (k % 7) as f64 * 0.05, a.sin() * 1.2);
            p.spheres
                .push(Sphere32::new(c, 0.01 + (k % 5) as f64 * 0.004, DVec3::ZERO));
            p.sphere_obj.push(1 + k as u32);
        }
        p
    }

    /// The build on two threads (subtrees in parallel, joined) gives the serial
    /// build's nodes in the serial order, and the same primitive order.
    #[test]
    fn parallel_build_is_the_serial_build() {
        let (mut serial, mut parallel) = (prims(), prims());
        assert!(serial.tri_corners.len() + serial.spheres.len() > PARALLEL_REFS);
        let one = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap();
        let two = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap();
        let (a, order_a) = one.install(|| build(&mut serial));
        let (b, order_b) = two.install(|| build(&mut parallel));
        assert_eq!(without_pad(&a), without_pad(&b));
        assert_eq!(order_a, order_b);
        assert_eq!(serial.triangle_obj, parallel.triangle_obj);
        assert_eq!(serial.spheres, parallel.spheres);
        assert_eq!(serial.sphere_obj, parallel.sphere_obj);
        // and it is a tree with more than one parallel task
        assert!(a.len() > 4 * TASK_REFS / MAX_LEAF, "{} nodes", a.len());
    }
}
