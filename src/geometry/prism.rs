//! Prism (spec §6): two parallel triangular ends and three quads, as the eight
//! outward-wound triangles of [`super::prism_faces`], each intersected with the
//! watertight triangle kernel. The reference first rejects rays that miss the prism's
//! bounding sphere (a conservative test: it never rejects a ray that hits a face).

use glam::DVec3;

use super::{RefHit, SurfacePoint, prism_faces, triangle};
use crate::math::Ray;

/// Centre (the mean of the six vertices) and radius of a sphere holding the prism.
pub fn bounding_sphere(v: &[DVec3; 6]) -> (DVec3, f64) {
    let c = v.iter().copied().sum::<DVec3>() / 6.0;
    let r = v.iter().map(|p| p.distance(c)).fold(0.0, f64::max);
    (c, r)
}

/// Whether `ray` (0 < t < t_max) certainly misses the sphere (c, r). The radius is
/// padded far beyond rounding error, so a ray that touches the prism is never culled.
fn misses_sphere(c: DVec3, r: f64, ray: &Ray, t_max: f64) -> bool {
    let r = r * (1.0 + 1e-6) + 1e-9 * c.abs().max_element();
    let oc = c - ray.origin;
    let b = oc.dot(ray.dir);
    let inside = oc.length_squared() <= r * r;
    if inside {
        return false;
    }
    // outside and moving away, out of reach within t_max, or passing beside it
    b < 0.0 || b - r > t_max || (oc - ray.dir * b).length_squared() > r * r
}

/// A prism with its faces and bounding sphere computed once (the reference keeps one
/// per prism of the scene; [`intersect_ref`] gives the same hits).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Prepared {
    pub faces: [[DVec3; 3]; 8],
    pub center: DVec3,
    pub radius: f64,
}

impl Prepared {
    pub fn new(v: &[DVec3; 6]) -> Prepared {
        let (center, radius) = bounding_sphere(v);
        Prepared {
            faces: prism_faces(v),
            center,
            radius,
        }
    }

    /// Nearest hit of the eight faces with 0 < t < t_max; `part` is the face index.
    pub fn intersect_ref(&self, ray: &Ray, t_max: f64) -> Option<RefHit> {
        if misses_sphere(self.center, self.radius, ray, t_max) {
            return None;
        }
        self.faces
            .iter()
            .enumerate()
            .filter_map(|(part, f)| {
                triangle::intersect_ref(f, ray, t_max).map(|h| RefHit { part, ..h })
            })
            .min_by(|a, b| a.t.total_cmp(&b.t))
    }
}

impl Prepared {
    /// Surface at a hit of [`Prepared::intersect_ref`] (the same as [`surface_ref`]).
    pub fn surface_ref(&self, hit: &RefHit) -> SurfacePoint {
        triangle::surface_ref(&self.faces[hit.part], hit)
    }
}

/// Nearest hit of the eight faces with 0 < t < t_max; `part` is the face index.
pub fn intersect_ref(v: &[DVec3; 6], ray: &Ray, t_max: f64) -> Option<RefHit> {
    Prepared::new(v).intersect_ref(ray, t_max)
}

/// Surface at a hit of [`intersect_ref`]: the normal of face `part`, pointing out of
/// the prism (refraction needs the unflipped, outward normal).
pub fn surface_ref(v: &[DVec3; 6], hit: &RefHit) -> SurfacePoint {
    triangle::surface_ref(&prism_faces(v)[hit.part], hit)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sphere_cull_never_drops_a_hit() {
        let v = [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(10.0, 0.0, 0.0),
            DVec3::new(5.0, 8.0, 0.0),
            DVec3::new(0.0, 0.0, 20.0),
            DVec3::new(10.0, 0.0, 20.0),
            DVec3::new(5.0, 8.0, 20.0),
        ];
        let mut hits = 0;
        for k in 0..20_000u64 {
            let h = |i: u64| {
                crate::render::spectral::unit_from_hash(crate::render::spectral::hash_keys(&[k, i]))
            };
            let o = DVec3::new(h(0) * 60.0 - 25.0, h(1) * 60.0 - 25.0, h(2) * 60.0 - 20.0);
            let target = DVec3::new(h(3) * 12.0 - 1.0, h(4) * 10.0 - 1.0, h(5) * 22.0 - 1.0);
            let ray = Ray::new(o, (target - o).normalize());
            let brute = prism_faces(&v)
                .iter()
                .filter_map(|f| triangle::intersect_ref(f, &ray, f64::INFINITY))
                .map(|h| h.t)
                .fold(f64::INFINITY, f64::min);
            let got = intersect_ref(&v, &ray, f64::INFINITY).map_or(f64::INFINITY, |h| h.t);
            assert_eq!(got, brute, "ray {k}");
            hits += got.is_finite() as u32;
        }
        assert!(hits > 5000, "{hits}");
    }
}
