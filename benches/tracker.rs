//! Online tracker step: 30 live tracks and 40 detections per frame (30 objects plus 10
//! low-confidence clutter detections), camera-motion compensation on, world observations
//! on. Three cases: a steady-state frame, a frame in which 5 new tracks reach `w` frames
//! and are matched against a memory bank of 10 lost tracks (online ReID decision), and the
//! frame before it, in which the same assignment gives the undecided tracks their
//! provisional old ids (`reid.provisional_old_id`).
//! Target (issue 2): median <= 50 us per frame on one core.
//!
//! Third case (issue 14): one long-gap ReID decision against a memory bank of 200 ended
//! tracks (`reid_decision_200_in_memory`: 1 new track; `..._5_new`: 5 new tracks decided in
//! the same frame), every exit of the new track's class and within minutes of it, so that
//! every pair is evaluated under the Mahalanobis gate. Target: <= 1 ms per decision.
//!
//! Fourth case: the colour signature of one detection's box (`signature_*`), which
//! `mgmot run` computes for every detection (cost per frame: detections x this).
//!
//! Fifth: the 95 % circle of a track's position covariance (`circular_error_95_*`), computed
//! for every reported track of every frame.
//!
//! Detections and track ends carry colour signatures, so the appearance gate's distances are
//! in every figure.
//!
//! Each case is measured twice: wall-clock time (criterion's default) and the CPU time of the
//! benchmark thread (`*_cpu`), which is what "on one core" means when the machine is shared
//! and the wall clock includes time spent waiting for a core.

use std::time::Duration;

use cpu_time::ThreadTime;
use criterion::measurement::{Measurement, ValueFormatter};
use criterion::{criterion_group, criterion_main, BatchSize, Criterion, Throughput};
use mgmot::track::reid::{associate_exits_to_entries, TrackEnd};
use mgmot::track::{
    appearance, Appearance, BBox, Detection, FrameInput, ReidParams, RgbImage, SeaDrift,
    TrackState, Tracker, TrackerParams, WorldObservation,
};
use nalgebra::{Matrix2, Matrix3, Vector2};

const FPS: f64 = 30.0;
const PX_PER_M: f64 = 10.0;
const IMAGE: (u32, u32) = (3840, 2160);

/// Deterministic pseudo-random numbers in [0, 1) (a 64-bit LCG; no dependency needed).
struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

struct Obj {
    pos: Vector2<f64>,
    vel: Vector2<f64>,
    frames: std::ops::Range<u64>,
    class_id: u32,
    /// Hue bin of its colour signature.
    colour: usize,
}

/// A colour signature mostly in hue bin `bin`, the rest dark (a jacket and a head), as
/// `mgmot run` computes for every detection, so the appearance gate does its work.
fn signature(bin: usize) -> Option<Appearance> {
    let mut bins = [0.0; appearance::BINS];
    bins[bin % appearance::HUE_BINS] = 0.8;
    bins[appearance::HUE_BINS] = 0.2;
    Some(Appearance { bins })
}

/// Frame the 5 new objects appear in; their ReID decision comes `reid.window_frames` later.
const APPEAR: u64 = 170;

/// 25 persistent objects, 10 that vanish at frame 100 (memory bank), 5 that appear at
/// frame [`APPEAR`], 10 clutter detections per frame.
fn scene(n_frames: u64) -> Vec<FrameInput> {
    let mut rng = Lcg(42);
    let mut objs = Vec::new();
    let mut add = |rng: &mut Lcg, frames: std::ops::Range<u64>| {
        // Eight jacket colours for 40 objects (not drawn from `rng`, so the scene's
        // positions stay those of the benchmark without signatures): a new object shares its
        // colour with some ended ones, so the gate lets some pairs through and stops others.
        let colour = 2 * ((objs.len() * 5) % 8);
        objs.push(Obj {
            pos: Vector2::new(rng.next() * 150.0 - 75.0, rng.next() * 300.0 - 150.0),
            vel: Vector2::new(rng.next() * 2.0 - 1.0, rng.next() * 2.0 - 1.0),
            frames,
            class_id: 1 + (rng.next() * 2.0) as u32,
            colour,
        });
    };
    for _ in 0..25 {
        add(&mut rng, 0..u64::MAX);
    }
    for _ in 0..10 {
        add(&mut rng, 0..100);
    }
    for _ in 0..5 {
        add(&mut rng, APPEAR..u64::MAX);
    }
    let (cx, cy) = (f64::from(IMAGE.0) / 2.0, f64::from(IMAGE.1) / 2.0);
    (0..n_frames)
        .map(|f| {
            let t = f as f64 / FPS;
            // camera drifting 1 m/s east
            let cam_e = t;
            let mut detections = Vec::new();
            for o in objs.iter().filter(|o| o.frames.contains(&f)) {
                let p = o.pos + o.vel * t;
                let noise = Vector2::new(rng.next() - 0.5, rng.next() - 0.5) * 0.3;
                let (u, v) = (cx + PX_PER_M * (p.y - cam_e), cy - PX_PER_M * p.x);
                detections.push(Detection {
                    bbox: BBox::from_center(u + rng.next(), v + rng.next(), 24.0, 24.0),
                    score: 0.6 + 0.4 * rng.next() as f32,
                    class_id: o.class_id,
                    world: Some(WorldObservation {
                        pos_ne_m: p + noise,
                        cov_ne_m2: Matrix2::identity() * 0.25,
                    }),
                    appearance: signature(o.colour),
                });
            }
            for _ in 0..10 {
                detections.push(Detection {
                    bbox: BBox::new(
                        rng.next() * 3700.0,
                        rng.next() * 2000.0,
                        10.0 + 20.0 * rng.next(),
                        10.0 + 20.0 * rng.next(),
                    ),
                    score: 0.15 + 0.3 * rng.next() as f32,
                    class_id: 1,
                    world: None,
                    appearance: None,
                });
            }
            FrameInput {
                frame_index: f,
                time_s: t,
                image_size_px: IMAGE,
                detections,
                image_motion: Some(Matrix3::new(
                    1.0,
                    0.0,
                    -PX_PER_M / FPS,
                    0.0,
                    1.0,
                    0.0,
                    0.0,
                    0.0,
                    1.0,
                )),
            }
        })
        .collect()
}

/// Criterion measurement: CPU time consumed by the measuring thread.
struct ThreadCpuTime;

/// Formats nanoseconds like criterion's wall-time formatter.
struct NanosFormatter;

impl ValueFormatter for NanosFormatter {
    fn scale_values(&self, typical_ns: f64, values: &mut [f64]) -> &'static str {
        let (factor, unit) = if typical_ns < 1e3 {
            (1.0, "ns")
        } else if typical_ns < 1e6 {
            (1e-3, "µs")
        } else {
            (1e-6, "ms")
        };
        values.iter_mut().for_each(|v| *v *= factor);
        unit
    }

    fn scale_throughputs(&self, _: f64, _: &Throughput, values: &mut [f64]) -> &'static str {
        values.iter_mut().for_each(|v| *v = 1e9 / *v);
        "iter/s"
    }

    fn scale_for_machines(&self, _: &mut [f64]) -> &'static str {
        "ns"
    }
}

impl Measurement for ThreadCpuTime {
    type Intermediate = ThreadTime;
    type Value = Duration;

    fn start(&self) -> ThreadTime {
        ThreadTime::now()
    }
    fn end(&self, start: ThreadTime) -> Duration {
        start.elapsed()
    }
    fn add(&self, a: &Duration, b: &Duration) -> Duration {
        *a + *b
    }
    fn zero(&self) -> Duration {
        Duration::ZERO
    }
    fn to_f64(&self, d: &Duration) -> f64 {
        d.as_nanos() as f64
    }
    fn formatter(&self) -> &dyn ValueFormatter {
        &NanosFormatter
    }
}

/// The two tracker states to step from (at the ReID decision frame, steady), the frames,
/// and the decision frame.
/// Tracker states: before a frame whose undecided tracks only get their provisional old id
/// (`decide - 1`), before the decision frame, and before the steady frame 250.
struct Prepared {
    before_provisional: Tracker,
    at_reid: Tracker,
    steady: Tracker,
    frames: Vec<FrameInput>,
    decide: usize,
}

fn prepared() -> Prepared {
    let frames = scene(260);
    let params = TrackerParams::default();
    let decide = (APPEAR + u64::from(params.reid.window_frames)) as usize;
    assert!(
        decide < 250,
        "the decision frame must come before the steady one"
    );
    let mut tracker = Tracker::new(params).expect("default params");
    // Warm up to the frame before the decision; frame 250 is a steady one.
    for f in &frames[..decide - 1] {
        tracker.step(f).expect("ordered frames");
    }
    let before_provisional = tracker.clone();
    let out = tracker.step(&frames[decide - 1]).expect("ordered frames");
    let provisional = out.tracks.iter().filter(|t| t.provisional).count();
    let at_reid = tracker.clone();
    // The decision frame really decides: the new tracks are provisional before it, not after.
    let decided = at_reid
        .clone()
        .step(&frames[decide])
        .expect("ordered frames");
    assert!(
        provisional > 0,
        "no provisional track before the decision frame"
    );
    assert_eq!(decided.tracks.iter().filter(|t| t.provisional).count(), 0);
    for f in &frames[decide..250] {
        tracker.step(f).expect("ordered frames");
    }
    let steady = tracker;
    assert_eq!(frames[250].detections.len(), 40);
    assert_eq!(
        steady
            .live_tracks()
            .filter(|t| t.state == TrackState::Confirmed)
            .count(),
        30
    );
    Prepared {
        before_provisional,
        at_reid,
        steady,
        frames,
        decide,
    }
}

/// The three step cases under one measurement; `suffix` tells the measurements apart.
fn step_cases<M: Measurement + 'static>(c: &mut Criterion<M>, suffix: &str) {
    let p = prepared();
    let cases = [
        ("", &p.steady, 250),
        ("_with_reid_decision", &p.at_reid, p.decide),
        ("_with_provisional_ids", &p.before_provisional, p.decide - 1),
    ];
    for (name, tracker, frame) in cases {
        c.bench_function(
            &format!("tracker_step_30_tracks_40_dets{name}{suffix}"),
            |b| {
                b.iter_batched_ref(
                    || tracker.clone(),
                    |t| t.step(&p.frames[frame]),
                    BatchSize::SmallInput,
                )
            },
        );
    }
}

fn bench_step(c: &mut Criterion) {
    step_cases(c, "");
}

fn bench_step_cpu(c: &mut Criterion<ThreadCpuTime>) {
    step_cases(c, "_cpu");
}

/// A memory bank of 200 exits (swimmers and boats, ended 1-300 s before) and `n` entries.
fn long_gap_case(n: usize) -> (Vec<TrackEnd>, Vec<TrackEnd>) {
    let mut rng = Lcg(7);
    let end = |rng: &mut Lcg, t: f64, spread: f64| TrackEnd {
        class_id: if rng.next() < 0.8 { 1 } else { 2 },
        time_s: t,
        pos_ne_m: Vector2::new(rng.next() * spread, rng.next() * spread),
        vel_ne_m_s: Vector2::new(rng.next() - 0.5, rng.next() - 0.5),
        pos_cov_m2: Matrix2::identity() * (0.5 + rng.next()),
        vel_cov_m2_s2: Matrix2::identity() * 0.05,
        left_view: rng.next() < 0.7,
        appearance: signature(2 * (rng.next() * 8.0) as usize),
    };
    let exits = (0..200)
        .map(|_| {
            let t = 300.0 * rng.next();
            end(&mut rng, t, 200.0)
        })
        .collect();
    let entries = (0..n).map(|_| end(&mut rng, 301.0, 200.0)).collect();
    (exits, entries)
}

fn bench_long_gap(c: &mut Criterion) {
    let params = ReidParams::default();
    // A swimmer drift estimated from a minute of two swimmers, so the decision uses it.
    let mut drift = SeaDrift::new(params.drift.clone());
    for k in 0..1800 {
        let samples = [
            (1, 1, Vector2::new(0.1, 0.05)),
            (1, 2, Vector2::new(0.0, 0.1)),
        ];
        drift.observe(f64::from(k) / FPS, &samples);
    }
    assert!(drift.estimate(1).is_some());
    for n in [1, 5] {
        let (exits, entries) = long_gap_case(n);
        let name = if n == 1 {
            "reid_decision_200_in_memory".to_owned()
        } else {
            format!("reid_decision_200_in_memory_{n}_new")
        };
        c.bench_function(&name, |b| {
            b.iter(|| associate_exits_to_entries(&exits, &entries, &params, &drift))
        });
    }
}

/// The colour signature of one detection (`Appearance::from_box`, what `mgmot run` adds to
/// every detection of a frame): a 20 x 20 px swimmer and a 200 x 120 px boat (subsampled on
/// a 32 x 32 grid), each on a sea background with a jacket-coloured patch.
fn bench_signature(c: &mut Criterion) {
    let (w, h) = (320usize, 200usize);
    let mut rgb = vec![0u8; w * h * 3];
    let mut rng = Lcg(3);
    for px in rgb.chunks_exact_mut(3) {
        let n = (rng.next() * 20.0) as u8;
        px.copy_from_slice(&[20 + n, 60 + n, 80 + n]);
    }
    for y in 30..150 {
        for x in 50..250 {
            if (x + y) % 3 == 0 || (14..26).contains(&(x % 40)) {
                let i = (y * w + x) * 3;
                rgb[i..i + 3].copy_from_slice(&[255, 110, 0]);
            }
        }
    }
    let image = RgbImage {
        rgb: &rgb,
        width: w,
        height: h,
    };
    for (name, b) in [
        ("signature_swimmer_20px", BBox::new(60.0, 40.0, 20.0, 20.0)),
        (
            "signature_boat_200x120px",
            BBox::new(50.0, 30.0, 200.0, 120.0),
        ),
    ] {
        assert!(Appearance::from_box(&image, &b).is_some());
        c.bench_function(name, |bch| bch.iter(|| Appearance::from_box(&image, &b)));
    }
}

/// The 95 % circle of a track's position covariance (`geo::circular_error_m`), which
/// `mgmot run` computes for every reported track of every frame (Cursor-on-Target's `ce`):
/// a circular covariance and an elongated, rotated one (axes 3 m and 0.9 m).
fn bench_circular_error(c: &mut Criterion) {
    use mgmot::geo::circular_error_m;
    let (s, co) = 0.6f64.sin_cos();
    let rot = Matrix2::new(co, -s, s, co);
    let elongated = rot * Matrix2::new(9.0, 0.0, 0.0, 0.81) * rot.transpose();
    for (name, cov) in [
        (
            "circular_error_95_circular",
            Matrix2::new(4.0, 0.0, 0.0, 4.0),
        ),
        ("circular_error_95_elongated", elongated),
    ] {
        assert!(circular_error_m(&cov, 0.95).is_some());
        c.bench_function(name, |b| b.iter(|| circular_error_m(&cov, 0.95)));
    }
}

criterion_group!(
    benches,
    bench_step,
    bench_long_gap,
    bench_signature,
    bench_circular_error
);
criterion_group! {
    name = benches_cpu;
    config = Criterion::default().with_measurement(ThreadCpuTime);
    targets = bench_step_cpu
}
criterion_main!(benches, benches_cpu);
