//! Per-lane equivalence of the fast path's f32 kernels and BVH traversal with the f64
//! reference.
//!
//! Rules (design.md): hit/miss must agree except for rays at an edge, t must agree to
//! a relative 1e-4, the object must agree unless two hits tie. A ray counts as "at an
//! edge" when the reference itself changes its answer under a relative perturbation
//! of 1e-5 of the ray (hit/miss, object, or t by more than the tolerance): there f32
//! and f64 may legitimately fall on different sides. Packet lanes must equal the
//! single-ray results bit for bit (same arithmetic), and inactive lanes must neither
//! report nor disturb anything.

mod common;

use common::Rng;
use glam::{DVec3, Vec3};
use octaray::bvh::{Bvh, Steps};
use octaray::geometry::triangle::Watertight;
use octaray::geometry::{self, Hit1, PrimKind, PrimSet, split_code};
use octaray::math::Ray;
use octaray::math::packet::{HitPacket8, Mask8, Ray1, RayPacket8, Vec3x8};
use octaray::render::reference::{Reference, Target};
use octaray::scene::{Material, Object, Quadric, Scene, Shape};
use wide::f32x8;

const T_TOL: f64 = 1e-4;

fn object(shape: Shape) -> Object {
    Object {
        shape,
        material: Material {
            color: DVec3::ONE,
            ka: 1.0,
            kd: 0.0,
            ks: 0.0,
            kr: 0.0,
            shine: 1.0,
        },
    }
}

fn scene_of(objects: Vec<Object>) -> Scene {
    Scene {
        recursion_level: 1,
        pixels: 8,
        objects,
        point_lights: vec![],
        spot_lights: vec![],
    }
}

/// The reference's nearest hit: (object or −2 for the floor, t). Without the floor,
/// the reference's own loop over the objects (ties to the first).
fn ref_hit(tracer: &Reference, scene: &Scene, ray: &Ray, with_floor: bool) -> Option<(i64, f64)> {
    if !with_floor {
        let mut best = None;
        let mut t_best = f64::INFINITY;
        for (k, o) in scene.objects.iter().enumerate() {
            if let Some(h) = geometry::intersect_ref(&o.shape, ray, t_best) {
                t_best = h.t;
                best = Some((k as i64, h.t));
            }
        }
        return best;
    }
    tracer.nearest(ray, f64::INFINITY).map(|f| {
        let id = match f.target {
            Target::Object(k) => k as i64,
            Target::Floor => -2,
        };
        (id, f.hit.t)
    })
}

/// Whether the reference's answer is unstable under small perturbations of the ray.
fn at_edge(tracer: &Reference, scene: &Scene, ray: &Ray, with_floor: bool, rng: &mut Rng) -> bool {
    let base = ref_hit(tracer, scene, ray, with_floor);
    let scale = ray.origin.abs().max_element().max(1.0);
    (0..8).any(|_| {
        let o = ray.origin + rng.unit() * (1e-5 * scale);
        let d = (ray.dir + rng.unit() * 1e-5).normalize();
        let h = ref_hit(tracer, scene, &Ray::new(o, d), with_floor);
        match (base, h) {
            (None, None) => false,
            (Some((a, ta)), Some((b, tb))) => a != b || ((ta - tb) / ta).abs() > T_TOL,
            _ => true,
        }
    })
}

fn fast_object(bvh: &Bvh, h: &Hit1) -> i64 {
    if !h.is_hit() {
        return -1;
    }
    if split_code(h.prim).unwrap().0 == PrimKind::Floor {
        -2
    } else {
        bvh.prims.object(h.prim) as i64
    }
}

#[derive(Default, Debug)]
struct Tally {
    rays: usize,
    edge_mismatches: usize,
}

/// Traces `rays` through the scene on the reference, the single-ray BVH path and the
/// packet path (in packets of 8, some lanes inactive), and checks the rules.
/// At most `max_edge` of the rays may disagree at an edge.
fn check_rays(
    name: &str,
    scene: &Scene,
    with_floor: bool,
    rays: &[Ray],
    seed: u64,
    max_edge: f64,
) -> Tally {
    let mut prims = PrimSet::from_scene(scene, DVec3::ZERO);
    if !with_floor {
        prims.floor = None;
    }
    let bvh = Bvh::build(prims);
    let tracer = Reference::new(scene);
    let mut rng = Rng(seed);
    let mut tally = Tally::default();
    let mut steps = Steps::default();
    for (c, chunk) in rays.chunks(8).enumerate() {
        // lanes: the chunk's rays, the rest padded with NaN garbage and left inactive;
        // every third packet also deactivates lane 3
        let mut o = [Vec3::NAN; 8];
        let mut d = [Vec3::NAN; 8];
        let mut bits = 0u32;
        for (i, r) in chunk.iter().enumerate() {
            o[i] = r.origin.as_vec3();
            d[i] = r.dir.as_vec3();
            if !(c % 3 == 0 && i == 3) {
                bits |= 1 << i;
            }
        }
        let active = Mask8::from_bits(bits);
        let packet = RayPacket8::new(Vec3x8::from_lanes(&o), Vec3x8::from_lanes(&d), active);
        let mut hp = HitPacket8::new(f32x8::splat(f32::INFINITY));
        bvh.intersect_x8::<Watertight>(&packet, active, &mut hp, &mut steps);
        let occ_tmax = f32x8::splat(50.0);
        let occ = bvh.occluded_x8::<Watertight>(&packet, active, occ_tmax, &mut steps);
        for (i, r) in chunk.iter().enumerate() {
            let lane_active = bits >> i & 1 == 1;
            let (pt, pp) = (hp.t.to_array()[i], hp.prim_lane(i));
            if !lane_active {
                assert_eq!(pp, -1, "{name}: inactive lane {i} reported a hit");
                assert!(!occ.lane(i), "{name}: inactive lane {i} reported a blocker");
                continue;
            }
            tally.rays += 1;
            let r1 = Ray1::new(o[i], d[i]);
            let mut h1 = Hit1::new(f32::INFINITY);
            bvh.intersect_1::<Watertight>(&r1, &mut h1, &mut steps);
            // packet lane == single ray, bit for bit
            assert_eq!(
                (pt.to_bits(), pp),
                (
                    if h1.is_hit() {
                        h1.t.to_bits()
                    } else {
                        f32::INFINITY.to_bits()
                    },
                    h1.prim
                ),
                "{name}: ray {} packet lane {i} differs from the single ray",
                c * 8 + i
            );
            assert_eq!(
                occ.lane(i),
                bvh.occluded_1::<Watertight>(&r1, 50.0, &mut steps),
                "{name}: ray {} occlusion differs between widths",
                c * 8 + i
            );
            let fast = (fast_object(&bvh, &h1), h1.t as f64);
            let reference =
                ref_hit(&tracer, scene, r, with_floor).map_or((-1, f64::INFINITY), |h| h);
            let agree = fast.0 == reference.0
                && (fast.0 == -1 || ((fast.1 - reference.1) / reference.1).abs() <= T_TOL);
            if !agree {
                assert!(
                    at_edge(&tracer, scene, r, with_floor, &mut rng),
                    "{name}: ray {} ({:?}) fast {:?} vs reference {:?}, not at an edge",
                    c * 8 + i,
                    r,
                    fast,
                    reference
                );
                tally.edge_mismatches += 1;
            }
        }
    }
    println!("{name}: {tally:?}");
    assert!(
        tally.edge_mismatches as f64 <= max_edge * tally.rays as f64,
        "{name}: too many edge mismatches: {tally:?}"
    );
    tally
}

/// Rays from a box aimed near `target` (jittered by `spread`), plus a few with
/// exactly ±0 direction components.
fn rays_at(rng: &mut Rng, n: usize, lo: DVec3, hi: DVec3, target: DVec3, spread: f64) -> Vec<Ray> {
    let mut rays = Vec::with_capacity(n);
    for k in 0..n {
        let o = rng.vec_in(lo, hi);
        let aim = target + rng.unit() * spread * rng.f64();
        let mut d = (aim - o).normalize();
        match k % 16 {
            0 => d = DVec3::new(0.0, 0.0, if o.z > target.z { -1.0 } else { 1.0 }),
            1 => d = DVec3::new(-0.0, if o.y > target.y { -1.0 } else { 1.0 }, 0.0),
            2 => {
                d = DVec3::new(d.x, -0.0, d.z)
                    .try_normalize()
                    .unwrap_or(DVec3::X)
            }
            _ => {}
        }
        rays.push(Ray::new(o, d));
    }
    rays
}

#[test]
fn spheres_match_per_lane() {
    let mut rng = Rng(1);
    let objects = vec![
        object(Shape::Sphere {
            center: DVec3::new(0.0, 0.0, 0.0),
            radius: 2.0,
        }),
        object(Shape::Sphere {
            center: DVec3::new(3.0, 0.5, 0.0),
            radius: 1.0,
        }),
        // a small sphere far away: the discriminant form must keep it
        object(Shape::Sphere {
            center: DVec3::new(2000.0, 0.0, 0.0),
            radius: 1.0,
        }),
    ];
    let scene = scene_of(objects);
    let mut rays = rays_at(
        &mut rng,
        2000,
        DVec3::splat(-10.0),
        DVec3::splat(10.0),
        DVec3::ZERO,
        4.0,
    );
    rays.extend(rays_at(
        &mut rng,
        500,
        DVec3::splat(-3.0),
        DVec3::splat(3.0),
        DVec3::new(2000.0, 0.0, 0.0),
        1.2,
    ));
    // rays from inside
    rays.extend(rays_at(
        &mut rng,
        200,
        DVec3::splat(-0.5),
        DVec3::splat(0.5),
        DVec3::ZERO,
        3.0,
    ));
    let t = check_rays("spheres", &scene, false, &rays, 11, 0.01);
    assert!(t.rays > 2500);
}

#[test]
fn triangles_match_per_lane_at_vertices_and_shared_edges() {
    let mut rng = Rng(2);
    // a 4 × 4 grid of quads with integer vertices, each split in two
    let mut objects = Vec::new();
    for i in 0..4 {
        for j in 0..4 {
            let p = |a: i32, b: i32| DVec3::new((i + a) as f64, (j + b) as f64, 0.0);
            objects.push(object(Shape::Triangle {
                v: [p(0, 0), p(1, 0), p(1, 1)],
            }));
            objects.push(object(Shape::Triangle {
                v: [p(0, 0), p(1, 1), p(0, 1)],
            }));
        }
    }
    objects.push(object(Shape::Triangle {
        v: [
            DVec3::new(-2.0, -1.0, 1.0),
            DVec3::new(3.0, 6.0, 2.0),
            DVec3::new(5.0, -1.0, 3.0),
        ],
    }));
    let scene = scene_of(objects);
    let mut rays = rays_at(
        &mut rng,
        1500,
        DVec3::new(-2.0, -2.0, 3.0),
        DVec3::new(6.0, 6.0, 6.0),
        DVec3::new(2.0, 2.0, 0.0),
        3.0,
    );
    // rays at every vertex and along every shared edge, axis-aligned (edge functions
    // exactly zero) and oblique
    for i in 0..=4 {
        for j in 0..=4 {
            let v = DVec3::new(i as f64, j as f64, 0.0);
            rays.push(Ray::new(v + DVec3::Z * 5.0, DVec3::NEG_Z));
            rays.push(Ray::new(v + DVec3::Z * 5.0, DVec3::new(-0.0, 0.0, -1.0)));
            let o = v + DVec3::new(0.3, -0.2, 4.0);
            rays.push(Ray::new(o, (v - o).normalize()));
            for k in 1..4 {
                let s = k as f64 / 4.0;
                for e in [
                    DVec3::new(s, 0.0, 0.0),
                    DVec3::new(0.0, s, 0.0),
                    DVec3::new(s, s, 0.0),
                ] {
                    let p = v + e;
                    rays.push(Ray::new(p + DVec3::Z * 5.0, DVec3::NEG_Z));
                    let o = p + DVec3::new(-0.7, 0.4, 3.0);
                    rays.push(Ray::new(o, (p - o).normalize()));
                }
            }
        }
    }
    check_rays("triangles", &scene, false, &rays, 12, 0.1);
}

#[test]
fn shared_edges_are_watertight_in_both_widths() {
    // a fan of triangles around the origin; rays through the interior must all hit
    let mut objects = Vec::new();
    let n = 12;
    for k in 0..n {
        let a = |k: i32| {
            let phi = k as f64 / n as f64 * std::f64::consts::TAU;
            DVec3::new(3.0 * phi.cos(), 3.0 * phi.sin(), 0.1 * (k % 3) as f64)
        };
        objects.push(object(Shape::Triangle {
            v: [DVec3::ZERO, a(k), a(k + 1)],
        }));
    }
    let scene = scene_of(objects);
    let bvh = Bvh::build(PrimSet::from_scene(&scene, DVec3::ZERO));
    let mut rng = Rng(3);
    let mut steps = Steps::default();
    let mut escaped = 0;
    for k in 0..4000 {
        // aim at a point on a spoke (a shared edge), from a random origin above
        let spoke = k % n;
        let phi = spoke as f64 / n as f64 * std::f64::consts::TAU;
        let s = rng.range(0.05, 2.5);
        let target = DVec3::new(
            s * phi.cos(),
            s * phi.sin(),
            0.1 * (spoke % 3) as f64 * s / 3.0,
        );
        let o = target + rng.vec_in(DVec3::new(-2.0, -2.0, 1.0), DVec3::new(2.0, 2.0, 4.0));
        let r = Ray1::new(o.as_vec3(), (target - o).normalize().as_vec3());
        let mut h = Hit1::new(f32::INFINITY);
        bvh.intersect_1::<Watertight>(&r, &mut h, &mut steps);
        let packet = RayPacket8::from_lanes(&[r.origin; 8], &[r.dir; 8]);
        let mut hp = HitPacket8::new(f32x8::splat(f32::INFINITY));
        bvh.intersect_x8::<Watertight>(&packet, Mask8::ALL, &mut hp, &mut steps);
        if !h.is_hit() || hp.prim_lane(0) < 0 {
            escaped += 1;
        }
    }
    assert_eq!(escaped, 0, "rays slipped through shared edges");
}

fn quadric(coef: [f64; 10], min: [f64; 3], size: [f64; 3]) -> Shape {
    let m = coef.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    Shape::Quadric(Quadric {
        coef: coef.map(|v| v / m),
        min: DVec3::from(min),
        size: DVec3::from(size),
    })
}

#[test]
fn quadrics_match_per_lane_with_box_clipping() {
    let mut rng = Rng(4);
    let objects = vec![
        // ellipsoid clipped on z only (unbounded list): shows its inside
        object(quadric(
            [1.0, 1.0, 4.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -4.0],
            [0.0, 0.0, 0.0],
            [0.0, 0.0, 0.7],
        )),
        // cylinder around z, clipped on every axis (in the BVH)
        object(quadric(
            [1.0, 1.0, 0.0, 0.0, 0.0, 0.0, -10.0, 0.0, 0.0, 24.0],
            [4.0, -1.0, -2.0],
            [2.0, 2.0, 4.0],
        )),
        // a cone and a paraboloid, partly clipped
        object(quadric(
            [1.0, 1.0, -1.0, 0.0, 0.0, 0.0, 0.0, 12.0, 0.0, 36.0],
            [-3.0, -9.0, -3.0],
            [6.0, 6.0, 6.0],
        )),
        object(quadric(
            [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0],
            [0.0, 0.0, 0.0],
            [0.0, 0.0, 0.0],
        )),
        // a plane (linear: A..F zero)
        object(quadric(
            [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 5.0],
            [-2.0, -2.0, 0.0],
            [4.0, 4.0, 0.0],
        )),
    ];
    let scene = scene_of(objects);
    let mut rays = rays_at(
        &mut rng,
        2500,
        DVec3::splat(-10.0),
        DVec3::splat(10.0),
        DVec3::ZERO,
        6.0,
    );
    rays.extend(rays_at(
        &mut rng,
        500,
        DVec3::splat(-0.3),
        DVec3::splat(0.3),
        DVec3::ZERO,
        2.0,
    ));
    rays.extend(rays_at(
        &mut rng,
        500,
        DVec3::new(0.0, -10.0, -10.0),
        DVec3::new(10.0, 10.0, 10.0),
        DVec3::new(5.0, 0.0, 0.0),
        2.0,
    ));
    check_rays("quadrics", &scene, false, &rays, 13, 0.01);
}

#[test]
fn floor_matches_per_lane() {
    let mut rng = Rng(5);
    let scene = scene_of(vec![object(Shape::Sphere {
        center: DVec3::new(0.0, 0.0, 5.0),
        radius: 5.0,
    })]);
    let mut rays = rays_at(
        &mut rng,
        1500,
        DVec3::new(-600.0, -600.0, 1.0),
        DVec3::new(600.0, 600.0, 100.0),
        DVec3::ZERO,
        600.0,
    );
    // rays from below, rays parallel to the floor, rays at its border
    rays.extend(rays_at(
        &mut rng,
        200,
        DVec3::new(-100.0, -100.0, -50.0),
        DVec3::new(100.0, 100.0, -1.0),
        DVec3::ZERO,
        50.0,
    ));
    rays.push(Ray::new(DVec3::new(0.0, 0.0, 1.0), DVec3::X));
    rays.push(Ray::new(DVec3::new(500.0, -500.0, 10.0), DVec3::NEG_Z));
    check_rays("floor", &scene, true, &rays, 14, 0.01);
}

/// Surfaces within the floor's f32 tie band: a triangle crossing the plane a few 1e-4
/// below it over most of its area, the plane z = −0.0002 as an unclipped quadric, a
/// sphere sunk to a 0.001 cap, and a triangle lying on the floor. Rays from above and
/// below: packet lanes equal single rays bit for bit, and both agree with the
/// reference (the tie band decided in f64, `PrimSet::floor_first`).
#[test]
fn floor_ties_match_per_lane() {
    let mut rng = Rng(7);
    let tri = |v: [[f64; 3]; 3]| {
        object(Shape::Triangle {
            v: v.map(DVec3::from),
        })
    };
    let scene = scene_of(vec![
        tri([
            [-400.0, -400.0, -0.0002],
            [400.0, -400.0, -0.0002],
            [0.0, 400.0, 0.0001],
        ]),
        object(quadric(
            [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0002],
            [0.0; 3],
            [0.0; 3],
        )),
        object(Shape::Sphere {
            center: DVec3::new(50.0, 50.0, -9.999),
            radius: 10.0,
        }),
        tri([
            [-100.0, -300.0, 0.0],
            [100.0, -300.0, 0.0],
            [0.0, -200.0, 0.0],
        ]),
    ]);
    let mut rays = rays_at(
        &mut rng,
        1600,
        DVec3::new(-300.0, -300.0, 5.0),
        DVec3::new(300.0, 300.0, 100.0),
        DVec3::ZERO,
        300.0,
    );
    // aimed at the cap's rim (radius ~0.14 around (50, 50))
    rays.extend(rays_at(
        &mut rng,
        400,
        DVec3::new(49.0, 49.0, 0.2),
        DVec3::new(51.0, 51.0, 1.0),
        DVec3::new(50.0, 50.0, 0.0),
        0.3,
    ));
    rays.extend(rays_at(
        &mut rng,
        400,
        DVec3::new(-100.0, -100.0, -60.0),
        DVec3::new(100.0, 100.0, -5.0),
        DVec3::ZERO,
        200.0,
    ));
    check_rays("floor ties", &scene, true, &rays, 16, 0.01);
}

#[test]
fn whole_bvh_traversal_matches_with_mixed_packets() {
    let scene = common::generated_scene(600, 21);
    let mut rng = Rng(6);
    let mut rays = Vec::new();
    for _ in 0..3000 {
        // mixed directions within a packet: every ray independent
        let o = rng.vec_in(
            DVec3::new(-100.0, -100.0, 1.0),
            DVec3::new(100.0, 100.0, 60.0),
        );
        rays.push(Ray::new(o, rng.unit()));
    }
    // and coherent camera-like packets
    rays.extend(rays_at(
        &mut rng,
        2000,
        DVec3::new(99.0, 99.0, 49.0),
        DVec3::new(101.0, 101.0, 51.0),
        DVec3::ZERO,
        60.0,
    ));
    let t = check_rays("generated 600", &scene, true, &rays, 15, 0.01);
    assert!(t.rays > 4000);
}

#[test]
fn meshes_are_hit_like_their_triangles() {
    let text = "v 0 0 0\nv 2 0 0\nv 2 2 0\nv 0 2 1\nf 1 2 3 4\n";
    let mesh = octaray::scene::obj::parse_obj(text, "quad.obj").unwrap();
    let scene = scene_of(vec![object(Shape::Mesh(std::sync::Arc::new(mesh)))]);
    let mut rng = Rng(7);
    let rays = rays_at(
        &mut rng,
        800,
        DVec3::new(-1.0, -1.0, 3.0),
        DVec3::new(3.0, 3.0, 5.0),
        DVec3::new(1.0, 1.0, 0.0),
        1.5,
    );
    check_rays("mesh", &scene, false, &rays, 16, 0.01);
    let r = Ray::new(DVec3::new(0.5, 0.2, 3.0), DVec3::NEG_Z);
    let h = geometry::intersect_ref(&scene.objects[0].shape, &r, f64::INFINITY).unwrap();
    assert!((h.t - 3.0).abs() < 1e-12 && h.part == 0);
}

#[test]
fn surfaces_of_a_primitive_on_eight_lanes_equal_the_single_ray_ones() {
    // every kind in the BVH, plus unbounded quadrics, hit by coherent and mixed packets
    let scene = common::generated_scene(600, 22);
    let base = DVec3::new(100.0, 100.0, 50.0);
    let bvh = Bvh::build(PrimSet::from_scene(&scene, base));
    let mut rng = Rng(23);
    let (mut checked, mut kinds) = (0, std::collections::BTreeSet::new());
    for packet in 0..6000 {
        let o = rng.vec_in(
            DVec3::new(-100.0, -100.0, 1.0),
            DVec3::new(100.0, 100.0, 60.0),
        );
        let target = rng.vec_in(
            DVec3::new(-150.0, -150.0, 0.0),
            DVec3::new(150.0, 150.0, 40.0),
        );
        let (mut os, mut ds) = ([Vec3::ZERO; 8], [Vec3::Z; 8]);
        for k in 0..8 {
            let d = if packet % 2 == 0 {
                (target - o).normalize() + rng.unit() * 0.01
            } else {
                rng.unit()
            };
            os[k] = (o - base).as_vec3();
            ds[k] = d.normalize().as_vec3();
        }
        let r = RayPacket8::from_lanes(&os, &ds);
        let mut hit = HitPacket8::new(f32x8::splat(f32::INFINITY));
        bvh.intersect_x8::<Watertight>(&r, Mask8::ALL, &mut hit, &mut Steps::default());
        let (t, u, v) = (hit.t.to_array(), hit.u.to_array(), hit.v.to_array());
        for (i, &code) in hit.prim.to_array().iter().enumerate() {
            let Some(s8) = bvh.prims.surface_x8(code, &r, hit.t, hit.u, hit.v) else {
                continue; // the floor (its twin lives in the shading) or no hit
            };
            let s1 = bvh.prims.surface_1(code, &r.ray(i), t[i], u[i], v[i]);
            let lane = |w: Vec3x8| w.lane(i).to_array().map(f32::to_bits);
            let bits = |w: Vec3| w.to_array().map(f32::to_bits);
            assert_eq!(lane(s8.point), bits(s1.point), "point, code {code:#x}");
            assert_eq!(lane(s8.normal), bits(s1.normal), "normal, code {code:#x}");
            assert_eq!(lane(s8.err), bits(s1.err), "error bound, code {code:#x}");
            checked += 1;
            kinds.insert(split_code(code).unwrap().0 as u32);
        }
    }
    assert!(checked > 5000, "{checked} lanes checked");
    assert!(kinds.len() >= 3, "kinds hit: {kinds:?}");
}
