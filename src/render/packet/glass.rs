//! Glass (dispersive prisms) on the packet path: the same transport as the reference
//! (`render::reference`, module doc), computed on packets.
//!
//! At a glass hit at level L the lane's colour is
//! `clamp(phong + (kr + kt·F)·C_reflected + kt·(1 − F)·C_transmitted, 0, 1)` with both
//! rays traced at level L + 1. An RGB lane (one that has met no glass yet) splits its
//! transmitted light into its pixel's 16 wavelengths ([`Wavelengths::for_pixel`], the
//! same as the reference's): the 16 refracted rays leave one point in nearly one
//! direction, so they are traced nested as two coherent packets of 8 monochromatic
//! lanes. Its reflection (one direction for every wavelength, weighted per channel by
//! the mean of kr + kt·F) goes on in the packet's mirror-chain loop, as the reference's
//! does. A monochromatic lane splits into one reflected and one transmitted ray
//! (Fresnel at its own n(λ)); as in the reference, the heavier goes on in the loop
//! (light trapped by total internal reflection bounces there at constant stack, up to
//! the recursion level) and the lighter is traced nested, lanes in place.
//!
//! Pruning as the reference: a branch whose colour could add at most
//! [`GLASS_CUTOFF`] to the pixel is not traced, and [`MAX_GLASS_DEPTH`] bounds the
//! nested branchings.
//!
//! Non-glass surfaces add the caustic (`kd · c ⊙ E`, [`CausticMap::irradiance`]), whose
//! photons this renderer traces through its own BVH ([`PhotonTracer`] below).
//!
//! [`CausticMap::irradiance`]: crate::render::caustic::CausticMap::irradiance

use glam::{DVec3, Vec3};
use wide::f32x8;

use super::chain::Chain;
use super::gather::Gathered;
use super::path::PathState;
use super::{Offset, PacketRenderer, Settings, Tracer};
use crate::bvh::Steps;
use crate::geometry::Hit1;
use crate::math::Ray;
use crate::math::packet::{Cmp8, HitPacket8, Mask8, Ray1, RayPacket8, Vec3x8};
use crate::render::RenderStats;
use crate::render::caustic::{PhotonHit, PhotonTracer};
use crate::render::spectral::{CAMERA_SAMPLES, GLASS_CUTOFF, MAX_GLASS_DEPTH, Wavelengths};

/// What happens to eight rays at glass surfaces (f32 twin of
/// [`crate::render::spectral::glass_interface`], lane by lane).
struct Interface8 {
    /// Mirror directions.
    reflected: Vec3x8,
    /// Fresnel reflectance (1 under total internal reflection).
    fresnel: f32x8,
    /// Refracted directions, valid in `refracts`.
    transmitted: Vec3x8,
    refracts: Mask8,
}

/// Splits unit directions `d` at glass surfaces with unit *outward* normals `n_out` and
/// indices `n_glass`, in air: Snell's law, total internal reflection, exact Fresnel.
#[inline]
fn interface_x8(d: Vec3x8, n_out: Vec3x8, n_glass: f32x8) -> Interface8 {
    let (zero, one) = (f32x8::ZERO, f32x8::splat(1.0));
    let entering = d.dot(n_out).lt(zero);
    // the normal on the incident side, and the indices either side
    let n = Vec3x8::select(entering, n_out, -n_out);
    let n_i = entering.select(one, n_glass);
    let n_t = entering.select(n_glass, one);
    let eta = n_i / n_t;
    let cos_i = (-n.dot(d)).max(zero).min(one);
    let sin2_t = eta * eta * (one - cos_i * cos_i).max(zero);
    let refracts = sin2_t.lt(one);
    let cos_t = (one - sin2_t).max(zero).sqrt();
    let t = d * eta + n * (eta * cos_i - cos_t);
    let transmitted = t * (one / t.length());
    let rs = (n_i * cos_i - n_t * cos_t) / (n_i * cos_i + n_t * cos_t);
    let rp = (n_t * cos_i - n_i * cos_t) / (n_t * cos_i + n_i * cos_t);
    let fresnel = refracts.select(f32x8::splat(0.5) * (rs * rs + rp * rp), one);
    let r = d - n * (f32x8::splat(2.0) * d.dot(n));
    Interface8 {
        reflected: r * (one / r.length()),
        fresnel,
        transmitted,
        refracts,
    }
}

/// The glass lanes of a packet's hits, and per lane the glass's kr, kt and Cauchy
/// coefficients (zero in the other lanes).
pub(super) struct GlassHits {
    pub mask: Mask8,
    pub kr: f32x8,
    pub kt: f32x8,
    pub cauchy_a: f32x8,
    pub cauchy_b: f32x8,
}

/// What [`Tracer::split_mono`] leaves to the caller's loop.
pub(super) struct MonoSplit {
    /// The lighter branch's weighted colour (zero where it was not traced).
    pub side: Vec3x8,
    /// The heavier branch's direction ...
    pub main_dir: Vec3x8,
    /// ... and weight (0 where it stops: nothing more than the cutoff to add).
    pub main_weight: f32x8,
    /// Lanes whose heavier branch is the refracted ray.
    pub refracted: Mask8,
}

impl PacketRenderer {
    /// The lanes of `lanes` whose hit is a glass object, and their glass.
    pub(super) fn glass_hits(&self, hit: &HitPacket8, lanes: Mask8) -> GlassHits {
        let mut mask = 0;
        let mut k = [[0.0f32; 8]; 4];
        let mut bits = lanes.bits();
        while bits != 0 {
            let i = bits.trailing_zeros() as usize;
            bits &= bits - 1;
            let object = self.bvh.prims.object(hit.prim_lane(i)) as usize;
            if let Some(Some(gl)) = self.glass.get(object) {
                mask |= 1 << i;
                k[0][i] = self.materials[object].kr;
                k[1][i] = gl.kt as f32;
                k[2][i] = gl.cauchy_a as f32;
                k[3][i] = gl.cauchy_b as f32;
            }
        }
        let [kr, kt, cauchy_a, cauchy_b] = k.map(f32x8::new);
        GlassHits {
            mask: Mask8::from_bits(mask),
            kr,
            kt,
            cauchy_a,
            cauchy_b,
        }
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
}

impl<S: Settings> Tracer<'_, S> {
    /// The glass lanes of a packet of RGB rays: what they transmit, split into their
    /// pixel's wavelengths and traced at `path.level + 1` (weighted; zero in the other
    /// lanes), and the per-channel weight of their reflection (the mean of kr + kt·F
    /// over the wavelengths; zero where it could add no more than the cutoff), which
    /// the caller's loop follows like a mirror ray.
    pub(super) fn split_rgb(
        &self,
        ray: &RayPacket8,
        g: &Gathered,
        gh: &GlassHits,
        path: &PathState,
        stats: &mut RenderStats,
        steps: &mut Steps,
    ) -> (Vec3x8, Vec3x8) {
        let (glass, kr, kt, ca, cb) = (gh.mask, gh.kr, gh.kt, gh.cauchy_a, gh.cauchy_b);
        let outward = Vec3x8::select(g.flipped, -g.normal, g.normal);
        let cutoff = f32x8::splat(GLASS_CUTOFF as f32);
        let nest = path.depth < MAX_GLASS_DEPTH;
        // RGB meets glass: the transmitted light splits into the pixel's
        // wavelengths, two packets of eight per lane; the reflected ray (one
        // direction for every wavelength) stays RGB, in its lane
        let mut out = [Vec3::ZERO; 8];
        let mut reflect_weight = [Vec3::ZERO; 8];
        let (kr, kt, ca, cb) = (kr.to_array(), kt.to_array(), ca.to_array(), cb.to_array());
        let w = path.weight.to_array();
        let mut bits = glass.bits();
        while bits != 0 {
            let i = bits.trailing_zeros() as usize;
            bits &= bits - 1;
            let (x, y) = (path.pixel[0] + i as u32 % 4, path.pixel[1] + i as u32 / 4);
            let wl = Wavelengths::for_pixel(x, y, self.seed);
            // one bound for every wavelength of the pixel (as the reference)
            let reach_w = wl
                .weight
                .iter()
                .map(|w| w.max_element())
                .fold(0.0, f64::max) as f32;
            let splat = |v: Vec3x8| Vec3x8::splat(v.lane(i));
            let (p, err, n_out, d) = (splat(g.point), splat(g.err), splat(outward), splat(ray.dir));
            for half in 0..CAMERA_SAMPLES / 8 {
                let lambda: [f32; 8] = std::array::from_fn(|j| wl.lambda[half * 8 + j] as f32);
                let um = f32x8::new(lambda) * f32x8::splat(1e-3);
                let n_glass = f32x8::splat(ca[i]) + f32x8::splat(cb[i]) / (um * um);
                let f = interface_x8(d, n_out, n_glass);
                let fresnel = f.fresnel.to_array();
                let wt = f32x8::splat(kt[i]) * (f32x8::splat(1.0) - f.fresnel);
                let reach = f32x8::splat(w[i] * reach_w) * wt;
                let wt = wt.to_array();
                let weights = &wl.weight[half * 8..half * 8 + 8];
                for (wk, fj) in weights.iter().zip(fresnel) {
                    reflect_weight[i] += wk.as_vec3() * (kr[i] + kt[i] * fj);
                }
                let go = f.refracts & reach.gt(cutoff);
                if !nest || go.none() {
                    continue;
                }
                let o = self.offset.origin(p, err, n_out, f.transmitted);
                let packet = RayPacket8::new(o, f.transmitted, go);
                stats.refraction_rays += go.count() as u64;
                let c =
                    self.trace_deeper(&packet, go, &path.branch(Some(lambda), reach), stats, steps);
                for (j, (wk, wtj)) in weights.iter().zip(wt).enumerate() {
                    if go.lane(j) {
                        out[i] += wk.as_vec3() * wtj * c.lane(j);
                    }
                }
            }
        }
        // the reflection goes on in the caller's loop where it can still add anything
        let rw = Vec3x8::from_lanes(&reflect_weight);
        let goes_on = glass & (path.weight * rw.x.max(rw.y).max(rw.z)).gt(cutoff);
        (
            Vec3x8::from_lanes(&out),
            Vec3x8::select(goes_on, rw, Vec3x8::ZERO),
        )
    }

    /// Monochromatic glass lanes (each at its own n(λ)) split into a reflected and a
    /// transmitted ray, as in the reference: the heavier goes on in the caller's loop
    /// (returned), the lighter is traced here one level deeper, nested, if it could add
    /// more than [`GLASS_CUTOFF`] and fewer than [`MAX_GLASS_DEPTH`] branchings are
    /// nested already. Light kept by total internal reflection therefore bounces in
    /// the loop, at constant stack, up to the scene's recursion level.
    pub(super) fn split_mono(
        &self,
        ray: &RayPacket8,
        g: &Gathered,
        gh: &GlassHits,
        path: &PathState,
        stats: &mut RenderStats,
        steps: &mut Steps,
    ) -> MonoSplit {
        let (glass, kr, kt, ca, cb) = (gh.mask, gh.kr, gh.kt, gh.cauchy_a, gh.cauchy_b);
        let lambda = path.lambda.unwrap_or([0.0; 8]);
        let outward = Vec3x8::select(g.flipped, -g.normal, g.normal);
        let (zero, one) = (f32x8::ZERO, f32x8::splat(1.0));
        let cutoff = f32x8::splat(GLASS_CUTOFF as f32);
        let um = f32x8::new(lambda) * f32x8::splat(1e-3);
        let f = interface_x8(ray.dir, outward, ca + cb / (um * um));
        let wr = kr + kt * f.fresnel;
        let wt = f.refracts.select(kt * (one - f.fresnel), zero);
        let both = f.refracts & wt.gt(zero);
        // the heavier branch goes on (ties: the transmitted one, as the reference)
        let t_main = both & wt.ge(wr);
        let main_dir = Vec3x8::select(t_main, f.transmitted, f.reflected);
        let main_weight = t_main.select(wt, wr);
        let other_dir = Vec3x8::select(t_main, f.reflected, f.transmitted);
        let other_weight = t_main.select(wr, wt);
        let mut side = Vec3x8::ZERO;
        let go = glass & both & (path.weight * other_weight).gt(cutoff);
        if go.any() && path.depth < MAX_GLASS_DEPTH {
            let o = self.offset.origin(g.point, g.err, outward, other_dir);
            let packet = RayPacket8::new(o, other_dir, go);
            let refracted = go.and_not(t_main);
            stats.refraction_rays += refracted.count() as u64;
            stats.reflection_rays += go.and_not(refracted).count() as u64;
            let next = path.branch(path.lambda, path.weight * other_weight);
            let c = self.trace_deeper(&packet, go, &next, stats, steps);
            side = Vec3x8::select(go, c * other_weight, Vec3x8::ZERO);
        }
        // the main branch stops where it could add no more than the cutoff
        let goes_on = glass & (path.weight * main_weight).gt(cutoff);
        MonoSplit {
            side,
            main_dir,
            main_weight: goes_on.select(main_weight, zero),
            refracted: t_main,
        }
    }

    /// [`Tracer::trace_path`] of a packet spawned at glass, with a mirror chain
    /// from this thread's pool (a recursion level deeper than its caller's).
    fn trace_deeper(
        &self,
        packet: &RayPacket8,
        active: Mask8,
        path: &PathState,
        stats: &mut RenderStats,
        steps: &mut Steps,
    ) -> Vec3x8 {
        thread_local! {
            static CHAINS: std::cell::RefCell<Vec<Chain>> = const { std::cell::RefCell::new(Vec::new()) };
        }
        let mut chain = CHAINS.with(|c| c.borrow_mut().pop()).unwrap_or_default();
        let c = self.trace_path(packet, active, None, path, &mut chain, stats, steps);
        CHAINS.with(|c| c.borrow_mut().push(chain));
        c
    }
}

/// The photon pass traces through the renderer's BVH (in its f32 frame).
impl<S: Settings> PhotonTracer for Tracer<'_, S> {
    fn nearest(&self, ray: &Ray) -> Option<PhotonHit> {
        let r = Ray1::from_f64(ray.origin, ray.dir, self.base);
        let mut h = Hit1::new(f32::INFINITY);
        self.bvh
            .intersect_1::<S::Tri>(&r, &mut h, &mut Steps::default());
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::spectral::glass_interface;

    /// The SIMD interface against the f64 one, lane by lane: crown glass at 400 and
    /// 700 nm, inside the glass, rays at the critical angle ± 1e-3° and ± 0.1°
    /// (catalogue item 13: TIR per wavelength), entering rays from 0° to 89°.
    #[test]
    fn interface_x8_matches_the_reference_at_the_critical_angle() {
        let index = |nm: f64| 1.5046 + 0.0042 / (nm * 1e-3 * nm * 1e-3);
        let n_out = DVec3::Z;
        // leaving the glass: the ray runs up (+z) at angle a from the normal
        let leaving = |a: f64| DVec3::new(a.to_radians().sin(), 0.0, a.to_radians().cos());
        let entering = |a: f64| DVec3::new(a.to_radians().sin(), 0.0, -a.to_radians().cos());
        let mut cases = Vec::new();
        for nm in [400.0, 700.0] {
            let n = index(nm);
            let crit = (1.0 / n).asin().to_degrees();
            for da in [-0.1, -1e-3, 1e-3, 0.1] {
                cases.push((leaving(crit + da), n, crit + da > crit));
            }
            for a in [0.0, 30.0, 60.0, 89.0] {
                cases.push((entering(a), n, false));
            }
        }
        for chunk in cases.chunks(8) {
            let mut d = [Vec3::Z; 8];
            let mut n = [1.5f32; 8];
            for (k, (dir, idx, _)) in chunk.iter().enumerate() {
                d[k] = dir.as_vec3();
                n[k] = *idx as f32;
            }
            let f = interface_x8(
                Vec3x8::from_lanes(&d),
                Vec3x8::splat(n_out.as_vec3()),
                f32x8::new(n),
            );
            let fresnel = f.fresnel.to_array();
            for (k, (dir, idx, tir)) in chunk.iter().enumerate() {
                let r = glass_interface(*dir, n_out, *idx);
                assert_eq!(r.transmitted.is_none(), *tir, "{dir} n {idx}");
                assert_eq!(f.refracts.lane(k), !*tir, "lane {k}: {dir} n {idx}");
                assert!((fresnel[k] as f64 - r.fresnel).abs() < 1e-4, "{dir}");
                assert!((f.reflected.lane(k).as_dvec3() - r.reflected).length() < 1e-6);
                if let Some(t) = r.transmitted {
                    assert!(
                        (f.transmitted.lane(k).as_dvec3() - t).length() < 1e-4,
                        "{dir}"
                    );
                }
            }
        }
    }
}
