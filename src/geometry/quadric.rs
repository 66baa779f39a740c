//! General quadric: `general A B C D E F G H I J  rx ry rz  length width height`
//! then the material.
//!
//! F(x,y,z) = Ax² + By² + Cz² + Dxy + Exz + Fyz + Gx + Hy + Iz + J = 0, clipped to the box
//! x ∈ [rx, rx+length], y ∈ [ry, ry+width], z ∈ [rz, rz+height]; a dimension of 0 does
//! not clip. Of the two roots the nearer positive one counts if its point is in the
//! box, else the farther positive one if its point is in the box (so a clipped
//! ellipsoid shows its inside). The coefficients were divided by their largest
//! magnitude at load; the normal is ∇F.
//!
//! Along a ray, F(o + t·d) = a·t² + b·t + c with a = Q(d) (the quadratic part),
//! b = ∇F(o)·d and c = F(o).

use glam::DVec3;

use super::SurfacePoint;
use crate::math::Ray;
use crate::math::float::gamma;
use crate::scene::Quadric;

// ---------------------------------------------------------------- reference (f64)

/// The roots of a·t² + b·t + c = 0 in ascending order, computed stably
/// (q = −(b + sign(b)√Δ)/2, roots q/a and c/q); linear when a is exactly 0.
pub fn solve_quadratic(a: f64, b: f64, c: f64) -> Option<(f64, f64)> {
    if a == 0.0 {
        if b == 0.0 {
            return None;
        }
        let t = -c / b;
        return Some((t, t));
    }
    let disc = b.mul_add(b, -4.0 * a * c);
    if disc < 0.0 {
        return None;
    }
    let q = -0.5 * (b + b.signum() * disc.sqrt());
    if q == 0.0 {
        // b = 0 and Δ = 0, so c = 0: a double root at 0.
        return Some((0.0, 0.0));
    }
    let (r0, r1) = (q / a, c / q);
    Some(if r0 <= r1 { (r0, r1) } else { (r1, r0) })
}

/// Nearest t with 0 < t < t_max under the box-clipping root rule.
pub fn intersect_ref(q: &Quadric, ray: &Ray, t_max: f64) -> Option<f64> {
    // the all-zero quadric is never hit
    if q.is_degenerate() {
        return None;
    }
    // coefficients of F along the ray
    let [qa, qb, qc, qd, qe, qf, ..] = q.coef;
    let d = ray.dir;
    let a = qa * d.x * d.x
        + qb * d.y * d.y
        + qc * d.z * d.z
        + qd * d.x * d.y
        + qe * d.x * d.z
        + qf * d.y * d.z;
    let b = q.gradient(ray.origin).dot(d);
    let c = q.value(ray.origin);
    // solve for both roots
    let (t0, t1) = solve_quadratic(a, b, c)?;
    // nearer positive root in the box, else the farther one
    [t0, t1]
        .into_iter()
        .filter(|&t| t > 0.0 && t < t_max)
        .find(|&t| q.in_box(ray.at(t)))
}

/// Surface at distance t. The error bound is measured after the fact: how far the
/// computed point can be from the surface along the normal, |F(p)| plus the rounding
/// error of evaluating F, divided by |∇F|.
pub fn surface_ref(q: &Quadric, ray: &Ray, t: f64) -> SurfacePoint {
    let point = ray.at(t);
    let grad = q.gradient(point);
    let glen = grad.length();
    let normal = if glen > 0.0 && glen.is_finite() {
        grad / glen
    } else {
        -ray.dir // singular point (a cone's apex): no normal; face the ray
    };
    let [a, b, c, d, e, f, g, h, i, j] = q.coef;
    let (x, y, z) = (point.x, point.y, point.z);
    let magnitude = (a * x * x).abs()
        + (b * y * y).abs()
        + (c * z * z).abs()
        + (d * x * y).abs()
        + (e * x * z).abs()
        + (f * y * z).abs()
        + (g * x).abs()
        + (h * y).abs()
        + (i * z).abs()
        + j.abs();
    let dist = if glen > 0.0 && glen.is_finite() {
        2.0 * (q.value(point).abs() + gamma(12) * magnitude) / glen
    } else {
        gamma(16) * point.abs().max_element()
    };
    let err = DVec3::splat(dist) + point.abs() * gamma(1);
    SurfacePoint { point, normal, err }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quadric(coef: [f64; 10], min: [f64; 3], size: [f64; 3]) -> Quadric {
        Quadric {
            coef,
            min: DVec3::from(min),
            size: DVec3::from(size),
        }
    }

    fn unit_sphere_clipped(size: [f64; 3], min: [f64; 3]) -> Quadric {
        quadric([1., 1., 1., 0., 0., 0., 0., 0., 0., -1.], min, size)
    }

    #[test]
    fn unclipped_sphere_quadric_hits_like_a_sphere() {
        let q = unit_sphere_clipped([0.0; 3], [0.0; 3]);
        let r = Ray::new(DVec3::new(0.0, 0.0, -5.0), DVec3::Z);
        assert_eq!(intersect_ref(&q, &r, f64::INFINITY), Some(4.0));
        let s = surface_ref(&q, &r, 4.0);
        assert!((s.normal - DVec3::NEG_Z).length() < 1e-15);
    }

    #[test]
    fn near_root_outside_box_falls_back_to_far_root() {
        // Keep only z in [0, 1]: a ray from below enters at z = −1 (clipped) and
        // leaves at z = +1 (kept), so it sees the inside of the upper half.
        let q = unit_sphere_clipped([0.0, 0.0, 1.0], [0.0, 0.0, 0.0]);
        let r = Ray::new(DVec3::new(0.0, 0.0, -5.0), DVec3::Z);
        assert_eq!(intersect_ref(&q, &r, f64::INFINITY), Some(6.0));
        // Both roots outside: miss.
        let q = unit_sphere_clipped([0.0, 0.0, 0.5], [0.0, 0.0, 2.0]);
        assert_eq!(intersect_ref(&q, &r, f64::INFINITY), None);
    }

    #[test]
    fn origin_inside_takes_the_positive_root() {
        let q = unit_sphere_clipped([0.0; 3], [0.0; 3]);
        let r = Ray::new(DVec3::new(0.5, 0.0, 0.0), DVec3::X);
        assert_eq!(intersect_ref(&q, &r, f64::INFINITY), Some(0.5));
    }

    #[test]
    fn plane_quadric_is_solved_linearly() {
        // z − 3 = 0 with coefficients A..F zero.
        let q = quadric(
            [0., 0., 0., 0., 0., 0., 0., 0., 1., -3.],
            [0.0; 3],
            [0.0; 3],
        );
        let r = Ray::new(DVec3::ZERO, DVec3::new(0.0, 0.6, 0.8));
        let t = intersect_ref(&q, &r, f64::INFINITY).unwrap();
        assert!((t - 3.75).abs() < 1e-14);
        let s = surface_ref(&q, &r, t);
        assert!((s.normal - DVec3::Z).length() < 1e-15);
    }

    #[test]
    fn cylinder_hit_by_ray_parallel_to_axis_misses_or_hits_cleanly() {
        // x² + y² = 1 around z.
        let q = quadric(
            [1., 1., 0., 0., 0., 0., 0., 0., 0., -1.],
            [0.0; 3],
            [0.0; 3],
        );
        let inside = Ray::new(DVec3::new(0.5, 0.0, -5.0), DVec3::Z);
        assert_eq!(intersect_ref(&q, &inside, f64::INFINITY), None);
        let tilted = Ray::new(
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1e-9, 0.0, 1.0).normalize(),
        );
        let t = intersect_ref(&q, &tilted, f64::INFINITY).unwrap();
        assert!((t / 1e9 - 1.0).abs() < 1e-6, "{t}");
    }

    #[test]
    fn all_zero_quadric_never_hits() {
        let q = quadric([0.0; 10], [0.0; 3], [0.0; 3]);
        let r = Ray::new(DVec3::new(0.0, 0.0, -5.0), DVec3::Z);
        assert_eq!(intersect_ref(&q, &r, f64::INFINITY), None);
    }

    #[test]
    fn tangent_ray_gives_double_root() {
        let q = unit_sphere_clipped([0.0; 3], [0.0; 3]);
        let r = Ray::new(DVec3::new(-5.0, 1.0, 0.0), DVec3::X);
        let t = intersect_ref(&q, &r, f64::INFINITY).unwrap();
        assert!((t - 5.0).abs() < 1e-6);
    }

    #[test]
    fn cone_apex_has_a_finite_normal() {
        // x² + y² − z² = 0; the apex is at the origin.
        let q = quadric(
            [1., 1., -1., 0., 0., 0., 0., 0., 0., 0.],
            [0.0; 3],
            [0.0; 3],
        );
        let r = Ray::new(DVec3::new(0.0, 0.0, -1.0), DVec3::Z);
        let s = surface_ref(&q, &r, 1.0);
        assert!(s.normal.is_finite() && s.err.is_finite());
    }
}
