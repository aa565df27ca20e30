//! Per-frame detector latency split into preprocess / inference / postprocess,
//! int8 vs fp32, at the model's input size, with 2 threads.
//!
//! One backend per process (ort's API table is process-global):
//!
//! ```text
//! cargo bench --bench detect                                   # tract
//! MGMOT_BENCH_BACKEND=onnxruntime ORT_DYLIB_PATH=$(scripts/detect_fetch_onnxruntime.sh) \
//!     cargo bench --bench detect                               # ONNX Runtime
//! ```
//!
//! Each stage is its own benchmark (`iter_custom` over `detect_timed`, summing
//! only that stage), `total` times the whole `detect` call, and `tiled-total` the whole call
//! with tiling (`[detector] tile = true`: the 1280x720 frame in four 800x448 tiles plus the
//! whole frame, merged).

use std::path::PathBuf;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, Criterion};
use mgmot::detect::{BackendConfig, BackendKind, Detector, DetectorConfig, TilingConfig};

fn bench_detect(c: &mut Criterion) {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let backend: BackendKind = std::env::var("MGMOT_BENCH_BACKEND")
        .unwrap_or_else(|_| "tract".into())
        .parse()
        .expect("MGMOT_BENCH_BACKEND must be tract or onnxruntime");
    let frame = image::open(root.join("tests/fixtures/detect/sim_heldout_a.jpg"))
        .expect("fixture frame")
        .to_rgb8();
    let mut group = c.benchmark_group(format!("detect/{backend}"));
    group.sample_size(30);
    group.measurement_time(Duration::from_secs(6));
    group.warm_up_time(Duration::from_secs(2));
    for (label, file) in [
        ("int8", "models/mgmot-det-int8.onnx"),
        ("fp32", "models/mgmot-det-fp32.onnx"),
    ] {
        let mut config = DetectorConfig::new(root.join(file));
        config.backend = BackendConfig {
            kind: backend,
            ort_dylib_path: None,
        };
        config.threads = 2;
        let mut tiled = Detector::load(DetectorConfig {
            tiling: Some(TilingConfig::default()),
            ..config.clone()
        })
        .expect("load model");
        let mut det = Detector::load(config).expect("load model");
        type Stage = fn(&mgmot::detect::DetectTimings) -> Duration;
        let stages: [(&str, Stage); 3] = [
            ("preprocess", |t| t.preprocess),
            ("inference", |t| t.inference),
            ("postprocess", |t| t.postprocess),
        ];
        for (stage, pick) in stages {
            group.bench_function(format!("{label}/{stage}"), |b| {
                b.iter_custom(|iters| {
                    let mut sum = Duration::ZERO;
                    for _ in 0..iters {
                        let (_, t) = det.detect_timed(&frame).expect("detect");
                        sum += pick(&t);
                    }
                    sum
                })
            });
        }
        group.bench_function(format!("{label}/total"), |b| {
            b.iter(|| det.detect(&frame).expect("detect"))
        });
        group.bench_function(format!("{label}/tiled-total"), |b| {
            b.iter(|| tiled.detect(&frame).expect("detect"))
        });
    }
    group.finish();
}

criterion_group!(benches, bench_detect);
criterion_main!(benches);
