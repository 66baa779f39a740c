//! Per-image equivalence of the packet path with the reference.
//!
//! Every scene in `scenes/` and a generated scene of a few thousand mixed primitives
//! are rendered small on both paths and compared. Tolerance: PSNR >= 45 dB, and at most
//! 0.5 % of the pixels off by more than 2/255 outside the masks of legitimate
//! differences (silhouettes: the primary hit's object changes at a neighbour; edges:
//! the reference jumps by more than 24/255 to a neighbour — shadow, cone, tile and
//! reflected edges), where f32 and f64 may fall on different sides of an edge.
//! Scenes with glass (prisms) are held to the same bar: both paths split the same
//! wavelengths per pixel and build their photon maps with the same random numbers.
//! The figures of each image are printed (`cargo test -- --nocapture`).

mod common;

use std::path::Path;

use common::{compare, generated_scene, reference_ids};
use octaray::render::{RenderSettings, packet, reference};
use octaray::scene::Scene;
use octaray::scene::parse::parse_scene_file;

const SIZE: u32 = 96;
const MIN_PSNR_DB: f64 = 45.0;
const MAX_UNMASKED: f64 = 0.005;

fn check(name: &str, scene: &Scene, size: u32) {
    let mut settings = RenderSettings::for_scene(scene);
    settings.width = size;
    settings.height = size;
    let a = reference::render(scene, &settings);
    let b = packet::render(scene, &settings);
    let ids = reference_ids(scene, &settings.camera, size);
    let d = compare(&a.image, &b.image, &ids);
    println!(
        "{name}: {size}² psnr {:.1} dB, max diff {}, off>2: {} ({} in masks, {} outside = {:.3} %)",
        d.psnr_db,
        d.max_diff,
        d.off2,
        d.off2_masked,
        d.off2_unmasked,
        100.0 * d.unmasked_fraction()
    );
    assert!(d.psnr_db >= MIN_PSNR_DB, "{name}: PSNR {:.1} dB", d.psnr_db);
    assert!(
        d.unmasked_fraction() <= MAX_UNMASKED,
        "{name}: {} pixels off by > 2/255 outside the masks",
        d.off2_unmasked
    );
    // same rays traced, up to the rare lane that crosses an edge differently
    assert_eq!(a.stats.primary_rays, b.stats.primary_rays, "{name}");
}

#[test]
fn every_scene_in_scenes_matches_the_reference() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let mut paths: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "txt"))
        .collect();
    paths.sort();
    assert!(!paths.is_empty());
    for p in paths {
        let scene = parse_scene_file(&p).unwrap_or_else(|e| panic!("{e}")).scene;
        let name = p.file_name().unwrap().to_string_lossy().into_owned();
        check(&name, &scene, SIZE);
    }
}

#[test]
fn generated_scene_of_mixed_primitives_matches_the_reference() {
    let scene = generated_scene(3000, 7);
    check("generated 3000", &scene, 64);
}
