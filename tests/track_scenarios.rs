//! Synthetic scenes for the tracker: objects moving on the sea under a nadir camera that may
//! pan; checks ids, ReID links and invariants of both the online and the offline mode.

use std::collections::{BTreeMap, BTreeSet};

use mgmot::track::{
    track_sequence, BBox, Detection, FrameInput, TrackState, Tracker, TrackerParams,
    WorldObservation,
};
use nalgebra::{Matrix2, Matrix3, Vector2};
use proptest::prelude::*;

const FPS: f64 = 30.0;
const IMAGE: (u32, u32) = (1000, 800);
/// Nadir camera scale, px per metre.
const PX_PER_M: f64 = 10.0;

/// One simulated object: world position as a function of time, class and box size.
#[derive(Clone)]
struct Object {
    class_id: u32,
    start_ne_m: Vector2<f64>,
    vel_ne_m_s: Vector2<f64>,
    size_px: f64,
    /// Frames in which the detector misses the object although it is in view.
    missed: std::ops::Range<u64>,
}

impl Object {
    fn pos(&self, t: f64) -> Vector2<f64> {
        self.start_ne_m + self.vel_ne_m_s * t
    }
}

/// A scene: objects plus the camera centre's world position per time (nadir, north up).
struct Scene {
    objects: Vec<Object>,
    camera: fn(f64) -> Vector2<f64>,
    with_world: bool,
}

fn static_camera(_t: f64) -> Vector2<f64> {
    Vector2::zeros()
}

impl Scene {
    fn to_px(&self, t: f64, p: Vector2<f64>) -> (f64, f64) {
        let c = (self.camera)(t);
        (
            f64::from(IMAGE.0) / 2.0 + PX_PER_M * (p.y - c.y),
            f64::from(IMAGE.1) / 2.0 - PX_PER_M * (p.x - c.x),
        )
    }

    /// Frames with detections (object index kept in the order of `detections`: returned as
    /// the second vector, the ground truth).
    fn frames(&self, n_frames: u64) -> (Vec<FrameInput>, Vec<Vec<usize>>) {
        let mut frames = Vec::new();
        let mut truth = Vec::new();
        for f in 0..n_frames {
            let t = f as f64 / FPS;
            let mut dets = Vec::new();
            let mut gt = Vec::new();
            for (k, o) in self.objects.iter().enumerate() {
                if o.missed.contains(&f) {
                    continue;
                }
                let p = o.pos(t);
                let (u, v) = self.to_px(t, p);
                let b = BBox::from_center(u, v, o.size_px, o.size_px);
                let inside = b.x >= 0.0
                    && b.y >= 0.0
                    && b.x + b.w <= f64::from(IMAGE.0)
                    && b.y + b.h <= f64::from(IMAGE.1);
                if !inside {
                    continue;
                }
                dets.push(Detection {
                    bbox: b,
                    score: 0.9,
                    class_id: o.class_id,
                    world: self.with_world.then(|| WorldObservation {
                        pos_ne_m: p,
                        cov_ne_m2: Matrix2::identity() * 0.25,
                    }),
                    appearance: None,
                });
                gt.push(k);
            }
            let image_motion = if f == 0 {
                None
            } else {
                let (c0, c1) = ((self.camera)(t - 1.0 / FPS), (self.camera)(t));
                let d = c1 - c0;
                Some(Matrix3::new(
                    1.0,
                    0.0,
                    -PX_PER_M * d.y,
                    0.0,
                    1.0,
                    PX_PER_M * d.x,
                    0.0,
                    0.0,
                    1.0,
                ))
            };
            frames.push(FrameInput {
                frame_index: f,
                time_s: t,
                image_size_px: IMAGE,
                detections: dets,
                image_motion,
            });
            truth.push(gt);
        }
        (frames, truth)
    }
}

/// For each ground-truth object, the set of ids it was reported under (online mode).
fn online_ids(
    frames: &[FrameInput],
    truth: &[Vec<usize>],
    params: TrackerParams,
) -> (BTreeMap<usize, BTreeSet<u64>>, usize) {
    let mut tracker = Tracker::new(params).unwrap();
    let mut ids: BTreeMap<usize, BTreeSet<u64>> = BTreeMap::new();
    let mut merges = 0;
    for (f, gt) in frames.iter().zip(truth) {
        let out = tracker.step(f).unwrap();
        merges += out.merges.len();
        for t in &out.tracks {
            // A coasting track (missed in this frame) has no detection to match the truth by.
            let Some(j) = t.detection_index else {
                assert_eq!(t.state, TrackState::Lost);
                continue;
            };
            ids.entry(gt[j]).or_default().insert(t.id);
        }
    }
    (ids, merges)
}

/// Ids per object in the offline result (matched to the truth by box IoU > 0.5 on real
/// observations).
fn offline_ids(
    frames: &[FrameInput],
    truth: &[Vec<usize>],
    params: &TrackerParams,
) -> BTreeMap<usize, BTreeSet<u64>> {
    let res = track_sequence(frames, params).unwrap();
    let mut ids: BTreeMap<usize, BTreeSet<u64>> = BTreeMap::new();
    for ((f, gt), out) in frames.iter().zip(truth).zip(&res.frames) {
        for t in out.tracks.iter().filter(|t| !t.interpolated) {
            let best = f
                .detections
                .iter()
                .enumerate()
                .max_by(|a, b| t.bbox.iou(&a.1.bbox).total_cmp(&t.bbox.iou(&b.1.bbox)));
            if let Some((j, d)) = best {
                if t.bbox.iou(&d.bbox) > 0.5 {
                    ids.entry(gt[j]).or_default().insert(t.id);
                }
            }
        }
    }
    ids
}

fn swimmer(n: f64, e: f64, vn: f64, ve: f64) -> Object {
    Object {
        class_id: 1,
        start_ne_m: Vector2::new(n, e),
        vel_ne_m_s: Vector2::new(vn, ve),
        size_px: 20.0,
        missed: 0..0,
    }
}

#[test]
fn constant_velocity_objects_keep_one_id_each() {
    let scene = Scene {
        objects: vec![
            swimmer(0.0, -20.0, 0.2, 1.0),
            swimmer(10.0, 0.0, -0.5, 0.0),
            swimmer(-15.0, 10.0, 0.0, -0.8),
        ],
        camera: static_camera,
        with_world: true,
    };
    let (frames, truth) = scene.frames(150);
    let (ids, merges) = online_ids(&frames, &truth, TrackerParams::default());
    assert_eq!(ids.len(), 3);
    for (k, s) in &ids {
        assert_eq!(s.len(), 1, "object {k} got ids {s:?}");
    }
    let all: BTreeSet<u64> = ids.values().flatten().copied().collect();
    assert_eq!(all.len(), 3);
    assert_eq!(merges, 0);
    let off = offline_ids(&frames, &truth, &TrackerParams::default());
    assert!(off.values().all(|s| s.len() == 1), "{off:?}");
}

#[test]
fn crossing_objects_keep_their_ids() {
    // Two boats crossing head-on, 1.2 m apart laterally (boxes overlap at the crossing).
    let boat = |e: f64, ve: f64, n: f64| Object {
        class_id: 2,
        start_ne_m: Vector2::new(n, e),
        vel_ne_m_s: Vector2::new(0.0, ve),
        size_px: 30.0,
        missed: 0..0,
    };
    let scene = Scene {
        objects: vec![boat(-30.0, 6.0, 0.0), boat(30.0, -6.0, 1.2)],
        camera: static_camera,
        with_world: true,
    };
    let (frames, truth) = scene.frames(300);
    for params in [TrackerParams::default(), {
        let mut p = TrackerParams::default();
        p.reid.enabled = false;
        p
    }] {
        let (ids, _) = online_ids(&frames, &truth, params);
        assert_eq!(ids[&0].len(), 1, "{ids:?}");
        assert_eq!(ids[&1].len(), 1, "{ids:?}");
        assert_ne!(ids[&0], ids[&1]);
    }
}

/// Camera pans 60 m east over 6 s, waits 4 s, and comes back over 6 s: a swimmer near the
/// left of the view leaves it and re-enters about 14 s later (far beyond the lost buffer).
fn pan_away_and_back(t: f64) -> Vector2<f64> {
    let e = if t < 2.0 {
        0.0
    } else if t < 8.0 {
        10.0 * (t - 2.0)
    } else if t < 12.0 {
        60.0
    } else if t < 18.0 {
        60.0 - 10.0 * (t - 12.0)
    } else {
        0.0
    };
    Vector2::new(0.0, e)
}

#[test]
fn target_leaving_and_reentering_gets_its_old_id_in_both_modes() {
    let scene = Scene {
        objects: vec![swimmer(5.0, -20.0, 0.1, 0.0)],
        camera: pan_away_and_back,
        with_world: true,
    };
    let (frames, truth) = scene.frames(30 * 24);
    // the object really disappears for longer than the lost buffer
    let absent = truth.iter().filter(|g| g.is_empty()).count();
    assert!(absent > 150, "absent for {absent} frames");

    let (ids, merges) = online_ids(&frames, &truth, TrackerParams::default());
    assert_eq!(merges, 1);
    // reported under the new id until the link (w frames), then under the old one again
    let first_id = *ids[&0].iter().min().unwrap();
    let mut tracker = Tracker::new(TrackerParams::default()).unwrap();
    let mut last_id = None;
    for f in &frames {
        let out = tracker.step(f).unwrap();
        if let Some(m) = out.merges.first() {
            assert_eq!(m.merged_into_id, first_id);
        }
        if let Some(t) = out.tracks.first() {
            last_id = Some(t.id);
        }
    }
    assert_eq!(last_id, Some(first_id));

    let off = offline_ids(&frames, &truth, &TrackerParams::default());
    assert_eq!(off[&0].len(), 1, "{off:?}");

    // without ReID the baseline gives it a second id: the test exercises the ReID
    let mut no_reid = TrackerParams::default();
    no_reid.reid.enabled = false;
    assert_eq!(offline_ids(&frames, &truth, &no_reid)[&0].len(), 2);

    // Each mode has its own long-term gate: `reid.gate_chi2` (and `reid.long_gap_gate_chi2`
    // after long gaps) online, `offline.gate_chi2` offline. Shut one and only that mode
    // loses the link.
    let mut online_shut = TrackerParams::default();
    online_shut.reid.gate_chi2 = 1e-9;
    online_shut.reid.long_gap_gate_chi2 = 1e-9;
    assert_eq!(online_ids(&frames, &truth, online_shut.clone()).1, 0);
    assert_eq!(offline_ids(&frames, &truth, &online_shut)[&0].len(), 1);
    let mut offline_shut = TrackerParams::default();
    offline_shut.offline.gate_chi2 = 1e-9;
    assert_eq!(online_ids(&frames, &truth, offline_shut.clone()).1, 1);
    assert_eq!(offline_ids(&frames, &truth, &offline_shut)[&0].len(), 2);
}

#[test]
fn two_classes_are_never_merged() {
    // A swimmer leaves the view; a boat appears where the swimmer would be.
    let mut boat = swimmer(5.0, -20.0, 0.1, 0.0);
    boat.class_id = 2;
    boat.missed = 0..(30 * 16);
    let mut swim = swimmer(5.0, -20.0, 0.1, 0.0);
    swim.missed = (30 * 6)..(30 * 24);
    let scene = Scene {
        objects: vec![swim, boat],
        camera: pan_away_and_back,
        with_world: true,
    };
    let (frames, truth) = scene.frames(30 * 24);
    let (ids, merges) = online_ids(&frames, &truth, TrackerParams::default());
    assert_eq!(merges, 0);
    assert!(ids[&0].is_disjoint(&ids[&1]));
    let off = offline_ids(&frames, &truth, &TrackerParams::default());
    assert!(off[&0].is_disjoint(&off[&1]), "{off:?}");

    // Control: were the boat a swimmer, it would be linked (only the class keeps them apart).
    let mut same = Scene {
        objects: scene.objects.clone(),
        camera: pan_away_and_back,
        with_world: true,
    };
    same.objects[1].class_id = 1;
    let (frames, truth) = same.frames(30 * 24);
    let (ids, merges) = online_ids(&frames, &truth, TrackerParams::default());
    assert_eq!(merges, 1);
    // the second object is reported under its own id for w frames, then under the first's
    assert_eq!(ids[&0].len(), 1);
    assert!(ids[&1].is_superset(&ids[&0]));
}

#[test]
fn short_gap_inside_view_is_relinked_by_short_term_reid() {
    // Missed for 5 s (150 frames > lost buffer) in the middle of the image.
    let mut s = swimmer(0.0, 0.0, 0.05, 0.0);
    s.missed = 60..210;
    let scene = Scene {
        objects: vec![s],
        camera: static_camera,
        with_world: true,
    };
    let (frames, truth) = scene.frames(300);
    let mut p = TrackerParams::default();
    p.reid.long_term = false; // only short-term may link it
    p.reid.short_term = true;
    let (ids, merges) = online_ids(&frames, &truth, p.clone());
    assert_eq!(merges, 1);
    let mut tracker = Tracker::new(p.clone()).unwrap();
    let last = frames
        .iter()
        .map(|f| tracker.step(f).unwrap())
        .last()
        .unwrap();
    assert_eq!(last.tracks[0].id, *ids[&0].iter().min().unwrap());
    assert_eq!(offline_ids(&frames, &truth, &p)[&0].len(), 1);

    // Control: the gap is longer than the lost buffer, so the baseline alone splits it.
    let mut no_reid = p.clone();
    no_reid.reid.enabled = false;
    assert_eq!(online_ids(&frames, &truth, no_reid.clone()).0[&0].len(), 2);
    assert_eq!(offline_ids(&frames, &truth, &no_reid)[&0].len(), 2);
}

#[test]
fn no_merge_beyond_the_world_distance_gate() {
    // One swimmer vanishes in view; 5 s later another appears 20 m away.
    let mut a = swimmer(0.0, 0.0, 0.0, 0.0);
    a.missed = 60..400;
    let mut b = swimmer(0.0, 20.0, 0.0, 0.0);
    b.missed = 0..210;
    let scene = Scene {
        objects: vec![a, b],
        camera: static_camera,
        with_world: true,
    };
    let (frames, truth) = scene.frames(330);
    let (ids, merges) = online_ids(&frames, &truth, TrackerParams::default());
    assert_eq!(merges, 0);
    assert!(ids[&0].is_disjoint(&ids[&1]));
    let off = offline_ids(&frames, &truth, &TrackerParams::default());
    assert!(off[&0].is_disjoint(&off[&1]));

    // Control: with the paper's short-term stage and a 25 m gate the same scene is linked.
    let mut wide = TrackerParams::default();
    wide.reid.short_term = true;
    wide.reid.classes.get_mut(&1).unwrap().tau_match_m = 25.0;
    let (ids, merges) = online_ids(&frames, &truth, wide);
    assert_eq!(merges, 1);
    // the second object is reported under its own id for w frames, then under the first's
    assert_eq!(ids[&0].len(), 1);
    assert!(ids[&1].is_superset(&ids[&0]));
}

#[test]
fn tracks_without_metadata_as_plain_baseline() {
    let scene = Scene {
        objects: vec![swimmer(0.0, -20.0, 0.2, 1.0), swimmer(10.0, 0.0, -0.5, 0.0)],
        camera: static_camera,
        with_world: false,
    };
    let (mut frames, truth) = scene.frames(100);
    for f in &mut frames {
        f.image_motion = None;
    }
    let mut tracker = Tracker::new(TrackerParams::default()).unwrap();
    let mut ids: BTreeMap<usize, BTreeSet<u64>> = BTreeMap::new();
    for (f, gt) in frames.iter().zip(&truth) {
        let out = tracker.step(f).unwrap();
        for t in &out.tracks {
            assert!(t.world.is_none());
            let Some(j) = t.detection_index else {
                assert_eq!(t.state, TrackState::Lost);
                continue;
            };
            ids.entry(gt[j]).or_default().insert(t.id);
        }
    }
    assert_eq!(ids.len(), 2);
    assert!(ids.values().all(|s| s.len() == 1));
    let res = track_sequence(&frames, &TrackerParams::default()).unwrap();
    assert!(res.frames.iter().all(|f| f.tracks.len() <= 2));
}

#[test]
fn world_state_estimates_velocity() {
    let scene = Scene {
        objects: vec![swimmer(0.0, -20.0, 0.5, 1.0)],
        camera: static_camera,
        with_world: true,
    };
    let (frames, _) = scene.frames(120);
    let mut tracker = Tracker::new(TrackerParams::default()).unwrap();
    let last = frames
        .iter()
        .map(|f| tracker.step(f).unwrap())
        .last()
        .unwrap();
    let w = last.tracks[0].world.unwrap();
    assert!(
        (w.vel_ne_m_s - Vector2::new(0.5, 1.0)).norm() < 0.05,
        "{w:?}"
    );
    assert!(
        (w.pos_ne_m - Vector2::new(0.5, 1.0) * (119.0 / FPS) - Vector2::new(0.0, -20.0)).norm()
            < 0.2
    );
}

#[test]
fn live_tracks_report_lost_state_with_predicted_world() {
    let mut s = swimmer(0.0, 0.0, 0.0, 1.0);
    s.missed = 60..1000;
    let scene = Scene {
        objects: vec![s],
        camera: static_camera,
        with_world: true,
    };
    let (frames, _) = scene.frames(90);
    let mut tracker = Tracker::new(TrackerParams::default()).unwrap();
    for f in &frames {
        tracker.step(f).unwrap();
    }
    let live: Vec<_> = tracker.live_tracks().collect();
    assert_eq!(live.len(), 1);
    assert_eq!(live[0].state, TrackState::Lost);
    assert!(live[0].detection_index.is_none());
    // last seen at frame 59, predicted to frame 89 at 1 m/s east
    let w = live[0].world.unwrap();
    assert!((w.pos_ne_m.y - 89.0 / FPS).abs() < 0.2, "{w:?}");
}

#[test]
fn out_of_order_frames_are_rejected() {
    let mut tracker = Tracker::new(TrackerParams::default()).unwrap();
    let f = |i: u64| FrameInput {
        frame_index: i,
        time_s: i as f64,
        image_size_px: IMAGE,
        detections: vec![],
        image_motion: None,
    };
    tracker.step(&f(3)).unwrap();
    assert!(tracker.step(&f(3)).is_err());
    assert!(tracker.step(&f(2)).is_err());
    tracker.step(&f(4)).unwrap();
}

/// Random object: class, north, east, v_north, v_east, first missed frame, missed length.
type ObjSpec = (u32, f64, f64, f64, f64, u64, u64);

fn random_scene() -> impl Strategy<Value = (Vec<ObjSpec>, bool)> {
    (
        prop::collection::vec(
            (
                1u32..3,
                -30.0..30.0f64,
                -40.0..40.0f64,
                -3.0..3.0f64,
                -3.0..3.0f64,
                0u64..200,
                0u64..120,
            ),
            1..10,
        ),
        any::<bool>(),
    )
}

fn build(objs: &[ObjSpec], pan: bool) -> Vec<FrameInput> {
    let scene = Scene {
        objects: objs
            .iter()
            .map(|&(c, n, e, vn, ve, m0, ml)| Object {
                class_id: c,
                start_ne_m: Vector2::new(n, e),
                vel_ne_m_s: Vector2::new(vn, ve),
                size_px: 15.0 + 10.0 * f64::from(c),
                missed: m0..m0 + ml,
            })
            .collect(),
        camera: if pan {
            pan_away_and_back
        } else {
            static_camera
        },
        with_world: true,
    };
    scene.frames(300).0
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(12))]

    #[test]
    fn ids_unique_per_frame_in_both_modes_and_deterministic((objs, pan) in random_scene()) {
        let frames = build(&objs, pan);
        let params = TrackerParams::default();
        let run = || {
            let mut tracker = Tracker::new(params.clone()).unwrap();
            frames.iter().map(|f| tracker.step(f).unwrap()).collect::<Vec<_>>()
        };
        let a = run();
        for out in &a {
            let ids: BTreeSet<u64> = out.tracks.iter().map(|t| t.id).collect();
            prop_assert_eq!(ids.len(), out.tracks.len());
        }
        prop_assert_eq!(&a, &run());

        let off = track_sequence(&frames, &params).unwrap();
        prop_assert_eq!(off.frames.len(), frames.len());
        for f in &off.frames {
            let ids: BTreeSet<u64> = f.tracks.iter().map(|t| t.id).collect();
            prop_assert_eq!(ids.len(), f.tracks.len());
        }
        prop_assert_eq!(off, track_sequence(&frames, &params).unwrap());
    }
}

fn wild_f64() -> impl Strategy<Value = f64> {
    prop_oneof![
        8 => -100.0..1100.0f64,
        1 => Just(f64::NAN),
        1 => Just(f64::INFINITY),
        1 => Just(-1e300),
        1 => Just(0.0),
    ]
}

fn wild_detection() -> impl Strategy<Value = Detection> {
    (
        (wild_f64(), wild_f64(), wild_f64(), wild_f64()),
        prop_oneof![8 => 0.0..1.0f32, 1 => Just(f32::NAN), 1 => Just(5.0f32)],
        0u32..4,
        proptest::option::of((wild_f64(), wild_f64(), wild_f64())),
    )
        .prop_map(|((x, y, w, h), score, class_id, world)| Detection {
            bbox: BBox::new(x, y, w, h),
            score,
            class_id,
            world: world.map(|(n, e, v)| WorldObservation {
                pos_ne_m: Vector2::new(n, e),
                cov_ne_m2: Matrix2::identity() * v,
            }),
            appearance: None,
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(32))]

    /// Garbage in (NaN, infinities, empty boxes, singular homographies, negative
    /// covariances): the tracker neither panics nor errors on ordered frames, and ids stay
    /// unique in every frame of both modes.
    #[test]
    fn arbitrary_input_never_panics(
        frames in prop::collection::vec(
            (
                prop::collection::vec(wild_detection(), 0..12),
                proptest::option::of(prop::array::uniform9(wild_f64())),
                1u64..40,
            ),
            1..25,
        )
    ) {
        let mut index = 0;
        let inputs: Vec<FrameInput> = frames
            .into_iter()
            .map(|(detections, h, gap)| {
                index += gap;
                FrameInput {
                    frame_index: index,
                    time_s: index as f64 / FPS,
                    image_size_px: IMAGE,
                    detections,
                    image_motion: h.map(|m| Matrix3::from_row_slice(&m)),
                }
            })
            .collect();
        let mut tracker = Tracker::new(TrackerParams::default()).unwrap();
        for f in &inputs {
            let out = tracker.step(f).unwrap();
            let ids: BTreeSet<u64> = out.tracks.iter().map(|t| t.id).collect();
            prop_assert_eq!(ids.len(), out.tracks.len());
        }
        tracker.finish();
        let off = track_sequence(&inputs, &TrackerParams::default()).unwrap();
        for f in &off.frames {
            let ids: BTreeSet<u64> = f.tracks.iter().map(|t| t.id).collect();
            prop_assert_eq!(ids.len(), f.tracks.len());
        }
    }
}
