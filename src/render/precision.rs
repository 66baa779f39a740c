//! Where the packet path's f32 stops resolving a scene: its smallest object against
//! the distances its rays travel.
//!
//! The packet path works in f32 coordinates centred on the camera, so a point is held
//! to about 2⁻²⁴ of its distance from the camera, and a ray's direction to about 2⁻²⁴
//! of its length. An object much smaller than that fraction of the scene's extent
//! (the camera, the objects, the lights and the floor beneath them: the distances
//! camera, shadow and mirror rays travel) has its edges and its shadows misplaced by
//! a visible fraction of its size. The reference (f64) holds at every scale, so the
//! command line warns and names it ([`Detail::below_f32`]).

use glam::Vec3;

use crate::geometry::{PrimKind, PrimSet, prim_code};
use crate::scene::Scene;

/// The smallest bounded primitive of a packet renderer and the extent it sits in, in
/// scene units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Detail {
    /// Index of its object in the scene file (0-based).
    pub object: u32,
    /// The diagonal of its bounding box.
    pub size: f64,
    /// The diagonal of the box around the camera, every bounded object, every light
    /// and the point of the floor beneath the objects.
    pub extent: f64,
}

impl Detail {
    /// Whether f32 loses this detail: `size` below 8 f32 epsilons (2⁻²⁰ ≈ 9.5e-7) of
    /// `extent`. Measured on the given scene scaled about the eye, `fast` against the
    /// reference at 128² (`tests/extremes.rs`, `detail_below_f32_precision_is_flagged`):
    /// size/extent 1.8e-6 (scale 3e-6) puts 0.65 % of the pixels more than 8/255 off,
    /// within the `fast` profile's 1 %; 6.1e-7 (scale 1e-6) puts 2.0 % off, and 2.5e-8
    /// (scale 1e-7) 5.5 %.
    pub fn below_f32(&self) -> bool {
        self.size < 8.0 * f64::from(f32::EPSILON) * self.extent
    }

    /// The warning for `scene` rendered with the profile named `profile`.
    pub fn warning(&self, scene: &Scene, profile: &str) -> String {
        format!(
            "octaray: warning: {} (bounds {:.1e} across) is below f32 precision at this \
             scene's extent ({:.1e}): profile {profile} may misplace its edges and shadows; \
             --profile reference renders it exactly",
            scene.object_name(self.object as usize),
            self.size,
            self.extent,
        )
    }
}

/// The smallest bounded primitive of `prims` (an f32 frame whose origin is the camera)
/// and the extent around it, with `lights` (positions in the same frame); `None` for a
/// scene without bounded primitives. Unbounded quadrics have no size and the floor's
/// is fixed: neither is a candidate.
pub fn smallest_detail(prims: &PrimSet, lights: impl Iterator<Item = Vec3>) -> Option<Detail> {
    // the camera is the frame's origin
    let (mut lo, mut hi) = (Vec3::ZERO, Vec3::ZERO);
    let mut smallest: Option<(f32, i32)> = None;
    let (mut objects_lo, mut objects_hi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
    let triangles = if prims.moller {
        PrimKind::TriangleMoller
    } else {
        PrimKind::Triangle
    };
    for kind in [PrimKind::Sphere, triangles, PrimKind::Quadric] {
        for i in 0..prims.len(kind) {
            let b = prims.bounds(kind, i);
            let size = (b.hi - b.lo).length();
            if smallest.is_none_or(|(s, _)| size < s) {
                smallest = Some((size, prim_code(kind, i)));
            }
            objects_lo = objects_lo.min(b.lo);
            objects_hi = objects_hi.max(b.hi);
        }
    }
    let (size, code) = smallest?;
    lo = lo.min(objects_lo);
    hi = hi.max(objects_hi);
    for p in lights {
        lo = lo.min(p);
        hi = hi.max(p);
    }
    // the floor beneath the objects, where their shadows fall and from where mirror
    // rays rise
    if let Some(f) = &prims.floor {
        let c = (objects_lo + objects_hi) * 0.5;
        let below = Vec3::new(c.x.clamp(f.x0, f.x1), c.y.clamp(f.y0, f.y1), f.z);
        lo = lo.min(below);
        hi = hi.max(below);
    }
    Some(Detail {
        object: prims.object(code),
        size: f64::from(size),
        extent: f64::from((hi - lo).length()),
    })
}
