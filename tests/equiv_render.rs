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
use glam::DVec3;
use octaray::render::prepared::frame_origin;
use octaray::render::profile::Profile;
use octaray::render::{RenderSettings, Rendered, packet, reference};
use octaray::scene::parse::parse_scene_file;
use octaray::scene::{Camera, Scene};

const SIZE: u32 = 96;
const MIN_PSNR_DB: f64 = 45.0;
const MAX_UNMASKED: f64 = 0.005;

fn check(name: &str, scene: &Scene, size: u32) {
    let mut settings = RenderSettings::for_scene(scene);
    settings.width = size;
    settings.height = size;
    let a = reference::render(scene, &settings);
    let b = packet::render(scene, &settings);
    check_images(name, scene, &settings, &a, &b);
}

/// `b` (a fast render of `scene`) against the reference render `a`, by the bar above.
fn check_images(name: &str, scene: &Scene, settings: &RenderSettings, a: &Rendered, b: &Rendered) {
    let size = settings.width;
    assert_eq!(size, settings.height, "square images only");
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

/// A torus of f32 vertices in an OBJ file, `nu` × `nv` quads split in two (the
/// standard work's generator: benches/embree/gen_data.py), standing on its rim half
/// below the floor; the coordinates written so that they read back as the same f32.
fn torus_obj(nu: usize, nv: usize) -> String {
    use std::f64::consts::TAU;
    use std::fmt::Write as _;
    let mut obj = String::new();
    for i in 0..nu {
        for j in 0..nv {
            let (u, v) = (i as f64 * TAU / nu as f64, j as f64 * TAU / nv as f64);
            let ring = 1.0 + 0.4 * v.cos();
            let p = [ring * u.cos(), 0.4 * v.sin(), ring * u.sin()].map(|c| c as f32 as f64);
            writeln!(obj, "v {} {} {}", p[0], p[1], p[2]).unwrap();
        }
    }
    for i in 0..nu {
        for j in 0..nv {
            let at = |i: usize, j: usize| (i % nu) * nv + j % nv + 1;
            let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
            writeln!(obj, "f {a} {b} {c}\nf {a} {c} {d}").unwrap();
        }
    }
    obj
}

/// A mesh of small triangles loaded from an OBJ file, on the fast profile (its f32 frame
/// at the world origin, where the mesh's f32 vertices stay exact:
/// `render::prepared::frame_origin`) and on the packet path's frame at the eye: both
/// match the reference, which tests every triangle of the mesh for every ray.
#[test]
fn a_mesh_of_small_triangles_matches_the_reference_in_either_frame() {
    let dir = common::Scratch::new("equiv-mesh");
    std::fs::write(dir.join("torus.obj"), torus_obj(80, 32)).unwrap();
    // recursion level 3, one mirror-like torus, one point light above and to the side
    let text = "3 80 1\nmesh torus.obj\n0.8 0.6 0.3  0.2 0.5 0.3 0.3  20\n1\n3 -4 6  1 1 1\n0\n";
    std::fs::write(dir.join("torus.txt"), text).unwrap();
    let scene = parse_scene_file(&dir.join("torus.txt"))
        .unwrap_or_else(|e| panic!("{e}"))
        .scene;
    let mut settings = RenderSettings::for_scene(&scene);
    let up = Camera::default().up;
    settings.camera = Camera::look_at(DVec3::new(0.0, -3.2, 2.2), DVec3::ZERO, up, 50.0).unwrap();
    assert_eq!(
        frame_origin(&scene, settings.camera.eye),
        DVec3::ZERO,
        "the view keeps the mesh's vertices exact"
    );
    // the torus fills a good part of the frame (ids: −1 background, −2 floor, else the
    // object; the mesh is object 0)
    let ids = reference_ids(&scene, &settings.camera, settings.width);
    let on_mesh = ids.iter().filter(|&&id| id == 0).count();
    assert!(
        on_mesh * 5 > ids.len(),
        "{on_mesh} of {} pixels on the mesh",
        ids.len()
    );
    let a = reference::render(&scene, &settings);
    let fast = Profile::by_name("fast").unwrap().render(&scene, &settings);
    check_images("torus mesh, fast profile", &scene, &settings, &a, &fast);
    let at_eye = packet::render(&scene, &settings);
    check_images(
        "torus mesh, frame at the eye",
        &scene,
        &settings,
        &a,
        &at_eye,
    );
}
