//! Whole frames of the given scene (recursion level 4) at 256², 1 thread: the packet
//! path (with and without the single-ray fallback for sparse packets) and the reference.

use criterion::{Criterion, criterion_group, criterion_main};
use octaray::render::caustic::CausticSettings;
use octaray::render::options::PacketOptions;
use octaray::render::packet::PacketRenderer;
use octaray::render::{RenderSettings, reference};
use octaray::scene::Scene;

fn bench(c: &mut Criterion) {
    let scene = Scene::given();
    let mut settings = RenderSettings::for_scene(&scene);
    settings.width = 256;
    settings.height = 256;
    settings.threads = Some(1);
    let mut g = c.benchmark_group("frame");
    g.sample_size(10);
    g.bench_function("given256/fast", |b| {
        b.iter(|| octaray::render::packet::render(&scene, &settings))
    });
    for lanes in [0, 1, 2, 4] {
        let options = PacketOptions {
            single_ray_lanes: lanes,
            ..PacketOptions::default()
        };
        let r = PacketRenderer::with_options(
            &scene,
            settings.camera.eye,
            &options,
            &CausticSettings::default(),
        );
        g.bench_function(format!("given256/fast_prebuilt_fallback{lanes}"), |b| {
            b.iter(|| r.render(&settings))
        });
    }
    g.bench_function("given256/reference", |b| {
        b.iter(|| reference::render(&scene, &settings))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
