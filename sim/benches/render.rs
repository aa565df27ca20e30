//! Rendering speed: one 1280x720 frame (sea + objects) on one core. Target: >= 60 fps,
//! i.e. <= 16.7 ms per frame.

use criterion::{criterion_group, criterion_main, Criterion};
use mgmot_sim::render::Renderer;
use mgmot_sim::scenario::Scenario;
use mgmot_sim::truth::{frame_truth, Optics};
use mgmot_sim::world::World;
use std::hint::black_box;

fn bench_render(c: &mut Criterion) {
    for name in ["calm_baseline", "boats_crossing", "high_altitude_tiny"] {
        let scenario = match Scenario::load(name) {
            Ok(s) => s,
            Err(e) => panic!("{e}"),
        };
        assert_eq!(
            (scenario.camera.width_px, scenario.camera.height_px),
            (1280, 720)
        );
        let optics = match Optics::new(&scenario) {
            Ok(o) => o,
            Err(e) => panic!("{e}"),
        };
        let renderer = Renderer::new(&scenario, 1);
        let world = World::new(scenario, 1);
        let mut rgb = vec![0u8; renderer.frame_bytes()];
        let mut t = 20.0;
        c.bench_function(&format!("render_1280x720_{name}"), |b| {
            b.iter(|| {
                t += 1.0 / 30.0;
                renderer.render(&world, &optics, black_box(t), &mut rgb, true);
                black_box(&rgb);
            })
        });
        c.bench_function(&format!("ground_truth_{name}"), |b| {
            b.iter(|| black_box(frame_truth(&world, &optics, black_box(600))))
        });
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(30);
    targets = bench_render
}
criterion_main!(benches);
