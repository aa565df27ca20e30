//! The tracker on real SeaDronesSee detections (`../shared/data/seadronessee`): three clips,
//! every 15th frame (2 fps, so the tracker sees dropped frames and large image motion).
//! Run once as the plain baseline (no metadata) and once with the drone metadata
//! (geolocated detections and the sea-plane homography as camera-motion compensation).
//!
//! The clips' metadata is a 1 Hz log: it changes only every other sampled frame, and it
//! lags the video. Measured on these clips (median distance from a compensated detection
//! centre to the nearest detection of the next frame; uncompensated 82/56/38 px): held
//! step-wise, compensation does harm (93/67/47 px); interpolated between log updates,
//! 34/54/32 px; interpolated with each record taken to describe the moment 1 s (one log
//! period) before the frame it arrives with, 27/30/22 px. Tracking agrees: with the
//! baseline, boxes continuing an id from the previous frame were 410 without compensation,
//! 355 with the interpolated pose and 487 with the 1 s lag as well (0.5 s: 445, 1.5 s: 440).
//! So the pose is interpolated with [`METADATA_LAG_FRAMES`] here, as the pipeline does for
//! live telemetry with its camera latency.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

use mgmot::formats::coco::read_detections;
use mgmot::formats::seadronessee::{read_dataset, Dataset, SequenceFrame, DEFAULT_VIDEO_FPS};
use mgmot::geo::{CameraModel, FrameMetadata, Geolocator, Pixel, PoseNoise};
use mgmot::track::{
    track_sequence, BBox, Detection, FrameInput, TrackState, Tracker, TrackerParams,
    WorldObservation,
};

const DATA: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/data/seadronessee");
/// The paper's calibrated field of view (Sec. 5.1).
const FOV_DEG: f64 = 70.0;
/// Video frames by which a metadata record lags the image it arrives with (1 s at 30 fps;
/// measured on these clips, see the module docs).
const METADATA_LAG_FRAMES: u64 = 30;

/// Per-frame `[lat_deg, lon_deg, height_m, gimbal_heading_deg, gimbal_pitch_deg]` from a
/// log that updates now and then and lags the video by `lag_frames`: a record first seen
/// with frame `f` describes frame `f - lag_frames`. Values between records are interpolated
/// linearly in frame number (heading along the shorter way round) and held outside them.
fn interpolate_log(raw: &[(u64, [f64; 5])], lag_frames: u64) -> Vec<[f64; 5]> {
    let mut updates = vec![0];
    updates.extend((1..raw.len()).filter(|&i| raw[i].1 != raw[i - 1].1));
    let valid_at = |k: usize| raw[updates[k]].0 as f64 - lag_frames as f64;
    raw.iter()
        .map(|&(frame, _)| {
            let f = frame as f64;
            let k = (0..updates.len())
                .rev()
                .find(|&k| valid_at(k) <= f)
                .unwrap_or(0);
            if k + 1 >= updates.len() || valid_at(k) > f {
                return raw[updates[k]].1;
            }
            let s = (f - valid_at(k)) / (valid_at(k + 1) - valid_at(k));
            let (va, vb) = (raw[updates[k]].1, raw[updates[k + 1]].1);
            std::array::from_fn(|j| {
                let mut d = vb[j] - va[j];
                if j == 3 {
                    d = (d + 540.0).rem_euclid(360.0) - 180.0;
                }
                va[j] + s * d
            })
        })
        .collect()
}

/// The frame's number in the source video (`source.frame_no`): the subset keeps every 15th
/// frame, and the tracker must see those gaps (its Kalman prediction and lost-track buffer
/// count frames), which the sequence's 1-based `frame_number` hides.
fn video_frame(ds: &Dataset, f: &SequenceFrame) -> u64 {
    ds.images[f.image_index]
        .source
        .as_ref()
        .and_then(|s| s.frame_no)
        .unwrap_or(f.frame_number)
}

/// Frames per clip; with `metadata`, detections carry world positions and frames carry the
/// image motion from the previous frame.
fn clips(metadata: bool) -> BTreeMap<String, Vec<FrameInput>> {
    let ann = format!("{DATA}/val_subset_annotations.json");
    let det = format!("{DATA}/val_subset_detections.json");
    for p in [&ann, &det] {
        assert!(
            Path::new(p).exists(),
            "fixture missing: {p} (../shared must sit beside the repo)"
        );
    }
    let ds = read_dataset(Path::new(&ann)).unwrap();
    let mut by_image: BTreeMap<u64, Vec<Detection>> = BTreeMap::new();
    for d in read_detections(Path::new(&det)).unwrap() {
        let [x, y, w, h] = d.bbox;
        by_image.entry(d.image_id).or_default().push(Detection {
            bbox: BBox::new(x, y, w, h),
            score: d.score as f32,
            class_id: d.category_id,
            world: None,
            appearance: None,
        });
    }
    let mut clips = BTreeMap::new();
    for seq in ds.sequences(DEFAULT_VIDEO_FPS) {
        let first = &ds.images[seq.frames[0].image_index];
        let cam = CameraModel::from_hfov(first.width, first.height, FOV_DEG).unwrap();
        let raw: Vec<(u64, [f64; 5])> = seq
            .frames
            .iter()
            .map(|f| {
                let m = ds.images[f.image_index].meta.as_ref().unwrap();
                (
                    video_frame(&ds, f),
                    [
                        m.latitude,
                        m.longitude,
                        m.height_above_takeoff_m,
                        m.gimbal_heading_deg,
                        m.gimbal_pitch_deg,
                    ],
                )
            })
            .collect();
        let metas: Vec<FrameMetadata> = interpolate_log(&raw, METADATA_LAG_FRAMES)
            .iter()
            .map(|m| FrameMetadata::from_seadronessee(m[0], m[1], m[2], m[3], m[4]).unwrap())
            .collect();
        let geolocator = Geolocator::new(metas[0].nadir_on_water(), cam, PoseNoise::default());
        let mut prev_geometry = None;
        let mut frames = Vec::new();
        for (f, meta) in seq.frames.iter().zip(&metas) {
            let image = &ds.images[f.image_index];
            let mut detections = by_image.get(&image.id).cloned().unwrap_or_default();
            let mut image_motion = None;
            if metadata {
                let geometry = geolocator.frame(meta).unwrap();
                for d in &mut detections {
                    let (u, v) = d.bbox.center();
                    d.world = geometry
                        .locate(Pixel::new(u, v))
                        .ok()
                        .map(|g| WorldObservation {
                            pos_ne_m: g.ned_m.xy(),
                            cov_ne_m2: g.cov_ne_m2,
                        });
                }
                image_motion =
                    prev_geometry
                        .as_ref()
                        .and_then(|p: &mgmot::geo::FrameGeometry<'_>| {
                            p.image_motion_to(&geometry).ok()
                        });
                prev_geometry = Some(geometry);
            }
            frames.push(FrameInput {
                frame_index: video_frame(&ds, f),
                time_s: f.time_s,
                image_size_px: (image.width, image.height),
                detections,
                image_motion,
            });
        }
        clips.insert(seq.name.clone(), frames);
    }
    clips
}

/// Runs both modes on every clip, checks the invariants and returns (boxes reported
/// online, boxes continuing an id of the previous frame, distinct ids offline).
fn run(clips: &BTreeMap<String, Vec<FrameInput>>, params: &TrackerParams) -> (usize, usize, usize) {
    let (mut continued, mut reported, mut offline_ids) = (0, 0, 0);
    for (name, frames) in clips {
        let mut tracker = Tracker::new(params.clone()).unwrap();
        let mut prev: BTreeSet<u64> = BTreeSet::new();
        for f in frames {
            let out = tracker.step(f).unwrap();
            let ids: BTreeSet<u64> = out.tracks.iter().map(|t| t.id).collect();
            assert_eq!(
                ids.len(),
                out.tracks.len(),
                "{name} frame {}",
                f.frame_index
            );
            for t in &out.tracks {
                match t.detection_index {
                    Some(j) => assert!(f.detections[j].score >= params.baseline.track_low_thresh),
                    // Coasting: missed in this frame, reported with its predicted box.
                    None => assert_eq!(t.state, TrackState::Lost),
                }
            }
            continued += ids.intersection(&prev).count();
            reported += ids.len();
            prev = ids;
        }
        let off = track_sequence(frames, params).unwrap();
        let mut all = BTreeSet::new();
        for f in &off.frames {
            let ids: BTreeSet<u64> = f.tracks.iter().map(|t| t.id).collect();
            assert_eq!(ids.len(), f.tracks.len());
            all.extend(ids);
        }
        offline_ids += all.len();
    }
    (reported, continued, offline_ids)
}

#[test]
fn real_detections_track_with_unique_ids_and_continuity() {
    let plain = clips(false);
    assert_eq!(plain.len(), 3);
    let strong: usize = plain
        .values()
        .flatten()
        .map(|f| f.detections.iter().filter(|d| d.score >= 0.5).count())
        .sum();
    let (reported, continued, ids) = run(&plain, &TrackerParams::default());
    let ratio = continued as f64 / reported as f64;
    eprintln!(
        "no metadata: {reported} boxes reported of {strong} detections >= 0.5, \
         {continued} continuing ({ratio:.3}), {ids} ids offline"
    );
    // Most reported boxes continue a track of the previous frame (objects persist; a broken
    // association would start a new id every frame). Observed at the time of writing: 473
    // boxes reported out of 953 detections >= 0.5, 86.7 % continuing; at 2 fps without
    // camera-motion compensation many boxes jump too far for IoU matching. The floors below
    // leave room for tuning but catch a broken association.
    assert!(reported > 400, "only {reported} boxes reported");
    assert!(ratio > 0.8, "continuity {ratio:.3}");
}

#[test]
fn metadata_compensates_camera_motion_and_links_tracks() {
    let with_meta = clips(true);
    let located: usize = with_meta
        .values()
        .flatten()
        .flat_map(|f| &f.detections)
        .filter(|d| d.world.is_some())
        .count();
    assert!(located > 1000, "only {located} detections geolocated");
    let mut no_cmc = with_meta.clone();
    for f in no_cmc.values_mut().flatten() {
        f.image_motion = None;
    }
    let mut baseline = TrackerParams::default();
    baseline.reid.enabled = false;
    let cmc_only = run(&with_meta, &baseline);
    let neither = run(&no_cmc, &baseline);
    let reid_only = run(&no_cmc, &TrackerParams::default());
    let both = run(&with_meta, &TrackerParams::default());
    eprintln!(
        "(reported, continued, offline ids): baseline {neither:?}, +CMC {cmc_only:?}, \
         +ReID {reid_only:?}, +CMC+ReID {both:?}; {located} detections geolocated"
    );
    // The sea-plane homography keeps more boxes associated across the 0.5 s frame gaps.
    assert!(
        cmc_only.1 > neither.1,
        "continued {} vs {}",
        cmc_only.1,
        neither.1
    );
    // ReID merges tracklets: fewer distinct ids over the same detections.
    assert!(
        reid_only.2 < neither.2,
        "offline ids {} vs {}",
        reid_only.2,
        neither.2
    );
    assert!(
        both.2 < cmc_only.2,
        "offline ids {} vs {}",
        both.2,
        cmc_only.2
    );
}
