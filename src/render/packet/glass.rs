//! Glass (dispersive prisms) on the packet path: the same transport as the reference
//! (`render::reference`, module doc), computed on packets.
//!
//! At a glass hit at level L the lane's colour is
//! `clamp(phong + (kr + kt·F)·C_reflected + kt·(1 − F)·C_transmitted, 0, 1)` with both
//! rays traced at level L + 1. An RGB lane (one that has met no glass yet) splits its
//! transmitted light into its pixel's 16 wavelengths ([`Wavelengths::for_pixel`], the
//! same as the reference's): the 16 refracted rays leave one point in nearly one
//! direction, so they are traced as two coherent packets of 8 monochromatic lanes.
//! Its reflected ray (one direction for every wavelength, weighted by the mean of
//! kr + kt·F) stays RGB and is traced with the other RGB glass lanes of the packet, in
//! their own lanes. A monochromatic lane splits into one reflected and one transmitted
//! ray (Fresnel at its own n(λ)), batched with the other lanes' into packets of 8.
//!
//! Pruning as the reference: a branch whose colour could add at most
//! [`GLASS_CUTOFF`] to the pixel is not traced. Unlike the reference, which follows the
//! heavier branch of each split in a loop, every branch here nests one level of
//! recursion, so [`MAX_GLASS_DEPTH`] bounds both branches (the reference bounds only the
//! lighter one): the two differ only for light trapped by more than 64 glass
//! interactions that each keep more than 1/2048 of it.
//!
//! Non-glass surfaces add the caustic (`kd · c ⊙ E`, [`CausticMap::irradiance`]), whose
//! photons this renderer traces through its own BVH ([`PhotonTracer`] below).

use glam::{DVec3, Vec3};
use wide::f32x8;

use super::{Gathered, PacketRenderer, PathState};
use crate::bvh::Steps;
use crate::geometry::Hit1;
use crate::math::Ray;
use crate::math::packet::{HitPacket8, Mask8, Ray1, RayPacket8, Vec3x8, offset_origin_1};
use crate::render::RenderStats;
use crate::render::caustic::{PhotonHit, PhotonTracer};
use crate::render::spectral::{
    CAMERA_SAMPLES, GLASS_CUTOFF, MAX_GLASS_DEPTH, Wavelengths, glass_interface, nm_to_um,
};

/// A ray leaving a glass hit, and what its colour is worth to the lane that spawned it.
#[derive(Clone, Copy, Debug)]
struct Branch {
    /// Lane of the glass hit.
    lane: usize,
    origin: Vec3,
    dir: Vec3,
    /// Wavelength (nm) of a monochromatic ray.
    lambda: f32,
    /// Path weight of the new ray (for pruning deeper down).
    weight: f32,
    /// The spawning lane adds `coef ⊙ colour`.
    coef: Vec3,
    /// Refracted (for the counters).
    transmitted: bool,
}

impl PacketRenderer {
    /// Lanes of `lanes` whose hit is a glass object.
    pub(super) fn glass_lanes(&self, hit: &HitPacket8, lanes: Mask8) -> Mask8 {
        let mut glass = 0;
        let mut bits = lanes.bits();
        while bits != 0 {
            let i = bits.trailing_zeros() as usize;
            bits &= bits - 1;
            let object = self.bvh.prims.object(hit.prim_lane(i));
            if self.glass.get(object as usize).is_some_and(|g| g.is_some()) {
                glass |= 1 << i;
            }
        }
        Mask8::from_bits(glass)
    }

    /// `local` plus the caustic's `kd · c ⊙ E` on `lanes`.
    pub(super) fn add_caustic(&self, g: &Gathered, lanes: Mask8, local: Vec3x8) -> Vec3x8 {
        let Some(map) = &self.caustics else {
            return local;
        };
        let mut add = [Vec3::ZERO; 8];
        let mut any = false;
        let kd = g.kd.as_array();
        let mut bits = lanes.bits();
        while bits != 0 {
            let i = bits.trailing_zeros() as usize;
            bits &= bits - 1;
            let p = g.point.lane(i).as_dvec3() + self.base;
            let e = map.irradiance(p, g.normal.lane(i).as_dvec3());
            if e != DVec3::ZERO {
                add[i] = e.as_vec3() * kd[i] * g.color.lane(i);
                any = true;
            }
        }
        if any {
            local + Vec3x8::from_lanes(&add)
        } else {
            local
        }
    }

    /// The origin of a ray leaving `p` along `w` (the single-lane twin of `leave`).
    fn leave_1<const EPS: bool>(&self, p: Vec3, err: Vec3, n: Vec3, w: Vec3) -> Vec3 {
        if EPS {
            let e = self.offset_epsilon.unwrap_or(0.0);
            p + n * if w.dot(n) < 0.0 { -e } else { e }
        } else {
            offset_origin_1(p, err, n, w)
        }
    }

    /// What the glass lanes of a packet reflect and transmit, traced at `path.level + 1`
    /// and weighted (zero in the other lanes). The caller adds it to the lanes' Phong
    /// colour and ends their mirror chain.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn split_at_glass<const ANY_HIT: bool, const EPS: bool>(
        &self,
        ray: &RayPacket8,
        hit: &HitPacket8,
        g: &Gathered,
        glass: Mask8,
        path: &PathState,
        stats: &mut RenderStats,
        steps: &mut Steps,
    ) -> Vec3x8 {
        let (t, u, v) = (hit.t.as_array(), hit.u.as_array(), hit.v.as_array());
        let weight = path.weight.as_array();
        let cutoff = GLASS_CUTOFF as f32;
        let nest = path.depth < MAX_GLASS_DEPTH;
        // RGB reflected rays stay in their lanes (their pixel's wavelengths deeper
        // down); every monochromatic ray goes into `mono`, eight to a packet
        let mut rgb: [Option<Branch>; 8] = [None; 8];
        let mut mono: Vec<Branch> = Vec::new();
        let mut bits = glass.bits();
        while bits != 0 {
            let i = bits.trailing_zeros() as usize;
            bits &= bits - 1;
            let code = hit.prim_lane(i);
            let object = self.bvh.prims.object(code) as usize;
            let Some(gl) = self.glass[object] else {
                continue;
            };
            let kr = self.materials[object].kr as f64;
            let d32 = ray.dir.lane(i);
            let lane_ray = Ray1::new(ray.origin.lane(i), d32);
            // the unflipped normal: prism faces are wound outwards
            let outward = self
                .bvh
                .prims
                .surface_1(code, &lane_ray, t[i], u[i], v[i])
                .normal;
            let (p, err) = (g.point.lane(i), g.err.lane(i));
            let d = d32.as_dvec3();
            let n_out = outward.as_dvec3();
            let w = weight[i];
            let branch = |dir: DVec3, lambda: f32, weight: f32, coef: DVec3, transmitted| {
                let dir = dir.as_vec3();
                Branch {
                    lane: i,
                    origin: self.leave_1::<EPS>(p, err, outward, dir),
                    dir,
                    lambda,
                    weight,
                    coef: coef.as_vec3(),
                    transmitted,
                }
            };
            match path.lambda {
                None => {
                    // RGB meets glass: the transmitted light splits into wavelengths
                    let (x, y) = (path.pixel[0] + i as u32 % 4, path.pixel[1] + i as u32 / 4);
                    let wl = Wavelengths::for_pixel(x, y, self.seed);
                    // one bound for every wavelength of the pixel (as the reference)
                    let reach_w = wl
                        .weight
                        .iter()
                        .map(|w| w.max_element())
                        .fold(0.0, f64::max);
                    let mut reflect_weight = DVec3::ZERO;
                    let mut reflected = d;
                    for k in 0..CAMERA_SAMPLES {
                        let n = gl.index(nm_to_um(wl.lambda[k]));
                        let f = glass_interface(d, n_out, n);
                        reflected = f.reflected;
                        reflect_weight += wl.weight[k] * (kr + gl.kt * f.fresnel);
                        let wt = gl.kt * (1.0 - f.fresnel);
                        let reach = (w as f64 * wt * reach_w) as f32;
                        if let Some(tr) = f.transmitted
                            && reach > cutoff
                            && nest
                        {
                            mono.push(branch(
                                tr,
                                wl.lambda[k] as f32,
                                reach,
                                wl.weight[k] * wt,
                                true,
                            ));
                        }
                    }
                    let wr = (w as f64 * reflect_weight.max_element()) as f32;
                    if wr > cutoff && nest {
                        rgb[i] = Some(branch(reflected, 0.0, wr, reflect_weight, false));
                    }
                }
                Some(lambda) => {
                    let l = lambda[i];
                    let f = glass_interface(d, n_out, gl.index(nm_to_um(l as f64)));
                    let wr = kr + gl.kt * f.fresnel;
                    if (w as f64 * wr) as f32 > cutoff && nest {
                        let b = branch(
                            f.reflected,
                            l,
                            (w as f64 * wr) as f32,
                            DVec3::splat(wr),
                            false,
                        );
                        mono.push(b);
                    }
                    let wt = gl.kt * (1.0 - f.fresnel);
                    if let Some(tr) = f.transmitted
                        && wt > 0.0
                        && (w as f64 * wt) as f32 > cutoff
                        && nest
                    {
                        let b = branch(tr, l, (w as f64 * wt) as f32, DVec3::splat(wt), true);
                        mono.push(b);
                    }
                }
            }
        }
        let mut out = [Vec3::ZERO; 8];
        let deeper = |lambda| PathState {
            level: path.level + 1,
            lambda,
            weight: f32x8::ZERO, // set per batch
            depth: path.depth + 1,
            pixel: path.pixel,
        };
        if rgb.iter().any(Option::is_some) {
            let c = self.trace_branches::<ANY_HIT, EPS>(&rgb, deeper(None), stats, steps);
            for (b, c) in rgb.iter().zip(c) {
                if let Some(b) = b {
                    out[b.lane] += b.coef * c;
                }
            }
        }
        for chunk in mono.chunks(8) {
            let mut batch: [Option<Branch>; 8] = [None; 8];
            let mut lambda = [0.0f32; 8];
            for (k, b) in chunk.iter().enumerate() {
                batch[k] = Some(*b);
                lambda[k] = b.lambda;
            }
            let c = self.trace_branches::<ANY_HIT, EPS>(&batch, deeper(Some(lambda)), stats, steps);
            for (b, c) in chunk.iter().zip(c) {
                out[b.lane] += b.coef * c;
            }
        }
        Vec3x8::from_lanes(&out)
    }

    /// Traces up to eight branches as one packet (lane k: `batch[k]`), at `path`'s
    /// level with their weights; their colours, by lane.
    fn trace_branches<const ANY_HIT: bool, const EPS: bool>(
        &self,
        batch: &[Option<Branch>; 8],
        mut path: PathState,
        stats: &mut RenderStats,
        steps: &mut Steps,
    ) -> [Vec3; 8] {
        let mut origin = [Vec3::ZERO; 8];
        let mut dir = [Vec3::Z; 8];
        let mut weight = [0.0f32; 8];
        let mut bits = 0;
        for (k, b) in batch.iter().enumerate() {
            if let Some(b) = b {
                (origin[k], dir[k], weight[k]) = (b.origin, b.dir, b.weight);
                bits |= 1 << k;
                if b.transmitted {
                    stats.refraction_rays += 1;
                } else {
                    stats.reflection_rays += 1;
                }
            }
        }
        let active = Mask8::from_bits(bits);
        path.weight = f32x8::new(weight);
        let packet = RayPacket8::new(
            Vec3x8::from_lanes(&origin),
            Vec3x8::from_lanes(&dir),
            active,
        );
        let mut chain = Vec::new();
        let c =
            self.trace_path::<ANY_HIT, EPS, true>(&packet, active, &path, &mut chain, stats, steps);
        std::array::from_fn(|k| c.lane(k))
    }
}

/// The photon pass traces through the renderer's BVH (in its f32 frame).
impl PhotonTracer for PacketRenderer {
    fn nearest(&self, ray: &Ray) -> Option<PhotonHit> {
        let r = Ray1::from_f64(ray.origin, ray.dir, self.base);
        let mut h = Hit1::new(f32::INFINITY);
        self.bvh.intersect_1(&r, &mut h, &mut Steps::default());
        if !h.is_hit() {
            return None;
        }
        let s = self.bvh.prims.surface_1(h.prim, &r, h.t, h.u, h.v);
        let object = self.bvh.prims.object(h.prim);
        // the f32 point's error bound, plus one rounding of the next origin back into
        // the f32 frame
        let err = s.err.as_dvec3() + s.point.abs().as_dvec3() * f32::EPSILON as f64;
        Some(PhotonHit {
            t: h.t as f64,
            point: s.point.as_dvec3() + self.base,
            normal: s.normal.as_dvec3().normalize(),
            err,
            object: (object != u32::MAX).then_some(object as usize),
        })
    }
}
