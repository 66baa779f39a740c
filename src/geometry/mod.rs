//! Ray–primitive intersection, one file per kind.
//!
//! Each kind's file holds the f64 reference kernel (`intersect_ref`, `surface_ref`:
//! the oracle, written to be read) and, beside it, the kernels of the fast path with
//! the same step comments in the same order.
//!
//! Edge rules, shared by every kind:
//! - A hit counts iff `0 < t < t_max` (t along a unit direction).
//! - NaN never produces a hit.
//! - A ray through an edge shared by two triangles hits at least one of them
//!   (watertight test); equal t ties go to the object listed first in the file.

pub mod floor;
pub mod quadric;
pub mod sphere;
pub mod triangle;

use glam::DVec3;

use crate::math::Ray;
use crate::scene::Shape;

/// What a reference kernel reports for a hit: the distance, for triangles the
/// barycentric coordinates (b0, b1, b2) of the hit point, and for compound shapes
/// (the prism) which part was hit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RefHit {
    pub t: f64,
    pub bary: DVec3,
    pub part: usize,
}

impl RefHit {
    pub fn at(t: f64) -> RefHit {
        RefHit {
            t,
            bary: DVec3::ZERO,
            part: 0,
        }
    }
}

/// The surface at the winning hit, computed once: the point, its unit geometric
/// normal (not yet flipped towards the ray) and a per-component bound on the error
/// of `point`, used to start secondary rays off the surface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfacePoint {
    pub point: DVec3,
    pub normal: DVec3,
    pub err: DVec3,
}

/// Reference intersection of one ray with one scene shape, 0 < t < t_max.
pub fn intersect_ref(shape: &Shape, ray: &Ray, t_max: f64) -> Option<RefHit> {
    match shape {
        Shape::Sphere { center, radius } => {
            sphere::intersect_ref(*center, *radius, ray, t_max).map(RefHit::at)
        }
        Shape::Triangle { v } => triangle::intersect_ref(v, ray, t_max),
        Shape::Quadric(q) => quadric::intersect_ref(q, ray, t_max).map(RefHit::at),
        Shape::Prism { v, .. } => prism_faces(v)
            .iter()
            .enumerate()
            .filter_map(|(part, f)| {
                triangle::intersect_ref(f, ray, t_max).map(|h| RefHit { part, ..h })
            })
            .min_by(|a, b| a.t.total_cmp(&b.t)),
    }
}

/// Reference surface record at a hit found by [`intersect_ref`].
pub fn surface_ref(shape: &Shape, ray: &Ray, hit: &RefHit) -> SurfacePoint {
    match shape {
        Shape::Sphere { center, radius } => sphere::surface_ref(*center, *radius, ray, hit.t),
        Shape::Triangle { v } => triangle::surface_ref(v, hit),
        Shape::Quadric(q) => quadric::surface_ref(q, ray, hit.t),
        Shape::Prism { v, .. } => triangle::surface_ref(&prism_faces(v)[hit.part], hit),
    }
}

/// The five faces of a prism as eight triangles (ends abc, def; quads split in two),
/// all wound so that (b − a) × (c − a) points out of the prism.
pub fn prism_faces(v: &[DVec3; 6]) -> [[DVec3; 3]; 8] {
    let [a, b, c, d, e, f] = *v;
    let mut faces = [
        [a, b, c],
        [d, f, e],
        [a, d, e],
        [a, e, b],
        [b, e, f],
        [b, f, c],
        [c, f, d],
        [c, d, a],
    ];
    // Orient outwards: the centroid must lie behind every face.
    let centroid = v.iter().copied().sum::<DVec3>() / 6.0;
    for face in &mut faces {
        let n = (face[1] - face[0]).cross(face[2] - face[0]);
        if n.dot(centroid - face[0]) > 0.0 {
            face.swap(1, 2);
        }
    }
    faces
}
