//! Rendering speed: one 1280x720 frame (sea + objects + camera effects) on one core.
//! Target: <= 25 ms per frame (live streaming at 30 fps leaves room for the rest).

use criterion::{criterion_group, criterion_main, Criterion};
use mgmot_sim::render::Renderer;
use mgmot_sim::scenario::{Render, Scenario};
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
        if name == "calm_baseline" {
            // The same frames with every realism feature of `[render]` off.
            let mut plain = world.scenario.clone();
            plain.render = Render::off();
            let renderer = Renderer::new(&plain, 1);
            c.bench_function(&format!("render_1280x720_{name}_render_off"), |b| {
                b.iter(|| {
                    t += 1.0 / 30.0;
                    renderer.render(&world, &optics, black_box(t), &mut rgb, true);
                    black_box(&rgb);
                })
            });
        }
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
