//! A profile applied to one scene: the per-scene data built once, any number of frames.
//!
//! The frame-level knobs of a [`Profile`] live here, the same for both paths and each
//! chosen once per frame:
//!
//! - `resolution_scale`: the frame is rendered at the scaled size, then upscaled
//!   (bilinear) to the requested one.
//! - `samples_per_pixel` = n²: the frame is traced on the n×-resolution pixel grid of the
//!   same camera, whose pixel centres are exactly the n × n stratified sub-pixel centres
//!   of the requested pixels; each pixel averages its n² samples in linear [0, 1] and is
//!   quantized once. Chosen over a sub-pixel offset in `RenderSettings` because it needs
//!   no change to either renderer's ray generation and keeps packets of neighbouring
//!   samples coherent; at n = 1 the renderers' own frame loops run, so the reference
//!   image is exactly the spec's.
//! - `max_recursion`: caps the recursion level the renderer is built with.
//! - `photons`: the caustic photon count (scenes with glass only).

use std::sync::OnceLock;
use std::time::Instant;

use glam::DVec3;

use super::caustic::CausticSettings;
use super::frame::render_bands;
use super::packet::{BAND_ROWS, CameraPackets, PacketRenderer};
use super::profile::{Profile, RayOffset, RenderPath, TriangleTest};
use super::reference::Reference;
use super::{RenderSettings, RenderStats, Rendered};
use crate::bvh::Steps;
use crate::math::Ray;
use crate::math::packet::Mask8;
use crate::output::Framebuffer;
use crate::output::framebuffer::quantize;
use crate::scene::Scene;

/// A profile prepared for one scene (see [`Profile::prepare`]).
pub struct Prepared<'a> {
    profile: Profile,
    scene: &'a Scene,
    engine: Engine<'a>,
}

/// The renderer a profile picked for a scene, once.
enum Engine<'a> {
    /// The reference, with its photon map if the scene has glass.
    Reference(Box<Reference<'a>>),
    /// The packet renderer, built at the first frame in an f32 frame centred on that
    /// frame's eye (later frames reuse it from any camera).
    Packet(Box<OnceLock<PacketRenderer>>),
}

impl<'a> Prepared<'a> {
    /// Builds what `profile` needs for `scene`: the reference (and its photon map) now,
    /// the packet BVH at the first frame.
    pub fn new(profile: &Profile, scene: &'a Scene) -> Prepared<'a> {
        let path = profile.path;
        let engine = match path {
            RenderPath::Reference => {
                let caustic = CausticSettings {
                    photons: profile.photons,
                    ..CausticSettings::default()
                };
                let mut r = Reference::with_caustics(scene, &caustic);
                if let Some(cap) = profile.max_recursion {
                    r.cap_recursion(cap);
                }
                Engine::Reference(Box::new(r))
            }
            RenderPath::Packet => Engine::Packet(Box::default()),
        };
        Prepared {
            profile: profile.clone(),
            scene,
            engine,
        }
    }

    /// The profile this was prepared with.
    pub fn profile(&self) -> &Profile {
        &self.profile
    }

    /// The path that renders this scene.
    pub fn path(&self) -> RenderPath {
        match self.engine {
            Engine::Reference(_) => RenderPath::Reference,
            Engine::Packet(_) => RenderPath::Packet,
        }
    }

    /// On the packet path, once a frame has built its renderer: the scene's smallest
    /// object against its distance ([`super::precision`]).
    pub fn smallest_detail(&self) -> Option<super::precision::Detail> {
        let Engine::Packet(cell) = &self.engine else {
            return None;
        };
        cell.get()?.smallest_detail()
    }

    /// [`Prepared::smallest_detail`] where f32 loses it
    /// ([`super::precision::Detail::below_f32`]): the command line warns.
    pub fn detail_below_f32(&self) -> Option<super::precision::Detail> {
        self.smallest_detail().filter(|d| d.below_f32())
    }

    fn packet(&self, eye: DVec3) -> &PacketRenderer {
        let Engine::Packet(cell) = &self.engine else {
            unreachable!("packet() on the reference engine")
        };
        cell.get_or_init(|| {
            let caustic = CausticSettings {
                photons: self.profile.photons,
                ..CausticSettings::default()
            };
            let moller = self.profile.triangle_test == TriangleTest::Moller;
            let mut r = match self.profile.max_recursion {
                Some(cap) if cap < self.scene.recursion_level => {
                    let capped = Scene {
                        recursion_level: cap,
                        ..self.scene.clone()
                    };
                    PacketRenderer::with_options(&capped, eye, &caustic, moller)
                }
                _ => PacketRenderer::with_options(self.scene, eye, &caustic, moller),
            };
            r.fallback_lanes = self.profile.single_ray_lanes;
            r.shadow_any_hit = self.profile.shadow_any_hit;
            r.offset_epsilon = match self.profile.ray_offset {
                RayOffset::ErrorBound => None,
                RayOffset::Epsilon(e) => Some(e),
            };
            r
        })
    }

    /// Renders one frame. `stats.elapsed` covers the frame (and, on the first packet
    /// frame, the BVH build), not the photon pass.
    pub fn render(&self, settings: &RenderSettings) -> Rendered {
        let start = Instant::now();
        let scale = self.profile.resolution_scale;
        let scaled = |v: u32| ((v as f64 * scale).round() as u32).clamp(1, v.max(1));
        let inner = RenderSettings {
            width: scaled(settings.width),
            height: scaled(settings.height),
            ..settings.clone()
        };
        let n = self.profile.samples_per_axis();
        let mut out = match (&self.engine, n) {
            (Engine::Reference(r), 1) => super::reference::render_frame(r, &inner),
            (Engine::Reference(r), n) => reference_supersampled(r, &inner, n),
            (Engine::Packet(_), 1) => self.packet(settings.camera.eye).render(&inner),
            (Engine::Packet(_), n) => {
                let p = self.packet(settings.camera.eye);
                // the packet knobs pick one compiled instance, once per frame
                crate::with_packet_knobs!(p, supersampled(&inner, n))
            }
        };
        if (inner.width, inner.height) != (settings.width, settings.height) {
            out.image = upscale_bilinear(&out.image, settings.width, settings.height);
        }
        out.stats.elapsed = start.elapsed();
        out
    }
}

/// n × n samples per pixel on the reference path: the pixel centres of the n×-resolution
/// grid, each with its own wavelengths should it meet glass.
fn reference_supersampled(tracer: &Reference, settings: &RenderSettings, n: u32) -> Rendered {
    let grid = settings
        .camera
        .pixel_grid(settings.width * n, settings.height * n);
    let inv = 1.0 / (n * n) as f64;
    render_bands(settings, 1, |row, pixels| {
        let mut stats = RenderStats::default();
        for (i, px) in pixels.iter_mut().enumerate() {
            let mut sum = DVec3::ZERO;
            for b in 0..n {
                for a in 0..n {
                    let (x, y) = (i as u32 * n + a, row * n + b);
                    let ray = Ray::new(grid.eye, grid.direction(x as f64, y as f64));
                    sum += tracer.trace_pixel(&ray, x, y, &mut stats);
                }
            }
            let c = sum * inv;
            *px = [quantize(c.x), quantize(c.y), quantize(c.z)];
        }
        stats.primary_rays += (pixels.len() as u64) * (n * n) as u64;
        stats
    })
}

/// n × n samples per pixel on the packet path: 4 × 2 packets over the n×-resolution
/// grid (as `PacketRenderer::render` builds them), summed per pixel in f32.
trait Supersampled {
    fn supersampled<const ANY_HIT: bool, const EPS: bool, const GLASS: bool>(
        &self,
        settings: &RenderSettings,
        n: u32,
    ) -> Rendered;
}

impl Supersampled for PacketRenderer {
    fn supersampled<const ANY_HIT: bool, const EPS: bool, const GLASS: bool>(
        &self,
        settings: &RenderSettings,
        n: u32,
    ) -> Rendered {
        packet_supersampled::<ANY_HIT, EPS, GLASS>(self, settings, n)
    }
}

fn packet_supersampled<const ANY_HIT: bool, const EPS: bool, const GLASS: bool>(
    p: &PacketRenderer,
    settings: &RenderSettings,
    n: u32,
) -> Rendered {
    let (big_w, big_h) = (settings.width * n, settings.height * n);
    let grid = settings.camera.pixel_grid(big_w, big_h);
    let camera = CameraPackets::new(&grid, p.base());
    let width = settings.width as usize;
    let (bw, nn) = (big_w as usize, n as usize);
    let inv = 1.0 / (n * n) as f32;
    render_bands(settings, BAND_ROWS, |first_row, pixels| {
        let mut stats = RenderStats::default();
        let mut steps = Steps::default();
        let mut chain = Vec::new();
        let rows = pixels.len() / width;
        let big_rows = rows * nn;
        let big_first = first_row as usize * nn;
        let mut sum = vec![[0.0f32; 3]; pixels.len()];
        for py in (0..big_rows).step_by(2) {
            for px in (0..bw).step_by(4) {
                let row = big_first + py;
                let bits = CameraPackets::lanes(px, py, bw, big_rows, row, big_h as usize);
                let active = Mask8::from_bits(bits);
                let ray = camera.packet(px, row, active);
                let pixel = [px as u32, row as u32];
                let c = p.trace_knobs::<ANY_HIT, EPS, GLASS>(
                    &ray,
                    active,
                    pixel,
                    Some(&grid),
                    &mut chain,
                    &mut stats,
                    &mut steps,
                );
                stats.primary_rays += active.count() as u64;
                let (r, g, b) = (c.x.to_array(), c.y.to_array(), c.z.to_array());
                for lane in 0..8 {
                    if bits >> lane & 1 == 1 {
                        let (x, y) = (px + lane % 4, py + lane / 4);
                        let s = &mut sum[(y / nn) * width + x / nn];
                        s[0] += r[lane];
                        s[1] += g[lane];
                        s[2] += b[lane];
                    }
                }
            }
        }
        stats.quadric_tests += steps.quadrics;
        for (px, s) in pixels.iter_mut().zip(&sum) {
            *px = s.map(|v| quantize((v * inv) as f64));
        }
        stats
    })
}

/// Bilinear upscale (pixel centres aligned, edges clamped).
pub fn upscale_bilinear(src: &Framebuffer, width: u32, height: u32) -> Framebuffer {
    let mut out = Framebuffer::new(width, height);
    if src.width == 0 || src.height == 0 {
        return out;
    }
    let (sw, sh) = (src.width as usize, src.height as usize);
    let coord = |x: u32, n: u32, sn: usize| {
        let f = ((x as f64 + 0.5) * sn as f64 / n as f64 - 0.5).clamp(0.0, (sn - 1) as f64);
        let i = (f.floor() as usize).min(sn - 1);
        (i, (i + 1).min(sn - 1), f - i as f64)
    };
    let cols: Vec<_> = (0..width).map(|x| coord(x, width, sw)).collect();
    for y in 0..height {
        let (y0, y1, fy) = coord(y, height, sh);
        for (x, &(x0, x1, fx)) in cols.iter().enumerate() {
            let p = |xx: usize, yy: usize| src.pixels[yy * sw + xx];
            let (a, b, c, d) = (p(x0, y0), p(x1, y0), p(x0, y1), p(x1, y1));
            let mut px = [0u8; 3];
            for k in 0..3 {
                let top = a[k] as f64 * (1.0 - fx) + b[k] as f64 * fx;
                let bottom = c[k] as f64 * (1.0 - fx) + d[k] as f64 * fx;
                px[k] = (top * (1.0 - fy) + bottom * fy).round() as u8;
            }
            out.pixels[y as usize * width as usize + x] = px;
        }
    }
    out
}
