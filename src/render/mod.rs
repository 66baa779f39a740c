//! Renderers: they turn a [`Scene`] and a camera into a [`Framebuffer`] and know
//! nothing of files or windows.
//!
//! - [`reference`]: f64, one ray at a time, every object tested. The oracle.
//! - [`packet`]: f32, 8-ray packets through a BVH. The fast path and the default.
//! - [`frame`]: splits a frame into bands of rows over rayon.
//! - [`precision`]: where the packet path's f32 stops resolving a scene.

pub mod caustic;
pub mod diff;
pub mod frame;
pub mod packet;
pub mod precision;
pub mod prepared;
pub mod profile;
pub mod reference;
pub mod spectral;

use std::time::Duration;

use crate::output::Framebuffer;
use crate::scene::{Camera, Scene};

/// What to render: image size, camera and threads.
#[derive(Clone, Debug)]
pub struct RenderSettings {
    pub width: u32,
    pub height: u32,
    pub camera: Camera,
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
            threads: None,
            progress: false,
        }
    }

    /// The scene's own size and the default camera.
    pub fn for_scene(scene: &Scene) -> RenderSettings {
        RenderSettings::square(scene.pixels)
    }
}

/// Counters of a finished frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
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
    pub elapsed: Duration,
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
    }
}

/// A finished frame and its counters.
pub struct Rendered {
    pub image: Framebuffer,
    pub stats: RenderStats,
}
