//! Image comparison against the reference, with masks of legitimate differences.
//!
//! Two 8-bit images differ where f32 and f64 legitimately disagree: at silhouettes (the
//! primary-hit object changes between neighbours) and at edges of the reference image
//! (a channel jumps by more than [`EDGE_JUMP`] to a neighbour: shadow edges, the
//! spotlight cone edge, checker tile edges, reflections of them). A pixel is *masked*
//! if it or one of its 8 neighbours crosses such a boundary. Differences outside the
//! masks are bug candidates.

use super::reference::{Reference, Target};
use crate::math::Ray;
use crate::output::Framebuffer;
use crate::scene::{Camera, Scene};

/// A jump to a neighbour larger than this (in 1/255) marks an edge of the reference.
pub const EDGE_JUMP: u8 = 24;

/// Comparison of an image with the reference.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ImageDiff {
    pub pixels: usize,
    /// Largest channel difference, in 1/255.
    pub max_diff: u8,
    /// Over the three channels; infinite for identical images.
    pub psnr_db: f64,
    /// Pixels off by more than 1/255, 2/255 and 8/255 in some channel.
    pub off1: usize,
    pub off2: usize,
    pub off8: usize,
    /// Of the pixels off by more than 2/255, those inside the masks.
    pub off2_masked: usize,
    /// Pixels off by more than 1/255, 2/255 and 8/255 outside the masks.
    pub off1_unmasked: usize,
    pub off2_unmasked: usize,
    pub off8_unmasked: usize,
}

impl ImageDiff {
    /// Fraction of pixels off by more than 2/255 outside the masks.
    pub fn unmasked_fraction(&self) -> f64 {
        self.off2_unmasked as f64 / self.pixels.max(1) as f64
    }

    /// `count` as a percentage of the pixels.
    pub fn percent(&self, count: usize) -> f64 {
        100.0 * count as f64 / self.pixels.max(1) as f64
    }
}

/// The primary-hit object of each pixel centre on the reference path (−1 background,
/// −2 floor), row-major.
pub fn reference_ids(scene: &Scene, camera: &Camera, width: u32, height: u32) -> Vec<i64> {
    let grid = camera.pixel_grid(width, height);
    // Primary hits only: the photon map of scenes with glass is not needed.
    let tracer = Reference::with_caustics(
        scene,
        &super::caustic::CausticSettings {
            photons: 0,
            ..Default::default()
        },
    );
    let mut ids = Vec::with_capacity(width as usize * height as usize);
    for j in 0..height {
        for i in 0..width {
            let ray = Ray::new(grid.eye, grid.direction(i as f64, j as f64));
            ids.push(match tracer.nearest(&ray, f64::INFINITY) {
                None => -1,
                Some(f) => match f.target {
                    Target::Floor => -2,
                    Target::Object(k) => k as i64,
                },
            });
        }
    }
    ids
}

/// Compares `image` with `reference` (same size); `ids` from [`reference_ids`].
pub fn compare(reference: &Framebuffer, image: &Framebuffer, ids: &[i64]) -> ImageDiff {
    assert_eq!(
        (reference.width, reference.height),
        (image.width, image.height),
        "images of different sizes"
    );
    assert_eq!(
        ids.len(),
        reference.pixels.len(),
        "id buffer of another size"
    );
    let (w, h) = (reference.width as i64, reference.height as i64);
    let mut d = ImageDiff {
        pixels: reference.pixels.len(),
        ..ImageDiff::default()
    };
    let mut sq = 0.0;
    for y in 0..h {
        for x in 0..w {
            let k = (y * w + x) as usize;
            let (a, b) = (reference.pixels[k], image.pixels[k]);
            let diff = (0..3).map(|c| a[c].abs_diff(b[c])).max().unwrap_or(0);
            sq += (0..3)
                .map(|c| (a[c] as f64 - b[c] as f64).powi(2))
                .sum::<f64>();
            d.max_diff = d.max_diff.max(diff);
            if diff <= 1 {
                continue;
            }
            let masked = in_mask(reference, ids, x, y);
            d.off1 += 1;
            d.off1_unmasked += usize::from(!masked);
            if diff > 2 {
                d.off2 += 1;
                d.off2_masked += usize::from(masked);
                d.off2_unmasked += usize::from(!masked);
            }
            if diff > 8 {
                d.off8 += 1;
                d.off8_unmasked += usize::from(!masked);
            }
        }
    }
    let mse = sq / (3.0 * d.pixels.max(1) as f64);
    d.psnr_db = if mse == 0.0 {
        f64::INFINITY
    } else {
        10.0 * (255.0f64 * 255.0 / mse).log10()
    };
    d
}

/// Whether pixel (x, y) touches a silhouette or an edge of the reference image.
fn in_mask(reference: &Framebuffer, ids: &[i64], x: i64, y: i64) -> bool {
    let (w, h) = (reference.width as i64, reference.height as i64);
    let k = (y * w + x) as usize;
    let a = reference.pixels[k];
    for (dx, dy) in [
        (-1, 0),
        (1, 0),
        (0, -1),
        (0, 1),
        (-1, -1),
        (1, 1),
        (-1, 1),
        (1, -1),
    ] {
        let (nx, ny) = (x + dx, y + dy);
        if nx < 0 || ny < 0 || nx >= w || ny >= h {
            continue;
        }
        let n = (ny * w + nx) as usize;
        let jump = (0..3)
            .map(|c| a[c].abs_diff(reference.pixels[n][c]))
            .max()
            .unwrap_or(0);
        if ids[n] != ids[k] || jump > EDGE_JUMP {
            return true;
        }
    }
    false
}
