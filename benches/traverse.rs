//! BVH traversal of the standard torus100k: coherent (primary camera rays in 4 × 2
//! packets) and incoherent rays, packet (`x8`: the 8-wide tree for coherent packets),
//! binary packet (`x8b`), single-ray (`1`) and stream (`1s`: sixteen walks in flight,
//! this tree being large enough for them) paths, 1 thread.
//! Steps per ray (box and triangle tests) are printed once.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use octaray::bvh::Bvh;
use octaray::bvh::bench::{Mode, RaySet, incoherent_rays, primary_rays, torus, trace};
use octaray::geometry::PrimSet;

fn subset(r: RaySet, n: usize) -> RaySet {
    // every k-th packet of 8, so coherent rays stay in their packets
    let step = r.origin.len() / (n / 8);
    let idx: Vec<usize> = (0..n / 8)
        .flat_map(|p| (0..8).map(move |k| p * step + k))
        .collect();
    RaySet {
        name: r.name,
        origin: idx.iter().map(|&i| r.origin[i]).collect(),
        dir: idx.iter().map(|&i| r.dir[i]).collect(),
    }
}

fn bench(c: &mut Criterion) {
    let bvh = Bvh::build(PrimSet::from_triangles(torus(250, 200)));
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let sets = [
        ("coherent", subset(primary_rays(1024, 1024), 1 << 16)),
        ("incoherent", incoherent_rays(1 << 14, 7)),
    ];
    let mut g = c.benchmark_group("traverse");
    for (name, rays) in &sets {
        g.throughput(Throughput::Elements(rays.origin.len() as u64));
        for (mode, tag) in [
            (Mode::Single, "1"),
            (Mode::Stream, "1s"),
            (Mode::Packet8, "x8"),
            (Mode::Packet8Binary, "x8b"),
        ] {
            let mut t = vec![0.0f32; rays.origin.len()];
            let steps = pool.install(|| trace(&bvh, rays, mode, &mut t));
            let n = rays.origin.len() as f64;
            eprintln!(
                "traverse/{name}/{tag}: {:.1} box tests, {:.1} triangle tests per ray",
                steps.boxes as f64 / n,
                steps.prims as f64 / n
            );
            g.bench_function(format!("{name}/{tag}"), |b| {
                b.iter(|| pool.install(|| trace(&bvh, rays, mode, &mut t)))
            });
        }
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
