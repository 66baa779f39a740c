//! Where the packet path's f32 stops resolving a scene: an object small against the
//! distances its rays travel.
//!
//! The packet path works in f32 coordinates centred on the camera, so a point is held
//! to about 2⁻²⁴ of its distance from the camera, and a ray's direction to about 2⁻²⁴,
//! which at a distance d puts the ray 2⁻²⁴·d off. An object much smaller than that
//! fraction of its distance from the camera, or from the floor (shadow and mirror rays
//! between them), has its edges and its shadows misplaced by a visible fraction of its
//! size. The reference (f64) holds at every scale, so the command line warns and names
//! the object ([`Detail::below_f32`]).
//!
//! The frame also has a range: [`F32_RANGE`] from the camera. The kernels multiply
//! coordinates (the sphere test squares lengths, the watertight triangle test takes
//! products of three), so beyond it they overflow f32 and miss, and the BVH clamps
//! every bound at [`BOUNDS_LIMIT`](crate::geometry::BOUNDS_LIMIT) = 2⁴⁴. An object
//! reaching past the range is named too: on the f32 paths a sphere of radius 2e19
//! around the camera (its squared radius is infinite in f32) leaves only the floor, a
//! sphere of radius 9e14 at 1e15 (its bounds clamped to a sliver) and a triangle at
//! 8e12 (its scaled distance overflows) vanish.

use glam::Vec3;
use wide::f32x8;

use crate::geometry::floor::Floor32;
use crate::geometry::triangle::TriBlock;
use crate::geometry::{PrimKind, PrimSet, prim_code};
use crate::math::Aabb;
use crate::math::packet::Cmp8;
use crate::scene::Scene;
use crate::simd::packet::dot3;

/// How far from its origin the f32 frame holds a scene: 2⁴² (4.4e12), where a product
/// of three coordinates (2¹²⁶) still fits in f32 (below 2¹²⁸), as the watertight
/// triangle test needs; spheres and quadrics need only squares.
pub const F32_RANGE: f32 = 4_398_046_511_104.0;

/// The bounded primitive of a packet renderer that is smallest against its distance,
/// in scene units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Detail {
    /// Index of its object in the scene file (0-based).
    pub object: u32,
    /// The diagonal of its bounding box.
    pub size: f64,
    /// The distance from the centre of its bounds to the camera or to the nearest
    /// point of the floor, whichever is farther.
    pub distance: f64,
    /// The largest coordinate of its bounds, relative to the camera (as the BVH sees
    /// them: at most [`BOUNDS_LIMIT`](crate::geometry::BOUNDS_LIMIT)).
    pub reach: f64,
}

impl Detail {
    /// Whether f32 loses this detail: `size` below 8 f32 epsilons (2⁻²⁰ ≈ 9.5e-7) of
    /// `distance`, where the `fast` profile leaves its 1 % bound of pixels off by more
    /// than 8/255 (`tests/extremes.rs`, `detail_below_f32_precision_is_flagged`).
    ///
    /// An object reaching beyond [`F32_RANGE`] is lost to f32 whatever its size.
    pub fn below_f32(&self) -> bool {
        self.beyond_range() || self.size < 8.0 * f64::from(f32::EPSILON) * self.distance
    }

    /// Whether its bounds reach beyond [`F32_RANGE`] from the camera.
    pub fn beyond_range(&self) -> bool {
        self.reach > f64::from(F32_RANGE)
    }

    /// The warning for `scene` rendered with the profile named `profile`.
    pub fn warning(&self, scene: &Scene, profile: &str) -> String {
        if self.beyond_range() {
            return format!(
                "octaray: warning: {} reaches farther from the camera than f32's range \
                 (2^42 = {:.1e}): profile {profile} may lose it; --profile reference \
                 renders it exactly",
                scene.object_name(self.object as usize),
                F32_RANGE,
            );
        }
        format!(
            "octaray: warning: {} (bounds {:.1e} across) is below f32 precision at its \
             distance from the camera or the floor ({:.1e}): profile {profile} may misplace \
             its edges and shadows; --profile reference renders it exactly",
            scene.object_name(self.object as usize),
            self.size,
            self.distance,
        )
    }
}

/// The bounded primitive of `prims` (in an f32 frame, at or near the camera) reaching
/// farthest beyond [`F32_RANGE`], if one does, else the one with the smallest ratio of
/// size to distance; `None` for a scene without bounded primitives.
/// Unbounded quadrics have no size and the floor's is fixed: neither is a candidate.
/// (Lights do not count: a shadow ray starts at the surface, so a far light only sets
/// its direction.)
pub fn smallest_detail(prims: &PrimSet) -> Option<Detail> {
    let mut scan = Scan {
        floor: prims.floor.as_ref(),
        smallest: None,
    };
    for kind in PrimKind::BVH_KINDS {
        if kind == PrimKind::Triangle {
            // most scenes' bulk: loops of their own, without the kind's dispatch; in
            // the order of `PrimSet::each_triangle` (the first of equals wins)
            for i in 0..prims.tri_corners.len() {
                scan.visit(kind, i, prims.triangle(i).bounds());
            }
            for b in &prims.blocks {
                scan.visit_block(b);
            }
        } else {
            for i in 0..prims.len(kind) {
                scan.visit(kind, i, prims.bounds(kind, i));
            }
        }
    }
    scan.smallest.map(|(_, kind, i)| {
        let (reach, size, c) = measure(prims.bounds(kind, i));
        Detail {
            object: prims.object(prim_code(kind, i)),
            size: f64::from(size.length()),
            distance: f64::from(c.length().max(scan.to_floor(c).length())),
            reach: f64::from(reach),
        }
    })
}

/// A bounded primitive's reach (largest coordinate), size (the diagonal) and centre.
#[inline(always)]
fn measure(b: Aabb) -> (f32, Vec3, Vec3) {
    let reach = b.lo.abs().max(b.hi.abs()).max_element();
    (reach, b.hi - b.lo, (b.lo + b.hi) * 0.5)
}

/// [`smallest_detail`]'s pass: the floor and the best so far.
struct Scan<'a> {
    floor: Option<&'a Floor32>,
    smallest: Option<((f32, f64), PrimKind, usize)>,
}

impl Scan<'_> {
    /// From `c` to the nearest point of the floor (zero without a floor).
    #[inline(always)]
    fn to_floor(&self, c: Vec3) -> Vec3 {
        self.floor.map_or(Vec3::ZERO, |f| {
            Vec3::new(c.x.clamp(f.x0, f.x1), c.y.clamp(f.y0, f.y1), f.z) - c
        })
    }

    /// Ranks primitive `i` of `kind`, bounds `b`, by (reach beyond the range, then
    /// ratio): the lowest wins, the first of equals. The ratio is compared in squares,
    /// in f64 (where an f32 value's square is exact, and sizes below 1e-19 or distances
    /// past 1e19 neither vanish nor overflow): no square root per primitive. Inlined
    /// into each loop: out of line, its bounds went through memory (a stalled load each).
    #[inline(always)]
    fn visit(&mut self, kind: PrimKind, i: usize, b: Aabb) {
        let d2 = |v: Vec3| v.as_dvec3().length_squared();
        let (reach, size, c) = measure(b);
        let distance2 = d2(c).max(d2(self.to_floor(c)));
        let rank = (-(reach - F32_RANGE).max(0.0), d2(size) / distance2);
        if self.smallest.is_none_or(|(r, _, _)| rank < r) {
            self.smallest = Some((rank, kind, i));
        }
    }

    /// [`Scan::visit`] of the triangles of block `b`, in lane order, for those eight
    /// at a time an f32 estimate cannot rule out: one whose squared size or distance
    /// lies outside [2⁻⁶⁰, 2⁶⁰] (where f32 squares may lose it; so also any reaching
    /// past the range, whose size or centre then exceeds 2⁴¹ on an axis, and any with
    /// non-finite bounds), or one whose squared ratio is within 2⁻¹⁰ of the best so
    /// far. The estimate's squares, sums and product err by a few units of 2⁻²⁴, so no
    /// triangle that `visit` would rank first is skipped; the others are only read (a
    /// million triangles: one pass over their blocks).
    #[inline(always)]
    fn visit_block(&mut self, b: &TriBlock) {
        const LO: f32 = 1.0 / (1u64 << 60) as f32;
        const HI: f32 = (1u64 << 60) as f32;
        let v = &b.tri.v;
        // the bounds as `Triangle32::bounds` makes them (the same values: corners are
        // never NaN)
        let lo = [0, 1, 2].map(|a| v[0][a].min(v[1][a]).min(v[2][a]));
        let hi = [0, 1, 2].map(|a| v[0][a].max(v[1][a]).max(v[2][a]));
        let dot = |p: [f32x8; 3]| dot3(p, p);
        let size2 = dot([0, 1, 2].map(|a| hi[a] - lo[a]));
        let c = [0, 1, 2].map(|a| (lo[a] + hi[a]) * f32x8::splat(0.5));
        let mut dist2 = dot(c);
        if let Some(f) = self.floor {
            let s = f32x8::splat;
            let to = [
                c[0].max(s(f.x0)).min(s(f.x1)) - c[0],
                c[1].max(s(f.y0)).min(s(f.y1)) - c[1],
                s(f.z) - c[2],
            ];
            dist2 = dist2.max(dot(to));
        }
        let (lo_, hi_) = (f32x8::splat(LO), f32x8::splat(HI));
        let estimated = size2.ge(lo_) & size2.le(hi_) & dist2.ge(lo_) & dist2.le(hi_);
        let mut open = !estimated.bits();
        match self.smallest {
            None => open = u32::MAX,
            // past the range: only a triangle reaching farther can win
            Some(((excess, _), _, _)) if excess < 0.0 => {}
            Some(((_, ratio2), _, _)) => {
                let bound = f32x8::splat((ratio2 * (1.0 + 1.0 / 1024.0)) as f32);
                open |= size2.le(bound * dist2).bits();
            }
        }
        open &= (1u32 << b.count) - 1;
        while open != 0 {
            let l = open.trailing_zeros() as usize;
            open &= open - 1;
            let i = b.first as usize + l;
            self.visit(PrimKind::Triangle, i, b.tri.lane(l).bounds());
        }
    }
}

#[cfg(test)]
mod tests {
    use glam::DVec3;

    use super::*;
    use crate::geometry::triangle::Triangle32;
    use crate::math::test_rng::Xorshift;

    /// A triangle about `size` across, `distance` from the camera in a random direction
    /// in front of it.
    fn triangle_at(unit: &mut impl FnMut() -> f64, distance: f64, size: f64) -> Triangle32 {
        let at = DVec3::new(unit() - 0.5, unit() - 0.5, unit()).normalize() * distance;
        let v =
            [0.0, 1.0, 2.0].map(|k: f64| at + DVec3::new(unit(), unit() + k, unit() * k) * size);
        Triangle32::new(&v, DVec3::ZERO)
    }

    /// The ranking in squares picks the primitive that sizes and distances in f32
    /// (square roots and a division per primitive) pick, with the same figures: over
    /// triangles whose ratios of size to distance span a decade at distances over six,
    /// with and without a floor far below the camera (which then sets the distance of
    /// the triangles near the camera), an exact tie (the first wins) and, in some
    /// rounds, a triangle reaching past the f32 range (it wins whatever its ratio).
    #[test]
    fn smallest_detail_in_squares_picks_what_lengths_pick() {
        let mut rng = Xorshift(0x9e37_79b9_7f4a_7c15);
        let mut unit = move || rng.f64();
        for round in 0..40 {
            let mut tris: Vec<Triangle32> = (0..500)
                .map(|_| {
                    // ratios over one decade, distances over six: the ratio decides
                    let distance = 10f64.powf(unit() * 6.0);
                    let size = 10f64.powf(unit() - 4.0) * distance;
                    triangle_at(&mut unit, distance, size)
                })
                .collect();
            if round % 4 == 3 {
                let far = f64::from(F32_RANGE) * 2.0;
                let v = [0.0, 1.0, 2.0].map(|k| DVec3::new(far, k * 1e6, far));
                tris.insert(100, Triangle32::new(&v, DVec3::ZERO));
            }
            let mut prims = PrimSet::from_triangles(tris);
            prims.triangle_obj = (0..prims.tri_corners.len() as u32).collect();
            if round % 2 == 1 {
                // the floor 1e4 below the camera: the farther of it and the camera
                prims.floor = Some(Floor32::new(DVec3::new(0.0, 0.0, 1e4)));
            }
            // the ranking by lengths, in f32, as it was
            let distance = |c: Vec3| {
                let floor = prims.floor.as_ref().map_or(0.0, |f| {
                    Vec3::new(c.x.clamp(f.x0, f.x1), c.y.clamp(f.y0, f.y1), f.z).distance(c)
                });
                c.length().max(floor)
            };
            let mut best: Option<((f32, f32), usize)> = None;
            for i in 0..prims.tri_corners.len() {
                let b = prims.bounds(PrimKind::Triangle, i);
                let reach = b.lo.abs().max(b.hi.abs()).max_element();
                let ratio = (b.hi - b.lo).length() / distance((b.lo + b.hi) * 0.5);
                let rank = (-(reach - F32_RANGE).max(0.0), ratio);
                if best.is_none_or(|(r, _)| rank < r) {
                    best = Some((rank, i));
                }
            }
            let (_, i) = best.expect("triangles");
            let b = prims.bounds(PrimKind::Triangle, i);
            let d = smallest_detail(&prims).expect("triangles");
            assert_eq!(d.object, i as u32, "round {round}");
            assert_eq!(d.size, f64::from((b.hi - b.lo).length()), "round {round}");
            assert_eq!(
                d.distance,
                f64::from(distance((b.lo + b.hi) * 0.5)),
                "round {round}"
            );
            assert_eq!(d.beyond_range(), round % 4 == 3, "round {round}");
            // an exact tie: a copy of the winner, later in the array, loses
            prims.add_triangle(prims.triangle(i), u32::MAX);
            assert_eq!(smallest_detail(&prims).map(|d| d.object), Some(i as u32));
        }
    }

    /// The block pass (eight triangles at a time, an f32 estimate ruling most out)
    /// picks the triangle the plain pass picks: every triangle's exact rank, in
    /// `PrimSet::each_triangle`'s order. Packed scenes of triangles over many scales,
    /// with and without a floor: distances across 10 decades, sizes across 6.5 below
    /// them, some below the estimate's range (2⁻⁶⁰ squared), exact ties (copies), in
    /// some rounds a near tie (below), degenerate ones at and beside the camera, or
    /// two reaching past the f32 range by different amounts.
    #[test]
    fn the_block_pass_picks_what_every_triangle_ranked_picks() {
        use crate::bvh::Bvh;
        let plain = |prims: &PrimSet| {
            let mut scan = Scan {
                floor: prims.floor.as_ref(),
                smallest: None,
            };
            for (i, t) in prims.each_triangle() {
                scan.visit(PrimKind::Triangle, i, t.bounds());
            }
            scan.smallest.map(|(rank, _, i)| (rank, i))
        };
        let mut rng = Xorshift(0x2545_f491_4f6c_dd1d);
        let mut unit = move || rng.f64();
        for round in 0..48 {
            let n = 50 + round * 37;
            let mut tris: Vec<Triangle32> = (0..n)
                .map(|_| {
                    let distance = 10f64.powf(unit() * 10.0 - 4.0);
                    let decades = if round % 3 == 0 { 2.5 } else { 6.5 };
                    let size = 10f64.powf((unit() - 1.0) * decades) * distance;
                    triangle_at(&mut unit, distance, size)
                })
                .collect();
            if round % 3 == 0 {
                // a near tie, smaller than the rest (ratios above 10^-2.5): two triangles
                // 1000 from the camera, on opposite sides (in different blocks, the
                // smaller in the later one: leaves go from low x to high), 0.25 across
                // and 2⁻¹² less (corners on f32's grid there, 2⁻¹⁴): squared ratios 2⁻¹¹
                // apart
                let g = 1.0 / 16384.0;
                let pair =
                    [(-1000.0, -4096.0 * g), (1000.0, 4095.0 * g)].map(|(x, e)| Triangle32 {
                        v: [
                            Vec3::new(x, 0.0, 1000.0),
                            Vec3::new(x + e, 0.0, 1000.0),
                            Vec3::new(x, e, 1000.0),
                        ],
                    });
                for t in pair {
                    let at = (unit() * tris.len() as f64) as usize;
                    tris.insert(at, t);
                }
            }
            let n = tris.len();
            let pick = |u: f64| (u * n as f64) as usize % n;
            // ties: copies of some triangles, later in the array
            for _ in 0..3 {
                let t = tris[pick(unit())];
                tris.push(t);
            }
            if round % 6 == 2 {
                // degenerate: a point, at the camera and beside it
                tris.insert(pick(unit()), Triangle32 { v: [Vec3::ZERO; 3] });
                tris.insert(pick(unit()), Triangle32 { v: [Vec3::ONE; 3] });
            }
            if round % 4 == 3 {
                let far = f64::from(F32_RANGE);
                for k in 1..3 {
                    let x = far * (1.0 + k as f64 * unit());
                    let v = [0.0, 1.0, 2.0].map(|j| DVec3::new(x, j * 1e6, x));
                    tris.insert(pick(unit()), Triangle32::new(&v, DVec3::ZERO));
                }
            }
            let mut prims = PrimSet::from_triangles(tris);
            prims.triangle_obj = (0..prims.tri_corners.len() as u32).collect();
            if round % 2 == 1 {
                prims.floor = Some(Floor32::new(DVec3::new(0.0, 0.0, 10f64.powf(unit() * 6.0))));
            }
            let bvh = Bvh::build(prims);
            assert!(!bvh.prims.blocks.is_empty(), "round {round}: packed");
            let (rank, i) = plain(&bvh.prims).expect("triangles");
            let d = smallest_detail(&bvh.prims).expect("triangles");
            assert_eq!(
                d.object, bvh.prims.triangle_obj[i],
                "round {round}, rank {rank:?}"
            );
            assert_eq!(d.beyond_range(), round % 4 == 3, "round {round}");
        }
    }

    /// The margin is needed and enough: a best triangle, then the same triangle with one
    /// corner coordinate moved by one unit in the last place (ratios within a few units
    /// of 2⁻²⁴, where the estimate alone cannot tell them apart), packed in a block:
    /// the block pass takes the second exactly when ranking it takes it (with no margin,
    /// about 2 % of the better ones were skipped).
    #[test]
    fn the_block_pass_keeps_a_triangle_one_ulp_better() {
        use crate::geometry::triangle::{TriBlock, Triangle8};
        let mut rng = Xorshift(0x0bad_5eed_1234_5678);
        let mut unit = move || rng.f64();
        let floor = Floor32::new(DVec3::new(0.0, 0.0, 3.0));
        let (mut better, mut taken) = (0, 0);
        for trial in 0..20_000 {
            let distance = 10f64.powf(unit() * 8.0 - 3.0);
            let size = 10f64.powf(unit() * 3.0 - 3.0) * distance;
            let t1 = triangle_at(&mut unit, distance, size);
            let mut t2 = t1;
            let (k, a) = ((unit() * 3.0) as usize % 3, (unit() * 3.0) as usize % 3);
            let x = t2.v[k][a];
            t2.v[k][a] = if unit() < 0.5 {
                x.next_up()
            } else {
                x.next_down()
            };
            let floor = (trial % 2 == 1).then_some(&floor);
            let scan = || Scan {
                floor,
                smallest: None,
            };
            let mut exact = scan();
            exact.visit(PrimKind::Triangle, 0, t1.bounds());
            exact.visit(PrimKind::Triangle, 1, t2.bounds());
            let mut blocks = scan();
            blocks.visit(PrimKind::Triangle, 0, t1.bounds());
            blocks.visit_block(&TriBlock {
                tri: Triangle8::new(&[t2]),
                first: 1,
                count: 1,
                one_leaf: true,
            });
            let pick = |s: &Scan| s.smallest.map(|(_, _, i)| i);
            assert_eq!(
                pick(&blocks),
                pick(&exact),
                "trial {trial}: {t1:?} then {t2:?}"
            );
            better += usize::from(pick(&exact) == Some(1));
            taken += usize::from(pick(&blocks) == Some(1));
        }
        // the pairs did put the second ahead, often
        assert!(
            better > 2_000 && taken == better,
            "{better} better, {taken} taken"
        );
    }
}
