//! `mgmot eval`'s library path on the size: 10,000 frames x 30 objects,
//! parsing both MOTChallenge texts included. Target: <= 2 s.

use std::fmt::Write as _;
use std::hint::black_box;
use std::path::Path;

use criterion::{criterion_group, criterion_main, Criterion};
use mgmot::eval::{evaluate_sequence, ClassSelection, PreparedSequence};
use mgmot::formats::mot::{parse_str, MotRecord};

const FRAMES: u64 = 10_000;
const OBJECTS: u64 = 30;

/// Deterministic noise in [-0.5, 0.5) (xorshift64).
struct Noise(u64);

impl Noise {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    }
}

/// Ground truth: 30 objects drifting across a 1920x1080 image; results: noisy
/// boxes, 5% misses, an id switch every ~500 frames per object, 1 false
/// positive per frame.
fn make_case() -> (String, String) {
    let mut noise = Noise(0x2545_f491_4f6c_dd1d);
    let (mut gt, mut pred) = (String::new(), String::new());
    let mut pred_ids: Vec<u64> = (1..=OBJECTS).collect();
    let mut next_id = OBJECTS + 1;
    for f in 1..=FRAMES {
        for o in 0..OBJECTS {
            let t = f as f64;
            let x = (o as f64 * 60.0 + t * 0.3 * (1.0 + o as f64 / 30.0)) % 1800.0;
            let y = (o as f64 * 31.0 + t * 0.1) % 1000.0;
            let (w, h) = (40.0 + o as f64, 60.0);
            let _ = writeln!(gt, "{f},{},{x:.2},{y:.2},{w:.2},{h:.2},1,1,1", o + 1);
            if noise.next() < -0.45 {
                continue;
            }
            if noise.next() < -0.499 {
                pred_ids[o as usize] = next_id;
                next_id += 1;
            }
            let (px, py) = (x + 4.0 * noise.next(), y + 4.0 * noise.next());
            let _ = writeln!(
                pred,
                "{f},{},{px:.2},{py:.2},{w:.2},{h:.2},0.9,-1,-1,-1",
                pred_ids[o as usize]
            );
        }
        let _ = writeln!(
            pred,
            "{f},{},{:.2},{:.2},50,50,0.3,-1,-1,-1",
            100_000 + f,
            900.0 + 800.0 * noise.next(),
            500.0 + 400.0 * noise.next()
        );
    }
    (gt, pred)
}

fn eval_from_text(gt: &str, pred: &str) -> f64 {
    let gt = parse_str(gt, Path::new("gt.txt")).unwrap();
    let pred = parse_str(pred, Path::new("pred.txt")).unwrap();
    let gt: Vec<_> = gt.iter().map(MotRecord::to_gt_annotation).collect();
    let pred: Vec<_> = pred.iter().map(MotRecord::to_pred_annotation).collect();
    let seq = PreparedSequence::new(&gt, &pred, ClassSelection::All).unwrap();
    evaluate_sequence(&seq).summary().hota
}

fn bench_eval(c: &mut Criterion) {
    let (gt, pred) = make_case();
    let mut group = c.benchmark_group("eval");
    group.sample_size(10);
    group.bench_function("parse_and_evaluate_10000_frames_x_30_objects", |b| {
        b.iter(|| eval_from_text(black_box(&gt), black_box(&pred)))
    });
    group.finish();
}

criterion_group!(benches, bench_eval);
criterion_main!(benches);
