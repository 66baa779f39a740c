//! The caustic of dispersive objects: light carried forward from the lights through the
//! glass onto the surfaces it lands on (a caustic photon map).
//!
//! A Whitted tracer follows rays from the eye, so it cannot find the light that a prism
//! bends onto the floor: a shadow ray from the floor towards the light meets the prism
//! and stops. This pass runs before the frame:
//!
//! 1. **Emission, only towards glass.** For every (light, dispersive object) pair,
//!    photons leave the light inside the cone that subtends the object's bounding sphere,
//!    intersected with the spotlight's cone (hard edge, as in direct light): directions
//!    are drawn uniformly in the narrower of the two cones and those outside the other are
//!    dropped. The cost scales with the prism, never with the rest of the scene.
//! 2. **Transport.** Each photon carries one wavelength (stratified over 380–720 nm) and
//!    an RGB power `Lc ⊙ w(λ)` ([`spectral_weight`]). At glass it reflects with probability
//!    (kr + kt·F) / (kr + kt) or refracts with Snell's law at n(λ) (F = exact Fresnel; total
//!    internal reflection always reflects), and its power is multiplied by kr + kt. Photons
//!    that meet a non-glass surface before any glass are dropped (direct light already
//!    covers them); after glass they are stored on the first surface with kd > 0 and stop
//!    (mirror bounces carry no light in the spec's model, here as for direct light).
//!    At most [`MAX_PHOTON_BOUNCES`] glass interactions.
//! 3. **Units.** The spec's lights have no distance falloff: a light of colour Lc gives
//!    irradiance Lc·(N·L) at any distance. A photon's power is therefore scaled by the
//!    square of its equivalent distance D (air path + glass path / n, the paraxial
//!    spreading distance), so that light through flat glass lands with exactly the
//!    spec's direct irradiance times the Fresnel transmission: `Φ = Lc ⊙ w(λ) · Ω / N · D²`.
//! 4. **Density estimate.** At shading time, [`CausticMap::irradiance`] sums the photons
//!    within `radius` of the point with the Epanechnikov kernel `2/(πr²)·(1 − d²/r²)`,
//!    counting only photons that arrive on the side the shading normal faces and lie on a
//!    surface of the same orientation; where fewer than [`MIN_PHOTONS`] fall inside, the
//!    estimate is taken at 4× the radius (a second grid over the same photons). The shading adds `kd · c ⊙ E`, like the Phong diffuse
//!    term.
//!
//! Deterministic: every random number is a hash of (seed, photon, bounce); photons are
//! traced in fixed blocks, so the map does not depend on the thread count.
//!
//! The tracer is abstract ([`PhotonTracer`]): the reference passes its brute-force f64
//! intersection, a fast path can pass its BVH.

use std::time::{Duration, Instant};

use glam::DVec3;
use rayon::prelude::*;

use super::spectral::{
    LAMBDA_MAX_NM, LAMBDA_MIN_NM, glass_interface, hash_keys, nm_to_um, spectral_weight,
    unit_from_hash,
};
use crate::math::Ray;
use crate::math::float::offset_ray_origin;
use crate::scene::{Floor, Glass, Scene, Shape};

/// Most glass interactions a photon may have before it is dropped.
pub const MAX_PHOTON_BOUNCES: u32 = 32;

/// Knobs of the caustic pass.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CausticSettings {
    /// Photons emitted (directions sampled) per frame, shared by the (light, dispersive
    /// object) pairs in proportion to the power each can send. 0 turns the caustic off.
    pub photons: u32,
    /// Density-estimation radius in scene units; `None`: [`AUTO_RADIUS_FRACTION`] of the
    /// largest dispersive object's bounding radius.
    pub radius: Option<f64>,
    /// Seed of every random number of the pass.
    pub seed: u64,
}

/// Fewest photons a density estimate uses before its radius is widened.
pub const MIN_PHOTONS: usize = 8;

/// The widened density-estimation radius, in multiples of the base radius.
pub const WIDENING: f64 = 4.0;

/// Default radius as a fraction of the dispersive object's bounding radius.
pub const AUTO_RADIUS_FRACTION: f64 = 0.03;

impl Default for CausticSettings {
    fn default() -> Self {
        CausticSettings {
            photons: 100_000,
            radius: None,
            seed: 0,
        }
    }
}

/// A hit as the photon tracer needs it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PhotonHit {
    pub t: f64,
    pub point: DVec3,
    /// Unit geometric normal, NOT flipped towards the ray (outward for prisms).
    pub normal: DVec3,
    /// Error bound of `point` (for [`offset_ray_origin`]).
    pub err: DVec3,
    /// Index of the object hit in the scene; `None` for the floor.
    pub object: Option<usize>,
}

/// Nearest-hit queries for the photon pass; `Sync` so photons trace in parallel.
pub trait PhotonTracer: Sync {
    /// The nearest hit along `ray` with t > 0, the floor included.
    fn nearest(&self, ray: &Ray) -> Option<PhotonHit>;
}

/// A stored photon: where it landed, which way it travelled, its RGB power.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Photon {
    pub position: DVec3,
    /// Unit direction of travel when it landed.
    pub direction: DVec3,
    /// Unit geometric normal of the surface it landed on (unflipped).
    pub normal: DVec3,
    /// RGB power (already weighted by its wavelength's colour).
    pub power: DVec3,
    /// Wavelength, nanometres.
    pub lambda_nm: f64,
}

/// Counters of the pass.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CausticStats {
    /// Directions sampled (inside the narrower cone).
    pub emitted: u64,
    /// Photons stored on surfaces.
    pub stored: u64,
    /// Photon rays traced (every segment).
    pub rays: u64,
    pub elapsed: Duration,
}

/// The photons of a frame in a dense grid over their bounding box, for fixed-radius
/// queries: cells of radius / [`CELLS_PER_RADIUS`] (coarser if that would exceed
/// [`MAX_CELLS`]), photons sorted by cell in x-fastest order, so the cells of one grid
/// row that a query disc overlaps are one contiguous run of photons. A query reads, row
/// by row, only the cells its sphere's chord crosses: about 2.5r × 2.5r of photons for
/// a caustic on a plane, where a grid of 2r cells reads 4r × 4r.
#[derive(Clone, Debug)]
pub struct CausticMap {
    photons: Vec<Photon>,
    /// The same photons, in the same order, as the density estimate reads them.
    soa: GatherSoa,
    grid: DenseGrid,
    radius: f64,
    /// The same photons at [`WIDENING`] times the radius, for sparse regions.
    wide: Option<Box<CausticMap>>,
    pub stats: CausticStats,
}

/// Grid cells per estimate radius (per axis).
pub const CELLS_PER_RADIUS: f64 = 2.0;

/// Most cells of a grid (4 M: 16 MB of `u32` run starts); a wider photon spread gets
/// coarser cells.
pub const MAX_CELLS: usize = 1 << 22;

/// Dense cell index over a box: cell (x, y, z) holds photons `start[i]..start[i + 1]`,
/// i = x + nx·(y + ny·z).
#[derive(Clone, Debug, Default)]
struct DenseGrid {
    /// Corner of cell (0, 0, 0).
    origin: DVec3,
    cell: f64,
    dims: [usize; 3],
    start: Vec<u32>,
}

impl DenseGrid {
    /// Sorts `photons` into a grid of cells of `cell` (or coarser) over their box.
    fn build(photons: &mut Vec<Photon>, cell: f64) -> DenseGrid {
        let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
        for p in photons.iter() {
            lo = lo.min(p.position);
            hi = hi.max(p.position);
        }
        if photons.is_empty() || !lo.is_finite() || !hi.is_finite() {
            return DenseGrid::default();
        }
        let mut cell = cell;
        let dims = loop {
            let d = ((hi - lo) / cell).floor() + 1.0;
            if d.x * d.y * d.z <= MAX_CELLS as f64 {
                break [d.x as usize, d.y as usize, d.z as usize];
            }
            cell *= 2.0;
        };
        let index = |p: DVec3| {
            let c = ((p - lo) / cell).floor();
            let at = |v: f64, n: usize| (v.max(0.0) as usize).min(n - 1);
            at(c.x, dims[0]) + dims[0] * (at(c.y, dims[1]) + dims[1] * at(c.z, dims[2]))
        };
        let mut keyed: Vec<(usize, Photon)> =
            photons.drain(..).map(|p| (index(p.position), p)).collect();
        // stable: photons keep their traced order within a cell (deterministic maps)
        keyed.sort_by_key(|(c, _)| *c);
        let n = dims[0] * dims[1] * dims[2];
        let mut start = vec![0u32; n + 1];
        for (c, _) in &keyed {
            start[c + 1] += 1;
        }
        for i in 0..n {
            start[i + 1] += start[i];
        }
        photons.extend(keyed.into_iter().map(|(_, p)| p));
        DenseGrid {
            origin: lo,
            cell,
            dims,
            start,
        }
    }

    /// Calls `f(a, b)` for each run of photons in the grid rows that the sphere of
    /// radius `r` around `p` crosses, clipped to the sphere's chord in each row.
    #[inline]
    fn runs(&self, p: DVec3, r: f64, f: &mut dyn FnMut(usize, usize)) {
        if self.start.is_empty() {
            return;
        }
        let q = (p - self.origin) / self.cell;
        let rc = r / self.cell;
        let [nx, ny, nz] = self.dims;
        let range = |c: f64, n: usize| -> Option<(usize, usize)> {
            let (lo, hi) = ((c - rc).floor(), (c + rc).floor());
            if hi < 0.0 || lo >= n as f64 || lo.is_nan() || hi.is_nan() {
                return None;
            }
            Some((lo.max(0.0) as usize, (hi as usize).min(n - 1)))
        };
        let (Some((y0, y1)), Some((z0, z1))) = (range(q.y, ny), range(q.z, nz)) else {
            return;
        };
        // distance (in cells) from q to the slab [k, k + 1)
        let gap = |c: f64, k: usize| (k as f64 - c).max(c - (k + 1) as f64).max(0.0);
        let rc2 = rc * rc;
        // the x cells of the whole sphere: a row empty there is skipped without a sqrt
        let Some((xa, xb)) = range(q.x, nx) else {
            return;
        };
        for z in z0..=z1 {
            let dz = gap(q.z, z);
            for y in y0..=y1 {
                let row = nx * (y + ny * z);
                if self.start[row + xa] == self.start[row + xb + 1] {
                    continue;
                }
                let dy = gap(q.y, y);
                let left = rc2 - dy * dy - dz * dz;
                if left < 0.0 {
                    continue;
                }
                // clipped to the sphere's chord in this row
                let chord = left.sqrt();
                let (lo, hi) = ((q.x - chord).floor(), (q.x + chord).floor());
                if hi < 0.0 || lo >= nx as f64 {
                    continue;
                }
                let (x0, x1) = (lo.max(0.0) as usize, (hi as usize).min(nx - 1));
                let (a, b) = (
                    self.start[row + x0] as usize,
                    self.start[row + x1 + 1] as usize,
                );
                if a < b {
                    f(a, b);
                }
            }
        }
    }
}

/// What a density estimate reads of each photon, as f32 columns (positions relative to
/// `origin`, so a map far from the world origin keeps its precision), padded to a
/// multiple of 8 so a cell's range is read eight photons at a time. f32 is ample for a
/// kernel weight: the positions are exact to 2⁻²⁴ of the map's extent, and each
/// estimate sums at most a few thousand terms.
#[derive(Clone, Debug, Default)]
struct GatherSoa {
    origin: DVec3,
    /// position x, y, z; direction x, y, z; normal x, y, z; power r, g, b
    cols: [Vec<f32>; 12],
}

impl GatherSoa {
    fn new(photons: &[Photon], origin: DVec3) -> GatherSoa {
        let n = photons.len().div_ceil(8) * 8 + 8;
        let mut cols: [Vec<f32>; 12] = std::array::from_fn(|_| Vec::with_capacity(n));
        for p in photons {
            let rel = p.position - origin;
            let vals = [
                rel.x,
                rel.y,
                rel.z,
                p.direction.x,
                p.direction.y,
                p.direction.z,
                p.normal.x,
                p.normal.y,
                p.normal.z,
                p.power.x,
                p.power.y,
                p.power.z,
            ];
            for (k, (c, v)) in cols.iter_mut().zip(vals).enumerate() {
                // a power beyond f32's range saturates: infinity times the zero weight
                // of a photon outside the radius would make the whole estimate NaN
                c.push(if k >= 9 {
                    (v as f32).min(f32::MAX)
                } else {
                    v as f32
                });
            }
        }
        // padding never counts: infinitely far away
        for (k, c) in cols.iter_mut().enumerate() {
            c.resize(n, if k < 3 { f32::INFINITY } else { 0.0 });
        }
        GatherSoa { origin, cols }
    }

    /// Epanechnikov-weighted power and number of the photons of `runs` within `r` of
    /// `p` that arrive on the side `n` faces, on a surface of the same orientation.
    #[inline]
    fn sum(
        &self,
        runs: impl FnOnce(&mut dyn FnMut(usize, usize)),
        p: DVec3,
        n: DVec3,
        r: f64,
    ) -> (DVec3, usize) {
        use crate::math::packet::{Cmp8, Mask8};
        use wide::f32x8;
        let q = p - self.origin;
        let s = |v: f64| f32x8::splat(v as f32);
        let (qx, qy, qz, nx, ny, nz) = (s(q.x), s(q.y), s(q.z), s(n.x), s(n.y), s(n.z));
        let r2 = s(r * r);
        let inv_r2 = s(1.0 / (r * r));
        let (zero, one, cos) = (f32x8::ZERO, f32x8::ONE, f32x8::splat(0.9));
        let col = |k: usize, i: usize| {
            let c: &[f32; 8] = self.cols[k][i..i + 8].try_into().expect("padded to 8");
            f32x8::new(*c)
        };
        let (mut sr, mut sg, mut sb) = (zero, zero, zero);
        let mut count = 0;
        runs(&mut |a, b| {
            let mut i = a;
            while i < b {
                let (dx, dy, dz) = (col(0, i) - qx, col(1, i) - qy, col(2, i) - qz);
                let d2 = dx * dx + dy * dy + dz * dz;
                let facing = (col(3, i) * nx + col(4, i) * ny + col(5, i) * nz).lt(zero);
                let aligned = (col(6, i) * nx + col(7, i) * ny + col(8, i) * nz)
                    .abs()
                    .gt(cos);
                // lanes past b belong to the next cell: masked off
                let tail = if b - i < 8 {
                    Mask8::from_bits((1u32 << (b - i)) - 1)
                } else {
                    Mask8::ALL
                };
                let m = d2.lt(r2) & facing & aligned & tail;
                if m.any() {
                    count += m.count() as usize;
                    let w = m.select(one - d2 * inv_r2, zero);
                    sr += col(9, i) * w;
                    sg += col(10, i) * w;
                    sb += col(11, i) * w;
                }
                i += 8;
            }
        });
        if count == 0 {
            return (DVec3::ZERO, 0);
        }
        let h = |v: f32x8| v.to_array().iter().map(|&x| x as f64).sum::<f64>();
        (DVec3::new(h(sr), h(sg), h(sb)), count)
    }
}

/// The glass parameters of a shape, if it is dispersive.
pub fn glass_of(shape: &Shape) -> Option<Glass> {
    match shape {
        Shape::Prism { glass, .. } => Some(*glass),
        _ => None,
    }
}

/// A bounding sphere (centre, radius) of a dispersive shape.
pub fn bounding_sphere(shape: &Shape) -> Option<(DVec3, f64)> {
    match shape {
        Shape::Prism { v, .. } => Some(crate::geometry::prism::bounding_sphere(v)),
        _ => None,
    }
}

/// A cone of directions: unit axis and the cosine of its half-angle.
#[derive(Clone, Copy, Debug)]
struct Cone {
    axis: DVec3,
    cos_max: f64,
}

impl Cone {
    fn contains(&self, w: DVec3) -> bool {
        self.axis.dot(w) >= self.cos_max
    }
    fn solid_angle(&self) -> f64 {
        2.0 * std::f64::consts::PI * (1.0 - self.cos_max)
    }
    /// Uniform direction in the cone from two numbers in [0, 1).
    fn sample(&self, u1: f64, u2: f64) -> DVec3 {
        let cos_t = 1.0 - u1 * (1.0 - self.cos_max);
        let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
        let phi = 2.0 * std::f64::consts::PI * u2;
        let (t, b) = self.axis.any_orthonormal_pair();
        (t * (sin_t * phi.cos()) + b * (sin_t * phi.sin()) + self.axis * cos_t).normalize()
    }
}

/// One (light, glass object) pair that can exchange light.
#[derive(Clone, Copy, Debug)]
struct Emitter {
    position: DVec3,
    color: DVec3,
    /// Directions are drawn here ...
    sample: Cone,
    /// ... and kept if they also lie here (the other cone), and in the spot cone.
    keep: Option<Cone>,
    /// Spot cone as the direct light tests it (angle <= cutoff), if a spotlight.
    spot: Option<(DVec3, f64)>,
}

impl Emitter {
    /// The power the pair can send, in units of `unit` (see [`power_unit`]): the light's
    /// largest channel times the solid angle sampled.
    fn power(&self, unit: f64) -> f64 {
        self.color.max_element() / unit * self.sample.solid_angle()
    }
}

/// Every (light, glass object) pair that can exchange light, in a fixed order (lights
/// as listed, point lights first; objects as listed), without holding them: a scene
/// may have as many pairs as lights times glass objects.
fn for_each_emitter(scene: &Scene, mut f: impl FnMut(Emitter)) {
    let lights = scene
        .point_lights
        .iter()
        .map(|l| (l.position, l.color, None))
        .chain(
            scene
                .spot_lights
                .iter()
                .map(|s| (s.position, s.color, Some((s.direction, s.cutoff_deg)))),
        );
    for (position, color, spot) in lights {
        if color.max_element() <= 0.0 {
            continue;
        }
        for o in &scene.objects {
            let Some((c, r)) = bounding_sphere(&o.shape) else {
                continue;
            };
            let to = c - position;
            let d = to.length();
            let sphere = if d > r * (1.0 + 1e-9) {
                Cone {
                    axis: to / d,
                    cos_max: (1.0 - (r / d) * (r / d)).max(0.0).sqrt(),
                }
            } else {
                // the light is inside the bounding sphere: every direction
                Cone {
                    axis: DVec3::Z,
                    cos_max: -1.0,
                }
            };
            let (sample, keep) = match spot {
                None => (sphere, None),
                Some((dir, cutoff)) => {
                    let spot_cone = Cone {
                        axis: dir.normalize(),
                        cos_max: cutoff.to_radians().cos(),
                    };
                    // disjoint cones exchange no light
                    let gap = spot_cone.axis.dot(sphere.axis).clamp(-1.0, 1.0).acos();
                    let half = |c: &Cone| c.cos_max.clamp(-1.0, 1.0).acos();
                    if gap > half(&spot_cone) + half(&sphere) + 1e-9 {
                        continue;
                    }
                    if spot_cone.solid_angle() < sphere.solid_angle() {
                        (spot_cone, Some(sphere))
                    } else {
                        (sphere, Some(spot_cone))
                    }
                }
            };
            f(Emitter {
                position,
                color,
                sample,
                keep,
                spot,
            });
        }
    }
}

/// Most photons a caustic pass emits, whatever [`CausticSettings::photons`] asks (the
/// profiles' limit): about 1.5 GB of photon map.
pub const MAX_PHOTONS: u32 = 10_000_000;

/// The (light, glass object) pairs of `scene` that can exchange light, and their
/// total power in units of [`power_unit`].
fn pairs(scene: &Scene) -> (u64, f64) {
    let unit = power_unit(scene);
    let (mut n, mut total) = (0u64, 0.0);
    for_each_emitter(scene, |e| {
        n += 1;
        total += e.power(unit);
    });
    (n, total)
}

/// The largest power of two at most the brightest light's largest channel (1 where
/// there is none): powers are computed in this unit so that a light of any finite
/// colour cannot overflow them. Dividing by a power of two is exact, so every
/// photon count is the one computed without the unit wherever that did not overflow.
fn power_unit(scene: &Scene) -> f64 {
    let brightest = scene
        .point_lights
        .iter()
        .map(|l| l.color.max_element())
        .chain(scene.spot_lights.iter().map(|l| l.color.max_element()))
        .fold(0.0, f64::max);
    // (the exponent bits alone: the power of two at or below a normal number)
    let unit = f64::from_bits(brightest.to_bits() & 0x7FF0_0000_0000_0000);
    if unit.is_normal() { unit } else { 1.0 }
}

/// Where a scene has more (light, glass object) pairs than `photons`, the pass gives
/// no photon to a pair whose share rounds to zero (below it, every pair has at least
/// one): the warning that says so, with the counts.
pub fn pairs_warning(scene: &Scene, photons: u32) -> Option<String> {
    let photons = photons.min(MAX_PHOTONS);
    if photons == 0 || !scene.has_prisms() {
        return None;
    }
    let (n, _) = pairs(scene);
    (n > u64::from(photons)).then(|| {
        format!(
            "octaray: warning: {n} light-glass pairs share {photons} caustic photons: \
             pairs whose share is below half a photon send no caustic light"
        )
    })
}

/// Point `k` of the additive-recurrence (R2) low-discrepancy sequence of 2D (Roberts
/// 2018), rotated by `shift`: photon directions.
fn r2(k: u64, shift: [f64; 2]) -> [f64; 2] {
    // 1/ρ, 1/ρ² with ρ the plastic number, the real root of x³ = x + 1
    const A: [f64; 2] = [0.754_877_666_246_692_7, 0.569_840_290_998_053_2];
    std::array::from_fn(|i| (shift[i] + (k as f64 * A[i]).fract()).fract())
}

impl CausticMap {
    /// Traces the photons of `scene` through `tracer`. `None` when the scene has no
    /// dispersive object, no light reaches one, or `settings.photons` is 0.
    pub fn build(
        scene: &Scene,
        settings: &CausticSettings,
        tracer: &dyn PhotonTracer,
    ) -> Option<CausticMap> {
        let start = Instant::now();
        let photons = settings.photons.min(MAX_PHOTONS);
        if photons == 0 {
            return None;
        }
        let (n_pairs, total) = pairs(scene);
        if n_pairs == 0 {
            return None;
        }
        let radius = settings.radius.unwrap_or_else(|| {
            let r = scene
                .objects
                .iter()
                .filter_map(|o| bounding_sphere(&o.shape))
                .map(|(_, r)| r)
                .fold(0.0, f64::max);
            AUTO_RADIUS_FRACTION * r
        });
        if radius.is_nan() || radius <= 0.0 || radius.is_infinite() {
            return None;
        }
        // photons in proportion to the power each pair can send (max channel × solid
        // angle sampled), so every photon carries about the same power: each pair its
        // share rounded (at most `photons`, the share being at most 1), and at least
        // one while there are no more pairs than photons (at most doubling the work);
        // so at most 2 · photons pairs emit, whatever the number of pairs
        let unit = power_unit(scene);
        let floor = u64::from(n_pairs <= u64::from(photons));
        let mut emitters: Vec<(u64, Emitter)> = Vec::new();
        let mut counts: Vec<u64> = Vec::new();
        let mut pair = 0;
        for_each_emitter(scene, |e| {
            let n = ((photons as f64 * e.power(unit) / total).round() as u64).max(floor);
            if n > 0 {
                emitters.push((pair, e));
                counts.push(n);
            }
            pair += 1;
        });
        const BLOCK: u64 = 4096;
        let mut jobs = Vec::new();
        for (e, &n) in counts.iter().enumerate() {
            let mut k = 0;
            while k < n {
                jobs.push((e, k, (k + BLOCK).min(n)));
                k += BLOCK;
            }
        }
        let job = |&(i, k0, k1): &(usize, u64, u64)| {
            let mut out = Vec::new();
            let mut rays = 0;
            // (random numbers are keyed by the pair's index among all pairs)
            let (e, em) = (emitters[i].0, &emitters[i].1);
            let per_emitter = counts[i];
            let shift = {
                let h = |i: u64| unit_from_hash(hash_keys(&[settings.seed, e, i]));
                [h(1), h(2)]
            };
            for k in k0..k1 {
                let [u1, u2] = r2(k, shift);
                let dir = em.sample.sample(u1, u2);
                if em.keep.is_some_and(|c| !c.contains(dir)) {
                    continue;
                }
                if let Some((axis, cutoff)) = em.spot {
                    let angle = axis.cross(dir).length().atan2(axis.dot(dir));
                    if angle.to_degrees() > cutoff {
                        continue;
                    }
                }
                // the wavelength is independent of the direction (a hash, not a
                // second low-discrepancy axis that could correlate with it)
                let key = hash_keys(&[settings.seed, e, k, 0xC0FF_EE00]);
                let lambda = LAMBDA_MIN_NM + unit_from_hash(key) * (LAMBDA_MAX_NM - LAMBDA_MIN_NM);
                let power = em.color * spectral_weight(lambda) * em.sample.solid_angle()
                    / per_emitter as f64;
                if let Some(p) = trace_photon(
                    scene,
                    tracer,
                    em.position,
                    dir,
                    lambda,
                    power,
                    key,
                    &mut rays,
                ) {
                    out.push(p);
                }
            }
            (out, rays)
        };
        let results: Vec<(Vec<Photon>, u64)> = if crate::parallel::parallel() {
            jobs.par_iter().map(job).collect()
        } else {
            jobs.iter().map(job).collect()
        };
        let rays = results.iter().map(|r| r.1).sum();
        let photons: Vec<Photon> = results.into_iter().flat_map(|r| r.0).collect();
        let mut map = CausticMap::from_photons(photons, radius);
        map.stats = CausticStats {
            emitted: counts.iter().sum(),
            stored: map.photons.len() as u64,
            rays,
            elapsed: start.elapsed(),
        };
        Some(map)
    }

    /// A map over given photons (sorted into the grid here), with its widened twin.
    pub fn from_photons(photons: Vec<Photon>, radius: f64) -> CausticMap {
        let mut wide = CausticMap::grid(photons.clone(), radius * WIDENING);
        // the wide twin is read through its columns only
        wide.photons = Vec::new();
        let mut map = CausticMap::grid(photons, radius);
        map.wide = Some(Box::new(wide));
        map
    }

    /// The photons in a grid for queries of `radius`.
    fn grid(mut photons: Vec<Photon>, radius: f64) -> CausticMap {
        let grid = DenseGrid::build(&mut photons, radius / CELLS_PER_RADIUS);
        CausticMap {
            soa: GatherSoa::new(&photons, grid.origin),
            photons,
            grid,
            radius,
            wide: None,
            stats: CausticStats::default(),
        }
    }

    pub fn photons(&self) -> &[Photon] {
        &self.photons
    }

    pub fn radius(&self) -> f64 {
        self.radius
    }

    /// Irradiance (RGB, in the units of the spec's `Lc·(N·L)`) at `p` on a surface
    /// with unit normal `n` facing the viewer. The caller adds `kd · c ⊙ E`.
    ///
    /// Where fewer than [`MIN_PHOTONS`] photons fall within the radius (the faint, sparse
    /// fringe of a caustic), the estimate is taken at [`WIDENING`] times the radius
    /// instead: a sparse region then shows a smooth glow, not single-photon speckles.
    pub fn irradiance(&self, p: DVec3, n: DVec3) -> DVec3 {
        let norm = |r: f64| 2.0 / (std::f64::consts::PI * r * r);
        // most points see no photon at all, even within the wide radius (2.8 M of the
        // 3.0 M estimates of prism_povray at 768²): one scan of the wide grid's rows
        // settles them
        if let Some(w) = &self.wide {
            let mut any = false;
            w.grid.runs(p, w.radius, &mut |_, _| any = true);
            if !any {
                return DVec3::ZERO;
            }
        }
        // the narrow estimate first: where it has enough photons (the bright spectrum)
        // the wide one, sixteen times the photons, is never gathered
        let (sum, count) = self.gather(p, n, self.radius);
        if count >= MIN_PHOTONS {
            return sum * norm(self.radius);
        }
        match &self.wide {
            Some(w) => w.gather(p, n, w.radius).0 * norm(w.radius),
            None => sum * norm(self.radius),
        }
    }

    /// Epanechnikov-weighted power of the photons within `r` of `p` that arrive on the
    /// side `n` faces, on a surface of the same orientation, and their number.
    fn gather(&self, p: DVec3, n: DVec3, r: f64) -> (DVec3, usize) {
        self.soa.sum(|f| self.grid.runs(p, r, f), p, n, r)
    }
}

/// Follows one photon from the light; returns it where it lands after glass.
#[allow(clippy::too_many_arguments)]
fn trace_photon(
    scene: &Scene,
    tracer: &dyn PhotonTracer,
    origin: DVec3,
    dir: DVec3,
    lambda_nm: f64,
    mut power: DVec3,
    key: u64,
    rays: &mut u64,
) -> Option<Photon> {
    let mut ray = Ray::new(origin, dir);
    let mut distance = 0.0; // equivalent (paraxial) distance: air + glass / n
    let mut inside: Option<f64> = None; // index of the glass the photon is in
    let mut glass_hits = 0;
    loop {
        *rays += 1;
        let hit = tracer.nearest(&ray)?;
        distance += hit.t / inside.unwrap_or(1.0);
        let object = hit.object.map(|i| &scene.objects[i]);
        match object.and_then(|o| glass_of(&o.shape).map(|g| (o, g))) {
            Some((o, g)) => {
                glass_hits += 1;
                if glass_hits > MAX_PHOTON_BOUNCES {
                    return None;
                }
                let n = g.index(nm_to_um(lambda_nm));
                let i = glass_interface(ray.dir, hit.normal, n);
                let s = o.material.kr + g.kt;
                if s <= 0.0 {
                    return None;
                }
                let p_reflect = (o.material.kr + g.kt * i.fresnel) / s;
                let u = unit_from_hash(hash_keys(&[key, 1 + glass_hits as u64]));
                power *= s;
                let (new_dir, now_inside) = match i.transmitted {
                    Some(t) if u >= p_reflect => (t, if i.entering { Some(n) } else { None }),
                    _ => (i.reflected, inside),
                };
                inside = now_inside;
                let o = offset_ray_origin(hit.point, hit.err, hit.normal, new_dir);
                ray = Ray::new(o, new_dir);
            }
            None => {
                if glass_hits == 0 {
                    return None; // direct light: the Whitted pass has it
                }
                let kd = object.map_or(Floor::MATERIAL.kd, |o| o.material.kd);
                if kd <= 0.0 {
                    return None;
                }
                return Some(Photon {
                    position: hit.point,
                    direction: ray.dir,
                    normal: hit.normal,
                    power: power * (distance * distance),
                    lambda_nm,
                });
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cone_samples_stay_inside_and_cover_the_solid_angle() {
        let c = Cone {
            axis: DVec3::new(1.0, 2.0, -2.0).normalize(),
            cos_max: 0.9,
        };
        let mut mean = DVec3::ZERO;
        for k in 0..10_000 {
            let [u1, u2] = r2(k, [0.1, 0.2]);
            let w = c.sample(u1, u2);
            assert!((w.length() - 1.0).abs() < 1e-12);
            assert!(c.contains(w) || c.axis.dot(w) > 0.9 - 1e-12);
            mean += w;
        }
        // uniform on the cap: the mean direction is the axis, of length (1 + cos)/2
        let m = mean / 10_000.0;
        assert!((m.normalize() - c.axis).length() < 1e-3, "{m} {}", c.axis);
        assert!((m.length() - 0.95).abs() < 1e-3);
    }

    #[test]
    fn grid_query_matches_brute_force() {
        let mut photons = Vec::new();
        for k in 0..2000u64 {
            let [a, b] = r2(k, [0.0; 2]);
            let c = (k % 7) as f64;
            photons.push(Photon {
                position: DVec3::new(a * 10.0, b * 10.0, 0.0),
                direction: -DVec3::Z,
                normal: DVec3::Z,
                power: DVec3::new(c, 1.0, 2.0),
                lambda_nm: 500.0,
            });
        }
        let map = CausticMap::from_photons(photons.clone(), 0.7);
        for q in [
            DVec3::new(3.0, 4.0, 0.0),
            DVec3::new(0.1, 9.9, 0.0),
            DVec3::new(-5.0, 0.0, 0.0),
        ] {
            let r2 = 0.49;
            let brute: DVec3 = photons
                .iter()
                .filter(|p| p.position.distance_squared(q) < r2)
                .map(|p| p.power * (1.0 - p.position.distance_squared(q) / r2))
                .sum::<DVec3>()
                * (2.0 / (std::f64::consts::PI * r2));
            let got = map.gather(q, DVec3::Z, 0.7).0 * (2.0 / (std::f64::consts::PI * r2));
            // f32 columns: each weight to ~1e-7 relative, the sum to ~1e-6
            assert!(
                (got - brute).length() < 1e-5 * (1.0 + brute.length()),
                "{got} {brute}"
            );
            // from below, the same photons do not count
            assert_eq!(map.gather(q, -DVec3::Z, 0.7).0, DVec3::ZERO);
        }
    }
}
