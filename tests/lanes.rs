//! The 16-lane packets (`avx512`), and four of them walking the tree as one, against
//! the 8-lane ones, ray by ray: the same hit distance, bit for bit, and the same shadow
//! answer, on a mesh and on a scene of every primitive kind (whose spheres, quadrics
//! and floor the 16-lane walk hands to the 8-lane kernels half by half). On a CPU
//! without AVX-512 the choice of instruction set is checked instead: `avx512` is
//! refused and `auto` is `avx2`.

mod common;

use common::{Rng, generated_scene};
use glam::{DVec3, Vec3};
use octaray::bvh::bench::{
    Mode, RaySet, TILE_QUADRANTS, incoherent_rays, primary_rays, shadow_rays, torus, trace,
    trace_occluded,
};
use octaray::bvh::{Bvh, Steps};
use octaray::geometry::PrimSet;
use octaray::simd::Isa;
use octaray::simd::isa::IsaError;

/// The 16-lane mode, where this CPU runs it.
fn mode16() -> Option<Mode> {
    Isa::avx512()
        .and_then(|i| i.avx512_kernels())
        .map(Mode::Packet16)
}

/// The mode of 64 rays as four 16-lane packets, beside the 16-lane one.
fn mode64(m16: Mode) -> Mode {
    match m16 {
        Mode::Packet16(token) => Mode::Packet64(token),
        other => panic!("not the 16-lane mode: {other:?}"),
    }
}

/// Traces `rays` at 8 and 16 lanes and 64 rays at a time; asserts every ray's t is the
/// same bits and every shadow ray the same answer; returns the node tests of the
/// three.
fn same_per_ray(name: &str, bvh: &Bvh, rays: &RaySet, m16: Mode) -> (Steps, Steps, Steps) {
    let n = rays.origin.len();
    let (mut t8, mut t16, mut t64) = (vec![0.0f32; n], vec![0.0f32; n], vec![0.0f32; n]);
    let s8 = trace(bvh, rays, Mode::Packet8, &mut t8);
    let s16 = trace(bvh, rays, m16, &mut t16);
    let s64 = trace(bvh, rays, mode64(m16), &mut t64);
    let hits = t8.iter().filter(|t| **t >= 0.0).count();
    assert!(
        hits > n / 10,
        "{name}: too few hits ({hits} of {n}) to compare"
    );
    for (i, ((a, b), c)) in t8.iter().zip(&t16).zip(&t64).enumerate() {
        assert_eq!(
            a.to_bits(),
            b.to_bits(),
            "{name}: ray {i}: t {a} (8 lanes) vs {b} (16)"
        );
        assert_eq!(
            a.to_bits(),
            c.to_bits(),
            "{name}: ray {i}: t {a} (8 lanes) vs {c} (64 at a time)"
        );
    }
    let set = shadow_rays(rays.clone(), t8);
    let (mut b8, mut b16) = (vec![0u8; n], vec![0u8; n]);
    trace_occluded(bvh, &set, Mode::Packet8, &mut b8);
    trace_occluded(bvh, &set, m16, &mut b16);
    let blocked = b8.iter().filter(|b| **b == 1).count();
    assert!(
        blocked > 0 && blocked < hits,
        "{name}: shadow rays must go both ways"
    );
    for (i, (a, b)) in b8.iter().zip(&b16).enumerate() {
        assert_eq!(a, b, "{name}: shadow ray {i}: {a} (8 lanes) vs {b} (16)");
    }
    (s8, s16, s64)
}

#[test]
fn sixteen_lanes_give_every_ray_what_eight_give_it_on_a_mesh() {
    let Some(m16) = mode16() else {
        assert_eq!(Isa::detect(), Isa::AVX2);
        assert_eq!(Isa::parse("avx512"), Err(IsaError::Unsupported("avx512")));
        return;
    };
    let bvh = Bvh::build(PrimSet::from_triangles(torus(120, 60)));
    let (s8, s16, s64) = same_per_ray("primary", &bvh, &primary_rays(512, 512), m16);
    // the 16-lane frustum walk ran (not the halves): one node test serves 16 rays
    assert!(
        (s16.boxes as f64) < 0.75 * s8.boxes as f64,
        "node tests: {} at 16 lanes vs {} at 8",
        s16.boxes,
        s8.boxes
    );
    // and four packets walked as one: one node test serves 64 rays, each leaf is
    // tested by each packet as before
    assert!(
        (s64.boxes as f64) < 0.5 * s16.boxes as f64,
        "node tests: {} 64 at a time vs {} at 16 lanes",
        s64.boxes,
        s16.boxes
    );
    // incoherent packets: each lane's own walk at either width (closest hit: 16 or 8
    // stepped in turn; any hit: one after another), so the same node and triangle tests
    let (s8, s16, s64) = same_per_ray("incoherent", &bvh, &incoherent_rays(1 << 14, 3), m16);
    assert_eq!(s8, s16, "incoherent: 8 lanes vs 16");
    assert_eq!(s16, s64, "incoherent: 16 lanes vs 64 at a time");
}

/// The 64-ray walk on packets that do not share one origin: each of its 16-ray packets
/// (a quadrant of an 8 × 8 tile of the camera rays, `TILE_QUADRANTS`) moved by its own
/// offset (the union's origin bounds then differ from every packet's), then every ray
/// by its own; and a ray count that leaves a last group of 40 rays (a packet of 8 and
/// two of none).
#[test]
fn sixty_four_at_a_time_give_every_ray_what_eight_give_it_from_spread_origins() {
    let Some(m16) = mode16() else {
        return;
    };
    let bvh = Bvh::build(PrimSet::from_triangles(torus(120, 60)));
    let camera = primary_rays(512, 512);
    let mut rng = Rng(17);
    let mut by_packet = camera.clone();
    for tile in by_packet.origin.chunks_mut(64) {
        for (a, c) in TILE_QUADRANTS {
            // 0.03 to 0.06 either way on each axis
            let mut off = || rng.range(0.03, 0.06) * if rng.f64() < 0.5 { -1.0 } else { 1.0 };
            let shift = DVec3::new(off(), off(), off()).as_vec3();
            for i in (a..a + 8).chain(c..c + 8) {
                tile[i] += shift;
            }
        }
    }
    let (_, s16, s64) = same_per_ray("origins by packet", &bvh, &by_packet, m16);
    assert!(
        s64.boxes < s16.boxes,
        "origins by packet: the 64-ray walk ran"
    );
    let mut by_ray = camera.clone();
    for o in &mut by_ray.origin {
        *o += rng
            .vec_in(DVec3::splat(-0.01), DVec3::splat(0.01))
            .as_vec3();
    }
    let (_, s16, s64) = same_per_ray("origins by ray", &bvh, &by_ray, m16);
    assert!(s64.boxes < s16.boxes, "origins by ray: the 64-ray walk ran");
    let mut short = camera;
    let n = short.origin.len() - 24;
    short.origin.truncate(n);
    short.dir.truncate(n);
    assert_eq!(n % 64, 40);
    same_per_ray("a short last group", &bvh, &short, m16);
}

/// A 16-lane packet whose halves are each one coherent frustum but of different
/// direction signs (a block across the image's centre column) goes half by half, each
/// half as one frustum: the node tests of the 8-lane packets, not of 16 single rays.
#[test]
fn halves_of_different_signs_each_go_as_one_frustum() {
    let Some(m16) = mode16() else {
        return;
    };
    let bvh = Bvh::build(PrimSet::from_triangles(torus(120, 60)));
    let (mut origin, mut dir) = (Vec::new(), Vec::new());
    for row in 0..64 {
        let y = (row as f32 - 32.0) * 0.004;
        for sign in [1.0f32, -1.0] {
            for i in 0..8 {
                origin.push(Vec3::new(0.0, y, -4.0));
                let x = sign * (0.0005 + 0.001 * i as f32);
                dir.push(Vec3::new(x, 0.0, 1.0).normalize());
            }
        }
    }
    let rays = RaySet {
        name: "centre column",
        origin,
        dir,
    };
    let n = rays.origin.len();
    let (mut t8, mut t16) = (vec![0.0f32; n], vec![0.0f32; n]);
    let s8 = trace(&bvh, &rays, Mode::Packet8, &mut t8);
    let s16 = trace(&bvh, &rays, m16, &mut t16);
    assert!(
        t8.iter().filter(|t| **t >= 0.0).count() > n / 2,
        "the rays meet the torus"
    );
    let bits = |t: &[f32]| t.iter().map(|t| t.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&t8), bits(&t16));
    assert_eq!(s8, s16, "centre column: node tests at 8 lanes vs 16");
}

#[test]
fn sixteen_lanes_give_every_ray_what_eight_give_it_on_every_primitive_kind() {
    let Some(m16) = mode16() else {
        assert_eq!(Isa::parse("auto"), Ok(Isa::AVX2));
        return;
    };
    let scene = generated_scene(400, 5);
    let bvh = Bvh::build(PrimSet::from_scene(&scene, DVec3::new(0.0, 0.0, 20.0)));
    let p = &bvh.prims;
    assert!(!p.spheres.is_empty() && !p.quadrics.is_empty() && p.floor.is_some());
    // coherent rays from a few eyes (rows of 64, 16 consecutive rays a strip of one
    // row), then scattered ones
    let mut rng = Rng(9);
    let (mut origin, mut dir) = (Vec::new(), Vec::new());
    for _ in 0..6 {
        let eye = Vec3::new(
            rng.range(-60.0, 40.0) as f32,
            rng.range(-60.0, 40.0) as f32,
            rng.range(30.0, 60.0) as f32,
        );
        let centre = (rng.unit() * 0.3 - DVec3::Z).normalize();
        let (right, up) = (
            centre.cross(DVec3::Y).normalize(),
            centre.cross(DVec3::Y).normalize().cross(centre),
        );
        for y in 0..64 {
            for x in 0..64 {
                // 0.5 mrad a pixel: 16 neighbours are one frustum
                let (u, v) = ((x as f64 - 32.0) / 2048.0, (y as f64 - 32.0) / 2048.0);
                origin.push(eye);
                dir.push((centre + right * u + up * v).normalize().as_vec3());
            }
        }
    }
    for _ in 0..8192 {
        origin.push(
            rng.vec_in(DVec3::new(-80.0, -80.0, 0.0), DVec3::new(60.0, 60.0, 40.0))
                .as_vec3(),
        );
        dir.push(rng.unit().as_vec3());
    }
    let rays = RaySet {
        name: "mixed",
        origin,
        dir,
    };
    let (s8, s16, s64) = same_per_ray("mixed", &bvh, &rays, m16);
    assert!(
        s64.boxes < s16.boxes,
        "node tests: {} 64 at a time vs {} at 16 lanes",
        s64.boxes,
        s16.boxes
    );
    assert!(
        s16.boxes < s8.boxes,
        "node tests: {} at 16 lanes vs {} at 8",
        s16.boxes,
        s8.boxes
    );
}

#[test]
fn the_instruction_set_is_parsed_and_refused_by_name() {
    assert_eq!(Isa::parse("avx2"), Ok(Isa::AVX2));
    assert_eq!(Isa::parse(" auto "), Ok(Isa::detect()));
    assert_eq!(Isa::parse("avx512").ok(), Isa::avx512());
    assert!(matches!(Isa::parse("sse9"), Err(IsaError::Unknown(s)) if s == "sse9"));
    assert_eq!(Isa::AVX2.avx512_kernels(), None);
    assert_eq!((Isa::AVX2.name(), Isa::AVX2.lanes()), ("avx2", 8));
}

#[test]
fn a_bad_instruction_set_is_an_input_error_naming_its_source() {
    let exe = env!("CARGO_BIN_EXE_octaray");
    let run = |args: &[&str], env: Option<&str>| {
        let mut c = std::process::Command::new(exe);
        c.args(args).env_remove("OCTARAY_ISA");
        if let Some(v) = env {
            c.env("OCTARAY_ISA", v);
        }
        c.output().expect("octaray runs")
    };
    let out = run(&["bench-trace", "no-such.obj", "--isa", "sse9"], None);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("--isa") && err.contains("sse9"), "{err}");
    // the viewer too, before any window opens
    let out = run(&["view", "--frames", "1", "--isa", "sse9"], None);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("--isa") && err.contains("sse9"), "{err}");
    let out = run(&["bench-trace", "no-such.obj"], Some("neon"));
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("OCTARAY_ISA") && err.contains("neon"), "{err}");
}

/// `bench-trace --rays DIR` checks the Embree harness's ray files before it loads the
/// mesh: a missing one is an input error naming the file.
#[test]
fn a_missing_ray_file_is_an_input_error_naming_it() {
    let dir = std::env::temp_dir().join(format!("octaray-no-rays-{}", std::process::id()));
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_octaray"))
        .args(["bench-trace", "no-such.obj", "--rays"])
        .arg(&dir)
        .env_remove("OCTARAY_ISA")
        .output()
        .expect("octaray runs");
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    let file = dir.join("primary.rays");
    assert!(err.contains(&*file.to_string_lossy()), "{err}");
    assert!(
        err.contains("cannot open") && !err.contains("panick"),
        "{err}"
    );
}

/// Every built-in packet profile renders the same bytes under `avx2` and `avx512` (the
/// camera rays of two blocks as one 16-lane packet), on a scene of every kind large
/// enough for the frustum walk, whole and in a crop, and on a mesh close up.
#[test]
fn the_image_is_the_same_under_every_instruction_set() {
    use octaray::render::profile::Profile;
    use octaray::render::{PixelRect, RenderSettings};
    use octaray::scene::Camera;
    let Some(avx512) = Isa::avx512() else {
        assert_eq!(Isa::detect(), Isa::AVX2);
        return;
    };
    let mixed = generated_scene(400, 5);
    let torus = {
        let mut s = generated_scene(1, 1);
        let (mut vertices, mut triangles) = (Vec::new(), Vec::new());
        for t in torus(64, 32) {
            let k = vertices.len() as u32;
            vertices.extend(t.v.map(|p| p.as_dvec3() * 10.0 + DVec3::new(0.0, 0.0, 15.0)));
            triangles.push([k, k + 1, k + 2]);
        }
        let mesh = octaray::scene::obj::Mesh::new(vertices, triangles);
        s.objects[0].shape = octaray::scene::Shape::Mesh(std::sync::Arc::new(mesh));
        s
    };
    // narrow views: a block of 8 × 2 pixels spans less than the frustum walk's limit
    let look = |eye: DVec3, at: DVec3| Camera::look_at(eye, at, DVec3::Z, 6.0).expect("a camera");
    let cameras = [
        (
            &mixed,
            look(
                DVec3::new(100.0, 100.0, 50.0),
                DVec3::new(-10.0, -10.0, 10.0),
            ),
        ),
        (
            &torus,
            look(DVec3::new(0.0, -40.0, 30.0), DVec3::new(10.0, 0.0, 15.0)),
        ),
    ];
    for name in ["fast", "preview", "quality"] {
        let profile = Profile::by_name(name).expect("built in");
        for (scene, camera) in &cameras {
            let mut settings = RenderSettings::square(96);
            settings.camera = *camera;
            let image = |isa: Isa, crop: Option<PixelRect>| {
                let mut p = profile.clone();
                p.packet.isa = isa;
                let settings = RenderSettings { crop, ..settings };
                let r = p.prepare(scene, camera.eye).render(&settings);
                (r.image.pixels, r.stats.node_tests)
            };
            for crop in [
                None,
                Some(PixelRect {
                    x0: 5,
                    x1: 61,
                    y0: 50,
                    y1: 90,
                }),
            ] {
                let ((a, n8), (b, n16)) = (image(Isa::AVX2, crop), image(avx512, crop));
                // the 16-lane frustum walk ran: one node test for two blocks' rays
                // (`preview` renders at half the size: its blocks spread past the limit)
                let fewer = n16 < n8 || (name == "preview" && n16 == n8);
                assert!(fewer, "{name}: node tests {n16} (avx512) vs {n8} (avx2)");
                assert!(
                    a == b,
                    "{name}: the images differ under avx2 and avx512 ({crop:?})"
                );
                let lit = a.iter().filter(|p| p.iter().any(|c| *c > 0)).count();
                assert!(
                    lit > a.len() / 4,
                    "{name}: too dark to compare ({lit} lit pixels of {}, eye {})",
                    a.len(),
                    camera.eye
                );
            }
        }
    }
}
