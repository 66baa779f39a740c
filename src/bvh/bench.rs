//! The standard trace work of `../shared/peers/PROTOCOL.md`, for `octaray bench-trace`
//! and the criterion benches: a triangle mesh from an OBJ file, 1024² coherent primary
//! rays in 4 × 2 pixel packets and 2²⁰ incoherent rays, closest hit with t in (0, ∞),
//! build best of 3 and trace best of 5, reported in the Embree harness's fields for
//! the packet path (mode=8: the 8-wide tree collapsed from the same BVH, as a frustum
//! for packets whose lanes share their direction signs, lane by lane for the others),
//! the binary packet path (mode=8b), the
//! single-ray path (mode=1, the 8-wide tree) and the binary single-ray path (mode=1b).

use std::path::Path;
use std::time::Instant;

use glam::{DVec3, Vec3};
use rayon::prelude::*;
use wide::f32x8;

use super::wide::WideBvh;
use super::{Bvh, Steps};
use crate::geometry::triangle::Triangle32;
use crate::geometry::triangle::Watertight;
use crate::geometry::{Hit1, PrimSet};
use crate::math::packet::{HitPacket8, Mask8, Ray1, RayPacket8, Vec3x8};
use crate::scene::obj::{ObjError, load_obj};

/// A ray set: origins and unit directions, in packet order (every 8 consecutive rays
/// form one packet).
#[derive(Clone, Debug)]
pub struct RaySet {
    pub name: &'static str,
    pub origin: Vec<Vec3>,
    pub dir: Vec<Vec3>,
}

/// The triangles of an OBJ mesh in f32 (the standard meshes are written with exact
/// float32 values, so nothing is rounded).
pub fn load_mesh(path: &Path) -> Result<Vec<Triangle32>, ObjError> {
    let mesh = load_obj(path)?;
    Ok((0..mesh.triangles.len())
        .map(|k| Triangle32::new(&mesh.triangle(k), DVec3::ZERO))
        .collect())
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

/// How rays are traced.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// `Bvh::intersect_1`, one ray at a time through the 8-wide tree.
    Single,
    /// `Bvh::intersect_1_binary`, one ray at a time through the binary tree (`mode=1b`).
    SingleBinary,
    /// `Bvh::intersect_x8`, 8 consecutive rays as one packet (the 8-wide tree: as a
    /// frustum when the lanes share their direction signs, lane by lane otherwise).
    Packet8,
    /// `Bvh::intersect_x8_binary`, packets through the binary tree only (`mode=8b`).
    Packet8Binary,
}

impl Mode {
    pub fn width(self) -> usize {
        match self {
            Mode::Single | Mode::SingleBinary => 1,
            Mode::Packet8 | Mode::Packet8Binary => 8,
        }
    }

    /// The `mode=` field: the width, `1b` for the binary single-ray path.
    pub fn label(self) -> &'static str {
        match self {
            Mode::Single => "1",
            Mode::SingleBinary => "1b",
            Mode::Packet8 => "8",
            Mode::Packet8Binary => "8b",
        }
    }
}

/// Traces every ray of `rays`, writing the hit distance (−1 for a miss) per ray.
pub fn trace(bvh: &Bvh, rays: &RaySet, mode: Mode, t_out: &mut [f32]) -> Steps {
    const CHUNK: usize = 1024;
    let chunk = |(c, out): (usize, &mut [f32])| {
        let mut steps = Steps::default();
        let base = c * CHUNK;
        match mode {
            Mode::Single => {
                for (i, t) in out.iter_mut().enumerate() {
                    let r = Ray1::new(rays.origin[base + i], rays.dir[base + i]);
                    let mut h = Hit1::new(f32::INFINITY);
                    bvh.intersect_1::<Watertight>(&r, &mut h, &mut steps);
                    *t = if h.is_hit() { h.t } else { -1.0 };
                }
            }
            Mode::SingleBinary => {
                for (i, t) in out.iter_mut().enumerate() {
                    let r = Ray1::new(rays.origin[base + i], rays.dir[base + i]);
                    let mut h = Hit1::new(f32::INFINITY);
                    bvh.intersect_1_binary::<Watertight>(&r, &mut h, &mut steps);
                    *t = if h.is_hit() { h.t } else { -1.0 };
                }
            }
            Mode::Packet8 | Mode::Packet8Binary => {
                for (k, ts) in out.chunks_mut(8).enumerate() {
                    let b = base + k * 8;
                    let n = ts.len();
                    let active = Mask8::from_bits((1u32 << n) - 1);
                    // a whole packet straight from the ray arrays; a short last one
                    // padded (a `copy_from_slice` of run-time length is a memmove
                    // call: 3.4 % of a perf profile of bench-trace primary mode=8)
                    let p = if let (Ok(o), Ok(d)) = (
                        <&[Vec3; 8]>::try_from(&rays.origin[b..b + n]),
                        <&[Vec3; 8]>::try_from(&rays.dir[b..b + n]),
                    ) {
                        RayPacket8::new(Vec3x8::from_lanes(o), Vec3x8::from_lanes(d), active)
                    } else {
                        let mut o = [rays.origin[b]; 8];
                        let mut d = [rays.dir[b]; 8];
                        o[..n].copy_from_slice(&rays.origin[b..b + n]);
                        d[..n].copy_from_slice(&rays.dir[b..b + n]);
                        RayPacket8::new(Vec3x8::from_lanes(&o), Vec3x8::from_lanes(&d), active)
                    };
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
        }
        steps
    };
    let add = |a: Steps, b: Steps| Steps {
        boxes: a.boxes + b.boxes,
        prims: a.prims + b.prims,
        quadrics: a.quadrics + b.quadrics,
    };
    // (on the calling thread where worker threads cannot start)
    if crate::parallel::parallel() {
        t_out
            .par_chunks_mut(CHUNK)
            .enumerate()
            .map(chunk)
            .reduce(Steps::default, add)
    } else {
        t_out
            .chunks_mut(CHUNK)
            .enumerate()
            .map(chunk)
            .fold(Steps::default(), add)
    }
}

/// One line of results, in the Embree harness's fields.
#[derive(Clone, Debug)]
pub struct TraceRun {
    pub mesh: String,
    pub rays: &'static str,
    pub threads: usize,
    pub mode: Mode,
    pub tris: usize,
    pub build_ms: f64,
    pub trace_ms: f64,
    pub mrays_per_s: f64,
    pub hits: f64,
    pub mean_t: f64,
    /// Box and primitive tests per ray in the last trace.
    pub boxes_per_ray: f64,
    pub prims_per_ray: f64,
}

impl std::fmt::Display for TraceRun {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "octaray mesh={} rays={} threads={} mode={} tris={} build_ms={:.1} trace_ms={:.1} Mrays/s={:.2} hits={:.4} mean_t={:.6}",
            self.mesh,
            self.rays,
            self.threads,
            self.mode.label(),
            self.tris,
            self.build_ms,
            self.trace_ms,
            self.mrays_per_s,
            self.hits,
            self.mean_t
        )
    }
}

/// Builds the BVH best of 3 (returns it and the best time in ms).
pub fn timed_build(tris: &[Triangle32]) -> (Bvh, f64) {
    let mut best = f64::INFINITY;
    let mut bvh = None;
    for _ in 0..3 {
        let prims = PrimSet::from_triangles(tris.to_vec());
        let start = Instant::now();
        let b = Bvh::build(prims);
        best = best.min(start.elapsed().as_secs_f64() * 1e3);
        bvh = Some(b);
    }
    (bvh.expect("three builds"), best)
}

/// Traces `rays` best of `reps` and summarises the run.
pub fn timed_trace(bvh: &Bvh, rays: &RaySet, mode: Mode, reps: usize) -> (f64, f64, f64, Steps) {
    let mut t = vec![0.0f32; rays.origin.len()];
    let mut best = f64::INFINITY;
    let mut steps = Steps::default();
    for _ in 0..reps {
        let start = Instant::now();
        steps = trace(bvh, rays, mode, &mut t);
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

/// The whole standard work on one mesh: build, then primary and incoherent rays on
/// the packet and the single-ray path, each line printed to `out` as it is measured.
/// SAH cost, depth and steps per ray go to `log`.
pub fn run(
    mesh: &Path,
    threads: usize,
    reps: usize,
    out: &mut (dyn std::io::Write + Send),
    log: &mut (dyn std::io::Write + Send),
) -> Result<Vec<TraceRun>, ObjError> {
    let tris = load_mesh(mesh)?;
    let name = mesh.file_name().map_or_else(
        || mesh.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    );
    crate::parallel::with_threads(Some(threads), || {
        let (bvh, build_ms) = timed_build(&tris);
        let _ = writeln!(
            log,
            "octaray bvh: {} nodes, depth {}, SAH cost {:.2}, {} triangles dropped as degenerate",
            bvh.nodes.len(),
            bvh.depth(),
            bvh.sah_cost(),
            tris.len() - bvh.prims.triangles.len()
        );
        // the collapse to the 8-wide tree is part of `Bvh::build` (so of build_ms);
        // timed again here on its own, best of 3
        let collapse_ms = (0..3)
            .map(|_| {
                let start = Instant::now();
                let w = WideBvh::collapse(&bvh.nodes, &bvh.prims);
                let ms = start.elapsed().as_secs_f64() * 1e3;
                std::hint::black_box(w);
                ms
            })
            .fold(f64::INFINITY, f64::min);
        let w = &bvh.wide;
        let lanes: u64 = w.blocks.iter().map(|b| b.count as u64).sum();
        let one_leaf = w.blocks.iter().filter(|b| b.one_leaf).count();
        let _ = writeln!(
            log,
            "octaray wide bvh: collapse_ms={collapse_ms:.1}, {} nodes, depth {}, {} triangle blocks ({:.1} of 8 lanes used, {:.0} % of one binary leaf)",
            w.nodes.len(),
            w.depth(),
            w.blocks.len(),
            lanes as f64 / w.blocks.len().max(1) as f64,
            100.0 * one_leaf as f64 / w.blocks.len().max(1) as f64
        );
        let mut runs = Vec::new();
        // OCTARAY_BENCH_ONLY=primary/8 (rays/mode, either part optional): one line only,
        // for profiling
        let only = std::env::var("OCTARAY_BENCH_ONLY").unwrap_or_default();
        let (only_rays, only_mode) = only.split_once('/').unwrap_or((&only, ""));
        for rays in [primary_rays(1024, 1024), incoherent_rays(1 << 20, 7)] {
            if !only_rays.is_empty() && only_rays != rays.name {
                continue;
            }
            for mode in [
                Mode::Packet8,
                Mode::Packet8Binary,
                Mode::Single,
                Mode::SingleBinary,
            ] {
                if !only_mode.is_empty() && only_mode != mode.label() {
                    continue;
                }
                let (trace_ms, hits, mean_t, steps) = timed_trace(&bvh, &rays, mode, reps);
                let n = rays.origin.len() as f64;
                let run = TraceRun {
                    mesh: name.clone(),
                    rays: rays.name,
                    threads,
                    mode,
                    tris: tris.len(),
                    build_ms,
                    trace_ms,
                    mrays_per_s: n / trace_ms / 1e3,
                    hits,
                    mean_t,
                    boxes_per_ray: steps.boxes as f64 / n,
                    prims_per_ray: steps.prims as f64 / n,
                };
                let _ = writeln!(out, "{run}");
                let _ = writeln!(
                    log,
                    "  ({} mode={}: {:.1} {} and {:.1} triangle tests per ray)",
                    run.rays,
                    mode.label(),
                    run.boxes_per_ray,
                    match mode {
                        Mode::Single => "wide node tests (8 boxes each)",
                        Mode::Packet8 =>
                            "node tests (8-wide: per packet when the signs agree, per lane when not)",
                        _ => "box tests",
                    },
                    run.prims_per_ray
                );
                runs.push(run);
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
