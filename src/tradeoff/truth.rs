//! The true picture: each pixel's area average, which anti-aliasing approaches and the
//! one-sample image of the spec does not. Estimated by the reference path (f64) with a
//! dense stratified grid, linear (not quantized), and cached on disk as a PFM file named
//! by a digest of everything it depends on (scene, size, camera, grid, photons).

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use crate::farm::digest::scene_hash;
use glam::DVec3;

use crate::output::Framebuffer;
use crate::render::caustic::CausticSettings;
use crate::render::frame::{PixelRect, Run, Sampler, render_frame};
use crate::render::profile::Profile;
use crate::render::reference::Reference;
use crate::scene::{Camera, Scene};

/// Samples per pixel along each axis of the true picture by default: 16 × 16, no position
/// shared with the grids of 2, 4 or 8 per axis that profiles use (the picture would
/// then agree with their refined pixels by construction).
pub const TRUTH_SAMPLES: u32 = 16;

/// Part of every digest: change it when the reference's picture changes, so that old
/// cached pictures are no longer found.
const FORMAT: &str = "octaray true picture 1";

/// A true picture: linear colour per pixel, row-major.
#[derive(Clone, Debug, PartialEq)]
pub struct Truth {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<DVec3>,
}

/// What identifies a true picture, and its grid.
#[derive(Clone, Debug)]
pub struct TruthKey<'a> {
    pub scene: &'a Scene,
    pub camera: Camera,
    pub width: u32,
    pub height: u32,
    /// Samples per pixel along each axis.
    pub samples: u32,
}

impl TruthKey<'_> {
    /// The caustic photons of the picture: the reference profile's.
    fn photons(&self) -> u32 {
        Profile::by_name("reference").expect("built in").photons
    }

    /// A digest (32 hex digits) of everything the picture depends on: the scene as
    /// parsed, bit for bit (the farm's scene hash), then the camera, size, grid and photons.
    pub fn digest(&self) -> String {
        let mut h = scene_hash(self.scene);
        // Debug prints every f64 exactly (shortest round trip)
        h.write(
            format!(
                "{FORMAT}\n{:?}\n{}x{} {} {}",
                self.camera,
                self.width,
                self.height,
                self.samples,
                self.photons()
            )
            .as_bytes(),
        );
        format!("{:032x}", h.finish())
    }

    /// Renders the picture (on every core; a progress bar where stderr is a terminal).
    pub fn render(&self) -> Truth {
        let caustic = CausticSettings {
            photons: self.photons(),
            ..CausticSettings::default()
        };
        let tracer = Reference::with_caustics(self.scene, &caustic);
        let (w, h) = (self.width, self.height);
        let mut pixels = vec![DVec3::ZERO; w as usize * h as usize];
        let run = Run {
            threads: None,
            progress: true,
        };
        let sampler = Sampler::Uniform { n: self.samples };
        let rect = PixelRect::full(w, h);
        render_frame(&tracer, &self.camera, w, h, rect, sampler, &mut pixels, run);
        Truth {
            width: w,
            height: h,
            pixels,
        }
    }
}

/// Where true pictures are cached when the user names no directory:
/// `$XDG_CACHE_HOME/octaray/truth`, else `~/.cache/octaray/truth` ([`crate::cache::root`]),
/// else `target/octaray-truth` under the current directory.
pub fn default_cache_dir() -> PathBuf {
    crate::cache::root().map_or_else(
        || PathBuf::from("target").join("octaray-truth"),
        |root| root.join("truth"),
    )
}

/// How a true picture was obtained.
#[derive(Clone, Debug)]
pub enum Source {
    /// Read from this file.
    Cached(PathBuf),
    /// Rendered in this time, then written to this file (`None`: it could not be, why).
    Rendered(Duration, Result<PathBuf, String>),
}

/// The true picture of `key`: from `dir` if it holds it, else rendered and stored there.
pub fn load_or_render(key: &TruthKey, dir: &Path) -> (Truth, Source) {
    let path = dir.join(format!("{}.pfm", key.digest()));
    if let Ok(bytes) = std::fs::read(&path)
        && let Some(t) = read_pfm(&bytes).filter(|t| (t.width, t.height) == (key.width, key.height))
    {
        return (t, Source::Cached(path));
    }
    let start = Instant::now();
    let truth = key.render();
    let took = start.elapsed();
    let stored = std::fs::create_dir_all(dir)
        .map_err(|e| e.to_string())
        .and_then(|_| {
            crate::output::write_atomic(&path, &write_pfm(&truth)).map_err(|e| e.to_string())
        })
        .map(|_| path);
    (truth, Source::Rendered(took, stored))
}

/// The Portable Float Map of `t` (colour, little-endian f32, rows bottom to top).
pub fn write_pfm(t: &Truth) -> Vec<u8> {
    let mut out = format!("PF\n{} {}\n-1.0\n", t.width, t.height).into_bytes();
    out.reserve(t.pixels.len() * 12);
    for row in t.pixels.chunks(t.width.max(1) as usize).rev() {
        for p in row {
            for v in p.to_array() {
                out.extend_from_slice(&(v as f32).to_le_bytes());
            }
        }
    }
    out
}

/// Reads what [`write_pfm`] wrote; `None` for anything else.
pub fn read_pfm(bytes: &[u8]) -> Option<Truth> {
    // three text lines, then the floats
    let mut fields = Vec::new();
    let mut at = 0;
    for _ in 0..3 {
        let end = at + bytes.get(at..)?.iter().position(|&b| b == b'\n')?;
        fields.push(std::str::from_utf8(&bytes[at..end]).ok()?);
        at = end + 1;
    }
    let (w, h) = fields[1].split_once(' ')?;
    let (w, h): (u32, u32) = (w.parse().ok()?, h.parse().ok()?);
    if fields[0] != "PF" || fields[2] != "-1.0" {
        return None;
    }
    let data = &bytes[at..];
    let n = (w as usize).checked_mul(h as usize)?;
    if data.len() != n.checked_mul(12)? {
        return None;
    }
    let f =
        |i: usize| f32::from_le_bytes(data[4 * i..4 * i + 4].try_into().expect("4 bytes")) as f64;
    let mut pixels = vec![DVec3::ZERO; n];
    for (k, p) in pixels.iter_mut().enumerate() {
        // file row r from the bottom is image row h - 1 - r
        let (x, y) = (k % w as usize, k / w as usize);
        let i = ((h as usize - 1 - y) * w as usize + x) * 3;
        *p = DVec3::new(f(i), f(i + 1), f(i + 2));
    }
    Some(Truth {
        width: w,
        height: h,
        pixels,
    })
}

/// An 8-bit image against the true picture.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TruthError {
    /// Over the three channels, in dB (peak 255).
    pub psnr_db: f64,
    /// Largest channel error, in 1/255.
    pub max: f64,
    /// Percentage of pixels off by more than 8/255 in some channel.
    pub over8_pct: f64,
}

/// Compares `image` (quantized) with `truth` (linear, scaled to 255).
pub fn error(image: &Framebuffer, truth: &Truth) -> TruthError {
    assert_eq!(
        (image.width, image.height),
        (truth.width, truth.height),
        "image and true picture of different sizes"
    );
    let (mut sq, mut max, mut over8) = (0.0, 0.0f64, 0usize);
    for (p, t) in image.pixels.iter().zip(&truth.pixels) {
        let mut worst = 0.0f64;
        for (c, v) in t.to_array().into_iter().enumerate() {
            let e = (p[c] as f64 - 255.0 * v.clamp(0.0, 1.0)).abs();
            sq += e * e;
            worst = worst.max(e);
        }
        max = max.max(worst);
        over8 += usize::from(worst > 8.0);
    }
    let n = image.pixels.len().max(1) as f64;
    let mse = sq / (3.0 * n);
    TruthError {
        psnr_db: if mse == 0.0 {
            f64::INFINITY
        } else {
            10.0 * (255.0 * 255.0 / mse).log10()
        },
        max,
        over8_pct: 100.0 * over8 as f64 / n,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn picture() -> Truth {
        Truth {
            width: 3,
            height: 2,
            pixels: (0..6)
                .map(|i| DVec3::new(i as f64 / 7.0, 0.25, 1.0 - i as f64 / 9.0))
                .collect(),
        }
    }

    #[test]
    fn pfm_round_trips_and_refuses_other_bytes() {
        let t = picture();
        let back = read_pfm(&write_pfm(&t)).expect("reads its own file");
        assert_eq!((back.width, back.height), (3, 2));
        for (a, b) in back.pixels.iter().zip(&t.pixels) {
            assert!((*a - *b).abs().max_element() < 1e-7, "{a} {b}");
        }
        let bytes = write_pfm(&t);
        assert!(read_pfm(&bytes[..bytes.len() - 1]).is_none());
        assert!(read_pfm(b"P6\n3 2\n255\n").is_none());
    }

    #[test]
    fn error_is_measured_against_the_unquantized_picture() {
        let t = Truth {
            width: 2,
            height: 1,
            pixels: vec![DVec3::splat(0.5), DVec3::new(0.0, 0.0, 1.0)],
        };
        let img = Framebuffer {
            width: 2,
            height: 1,
            pixels: vec![[128, 128, 128], [10, 0, 255]],
        };
        let e = error(&img, &t);
        // 0.5 is 127.5: every channel of pixel 0 is off by half a level
        assert!((e.max - 10.0).abs() < 1e-12, "{e:?}");
        assert_eq!(e.over8_pct, 50.0);
        let mse: f64 = (3.0 * 0.25 + 100.0) / 6.0;
        assert!((e.psnr_db - 10.0 * (255.0f64 * 255.0 / mse).log10()).abs() < 1e-9);
    }
}
