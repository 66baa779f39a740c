//! Where the packet path's f32 stops resolving a scene: an object small against the
//! distances its rays travel.
//!
//! The packet path works in f32 coordinates centred on the camera, so a point is held
//! to about 2⁻²⁴ of its distance from the camera, and a ray's direction to about 2⁻²⁴,
//! which at a distance d puts the ray 2⁻²⁴·d off. An object much smaller than that
//! fraction of its distance from the camera, or from the floor (shadow and mirror rays
//! between them), has its edges and its shadows misplaced by a visible fraction of its
//! size. The reference (f64) holds at every scale, so the command line warns and names
//! the object ([`Detail::below_f32`]).

use glam::Vec3;

use crate::geometry::{PrimKind, PrimSet, prim_code};
use crate::scene::Scene;

/// The bounded primitive of a packet renderer that is smallest against its distance,
/// in scene units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Detail {
    /// Index of its object in the scene file (0-based).
    pub object: u32,
    /// The diagonal of its bounding box.
    pub size: f64,
    /// The distance from the centre of its bounds to the camera or to the nearest
    /// point of the floor, whichever is farther.
    pub distance: f64,
}

impl Detail {
    /// Whether f32 loses this detail: `size` below 8 f32 epsilons (2⁻²⁰ ≈ 9.5e-7) of
    /// `distance`. Measured on the given scene scaled about the eye, `fast` against the
    /// reference at 128² (`tests/extremes.rs`, `detail_below_f32_precision_is_flagged`):
    /// size/distance 1.8e-6 (scale 3e-6) puts 0.65 % of the pixels more than 8/255 off,
    /// within the `fast` profile's 1 %; 6.1e-7 (scale 1e-6) puts 2.0 % off, and 2.5e-8
    /// (scale 1e-7) 5.5 %.
    pub fn below_f32(&self) -> bool {
        self.size < 8.0 * f64::from(f32::EPSILON) * self.distance
    }

    /// The warning for `scene` rendered with the profile named `profile`.
    pub fn warning(&self, scene: &Scene, profile: &str) -> String {
        format!(
            "octaray: warning: {} (bounds {:.1e} across) is below f32 precision at its \
             distance from the camera or the floor ({:.1e}): profile {profile} may misplace \
             its edges and shadows; --profile reference renders it exactly",
            scene.object_name(self.object as usize),
            self.size,
            self.distance,
        )
    }
}

/// The bounded primitive of `prims` (an f32 frame whose origin is the camera) with the
/// smallest ratio of size to distance; `None` for a scene without bounded primitives.
/// Unbounded quadrics have no size and the floor's is fixed: neither is a candidate.
/// (Lights do not count: a shadow ray starts at the surface, so a far light only sets
/// its direction.)
pub fn smallest_detail(prims: &PrimSet) -> Option<Detail> {
    let floor_distance = |c: Vec3| {
        prims.floor.as_ref().map_or(0.0, |f| {
            let nearest = Vec3::new(c.x.clamp(f.x0, f.x1), c.y.clamp(f.y0, f.y1), f.z);
            nearest.distance(c)
        })
    };
    let mut smallest: Option<(f32, Detail)> = None;
    for kind in PrimKind::BVH_KINDS {
        for i in 0..prims.len(kind) {
            let b = prims.bounds(kind, i);
            let size = (b.hi - b.lo).length();
            let c = (b.lo + b.hi) * 0.5;
            let distance = c.length().max(floor_distance(c));
            let ratio = size / distance;
            if smallest.is_none_or(|(r, _)| ratio < r) {
                let detail = Detail {
                    object: prims.object(prim_code(kind, i)),
                    size: f64::from(size),
                    distance: f64::from(distance),
                };
                smallest = Some((ratio, detail));
            }
        }
    }
    smallest.map(|(_, d)| d)
}
