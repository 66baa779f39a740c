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
//!
//! The frame also has a range: [`F32_RANGE`] from the camera. The kernels multiply
//! coordinates (the sphere test squares lengths, the watertight triangle test takes
//! products of three), so beyond it they overflow f32 and miss, and the BVH clamps
//! every bound at [`BOUNDS_LIMIT`](crate::geometry::BOUNDS_LIMIT) = 2⁴⁴. An object
//! reaching past the range is named too: on the f32 paths a sphere of radius 2e19
//! around the camera (its squared radius is infinite in f32) leaves only the floor, a
//! sphere of radius 9e14 at 1e15 (its bounds clamped to a sliver) and a triangle at
//! 8e12 (its scaled distance overflows) vanish.

use glam::Vec3;

use crate::geometry::{PrimKind, PrimSet, prim_code};
use crate::scene::Scene;

/// How far from the camera the f32 frame holds a scene: 2⁴² (4.4e12), where a product
/// of three coordinates (2¹²⁶) still fits in f32 (below 2¹²⁸), as the watertight
/// triangle test needs; spheres and quadrics need only squares.
pub const F32_RANGE: f32 = 4_398_046_511_104.0;

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
    /// The largest coordinate of its bounds, relative to the camera (as the BVH sees
    /// them: at most [`BOUNDS_LIMIT`](crate::geometry::BOUNDS_LIMIT)).
    pub reach: f64,
}

impl Detail {
    /// Whether f32 loses this detail: `size` below 8 f32 epsilons (2⁻²⁰ ≈ 9.5e-7) of
    /// `distance`, where the `fast` profile leaves its 1 % bound of pixels off by more
    /// than 8/255 (`tests/extremes.rs`, `detail_below_f32_precision_is_flagged`).
    ///
    /// An object reaching beyond [`F32_RANGE`] is lost to f32 whatever its size.
    pub fn below_f32(&self) -> bool {
        self.beyond_range() || self.size < 8.0 * f64::from(f32::EPSILON) * self.distance
    }

    /// Whether its bounds reach beyond [`F32_RANGE`] from the camera.
    pub fn beyond_range(&self) -> bool {
        self.reach > f64::from(F32_RANGE)
    }

    /// The warning for `scene` rendered with the profile named `profile`.
    pub fn warning(&self, scene: &Scene, profile: &str) -> String {
        if self.beyond_range() {
            return format!(
                "octaray: warning: {} reaches farther from the camera than f32's range \
                 (2^42 = {:.1e}): profile {profile} may lose it; --profile reference \
                 renders it exactly",
                scene.object_name(self.object as usize),
                F32_RANGE,
            );
        }
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

/// The bounded primitive of `prims` (an f32 frame whose origin is the camera) reaching
/// farthest beyond [`F32_RANGE`], if one does, else the one with the smallest ratio of
/// size to distance; `None` for a scene without bounded primitives.
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
    // ranked by (reach beyond the range, then ratio): the lowest wins
    let mut smallest: Option<((f32, f32), Detail)> = None;
    for kind in PrimKind::BVH_KINDS {
        for i in 0..prims.len(kind) {
            let b = prims.bounds(kind, i);
            let size = (b.hi - b.lo).length();
            let c = (b.lo + b.hi) * 0.5;
            let distance = c.length().max(floor_distance(c));
            let reach = b.lo.abs().max(b.hi.abs()).max_element();
            let rank = (-(reach - F32_RANGE).max(0.0), size / distance);
            if smallest.is_none_or(|(r, _)| rank < r) {
                let detail = Detail {
                    object: prims.object(prim_code(kind, i)),
                    size: f64::from(size),
                    distance: f64::from(distance),
                    reach: f64::from(reach),
                };
                smallest = Some((rank, detail));
            }
        }
    }
    smallest.map(|(_, d)| d)
}
