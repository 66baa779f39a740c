//! Renderers: they turn a [`Scene`] and a camera into a [`Framebuffer`] and know
//! nothing of files or windows.
//!
//! - [`reference`](mod@reference): f64, one ray at a time, every object tested. The oracle.
//! - [`packet`]: f32, 8-ray packets through a BVH. The fast path and the default.
//! - [`frame`]: the one frame loop over a rectangle of pixels, which both run.
//! - [`prepared`]: a profile applied to a scene, picking the renderer once.
//! - [`precision`]: where the packet path's f32 stops resolving a scene.

pub mod caustic;
pub mod diff;
pub mod frame;
pub mod options;
pub mod packet;
pub mod precision;
pub mod prepared;
pub mod profile;
pub mod reference;
pub mod spectral;

use std::time::Duration;

pub use frame::PixelRect;

use crate::output::Framebuffer;
use crate::scene::{Camera, Scene};

/// What to render: image size, camera, the part of the image, and threads.
#[derive(Clone, Debug)]
pub struct RenderSettings {
    pub width: u32,
    pub height: u32,
    pub camera: Camera,
    /// The pixels to render (the image returned is this rectangle); `None`: all.
    pub crop: Option<PixelRect>,
    /// Worker threads; `None` uses rayon's default (one per core).
    pub threads: Option<usize>,
    /// Show a progress bar on stderr (only drawn when stderr is a terminal).
    pub progress: bool,
}

impl RenderSettings {
    /// A `size × size` frame from the default camera, on every core, no progress bar.
    pub fn square(size: u32) -> RenderSettings {
        RenderSettings {
            width: size,
            height: size,
            camera: Camera::default(),
            crop: None,
            threads: None,
            progress: false,
        }
    }

    /// The scene's own size and the default camera.
    pub fn for_scene(scene: &Scene) -> RenderSettings {
        RenderSettings::square(scene.pixels)
    }

    /// The rectangle rendered: the crop, or the whole image.
    pub fn rect(&self) -> PixelRect {
        self.crop
            .unwrap_or_else(|| PixelRect::full(self.width, self.height))
    }

    /// How the frame loop runs.
    pub fn run(&self) -> frame::Run {
        frame::Run {
            threads: self.threads,
            progress: self.progress,
        }
    }
}

/// Counters of a finished frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderStats {
    /// Camera rays.
    pub primary_rays: u64,
    /// Shadow rays (one per light that faces the hit and passes the spot cone).
    pub shadow_rays: u64,
    /// Mirror rays.
    pub reflection_rays: u64,
    /// Rays refracted into or out of glass (one per wavelength after a split).
    pub refraction_rays: u64,
    /// Ray–quadric intersection tests (one per ray and quadric tested; per lane on
    /// the packet path). Zero in a scene without quadrics.
    pub quadric_tests: u64,
    /// Spotlight cone tests (one per shading point and spotlight). Zero without
    /// spotlights.
    pub cone_tests: u64,
    /// BVH node tests (packet path; per packet or per single ray, as the walks count
    /// them). Zero on the reference, which tests every object.
    pub node_tests: u64,
    /// Distance to the nearest thing a camera ray hit (infinite when none did).
    pub nearest_hit: f64,
    pub elapsed: Duration,
}

impl Default for RenderStats {
    fn default() -> Self {
        RenderStats {
            primary_rays: 0,
            shadow_rays: 0,
            reflection_rays: 0,
            refraction_rays: 0,
            quadric_tests: 0,
            cone_tests: 0,
            node_tests: 0,
            nearest_hit: f64::INFINITY,
            elapsed: Duration::ZERO,
        }
    }
}

impl RenderStats {
    pub fn total_rays(&self) -> u64 {
        self.primary_rays + self.shadow_rays + self.reflection_rays + self.refraction_rays
    }

    pub fn add(&mut self, o: &RenderStats) {
        self.primary_rays += o.primary_rays;
        self.shadow_rays += o.shadow_rays;
        self.reflection_rays += o.reflection_rays;
        self.refraction_rays += o.refraction_rays;
        self.quadric_tests += o.quadric_tests;
        self.cone_tests += o.cone_tests;
        self.node_tests += o.node_tests;
        self.nearest_hit = self.nearest_hit.min(o.nearest_hit);
    }
}

/// A finished frame (or the rectangle of it that was asked for) and its counters.
#[derive(Clone)]
pub struct Rendered {
    pub image: Framebuffer,
    /// Where `image` lies in the frame.
    pub rect: PixelRect,
    pub stats: RenderStats,
}

/// A renderer with its settings fixed, as [`prepared::Prepared`] picks it: renders
/// frames (the one dynamic call per frame).
pub trait FrameRenderer: Sync {
    /// A frame of `n × n` stratified samples per pixel.
    fn render(&self, settings: &RenderSettings, n: u32) -> Rendered {
        self.render_sampled(settings, frame::Sampler::Uniform { n })
    }

    /// A frame sampled by `sampler`.
    fn render_sampled(&self, settings: &RenderSettings, sampler: frame::Sampler) -> Rendered;
}

impl<T: frame::SampleTracer> FrameRenderer for T {
    fn render_sampled(&self, settings: &RenderSettings, sampler: frame::Sampler) -> Rendered {
        let start = std::time::Instant::now();
        let rect = settings.rect();
        let mut image = Framebuffer::new(rect.width(), rect.height());
        let (w, h) = (settings.width, settings.height);
        let pixels = &mut image.pixels;
        let run = settings.run();
        let mut stats =
            frame::render_frame(self, &settings.camera, w, h, rect, sampler, pixels, run);
        stats.elapsed = start.elapsed();
        Rendered { image, rect, stats }
    }
}
