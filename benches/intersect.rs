//! Kernel throughput: `intersect/<kind>/1` (eight single-ray calls) against
//! `intersect/<kind>/x8` (one packet call) on the same eight rays, per kind.

use std::hint::black_box;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use glam::{DVec3, Vec3};
use octaray::geometry::floor::Floor32;
use octaray::geometry::quadric::Quadric32;
use octaray::geometry::sphere::Sphere32;
use octaray::geometry::triangle::Triangle32;
use octaray::math::packet::{Mask8, Ray1, RayPacket8};
use octaray::scene::Quadric;
use wide::f32x8;

/// 64 packets of rays from around (0, 0, 5) towards the unit square at the origin.
fn packets() -> Vec<(RayPacket8, [Ray1; 8])> {
    let mut s = 1u32;
    let mut next = move || {
        s ^= s << 13;
        s ^= s >> 17;
        s ^= s << 5;
        s as f32 / u32::MAX as f32
    };
    (0..64)
        .map(|_| {
            let mut o = [Vec3::ZERO; 8];
            let mut d = [Vec3::ZERO; 8];
            for k in 0..8 {
                o[k] = Vec3::new(next() - 0.5, next() - 0.5, 5.0);
                let target = Vec3::new(2.0 * next() - 1.0, 2.0 * next() - 1.0, 0.0);
                d[k] = (target - o[k]).normalize();
            }
            let rays = std::array::from_fn(|k| Ray1::new(o[k], d[k]));
            (RayPacket8::from_lanes(&o, &d), rays)
        })
        .collect()
}

fn bench(c: &mut Criterion) {
    let ps = packets();
    let sphere = Sphere32::new(DVec3::ZERO, 0.8, DVec3::ZERO);
    let tri = Triangle32::new(
        &[
            DVec3::new(-1.0, -1.0, 0.0),
            DVec3::new(1.0, -1.0, 0.0),
            DVec3::new(0.0, 1.0, 0.2),
        ],
        DVec3::ZERO,
    );
    let quadric = Quadric32::new(
        &Quadric {
            coef: [1.0, 1.0, 0.5, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -0.5],
            min: DVec3::new(-1.0, -1.0, -1.0),
            size: DVec3::new(2.0, 2.0, 1.2),
        },
        DVec3::ZERO,
    );
    let floor = Floor32::new(DVec3::new(0.0, 0.0, 0.0));
    let inf = f32x8::splat(f32::INFINITY);
    let mut g = c.benchmark_group("intersect");
    g.throughput(Throughput::Elements(8 * ps.len() as u64));
    macro_rules! kind {
        ($name:literal, $prim:expr, $one:expr) => {
            g.bench_function(concat!($name, "/1"), |b| {
                b.iter(|| {
                    let mut n = 0u32;
                    for (_, rays) in &ps {
                        for r in rays {
                            n += $one(black_box(&$prim), r) as u32;
                        }
                    }
                    n
                })
            });
            g.bench_function(concat!($name, "/x8"), |b| {
                b.iter(|| {
                    let mut n = 0u32;
                    for (p, _) in &ps {
                        n += black_box(&$prim).occluded_x8(p, Mask8::ALL, inf).count();
                    }
                    n
                })
            });
        };
    }
    kind!("sphere", sphere, |s: &Sphere32, r| s
        .intersect_1(r, f32::INFINITY)
        .is_some());
    kind!("triangle", tri, |s: &Triangle32, r| s
        .intersect_1(r, f32::INFINITY)
        .is_some());
    kind!("quadric", quadric, |s: &Quadric32, r| s
        .intersect_1(r, f32::INFINITY)
        .is_some());
    kind!("floor", floor, |s: &Floor32, r| s
        .intersect_1(r, f32::INFINITY)
        .is_some());
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
