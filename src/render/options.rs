//! The packet path's options: one immutable value a [`super::packet::PacketRenderer`] is
//! built from (profile knobs `shadow_any_hit`, `ray_offset`, `single_ray_lanes`,
//! `triangle_test`).

use crate::simd::Isa;
use serde::Deserialize;

/// The packet path's ray/triangle test.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TriangleTest {
    /// Woop, Benthin and Wald 2013: no ray passes between two triangles sharing an edge.
    Watertight,
    /// Möller–Trumbore: cheaper, can miss both triangles at a shared edge.
    Moller,
}

/// How secondary rays leave a surface.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(try_from = "String")]
pub enum RayOffset {
    /// Past the hit point's floating-point error bound along the normal (any scale).
    ErrorBound,
    /// A fixed distance along the normal, in scene units (fails at extreme scales).
    Epsilon(f32),
}

/// Packets with at most this many active lanes are traced lane by lane with the
/// single-ray traversal (the default of `single_ray_lanes`).
pub const FALLBACK_LANES: u32 = 1;

/// Everything that picks the packet path's code, fixed when its renderer is built.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PacketOptions {
    /// Shadow rays stop at their first blocker (any hit) rather than searching for
    /// the nearest.
    pub shadow_any_hit: bool,
    /// How secondary rays leave surfaces.
    pub ray_offset: RayOffset,
    /// Packets with at most this many active lanes go ray by ray (0: never).
    pub single_ray_lanes: u32,
    /// The ray/triangle test.
    pub triangle_test: TriangleTest,
    /// The kernels' instruction set: under `avx512` the camera rays of two sample
    /// blocks are traced as one 16-lane packet (the same hits, bit for bit).
    pub isa: Isa,
}

impl Default for PacketOptions {
    /// The defaults, with the process's instruction set ([`Isa::process`]).
    fn default() -> Self {
        PacketOptions {
            shadow_any_hit: true,
            ray_offset: RayOffset::ErrorBound,
            single_ray_lanes: FALLBACK_LANES,
            triangle_test: TriangleTest::Watertight,
            isa: Isa::process(),
        }
    }
}
