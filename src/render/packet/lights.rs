//! Materials and lights in the packet path's f32 frame; a spotlight's cone test.

use glam::{DVec3, Vec3};
use wide::f32x8;

use crate::math::packet::{Cmp8, Mask8, Vec3x8};
use crate::scene::{Material, SpotLight};

/// Shading parameters of one object, in f32.
#[derive(Clone, Copy, Debug)]
pub(super) struct Mat32 {
    pub color: Vec3,
    pub ka: f32,
    pub kd: f32,
    pub ks: f32,
    pub kr: f32,
    pub shine: f32,
}

impl Mat32 {
    pub fn new(m: &Material) -> Mat32 {
        Mat32 {
            color: m.color.as_vec3(),
            ka: m.ka as f32,
            kd: m.kd as f32,
            ks: m.ks as f32,
            kr: m.kr as f32,
            // a positive shine stays positive (1e-300 would round to 0, whose rule,
            // x^0 = 1, lights every point with the full specular term)
            shine: if m.shine > 0.0 {
                (m.shine as f32).max(f32::from_bits(1))
            } else {
                0.0
            },
        }
    }
}

/// A light in the renderer's frame; spotlights carry their cone.
#[derive(Clone, Copy, Debug)]
pub(super) struct Light32 {
    pub position: Vec3,
    pub color: Vec3,
    /// The cone of a spotlight with cutoff < 180°.
    pub cone: Option<Cone32>,
}

/// A spotlight's cone: a point P is inside when the angle θ between the axis and
/// w = P − Lp is at most the cutoff φ, tested as sin(φ − θ) >= 0, i.e.
/// |axis × w|·cos φ <= (axis · w)·sin φ, and axis · w >= 0 unless φ >= 90°.
/// Sines of small angles keep their relative precision where cosines do not (the test
/// `axis · w >= cos φ·|w|` in f32 resolves angles only to ~0.02° near the axis). In f32
/// the limit is then the rounded axis and light position, ~1e-7 rad, a visible part of
/// a very narrow cone: cones within [`NARROW_CONE_DEG`] of 0° or 180° are tested in
/// f64.
#[derive(Clone, Copy, Debug)]
pub(super) struct Cone32 {
    axis: Vec3,
    cos: f32,
    sin: f32,
    /// φ >= 90°: points behind the light's plane can be inside.
    wide: bool,
    /// A narrow cone (or the narrow dark cone behind a nearly full one): the axis and
    /// the light's position relative to the frame's origin, unrounded, and cos φ, sin φ.
    exact: Option<(DVec3, DVec3, f64, f64)>,
}

/// Spotlights whose cutoff lies within this of 0° or 180° test their cone in f64,
/// where f32's ~1e-7 rad of rounding would be a visible part of it.
const NARROW_CONE_DEG: f64 = 0.1;

impl Cone32 {
    /// The cone of spotlight `s` in the frame centred on `base`.
    pub fn new(s: &SpotLight, base: DVec3) -> Cone32 {
        let phi = s.cutoff_deg;
        // exactly 90°: cos φ = 0, so that points in the light's plane (axis · w = 0)
        // are inside, as the reference's atan2 finds them (cos(π/2) rounds to 6e-17)
        let (sin, cos) = if phi == 90.0 {
            (1.0, 0.0)
        } else {
            phi.to_radians().sin_cos()
        };
        let narrow = phi.min(180.0 - phi) < NARROW_CONE_DEG;
        Cone32 {
            axis: s.direction.as_vec3(),
            cos: cos as f32,
            sin: sin as f32,
            wide: phi >= 90.0,
            exact: narrow.then(|| (s.direction, s.position - base, cos, sin)),
        }
    }

    /// Lanes whose point `p` (frame coordinates) is inside the cone; `lp` is the
    /// light's position in the frame.
    #[inline(always)]
    pub fn contains(&self, p: Vec3x8, lp: Vec3x8) -> Mask8 {
        if let Some((axis, apex, cos, sin)) = self.exact {
            let mut bits = 0;
            for i in 0..8 {
                let w = p.lane(i).as_dvec3() - apex;
                let c = axis.dot(w);
                if axis.cross(w).length() * cos <= c * sin && (self.wide || c >= 0.0) {
                    bits |= 1 << i;
                }
            }
            return Mask8::from_bits(bits);
        }
        let axis = Vec3x8::splat(self.axis);
        let w = p - lp;
        let c = axis.dot(w);
        let s = axis.cross(w).length();
        let inside = (s * f32x8::splat(self.cos)).le(c * f32x8::splat(self.sin));
        if self.wide {
            inside
        } else {
            inside & c.ge(f32x8::ZERO)
        }
    }
}
