//! Ray–primitive intersection, one file per kind.
//!
//! Each kind's file holds the f64 reference kernel (`intersect_ref`, `surface_ref`:
//! the oracle, written to be read) and, beside it, the kernels of the fast path with
//! the same step comments in the same order.
//!
//! Edge rules, shared by every kind:
//! - A hit counts iff `0 < t < t_max` (t along a unit direction).
//! - NaN never produces a hit.
//! - A ray through an edge shared by two triangles hits at least one of them
//!   (watertight test); equal t ties go to the object listed first in the file.

pub mod floor;
pub mod moller;
pub mod prism;
pub mod quadric;
pub mod sphere;
pub mod triangle;

use glam::{DVec3, Vec3};
use wide::f32x8;

use crate::math::Aabb;
use crate::math::Ray;
use crate::math::packet::{Cmp8, HitPacket8, Mask8, Ray1, RayPacket8, Vec3x8};
use crate::scene::parse::is_degenerate_triangle;
use crate::scene::{Scene, Shape};
use crate::simd;
use crate::simd::packet::HitLanes;
use triangle::TriangleKernel;

/// What a reference kernel reports for a hit: the distance, for triangles the
/// barycentric coordinates (b0, b1, b2) of the hit point, and for compound shapes
/// (the prism) which part was hit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RefHit {
    pub t: f64,
    pub bary: DVec3,
    pub part: usize,
}

impl RefHit {
    pub fn at(t: f64) -> RefHit {
        RefHit {
            t,
            bary: DVec3::ZERO,
            part: 0,
        }
    }
}

/// The surface at the winning hit, computed once: the point, its unit geometric
/// normal (not yet flipped towards the ray) and a per-component bound on the error
/// of `point`, used to start secondary rays off the surface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfacePoint {
    pub point: DVec3,
    pub normal: DVec3,
    pub err: DVec3,
}

/// Reference intersection of one ray with one scene shape, 0 < t < t_max.
pub fn intersect_ref(shape: &Shape, ray: &Ray, t_max: f64) -> Option<RefHit> {
    match shape {
        Shape::Sphere { center, radius } => {
            sphere::intersect_ref(*center, *radius, ray, t_max).map(RefHit::at)
        }
        Shape::Triangle { v } => triangle::intersect_ref(v, ray, t_max),
        Shape::Quadric(q) => quadric::intersect_ref(q, ray, t_max).map(RefHit::at),
        Shape::Prism { v, .. } => prism::intersect_ref(v, ray, t_max),
        // brute force, like every other object of the reference
        Shape::Mesh(m) => (0..m.triangles().len())
            .filter_map(|part| {
                triangle::intersect_ref(&m.triangle(part), ray, t_max).map(|h| RefHit { part, ..h })
            })
            .min_by(|a, b| a.t.total_cmp(&b.t)),
    }
}

/// Reference surface record at a hit found by [`intersect_ref`].
pub fn surface_ref(shape: &Shape, ray: &Ray, hit: &RefHit) -> SurfacePoint {
    match shape {
        Shape::Sphere { center, radius } => sphere::surface_ref(*center, *radius, ray, hit.t),
        Shape::Triangle { v } => triangle::surface_ref(v, hit),
        Shape::Quadric(q) => quadric::surface_ref(q, ray, hit.t),
        Shape::Prism { v, .. } => prism::surface_ref(v, hit),
        Shape::Mesh(m) => triangle::surface_ref(&m.triangle(hit.part), hit),
    }
}

/// The five faces of a prism as eight triangles (ends abc, def; quads split in two),
/// all wound so that (b − a) × (c − a) points out of the prism.
pub fn prism_faces(v: &[DVec3; 6]) -> [[DVec3; 3]; 8] {
    let [a, b, c, d, e, f] = *v;
    let mut faces = [
        [a, b, c],
        [d, f, e],
        [a, d, e],
        [a, e, b],
        [b, e, f],
        [b, f, c],
        [c, f, d],
        [c, d, a],
    ];
    // Orient outwards: the centroid must lie behind every face.
    let centroid = v.iter().copied().sum::<DVec3>() / 6.0;
    for face in &mut faces {
        let n = (face[1] - face[0]).cross(face[2] - face[0]);
        if n.dot(centroid - face[0]) > 0.0 {
            face.swap(1, 2);
        }
    }
    faces
}

// ---------------------------------------------------------------- fast path (f32)

/// The surface at the winning hit of the fast path, in its f32 frame: point, unit
/// geometric normal (not yet flipped), per-component error bound of `point`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Surface32 {
    pub point: Vec3,
    pub normal: Vec3,
    pub err: Vec3,
}

/// [`Surface32`] on eight lanes.
#[derive(Clone, Copy, Debug)]
pub struct Surface8 {
    pub point: Vec3x8,
    pub normal: Vec3x8,
    pub err: Vec3x8,
}

/// Primitive kinds of the fast path. A BVH leaf holds one kind, so it runs one kernel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PrimKind {
    Sphere = 0,
    Triangle = 1,
    /// A quadric with finite bounds (clipped on every axis, an ellipsoid, or cut across
    /// axes along which its sections are bounded): lives in the BVH.
    Quadric = 2,
    /// A quadric without finite bounds: tested beside the BVH.
    FreeQuadric = 3,
    /// The floor: tested beside the BVH, after everything else.
    Floor = 4,
}

impl PrimKind {
    pub const BVH_KINDS: [PrimKind; 3] = [PrimKind::Sphere, PrimKind::Triangle, PrimKind::Quadric];

    /// The kind numbered `k`, if there is one (the miss code's bits are none).
    pub fn from_bits(k: u32) -> Option<PrimKind> {
        Some(match k {
            0 => PrimKind::Sphere,
            1 => PrimKind::Triangle,
            2 => PrimKind::Quadric,
            3 => PrimKind::FreeQuadric,
            4 => PrimKind::Floor,
            _ => return None,
        })
    }
}

/// Bits of a primitive code below the kind: code = kind << 28 | index (always >= 0;
/// −1 in a hit means no hit).
pub const INDEX_BITS: u32 = 28;

// every triangle a scene may hold has a code
const _: () = assert!(crate::scene::parse::MAX_TRIANGLES < 1 << INDEX_BITS);

/// The code a hit records for primitive `index` of `kind`.
#[inline]
pub fn prim_code(kind: PrimKind, index: usize) -> i32 {
    ((kind as u32) << INDEX_BITS | index as u32) as i32
}

/// Splits a hit's primitive code into kind and index; `None` for the miss code (−1).
#[inline]
pub fn split_code(code: i32) -> Option<(PrimKind, usize)> {
    let c = code as u32;
    let kind = PrimKind::from_bits(c >> INDEX_BITS)?;
    Some((kind, (c & ((1 << INDEX_BITS) - 1)) as usize))
}

/// [`split_code`] of a code known to be a hit's.
#[inline]
fn hit_code(code: i32) -> (PrimKind, usize) {
    split_code(code).expect("the primitive code of a hit")
}

/// A hit of the single-ray path: distance, primitive code (−1: none), barycentrics.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit1 {
    pub t: f32,
    pub prim: i32,
    pub u: f32,
    pub v: f32,
}

impl Hit1 {
    pub fn new(t_max: f32) -> Hit1 {
        Hit1 {
            t: t_max,
            prim: -1,
            u: 0.0,
            v: 0.0,
        }
    }
    pub fn is_hit(&self) -> bool {
        self.prim >= 0
    }
}

/// The floor is tested after everything else; where something was hit, with that hit's
/// t scaled by this as `t_max`: it wins only if it is closer by more than 64 f32 ulps,
/// relative (7.6e-6). The floor loses every tie (spec §4), but a primitive lying on it
/// (a prism's base face, a triangle at z = 0) meets a ray at a t computed by another
/// formula than the floor's, so in f32 the two "equal" distances differ by a few ulps
/// either way; the reference computes them alike in f64 and the tie goes to the object,
/// so here it does too. 8 ulps were not enough: light trapped in a prism standing on
/// the floor, bouncing up to recursion level 1000, leaked through the base where the
/// floor won (the picture 47 % too bright, 18.4 dB from the reference; 25.0 dB and
/// within 1.2 % with 64 ulps, as close as the reference to itself with the eye moved
/// by 1e-3: `tests/extremes.rs`). The window is not applied to objects wholly behind
/// the floor plane from the ray's origin ([`PrimSet::floor_side`]), and inside it
/// (the floor between [`FLOOR_TIE`] and [`FLOOR_BAND`] times the object's t) the two
/// distances are recomputed in f64 to decide ([`PrimSet::floor_first`]).
pub const FLOOR_TIE: f32 = 1.0 - 64.0 * f32::EPSILON;

/// Top of the floor tie's band, relative to the object's t (64 f32 ulps beyond it):
/// a floor hit between [`FLOOR_TIE`] and this is too close to the object's in f32 to
/// order them, and [`PrimSet::floor_first`] decides.
pub const FLOOR_BAND: f32 = 1.0 + 64.0 * f32::EPSILON;

/// How far past the floor (relative to its t) a closest-hit walk looks for objects
/// ([`PrimSet::bound_by_floor_x8`]): an object hit beyond this loses to the floor in
/// [`PrimSet::intersect_floor_x8`] (its tie window, [`FLOOR_TIE`], ends 192 ulps short
/// of it, far more than the products' rounding).
pub const FLOOR_BOUND: f32 = 1.0 + 256.0 * f32::EPSILON;

/// How far (relative) the f64 root may lie from the f32 kernel's t and still be taken
/// as the same surface crossing by [`PrimSet::floor_first`].
const SAME_ROOT: f64 = 1e-3;

/// The BVH sees primitive bounds clamped to ±2⁴⁴ (1.8e13) in the f32 frame, so that its
/// SAH sums and products (areas up to 3·2⁹⁰ times counts up to 2²⁸) stay finite. A
/// sphere of radius 1e19 or at 1e39 made them overflow to inf and NaN, and the build
/// panicked. Clamping loses only hits beyond 2⁴⁴ from the camera on rays that do not
/// pass the clamped box, where f32 spacing (2²⁰) has long stopped meaning anything.
pub const BOUNDS_LIMIT: f32 = 17_592_186_044_416.0;

/// Every primitive of the fast path, by kind, in one f32 frame (coordinates relative
/// to a base point, e.g. the camera, so far-away scenes keep their precision), with
/// the scene object each came from (ties in t go to the lower object index; the
/// floor loses every tie). After a BVH build the BVH kinds are in leaf order.
#[derive(Clone, Debug, Default)]
pub struct PrimSet {
    pub spheres: Vec<sphere::Sphere32>,
    pub sphere_obj: Vec<u32>,
    /// The triangles as the scene gives them, until a BVH build packs them into
    /// `blocks` and empties these (reach them through [`PrimSet::triangle`]): their
    /// corners' indices in `tri_vertices`, the vertices in the frame (a mesh's shared,
    /// 18 bytes a mesh triangle where whole triangles took 36).
    pub tri_corners: Vec<[u32; 3]>,
    pub tri_vertices: Vec<Vec3>,
    pub triangle_obj: Vec<u32>,
    /// After a BVH build, every triangle, in leaf order, eight to a block
    /// ([`triangle::TriBlock`]): the wide tree's leaves, and the one copy kept.
    pub blocks: Vec<triangle::TriBlock>,
    /// `block_at[k]`: the block holding triangle 8·k ([`PrimSet::triangle`]'s lookup).
    pub block_at: Vec<u32>,
    pub quadrics: Vec<quadric::Quadric32>,
    pub quadric_obj: Vec<u32>,
    pub free_quadrics: Vec<quadric::Quadric32>,
    pub free_quadric_obj: Vec<u32>,
    pub floor: Option<floor::Floor32>,
    /// Number of degenerate triangles and all-zero quadrics dropped (never hit).
    pub dropped: usize,
    /// By object index, the side of the floor plane the object lies wholly on: −1
    /// below (world z < 0), +1 above, 0 touching or crossing it (or unbounded). A ray
    /// whose nearest hit so far is an object wholly on the far side of the plane from
    /// its origin crossed the plane first, so it takes the floor wherever it meets it,
    /// whatever the rounding of the two distances ([`FLOOR_TIE`]'s window is for
    /// surfaces lying on the floor, not a few ulps off it). Empty when no object lies
    /// wholly on one side; otherwise a ray pays for the lookup only when it comes from
    /// the side opposite such an object ([`PrimSet::any_below`], [`PrimSet::any_above`]):
    /// in a scene seen from above with nothing below the floor, one compare per packet.
    /// Whatever the eye: a prepared renderer serves every camera (the viewer), and
    /// photons start at the lights.
    pub floor_side: Vec<i8>,
    /// Some object lies wholly below the floor plane.
    pub any_below: bool,
    /// Some object lies wholly above the floor plane.
    pub any_above: bool,
    /// The world point of the frame's origin.
    pub base: DVec3,
    /// The spheres and quadrics of the scene in world coordinates, by object index
    /// (ascending), for [`PrimSet::floor_first`].
    pub curved: Vec<(u32, Shape)>,
}

/// Triangles of a [`PrimSet`] read at rising indices ([`PrimSet::triangles_from`]).
pub struct TriCursor<'a> {
    set: &'a PrimSet,
    /// The block of the last triangle read (built sets).
    block: usize,
}

impl TriCursor<'_> {
    /// Triangle `i`, at or past the last one read.
    #[inline(always)]
    pub fn at(&mut self, i: usize) -> triangle::Triangle32 {
        let p = self.set;
        if p.blocks.is_empty() {
            let v = &p.tri_vertices;
            return triangle::Triangle32 {
                v: p.tri_corners[i].map(|c| v[c as usize]),
            };
        }
        let mut b = &p.blocks[self.block];
        while i >= (b.first + b.count) as usize {
            self.block += 1;
            b = &p.blocks[self.block];
        }
        b.tri.lane(i - b.first as usize)
    }
}

impl PrimSet {
    /// The primitives of `scene` relative to `base`, the floor included. Degenerate
    /// triangles and all-zero quadrics are dropped (the reference never hits them either).
    pub fn from_scene(scene: &Scene, base: DVec3) -> PrimSet {
        let mut s = PrimSet {
            floor: Some(floor::Floor32::new(base)),
            base,
            curved: (scene.objects.iter().enumerate())
                .filter(|(_, o)| matches!(o.shape, Shape::Sphere { .. } | Shape::Quadric(_)))
                .map(|(i, o)| (i as u32, o.shape.clone()))
                .collect(),
            ..PrimSet::default()
        };
        // the lowest and highest world z of each object (±∞: unbounded)
        let mut tops = vec![f64::INFINITY; scene.objects.len()];
        let mut bottoms = vec![f64::NEG_INFINITY; scene.objects.len()];
        let highest = |v: &[DVec3]| v.iter().fold(f64::NEG_INFINITY, |z, p| z.max(p.z));
        let lowest = |v: &[DVec3]| v.iter().fold(f64::INFINITY, |z, p| z.min(p.z));
        for (i, o) in scene.objects.iter().enumerate() {
            let id = i as u32;
            match &o.shape {
                Shape::Sphere { center, radius } => {
                    s.spheres
                        .push(sphere::Sphere32::new(*center, *radius, base));
                    s.sphere_obj.push(id);
                    (bottoms[i], tops[i]) = (center.z - radius, center.z + radius);
                }
                Shape::Triangle { v } => {
                    s.push_triangle(v, base, id);
                    (bottoms[i], tops[i]) = (lowest(v), highest(v));
                }
                Shape::Quadric(q) => {
                    if q.is_degenerate() {
                        s.dropped += 1;
                        continue;
                    }
                    let q32 = quadric::Quadric32::new(q, base);
                    if let Some(b) = q32.bounds() {
                        // rounded outwards to f32: conservative
                        (bottoms[i], tops[i]) = (b.lo.z as f64 + base.z, b.hi.z as f64 + base.z);
                        s.quadrics.push(q32);
                        s.quadric_obj.push(id);
                    } else {
                        s.free_quadrics.push(q32);
                        s.free_quadric_obj.push(id);
                    }
                }
                Shape::Prism { v, .. } => {
                    for f in prism_faces(v) {
                        s.push_triangle(&f, base, id);
                    }
                    (bottoms[i], tops[i]) = (lowest(v), highest(v));
                }
                Shape::Mesh(m) => {
                    s.tri_corners.reserve(m.triangles().len());
                    s.triangle_obj.reserve(m.triangles().len());
                    // each vertex moved into the frame once (`Triangle32::new`'s
                    // rounding, vertex by vertex), into the pool the triangles share;
                    // the scene's own zero-area test only in a mesh that has such
                    // triangles. (u32 indices: 2³² vertices would take 48 GB in f32
                    // alone, past what any machine of the resource contract holds.)
                    let at = s.tri_vertices.len() as u32;
                    (s.tri_vertices).extend(m.vertices().iter().map(|p| (*p - base).as_vec3()));
                    let any_zero_area = m.zero_area() > 0;
                    for (k, t) in m.triangles().iter().enumerate() {
                        let v = &s.tri_vertices;
                        let t32 = t.map(|i| v[(at + i) as usize]);
                        let zero_area = any_zero_area && is_degenerate_triangle(&m.triangle(k));
                        if s.keeps(&t32, zero_area) {
                            s.tri_corners.push(t.map(|i| at + i));
                            s.triangle_obj.push(id);
                        }
                    }
                    (bottoms[i], tops[i]) = (lowest(m.vertices()), highest(m.vertices()));
                }
            }
        }
        s.any_below = tops.iter().any(|&z| z < 0.0);
        s.any_above = bottoms.iter().any(|&z| z > 0.0);
        if s.any_below || s.any_above {
            s.floor_side = (0..tops.len())
                .map(|i| (bottoms[i] > 0.0) as i8 - (tops[i] < 0.0) as i8)
                .collect();
        }
        s
    }

    /// Whether the floor test of a ray from `origin_z` (frame) must drop its tie window
    /// for the hit `code`: an object wholly on the far side of the floor plane.
    #[inline]
    fn behind_floor_hit(&self, code: i32, origin_z: f32, floor_z: f32) -> bool {
        let far = if origin_z > floor_z {
            self.any_below.then_some(-1)
        } else if origin_z < floor_z {
            self.any_above.then_some(1)
        } else {
            None
        };
        far.is_some_and(|side| self.floor_side.get(self.object(code) as usize) == Some(&side))
    }

    /// Whether the floor comes first on a ray (f32 frame, `o` and `d` widened exactly)
    /// whose nearest hit so far is primitive `code` at `t`, with the floor's f32 t in
    /// the tie band (within 64 f32 ulps of `t` either way), where f32 cannot order
    /// them: both distances recomputed in f64 from the same f32 data, and ordered as
    /// the reference orders them (the floor wins only by more than [`floor::TIE`]).
    /// The object's root is the one nearest `t` (for a quadric under the clipping
    /// rule, the kernel may have taken the far one); none within [`SAME_ROOT`] of `t`
    /// (a root the f32 kernel could not have meant): the object keeps its hit, as
    /// everywhere in the band before. A surface crossing the floor plane, or
    /// unbounded, a few ulps behind it (a triangle 1e-4 below over most of its area,
    /// a sphere sunk to a small cap, the plane z = −0.0002 as a quadric) no longer
    /// shows through the floor; one lying on it (a prism's base) still wins.
    #[cold]
    fn floor_first(&self, code: i32, t: f32, o: DVec3, d: DVec3, floor_z: f32) -> bool {
        let (kind, i) = hit_code(code);
        let t = t as f64;
        let nearest = |(a, b): (f64, f64)| if (a - t).abs() <= (b - t).abs() { a } else { b };
        // spheres and quadrics from their world data (frame rounding of a centre
        // moved the rim of a sphere sunk to a 0.001 cap by pixels), triangles from
        // the frame's (which triangle of a mesh a code names is not kept)
        let world = o + self.base;
        let obj = self.object(code);
        let curved =
            (self.curved.binary_search_by_key(&obj, |c| c.0).ok()).map(|k| &self.curved[k].1);
        let (t_obj, t_floor) = match (kind, curved) {
            (PrimKind::Triangle, _) => (
                self.triangle(i).plane_t_f64(o, d),
                (floor_z as f64 - o.z) / d.z,
            ),
            (_, Some(Shape::Sphere { center, radius })) => (
                sphere::roots_ref(*center, *radius, world, d).map(nearest),
                -world.z / d.z,
            ),
            (_, Some(Shape::Quadric(q))) => {
                (quadric::roots_ref(q, world, d).map(nearest), -world.z / d.z)
            }
            _ => (None, 0.0),
        };
        let Some(t_obj) = t_obj.filter(|&u| (u - t).abs() <= SAME_ROOT * t) else {
            return false;
        };
        t_floor < t_obj * floor::TIE
    }

    fn push_triangle(&mut self, v: &[DVec3; 3], base: DVec3, id: u32) {
        let t = triangle::Triangle32::new(v, base);
        self.push_triangle32(t, is_degenerate_triangle(v), id);
    }

    /// Triangle `t` of object `id` in the frame, dropped when it has zero area there or
    /// in the scene (`zero_area`).
    fn push_triangle32(&mut self, t: triangle::Triangle32, zero_area: bool, id: u32) {
        if self.keeps(&t.v, zero_area) {
            self.add_triangle(t, id);
        }
    }

    /// Whether a triangle of these corners in the frame is kept: not when it has zero
    /// area there or in the scene (`zero_area`), which counts it in `dropped`.
    #[inline(always)]
    fn keeps(&mut self, v: &[Vec3; 3], zero_area: bool) -> bool {
        let drop = zero_area || is_degenerate_triangle(&v.map(|p| p.as_dvec3()));
        self.dropped += drop as usize;
        !drop
    }

    /// Adds triangle `t` of object `id`, corners of its own, as it is (before a build).
    pub fn add_triangle(&mut self, t: triangle::Triangle32, id: u32) {
        debug_assert!(
            self.blocks.is_empty(),
            "a built set takes no more triangles"
        );
        let at = self.tri_vertices.len() as u32;
        self.tri_vertices.extend(t.v);
        self.tri_corners.push([at, at + 1, at + 2]);
        self.triangle_obj.push(id);
    }

    /// Triangle `i`: after a BVH build, a lane of the block holding it (the block
    /// [`PrimSet::block_at`] names, or one of the few after it); before, its corners
    /// from `tri_vertices`.
    #[inline(always)]
    pub fn triangle(&self, i: usize) -> triangle::Triangle32 {
        self.triangles_from(i).at(i)
    }

    /// The block holding triangle `i` of a built set.
    #[inline(always)]
    pub fn block_of(&self, i: usize) -> usize {
        let mut b = self.block_at[i >> 3] as usize;
        while i >= (self.blocks[b].first + self.blocks[b].count) as usize {
            b += 1;
        }
        b
    }

    /// A reader of triangles at rising indices from `i` (a leaf's run, in one block or
    /// two): the block is found once, then followed.
    #[inline(always)]
    pub fn triangles_from(&self, i: usize) -> TriCursor<'_> {
        let block = if self.blocks.is_empty() {
            0
        } else {
            self.block_of(i)
        };
        TriCursor { set: self, block }
    }

    /// Every triangle with its index, in index order, built or not.
    pub fn each_triangle(&self) -> impl Iterator<Item = (usize, triangle::Triangle32)> + '_ {
        let listed = (0..self.tri_corners.len()).map(|i| (i, self.triangle(i)));
        let packed = (self.blocks.iter()).flat_map(|b| {
            (0..b.count as usize).map(move |l| (b.first as usize + l, b.tri.lane(l)))
        });
        listed.chain(packed)
    }

    /// Makes `blocks` (every triangle, in index order: each block's `first` the one
    /// before's `first + count`, from 0) the store of the triangles, in place of
    /// `tri_corners` and `tri_vertices`, and indexes them for [`PrimSet::triangle`].
    pub fn pack_triangles(&mut self, blocks: Vec<triangle::TriBlock>) {
        let mut at = vec![0u32; self.triangle_obj.len().div_ceil(8)];
        for (b, blk) in blocks.iter().enumerate() {
            let (f, end) = (blk.first as usize, (blk.first + blk.count) as usize);
            for m in (f.next_multiple_of(8)..end).step_by(8) {
                at[m / 8] = b as u32;
            }
        }
        self.block_at = at;
        self.blocks = blocks;
        self.tri_corners = Vec::new();
        self.tri_vertices = Vec::new();
    }

    /// A triangle mesh on its own (object 0), no floor: the benchmark's input.
    pub fn from_triangles(tris: Vec<triangle::Triangle32>) -> PrimSet {
        let mut s = PrimSet::default();
        for t in tris {
            s.add_triangle(t, 0);
        }
        s
    }

    /// Number of primitives of a BVH kind.
    pub fn len(&self, kind: PrimKind) -> usize {
        match kind {
            PrimKind::Sphere => self.spheres.len(),
            PrimKind::Triangle => self.triangle_obj.len(),
            PrimKind::Quadric => self.quadrics.len(),
            PrimKind::FreeQuadric => self.free_quadrics.len(),
            PrimKind::Floor => self.floor.is_some() as usize,
        }
    }

    /// Bounds of a BVH primitive, clamped to ±[`BOUNDS_LIMIT`].
    #[inline(always)]
    pub fn bounds(&self, kind: PrimKind, i: usize) -> Aabb {
        let b = match kind {
            PrimKind::Sphere => self.spheres[i].bounds(),
            PrimKind::Triangle => self.triangle(i).bounds(),
            PrimKind::Quadric => self.quadrics[i].bounds().expect("bounded quadric"),
            PrimKind::FreeQuadric | PrimKind::Floor => unreachable!("not in the BVH"),
        };
        let clamp = |v: Vec3, nan: f32| {
            v.to_array().map(|c| {
                if c.is_nan() {
                    nan
                } else {
                    c.clamp(-BOUNDS_LIMIT, BOUNDS_LIMIT)
                }
            })
        };
        Aabb::new(
            Vec3::from(clamp(b.lo, -BOUNDS_LIMIT)),
            Vec3::from(clamp(b.hi, BOUNDS_LIMIT)),
        )
    }

    /// The scene object of a hit's primitive code (the floor: u32::MAX, it loses every
    /// tie).
    pub fn object(&self, code: i32) -> u32 {
        let (kind, i) = hit_code(code);
        match kind {
            PrimKind::Sphere => self.sphere_obj[i],
            PrimKind::Triangle => self.triangle_obj[i],
            PrimKind::Quadric => self.quadric_obj[i],
            PrimKind::FreeQuadric => self.free_quadric_obj[i],
            PrimKind::Floor => u32::MAX,
        }
    }

    /// The index of triangle hit `code` ([`PrimSet::triangle`]) and its scene object; `None`
    /// for any other code.
    #[inline]
    pub fn triangle_and_object(&self, code: i32) -> Option<(usize, u32)> {
        match split_code(code)? {
            (PrimKind::Triangle, i) => Some((i, *self.triangle_obj.get(i)?)),
            _ => None,
        }
    }

    /// Whether a hit of primitive `code` at exactly the t of the held hit `held` wins
    /// the tie: the lower object index (the file's order; the floor, u32::MAX, loses
    /// every tie), then the lower primitive code (one object's triangles), so the
    /// winner never depends on the order a walk meets them in.
    #[inline]
    fn wins_tie(&self, code: i32, held: i32) -> bool {
        (self.object(code), code) < (self.object(held), held)
    }

    /// Records a packet kernel's hits (lanes `m` at `t`, barycentrics `uv`) of
    /// primitive `code` in `hit`: nearer wins, exact ties by [`PrimSet::wins_tie`].
    /// Every walk records through here or [`PrimSet::record_1`].
    #[inline]
    pub(crate) fn record_x8(
        &self,
        hit: &mut HitPacket8,
        m: Mask8,
        t: f32x8,
        uv: (f32x8, f32x8),
        code: i32,
    ) {
        let mut h = HitLanes {
            t: hit.t,
            prim: hit.prim,
            u: hit.u,
            v: hit.v,
        };
        self.record_lanes(&mut h, m, t, uv, code);
        *hit = HitPacket8 {
            t: h.t,
            prim: h.prim,
            u: h.u,
            v: h.v,
        };
    }

    /// [`PrimSet::record_x8`] at any width.
    #[inline(always)]
    pub(crate) fn record_lanes<L: simd::Lanes>(
        &self,
        hit: &mut HitLanes<L>,
        m: L::Mask,
        t: L,
        uv: (L, L),
        code: i32,
    ) {
        use simd::{IntLanes as _, LaneMask as _};
        let mut closer = m & t.lt(hit.t);
        let tie = m & t.eq(hit.t) & hit.prim.non_negative();
        if tie.any() {
            let mut extra = 0;
            let mut bits = tie.bits();
            while bits != 0 {
                let lane = bits.trailing_zeros() as usize;
                bits &= bits - 1;
                if self.wins_tie(code, hit.prim.lane(lane)) {
                    extra |= 1 << lane;
                }
            }
            closer = closer | L::Mask::from_bits(extra);
        }
        if closer.none() {
            return;
        }
        hit.t = L::select(closer, t, hit.t);
        hit.prim = L::Int::select(closer, L::Int::splat(code), hit.prim);
        hit.u = L::select(closer, uv.0, hit.u);
        hit.v = L::select(closer, uv.1, hit.v);
    }

    /// Single-ray twin of [`PrimSet::record_x8`].
    #[inline]
    pub(crate) fn record_1(&self, hit: &mut Hit1, t: f32, u: f32, v: f32, code: i32) {
        if t < hit.t || (t == hit.t && hit.is_hit() && self.wins_tie(code, hit.prim)) {
            *hit = Hit1 {
                t,
                prim: code,
                u,
                v,
            };
        }
    }

    /// Closest-hit test of primitives `first..first + count` of one kind (a BVH leaf,
    /// or the list beside it) against the active lanes of a packet.
    #[inline]
    pub fn intersect_x8<T: TriangleKernel>(
        &self,
        kind: PrimKind,
        first: usize,
        count: usize,
        r: &RayPacket8,
        active: Mask8,
        hit: &mut HitPacket8,
    ) {
        let zero = (f32x8::ZERO, f32x8::ZERO);
        let mut tris = None;
        for i in first..first + count {
            let code = prim_code(kind, i);
            match kind {
                PrimKind::Sphere => {
                    let (m, t) = self.spheres[i].intersect_x8(r, active, hit.t);
                    self.record_x8(hit, m, t, zero, code);
                }
                PrimKind::Triangle => {
                    let tri = tris.get_or_insert_with(|| self.triangles_from(i)).at(i);
                    let (m, t, u, v) = T::intersect_x8(&tri, r, active, hit.t);
                    self.record_x8(hit, m, t, (u, v), code);
                }
                PrimKind::Quadric => {
                    let (m, t) = self.quadrics[i].intersect_x8(r, active, hit.t);
                    self.record_x8(hit, m, t, zero, code);
                }
                PrimKind::FreeQuadric => {
                    let (m, t) = self.free_quadrics[i].intersect_x8(r, active, hit.t);
                    self.record_x8(hit, m, t, zero, code);
                }
                PrimKind::Floor => self.intersect_floor_x8(r, active, hit),
            }
        }
    }

    /// Bounds the closest-hit search of the lanes of `active` without a hit yet at
    /// [`FLOOR_BOUND`] times their floor hit: a walk then skips what lies beyond the
    /// floor (the half of a mesh the floor cuts off, seen through it), which would lose
    /// to the floor anyway. `hit.t` of such a lane is then a bound without a primitive;
    /// the floor's own test after the walk ([`PrimSet::intersect_floor_x8`]) meets the
    /// same floor hit below it and records it, so every lane ends with the hit of the
    /// unbounded query, bit for bit. (The walks skip it in an empty tree, where it
    /// would bound nothing.)
    #[inline]
    pub fn bound_by_floor_x8(&self, r: &RayPacket8, active: Mask8, hit: &mut HitPacket8) {
        let Some(f) = &self.floor else { return };
        let free = active.and_not(hit.hit_mask());
        if free.none() {
            return;
        }
        let (m, t) = f.intersect_x8(r, free, hit.t);
        // (a subnormal t would round its bound back to itself, or to a few ulps past it)
        let m = m & t.ge(f32x8::splat(f32::MIN_POSITIVE));
        let bound = t * f32x8::splat(FLOOR_BOUND);
        hit.t = m.select(bound.fast_min(hit.t), hit.t);
    }

    /// The floor's part of [`PrimSet::intersect_x8`] (the ordering rules of
    /// [`PrimSet::floor_first`] and [`PrimSet::behind_floor_hit`]). The per-lane work
    /// of the rare cases sits in cold functions of its own (inlined, their f32 → f64
    /// widening of the ray was hoisted into every floor test).
    #[inline]
    pub fn intersect_floor_x8(&self, r: &RayPacket8, active: Mask8, hit: &mut HitPacket8) {
        let Some(f) = &self.floor else { return };
        let hits = hit.hit_mask();
        let mut t_max = hits.select(hit.t * f32x8::splat(FLOOR_TIE), hit.t);
        // lanes from the side opposite some object's (one compare)
        let fz = f32x8::splat(f.z);
        let mut ask = Mask8::from_bits(0);
        if self.any_below {
            ask = ask | r.origin.z.gt(fz);
        }
        if self.any_above {
            ask = ask | r.origin.z.lt(fz);
        }
        let ask = ask & hits;
        // lanes whose hit lies wholly behind the floor plane
        let behind = if ask.any() {
            self.behind_floor_lanes(ask, hit, r, f.z)
        } else {
            Mask8::NONE
        };
        if behind.any() {
            t_max = behind.select(f32x8::splat(f32::INFINITY), t_max);
        }
        // the other hit lanes look up to the top of the tie band
        let probe = hits
            .and_not(behind)
            .select(hit.t * f32x8::splat(FLOOR_BAND), t_max);
        let (m, t) = f.intersect_x8(r, active, probe);
        let take = m & t.lt(t_max);
        // floor hits in the band: ordered in f64 (rare)
        let band = (m & hits).and_not(take);
        let first = if band.any() {
            self.floor_first_lanes(band, hit, r, f.z)
        } else {
            Mask8::NONE
        };
        // the floor replaces these hits wherever the ray meets it
        let replace = (take & behind) | first;
        if replace.any() {
            hit.t = replace.select(f32x8::splat(f32::INFINITY), hit.t);
        }
        let code = prim_code(PrimKind::Floor, 0);
        self.record_x8(hit, take | first, t, (f32x8::ZERO, f32x8::ZERO), code);
    }

    /// The lanes of `ask` whose hit lies wholly behind the floor plane
    /// ([`PrimSet::behind_floor_hit`]).
    #[cold]
    #[inline(never)]
    fn behind_floor_lanes(&self, ask: Mask8, hit: &HitPacket8, r: &RayPacket8, fz: f32) -> Mask8 {
        let (prim, oz) = (hit.prim.to_array(), r.origin.z.to_array());
        let mut behind = 0;
        for l in 0..8 {
            if ask.lane(l) && self.behind_floor_hit(prim[l], oz[l], fz) {
                behind |= 1 << l;
            }
        }
        Mask8::from_bits(behind)
    }

    /// The lanes of `band` (floor and object hits within the tie band) where the
    /// floor comes first ([`PrimSet::floor_first`]).
    #[cold]
    #[inline(never)]
    fn floor_first_lanes(&self, band: Mask8, hit: &HitPacket8, r: &RayPacket8, fz: f32) -> Mask8 {
        let (ts, prim) = (hit.t.to_array(), hit.prim.to_array());
        let [ox, oy, oz] = [r.origin.x, r.origin.y, r.origin.z].map(|v| v.to_array());
        let [dx, dy, dz] = [r.dir.x, r.dir.y, r.dir.z].map(|v| v.to_array());
        let mut first = 0;
        for l in 0..8 {
            let o = DVec3::new(ox[l] as f64, oy[l] as f64, oz[l] as f64);
            let d = DVec3::new(dx[l] as f64, dy[l] as f64, dz[l] as f64);
            if band.lane(l) && self.floor_first(prim[l], ts[l], o, d, fz) {
                first |= 1 << l;
            }
        }
        Mask8::from_bits(first)
    }

    /// Any-hit test: the lanes of `active` blocked by one of the primitives with
    /// 0 < t < t_max. Stops as soon as every active lane is blocked.
    #[inline]
    pub fn occluded_x8<T: TriangleKernel>(
        &self,
        kind: PrimKind,
        first: usize,
        count: usize,
        r: &RayPacket8,
        active: Mask8,
        t_max: f32x8,
    ) -> Mask8 {
        let mut left = active;
        let mut tris = None;
        for i in first..first + count {
            let m = match kind {
                PrimKind::Sphere => self.spheres[i].occluded_x8(r, left, t_max),
                PrimKind::Triangle => {
                    let tri = tris.get_or_insert_with(|| self.triangles_from(i)).at(i);
                    T::occluded_x8(&tri, r, left, t_max)
                }
                PrimKind::Quadric => self.quadrics[i].occluded_x8(r, left, t_max),
                PrimKind::FreeQuadric => self.free_quadrics[i].occluded_x8(r, left, t_max),
                PrimKind::Floor => match &self.floor {
                    Some(f) => f.occluded_x8(r, left, t_max),
                    None => Mask8::NONE,
                },
            };
            left = left.and_not(m);
            if left.none() {
                break;
            }
        }
        active.and_not(left)
    }

    /// Single-ray twin of [`PrimSet::intersect_x8`].
    #[inline]
    pub fn intersect_1<T: TriangleKernel>(
        &self,
        kind: PrimKind,
        first: usize,
        count: usize,
        r: &Ray1,
        hit: &mut Hit1,
    ) {
        let mut tris = None;
        for i in first..first + count {
            let code = prim_code(kind, i);
            match kind {
                PrimKind::Sphere => {
                    if let Some(t) = self.spheres[i].intersect_1(r, hit.t) {
                        self.record_1(hit, t, 0.0, 0.0, code);
                    }
                }
                PrimKind::Triangle => {
                    let tri = tris.get_or_insert_with(|| self.triangles_from(i)).at(i);
                    if let Some((t, u, v)) = T::intersect_1(&tri, r, hit.t) {
                        self.record_1(hit, t, u, v, code);
                    }
                }
                PrimKind::Quadric => {
                    if let Some(t) = self.quadrics[i].intersect_1(r, hit.t) {
                        self.record_1(hit, t, 0.0, 0.0, code);
                    }
                }
                PrimKind::FreeQuadric => {
                    if let Some(t) = self.free_quadrics[i].intersect_1(r, hit.t) {
                        self.record_1(hit, t, 0.0, 0.0, code);
                    }
                }
                PrimKind::Floor => {
                    let Some(f) = &self.floor else { continue };
                    // a hit wholly behind the floor plane: the floor replaces
                    // it wherever the ray meets it
                    let behind = hit.is_hit() && self.behind_floor_hit(hit.prim, r.origin.z, f.z);
                    let (t_max, probe) = match (hit.is_hit(), behind) {
                        (_, true) => (f32::INFINITY, f32::INFINITY),
                        (true, false) => (hit.t * FLOOR_TIE, hit.t * FLOOR_BAND),
                        (false, false) => (hit.t, hit.t),
                    };
                    if let Some(t) = f.intersect_1(r, probe) {
                        // in the tie band: ordered in f64
                        let first = t >= t_max
                            && hit.is_hit()
                            && self.floor_first(
                                hit.prim,
                                hit.t,
                                r.origin.as_dvec3(),
                                r.dir.as_dvec3(),
                                f.z,
                            );
                        if t < t_max || first {
                            if behind || first {
                                *hit = Hit1::new(f32::INFINITY);
                            }
                            self.record_1(hit, t, 0.0, 0.0, code);
                        }
                    }
                }
            }
        }
    }

    /// Single-ray twin of [`PrimSet::occluded_x8`].
    #[inline]
    pub fn occluded_1<T: TriangleKernel>(
        &self,
        kind: PrimKind,
        first: usize,
        count: usize,
        r: &Ray1,
        t_max: f32,
    ) -> bool {
        let mut tris = None;
        (first..first + count).any(|i| match kind {
            PrimKind::Sphere => self.spheres[i].occluded_1(r, t_max),
            PrimKind::Triangle => {
                let tri = tris.get_or_insert_with(|| self.triangles_from(i)).at(i);
                T::occluded_1(&tri, r, t_max)
            }
            PrimKind::Quadric => self.quadrics[i].occluded_1(r, t_max),
            PrimKind::FreeQuadric => self.free_quadrics[i].occluded_1(r, t_max),
            PrimKind::Floor => self.floor.is_some_and(|f| f.occluded_1(r, t_max)),
        })
    }

    /// [`PrimSet::surface_1`] of primitive `code` on all eight lanes of `r` (`t`, `u`,
    /// `v` per lane), lane for lane the same operations; `None` for the floor, whose
    /// packet twin lives with its shading, and for −1 (no hit).
    pub fn surface_x8(
        &self,
        code: i32,
        r: &RayPacket8,
        t: f32x8,
        u: f32x8,
        v: f32x8,
    ) -> Option<Surface8> {
        let (kind, i) = split_code(code)?;
        Some(match kind {
            PrimKind::Sphere => self.spheres[i].surface_x8(r, t),
            PrimKind::Triangle => self.triangle(i).surface_x8(u, v),
            PrimKind::Quadric => self.quadrics[i].surface_x8(r, t),
            PrimKind::FreeQuadric => self.free_quadrics[i].surface_x8(r, t),
            PrimKind::Floor => return None,
        })
    }

    /// Surface record of a hit, computed once for the winner.
    pub fn surface_1(&self, code: i32, r: &Ray1, t: f32, u: f32, v: f32) -> Surface32 {
        let (kind, i) = hit_code(code);
        match kind {
            PrimKind::Sphere => self.spheres[i].surface_1(r, t),
            PrimKind::Triangle => self.triangle(i).surface_1(u, v),
            PrimKind::Quadric => self.quadrics[i].surface_1(r, t),
            PrimKind::FreeQuadric => self.free_quadrics[i].surface_1(r, t),
            PrimKind::Floor => self.floor.expect("floor hit").surface_1(r, t),
        }
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use glam::DVec3;

    use super::PrimSet;
    use crate::scene::obj::Mesh;
    use crate::scene::{Floor, Object, Scene, Shape};

    /// A mesh's triangles enter the f32 frame as the same triangles given one by one
    /// would: the same vertices bit for bit, the same dropped (zero area in the scene, or
    /// only once rounded to f32 far from the frame's origin), with or without a
    /// zero-area triangle in the mesh (its f64 test is skipped in a mesh without).
    #[test]
    fn mesh_triangles_enter_the_frame_as_single_triangles() {
        let far = 3.0e7;
        let vertices = vec![
            DVec3::new(0.1, 0.2, 0.3),
            DVec3::new(1.7, -0.4, 0.9),
            DVec3::new(-0.6, 2.2, 1.1),
            DVec3::new(-1.3, 4.2, 1.9), // on the line through 0 and 2 (zero area)
            DVec3::new(far, far, 1.0),
            DVec3::new(far + 0.3, far, 1.0),
            // a triangle in f64 whose corners round to one point in f32 (steps of 2 there)
            DVec3::new(far + 0.6, far + 0.5, 1.0),
        ];
        let base = DVec3::new(0.5, -0.25, 2.0);
        let scene = |shapes: Vec<Shape>| Scene {
            recursion_level: 1,
            pixels: 16,
            objects: (shapes.into_iter())
                .map(|shape| Object {
                    shape,
                    material: Floor::MATERIAL,
                })
                .collect(),
            point_lights: vec![],
            spot_lights: vec![],
        };
        for triangles in [
            vec![[0, 1, 2], [2, 1, 0], [4, 5, 6], [1, 2, 0]],
            vec![[0, 1, 2], [0, 2, 3], [4, 5, 6], [6, 1, 2]],
        ] {
            let mesh = Mesh::new(vertices.clone(), triangles.clone());
            // the mesh without zero-area triangles skips the per-triangle f64 test
            let zero_area = triangles.contains(&[0, 2, 3]) as usize;
            assert_eq!(mesh.zero_area(), zero_area);
            let single = (triangles.iter())
                .map(|t| Shape::Triangle {
                    v: t.map(|i| vertices[i as usize]),
                })
                .collect();
            let a = PrimSet::from_scene(&scene(vec![Shape::Mesh(Arc::new(mesh))]), base);
            let b = PrimSet::from_scene(&scene(single), base);
            let bits = |p: &PrimSet| -> Vec<[u32; 9]> {
                (p.each_triangle())
                    .map(|(_, t)| {
                        let [a, b, c] = t.v.map(|q| q.to_array().map(f32::to_bits));
                        [a[0], a[1], a[2], b[0], b[1], b[2], c[0], c[1], c[2]]
                    })
                    .collect()
            };
            assert_eq!(bits(&a), bits(&b));
            assert_eq!(a.dropped, b.dropped);
            assert_eq!(a.dropped, 1 + zero_area);
        }
    }
}
