//! Triangle: `triangle x1 y1 z1  x2 y2 z2  x3 y3 z3` then the material.
//!
//! The test is the watertight one of Woop, Benthin and Wald (2013), as in pbrt-v4:
//! vertices are moved into a ray-aligned frame (translate, permute so the largest
//! direction component is z, shear), and the three 2D edge functions decide
//! inside/outside. Each edge function depends only on its own edge, so two triangles
//! sharing an edge agree about it: no ray slips between them. Edge functions of exactly
//! 0 count as inside, so a ray through a shared edge hits both (ties go to the first).

use glam::DVec3;

use glam::Vec3;
use wide::f32x8;

use super::{RefHit, Surface8, Surface32, SurfacePoint};
use crate::math::Aabb;
use crate::math::Ray;
use crate::math::float::gamma;
use crate::math::packet::{Cmp8, Mask8, Ray1, RayPacket8, Vec3x8, gamma32};
use crate::scene::parse::is_degenerate_triangle;
use crate::simd;
use crate::simd::packet::{RayLanes, sub3};

// ---------------------------------------------------------------- reference (f64)

/// ab − cd with one rounding less (Kahan's difference of products, with FMA).
fn difference_of_products(a: f64, b: f64, c: f64, d: f64) -> f64 {
    let cd = c * d;
    let err = (-c).mul_add(d, cd);
    let dop = a.mul_add(b, -cd);
    dop + err
}

/// Nearest hit with 0 < t < t_max, with barycentrics (b0, b1, b2) of the hit point.
pub fn intersect_ref(v: &[DVec3; 3], ray: &Ray, t_max: f64) -> Option<RefHit> {
    // degenerate triangles (zero area) are never hit
    if is_degenerate_triangle(v) {
        return None;
    }
    // translate the vertices to the ray origin
    let mut p = v.map(|q| q - ray.origin);
    // permute so that the largest direction component is z
    let da = ray.dir.abs();
    let kz = if da.x > da.y && da.x > da.z {
        0
    } else if da.y > da.z {
        1
    } else {
        2
    };
    let (kx, ky) = ((kz + 1) % 3, (kz + 2) % 3);
    let perm = |q: DVec3| DVec3::new(q[kx], q[ky], q[kz]);
    let d = perm(ray.dir);
    p = p.map(perm);
    // shear so the ray runs along +z
    let (sx, sy, sz) = (-d.x / d.z, -d.y / d.z, 1.0 / d.z);
    for q in &mut p {
        q.x += sx * q.z;
        q.y += sy * q.z;
    }
    // edge functions
    let e0 = difference_of_products(p[1].x, p[2].y, p[1].y, p[2].x);
    let e1 = difference_of_products(p[2].x, p[0].y, p[2].y, p[0].x);
    let e2 = difference_of_products(p[0].x, p[1].y, p[0].y, p[1].x);
    // reject when the edge functions disagree in sign (zero counts as inside)
    if (e0 < 0.0 || e1 < 0.0 || e2 < 0.0) && (e0 > 0.0 || e1 > 0.0 || e2 > 0.0) {
        return None;
    }
    let det = e0 + e1 + e2;
    if det == 0.0 {
        return None; // the ray lies in the triangle's plane
    }
    // scaled distance, compared without dividing
    for q in &mut p {
        q.z *= sz;
    }
    let t_scaled = e0 * p[0].z + e1 * p[1].z + e2 * p[2].z;
    if det < 0.0 && (t_scaled >= 0.0 || t_scaled < t_max * det) {
        return None;
    }
    if det > 0.0 && (t_scaled <= 0.0 || t_scaled > t_max * det) {
        return None;
    }
    let inv_det = 1.0 / det;
    let t = t_scaled * inv_det;
    // t must be positive beyond its own rounding error (pbrt-v4's bound)
    let max_z = p.iter().map(|q| q.z.abs()).fold(0.0, f64::max);
    let max_x = p.iter().map(|q| q.x.abs()).fold(0.0, f64::max);
    let max_y = p.iter().map(|q| q.y.abs()).fold(0.0, f64::max);
    let delta_z = gamma(3) * max_z;
    let delta_x = gamma(5) * (max_x + max_z);
    let delta_y = gamma(5) * (max_y + max_z);
    let delta_e = 2.0 * (gamma(2) * max_x * max_y + delta_y * max_x + delta_x * max_y);
    let max_e = e0.abs().max(e1.abs()).max(e2.abs());
    let delta_t =
        3.0 * (gamma(3) * max_e * max_z + delta_e * max_z + delta_z * max_e) * inv_det.abs();
    if t <= delta_t || t >= t_max {
        return None;
    }
    Some(RefHit {
        t,
        bary: DVec3::new(e0, e1, e2) * inv_det,
        part: 0,
    })
}

/// Surface at a hit: the point from barycentrics (accurate even for grazing rays),
/// the unit normal (b − a) × (c − a).
pub fn surface_ref(v: &[DVec3; 3], hit: &RefHit) -> SurfacePoint {
    let b = hit.bary;
    let terms = [v[0] * b.x, v[1] * b.y, v[2] * b.z];
    let point = terms[0] + terms[1] + terms[2];
    let err = (terms[0].abs() + terms[1].abs() + terms[2].abs()) * gamma(7);
    let normal = (v[1] - v[0]).cross(v[2] - v[0]).normalize();
    SurfacePoint { point, normal, err }
}

// ---------------------------------------------------------------- fast path (f32)
//
// Edge functions are plain products and one subtraction, never an FMA: the shared edge
// of two triangles then gives exactly opposite values in both (a·b − c·d rounds the same
// as −(c·d − a·b)), which is what makes the test watertight. An FMA rounds only one of
// the two products and breaks that symmetry.

/// A triangle in the fast path's f32 frame: its three vertices.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Triangle32 {
    pub v: [Vec3; 3],
}

impl Triangle32 {
    /// From scene data, relative to `base`.
    pub fn new(v: &[DVec3; 3], base: DVec3) -> Triangle32 {
        Triangle32 {
            v: v.map(|p| (p - base).as_vec3()),
        }
    }

    pub fn bounds(&self) -> Aabb {
        Aabb::new(
            self.v[0].min(self.v[1]).min(self.v[2]),
            self.v[0].max(self.v[1]).max(self.v[2]),
        )
    }

    /// Where a ray of the f32 frame meets the triangle's plane, in f64 (no edge test):
    /// the floor tie's arbiter ([`crate::geometry::PrimSet`]'s floor test).
    pub fn plane_t_f64(&self, o: DVec3, d: DVec3) -> Option<f64> {
        let v = self.v.map(|p| p.as_dvec3());
        let n = (v[1] - v[0]).cross(v[2] - v[0]);
        let t = n.dot(v[0] - o) / n.dot(d);
        t.is_finite().then_some(t)
    }

    /// Nearest hit with 0 < t <= t_max (inclusive: the caller breaks exact ties):
    /// (t, b1, b2), the barycentrics of the second and third vertex.
    #[inline]
    pub fn intersect_1(&self, r: &Ray1, t_max: f32) -> Option<(f32, f32, f32)> {
        // (degenerate triangles are dropped when the primitives are built)
        // translate the vertices to the ray origin
        // permute so that the largest direction component is z
        let mut p = self.v.map(|q| r.permute(q - r.origin));
        // shear so the ray runs along +z
        for q in &mut p {
            q.x += r.shear.x * q.z;
            q.y += r.shear.y * q.z;
        }
        // edge functions
        let e0 = p[1].x * p[2].y - p[1].y * p[2].x;
        let e1 = p[2].x * p[0].y - p[2].y * p[0].x;
        let e2 = p[0].x * p[1].y - p[0].y * p[1].x;
        // reject when the edge functions disagree in sign (zero counts as inside)
        if (e0 < 0.0 || e1 < 0.0 || e2 < 0.0) && (e0 > 0.0 || e1 > 0.0 || e2 > 0.0) {
            return None;
        }
        let det = e0 + e1 + e2;
        if det == 0.0 {
            return None;
        }
        // scaled distance, compared without dividing (against a bound 4 ulp above
        // t_max, so that t == t_max survives the rounding of the product and exact
        // ties reach the caller; the division below decides)
        let z = p.map(|q| q.z * r.shear.z);
        let t_scaled = e0 * z[0] + e1 * z[1] + e2 * z[2];
        let t_lim = t_max * (1.0 + 4.0 * f32::EPSILON);
        if det < 0.0 && (t_scaled >= 0.0 || t_scaled < t_lim * det) {
            return None;
        }
        if det > 0.0 && (t_scaled <= 0.0 || t_scaled > t_lim * det) {
            return None;
        }
        let inv_det = 1.0 / det;
        let t = t_scaled * inv_det;
        // t must be positive beyond its own rounding error (pbrt-v4's bound)
        let max_z = z[0].abs().max(z[1].abs()).max(z[2].abs());
        let max_x = p[0].x.abs().max(p[1].x.abs()).max(p[2].x.abs());
        let max_y = p[0].y.abs().max(p[1].y.abs()).max(p[2].y.abs());
        let delta_z = gamma32(3) * max_z;
        let delta_x = gamma32(5) * (max_x + max_z);
        let delta_y = gamma32(5) * (max_y + max_z);
        let delta_e = 2.0 * (gamma32(2) * max_x * max_y + delta_y * max_x + delta_x * max_y);
        let max_e = e0.abs().max(e1.abs()).max(e2.abs());
        let delta_t =
            3.0 * (gamma32(3) * max_e * max_z + delta_e * max_z + delta_z * max_e) * inv_det.abs();
        if t <= delta_t || t > t_max {
            return None;
        }
        Some((t, e1 * inv_det, e2 * inv_det))
    }

    /// Whether the triangle meets the ray with 0 < t < t_max.
    #[inline]
    pub fn occluded_1(&self, r: &Ray1, t_max: f32) -> bool {
        self.intersect_1(r, t_max).is_some_and(|h| h.0 < t_max)
    }

    /// Packet twin of [`Triangle32::intersect_1`]: lanes with a hit in (0, t_max], t, b1, b2.
    #[inline]
    pub fn intersect_x8(
        &self,
        r: &RayPacket8,
        active: Mask8,
        t_max: f32x8,
    ) -> (Mask8, f32x8, f32x8, f32x8) {
        // (splatted one by one: a `map` over the array stayed a call)
        let [a, b, c] = self.v;
        let v = [Vec3x8::splat(a), Vec3x8::splat(b), Vec3x8::splat(c)];
        intersect_splat_x8(v, r, active, t_max)
    }

    /// Lanes of `active` whose ray meets the triangle with 0 < t < t_max.
    #[inline]
    pub fn occluded_x8(&self, r: &RayPacket8, active: Mask8, t_max: f32x8) -> Mask8 {
        let (m, t, _, _) = self.intersect_x8(r, active, t_max);
        m & t.lt(t_max)
    }

    /// Surface at a hit: the point from barycentrics, the unit normal (b − a) × (c − a).
    pub fn surface_1(&self, b1: f32, b2: f32) -> Surface32 {
        let b0 = 1.0 - b1 - b2;
        let terms = [self.v[0] * b0, self.v[1] * b1, self.v[2] * b2];
        let point = terms[0] + terms[1] + terms[2];
        let err = (terms[0].abs() + terms[1].abs() + terms[2].abs()) * gamma32(7);
        let normal = (self.v[1] - self.v[0])
            .cross(self.v[2] - self.v[0])
            .normalize_or(Vec3::Z);
        Surface32 { point, normal, err }
    }

    /// [`Triangle32::surface_1`] on eight lanes, operation for operation.
    pub fn surface_x8(&self, b1: f32x8, b2: f32x8) -> Surface8 {
        surface_lanes(self.v.map(Vec3x8::splat), b1, b2)
    }
}

/// [`Triangle32::surface_1`] of eight triangles at once: lane i of the corners `v` is
/// triangle i's, with its barycentrics `b1`, `b2`; operation for operation, so every
/// lane has the bits `surface_1` gives (glam's products, sums and `normalize_or`).
pub fn surface_lanes(v: [Vec3x8; 3], b1: f32x8, b2: f32x8) -> Surface8 {
    let b0 = f32x8::splat(1.0) - b1 - b2;
    let [a, b, c] = v;
    let terms = [a * b0, b * b1, c * b2];
    let point = terms[0] + terms[1] + terms[2];
    let err = (terms[0].abs() + terms[1].abs() + terms[2].abs()) * f32x8::splat(gamma32(7));
    let n = (b - a).cross(c - a);
    // `normalize_or(Vec3::Z)`: n / |n| where 1/|n| is finite and positive
    let rcp = f32x8::splat(1.0) / n.length();
    let ok = rcp.lt(f32x8::splat(f32::INFINITY)) & rcp.gt(f32x8::ZERO);
    let z = Vec3x8::splat(Vec3::Z);
    Surface8 {
        point,
        normal: Vec3x8::select(ok, n * rcp, z),
        err,
    }
}

/// [`Triangle32::intersect_x8`] of the triangle whose vertices `v` are given splatted
/// (the frustum walk reads them straight from a triangle block, one broadcast each,
/// instead of unpacking a [`Triangle32`] to splat it again).
#[inline(always)]
pub fn intersect_splat_x8(
    v: [Vec3x8; 3],
    r: &RayPacket8,
    active: Mask8,
    t_max: f32x8,
) -> (Mask8, f32x8, f32x8, f32x8) {
    // translate the vertices to the ray origin
    // permute so that the largest direction component is z
    // (an explicit array: `map` here is left as an outlined call in the any-hit walk)
    let mut p = [
        r.permute(v[0] - r.origin),
        r.permute(v[1] - r.origin),
        r.permute(v[2] - r.origin),
    ];
    // shear so the ray runs along +z
    for q in &mut p {
        q.x += r.shear.x * q.z;
        q.y += r.shear.y * q.z;
    }
    let p = [
        [p[0].x, p[0].y, p[0].z],
        [p[1].x, p[1].y, p[1].z],
        [p[2].x, p[2].y, p[2].z],
    ];
    sheared_x8(p, r.shear.z, active, t_max)
}

/// The watertight test from the vertices translated to the ray origin on (`moved`,
/// not yet permuted), at any width.
#[inline(always)]
fn from_moved<L: simd::Lanes>(
    moved: [[L; 3]; 3],
    r: &RayLanes<L>,
    active: L::Mask,
    t_max: L,
) -> (L::Mask, L, L, L) {
    let mut p = [
        r.permute(moved[0]),
        r.permute(moved[1]),
        r.permute(moved[2]),
    ];
    for q in &mut p {
        q[0] = q[0] + r.shear[0] * q[2];
        q[1] = q[1] + r.shear[1] * q[2];
    }
    sheared(p, r.shear[2], active, t_max)
}

/// The watertight test from the sheared vertices on, at any width (one ray against
/// eight triangles, or eight or sixteen rays against one): edge functions, the sign
/// rule, the distance compared without dividing and its rounding bound. `p`: the
/// vertices translated to the ray origin, permuted, and sheared in x and y (z not yet
/// scaled); `shear_z`: `1/d[kz]`. Every width runs the same operations in the same order,
/// so a lane's answer does not depend on the width (`tests/lanes.rs`).
#[inline(always)]
pub(crate) fn sheared<L: simd::Lanes>(
    p: [[L; 3]; 3],
    shear_z: L,
    active: L::Mask,
    t_max: L,
) -> (L::Mask, L, L, L) {
    use crate::simd::LaneMask as _;
    let zero = L::zero();
    // edge functions
    let e0 = p[1][0] * p[2][1] - p[1][1] * p[2][0];
    let e1 = p[2][0] * p[0][1] - p[2][1] * p[0][0];
    let e2 = p[0][0] * p[1][1] - p[0][1] * p[1][0];
    // reject when the edge functions disagree in sign (zero counts as inside)
    let any_neg = e0.lt(zero) | e1.lt(zero) | e2.lt(zero);
    let any_pos = e0.gt(zero) | e1.gt(zero) | e2.gt(zero);
    let det = e0 + e1 + e2;
    let valid = active.and_not(any_neg & any_pos).and_not(det.eq(zero));
    if valid.none() {
        return (valid, zero, zero, zero);
    }
    // scaled distance, compared without dividing (bound 4 ulp above t_max, see
    // `Triangle32::intersect_1`)
    let z = [p[0][2] * shear_z, p[1][2] * shear_z, p[2][2] * shear_z];
    let t_scaled = e0 * z[0] + e1 * z[1] + e2 * z[2];
    let ts = t_scaled.xor_sign(det); // |det|-scaled t with the sign of det removed
    let adet = det.abs();
    let t_lim = t_max * L::splat(1.0 + 4.0 * f32::EPSILON);
    let valid = valid & ts.gt(zero) & ts.le(t_lim * adet);
    if valid.none() {
        return (valid, zero, zero, zero);
    }
    let inv_det = L::splat(1.0) / det;
    let t = t_scaled * inv_det;
    // t must be positive beyond its own rounding error (pbrt-v4's bound)
    // (functions, not closures: a closure is compiled without the AVX-512 of the
    // function it is inlined into, and would call each 16-lane operation)
    #[inline(always)]
    fn amax<L: simd::Lanes>(a: L, b: L, c: L) -> L {
        a.abs().max(b.abs()).max(c.abs())
    }
    let max_z = amax(z[0], z[1], z[2]);
    let max_x = amax(p[0][0], p[1][0], p[2][0]);
    let max_y = amax(p[0][1], p[1][1], p[2][1]);
    let (g2, g3, g5) = (
        L::splat(gamma32(2)),
        L::splat(gamma32(3)),
        L::splat(gamma32(5)),
    );
    let delta_z = g3 * max_z;
    let delta_x = g5 * (max_x + max_z);
    let delta_y = g5 * (max_y + max_z);
    let delta_e = L::splat(2.0) * (g2 * max_x * max_y + delta_y * max_x + delta_x * max_y);
    let max_e = amax(e0, e1, e2);
    let delta_t =
        L::splat(3.0) * (g3 * max_e * max_z + delta_e * max_z + delta_z * max_e) * inv_det.abs();
    let valid = valid & t.gt(delta_t) & t.le(t_max);
    (valid, t, e1 * inv_det, e2 * inv_det)
}

/// [`sheared`] on eight lanes.
#[inline(always)]
fn sheared_x8(p: [[f32x8; 3]; 3], shear_z: f32x8, active: Mask8, t_max: f32x8) -> Hits8 {
    sheared::<f32x8>(p, shear_z, active, t_max)
}

// ------------------------------------------- fast path, one ray against 8 triangles
//
// The same steps again, with the eight lanes holding eight triangles and the ray
// splatted. The ray's permutation is one choice for all lanes, so it only picks which
// coordinate arrays to read. Every operation is the scalar kernel's, in its order,
// without FMA, so each lane returns bit for bit what [`Triangle32::intersect_1`] returns
// for its triangle (`tests/wide_bvh.rs` checks this). The scalar kernel has no
// double-precision fallback for zero edge functions (zero counts as inside), so
// neither has this one.

/// One ray prepared for [`Triangle8`]: origin in the permuted frame and the shear, splatted.
#[derive(Clone, Copy, Debug)]
pub struct TriRay8 {
    /// Origin components (`o[kx], o[ky], o[kz]`).
    pub origin: [f32x8; 3],
    /// `−d[kx]·s, −d[ky]·s, s` with `s = 1/d[kz]`.
    pub shear: [f32x8; 3],
    /// (kx, ky, kz): the axes read as x, y, z.
    pub axes: [usize; 3],
}

impl TriRay8 {
    #[inline]
    pub fn new(r: &Ray1) -> TriRay8 {
        let axes = [(r.kz + 1) % 3, (r.kz + 2) % 3, r.kz];
        TriRay8 {
            origin: axes.map(|k| f32x8::splat(r.origin[k])),
            shear: [r.shear.x, r.shear.y, r.shear.z].map(f32x8::splat),
            axes,
        }
    }
}

/// Up to eight triangles of one leaf of the fast path's trees, SoA: after a BVH build,
/// the only store of a [`PrimSet`](super::PrimSet)'s triangles, in leaf order (lane i is
/// triangle `first + i`; lanes >= `count` are padding that never hits; the blocks
/// follow one another, each `first` the last one's `first + count`). 320 B = five
/// cache lines. Each lane's binary leaf box is kept beside it, in the wide tree's
/// `leaf_boxes`.
///
/// A lane's hit counts only when the ray also passes its binary leaf's box: then a
/// merged leaf reports exactly the triangles the binary walk reaches (the slab test is
/// monotone under box containment, so passing the leaf's box implies passing every
/// ancestor's), even for a ray lying in a box face with a ±0 direction component. In a
/// block of one binary leaf (`one_leaf`) every lane's leaf box is the slot's, which a
/// single ray has already passed.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
pub struct TriBlock {
    pub tri: Triangle8,
    pub first: u32,
    pub count: u32,
    /// All lanes come from one binary leaf, whose box is the slot's: the single-ray
    /// walks skip the lane boxes.
    pub one_leaf: bool,
}

const _: () = assert!(std::mem::size_of::<TriBlock>() == 320);

/// Eight triangles as structure of arrays, `v[vertex][axis]`, one triangle per lane.
/// 288 B. Unused lanes repeat one point three times: their edge functions are exactly
/// 0 (x·y − y·x), so det = 0 and they are never hit (or NaN on overflow: no hit either).
#[derive(Clone, Copy, Debug)]
pub struct Triangle8 {
    pub v: [[f32x8; 3]; 3],
}

impl Triangle8 {
    /// Triangle `j` (lane `j` of each coordinate).
    #[inline(always)]
    pub fn lane(&self, j: usize) -> Triangle32 {
        let c = |i: usize| {
            let p = &self.v[i];
            Vec3::new(p[0].as_array()[j], p[1].as_array()[j], p[2].as_array()[j])
        };
        Triangle32 {
            v: [c(0), c(1), c(2)],
        }
    }

    /// The corners of triangle `j`, each splatted (one broadcast from memory each).
    #[inline(always)]
    pub fn splat_lanes<L: simd::Lanes>(&self, j: usize) -> [[L; 3]; 3] {
        // by reference, no closure over lanes (see `simd::packet`)
        let v = &self.v;
        let c = |i: usize, a: usize| v[i][a].as_array()[j];
        [
            [L::splat(c(0, 0)), L::splat(c(0, 1)), L::splat(c(0, 2))],
            [L::splat(c(1, 0)), L::splat(c(1, 1)), L::splat(c(1, 2))],
            [L::splat(c(2, 0)), L::splat(c(2, 1)), L::splat(c(2, 2))],
        ]
    }

    /// Packs up to 8 triangles; lane i holds `tris[i]`, padding lanes repeat the first
    /// vertex three times. Written lane by lane: the BVH collapse packs every triangle
    /// through here.
    #[allow(clippy::needless_range_loop)] // `lane` indexes the innermost arrays
    pub fn new(tris: &[Triangle32]) -> Triangle8 {
        assert!(!tris.is_empty() && tris.len() <= 8, "1 to 8 triangles");
        let pad = tris[0].v[0];
        let mut v = [[[0.0f32; 8]; 3]; 3];
        for lane in 0..8 {
            let t = tris.get(lane).map_or([pad; 3], |t| t.v);
            for (vi, p) in t.iter().enumerate() {
                v[vi][0][lane] = p.x;
                v[vi][1][lane] = p.y;
                v[vi][2][lane] = p.z;
            }
        }
        Triangle8 {
            v: v.map(|q| q.map(f32x8::new)),
        }
    }

    /// Lane i of `active`: [`Triangle32::intersect_1`] of triangle i (hit in (0, t_max],
    /// t, b1, b2), the ray's permutation read from `r.axes` at run time.
    #[inline(always)]
    pub fn intersect_1x8(
        &self,
        r: &TriRay8,
        active: Mask8,
        t_max: f32,
    ) -> (Mask8, f32x8, f32x8, f32x8) {
        self.intersect_1x8_axes(r, r.axes, active, t_max)
    }

    /// [`Triangle8::intersect_1x8`] for a ray whose largest direction component is
    /// axis `KZ` (`r.axes[2] == KZ`): the permutation fixed at compile time, one copy of
    /// the kernel per axis.
    #[inline(always)]
    pub fn intersect_1x8_kz<const KZ: usize>(
        &self,
        r: &TriRay8,
        active: Mask8,
        t_max: f32,
    ) -> (Mask8, f32x8, f32x8, f32x8) {
        debug_assert_eq!(r.axes[2], KZ);
        self.intersect_1x8_axes(r, [(KZ + 1) % 3, (KZ + 2) % 3, KZ], active, t_max)
    }

    /// The 1×8 test with the permutation `[kx, ky, kz]` (`r.axes`, or the same axes as
    /// constants): each vertex vector loaded from the block at its axis's offset (by
    /// reference, so no copy of the nine goes through the stack).
    #[inline(always)]
    fn intersect_1x8_axes(
        &self,
        r: &TriRay8,
        [kx, ky, kz]: [usize; 3],
        active: Mask8,
        t_max: f32,
    ) -> (Mask8, f32x8, f32x8, f32x8) {
        let v = &self.v;
        // translate the vertices to the ray origin, permuted so that the largest
        // direction component is z
        let moved = |i: usize| {
            let q = &v[i];
            [
                q[kx] - r.origin[0],
                q[ky] - r.origin[1],
                q[kz] - r.origin[2],
            ]
        };
        let p = [moved(0), moved(1), moved(2)];
        // shear so the ray runs along +z
        let p = p.map(|q| [q[0] + r.shear[0] * q[2], q[1] + r.shear[1] * q[2], q[2]]);
        sheared_x8(p, r.shear[2], active, f32x8::splat(t_max))
    }

    /// Lanes of `active` whose triangle meets the ray with 0 < t < t_max.
    #[inline(always)]
    pub fn occluded_1x8(&self, r: &TriRay8, active: Mask8, t_max: f32) -> Mask8 {
        let (m, t, _, _) = self.intersect_1x8(r, active, t_max);
        m & t.lt(f32x8::splat(t_max))
    }

    /// [`Triangle8::occluded_1x8`] with the permutation fixed (`r.axes[2] == KZ`).
    #[inline(always)]
    pub fn occluded_1x8_kz<const KZ: usize>(
        &self,
        r: &TriRay8,
        active: Mask8,
        t_max: f32,
    ) -> Mask8 {
        let (m, t, _, _) = self.intersect_1x8_kz::<KZ>(r, active, t_max);
        m & t.lt(f32x8::splat(t_max))
    }
}

// ---------------------------------------------------------------- the test as a type

/// A packet kernel's answer: lanes with a hit in (0, t_max], t, b1, b2.
pub type Hits8 = (Mask8, f32x8, f32x8, f32x8);

/// The ray/triangle test of the fast path as a type: every triangle kernel of one
/// instantiation (profile knob `triangle_test`, chosen once per frame), at every width.
/// Each lane of a packet or 1×8 kernel returns bit for bit what `intersect_1` returns
/// for its ray and triangle.
pub trait TriangleKernel: Copy + Send + Sync + 'static {
    /// One ray prepared for the 1×8 kernel.
    type Ray1x8: Copy;

    fn prepare(r: &Ray1) -> Self::Ray1x8;

    /// Nearest hit with 0 < t <= t_max (inclusive: the caller breaks exact ties):
    /// (t, b1, b2), the barycentrics of the second and third vertex.
    fn intersect_1(tri: &Triangle32, r: &Ray1, t_max: f32) -> Option<(f32, f32, f32)>;

    /// The triangle whose vertices `v` are given splatted against a packet.
    fn intersect_splat_x8(v: [Vec3x8; 3], r: &RayPacket8, active: Mask8, t_max: f32x8) -> Hits8;

    /// The triangle whose vertices `v` are given splatted against a packet of any
    /// width; lane for lane what [`TriangleKernel::intersect_splat_x8`] returns.
    fn intersect_splat_lanes<L: simd::Lanes>(
        v: [[L; 3]; 3],
        r: &RayLanes<L>,
        active: L::Mask,
        t_max: L,
    ) -> (L::Mask, L, L, L);

    /// A block's eight triangles made ready for packets whose lanes all share one
    /// origin: what the kernel computes from the triangle and the origin alone, once for
    /// the block instead of once per lane and triangle.
    type Moved: Copy;

    /// [`TriangleKernel::Moved`] of block `b` for the origin `o` (splatted).
    fn move_block(b: &Triangle8, o: [f32x8; 3]) -> Self::Moved;

    /// Triangle `j` of block `b`, moved to `m`, against a packet whose every lane of
    /// `active` has, bit for bit, the origin the block was moved to; lane for lane what
    /// [`TriangleKernel::intersect_splat_lanes`] returns for that triangle.
    fn intersect_moved_lanes<L: simd::Lanes>(
        b: &Triangle8,
        m: &Self::Moved,
        j: usize,
        r: &RayLanes<L>,
        active: L::Mask,
        t_max: L,
    ) -> (L::Mask, L, L, L);

    /// One ray (whose largest direction component is axis `KZ`, or any `KZ` > 2: the
    /// ray's own, read at run time) against the eight triangles of a block: lane i is
    /// triangle i.
    fn intersect_1x8<const KZ: usize>(
        b: &Triangle8,
        r: &Self::Ray1x8,
        active: Mask8,
        t_max: f32,
    ) -> Hits8;

    /// Whether the triangle meets the ray with 0 < t < t_max.
    #[inline(always)]
    fn occluded_1(tri: &Triangle32, r: &Ray1, t_max: f32) -> bool {
        Self::intersect_1(tri, r, t_max).is_some_and(|h| h.0 < t_max)
    }

    /// A packet against one triangle.
    #[inline(always)]
    fn intersect_x8(tri: &Triangle32, r: &RayPacket8, active: Mask8, t_max: f32x8) -> Hits8 {
        // (splatted one by one: a `map` over the array was left as a call)
        let [a, b, c] = tri.v;
        let v = [Vec3x8::splat(a), Vec3x8::splat(b), Vec3x8::splat(c)];
        Self::intersect_splat_x8(v, r, active, t_max)
    }

    /// Lanes of `active` whose ray meets the triangle with 0 < t < t_max.
    #[inline(always)]
    fn occluded_x8(tri: &Triangle32, r: &RayPacket8, active: Mask8, t_max: f32x8) -> Mask8 {
        let (m, t, _, _) = Self::intersect_x8(tri, r, active, t_max);
        m & t.lt(t_max)
    }

    /// Lanes of `active` whose triangle meets the ray with 0 < t < t_max.
    #[inline(always)]
    fn occluded_1x8<const KZ: usize>(
        b: &Triangle8,
        r: &Self::Ray1x8,
        active: Mask8,
        t_max: f32,
    ) -> Mask8 {
        let (m, t, _, _) = Self::intersect_1x8::<KZ>(b, r, active, t_max);
        m & t.lt(f32x8::splat(t_max))
    }
}

/// The watertight test of Woop, Benthin and Wald (2013): no ray passes between two
/// triangles sharing an edge. The default.
#[derive(Clone, Copy, Debug, Default)]
pub struct Watertight;

impl TriangleKernel for Watertight {
    type Ray1x8 = TriRay8;

    #[inline(always)]
    fn prepare(r: &Ray1) -> TriRay8 {
        TriRay8::new(r)
    }

    #[inline(always)]
    fn intersect_1(tri: &Triangle32, r: &Ray1, t_max: f32) -> Option<(f32, f32, f32)> {
        tri.intersect_1(r, t_max)
    }

    #[inline(always)]
    fn intersect_splat_x8(v: [Vec3x8; 3], r: &RayPacket8, active: Mask8, t_max: f32x8) -> Hits8 {
        intersect_splat_x8(v, r, active, t_max)
    }

    #[inline(always)]
    fn intersect_splat_lanes<L: simd::Lanes>(
        v: [[L; 3]; 3],
        r: &RayLanes<L>,
        active: L::Mask,
        t_max: L,
    ) -> (L::Mask, L, L, L) {
        // the steps of `intersect_splat_x8` (no closures: see `sheared`)
        let moved = [
            sub3(v[0], r.origin),
            sub3(v[1], r.origin),
            sub3(v[2], r.origin),
        ];
        from_moved(moved, r, active, t_max)
    }

    /// The vertices translated to the origin: eight triangles' subtractions in one,
    /// each lane's bits those of `intersect_splat_lanes`'s own.
    type Moved = Triangle8;

    #[inline(always)]
    fn move_block(b: &Triangle8, o: [f32x8; 3]) -> Triangle8 {
        let v = &b.v;
        Triangle8 {
            v: [sub3(v[0], o), sub3(v[1], o), sub3(v[2], o)],
        }
    }

    #[inline(always)]
    fn intersect_moved_lanes<L: simd::Lanes>(
        _: &Triangle8,
        m: &Triangle8,
        j: usize,
        r: &RayLanes<L>,
        active: L::Mask,
        t_max: L,
    ) -> (L::Mask, L, L, L) {
        from_moved(m.splat_lanes(j), r, active, t_max)
    }

    #[inline(always)]
    fn intersect_1x8<const KZ: usize>(
        b: &Triangle8,
        r: &TriRay8,
        active: Mask8,
        t_max: f32,
    ) -> Hits8 {
        if KZ > 2 {
            b.intersect_1x8(r, active, t_max)
        } else {
            b.intersect_1x8_kz::<KZ>(r, active, t_max)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::test_rng::Xorshift;

    const TRI: [DVec3; 3] = [
        DVec3::new(0.0, 0.0, 0.0),
        DVec3::new(1.0, 0.0, 0.0),
        DVec3::new(0.0, 1.0, 0.0),
    ];

    /// Eight different triangles' surfaces at once are, lane by lane, the bits of
    /// `surface_1`: ordinary triangles, degenerate ones (zero normal: the fallback +z),
    /// ones whose normal overflows or underflows f32 (fallback too), tiny and far ones.
    #[test]
    fn surfaces_of_eight_triangles_are_each_triangles_own() {
        let mut rng = Xorshift(0x2545_f491_4f6c_dd1d);
        let mut rnd = move |scale: f32| (rng.f32() * 2.0 - 1.0) * scale;
        let v3 = |x: f32, y: f32, z: f32| Vec3::new(x, y, z);
        for round in 0..200 {
            let scale = [1.0, 1e-20, 1e20, 3e4][round % 4];
            let tris: [Triangle32; 8] = std::array::from_fn(|i| {
                let mut v = [0; 3].map(|_| v3(rnd(scale), rnd(scale), rnd(scale)));
                match (round + i) % 7 {
                    0 => v[2] = v[0] + (v[1] - v[0]) * 0.5, // collinear
                    1 => v[1] = v[0],                       // a repeated corner
                    2 => {
                        v = [
                            v3(1e30, 0.0, 0.0),
                            v3(-1e30, 1e30, 0.0),
                            v3(0.0, -1e30, 1e30),
                        ]
                    }
                    3 => v = [v3(0.0, 0.0, 0.0), v3(1e-30, 0.0, 0.0), v3(0.0, 1e-30, 0.0)],
                    _ => {}
                }
                Triangle32 { v }
            });
            let b1: [f32; 8] = std::array::from_fn(|_| rnd(0.5) + 0.5);
            let b2: [f32; 8] = std::array::from_fn(|i| (rnd(0.5) + 0.5) * (1.0 - b1[i]));
            let corners = [0, 1, 2].map(|k| Vec3x8::from_lanes(&tris.map(|t| t.v[k])));
            let got = surface_lanes(corners, f32x8::new(b1), f32x8::new(b2));
            for (i, t) in tris.iter().enumerate() {
                let want = t.surface_1(b1[i], b2[i]);
                let bits = |v: Vec3| v.to_array().map(f32::to_bits);
                assert_eq!(
                    bits(got.point.lane(i)),
                    bits(want.point),
                    "round {round} lane {i}"
                );
                assert_eq!(
                    bits(got.normal.lane(i)),
                    bits(want.normal),
                    "round {round} lane {i}"
                );
                assert_eq!(
                    bits(got.err.lane(i)),
                    bits(want.err),
                    "round {round} lane {i}"
                );
            }
        }
    }

    /// A block moved to a packet's one origin gives every lane, bit for bit, what the
    /// single-ray kernel gives it, under both triangle tests: near and far origins
    /// (where translating rounds), every permutation and lanes of mixed permutations,
    /// hits and misses, lanes left out of `active` untouched by the answer.
    #[test]
    fn a_block_moved_to_the_one_origin_gives_each_lane_its_own_hit() {
        moved_block_lanes::<Watertight>();
        moved_block_lanes::<crate::geometry::moller::Moller>();
    }

    /// Round `round`'s cluster of eight random triangles at one of three scales: the
    /// scale, its centre, the triangles and their block.
    fn cluster(
        rnd: &mut impl FnMut() -> f32,
        round: usize,
    ) -> (f32, Vec3, [Triangle32; 8], Triangle8) {
        let scale = [1.0f32, 1e3, 3e5][round % 3];
        let centre = Vec3::new(rnd(), rnd(), rnd()) * scale;
        let tris: [Triangle32; 8] = std::array::from_fn(|_| Triangle32 {
            v: [0; 3].map(|_| centre + Vec3::new(rnd(), rnd(), rnd()) * (0.01 * scale)),
        });
        (scale, centre, tris, Triangle8::new(&tris))
    }

    fn moved_block_lanes<T: TriangleKernel>() {
        let mut rng = Xorshift(0x9e37_79b9_7f4a_7c15);
        let mut rnd = move || rng.f32() * 2.0 - 1.0;
        let (mut hits, mut mixed) = (0, 0);
        for round in 0..300 {
            let (scale, centre, tris, block) = cluster(&mut rnd, round);
            // the eye off to one side of the cluster, by axis in turn (each kz), every
            // fourth round off along a diagonal (lanes of different kz)
            let mut eye = centre;
            let side = if round % 2 == 0 { 0.2 } else { -0.2 } * scale;
            eye[round % 3] += side;
            if round % 4 == 3 {
                eye[(round + 1) % 3] += side;
            }
            let dirs: [Vec3; 8] = std::array::from_fn(|_| {
                let aim = centre + Vec3::new(rnd(), rnd(), rnd()) * (0.01 * scale);
                (aim - eye).normalize()
            });
            let p = RayPacket8::new(Vec3x8::splat(eye), Vec3x8::from_lanes(&dirs), Mask8::ALL);
            mixed += (p.kz_all == 3) as usize;
            let moved = T::move_block(&block, [eye.x, eye.y, eye.z].map(f32x8::splat));
            let lanes = simd::packet::RayLanes::of(&p);
            let active = Mask8::from_bits(if round % 5 == 0 { 0b1011_0110 } else { 0xff });
            for (j, tri) in tris.iter().enumerate() {
                let (m, t, u, v) = T::intersect_moved_lanes(
                    &block,
                    &moved,
                    j,
                    &lanes,
                    active,
                    f32x8::splat(f32::INFINITY),
                );
                for l in 0..8 {
                    let want = if active.lane(l) {
                        T::intersect_1(tri, &p.ray(l), f32::INFINITY)
                    } else {
                        None
                    };
                    let got = m
                        .lane(l)
                        .then(|| (t.as_array()[l], u.as_array()[l], v.as_array()[l]));
                    let bits =
                        |h: Option<(f32, f32, f32)>| h.map(|h| [h.0, h.1, h.2].map(f32::to_bits));
                    assert_eq!(bits(got), bits(want), "round {round} triangle {j} lane {l}");
                    hits += want.is_some() as usize;
                }
            }
        }
        assert!(hits > 1000, "too few hits to compare: {hits}");
        assert!(mixed > 10, "too few packets of mixed permutations: {mixed}");
    }

    /// The 1×8 kernel with the permutation read at run time (the stepped walks', from
    /// `TriRay8::axes`) gives every lane the bits the kernel of the permutation fixed at
    /// compile time gives it (one body: the run-time axes are the constant ones of the
    /// ray's `kz`): rays along each axis in turn and along diagonals (ties of |d|), near
    /// and far clusters, hits and misses, lanes left out of `active`.
    #[test]
    fn the_run_time_permutation_is_the_compile_time_ones() {
        let mut rng = Xorshift(0x51_7cc1_b727_220a);
        let mut rnd = move || rng.f32() * 2.0 - 1.0;
        let (mut hits, mut by_axis) = (0, [0; 3]);
        for round in 0..600 {
            let (scale, centre, tris, block) = cluster(&mut rnd, round);
            let mut eye = centre;
            eye[round % 3] += if round % 2 == 0 { 0.2 } else { -0.2 } * scale;
            // at one triangle's centroid (a hit in its lane, and in others it crosses)
            let v = tris[round % 8].v;
            let mut dir = ((v[0] + v[1] + v[2]) / 3.0 - eye).normalize();
            if round % 7 == 0 {
                // a tie of two or three components
                dir = Vec3::new(1.0, -1.0, if round % 2 == 0 { 1.0 } else { 0.5 }).normalize();
            }
            let r = Ray1::new(eye, dir);
            let tr = TriRay8::new(&r);
            by_axis[r.kz] += 1;
            let active = Mask8::from_bits(if round % 5 == 0 { 0b1101_0110 } else { 0xff });
            let t_max = if round % 3 == 0 {
                f32::INFINITY
            } else {
                0.2 * scale
            };
            let want = match r.kz {
                0 => block.intersect_1x8_kz::<0>(&tr, active, t_max),
                1 => block.intersect_1x8_kz::<1>(&tr, active, t_max),
                _ => block.intersect_1x8_kz::<2>(&tr, active, t_max),
            };
            let got = block.intersect_1x8(&tr, active, t_max);
            assert_eq!(got.0.bits(), want.0.bits(), "round {round}: the lanes hit");
            for l in (0..8).filter(|&l| want.0.lane(l)) {
                let bits = |h: &(Mask8, f32x8, f32x8, f32x8)| {
                    [h.1, h.2, h.3].map(|x| x.as_array()[l].to_bits())
                };
                assert_eq!(bits(&got), bits(&want), "round {round} lane {l}");
                hits += 1;
            }
        }
        assert!(hits > 500, "too few hits to compare: {hits}");
        assert!(
            by_axis.iter().all(|&n| n > 50),
            "every permutation: {by_axis:?}"
        );
    }

    #[test]
    fn hit_inside_gives_t_barycentrics_and_normal() {
        let r = Ray::new(DVec3::new(0.25, 0.25, 2.0), DVec3::NEG_Z);
        let h = intersect_ref(&TRI, &r, f64::INFINITY).unwrap();
        assert!((h.t - 2.0).abs() < 1e-15);
        let s = surface_ref(&TRI, &h);
        assert!((s.point - DVec3::new(0.25, 0.25, 0.0)).length() < 1e-15);
        assert_eq!(s.normal, DVec3::Z);
        assert!((h.bary.x + h.bary.y + h.bary.z - 1.0).abs() < 1e-15);
    }

    #[test]
    fn miss_outside_and_behind() {
        let r = Ray::new(DVec3::new(0.75, 0.75, 2.0), DVec3::NEG_Z);
        assert!(intersect_ref(&TRI, &r, f64::INFINITY).is_none());
        let r = Ray::new(DVec3::new(0.25, 0.25, 2.0), DVec3::Z);
        assert!(intersect_ref(&TRI, &r, f64::INFINITY).is_none());
    }

    #[test]
    fn shared_diagonal_of_a_quad_is_watertight() {
        // Quad (0,0)-(1,1) split along the diagonal; rays along the diagonal hit one.
        let a = [
            DVec3::ZERO,
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
        ];
        let b = [
            DVec3::ZERO,
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
        ];
        for i in 1..1000 {
            let s = (i as f64 * 0.618_033_988_749_894_9).fract();
            let p = DVec3::new(s, s, 0.0);
            let o = p + DVec3::new(0.3, -0.2, 1.0);
            let r = Ray::new(o, (p - o).normalize());
            let hits = intersect_ref(&a, &r, f64::INFINITY).is_some() as u32
                + intersect_ref(&b, &r, f64::INFINITY).is_some() as u32;
            assert!(hits >= 1, "ray {i} slipped through the shared edge");
        }
    }

    #[test]
    fn degenerate_triangles_are_never_hit() {
        let collinear = [DVec3::ZERO, DVec3::X, DVec3::X * 2.0];
        let repeated = [DVec3::ZERO, DVec3::ZERO, DVec3::Y];
        let r = Ray::new(DVec3::new(0.5, 0.0, 1.0), DVec3::NEG_Z);
        assert!(intersect_ref(&collinear, &r, f64::INFINITY).is_none());
        assert!(intersect_ref(&repeated, &r, f64::INFINITY).is_none());
    }

    #[test]
    fn ray_in_the_plane_misses() {
        let r = Ray::new(DVec3::new(-1.0, 0.2, 0.0), DVec3::X);
        assert!(intersect_ref(&TRI, &r, f64::INFINITY).is_none());
    }
}
