//! Render profiles: named choices of code path and knobs, picked once per frame.
//!
//! Profiles: `fast` (the default: the packet path) and `reference` (the oracle).
//! Today a profile is only its path; `profiles/*.toml` (knobs: precision, ray offsets,
//! samples, ...) extends this.

use super::{RenderSettings, Rendered};
use crate::scene::Scene;

/// Which renderer traces the frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RenderPath {
    /// f64, one ray at a time, every object tested: the oracle.
    Reference,
    /// f32, 8-ray packets through a binned-SAH BVH: the fast path.
    Packet,
}

/// A named profile.
#[derive(Clone, Debug, PartialEq)]
pub struct Profile {
    pub name: String,
    pub path: RenderPath,
}

impl Profile {
    /// Names accepted by [`Profile::by_name`].
    pub const NAMES: &'static [&'static str] = &["fast", "reference"];

    /// The profile used when none is named.
    pub fn default_name() -> &'static str {
        "fast"
    }

    pub fn by_name(name: &str) -> Option<Profile> {
        let path = match name {
            "reference" => RenderPath::Reference,
            "fast" => RenderPath::Packet,
            _ => return None,
        };
        Some(Profile {
            name: name.to_string(),
            path,
        })
    }

    /// Renders one frame on this profile's path.
    pub fn render(&self, scene: &Scene, settings: &RenderSettings) -> Rendered {
        match self.path {
            RenderPath::Reference => super::reference::render(scene, settings),
            // The packet path has no refraction: scenes with glass go to the reference.
            RenderPath::Packet if scene.has_prisms() => super::reference::render(scene, settings),
            RenderPath::Packet => super::packet::render(scene, settings),
        }
    }
}
