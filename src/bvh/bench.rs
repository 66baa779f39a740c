//! The standard trace work of the Embree comparison (`benches/embree/`, whose
//! `gen_data.py` writes the meshes), for `octaray bench-trace` and the criterion
//! benches: a triangle mesh from an OBJ file, 1024² coherent primary rays in 4 × 2
//! pixel packets and 2²⁰ incoherent rays (generated here, or read from the harness's
//! `.rays` files: [`read_rays`]), closest hit with t in (0, ∞), then the
//! shadow rays of each set (any hit, [`shadow_rays`]); build best of 3 and trace best
//! of 5, reported in the Embree harness's fields for the packet path (mode=8: the
//! 8-wide tree collapsed from the same BVH, as a frustum for packets whose lanes share
//! their direction signs, lane by lane for scattered ones), the binary packet path
//! (mode=8b), the single-ray path (mode=1, the 8-wide tree) and the binary single-ray
//! path (mode=1b); each line also gives the bytes per triangle of the trees and
//! triangle arrays, and the process's peak memory so far.

use std::path::Path;
use std::time::Instant;

use glam::{DVec3, Vec3};
use rayon::prelude::*;
use wide::f32x8;

use super::wide::WideBvh;
use super::{BinaryStats, Bvh, Steps};
use crate::geometry::triangle::Triangle32;
use crate::geometry::triangle::Watertight;
use crate::geometry::{Hit1, PrimSet};
use crate::math::packet::{Cmp8, HitPacket8, Mask8, Ray1, RayPacket8, Vec3x8};
use crate::scene::mesh_cache::{CacheUse, load_obj, load_obj_cached};
use crate::scene::obj::{Mesh, ObjError};
use crate::scene::{Material, Object, Scene, Shape};
use crate::simd::isa::{Avx512, Isa};

/// Where the four 4 × 4 quadrants of an 8 × 8 tile of camera rays lie among its 64
/// rays, as `(a, c)`: rays `a..a + 8` and `c..c + 8`. The tile is eight 4 × 2 packets,
/// two across and four down (the order of [`primary_rays`] and of the Embree harness's
/// ray files), and a quadrant is two of them, one above the other. `mode=64` traces a
/// whole tile as these four 16-lane packets.
pub const TILE_QUADRANTS: [(usize, usize); 4] = [(0, 16), (8, 24), (32, 48), (40, 56)];

/// A ray set: origins and unit directions, in packet order (every 8 consecutive rays
/// form one packet).
#[derive(Clone, Debug)]
pub struct RaySet {
    pub name: &'static str,
    pub origin: Vec<Vec3>,
    pub dir: Vec<Vec3>,
}

/// The triangles of an OBJ mesh in f32 as the renderer takes them (the standard
/// meshes are written with exact float32 values, so nothing is rounded); zero-area
/// triangles are dropped, by the renderer's rule ([`mesh_prims`]).
pub fn load_mesh(path: &Path) -> Result<Vec<Triangle32>, ObjError> {
    let prims = mesh_prims(load_obj(path)?);
    Ok(prims.each_triangle().map(|(_, t)| t).collect())
}

/// The triangles of `mesh` in the renderer's f32 frame at the origin, through the
/// renderer's own path ([`PrimSet::from_scene`] on a scene of this one mesh, whose
/// `dropped` counts the triangles it drops as degenerate), without the floor: the
/// vertices in f32 and each triangle's corners, as the renderer holds a mesh before its
/// build.
pub fn mesh_prims(mesh: Mesh) -> PrimSet {
    let scene = Scene {
        recursion_level: 1,
        pixels: 1,
        objects: vec![Object {
            shape: Shape::Mesh(std::sync::Arc::new(mesh)),
            material: Material {
                color: DVec3::ONE,
                ka: 0.0,
                kd: 1.0,
                ks: 0.0,
                kr: 0.0,
                shine: 1.0,
            },
        }],
        point_lights: Vec::new(),
        spot_lights: Vec::new(),
    };
    // the mesh alone: no floor (which a scene always has)
    PrimSet {
        floor: None,
        ..PrimSet::from_scene(&scene, DVec3::ZERO)
    }
}

/// 1024 × 1024 pinhole camera at (0, 2.2, 2.6) looking at the origin, up +y, vertical
/// field of view 40°, through pixel centres; ordered as 8 × 8 tiles of 4 × 2 packets
/// like the Embree harness's `primary.rays`.
pub fn primary_rays(w: usize, h: usize) -> RaySet {
    let eye = DVec3::new(0.0, 2.2, 2.6);
    let fwd = (-eye).normalize();
    let right = fwd.cross(DVec3::Y).normalize();
    let up = right.cross(fwd);
    let th = (40f64.to_radians() / 2.0).tan();
    let mut origin = Vec::with_capacity(w * h);
    let mut dir = Vec::with_capacity(w * h);
    for ty in (0..h).step_by(8) {
        for tx in (0..w).step_by(8) {
            for sy in (0..8).step_by(2) {
                for sx in (0..8).step_by(4) {
                    for py in 0..2 {
                        for px in 0..4 {
                            let (x, y) = (tx + sx + px, ty + sy + py);
                            let u = (x as f64 + 0.5) / w as f64 * 2.0 - 1.0;
                            let v = 1.0 - (y as f64 + 0.5) / h as f64 * 2.0;
                            let d = fwd + right * (u * th) + up * (v * th);
                            origin.push(eye.as_vec3());
                            dir.push(d.normalize().as_vec3());
                        }
                    }
                }
            }
        }
    }
    RaySet {
        name: "primary",
        origin,
        dir,
    }
}

/// `n` rays with origins uniform in [-1.4, 1.4] × [-0.4, 0.4] × [-1.4, 1.4] and
/// directions uniform on the sphere (SplitMix64, fixed seed).
pub fn incoherent_rays(n: usize, seed: u64) -> RaySet {
    let mut s = seed;
    let mut next = move || {
        s = s.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = s;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    };
    let lo = DVec3::new(-1.4, -0.4, -1.4);
    let hi = DVec3::new(1.4, 0.4, 1.4);
    let mut origin = Vec::with_capacity(n);
    let mut dir = Vec::with_capacity(n);
    for _ in 0..n {
        let o = lo + (hi - lo) * DVec3::new(next(), next(), next());
        let z = 2.0 * next() - 1.0;
        let phi = std::f64::consts::TAU * next();
        let r = (1.0 - z * z).sqrt();
        origin.push(o.as_vec3());
        dir.push(DVec3::new(r * phi.cos(), r * phi.sin(), z).as_vec3());
    }
    RaySet {
        name: "incoherent",
        origin,
        dir,
    }
}

/// Most rays a `.rays` file may hold (2²⁴: 384 MiB of rays; the standard sets hold
/// 2²⁰).
pub const MAX_FILE_RAYS: u32 = 1 << 24;

/// A `.rays` file that cannot be traced: the file and what is wrong with it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RaysError {
    pub file: String,
    pub message: String,
}

impl std::fmt::Display for RaysError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: {}", self.file, self.message)
    }
}

impl std::error::Error for RaysError {}

/// The ray count a `.rays` file of the Embree harness declares, checked against the
/// file's size: a little-endian u32 count, then per ray its origin and unit direction
/// as six little-endian f32 (`benches/embree/gen_data.py`, `save_rays`).
pub fn rays_in_file(path: &Path) -> Result<usize, RaysError> {
    open_rays(path).map(|(n, _)| n)
}

/// The file at `path` opened past its ray count, and the count ([`rays_in_file`]'s
/// checks).
fn open_rays(path: &Path) -> Result<(usize, std::fs::File), RaysError> {
    use std::io::Read;
    let fail = |message: String| RaysError {
        file: path.display().to_string(),
        message,
    };
    let mut f = std::fs::File::open(path).map_err(|e| fail(format!("cannot open: {e}")))?;
    let len = f
        .metadata()
        .map_err(|e| fail(format!("cannot read: {e}")))?
        .len();
    let mut head = [0u8; 4];
    f.read_exact(&mut head)
        .map_err(|_| fail(format!("{len} bytes: shorter than its 4-byte ray count")))?;
    let n = u32::from_le_bytes(head);
    if n == 0 {
        return Err(fail("ray count 0: no rays to trace".into()));
    }
    if n > MAX_FILE_RAYS {
        return Err(fail(format!(
            "ray count {n}: more than the {MAX_FILE_RAYS} this benchmark traces"
        )));
    }
    let want = 4 + 24 * u64::from(n);
    if len != want {
        return Err(fail(format!(
            "ray count {n} needs {want} bytes (24 per ray after the count), the file has {len}"
        )));
    }
    Ok((n as usize, f))
}

/// The rays of a `.rays` file of the Embree harness ([`rays_in_file`]), in its order
/// (streamed: the file is never held whole beside the rays).
pub fn read_rays(path: &Path, name: &'static str) -> Result<RaySet, RaysError> {
    use std::io::Read;
    let (n, f) = open_rays(path)?;
    let fail = |e: std::io::Error| RaysError {
        file: path.display().to_string(),
        message: format!("cannot read: {e}"),
    };
    let mut f = std::io::BufReader::new(f);
    let (mut origin, mut dir) = (Vec::with_capacity(n), Vec::with_capacity(n));
    let mut ray = [0u8; 24];
    for _ in 0..n {
        f.read_exact(&mut ray).map_err(fail)?;
        let c = |k: usize| f32::from_le_bytes([ray[k], ray[k + 1], ray[k + 2], ray[k + 3]]);
        origin.push(Vec3::new(c(0), c(4), c(8)));
        dir.push(Vec3::new(c(12), c(16), c(20)));
    }
    Ok(RaySet { name, origin, dir })
}

/// Why `bench-trace` stopped: its mesh or a ray file.
#[derive(Debug)]
pub enum BenchError {
    Mesh(ObjError),
    Rays(RaysError),
}

impl std::fmt::Display for BenchError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            BenchError::Mesh(e) => e.fmt(f),
            BenchError::Rays(e) => e.fmt(f),
        }
    }
}

impl std::error::Error for BenchError {}

impl From<ObjError> for BenchError {
    fn from(e: ObjError) -> Self {
        BenchError::Mesh(e)
    }
}

impl From<RaysError> for BenchError {
    fn from(e: RaysError) -> Self {
        BenchError::Rays(e)
    }
}

/// How rays are traced.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// `Bvh::intersect_1`, one ray at a time through the 8-wide tree.
    Single,
    /// `Bvh::intersect_1_binary`, one ray at a time through the binary tree (`mode=1b`).
    SingleBinary,
    /// `Bvh::intersect_stream`, each work item's rays as one stream of single rays
    /// (`mode=1s`: sixteen walks of the 8-wide tree in flight; Embree's analogue is
    /// `rtcIntersect1M`, the harness's `mode=1M`).
    Stream,
    /// `Bvh::intersect_x8`, 8 consecutive rays as one packet (the 8-wide tree: as a
    /// frustum when the lanes share their direction signs and lie close, lane by lane
    /// when scattered, `Bvh::intersect_x8` explains which).
    Packet8,
    /// `Bvh::intersect_x8_binary`, packets through the binary tree only (`mode=8b`).
    Packet8Binary,
    /// `Bvh::intersect_x16`, 16 consecutive rays as one packet (the `avx512` kernels;
    /// the proof that the CPU runs them).
    Packet16(Avx512),
    /// `Bvh::intersect_x64`, 64 consecutive rays (an 8 × 8 tile of the generated primary
    /// rays and of the harness's file) as four 16-lane packets walking the tree once;
    /// shadow rays (any hit) go 16 at a time, as in `Packet16`.
    Packet64(Avx512),
}

impl Mode {
    pub fn width(self) -> usize {
        match self {
            Mode::Single | Mode::SingleBinary | Mode::Stream => 1,
            Mode::Packet8 | Mode::Packet8Binary => 8,
            Mode::Packet16(_) => 16,
            Mode::Packet64(_) => 64,
        }
    }

    /// The `mode=` field: the width, `1b` for the binary single-ray path, `1s` for
    /// streams.
    pub fn label(self) -> &'static str {
        match self {
            Mode::Single => "1",
            Mode::SingleBinary => "1b",
            Mode::Stream => "1s",
            Mode::Packet8 => "8",
            Mode::Packet8Binary => "8b",
            Mode::Packet16(_) => "16",
            Mode::Packet64(_) => "64",
        }
    }
}

/// Rays per work item of the parallel traces.
const CHUNK: usize = 1024;

fn add_steps(a: Steps, b: Steps) -> Steps {
    Steps {
        boxes: a.boxes + b.boxes,
        prims: a.prims + b.prims,
        quadrics: a.quadrics + b.quadrics,
    }
}

/// Runs `chunk` on every `CHUNK` items of `out` (with the chunk's index) and sums the
/// steps; on the calling thread where worker threads cannot start.
fn chunks<T: Send>(
    out: &mut [T],
    chunk: impl Fn((usize, &mut [T])) -> Steps + Sync + Send,
) -> Steps {
    if crate::parallel::parallel() {
        out.par_chunks_mut(CHUNK)
            .enumerate()
            .map(chunk)
            .reduce(Steps::default, add_steps)
    } else {
        out.chunks_mut(CHUNK)
            .enumerate()
            .map(chunk)
            .fold(Steps::default(), add_steps)
    }
}

/// The packet of rays `b..b + n` of `origin`/`dir` (n <= 8; a short packet padded
/// with copies of its first ray), with `active` lanes.
#[inline]
fn packet(origin: &[Vec3], dir: &[Vec3], b: usize, n: usize, active: Mask8) -> RayPacket8 {
    // a whole packet straight from the ray arrays (a copy of run-time length would
    // be a memmove call); a short last one padded
    if let (Ok(o), Ok(d)) = (
        <&[Vec3; 8]>::try_from(&origin[b..b + n]),
        <&[Vec3; 8]>::try_from(&dir[b..b + n]),
    ) {
        RayPacket8::new(Vec3x8::from_lanes(o), Vec3x8::from_lanes(d), active)
    } else {
        let mut o = [origin[b]; 8];
        let mut d = [dir[b]; 8];
        o[..n].copy_from_slice(&origin[b..b + n]);
        d[..n].copy_from_slice(&dir[b..b + n]);
        RayPacket8::new(Vec3x8::from_lanes(&o), Vec3x8::from_lanes(&d), active)
    }
}

/// What the trace writes for a ray's hit: its distance, −1 for a miss (picked, not
/// branched on, as the Embree harness's `?:`).
#[inline(always)]
fn hit_t(h: &Hit1) -> f32 {
    [-1.0, h.t][usize::from(h.is_hit())]
}

/// Traces every ray of `rays`, writing the hit distance (−1 for a miss) per ray.
pub fn trace(bvh: &Bvh, rays: &RaySet, mode: Mode, t_out: &mut [f32]) -> Steps {
    chunks(t_out, |(c, out): (usize, &mut [f32])| {
        let mut steps = Steps::default();
        let base = c * CHUNK;
        match mode {
            Mode::Stream => {
                let rs: Vec<Ray1> = (base..base + out.len())
                    .map(|i| Ray1::new(rays.origin[i], rays.dir[i]))
                    .collect();
                let mut hs = vec![Hit1::new(f32::INFINITY); rs.len()];
                bvh.intersect_stream::<Watertight>(&rs, &mut hs, &mut steps);
                for (t, h) in out.iter_mut().zip(&hs) {
                    *t = hit_t(h);
                }
            }
            Mode::Single | Mode::SingleBinary => {
                for (i, t) in out.iter_mut().enumerate() {
                    let r = Ray1::new(rays.origin[base + i], rays.dir[base + i]);
                    let mut h = Hit1::new(f32::INFINITY);
                    if mode == Mode::Single {
                        bvh.intersect_1::<Watertight>(&r, &mut h, &mut steps);
                    } else {
                        bvh.intersect_1_binary::<Watertight>(&r, &mut h, &mut steps);
                    }
                    *t = hit_t(&h);
                }
            }
            Mode::Packet8 | Mode::Packet8Binary => {
                for (k, ts) in out.chunks_mut(8).enumerate() {
                    let n = ts.len();
                    let active = Mask8::from_bits((1u32 << n) - 1);
                    let p = packet(&rays.origin, &rays.dir, base + k * 8, n, active);
                    let mut h = HitPacket8::new(f32x8::splat(f32::INFINITY));
                    if mode == Mode::Packet8 {
                        bvh.intersect_x8::<Watertight>(&p, active, &mut h, &mut steps);
                    } else {
                        bvh.intersect_x8_binary::<Watertight>(&p, active, &mut h, &mut steps);
                    }
                    // t of the lanes that hit, −1 for the others, stored whole
                    let t = h.hit_mask().select(h.t, f32x8::splat(-1.0)).to_array();
                    if let Ok(ts) = <&mut [f32; 8]>::try_from(&mut *ts) {
                        *ts = t;
                    } else {
                        ts.copy_from_slice(&t[..n]);
                    }
                }
            }
            #[cfg(target_arch = "x86_64")]
            // SAFETY: the token proves this CPU has the features the function is
            // compiled with
            Mode::Packet16(_) => unsafe { x16::trace(bvh, rays, base, out, &mut steps) },
            #[cfg(target_arch = "x86_64")]
            // SAFETY: as above
            Mode::Packet64(_) => unsafe { x16::trace64(bvh, rays, base, out, &mut steps) },
            #[cfg(not(target_arch = "x86_64"))]
            Mode::Packet16(_) | Mode::Packet64(_) => unreachable!("no AVX-512 outside x86-64"),
        }
        steps
    })
}

/// The light of the shadow rays: beside the torus, a little above it (about half of
/// the primary rays' hit points are in its shadow).
pub const SHADOW_LIGHT: Vec3 = Vec3::new(3.0, 1.0, -2.0);

/// Shadow rays: ray i runs from the closest hit of ray i of a ray set toward
/// [`SHADOW_LIGHT`], unit direction, blocked by anything with 0 < t < `t_max[i]`;
/// `t_max[i]` <= 0 where ray i missed (no shadow ray: an inactive packet lane).
#[derive(Clone, Debug)]
pub struct ShadowRays {
    pub rays: RaySet,
    pub t_max: Vec<f32>,
}

/// The shadow rays of `rays`, from their closest hits `t` (−1 for a miss, as
/// [`trace`] writes them): the origin is the hit point pulled back toward the ray's
/// origin by 0.1 % of the hit distance (off the surface, on the side the ray came
/// from), p = o + 0.999·t·d, the direction (L − p)/|L − p| and t_max = |L − p|, all in
/// f64 from the f32 ray and t, then rounded to f32 (`benches/embree/embree_bench.cpp`
/// makes the same set from Embree's hits). Takes the ray set and `t` as its storage.
pub fn shadow_rays(mut rays: RaySet, mut t: Vec<f32>) -> ShadowRays {
    let light = SHADOW_LIGHT.as_dvec3();
    for ((o, d), t) in rays.origin.iter_mut().zip(&mut rays.dir).zip(&mut t) {
        if *t < 0.0 {
            *t = 0.0;
            continue;
        }
        let p = o.as_dvec3() + d.as_dvec3() * (0.999 * *t as f64);
        let to = light - p;
        let len = to.length();
        (*o, *d, *t) = (p.as_vec3(), (to / len).as_vec3(), len as f32);
    }
    rays.name = match rays.name {
        "primary" => "primary.shadow",
        "incoherent" => "incoherent.shadow",
        _ => "shadow",
    };
    ShadowRays { rays, t_max: t }
}

/// Traces every shadow ray of `set` (any hit), writing 1 where it is blocked, 0 where
/// not or where there is no shadow ray.
pub fn trace_occluded(bvh: &Bvh, set: &ShadowRays, mode: Mode, out: &mut [u8]) -> Steps {
    let rays = &set.rays;
    chunks(out, |(c, out): (usize, &mut [u8])| {
        let mut steps = Steps::default();
        let base = c * CHUNK;
        match mode {
            Mode::Stream => {
                // the rays without a shadow ray (t_max 0) are not traced
                let idx: Vec<usize> = (base..base + out.len())
                    .filter(|&i| set.t_max[i] > 0.0)
                    .collect();
                let rs: Vec<Ray1> = (idx.iter())
                    .map(|&i| Ray1::new(rays.origin[i], rays.dir[i]))
                    .collect();
                let tm: Vec<f32> = idx.iter().map(|&i| set.t_max[i]).collect();
                let mut bl = vec![false; rs.len()];
                bvh.occluded_stream::<Watertight>(&rs, &tm, &mut bl, &mut steps);
                out.fill(0);
                for (&i, &b) in idx.iter().zip(&bl) {
                    out[i - base] = b as u8;
                }
            }
            Mode::Single | Mode::SingleBinary => {
                for (i, blocked) in out.iter_mut().enumerate() {
                    let t_max = set.t_max[base + i];
                    *blocked = 0;
                    if t_max <= 0.0 {
                        continue;
                    }
                    let r = Ray1::new(rays.origin[base + i], rays.dir[base + i]);
                    *blocked = if mode == Mode::Single {
                        bvh.occluded_1::<Watertight>(&r, t_max, &mut steps)
                    } else {
                        bvh.occluded_1_binary::<Watertight>(&r, t_max, &mut steps)
                    } as u8;
                }
            }
            Mode::Packet8 | Mode::Packet8Binary => {
                for (k, bs) in out.chunks_mut(8).enumerate() {
                    let b = base + k * 8;
                    let n = bs.len();
                    let mut tm = [0.0f32; 8];
                    tm[..n].copy_from_slice(&set.t_max[b..b + n]);
                    let t_max = f32x8::from(tm);
                    let active = t_max.gt(f32x8::ZERO);
                    bs.fill(0);
                    if active.none() {
                        continue;
                    }
                    let p = packet(&rays.origin, &rays.dir, b, n, active);
                    let blocked = if mode == Mode::Packet8 {
                        bvh.occluded_x8::<Watertight>(&p, active, t_max, &mut steps)
                    } else {
                        bvh.occluded_x8_binary::<Watertight>(&p, active, t_max, &mut steps)
                    };
                    for (l, x) in bs.iter_mut().enumerate() {
                        *x = (blocked.bits() >> l & 1) as u8;
                    }
                }
            }
            #[cfg(target_arch = "x86_64")]
            // SAFETY: as in `trace`
            Mode::Packet16(_) | Mode::Packet64(_) => unsafe {
                x16::trace_occluded(bvh, set, base, out, &mut steps)
            },
            #[cfg(not(target_arch = "x86_64"))]
            Mode::Packet16(_) | Mode::Packet64(_) => unreachable!("no AVX-512 outside x86-64"),
        }
        steps
    })
}

/// The 16-lane traces, compiled with AVX-512 enabled.
#[cfg(target_arch = "x86_64")]
mod x16 {
    use super::{RaySet, ShadowRays, packet};
    use crate::bvh::{Bvh, Steps};
    use crate::geometry::triangle::Watertight;
    use crate::simd::packet::{HitPacket16, RayPacket16, half_mask};
    use crate::simd::w16::{F16, I16, M16};
    use crate::simd::{IntLanes as _, LaneMask as _, Lanes as _};

    /// The packet of rays `b..b + n` (n <= 16; missing lanes inactive) and its lanes.
    #[inline(always)]
    fn packet16(rays: &RaySet, b: usize, n: usize, active: M16) -> RayPacket16 {
        packet16_at(rays, [b, b + 8], n, active)
    }

    /// The packet of `n` rays (n <= 16; missing lanes inactive): lanes 0–7 from rays
    /// `at[0]..`, lanes 8–15 from rays `at[1]..`.
    #[inline(always)]
    fn packet16_at(rays: &RaySet, at: [usize; 2], n: usize, active: M16) -> RayPacket16 {
        let n0 = n.min(8);
        let h0 = packet(&rays.origin, &rays.dir, at[0], n0, half_mask(active, 0));
        let h1 = if n > 8 {
            packet(&rays.origin, &rays.dir, at[1], n - 8, half_mask(active, 1))
        } else {
            h0
        };
        RayPacket16::new([h0, h1])
    }

    /// Sixteen lanes without a hit.
    #[inline(always)]
    fn no_hit() -> HitPacket16 {
        HitPacket16 {
            t: F16::splat(f32::INFINITY),
            prim: I16::splat(-1),
            u: F16::zero(),
            v: F16::zero(),
        }
    }

    /// Closest hits of 16 consecutive rays at a time (as `super::trace`'s packets).
    #[target_feature(enable = "avx2,fma,avx512f,avx512vl,avx512bw,avx512dq")]
    pub(super) fn trace(bvh: &Bvh, rays: &RaySet, base: usize, out: &mut [f32], steps: &mut Steps) {
        for (k, ts) in out.chunks_mut(16).enumerate() {
            let n = ts.len();
            let active = M16::from_bits((1u32 << n) - 1);
            let p = packet16(rays, base + k * 16, n, active);
            let mut h = no_hit();
            bvh.intersect_x16::<Watertight>(&p, active, &mut h, steps);
            let t = F16::select(h.prim.non_negative(), h.t, F16::splat(-1.0)).to_array();
            ts.copy_from_slice(&t[..n]);
        }
    }

    /// Closest hits of 64 consecutive rays at a time, four 16-lane packets walking
    /// the tree once (`Bvh::intersect_x64`): a whole 8 × 8 tile as its four 4 × 4
    /// quadrants (a square packet's frustum meets fewer triangles than a strip's, 1.0
    /// candidates per ray against 1.2 on torus1m), a shorter run (the last of a set)
    /// as strips of 16 consecutive rays.
    #[target_feature(enable = "avx2,fma,avx512f,avx512vl,avx512bw,avx512dq")]
    pub(super) fn trace64(
        bvh: &Bvh,
        rays: &RaySet,
        base: usize,
        out: &mut [f32],
        steps: &mut Steps,
    ) {
        for (k, ts) in out.chunks_mut(64).enumerate() {
            let b = base + k * 64;
            let mut h = [no_hit(), no_hit(), no_hit(), no_hit()];
            if ts.len() == 64 {
                // (written out, as no closure touches a 16-lane value: `simd::packet`)
                let q = super::TILE_QUADRANTS;
                let all = M16::ALL;
                let p = [
                    packet16_at(rays, [b + q[0].0, b + q[0].1], 16, all),
                    packet16_at(rays, [b + q[1].0, b + q[1].1], 16, all),
                    packet16_at(rays, [b + q[2].0, b + q[2].1], 16, all),
                    packet16_at(rays, [b + q[3].0, b + q[3].1], 16, all),
                ];
                bvh.intersect_x64::<Watertight>(&p, [all; 4], &mut h, steps);
                for (h, &(a, c)) in h.iter().zip(&q) {
                    let t = F16::select(h.prim.non_negative(), h.t, F16::splat(-1.0)).to_array();
                    ts[a..a + 8].copy_from_slice(&t[..8]);
                    ts[c..c + 8].copy_from_slice(&t[8..]);
                }
                continue;
            }
            // the rays of packet q: ts[16q..], as many as there are (none past the end)
            let n = ts.len();
            let len = |q: usize| n.saturating_sub(16 * q).min(16);
            let act = [0, 1, 2, 3].map(|q| M16::from_bits((1u32 << len(q)) - 1));
            // (a packet past the end repeats the first one's rays, none of them active;
            // written out, as no closure touches a 16-lane value: `simd::packet`)
            let from = |q: usize| {
                if len(q) == 0 {
                    (b, len(0))
                } else {
                    (b + 16 * q, len(q))
                }
            };
            let f = [from(0), from(1), from(2), from(3)];
            let p = [
                packet16(rays, f[0].0, f[0].1, act[0]),
                packet16(rays, f[1].0, f[1].1, act[1]),
                packet16(rays, f[2].0, f[2].1, act[2]),
                packet16(rays, f[3].0, f[3].1, act[3]),
            ];
            bvh.intersect_x64::<Watertight>(&p, act, &mut h, steps);
            // (packets past the end have no rays: `zip` stops at the last one)
            for (h, ts) in h.iter().zip(ts.chunks_mut(16)) {
                let t = F16::select(h.prim.non_negative(), h.t, F16::splat(-1.0)).to_array();
                ts.copy_from_slice(&t[..ts.len()]);
            }
        }
    }

    /// Shadow rays 16 at a time (as `super::trace_occluded`'s packets).
    #[target_feature(enable = "avx2,fma,avx512f,avx512vl,avx512bw,avx512dq")]
    pub(super) fn trace_occluded(
        bvh: &Bvh,
        set: &ShadowRays,
        base: usize,
        out: &mut [u8],
        steps: &mut Steps,
    ) {
        for (k, bs) in out.chunks_mut(16).enumerate() {
            let b = base + k * 16;
            let n = bs.len();
            let mut tm = [0.0f32; 16];
            tm[..n].copy_from_slice(&set.t_max[b..b + n]);
            let t_max = F16::from_array(tm);
            let active = t_max.gt(F16::zero());
            bs.fill(0);
            if active.none() {
                continue;
            }
            let p = packet16(&set.rays, b, n, active);
            let blocked = bvh.occluded_x16::<Watertight>(&p, active, t_max, steps);
            for (l, x) in bs.iter_mut().enumerate() {
                *x = (blocked.bits() >> l & 1) as u8;
            }
        }
    }
}

/// One line of results, in the Embree harness's fields (and two of its own).
#[derive(Clone, Debug)]
pub struct TraceRun {
    pub mesh: String,
    /// The ray set: `primary`, `incoherent`, or their shadow rays `primary.shadow`,
    /// `incoherent.shadow` (any hit).
    pub rays: &'static str,
    pub threads: usize,
    pub mode: Mode,
    /// The kernels' instruction set (`avx2`, `avx512`).
    pub isa: Isa,
    pub tris: usize,
    pub build_ms: f64,
    pub trace_ms: f64,
    /// Rays traced per second (shadow sets: the shadow rays, one per hit of the set).
    pub mrays_per_s: f64,
    /// The fraction of rays that hit (shadow sets: of shadow rays blocked).
    pub hits: f64,
    /// The mean t of the hits (shadow sets: the mean t_max of the shadow rays, the
    /// distance to the light, which checks that both sides traced the same set).
    pub mean_t: f64,
    /// Box and primitive tests per ray in the last trace.
    pub boxes_per_ray: f64,
    pub prims_per_ray: f64,
    /// Bytes per triangle of the trees and triangle arrays ([`AccelBytes`]).
    pub bytes_per_tri: f64,
    /// The process's peak resident memory so far (MB), where the system tells it.
    pub peak_rss_mb: Option<f64>,
}

impl std::fmt::Display for TraceRun {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "octaray mesh={} rays={} threads={} mode={} isa={} tris={} build_ms={:.1} trace_ms={:.1} Mrays/s={:.2} hits={:.4} mean_t={:.6} bytes/tri={:.1}",
            self.mesh,
            self.rays,
            self.threads,
            self.mode.label(),
            self.isa,
            self.tris,
            self.build_ms,
            self.trace_ms,
            self.mrays_per_s,
            self.hits,
            self.mean_t,
            self.bytes_per_tri
        )?;
        if let Some(mb) = self.peak_rss_mb {
            write!(f, " peak_rss_MB={mb:.1}")?;
        }
        Ok(())
    }
}

/// The process's peak resident set size in MB (`VmHWM` of `/proc/self/status`);
/// `None` where there is no such file.
pub fn peak_rss_mb() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb / 1024.0)
}

/// The bytes a built [`Bvh`] keeps for tracing, by part.
#[derive(Clone, Copy, Debug, Default)]
pub struct AccelBytes {
    /// The binary tree's nodes.
    pub binary_nodes: usize,
    /// The 8-wide tree's nodes.
    pub wide_nodes: usize,
    /// The triangle blocks (the triangles, SoA, in leaf order) and their index.
    pub wide_blocks: usize,
    /// The binary leaves' boxes per lane of the blocks.
    pub leaf_boxes: usize,
    /// The other primitive arrays in leaf order (the triangles' object indices, the
    /// spheres and quadrics with theirs).
    pub prims: usize,
}

impl AccelBytes {
    pub fn of(bvh: &Bvh) -> AccelBytes {
        use std::mem::size_of_val;
        let p = &bvh.prims;
        AccelBytes {
            binary_nodes: size_of_val(&bvh.nodes[..]),
            wide_nodes: size_of_val(&bvh.wide.nodes[..]),
            wide_blocks: size_of_val(&p.blocks[..]) + size_of_val(&p.block_at[..]),
            leaf_boxes: size_of_val(&bvh.wide.leaf_boxes[..]),
            prims: size_of_val(&p.triangle_obj[..])
                + size_of_val(&p.spheres[..])
                + size_of_val(&p.sphere_obj[..])
                + size_of_val(&p.quadrics[..])
                + size_of_val(&p.quadric_obj[..]),
        }
    }

    pub fn total(&self) -> usize {
        self.binary_nodes + self.wide_nodes + self.wide_blocks + self.leaf_boxes + self.prims
    }
}

/// A BVH built best of 3: the tree, the best time of the whole build and of its
/// collapse to the 8-wide tree (ms), and the binary tree's figures (taken before the
/// collapse, which drops it unless kept).
pub struct Built {
    pub bvh: Bvh,
    pub build_ms: f64,
    pub collapse_ms: f64,
    pub binary: BinaryStats,
}

/// Builds the BVH best of 3 (as [`Bvh::build`], or [`Bvh::build_with_binary`] with
/// `keep_binary`; timed in its two parts: the binary tree, then its collapse), the
/// first over `prims`, the others over what `reload`
/// gives (the same mesh read again, untimed). Each build drops the tree before it
/// first and takes its triangles: no copy of the mesh or second tree stays beside the
/// one being built (a copy of torus1m's triangles kept for the next build would add
/// 18 MB to bench-trace's peak memory, the mesh itself 24 MB).
pub fn timed_build<E>(
    prims: PrimSet,
    mut reload: impl FnMut() -> Result<PrimSet, E>,
    keep_binary: bool,
) -> Result<Built, E> {
    let (mut build_ms, mut collapse_ms) = (f64::INFINITY, f64::INFINITY);
    let mut bvh = None;
    let mut binary = BinaryStats::default();
    let mut first = Some(prims);
    for _ in 0..3 {
        // the previous tree goes before this one's input is read and built
        drop(bvh.take());
        let mut prims = match first.take() {
            Some(prims) => prims,
            None => reload()?,
        };
        let start = Instant::now();
        let (nodes, order) = super::build::build(&mut prims);
        let built = Instant::now();
        // (untimed)
        binary = BinaryStats::of(&nodes);
        let root = nodes.first().copied();
        let resumed = Instant::now();
        let (wide, nodes) = WideBvh::collapse(nodes, &mut prims, order, keep_binary);
        let end = Instant::now();
        build_ms = build_ms.min((built - start + (end - resumed)).as_secs_f64() * 1e3);
        collapse_ms = collapse_ms.min((end - resumed).as_secs_f64() * 1e3);
        bvh = Some(Bvh {
            nodes,
            root,
            prims,
            wide,
        });
    }
    let bvh = bvh.expect("three builds");
    #[cfg(debug_assertions)]
    if let Err(e) = bvh.validate() {
        panic!("BVH invariant broken: {e}");
    }
    Ok(Built {
        bvh,
        build_ms,
        collapse_ms,
        binary,
    })
}

/// Traces `rays` best of `reps` and summarises the run: time (ms), fraction of hits,
/// mean t, steps; `t` receives the hit distances of the last run.
pub fn timed_trace(
    bvh: &Bvh,
    rays: &RaySet,
    mode: Mode,
    reps: usize,
    t: &mut [f32],
) -> (f64, f64, f64, Steps) {
    let mut best = f64::INFINITY;
    let mut steps = Steps::default();
    for _ in 0..reps {
        let start = Instant::now();
        steps = trace(bvh, rays, mode, t);
        best = best.min(start.elapsed().as_secs_f64() * 1e3);
    }
    let (n, sum) = t
        .iter()
        .filter(|&&t| t >= 0.0)
        .fold((0usize, 0.0f64), |(n, s), &t| (n + 1, s + t as f64));
    let hits = n as f64 / t.len() as f64;
    let mean = if n > 0 { sum / n as f64 } else { 0.0 };
    (best, hits, mean, steps)
}

/// Traces the shadow rays `set` best of `reps`: time (ms), the fraction of shadow
/// rays blocked, their mean t_max, steps.
pub fn timed_occluded(
    bvh: &Bvh,
    set: &ShadowRays,
    mode: Mode,
    reps: usize,
    blocked: &mut [u8],
) -> (f64, f64, f64, Steps) {
    let mut best = f64::INFINITY;
    let mut steps = Steps::default();
    for _ in 0..reps {
        let start = Instant::now();
        steps = trace_occluded(bvh, set, mode, blocked);
        best = best.min(start.elapsed().as_secs_f64() * 1e3);
    }
    let (n, sum, b) = set
        .t_max
        .iter()
        .zip(blocked.iter())
        .filter(|(t, _)| **t > 0.0)
        .fold((0usize, 0.0f64, 0usize), |(n, s, b), (&t, &x)| {
            (n + 1, s + t as f64, b + x as usize)
        });
    let n1 = n.max(1) as f64;
    (best, b as f64 / n1, sum / n1, steps)
}

/// The whole standard work on one mesh: load, build, then per ray set (primary,
/// incoherent) closest hit and the set's shadow rays (any hit) on the packet and the
/// single-ray paths, each line printed to `out` as it is measured. Load time, SAH cost,
/// depth, memory by part and steps per ray go to `log`.
#[allow(clippy::too_many_arguments)]
pub fn run(
    mesh: &Path,
    rays_dir: Option<&Path>,
    isa: Isa,
    threads: usize,
    reps: usize,
    out: &mut (dyn std::io::Write + Send),
    log: &mut (dyn std::io::Write + Send),
) -> Result<Vec<TraceRun>, BenchError> {
    let name = mesh.file_name().map_or_else(
        || mesh.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    );
    // the ray files are checked before the mesh is loaded and built
    let ray_file = |set: &str| rays_dir.map(|d| d.join(format!("{set}.rays")));
    for path in ["primary", "incoherent"].iter().filter_map(|s| ray_file(s)) {
        let n = rays_in_file(&path)?;
        let _ = writeln!(log, "octaray rays: {n} rays from {}", path.display());
    }
    crate::parallel::with_threads(Some(threads), || {
        let start = Instant::now();
        let cache = crate::scene::mesh_cache::dir();
        let (obj, used) = load_obj_cached(mesh, cache.as_deref())?;
        let load_ms = start.elapsed().as_secs_f64() * 1e3;
        let how = match used {
            CacheUse::Read(_) => "read the mesh cache".to_string(),
            CacheUse::Written(_) => "read and parse the OBJ file, write the mesh cache".into(),
            CacheUse::Unused => "read and parse the OBJ file".into(),
            CacheUse::NotWritten(why) => {
                format!("read and parse the OBJ file; mesh cache not written: {why}")
            }
        };
        let (vertices, faces) = (obj.vertices().len(), obj.triangles().len());
        let prims = mesh_prims(obj);
        let dropped = prims.dropped;
        // the process's peak memory so far, for the log
        let peak = || peak_rss_mb().map_or_else(String::new, |mb| format!(", peak_rss_MB={mb:.1}"));
        let _ = writeln!(
            log,
            "octaray mesh: {name}: load_ms={load_ms:.1} ({how}), {vertices} vertices, {faces} triangles, {dropped} dropped as degenerate{}",
            peak()
        );
        let mut runs = Vec::new();
        // OCTARAY_BENCH_ONLY=primary/8 (rays/mode, either part optional; rays may be a
        // shadow set, `primary.shadow`): only those lines, for profiling
        let only = std::env::var("OCTARAY_BENCH_ONLY").unwrap_or_default();
        let (only_rays, only_mode) = only.split_once('/').unwrap_or((&only, ""));
        // the 16-lane packets (and four of them at once) under `avx512` only
        let wide16 = isa.avx512_kernels();
        let modes = (wide16.map(Mode::Packet64).into_iter())
            .chain(wide16.map(Mode::Packet16))
            .chain([
                Mode::Packet8,
                Mode::Packet8Binary,
                Mode::Single,
                Mode::Stream,
                Mode::SingleBinary,
            ])
            .filter(|m| only_mode.is_empty() || only_mode == m.label())
            .collect::<Vec<_>>();
        // the binary tree stays for the binary modes only (the renderer drops it)
        let binary_modes = modes
            .iter()
            .any(|m| matches!(m, Mode::Packet8Binary | Mode::SingleBinary));
        let Built {
            bvh,
            build_ms,
            collapse_ms,
            binary,
        } = timed_build(
            prims,
            || Ok::<_, ObjError>(mesh_prims(load_obj_cached(mesh, cache.as_deref())?.0)),
            binary_modes,
        )?;
        let ntris = faces;
        let _ = writeln!(
            log,
            "octaray bvh: build_ms={build_ms:.1} (best of 3), {} binary nodes (kept {}), depth {}, SAH cost {:.2}",
            binary.nodes,
            if bvh.packets_walk_binary() {
                "for the packets"
            } else if !bvh.nodes.is_empty() {
                "for the binary modes"
            } else {
                "until the collapse"
            },
            binary.depth,
            binary.sah_cost,
        );
        let (w, blocks) = (&bvh.wide, &bvh.prims.blocks);
        let lanes: u64 = blocks.iter().map(|b| b.count as u64).sum();
        let one_leaf = blocks.iter().filter(|b| b.one_leaf).count();
        let _ = writeln!(
            log,
            "octaray wide bvh: collapse_ms={collapse_ms:.1} (of build_ms), {} nodes, depth {}, {} triangle blocks ({:.1} of 8 lanes used, {:.0} % of one binary leaf)",
            w.nodes.len(),
            w.depth(),
            blocks.len(),
            lanes as f64 / blocks.len().max(1) as f64,
            100.0 * one_leaf as f64 / blocks.len().max(1) as f64
        );
        let mut bytes = AccelBytes::of(&bvh);
        let per = |b: usize| b as f64 / ntris.max(1) as f64;
        // what the renderer keeps: a binary tree here only for the binary modes is not
        let binary_here = if bvh.packets_walk_binary() {
            0
        } else {
            std::mem::take(&mut bytes.binary_nodes)
        };
        let _ = writeln!(
            log,
            "octaray memory: {:.1} bytes per triangle kept for tracing: binary nodes {:.1}{}, wide nodes {:.1}, triangle blocks {:.1}, their leaf boxes {:.1}, object indices {:.1}{}",
            per(bytes.total()),
            per(bytes.binary_nodes),
            if binary_here > 0 {
                format!(
                    " (and {:.1} kept for the binary modes only)",
                    per(binary_here)
                )
            } else {
                String::new()
            },
            per(bytes.wide_nodes),
            per(bytes.wide_blocks),
            per(bytes.leaf_boxes),
            per(bytes.prims),
            peak()
        );
        let wanted = |name: &str| only_rays.is_empty() || only_rays == name;
        let mut line = |rays: &'static str, n: usize, mode: Mode, r: (f64, f64, f64, Steps)| {
            let (trace_ms, hits, mean_t, steps) = r;
            let n = n as f64;
            let run = TraceRun {
                mesh: name.clone(),
                rays,
                threads,
                mode,
                isa,
                tris: ntris,
                build_ms,
                trace_ms,
                mrays_per_s: n / trace_ms / 1e3,
                hits,
                mean_t,
                boxes_per_ray: steps.boxes as f64 / n,
                prims_per_ray: steps.prims as f64 / n,
                bytes_per_tri: per(bytes.total()),
                peak_rss_mb: peak_rss_mb(),
            };
            let _ = writeln!(out, "{run}");
            let _ = writeln!(
                log,
                "  ({} mode={}: {:.1} {} and {:.1} triangle tests per ray)",
                run.rays,
                mode.label(),
                run.boxes_per_ray,
                match mode {
                    Mode::Single | Mode::Stream => "wide node tests (8 boxes each)",
                    Mode::Packet8 | Mode::Packet16(_) | Mode::Packet64(_) =>
                        "node tests (8-wide: per packet when the signs agree, per lane when not)",
                    _ => "box tests",
                },
                run.prims_per_ray
            );
            runs.push(run);
        };
        // one ray set at a time (2²⁰ rays are 24 MB), its shadow rays in its storage
        for (set, shadow) in [
            ("primary", "primary.shadow"),
            ("incoherent", "incoherent.shadow"),
        ] {
            if !wanted(set) && !wanted(shadow) {
                continue;
            }
            let rays = match ray_file(set) {
                Some(path) => read_rays(&path, set)?,
                None if set == "primary" => primary_rays(1024, 1024),
                None => incoherent_rays(1 << 20, 7),
            };
            let mut t = vec![0.0f32; rays.origin.len()];
            if wanted(set) {
                for &mode in &modes {
                    let r = timed_trace(&bvh, &rays, mode, reps, &mut t);
                    line(rays.name, rays.origin.len(), mode, r);
                }
            }
            if wanted(shadow) {
                // from the closest hits of the single-ray path
                trace(&bvh, &rays, Mode::Single, &mut t);
                let set = shadow_rays(rays, t);
                let n = set.t_max.iter().filter(|&&t| t > 0.0).count();
                let mut blocked = vec![0u8; set.t_max.len()];
                // (`mode=64` traces shadow rays 16 at a time: the any-hit walk of 64 as
                // one ran 0.7–0.8 of it, benches/README.md)
                for &mode in modes.iter().filter(|m| !matches!(m, Mode::Packet64(_))) {
                    let r = timed_occluded(&bvh, &set, mode, reps, &mut blocked);
                    line(set.rays.name, n, mode, r);
                }
            }
        }
        Ok(runs)
    })
}

/// The standard torus (major radius 1, minor 0.4, around y; `nu` × `nv` segments, two
/// triangles per quad), built in f32 exactly as `gen_data.py` does, for the criterion
/// benches (bench-trace itself loads the OBJ file).
pub fn torus(nu: usize, nv: usize) -> Vec<Triangle32> {
    let vert = |i: usize, j: usize| {
        let u = (i % nu) as f64 * std::f64::consts::TAU / nu as f64;
        let v = (j % nv) as f64 * std::f64::consts::TAU / nv as f64;
        let r = 1.0 + 0.4 * v.cos();
        Vec3::new(
            (r * u.cos()) as f32,
            (0.4 * v.sin()) as f32,
            (r * u.sin()) as f32,
        )
    };
    let mut tris = Vec::with_capacity(2 * nu * nv);
    for pass in 0..2 {
        for i in 0..nu {
            for j in 0..nv {
                let (a, b, c, d) = (
                    vert(i, j),
                    vert(i + 1, j),
                    vert(i + 1, j + 1),
                    vert(i, j + 1),
                );
                tris.push(Triangle32 {
                    v: if pass == 0 { [a, b, c] } else { [a, c, d] },
                });
            }
        }
    }
    tris
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `mode=1s` writes each ray's answer where `mode=1` writes it, closest hit and
    /// shadow rays (some without one), with the same tests, on a tree whose streams
    /// step their walks and on one whose streams do not.
    #[test]
    fn the_stream_mode_traces_what_the_single_ray_mode_traces() {
        let small = Bvh::build(PrimSet::from_triangles(torus(60, 40)));
        let mut big = small.clone();
        (big.wide.stream_steps, big.wide.stream_any_hit_steps) = (true, true);
        assert!(!small.wide.stream_steps);
        // more than one work item, the last one short
        let rays = incoherent_rays(2 * CHUNK + 300, 3);
        for bvh in [&small, &big] {
            let n = rays.origin.len();
            let (mut t1, mut ts) = (vec![0.0; n], vec![0.0; n]);
            let s1 = trace(bvh, &rays, Mode::Single, &mut t1);
            let ss = trace(bvh, &rays, Mode::Stream, &mut ts);
            assert_eq!(
                t1.iter().map(|t| t.to_bits()).collect::<Vec<_>>(),
                ts.iter().map(|t| t.to_bits()).collect::<Vec<_>>()
            );
            assert_eq!(s1, ss);
            let set = shadow_rays(rays.clone(), t1.clone());
            assert!(set.t_max.contains(&0.0) && set.t_max.iter().any(|&t| t > 0.0));
            let (mut b1, mut bs) = (vec![2u8; n], vec![2u8; n]);
            let s1 = trace_occluded(bvh, &set, Mode::Single, &mut b1);
            let ss = trace_occluded(bvh, &set, Mode::Stream, &mut bs);
            assert_eq!(b1, bs);
            assert_eq!(s1, ss);
            assert!(b1.contains(&1) && b1.contains(&0));
        }
    }

    /// The timed builds take their input: the first the triangles given, the other two
    /// each a fresh read, and the tree returned is the one a single build makes; a
    /// failed read is the benchmark's error.
    #[test]
    fn timed_builds_read_the_mesh_again_and_return_the_tree_of_one_build() {
        let tris = torus(30, 20);
        let mut reads = 0;
        let reload = |reads: &mut usize| {
            *reads += 1;
            Ok::<_, &str>(PrimSet::from_triangles(tris.clone()))
        };
        let built = timed_build(
            PrimSet::from_triangles(tris.clone()),
            || reload(&mut reads),
            false,
        )
        .unwrap();
        assert_eq!(reads, 2);
        let one = Bvh::build(PrimSet::from_triangles(tris.clone()));
        let packed = |b: &Bvh| b.prims.each_triangle().collect::<Vec<_>>();
        assert_eq!(packed(&built.bvh), packed(&one));
        assert_eq!(built.bvh.nodes.len(), one.nodes.len());
        let root_box = |b: &Bvh| b.root.map(|r| r.bounds());
        assert_eq!(root_box(&built.bvh), root_box(&one));
        assert_eq!(built.bvh.prims.blocks.len(), one.prims.blocks.len());
        assert!(built.build_ms >= built.collapse_ms && built.collapse_ms >= 0.0);
        // the binary tree's figures whether it stays or not (its node count may differ
        // by the pad that puts children pairs on cache lines, which depends on where
        // the array lies); kept, it is the tree a build that keeps it keeps
        let with = Bvh::build_with_binary(PrimSet::from_triangles(tris.clone()));
        assert!(!with.nodes.is_empty() && one.nodes.is_empty());
        let same = |a: BinaryStats, b: BinaryStats| {
            a.depth == b.depth && a.sah_cost == b.sah_cost && a.nodes.abs_diff(b.nodes) <= 1
        };
        assert!(same(built.binary, BinaryStats::of(&with.nodes)));
        let kept = timed_build(
            PrimSet::from_triangles(tris.clone()),
            || reload(&mut reads),
            true,
        )
        .unwrap();
        assert!(same(kept.binary, BinaryStats::of(&kept.bvh.nodes)));
        assert!(same(kept.binary, built.binary));
        let failed = timed_build(
            PrimSet::from_triangles(tris),
            || Err::<PrimSet, _>("the mesh is gone"),
            false,
        );
        assert_eq!(failed.err(), Some("the mesh is gone"));
    }

    /// bench-trace takes a mesh's triangles as the renderer does: the zero-area ones
    /// (collinear corners, a repeated corner, all three the same) are dropped, not
    /// traced (10,000 identical degenerate faces took bench-trace 106 s).
    #[test]
    fn degenerate_triangles_are_dropped_as_the_renderer_drops_them() {
        let path = std::env::temp_dir().join(format!("octaray-degen-{}.obj", std::process::id()));
        let mut text = String::from("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\nv 0 0 1\n");
        text += "f 1 2 3\nf 1 2 4\nf 1 1 3\nf 2 2 2\nf 1 3 5\n";
        text += &"f 3 3 3\n".repeat(1000);
        std::fs::write(&path, text).unwrap();
        let tris = load_mesh(&path);
        std::fs::remove_file(&path).unwrap();
        let tris = tris.unwrap();
        assert_eq!(tris.len(), 2, "{tris:?}");
        assert_eq!(tris[0].v[1], Vec3::X);
        assert_eq!(tris[1].v[2], Vec3::Z);
        let mesh = crate::scene::obj::parse_obj("v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n", "d.obj");
        let prims = mesh_prims(mesh.unwrap());
        assert_eq!((prims.each_triangle().count(), prims.dropped), (0, 1));
        // the mesh alone: the scene it goes through has a floor, the benchmark none
        assert!(prims.floor.is_none() && prims.len(crate::geometry::PrimKind::Floor) == 0);
    }

    /// The Embree harness's ray files: count, then origin and direction per ray (the
    /// layout `gen_data.py` writes); a file whose count, size or content disagree is an
    /// error naming it, never a panic or a partial set.
    #[test]
    fn ray_files_are_read_as_the_harness_writes_them_or_refused_by_name() {
        let dir = std::env::temp_dir().join(format!("octaray-rays-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = |name: &str, bytes: &[u8]| {
            let p = dir.join(name);
            std::fs::write(&p, bytes).unwrap();
            p
        };
        let rays: [[f32; 6]; 3] = [
            [0.5, -1.25, 3.0, 0.0, 0.0, 1.0],
            [-0.0, 1e-30, f32::MAX, 0.6, 0.8, 0.0],
            [1.0, 2.0, 3.0, -1.0, 0.0, 0.0],
        ];
        let mut bytes = 3u32.to_le_bytes().to_vec();
        for v in rays.iter().flatten() {
            bytes.extend_from_slice(&v.to_le_bytes());
        }
        let good = file("good.rays", &bytes);
        let set = read_rays(&good, "primary").unwrap();
        assert_eq!(set.name, "primary");
        for (k, r) in rays.iter().enumerate() {
            assert_eq!(set.origin[k].to_array(), [r[0], r[1], r[2]], "ray {k}");
            assert_eq!(set.dir[k].to_array(), [r[3], r[4], r[5]], "ray {k}");
        }
        assert_eq!(set.origin[1].x.to_bits(), (-0.0f32).to_bits());
        let refused = |path: &Path, says: &str| {
            let e = read_rays(path, "incoherent").unwrap_err();
            assert_eq!(e.file, path.display().to_string());
            assert!(e.message.contains(says), "{e}");
            assert!(
                e.to_string().starts_with(&path.display().to_string()),
                "{e}"
            );
        };
        refused(&dir.join("missing.rays"), "cannot open");
        refused(
            &file("short.rays", &[1, 0]),
            "shorter than its 4-byte ray count",
        );
        refused(&file("empty.rays", &0u32.to_le_bytes()), "no rays");
        refused(&file("huge.rays", &u32::MAX.to_le_bytes()), "more than");
        refused(
            &file("cut.rays", &bytes[..bytes.len() - 1]),
            "needs 76 bytes",
        );
        let mut long = bytes.clone();
        long.push(0);
        refused(&file("long.rays", &long), "the file has 77");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
