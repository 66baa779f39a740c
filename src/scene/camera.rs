//! The pinhole camera of the assignment (`docs/scene-format.md` section 3).

use glam::DVec3;

use crate::math::float::unit;

/// An orthonormal pinhole camera: `look`, `right`, `up` with right = look × up.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    pub eye: DVec3,
    pub look: DVec3,
    pub right: DVec3,
    pub up: DVec3,
    /// Vertical field of view in degrees.
    pub fov_y_deg: f64,
}

impl Default for Camera {
    /// Eye (100, 100, 50) looking along (−1, −1, 0)/√2 with z up, 80° vertical field of view.
    fn default() -> Self {
        let s = std::f64::consts::FRAC_1_SQRT_2;
        Camera {
            eye: DVec3::new(100.0, 100.0, 50.0),
            look: DVec3::new(-s, -s, 0.0),
            right: DVec3::new(-s, s, 0.0),
            up: DVec3::Z,
            fov_y_deg: 80.0,
        }
    }
}

/// The height of the assignment's virtual window; any value gives the same rays.
const WINDOW_H: f64 = 500.0;

/// Everything needed to generate the primary ray through any pixel of a
/// `width × height` image; computed once per frame.
#[derive(Clone, Copy, Debug)]
pub struct PixelGrid {
    pub eye: DVec3,
    /// Centre of pixel (0, 0), the top-left one.
    pub top_left: DVec3,
    /// Step to the next column.
    pub du: DVec3,
    /// Step to the next row (downwards).
    pub dv: DVec3,
}

impl PixelGrid {
    /// The point pixel (i + fx − ½, j + fy − ½) looks through; (fx, fy) = (½, ½) is the
    /// pixel centre of the spec.
    pub fn point(&self, i: f64, j: f64) -> DVec3 {
        self.top_left + self.du * i + self.dv * j
    }

    /// Normalised direction of the ray through pixel (i, j) (fractional for subpixels).
    pub fn direction(&self, i: f64, j: f64) -> DVec3 {
        (self.point(i, j) - self.eye).normalize()
    }
}

impl Camera {
    /// A camera at `eye` looking at `target` with the given up hint. `None` when the
    /// view direction is zero or parallel to `up`.
    pub fn look_at(eye: DVec3, target: DVec3, up: DVec3, fov_y_deg: f64) -> Option<Camera> {
        let look = unit(target - eye)?;
        Camera::from_look(eye, look, up, fov_y_deg)
    }

    /// A camera at `eye` looking along `look`; `up` is made orthogonal to it.
    pub fn from_look(eye: DVec3, look: DVec3, up: DVec3, fov_y_deg: f64) -> Option<Camera> {
        let look = unit(look)?;
        let right = unit(look.cross(unit(up)?))?;
        let up = right.cross(look);
        Some(Camera {
            eye,
            look,
            right,
            up,
            fov_y_deg,
        })
    }

    /// The pixel grid of the spec: for a square image exactly
    /// `topleft = eye + l·d − r·W/2 + u·H/2 + r·du/2 − u·dv/2` with W = H = 500.
    /// For a non-square image the window is widened to keep pixels square.
    pub fn pixel_grid(&self, width: u32, height: u32) -> PixelGrid {
        let h = WINDOW_H;
        let w = WINDOW_H * width as f64 / height as f64;
        let d = (h / 2.0) / (self.fov_y_deg.to_radians() / 2.0).tan();
        let du = w / width as f64;
        let dv = h / height as f64;
        let top_left = self.eye + self.look * d - self.right * (w / 2.0)
            + self.up * (h / 2.0)
            + self.right * (du / 2.0)
            - self.up * (dv / 2.0);
        PixelGrid {
            eye: self.eye,
            top_left,
            du: self.right * du,
            dv: -self.up * dv,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_camera_is_right_handed_and_orthonormal() {
        let c = Camera::default();
        assert!((c.look.cross(c.up) - c.right).length() < 1e-15);
        assert!(c.look.dot(c.right).abs() < 1e-15);
        assert!((c.look.length() - 1.0).abs() < 1e-15);
    }

    #[test]
    fn centre_pixel_of_odd_image_looks_straight_ahead() {
        let c = Camera::default();
        let g = c.pixel_grid(101, 101);
        let d = g.direction(50.0, 50.0);
        assert!((d - c.look).length() < 1e-12, "{d}");
        // Top-left pixel looks up and to the left (−right, +up).
        let tl = g.direction(0.0, 0.0);
        assert!(tl.dot(c.right) < 0.0 && tl.dot(c.up) > 0.0);
    }

    #[test]
    fn vertical_fov_spans_the_image_height() {
        let c = Camera::default();
        let n = 1000;
        let g = c.pixel_grid(n, n);
        // The outer edge of the top row is half a pixel above its centre.
        let top_edge = (g.point(n as f64 / 2.0 - 0.5, -0.5) - c.eye).normalize();
        let angle = top_edge.dot(c.look).acos().to_degrees();
        assert!((angle - 40.0).abs() < 1e-9, "{angle}");
    }

    #[test]
    fn look_at_matches_default_camera_direction() {
        let d = Camera::default();
        let c = Camera::look_at(d.eye, d.eye + d.look * 3.0, DVec3::Z, 80.0).unwrap();
        assert!((c.right - d.right).length() < 1e-15);
        assert!((c.up - d.up).length() < 1e-15);
        assert!(Camera::look_at(d.eye, d.eye + DVec3::Z, DVec3::Z, 80.0).is_none());
    }
}
