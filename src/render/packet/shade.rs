//! Shading: the ambient term and, per light, Phong diffuse and specular where a shadow
//! packet finds the light unblocked.

use wide::f32x8;

use super::gather::Gathered;
use super::lights::Light32;
use super::{Offset, Settings, Tracer};
use crate::bvh::Steps;
use crate::math::packet::{Cmp8, Mask8, RayPacket8, Vec3x8};
use crate::render::RenderStats;

/// Lights whose shadow packets [`Tracer::phong`] sets up together.
const SHADOW_BATCH: usize = 4;

/// One light's shadow packet and what shading needs of it.
#[derive(Clone, Copy, Debug)]
struct ShadowRay {
    /// Lanes the light can reach (cone, front side).
    m: Mask8,
    /// Unit direction to the light and its cosine with the normal.
    l: Vec3x8,
    n_dot_l: f32x8,
    /// From the surface (offset) to the light, `len` long, over lanes `m_ray`.
    ray: RayPacket8,
    len: f32x8,
    m_ray: Mask8,
}

impl<S: Settings> Tracer<'_, S> {
    /// Ambient plus, per light, Phong diffuse and specular where the light is inside
    /// its cone, in front of the surface and unshadowed.
    pub(super) fn phong(
        &self,
        g: &Gathered,
        view: Vec3x8,
        lanes: Mask8,
        stats: &mut RenderStats,
        steps: &mut Steps,
    ) -> Vec3x8 {
        let zero = f32x8::ZERO;
        let mut out = g.color * g.ka;
        let n = g.normal;
        // A few lights' shadow packets are set up before any is traced: their square
        // roots and divisions then overlap instead of each waiting behind the previous
        // light's (branchy) traversal.
        for lights in self.lights.chunks(SHADOW_BATCH) {
            let mut rays = [None; SHADOW_BATCH];
            for (ray, light) in rays.iter_mut().zip(lights) {
                *ray = self.shadow_ray(light, g, lanes, stats);
            }
            for (ray, light) in rays.iter().zip(lights) {
                let Some(s) = ray else { continue };
                let blocked = if S::ANY_HIT {
                    self.occluded(&s.ray, s.m_ray, s.len, steps)
                } else {
                    self.occluded_closest(&s.ray, s.m_ray, s.len, steps)
                };
                let lit = s.m.and_not(blocked);
                if lit.none() {
                    continue;
                }
                let r = n * (f32x8::splat(2.0) * s.n_dot_l) - s.l;
                let lc = Vec3x8::splat(light.color);
                let diffuse = g.kd * s.n_dot_l;
                let rv = r.dot(view).max(zero);
                // x^0 = 1 and 0^s = 0 (s > 0), as f64::powf
                let pow = match self.whole_shine {
                    Some(bits) => pow_whole(rv, g.shine, bits),
                    None => rv.powf_simd(g.shine),
                };
                let spec = rv
                    .gt(zero)
                    .select(pow, g.shine.eq8(zero).select(f32x8::splat(1.0), zero));
                let spec = g.shine.eq8(zero).select(f32x8::splat(1.0), spec);
                let w = diffuse + g.ks * spec;
                let add = (lc * g.color) * w;
                out = out + Vec3x8::select(lit, add, Vec3x8::ZERO);
            }
        }
        out
    }

    /// The shadow packet towards `light` from the lanes it can light (inside its cone,
    /// in front of the surface); `None` if there are none.
    #[inline(always)]
    fn shadow_ray(
        &self,
        light: &Light32,
        g: &Gathered,
        lanes: Mask8,
        stats: &mut RenderStats,
    ) -> Option<ShadowRay> {
        let zero = f32x8::ZERO;
        let (p, n) = (g.point, g.normal);
        let lp = Vec3x8::splat(light.position);
        let mut m = lanes;
        // spotlight only: skip lanes outside the cone (hard edge)
        if let Some(cone) = &light.cone {
            stats.cone_tests += m.count() as u64;
            m = m & cone.contains(p, lp);
            // (most shading points of a narrow spotlight's scene lie outside it)
            if m.none() {
                return None;
            }
        }
        let to_light = lp - p;
        let dist = to_light.length();
        m = m & dist.gt(zero);
        let l = to_light * (f32x8::splat(1.0) / dist);
        let n_dot_l = n.dot(l);
        m = m & n_dot_l.gt(zero);
        if m.none() {
            return None;
        }
        // shadow: anything on the segment between the surface and the light
        let origin = self.offset.origin(p, g.err, n, l);
        let seg = lp - origin;
        let len = seg.length();
        let m_ray = m & len.gt(zero);
        stats.shadow_rays += m.count() as u64;
        Some(ShadowRay {
            m,
            l,
            n_dot_l,
            ray: RayPacket8::new(origin, seg * (f32x8::splat(1.0) / len), m_ray),
            len,
            m_ray,
        })
    }
}

/// `x^e` per lane by repeated squaring, for exponents `e` that are whole numbers
/// below 2^`bits`: `bits` multiplies and selects, where `powf` takes a logarithm and
/// an exponential.
#[inline(always)]
fn pow_whole(x: f32x8, e: f32x8, bits: u32) -> f32x8 {
    let (mut acc, mut sq, mut e) = (f32x8::splat(1.0), x, e);
    for k in 0..bits {
        if k > 0 {
            sq = sq * sq;
        }
        let half = (e * f32x8::splat(0.5)).floor();
        acc = e.gt(half + half).select(acc * sq, acc);
        e = half;
    }
    acc
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn whole_powers_by_squaring_match_powf() {
        let x = f32x8::new([0.0, 1e-3, 0.1, 0.5, 0.7, 0.9, 0.999, 1.0]);
        for e in [0u32, 1, 2, 3, 5, 10, 15, 16, 100, 255] {
            let bits = u32::BITS - e.leading_zeros();
            let got = pow_whole(x, f32x8::splat(e as f32), bits).to_array();
            for (g, xv) in got.iter().zip(x.to_array()) {
                // relative, down to where f32 goes subnormal
                let want = (xv as f64).powi(e as i32);
                let tol = want.max(f32::MIN_POSITIVE as f64) * 1e-5;
                assert!(
                    (*g as f64 - want).abs() <= tol,
                    "{xv}^{e}: {g} against {want}"
                );
            }
        }
        // lanes with different exponents
        let e = f32x8::new([0.0, 1.0, 2.0, 3.0, 4.0, 7.0, 8.0, 9.0]);
        let got = pow_whole(f32x8::splat(0.5), e, 4).to_array();
        for (g, k) in got.iter().zip(e.to_array()) {
            assert_eq!(*g, 0.5f32.powi(k as i32));
        }
    }
}
