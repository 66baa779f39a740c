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

use std::collections::HashMap;
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

/// A cheap hasher for grid cells (the keys are small integers; no adversary).
#[derive(Default)]
struct CellHasher(u64);

impl std::hash::Hasher for CellHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for chunk in bytes.chunks(8) {
            let mut b = [0u8; 8];
            b[..chunk.len()].copy_from_slice(chunk);
            self.write_u64(u64::from_le_bytes(b));
        }
    }
    fn write_u64(&mut self, v: u64) {
        self.0 = (self.0.rotate_left(5) ^ v).wrapping_mul(0x517C_C1B7_2722_0A95);
    }
    fn write_i64(&mut self, v: i64) {
        self.write_u64(v as u64);
    }
}

type CellMap = HashMap<[i64; 3], (u32, u32), std::hash::BuildHasherDefault<CellHasher>>;

/// The photons of a frame in a uniform hash grid (cell = 2 × radius: a query touches
/// at most 2 × 2 × 2 cells), for fixed-radius queries.
#[derive(Clone, Debug)]
pub struct CausticMap {
    photons: Vec<Photon>,
    cells: CellMap,
    radius: f64,
    lo: DVec3,
    hi: DVec3,
    /// The same photons at [`WIDENING`] times the radius, for sparse regions.
    wide: Option<Box<CausticMap>>,
    pub stats: CausticStats,
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

fn emitters(scene: &Scene) -> Vec<Emitter> {
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
    let mut out = Vec::new();
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
            out.push(Emitter {
                position,
                color,
                sample,
                keep,
                spot,
            });
        }
    }
    out
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
        let emitters = emitters(scene);
        if emitters.is_empty() || settings.photons == 0 {
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
        // angle sampled), so every photon carries about the same power
        let power: Vec<f64> = emitters
            .iter()
            .map(|e| e.color.max_element() * e.sample.solid_angle())
            .collect();
        let total: f64 = power.iter().sum();
        let counts: Vec<u64> = power
            .iter()
            .map(|p| ((settings.photons as f64 * p / total).round() as u64).max(1))
            .collect();
        const BLOCK: u64 = 4096;
        let mut jobs = Vec::new();
        for (e, &n) in counts.iter().enumerate() {
            let mut k = 0;
            while k < n {
                jobs.push((e, k, (k + BLOCK).min(n)));
                k += BLOCK;
            }
        }
        let results: Vec<(Vec<Photon>, u64)> = jobs
            .par_iter()
            .map(|&(e, k0, k1)| {
                let mut out = Vec::new();
                let mut rays = 0;
                let em = &emitters[e];
                let per_emitter = counts[e];
                let shift = {
                    let h = |i: u64| unit_from_hash(hash_keys(&[settings.seed, e as u64, i]));
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
                    let key = hash_keys(&[settings.seed, e as u64, k, 0xC0FF_EE00]);
                    let lambda =
                        LAMBDA_MIN_NM + unit_from_hash(key) * (LAMBDA_MAX_NM - LAMBDA_MIN_NM);
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
            })
            .collect();
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
        let wide = CausticMap::grid(photons.clone(), radius * WIDENING);
        let mut map = CausticMap::grid(photons, radius);
        map.wide = Some(Box::new(wide));
        map
    }

    /// The photons in a grid of cell 2 × `radius`.
    fn grid(photons: Vec<Photon>, radius: f64) -> CausticMap {
        let size = 2.0 * radius;
        let cell = |p: DVec3| (p / size).floor().as_i64vec3().to_array();
        let mut keyed: Vec<([i64; 3], Photon)> =
            photons.into_iter().map(|p| (cell(p.position), p)).collect();
        keyed.sort_by_key(|(c, _)| *c);
        let mut cells = CellMap::default();
        let mut i = 0;
        while i < keyed.len() {
            let c = keyed[i].0;
            let mut j = i + 1;
            while j < keyed.len() && keyed[j].0 == c {
                j += 1;
            }
            cells.insert(c, (i as u32, j as u32));
            i = j;
        }
        let photons: Vec<Photon> = keyed.into_iter().map(|(_, p)| p).collect();
        let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
        for p in &photons {
            lo = lo.min(p.position);
            hi = hi.max(p.position);
        }
        CausticMap {
            photons,
            cells,
            radius,
            lo: lo - radius,
            hi: hi + radius,
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
        let far = self.radius * WIDENING;
        if p.cmplt(self.lo - far).any() || p.cmpgt(self.hi + far).any() {
            return DVec3::ZERO;
        }
        let norm = |r: f64| 2.0 / (std::f64::consts::PI * r * r);
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
        let r2 = r * r;
        let size = 2.0 * self.radius;
        let lo = ((p - r) / size).floor().as_i64vec3();
        let hi = ((p + r) / size).floor().as_i64vec3();
        let mut sum = DVec3::ZERO;
        let mut count = 0;
        for z in lo.z..=hi.z {
            for y in lo.y..=hi.y {
                for x in lo.x..=hi.x {
                    let Some(&(a, b)) = self.cells.get(&[x, y, z]) else {
                        continue;
                    };
                    for ph in &self.photons[a as usize..b as usize] {
                        let d2 = ph.position.distance_squared(p);
                        if d2 < r2 && ph.direction.dot(n) < 0.0 && ph.normal.dot(n).abs() > 0.9 {
                            sum += ph.power * (1.0 - d2 / r2);
                            count += 1;
                        }
                    }
                }
            }
        }
        (sum, count)
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
            assert!(
                (got - brute).length() < 1e-9 * (1.0 + brute.length()),
                "{got} {brute}"
            );
            // from below, the same photons do not count
            assert_eq!(map.gather(q, -DVec3::Z, 0.7).0, DVec3::ZERO);
        }
    }
}
