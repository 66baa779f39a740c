//! Floating-point error bounds (Higham's γ) and robust secondary-ray origins.
//!
//! A hit point is known only up to an error box; a secondary ray started inside that
//! box can re-hit the surface it leaves. Instead of a fixed epsilon (wrong at both
//! 1e-3 and 1e5 scale), every primitive reports a per-component bound on the error of
//! its hit point, and [`offset_ray_origin`] moves the origin just past that box along
//! the normal, to the side the new ray leaves on (pbrt-v4 `OffsetRayOrigin`).

use glam::DVec3;

/// Unit roundoff of f64 (half an ulp of 1).
pub const EPS_F64: f64 = f64::EPSILON * 0.5;

/// γ(n) = nε / (1 − nε): the relative error bound of n chained f64 operations.
pub const fn gamma(n: u32) -> f64 {
    let ne = n as f64 * EPS_F64;
    ne / (1.0 - ne)
}

/// Moves `p` (with per-component error bound `err`) off its surface along the unit
/// normal `n`, to the side that direction `w` leaves towards, and rounds each moved
/// component away from `p` so the rounding of the sum cannot undo the offset.
pub fn offset_ray_origin(p: DVec3, err: DVec3, n: DVec3, w: DVec3) -> DVec3 {
    let d = n.abs().dot(err);
    let mut offset = n * d;
    if w.dot(n) < 0.0 {
        offset = -offset;
    }
    let mut po = p + offset;
    for i in 0..3 {
        if offset[i] > 0.0 {
            po[i] = po[i].next_up();
        } else if offset[i] < 0.0 {
            po[i] = po[i].next_down();
        }
    }
    po
}

/// `v` scaled to unit length, or `None` when it is zero or not finite. Divided by its
/// largest component first, so that |v|² neither overflows nor underflows: a direction
/// of (0, 0, −1e200) or (0, 0, −1e-200) is a valid one (spec §1 asks only for finite
/// numbers), which `DVec3::try_normalize` rejects.
pub fn unit(v: DVec3) -> Option<DVec3> {
    let m = v.abs().max_element();
    if !(m > 0.0 && m.is_finite()) {
        return None;
    }
    (v / m).try_normalize()
}

/// The largest f32 not above x.
pub fn f32_down(x: f64) -> f32 {
    let f = x as f32;
    if f as f64 > x { f.next_down() } else { f }
}

/// The smallest f32 not below x.
pub fn f32_up(x: f64) -> f32 {
    let f = x as f32;
    if (f as f64) < x { f.next_up() } else { f }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gamma_grows_with_n() {
        assert!(gamma(1) > EPS_F64 && gamma(2) > gamma(1));
        assert!(gamma(3) < 4.0 * EPS_F64);
    }

    #[test]
    fn offset_leaves_on_the_side_of_the_new_direction() {
        let p = DVec3::new(1e5, 0.0, 0.0);
        let err = DVec3::splat(1e-9);
        let out = offset_ray_origin(p, err, DVec3::X, DVec3::new(1.0, 1.0, 0.0));
        let inn = offset_ray_origin(p, err, DVec3::X, DVec3::new(-1.0, 0.0, 0.0));
        assert!(out.x > p.x && inn.x < p.x);
        assert_eq!(out.y, 0.0);
    }
}
