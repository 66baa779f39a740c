//! An 8-bit RGB image, row 0 at the top: what every renderer produces.
//!
//! Renderers quantize as `round(255 · clamp(c, 0, 1))` in their own precision (f64 on
//! the reference path), so that the reference's bytes are exactly the spec's.

/// `width × height` RGB8 pixels, row-major, row 0 at the top.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Framebuffer {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<[u8; 3]>,
}

impl Framebuffer {
    pub fn new(width: u32, height: u32) -> Framebuffer {
        Framebuffer {
            width,
            height,
            pixels: vec![[0; 3]; width as usize * height as usize],
        }
    }

    pub fn get(&self, x: u32, y: u32) -> [u8; 3] {
        self.pixels[y as usize * self.width as usize + x as usize]
    }

    /// The pixels as packed RGB bytes.
    pub fn as_bytes(&self) -> &[u8] {
        self.pixels.as_flattened()
    }

    /// Reads a BMP or PNG file (for tests and comparisons).
    pub fn load(path: &std::path::Path) -> Result<Framebuffer, image::ImageError> {
        let img = image::open(path)?.to_rgb8();
        let (width, height) = img.dimensions();
        let pixels = img.pixels().map(|p| p.0).collect();
        Ok(Framebuffer {
            width,
            height,
            pixels,
        })
    }
}

/// Quantizes one linear channel the spec's way: round(255 · clamp(c, 0, 1)).
pub fn quantize(c: f64) -> u8 {
    (255.0 * c.clamp(0.0, 1.0)).round() as u8
}
