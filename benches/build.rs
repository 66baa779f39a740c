//! Binned-SAH build of the standard torus100k (1 thread); prints node count, depth and
//! SAH cost once.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use octaray::bvh::bench::torus;
use octaray::bvh::{BinaryStats, Bvh};
use octaray::geometry::PrimSet;

fn bench(c: &mut Criterion) {
    let tris = torus(250, 200);
    let bvh = Bvh::build_with_binary(PrimSet::from_triangles(tris.clone()));
    let s = BinaryStats::of(&bvh.nodes);
    eprintln!(
        "build/torus100k: {} nodes, depth {}, SAH cost {:.2}",
        s.nodes, s.depth, s.sah_cost
    );
    let mut g = c.benchmark_group("build");
    g.sample_size(10);
    g.throughput(Throughput::Elements(tris.len() as u64));
    g.bench_function("torus100k", |b| {
        b.iter_batched(
            || PrimSet::from_triangles(tris.clone()),
            Bvh::build,
            criterion::BatchSize::LargeInput,
        )
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
