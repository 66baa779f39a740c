//! octaray: a CPU ray tracer for the scenes of a classic graphics assignment
//! (spheres, triangles, clipped quadrics, a checkerboard floor, point and spot lights,
//! Phong shading, shadows and recursive reflection).
//!
//! Data flows one way: [`scene`] parses text into plain data, [`render`] turns a scene
//! and a camera into a [`output::Framebuffer`], [`output`] writes it. See
//! ARCHITECTURE.md.
//!
//! The module docs explain the code, private parts included: read them with
//! `cargo doc --document-private-items`.

// (public items' docs link to the private items they rely on)
#![allow(rustdoc::private_intra_doc_links)]

pub mod bvh;
pub mod cache;
pub mod farm;
pub mod geometry;
pub mod math;
pub mod output;
pub mod parallel;
pub mod render;
pub mod scene;
pub mod simd;
pub mod temporaries;
pub mod tradeoff;
pub mod viewer;
