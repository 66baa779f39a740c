//! The 8-wide single-ray path (`Bvh::intersect_1`/`occluded_1`, `bvh/wide.rs`) against
//! the binary single-ray walk (`intersect_1_binary`/`occluded_1_binary`), and the 1×8
//! triangle kernel against the 1×1 kernel.
//!
//! Tolerances: both walks run the same per-primitive kernels (the 1×8 triangle kernel
//! equals the 1×1 kernel bit for bit, checked below), so when both report the same
//! primitive, t, u and v must be **bit-identical** (tolerance 0). They may report
//! different primitives only on a legitimate tie: equal t (bitwise) and the same scene
//! object (e.g. a ray through the shared edge of two triangles of one mesh, where the
//! contract only orders objects, not primitives). Hit/miss must always agree. Any-hit
//! must agree with closest-hit: `occluded_1(r, t_max)` iff `intersect_1` below t_max
//! finds something.
//!
//! The packet walks (`Bvh::intersect_x8`/`occluded_x8`: the 8-wide tree for packets whose
//! lanes share their direction signs, `wide_x8.rs`; lane by lane through the wide tree
//! for packets of mixed signs or scattered origins in trees big enough for it, the
//! binary tree otherwise) are
//! held to the same rules per lane against the binary single-ray walk, with inactive
//! lanes (holding NaN) and active NaN lanes that must never hit.

mod common;

use common::{Rng, generated_scene};
use glam::{DVec3, Vec3};
use octaray::bvh::bench::{incoherent_rays, primary_rays, torus};
use octaray::bvh::traverse_x8::LANES_MIN_NODES;
use octaray::bvh::wide::walk_x8::{FRUSTUM_SPREAD, LANES_SPREAD};
use octaray::bvh::wide::{PREFETCH_FROM, STREAM_ANY_HIT_FROM, STREAM_FROM};
use octaray::bvh::{BinaryStats, Bvh, Steps};
use octaray::geometry::triangle::Watertight;
use octaray::geometry::triangle::{TriRay8, Triangle8, Triangle32};
use octaray::geometry::{Hit1, PrimKind, PrimSet, split_code};
use octaray::math::packet::{HitPacket8, Mask8, Ray1, RayPacket8, Vec3x8};
use octaray::scene::{Object, Quadric, Scene, Shape};
use wide::f32x8;

#[derive(Debug, Default)]
struct Tally {
    rays: usize,
    hits: usize,
    /// Equal t, same object, different primitive.
    ties: usize,
    /// Different answers at a triangle edge or vertex.
    edge: usize,
}

/// A triangle hit within 1e-4 (barycentric) of an edge.
fn at_edge(h: &Hit1) -> bool {
    h.is_hit()
        && split_code(h.prim).unwrap().0 == PrimKind::Triangle
        && h.u.abs().min(h.v.abs()).min((1.0 - h.u - h.v).abs()) <= 1e-4
}

fn closest(bvh: &Bvh, r: &Ray1, t_max: f32, wide: bool, steps: &mut Steps) -> Hit1 {
    let mut h = Hit1::new(t_max);
    if wide {
        bvh.intersect_1::<Watertight>(r, &mut h, steps);
    } else {
        bvh.intersect_1_binary::<Watertight>(r, &mut h, steps);
    }
    h
}

/// Wide vs binary on every ray of `rays`, closest hit and any hit at several t_max.
fn compare(name: &str, bvh: &Bvh, rays: &[Ray1], rng: &mut Rng) -> (Tally, Steps, Steps) {
    let mut tally = Tally::default();
    let (mut sw, mut sb) = (Steps::default(), Steps::default());
    for (i, r) in rays.iter().enumerate() {
        tally.rays += 1;
        let hw = closest(bvh, r, f32::INFINITY, true, &mut sw);
        let hb = closest(bvh, r, f32::INFINITY, false, &mut sb);
        assert_eq!(
            hw.is_hit(),
            hb.is_hit(),
            "{name}: ray {i} {r:?}: wide {hw:?} vs binary {hb:?}"
        );
        let mut edge_ray = false;
        if hw.prim == hb.prim {
            // same primitive (or both miss): bit-identical
            assert_eq!(
                (hw.t.to_bits(), hw.u.to_bits(), hw.v.to_bits()),
                (hb.t.to_bits(), hb.u.to_bits(), hb.v.to_bits()),
                "{name}: ray {i} {r:?}: wide {hw:?} vs binary {hb:?}"
            );
        } else if hw.is_hit()
            && hb.is_hit()
            && hw.t == hb.t
            && bvh.prims.object(hw.prim) == bvh.prims.object(hb.prim)
        {
            // a tie between primitives of one object may go either way
            tally.ties += 1;
        } else {
            // otherwise only at a triangle edge or vertex, where a hit can fall an ulp
            // outside its leaf's box and one walk (whose box there is the larger, merged
            // one) finds it while the other does not
            assert!(
                at_edge(&hw) || at_edge(&hb),
                "{name}: ray {i} {r:?}: wide {hw:?} vs binary {hb:?}, not at an edge"
            );
            tally.edge += 1;
            edge_ray = true;
        }
        tally.hits += hw.is_hit() as usize;
        // any hit: at the hit itself (nothing nearer), just past it, and at random t_max
        let mut t_maxes = vec![rng.range(0.0, 3.0) as f32, f32::INFINITY];
        if hb.is_hit() {
            t_maxes.extend([hb.t, hb.t.next_up(), hb.t * rng.range(0.5, 2.0) as f32]);
        }
        for t_max in t_maxes {
            let ow = bvh.occluded_1::<Watertight>(r, t_max, &mut sw);
            let ob = bvh.occluded_1_binary::<Watertight>(r, t_max, &mut sb);
            let cw = closest(bvh, r, t_max, true, &mut sw).is_hit();
            assert!(
                ow == ob || edge_ray,
                "{name}: ray {i} {r:?}: occluded at {t_max}"
            );
            // (closest hit culls a box entered beyond the current hit; at a vertex a hit
            // can lie an ulp outside its box, so there the unculled any-hit walk may see
            // it and the closest-hit walk not; the binary walks do the same)
            if ow != cw {
                assert!(
                    at_edge(&hw) || at_edge(&hb),
                    "{name}: ray {i} {r:?}: any hit and closest hit disagree at {t_max}"
                );
                if !edge_ray {
                    tally.edge += 1;
                    edge_ray = true;
                }
            }
        }
    }
    println!("{name}: {tally:?}, wide {sw:?}, binary {sb:?}");
    assert!(
        tally.edge * 200 <= tally.rays,
        "{name}: too many edge differences: {tally:?}"
    );
    (tally, sw, sb)
}

fn rays_of(set: &octaray::bvh::bench::RaySet) -> Vec<Ray1> {
    set.origin
        .iter()
        .zip(&set.dir)
        .map(|(&o, &d)| Ray1::new(o, d))
        .collect()
}

/// The triangles of a set, in index order.
fn triangles_of(p: &PrimSet) -> Vec<Triangle32> {
    p.each_triangle().map(|(_, t)| t).collect()
}

/// Rays aimed exactly at vertices and at points on (or within an ulp of) edges of
/// random triangles, from random origins.
fn edge_rays(tris: &[Triangle32], n: usize, lo: Vec3, hi: Vec3, rng: &mut Rng) -> Vec<Ray1> {
    (0..n)
        .map(|k| {
            let t = &tris[rng.next_u64() as usize % tris.len()];
            let (a, b) = (t.v[k % 3], t.v[(k + 1) % 3]);
            let target = match k % 3 {
                0 => a,
                1 => (a + b) * 0.5,
                _ => a + (b - a) * rng.f64() as f32,
            };
            let o = Vec3::new(
                rng.range(lo.x as f64, hi.x as f64) as f32,
                rng.range(lo.y as f64, hi.y as f64) as f32,
                rng.range(lo.z as f64, hi.z as f64) as f32,
            );
            Ray1::new(o, (target - o).normalize())
        })
        .collect()
}

/// Axis-aligned and in-plane directions with every sign of zero, from a grid of origins.
fn signed_zero_rays(lo: Vec3, hi: Vec3, steps: usize) -> Vec<Ray1> {
    let s = std::f32::consts::FRAC_1_SQRT_2;
    let dirs = [
        Vec3::new(0.0, -1.0, 0.0),
        Vec3::new(-0.0, -1.0, -0.0),
        Vec3::new(0.0, 1.0, -0.0),
        Vec3::new(1.0, 0.0, -0.0),
        Vec3::new(-1.0, -0.0, 0.0),
        Vec3::new(0.0, -0.0, 1.0),
        Vec3::new(-0.0, 0.0, -1.0),
        Vec3::new(s, -0.0, -s),
        Vec3::new(-s, s, 0.0),
        Vec3::new(-0.0, -s, s),
    ];
    let mut rays = Vec::new();
    for i in 0..steps {
        for j in 0..steps {
            let f = |k: usize| (k as f32 + 0.5) / steps as f32;
            let o = lo + (hi - lo) * Vec3::new(f(i), f(j), f((i * 7 + j * 3) % steps));
            for d in dirs {
                rays.push(Ray1::new(o, d));
            }
        }
    }
    rays
}

fn torus_bvh() -> Bvh {
    Bvh::build_with_binary(PrimSet::from_triangles(torus(96, 48)))
}

#[test]
fn wide_equals_binary_on_a_torus_incoherent() {
    let bvh = torus_bvh();
    let mut rng = Rng(11);
    let rays = rays_of(&incoherent_rays(20_000, 3));
    let (t, sw, sb) = compare("torus incoherent", &bvh, &rays, &mut rng);
    assert!(t.hits > t.rays / 3, "{t:?}: too few hits to test anything");
    assert!(sw.boxes > 0 && sw.prims > 0 && sb.boxes > 0);
    // a wide node test stands for up to 8 box tests: far fewer than the binary walk's
    assert!(sw.boxes < sb.boxes, "wide {sw:?} vs binary {sb:?}");
}

#[test]
fn wide_equals_binary_on_a_torus_coherent() {
    let bvh = torus_bvh();
    let mut rng = Rng(12);
    let rays = rays_of(&primary_rays(128, 128));
    let (t, _, _) = compare("torus primary", &bvh, &rays, &mut rng);
    assert!(t.hits > t.rays / 3, "{t:?}");
}

#[test]
fn wide_equals_binary_through_shared_edges_and_vertices() {
    let tris = torus(96, 48);
    let bvh = Bvh::build_with_binary(PrimSet::from_triangles(tris.clone()));
    let mut rng = Rng(13);
    let rays = edge_rays(
        &tris,
        20_000,
        Vec3::new(-2.0, -1.5, -2.0),
        Vec3::new(2.0, 1.5, 2.0),
        &mut rng,
    );
    let (t, _, _) = compare("torus edges", &bvh, &rays, &mut rng);
    // rays aimed at the surface from outside or inside hit it (watertight)
    assert!(t.hits * 10 >= t.rays * 9, "{t:?}");
}

#[test]
fn wide_equals_binary_with_signed_zero_directions() {
    let bvh = torus_bvh();
    let mut rng = Rng(14);
    let rays = signed_zero_rays(Vec3::new(-1.6, -0.5, -1.6), Vec3::new(1.6, 0.5, 1.6), 40);
    let (t, _, _) = compare("torus signed zeros", &bvh, &rays, &mut rng);
    assert!(t.hits > t.rays / 4, "{t:?}");
}

/// The generated mixed scene (spheres, triangles, clipped and unclipped quadrics, the
/// floor) with its first 40 objects repeated at the end: exact ties in t, which must go
/// to the lower object index on both walks.
fn mixed_scene() -> Scene {
    let mut scene = generated_scene(400, 5);
    // two unbounded quadrics (tested beside the tree): a tilted plane and a saddle
    // (cylinders along an axis, unclipped, have a footprint and go in the tree)
    let material = scene.objects[0].material;
    for coef in [
        [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.3, -0.2, 1.0, -15.0],
        [0.01, -0.01, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -1.0, 5.0],
    ] {
        scene.objects.push(Object {
            shape: Shape::Quadric(Quadric {
                coef,
                min: DVec3::ZERO,
                size: DVec3::ZERO,
            }),
            material,
        });
    }
    let dup: Vec<Object> = scene.objects[..40].to_vec();
    scene.objects.extend(dup);
    scene
}

#[test]
fn wide_equals_binary_on_a_mixed_scene() {
    let scene = mixed_scene();
    let bvh = Bvh::build_with_binary(PrimSet::from_scene(&scene, DVec3::new(0.0, 0.0, 20.0)));
    let p = &bvh.prims;
    assert!(
        !p.spheres.is_empty()
            && !p.blocks.is_empty()
            && !p.quadrics.is_empty()
            && !p.free_quadrics.is_empty()
            && p.floor.is_some(),
        "the scene must hold every kind"
    );
    let mut rng = Rng(15);
    let (lo, hi) = (
        Vec3::new(-100.0, -100.0, -20.0),
        Vec3::new(80.0, 80.0, 50.0),
    );
    let mut rays: Vec<Ray1> = (0..15_000)
        .map(|_| {
            let o = Vec3::new(
                rng.range(lo.x as f64, hi.x as f64) as f32,
                rng.range(lo.y as f64, hi.y as f64) as f32,
                rng.range(lo.z as f64, hi.z as f64) as f32,
            );
            Ray1::new(o, rng.unit().as_vec3())
        })
        .collect();
    // rays aimed at the bounded primitives' centres (the duplicates give exact ties)
    for k in 0..5_000 {
        let kind = PrimKind::BVH_KINDS[k % 3];
        let n = p.len(kind);
        let b = p.bounds(kind, rng.next_u64() as usize % n);
        let o = Vec3::new(
            rng.range(lo.x as f64, hi.x as f64) as f32,
            rng.range(lo.y as f64, hi.y as f64) as f32,
            hi.z,
        );
        rays.push(Ray1::new(o, (b.centroid() - o).normalize()));
    }
    rays.extend(edge_rays(&triangles_of(p), 3_000, lo, hi, &mut rng));
    rays.extend(signed_zero_rays(lo, hi, 20));
    let (t, sw, _) = compare("mixed", &bvh, &rays, &mut rng);
    assert!(t.hits > t.rays / 3, "{t:?}");
    assert!(sw.quadrics > 0, "quadric tests must be counted: {sw:?}");
    // ties between an object and its duplicate went to the lower index on both walks
    // (checked per ray above); make sure some happened: the duplicate is never the winner
    let mut steps = Steps::default();
    let n_orig = scene.objects.len() as u32 - 40;
    let mut dup_targets = 0;
    for r in &rays {
        let h = closest(&bvh, r, f32::INFINITY, true, &mut steps);
        if h.is_hit() && split_code(h.prim).unwrap().0 != PrimKind::Floor {
            let obj = bvh.prims.object(h.prim);
            assert!(obj < n_orig, "ray {r:?} hit duplicate object {obj}");
            dup_targets += (obj < 40) as usize;
        }
    }
    assert!(
        dup_targets > 100,
        "only {dup_targets} rays hit duplicated objects"
    );
}

/// A triangle past ±2^44, where the build clamps every box (`PrimSet::bounds`), merged
/// into one block with a triangle near the origin: a ray that meets the far triangle
/// beyond its clamped leaf box gets the binary walk's answer from the wide walks too
/// (the single-ray walks check a hit lane's leaf box by its triangle's own box first,
/// clamped the same way).
#[test]
fn wide_equals_binary_past_the_clamped_bounds() {
    let (c, s) = (Vec3::new(2.0e13, 2.4e13, 0.0), 1.0e9);
    let far = Triangle32 {
        v: [
            c + Vec3::new(s, -s, -s),
            c + Vec3::new(-s, s, -s),
            c + Vec3::new(0.0, 0.0, s),
        ],
    };
    let near = Triangle32 {
        v: [
            Vec3::new(-1.0, -1.0, 5.0),
            Vec3::new(1.0, -1.0, 5.0),
            Vec3::new(-1.0, 1.0, 5.0),
        ],
    };
    let bvh = Bvh::build_with_binary(PrimSet::from_triangles(vec![far, near]));
    assert!(
        bvh.prims.blocks.iter().any(|b| !b.one_leaf),
        "the two triangles share a block of two binary leaves"
    );
    let mut steps = Steps::default();
    for d in [
        Vec3::new(1.0, 1.2, 0.0),
        Vec3::new(1.0, 1.2, 0.01),
        Vec3::new(0.1, 0.1, 1.0),
    ] {
        let r = Ray1::new(Vec3::ZERO, d.normalize());
        for t_max in [f32::INFINITY, 1.0e14, 10.0] {
            let (w, b) = (
                closest(&bvh, &r, t_max, true, &mut steps),
                closest(&bvh, &r, t_max, false, &mut steps),
            );
            assert_eq!(
                (w.t.to_bits(), w.prim),
                (b.t.to_bits(), b.prim),
                "{r:?} {t_max}"
            );
            assert_eq!(
                bvh.occluded_1::<Watertight>(&r, t_max, &mut steps),
                bvh.occluded_1_binary::<Watertight>(&r, t_max, &mut steps),
                "{r:?} {t_max}"
            );
        }
    }
}

#[test]
fn nan_rays_never_hit() {
    let bvh = Bvh::build_with_binary(PrimSet::from_scene(&mixed_scene(), DVec3::ZERO));
    let big = torus_bvh();
    let mut steps = Steps::default();
    for (o, d) in [
        (Vec3::new(f32::NAN, 0.0, 10.0), Vec3::NEG_Z),
        (Vec3::new(0.0, 0.0, 10.0), Vec3::new(f32::NAN, 0.0, -1.0)),
        (Vec3::splat(f32::NAN), Vec3::splat(f32::NAN)),
        (
            Vec3::new(0.0, 0.0, 10.0),
            Vec3::new(f32::INFINITY, 0.0, -1.0),
        ),
        (
            Vec3::new(0.0, 0.0, 10.0),
            Vec3::new(0.0, f32::NEG_INFINITY, -1.0),
        ),
        // every component infinite: 1/d is ±0 on every axis, finite
        (Vec3::new(0.0, 0.0, 10.0), Vec3::splat(f32::INFINITY)),
        (
            Vec3::new(0.3, -0.2, 0.1),
            Vec3::new(f32::NEG_INFINITY, f32::INFINITY, f32::NEG_INFINITY),
        ),
    ] {
        for bvh in [&bvh, &big] {
            let r = Ray1::new(o, d);
            let h = closest(bvh, &r, f32::INFINITY, true, &mut steps);
            assert!(!h.is_hit(), "NaN ray {r:?} hit {h:?}");
            assert!(!bvh.occluded_1::<Watertight>(&r, f32::INFINITY, &mut steps));
        }
    }
}

/// The torus tests above walk a tree that prefetches, the small scenes below one that
/// does not: both kinds of walk are held to the binary walk's answers.
#[test]
fn only_trees_past_the_prefetch_size_prefetch() {
    let big = torus_bvh();
    assert!(big.walked_bytes() > PREFETCH_FROM && big.wide.prefetches);
    let small = Bvh::build_with_binary(PrimSet::from_triangles(torus(24, 12)));
    assert!(small.walked_bytes() <= PREFETCH_FROM && !small.wide.prefetches);
    assert!(!Bvh::build_with_binary(PrimSet::default()).wide.prefetches);
}

#[test]
fn empty_tree_has_no_wide_nodes_and_misses() {
    let bvh = Bvh::build_with_binary(PrimSet::default());
    assert!(bvh.wide.nodes.is_empty());
    let r = Ray1::new(Vec3::ZERO, Vec3::Z);
    let mut steps = Steps::default();
    assert!(!closest(&bvh, &r, f32::INFINITY, true, &mut steps).is_hit());
    assert!(!bvh.occluded_1::<Watertight>(&r, f32::INFINITY, &mut steps));
}

#[test]
fn every_triangle_is_in_exactly_one_block_lane() {
    // large enough (> 4 MiB of blocks) for the huge-page copy of the block array
    let tris = torus(320, 160);
    let bvh = Bvh::build_with_binary(PrimSet::from_triangles(tris.clone()));
    assert!(bvh.prims.blocks.len() * std::mem::size_of_val(&bvh.prims.blocks[0]) > 4 << 20);
    let n = tris.len();
    let mut seen = vec![0u32; n];
    for b in &bvh.prims.blocks {
        assert!(b.count >= 1 && b.count <= 8);
        for l in 0..b.count as usize {
            let i = b.first as usize + l;
            seen[i] += 1;
            // the lane is triangle i as the set's lookup finds it
            assert_eq!(bvh.prims.triangle(i), b.tri.lane(l));
        }
    }
    assert!(
        seen.iter().all(|&c| c == 1),
        "a triangle index is missing or repeated"
    );
    // a leaf's reader, from anywhere in a block, across the blocks after it
    for start in [0, 5, 13, n / 2 + 3] {
        let mut run = bvh.prims.triangles_from(start);
        for j in start..n.min(start + 40) {
            assert_eq!(
                run.at(j),
                bvh.prims.triangle(j),
                "from {start}, triangle {j}"
            );
        }
    }
    // and the lanes hold the mesh's triangles, each once, bit for bit
    let bits = |t: &Triangle32| t.v.map(|p| p.to_array().map(f32::to_bits));
    let mut want: Vec<_> = tris.iter().map(bits).collect();
    let mut got: Vec<_> = bvh.prims.each_triangle().map(|(_, t)| bits(&t)).collect();
    want.sort_unstable();
    got.sort_unstable();
    assert!(
        got == want,
        "the blocks hold other triangles than the mesh's"
    );
    assert!(bvh.wide.depth() <= BinaryStats::of(&bvh.nodes).depth);
}

/// Triangles and rays for the kernel test: torus triangles and random ones, rays aimed
/// inside, at vertices and along edges, and random rays.
#[test]
fn kernel_1x8_equals_1x1_per_lane() {
    let mut rng = Rng(16);
    let mut tris = torus(24, 12);
    for _ in 0..256 {
        let c = rng.vec_in(DVec3::splat(-2.0), DVec3::splat(2.0));
        let s = rng.range(0.01, 2.0);
        tris.push(Triangle32 {
            v: [c, c + rng.unit() * s, c + rng.unit() * s].map(|p| p.as_vec3()),
        });
    }
    let (mut hits, mut lanes) = (0usize, 0usize);
    // blocks of 1..=8 triangles, so padding lanes are exercised too
    let mut start = 0;
    let mut k = 0;
    while start < tris.len() {
        let len = (k % 8 + 1).min(tris.len() - start);
        k += 1;
        let block = &tris[start..start + len];
        start += len;
        let t8 = Triangle8::new(block);
        for q in 0..24 {
            let target = &block[rng.next_u64() as usize % len];
            let aim = match q % 4 {
                0 => {
                    let (b1, b2) = (rng.f64() as f32, rng.f64() as f32);
                    let (b1, b2) = if b1 + b2 > 1.0 {
                        (1.0 - b1, 1.0 - b2)
                    } else {
                        (b1, b2)
                    };
                    target.v[0]
                        + (target.v[1] - target.v[0]) * b1
                        + (target.v[2] - target.v[0]) * b2
                }
                1 => target.v[q % 3],
                2 => (target.v[0] + target.v[1]) * 0.5,
                _ => rng.vec_in(DVec3::splat(-2.0), DVec3::splat(2.0)).as_vec3(),
            };
            let o = rng.vec_in(DVec3::splat(-4.0), DVec3::splat(4.0)).as_vec3();
            let r = Ray1::new(o, (aim - o).normalize());
            let tr = TriRay8::new(&r);
            for t_max in [f32::INFINITY, rng.range(0.0, 8.0) as f32] {
                let (m, t, u, v) = t8.intersect_1x8(&tr, Mask8::ALL, t_max);
                let occ = t8.occluded_1x8(&tr, Mask8::ALL, t_max);
                for lane in len..8 {
                    assert!(!m.lane(lane) && !occ.lane(lane), "padding lane {lane} hit");
                }
                for (lane, tri) in block.iter().enumerate() {
                    lanes += 1;
                    let one = tri.intersect_1(&r, t_max);
                    let eight = m
                        .lane(lane)
                        .then(|| (t.to_array()[lane], u.to_array()[lane], v.to_array()[lane]));
                    assert_eq!(
                        one.map(|h| (h.0.to_bits(), h.1.to_bits(), h.2.to_bits())),
                        eight.map(|h| (h.0.to_bits(), h.1.to_bits(), h.2.to_bits())),
                        "lane {lane}, ray {r:?}, t_max {t_max}"
                    );
                    assert_eq!(occ.lane(lane), tri.occluded_1(&r, t_max));
                    hits += one.is_some() as usize;
                }
            }
        }
    }
    println!("kernel: {hits} hits in {lanes} lane tests");
    assert!(
        hits * 20 > lanes,
        "too few hits ({hits} of {lanes}) to test anything"
    );
}

/// Per-lane tally of the packet comparisons.
#[derive(Debug, Default)]
struct PacketTally {
    lanes: usize,
    hits: usize,
    ties: usize,
    edge: usize,
    /// Packets whose active lanes share their direction signs (the wide packet walk).
    one_octant: usize,
    packets: usize,
}

/// The direction signs of a ray (bit k: 1/d < 0 on axis k).
fn octant(r: &Ray1) -> u32 {
    (0..3).map(|a| ((r.inv_dir[a] < 0.0) as u32) << a).sum()
}

/// Packets of `rays` in order, eight at a time; with `by_octant`, first sorted by
/// direction signs (stable) so that most packets share them.
fn packets_of(rays: &[Ray1], by_octant: bool) -> Vec<Vec<Ray1>> {
    let mut rays = rays.to_vec();
    if by_octant {
        rays.sort_by_key(octant);
    }
    rays.chunks(8).map(|c| c.to_vec()).collect()
}

/// Packet walks against the binary single-ray walk, lane by lane: closest hit (the
/// rules of `compare`) and any hit at random t_max, at each lane's hit and just past it.
/// Lanes outside a random active mask hold NaN and must be left untouched; with
/// `nan_lane`, one active lane of some packets is NaN and must miss.
fn compare_packets(
    name: &str,
    bvh: &Bvh,
    packets: &[Vec<Ray1>],
    rng: &mut Rng,
    nan_lane: bool,
) -> (PacketTally, Steps, Steps) {
    let mut out = (PacketTally::default(), Steps::default(), Steps::default());
    // the packet walks as the renderer calls them, then every packet whose lanes share
    // their signs and lie within `LANES_SPREAD` through the hybrid walk (spread 0: past
    // the frustum's limit), then every such packet forced through the frustum walk
    // (spread ∞), however incoherent
    for spread in [FRUSTUM_SPREAD, 0.0, f32::INFINITY] {
        let name = format!("{name} (spread {spread})");
        let r = compare_packets_at(&name, bvh, packets, rng, nan_lane, spread);
        if spread == FRUSTUM_SPREAD {
            out = r;
        }
    }
    out
}

fn compare_packets_at(
    name: &str,
    bvh: &Bvh,
    packets: &[Vec<Ray1>],
    rng: &mut Rng,
    nan_lane: bool,
    spread: f32,
) -> (PacketTally, Steps, Steps) {
    let mut tally = PacketTally::default();
    let (mut sx, mut sxb, mut sb) = (Steps::default(), Steps::default(), Steps::default());
    for (pi, rays) in packets.iter().enumerate() {
        tally.packets += 1;
        // random active lanes in a third of the packets, all present lanes otherwise
        let present = (1u32 << rays.len()) - 1;
        let bits = if pi % 3 == 0 {
            (rng.next_u64() as u32 & present).max(1 << (rays.len() - 1))
        } else {
            present
        };
        let mut o = [Vec3::NAN; 8];
        let mut d = [Vec3::NAN; 8];
        for (l, r) in rays.iter().enumerate() {
            if bits >> l & 1 == 1 {
                o[l] = r.origin;
                d[l] = r.dir;
            }
        }
        let mut nan = 0;
        if nan_lane && pi % 4 == 1 && bits.count_ones() > 1 {
            let l = bits.trailing_zeros() as usize;
            o[l] = Vec3::new(f32::NAN, 0.0, 0.0);
            nan = 1 << l;
        }
        if nan_lane && pi % 4 == 3 && bits.count_ones() > 1 {
            // a direction infinite on every axis, its signs the lane's own: 1/d is all
            // ±0, finite, and the lane still shares the packet's octant
            let l = bits.trailing_zeros() as usize;
            d[l] = d[l].signum() * f32::INFINITY;
            nan = 1 << l;
        }
        let active = Mask8::from_bits(bits);
        let p = RayPacket8::new(Vec3x8::from_lanes(&o), Vec3x8::from_lanes(&d), active);
        let shared = (0..8)
            .filter(|&l| bits >> l & 1 == 1 && nan >> l & 1 == 0)
            .map(|l| octant(&rays[l]))
            .collect::<Vec<_>>();
        tally.one_octant += shared.windows(2).all(|w| w[0] == w[1]) as usize;
        let t0 = f32x8::new(std::array::from_fn::<f32, 8, _>(|l| {
            if l % 5 == 4 { 2.5 } else { f32::INFINITY }
        }));
        let mut hp = HitPacket8::new(t0);
        bvh.intersect_x8_spread::<Watertight>(&p, active, spread, &mut hp, &mut sx);
        let mut hpb = HitPacket8::new(t0);
        bvh.intersect_x8_binary::<Watertight>(&p, active, &mut hpb, &mut sxb);
        let t_occ = f32x8::new(std::array::from_fn::<f32, 8, _>(|_| {
            rng.range(0.0, 3.0) as f32
        }));
        let occ = bvh.occluded_x8_spread::<Watertight>(&p, active, spread, t_occ, &mut sx);
        let (ht, hu, hv) = (hp.t.to_array(), hp.u.to_array(), hp.v.to_array());
        let mut hit_t = [f32::INFINITY; 8];
        for l in 0..8 {
            if bits >> l & 1 == 0 {
                assert!(
                    hp.prim_lane(l) < 0 && ht[l] == t0.to_array()[l],
                    "{name}: inactive lane {l} touched"
                );
                assert!(!occ.lane(l), "{name}: inactive lane {l} occluded");
                continue;
            }
            if nan >> l & 1 == 1 {
                assert!(
                    hp.prim_lane(l) < 0 && !occ.lane(l),
                    "{name}: NaN or infinite lane {l} hit"
                );
                continue;
            }
            tally.lanes += 1;
            let r = p.ray(l);
            let hx = Hit1 {
                t: ht[l],
                prim: hp.prim_lane(l),
                u: hu[l],
                v: hv[l],
            };
            let hb = closest(bvh, &r, t0.to_array()[l], false, &mut sb);
            let ctx = format!("{name}: packet {pi} lane {l} {r:?}: packet {hx:?} vs binary {hb:?}");
            assert_eq!(hx.is_hit(), hb.is_hit(), "{ctx}");
            // the binary packet walk too (it serves packets in small trees and packets
            // too spread for the frustum)
            assert_eq!(
                hpb.prim_lane(l) >= 0,
                hb.is_hit(),
                "{ctx}: binary packet walk"
            );
            let mut edge_lane = false;
            if hx.prim == hb.prim {
                assert_eq!(
                    (hx.t.to_bits(), hx.u.to_bits(), hx.v.to_bits()),
                    (hb.t.to_bits(), hb.u.to_bits(), hb.v.to_bits()),
                    "{ctx}"
                );
            } else if hx.is_hit()
                && hx.t == hb.t
                && bvh.prims.object(hx.prim) == bvh.prims.object(hb.prim)
            {
                tally.ties += 1;
            } else {
                assert!(at_edge(&hx) || at_edge(&hb), "{ctx}: not at an edge");
                tally.edge += 1;
                edge_lane = true;
            }
            tally.hits += hx.is_hit() as usize;
            hit_t[l] = if hb.is_hit() {
                hb.t
            } else {
                rng.range(0.0, 3.0) as f32
            };
            let ob = bvh.occluded_1_binary::<Watertight>(&r, t_occ.to_array()[l], &mut sb);
            assert!(
                occ.lane(l) == ob || edge_lane || at_edge(&hb),
                "{ctx}: occluded at {t_occ:?}"
            );
            tally.edge += (occ.lane(l) != ob && !edge_lane) as usize;
        }
        // any hit exactly at each lane's hit (nothing nearer: not occluded) and just past it
        let live = Mask8::from_bits(bits & !nan);
        for past in [false, true] {
            let tm = f32x8::new(hit_t.map(|t| if past { t.next_up() } else { t }));
            let occ = bvh.occluded_x8_spread::<Watertight>(&p, live, spread, tm, &mut sx);
            for l in 0..8 {
                if live.lane(l) {
                    let r = p.ray(l);
                    let ob = bvh.occluded_1_binary::<Watertight>(&r, tm.to_array()[l], &mut sb);
                    let hb = closest(bvh, &r, f32::INFINITY, false, &mut sb);
                    // (a clipped quadric's any-hit kernels, packet and single, decide
                    // t == t_max within an ulp of each other, not bit for bit:
                    // `tests/equiv_geometry.rs` holds them to a tolerance)
                    let quadric =
                        hb.is_hit() && split_code(hb.prim).unwrap().0 == PrimKind::Quadric;
                    assert!(
                        occ.lane(l) == ob || at_edge(&hb) || quadric,
                        "{name}: packet {pi} lane {l} {r:?}: occluded at {} (past {past}): packet {}, binary {ob}, hit {hb:?} ({:?})",
                        tm.to_array()[l],
                        occ.lane(l),
                        split_code(hb.prim).unwrap().0
                    );
                }
            }
        }
    }
    println!("{name}: {tally:?}, packet {sx:?}, binary packet {sxb:?}");
    assert!(
        tally.edge * 200 <= tally.lanes,
        "{name}: too many edge differences: {tally:?}"
    );
    (tally, sx, sxb)
}

/// `Bvh::build` keeps the binary tree only where packets walk it: a torus's goes in
/// the collapse, and every query (single rays and packets, closest and any hit) gets
/// the answers of the tree that keeps it; a few triangles' stays (their wide tree is
/// too small for the packet walks); and the binary walks refuse a tree without it.
#[test]
fn the_binary_tree_stays_only_where_packets_walk_it() {
    let tris = torus(96, 48);
    let with = Bvh::build_with_binary(PrimSet::from_triangles(tris.clone()));
    let bvh = Bvh::build(PrimSet::from_triangles(tris));
    assert!(bvh.nodes.is_empty() && !bvh.packets_walk_binary() && !with.nodes.is_empty());
    assert_eq!(bvh.root.map(|r| r.bounds()), with.root.map(|r| r.bounds()));
    assert_eq!(bvh.validate(), Ok(()));
    let mut rng = Rng(41);
    let mut steps = Steps::default();
    let (mut lanes, mut hits) = (0, 0);
    for rays in [primary_rays(64, 64), incoherent_rays(4096, 7)] {
        let rays = rays_of(&rays);
        for chunk in rays.chunks(8) {
            let o: [Vec3; 8] = std::array::from_fn(|l| chunk[l % chunk.len()].origin);
            let d: [Vec3; 8] = std::array::from_fn(|l| chunk[l % chunk.len()].dir);
            let p = RayPacket8::new(Vec3x8::from_lanes(&o), Vec3x8::from_lanes(&d), Mask8::ALL);
            let t0 = f32x8::splat(f32::INFINITY);
            let (mut a, mut b) = (HitPacket8::new(t0), HitPacket8::new(t0));
            bvh.intersect_x8::<Watertight>(&p, Mask8::ALL, &mut a, &mut steps);
            with.intersect_x8::<Watertight>(&p, Mask8::ALL, &mut b, &mut steps);
            let t_max = f32x8::new(std::array::from_fn(|_| rng.range(0.1, 4.0) as f32));
            let occ = bvh.occluded_x8::<Watertight>(&p, Mask8::ALL, t_max, &mut steps);
            let occ_w = with.occluded_x8::<Watertight>(&p, Mask8::ALL, t_max, &mut steps);
            for l in 0..8 {
                let r = p.ray(l);
                let (mut h, mut hw) = (Hit1::new(f32::INFINITY), Hit1::new(f32::INFINITY));
                bvh.intersect_1::<Watertight>(&r, &mut h, &mut steps);
                with.intersect_1::<Watertight>(&r, &mut hw, &mut steps);
                let tm = t_max.to_array()[l];
                let lane = |h: &HitPacket8| (h.t.to_array()[l].to_bits(), h.prim_lane(l));
                assert_eq!(lane(&a), lane(&b), "lane {l} of {r:?}");
                assert_eq!(occ.lane(l), occ_w.lane(l), "lane {l} of {r:?}");
                assert_eq!((h.t.to_bits(), h.prim), (hw.t.to_bits(), hw.prim), "{r:?}");
                assert_eq!(
                    bvh.occluded_1::<Watertight>(&r, tm, &mut steps),
                    with.occluded_1::<Watertight>(&r, tm, &mut steps)
                );
                lanes += 1;
                hits += h.is_hit() as usize;
            }
        }
    }
    assert!(hits > lanes / 4, "{hits} hits of {lanes} rays");
    let small = Bvh::build(PrimSet::from_triangles(torus(6, 4)));
    assert!(small.packets_walk_binary() && !small.nodes.is_empty());
    let r = Ray1::new(
        Vec3::new(0.0, 0.0, 5.0),
        Vec3::new(0.01, 0.02, -1.0).normalize(),
    );
    let refused = std::panic::catch_unwind(|| {
        bvh.intersect_1_binary::<Watertight>(
            &r,
            &mut Hit1::new(f32::INFINITY),
            &mut Steps::default(),
        )
    });
    assert!(refused.is_err(), "a binary walk without the binary tree");
}

/// Packets past the frustum's limit whose lanes share their direction signs within
/// `LANES_SPREAD` (a curved mirror's: origins a millimetre apart, directions 0.03 to
/// 0.19 rad apart) take the hybrid walk of the wide tree: every lane gets what the
/// binary packet walk gives it, bit for bit (t, primitive, u, v), and the same shadow
/// answer.
#[test]
fn spread_packets_take_the_hybrid_walk_and_get_the_binary_walks_answers() {
    let bvh = torus_bvh();
    let mut rng = Rng(31);
    let (mut packets, mut hits, mut blocked, mut lanes) = (0, 0, 0, 0);
    while packets < 4000 {
        // at least 0.4 from every axis plane: a turn of 0.19 rad keeps every sign
        let base = rng.unit();
        if base.abs().min_element() < 0.4 {
            continue;
        }
        packets += 1;
        // a unit vector across `base`
        let across = |rng: &mut Rng| {
            let u = rng.unit();
            (u - base * u.dot(base)).normalize()
        };
        // lane 0 along `base`, lane 1 `spread` from it: past the frustum's limit
        let spread = rng.range(
            2.0 * f64::from(FRUSTUM_SPREAD),
            0.8 * f64::from(LANES_SPREAD),
        );
        let at = DVec3::new(
            rng.range(-1.3, 1.3),
            rng.range(-1.3, 1.3),
            rng.range(-0.35, 0.35),
        );
        let mut o = [Vec3::ZERO; 8];
        let mut d = [Vec3::ZERO; 8];
        for l in 0..8 {
            let turn = match l {
                0 => 0.0,
                1 => spread,
                _ => rng.range(0.0, spread),
            };
            d[l] = (base + across(&mut rng) * turn).normalize().as_vec3();
            o[l] = (at + rng.unit() * 1e-3).as_vec3();
        }
        let active = Mask8::ALL;
        let p = RayPacket8::new(Vec3x8::from_lanes(&o), Vec3x8::from_lanes(&d), active);
        let t0 = f32x8::splat(f32::INFINITY);
        let (mut h, mut hb) = (HitPacket8::new(t0), HitPacket8::new(t0));
        let mut steps = Steps::default();
        bvh.intersect_x8::<Watertight>(&p, active, &mut h, &mut steps);
        bvh.intersect_x8_binary::<Watertight>(&p, active, &mut hb, &mut steps);
        let t_occ = f32x8::new(std::array::from_fn(|_| rng.range(0.05, 2.0) as f32));
        let occ = bvh.occluded_x8::<Watertight>(&p, active, t_occ, &mut steps);
        let occ_b = bvh.occluded_x8_binary::<Watertight>(&p, active, t_occ, &mut steps);
        for l in 0..8 {
            let lane = |h: &HitPacket8| {
                let [t, u, v] = [h.t, h.u, h.v].map(|x| x.to_array()[l].to_bits());
                (t, h.prim_lane(l), u, v)
            };
            assert_eq!(
                lane(&h),
                lane(&hb),
                "packet {packets}, lane {l}: {:?}",
                p.ray(l)
            );
            assert_eq!(
                occ.lane(l),
                occ_b.lane(l),
                "packet {packets}, lane {l} (shadow)"
            );
            lanes += 1;
            hits += (h.prim_lane(l) >= 0) as usize;
            blocked += occ.lane(l) as usize;
        }
    }
    assert!(
        hits > lanes / 4 && hits < lanes,
        "{hits} hits of {lanes} lanes"
    );
    assert!(
        blocked > lanes / 8 && blocked < lanes,
        "{blocked} blocked of {lanes} lanes"
    );
}

#[test]
fn packet_walks_equal_binary_on_a_torus_coherent() {
    let bvh = torus_bvh();
    let mut rng = Rng(21);
    let packets = packets_of(&rays_of(&primary_rays(128, 128)), false);
    let (t, sx, sxb) = compare_packets("packets primary", &bvh, &packets, &mut rng, true);
    assert!(t.hits > t.lanes / 3, "{t:?}");
    // camera packets share their direction signs but at the image's centre lines: the
    // wide walk serves nearly all, with fewer (8-wide) node tests than the binary walk
    assert!(t.one_octant * 10 >= t.packets * 9, "{t:?}");
    assert!(sx.boxes < sxb.boxes, "wide {sx:?} vs binary {sxb:?}");
}

#[test]
fn packet_walks_equal_binary_on_a_torus_incoherent() {
    let bvh = torus_bvh();
    let mut rng = Rng(22);
    let rays = rays_of(&incoherent_rays(16_000, 5));
    // as they come (mixed signs: lane by lane through the wide tree) and grouped by
    // signs (the wide walk with wide frustums)
    for by_octant in [false, true] {
        let packets = packets_of(&rays, by_octant);
        let (t, _, _) = compare_packets("packets incoherent", &bvh, &packets, &mut rng, true);
        assert!(t.hits > t.lanes / 3, "{t:?}");
        if by_octant {
            assert!(t.one_octant * 10 >= t.packets * 9, "{t:?}");
        }
    }
    // a packet of mixed signs, and one of shared signs whose origins lie far apart,
    // take exactly the single-ray walks of their lanes (same node and primitive
    // tests), closest and any hit
    let packets = packets_of(&rays, false);
    let mixed = packets
        .iter()
        .find(|p| p.len() == 8 && p.iter().any(|r| octant(r) != octant(&p[0])))
        .expect("a packet of mixed signs");
    walks_as_its_lanes(&bvh, mixed);
    let extent = |p: &[Ray1]| {
        let lo = p.iter().fold(Vec3::INFINITY, |m, r| m.min(r.origin));
        let hi = p.iter().fold(Vec3::NEG_INFINITY, |m, r| m.max(r.origin));
        (hi - lo).max_element()
    };
    let scattered = packets_of(&rays, true)
        .into_iter()
        .find(|p| p.len() == 8 && extent(p) > 2.0 * LANES_SPREAD * bvh.wide.diagonal)
        .expect("a packet of one octant, origins far apart");
    walks_as_its_lanes(&bvh, &scattered);
}

/// The packet walks of the eight `rays` give each lane its single-ray walk's answers,
/// closest and any hit, with the same node and primitive tests.
fn walks_as_its_lanes(bvh: &Bvh, rays: &[Ray1]) {
    let o: [Vec3; 8] = std::array::from_fn(|l| rays[l].origin);
    let d: [Vec3; 8] = std::array::from_fn(|l| rays[l].dir);
    let p = RayPacket8::new(Vec3x8::from_lanes(&o), Vec3x8::from_lanes(&d), Mask8::ALL);
    let (mut sx, mut s1) = (Steps::default(), Steps::default());
    let mut hp = HitPacket8::new(f32x8::splat(f32::INFINITY));
    bvh.intersect_x8::<Watertight>(&p, Mask8::ALL, &mut hp, &mut sx);
    let tm = f32x8::splat(1.0);
    let occ = bvh.occluded_x8::<Watertight>(&p, Mask8::ALL, tm, &mut sx);
    for l in 0..8 {
        let mut h = Hit1::new(f32::INFINITY);
        bvh.intersect_1::<Watertight>(&p.ray(l), &mut h, &mut s1);
        let hl = (
            hp.t.to_array()[l],
            hp.prim_lane(l),
            hp.u.to_array()[l],
            hp.v.to_array()[l],
        );
        assert_eq!((h.t, h.prim, h.u, h.v), hl);
        assert_eq!(
            bvh.occluded_1::<Watertight>(&p.ray(l), 1.0, &mut s1),
            occ.lane(l)
        );
    }
    assert_eq!(sx, s1, "the packet walks as its eight lanes do");
}

#[test]
fn packet_walks_equal_binary_through_shared_edges_signed_zeros_and_mixed_kinds() {
    let tris = torus(96, 48);
    let bvh = Bvh::build_with_binary(PrimSet::from_triangles(tris.clone()));
    let mut rng = Rng(23);
    let (lo, hi) = (Vec3::new(-2.0, -1.5, -2.0), Vec3::new(2.0, 1.5, 2.0));
    let edges = edge_rays(&tris, 16_000, lo, hi, &mut rng);
    let (t, _, _) = compare_packets(
        "packets edges",
        &bvh,
        &packets_of(&edges, true),
        &mut rng,
        false,
    );
    assert!(t.hits * 10 >= t.lanes * 9, "{t:?}");
    // rays aimed at points near one spot from one origin: coherent packets over edges
    let spot: Vec<Ray1> = (0..8_000)
        .map(|k| {
            let tri = &tris[(k / 64 * 37) % tris.len()];
            let o = Vec3::new(0.3, 2.0, 2.5);
            let aim = tri.v[k % 3] + (tri.v[(k + 1) % 3] - tri.v[k % 3]) * ((k % 64) as f32 / 64.0);
            Ray1::new(o, (aim - o).normalize())
        })
        .collect();
    let (t, _, _) = compare_packets(
        "packets spot edges",
        &bvh,
        &packets_of(&spot, false),
        &mut rng,
        true,
    );
    assert!(t.one_octant * 2 >= t.packets, "{t:?}");
    let zeros = signed_zero_rays(Vec3::new(-1.6, -0.5, -1.6), Vec3::new(1.6, 0.5, 1.6), 40);
    for by_octant in [false, true] {
        let (t, _, _) = compare_packets(
            "packets signed zeros",
            &bvh,
            &packets_of(&zeros, by_octant),
            &mut rng,
            false,
        );
        assert!(t.hits > t.lanes / 4, "{t:?}");
    }
    // every kind, exact ties between duplicated objects, the list beside the tree
    let scene = mixed_scene();
    let bvh = Bvh::build_with_binary(PrimSet::from_scene(&scene, DVec3::new(0.0, 0.0, 20.0)));
    let (lo, hi) = (
        Vec3::new(-100.0, -100.0, -20.0),
        Vec3::new(80.0, 80.0, 50.0),
    );
    let mut rays: Vec<Ray1> = Vec::new();
    for k in 0..12_000 {
        let kind = PrimKind::BVH_KINDS[k % 3];
        let p = &bvh.prims;
        let b = p.bounds(kind, rng.next_u64() as usize % p.len(kind));
        let o = Vec3::new(
            rng.range(lo.x as f64, hi.x as f64) as f32,
            rng.range(lo.y as f64, hi.y as f64) as f32,
            hi.z,
        );
        rays.push(Ray1::new(o, (b.centroid() - o).normalize()));
    }
    rays.extend(edge_rays(
        &triangles_of(&bvh.prims),
        4_000,
        lo,
        hi,
        &mut rng,
    ));
    // grouped by signs (frustum walks) and as they come (mixed signs: lane by lane,
    // with the floor and the free quadrics beside the tree tested once per lane)
    assert!(
        bvh.wide.nodes.len() >= LANES_MIN_NODES,
        "a tree the lane walk serves"
    );
    for by_octant in [true, false] {
        let (t, sx, _) = compare_packets(
            "packets mixed",
            &bvh,
            &packets_of(&rays, by_octant),
            &mut rng,
            true,
        );
        assert!(t.hits > t.lanes / 3, "{t:?}");
        assert!(sx.quadrics > 0, "{sx:?}");
        if !by_octant {
            assert!(t.one_octant * 2 < t.packets, "{t:?}");
        }
    }
}

/// Closest-hit packets over the floor (`PrimSet::bound_by_floor_x8`): a torus standing
/// half below the floor, seen from above, as in the benchmark frames. A lane that meets
/// the floor looks for objects only a little past it, yet every lane gets what the
/// unbounded single-ray walk (the floor tested after the tree) gives it, bit for bit, on
/// every route a packet can take (the frustum walk, the binary packet walk, the lanes'
/// single-ray walks), with some lanes starting from a finite bound; and the frustum walk
/// skips the half below the floor: far fewer node tests than the same packets over the
/// same torus without a floor.
#[test]
fn packets_bounded_by_the_floor_get_the_unbounded_hits() {
    let mut prims = PrimSet::from_triangles(torus(96, 48));
    prims.floor = Some(octaray::geometry::floor::Floor32::new(DVec3::ZERO));
    let floor = Bvh::build_with_binary(prims);
    let bare = torus_bvh();
    let rays = rays_of(&primary_rays(128, 128));
    // lanes 3 and 6 start from a finite bound: one short of most hits, one beyond them
    let t0 = f32x8::new(std::array::from_fn(|l| match l {
        3 => 2.0,
        6 => 4.0,
        _ => f32::INFINITY,
    }));
    let (mut s_floor, mut s_bare, mut s_single) =
        (Steps::default(), Steps::default(), Steps::default());
    let (mut on_floor, mut on_torus) = (0, 0);
    // the frustum walk (the renderer's limit), the binary packet walk (spread < 0), every
    // packet of shared signs through the frustum (∞), and the lanes' own walks
    for route in 0..4 {
        for (pi, chunk) in rays.chunks(8).enumerate() {
            let lanes =
                |f: fn(&Ray1) -> Vec3| Vec3x8::from_lanes(&std::array::from_fn(|l| f(&chunk[l])));
            let p = RayPacket8::new(lanes(|r| r.origin), lanes(|r| r.dir), Mask8::ALL);
            let mut h = HitPacket8::new(t0);
            let steps = &mut s_floor;
            match route {
                0 => floor.intersect_x8_spread::<Watertight>(
                    &p,
                    Mask8::ALL,
                    FRUSTUM_SPREAD,
                    &mut h,
                    steps,
                ),
                1 => floor.intersect_x8_spread::<Watertight>(&p, Mask8::ALL, -1.0, &mut h, steps),
                2 => floor.intersect_x8_spread::<Watertight>(
                    &p,
                    Mask8::ALL,
                    f32::INFINITY,
                    &mut h,
                    steps,
                ),
                _ => floor.intersect_x8_lanes::<Watertight>(&p, Mask8::ALL, &mut h, steps),
            }
            if route == 0 {
                let mut hb = HitPacket8::new(t0);
                bare.intersect_x8_spread::<Watertight>(
                    &p,
                    Mask8::ALL,
                    FRUSTUM_SPREAD,
                    &mut hb,
                    &mut s_bare,
                );
            }
            let (t, u, v) = (h.t.to_array(), h.u.to_array(), h.v.to_array());
            for l in 0..8 {
                let want = closest(&floor, &p.ray(l), t0.to_array()[l], false, &mut s_single);
                assert_eq!(
                    (
                        h.prim_lane(l),
                        t[l].to_bits(),
                        u[l].to_bits(),
                        v[l].to_bits()
                    ),
                    (
                        want.prim,
                        want.t.to_bits(),
                        want.u.to_bits(),
                        want.v.to_bits()
                    ),
                    "route {route} packet {pi} lane {l}: {:?}",
                    p.ray(l)
                );
                if route == 0 {
                    match want.is_hit().then(|| split_code(want.prim).unwrap().0) {
                        Some(PrimKind::Floor) => on_floor += 1,
                        Some(_) => on_torus += 1,
                        None => {}
                    }
                }
            }
        }
        if route == 0 {
            // rays of both kinds, and many floor rays that go on to the torus below it
            assert!(
                on_floor > rays.len() / 4 && on_torus > rays.len() / 8,
                "{on_floor} {on_torus}"
            );
            assert!(
                s_floor.boxes * 10 < s_bare.boxes * 8,
                "node tests with the floor {s_floor:?}, without {s_bare:?}"
            );
        }
    }
}

/// A packet whose lanes' origins differ only in the sign of a zero is not one of one
/// origin: each lane gets its own bits (a vertex at −0 moved to +0 and to −0 gives
/// zeros of different signs, which reach the barycentrics), through the frustum walk
/// as through the binary single-ray walk.
#[test]
fn origins_differing_in_a_zeros_sign_keep_each_lanes_bits() {
    let mut tris = vec![Triangle32 {
        v: [
            Vec3::new(-0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
        ],
    }];
    // enough triangles beside it for a wide tree
    for i in 0..200 {
        let (x, y) = (3.0 + (i % 20) as f32, 3.0 + (i / 20) as f32);
        tris.push(Triangle32 {
            v: [
                Vec3::new(x, y, 0.0),
                Vec3::new(x + 0.5, y, 0.0),
                Vec3::new(x, y + 0.5, 0.0),
            ],
        });
    }
    let bvh = Bvh::build_with_binary(PrimSet::from_triangles(tris));
    assert!(!bvh.wide.nodes.is_empty());
    for (first, rest) in [(0.0f32, -0.0f32), (-0.0, 0.0)] {
        let mut o = [Vec3::new(rest, 0.0, 5.0); 8];
        o[0].x = first;
        let p = RayPacket8::new(
            Vec3x8::from_lanes(&o),
            Vec3x8::splat(Vec3::NEG_Z),
            Mask8::ALL,
        );
        for spread in [FRUSTUM_SPREAD, f32::INFINITY] {
            let mut hp = HitPacket8::new(f32x8::splat(f32::INFINITY));
            let mut s = Steps::default();
            bvh.intersect_x8_spread::<Watertight>(&p, Mask8::ALL, spread, &mut hp, &mut s);
            for l in 0..8 {
                let mut h = Hit1::new(f32::INFINITY);
                bvh.intersect_1_binary::<Watertight>(&p.ray(l), &mut h, &mut s);
                assert!(h.is_hit(), "lane {l} meets the triangle at its corner");
                let bits = |t: f32, u: f32, v: f32| [t, u, v].map(f32::to_bits);
                assert_eq!(
                    (
                        hp.prim_lane(l),
                        bits(hp.t.to_array()[l], hp.u.to_array()[l], hp.v.to_array()[l])
                    ),
                    (h.prim, bits(h.t, h.u, h.v)),
                    "origins x = {first} then {rest}, spread {spread}, lane {l}"
                );
            }
        }
    }
}

/// Each ray of `rays` as one stream (`Bvh::intersect_stream`/`occluded_stream`) gets
/// what the single-ray queries give it, bit for bit, with the same node and primitive
/// tests in all; `t_max` per ray, the shadow queries' bound and the closest-hit
/// queries' starting `t`.
fn stream_as_single_queries(bvh: &Bvh, rays: &[Ray1], t_max: &[f32]) -> usize {
    let (mut ss, mut s1) = (Steps::default(), Steps::default());
    let mut hits: Vec<Hit1> = t_max.iter().map(|&t| Hit1::new(t)).collect();
    bvh.intersect_stream::<Watertight>(rays, &mut hits, &mut ss);
    let mut blocked = vec![false; rays.len()];
    bvh.occluded_stream::<Watertight>(rays, t_max, &mut blocked, &mut ss);
    let mut n_hits = 0;
    for ((r, h), (&tm, &b)) in rays.iter().zip(&hits).zip(t_max.iter().zip(&blocked)) {
        let mut one = Hit1::new(tm);
        bvh.intersect_1::<Watertight>(r, &mut one, &mut s1);
        assert_eq!(
            (one.t.to_bits(), one.prim, one.u.to_bits(), one.v.to_bits()),
            (h.t.to_bits(), h.prim, h.u.to_bits(), h.v.to_bits()),
            "ray {r:?}"
        );
        assert_eq!(
            bvh.occluded_1::<Watertight>(r, tm, &mut s1),
            b,
            "ray {r:?}, t_max {tm}"
        );
        n_hits += h.is_hit() as usize;
    }
    assert_eq!(ss, s1, "the streams make the single queries' tests");
    n_hits
}

#[test]
fn streams_give_every_ray_what_single_queries_give_it() {
    let tris = torus(96, 48);
    let big = Bvh::build_with_binary(PrimSet::from_triangles(tris.clone()));
    let mixed = Bvh::build_with_binary(PrimSet::from_scene(
        &mixed_scene(),
        DVec3::new(0.0, 0.0, 20.0),
    ));
    // these trees are too small for stepped streams: each is tested both ways
    for b in [&big, &mixed] {
        assert!(!b.wide.stream_steps && !b.wide.stream_any_hit_steps);
    }
    // a floor and nothing in the tree
    let floor_only = {
        let mut scene = mixed_scene();
        scene.objects.clear();
        Bvh::build_with_binary(PrimSet::from_scene(&scene, DVec3::ZERO))
    };
    assert!(floor_only.prims.floor.is_some() && floor_only.wide.nodes.is_empty());
    let stepped = |b: &Bvh| {
        let mut b = b.clone();
        (b.wide.stream_steps, b.wide.stream_any_hit_steps) = (true, true);
        b
    };
    let (big_s, mixed_s) = (stepped(&big), stepped(&mixed));
    let mut rng = Rng(31);
    let torus_box = (Vec3::new(-2.0, -1.5, -2.0), Vec3::new(2.0, 1.5, 2.0));
    let mixed_box = (
        Vec3::new(-100.0, -100.0, -20.0),
        Vec3::new(80.0, 80.0, 50.0),
    );
    let floor_s = stepped(&floor_only);
    for (bvh, (lo, hi)) in [
        (&big, torus_box),
        (&big_s, torus_box),
        (&mixed, mixed_box),
        (&mixed_s, mixed_box),
        (&floor_only, mixed_box),
        (&floor_s, mixed_box),
    ] {
        let mut rays = rays_of(&incoherent_rays(3_000, 5));
        if !bvh.prims.blocks.is_empty() {
            rays.extend(edge_rays(
                &triangles_of(&bvh.prims),
                2_000,
                lo,
                hi,
                &mut rng,
            ));
        }
        rays.extend(signed_zero_rays(lo, hi, 10));
        // rays that never enter the tree, here and there in the stream
        for k in [0, 17, 500, 3_001] {
            rays.insert(k, Ray1::new(Vec3::new(f32::NAN, 0.0, 1.0), Vec3::NEG_Z));
        }
        rays.push(Ray1::new(Vec3::ZERO, Vec3::splat(f32::INFINITY)));
        // bounds: none (0, −0, negative, NaN), short, long, unbounded
        let t_max: Vec<f32> = (0..rays.len())
            .map(|k| match k % 13 {
                0 => 0.0,
                1 => -0.0,
                2 => -1.0,
                3 => f32::NAN,
                4..=6 => f32::INFINITY,
                _ => rng.f64() as f32 * 3.0,
            })
            .collect();
        let hits = stream_as_single_queries(bvh, &rays, &t_max);
        if !bvh.wide.nodes.is_empty() {
            assert!(hits > rays.len() / 8, "{hits} of {}", rays.len());
        }
        // streams shorter than the walks in flight, and empty
        for n in [0, 1, 5, 16, 17] {
            stream_as_single_queries(bvh, &rays[1..1 + n], &t_max[1..1 + n]);
        }
        // a stream of rays that never enter the tree
        let nan = vec![Ray1::new(Vec3::splat(f32::NAN), Vec3::NEG_Z); 20];
        stream_as_single_queries(bvh, &nan, &t_max[..20]);
    }
}

/// Streams step their walks from the sizes `STREAM_FROM` and `STREAM_ANY_HIT_FROM` of the
/// arrays walked on, in every tree (the torus above stays below both).
#[test]
fn streams_step_only_in_trees_past_their_sizes() {
    for bvh in [
        torus_bvh(),
        Bvh::build_with_binary(PrimSet::from_triangles(torus(400, 100))),
    ] {
        let bytes = bvh.walked_bytes();
        assert_eq!(bvh.wide.stream_steps, bytes >= STREAM_FROM, "{bytes} B");
        assert_eq!(
            bvh.wide.stream_any_hit_steps,
            bytes >= STREAM_ANY_HIT_FROM,
            "{bytes} B"
        );
    }
    let big = Bvh::build_with_binary(PrimSet::from_triangles(torus(400, 100)));
    assert!(
        big.wide.stream_steps,
        "80k triangles walk {} B",
        big.walked_bytes()
    );
    assert!(!Bvh::build_with_binary(PrimSet::default()).wide.stream_steps);
}
