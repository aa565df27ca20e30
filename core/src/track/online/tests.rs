//! Tests of the online tracker: association, the pending ReID decisions and contact repair.

use nalgebra::{Matrix2, Matrix3, Vector2};

use super::track::ProvisionalLink;
use super::*;
use crate::track::appearance::AppearanceMean;
use crate::track::contact::{ContactIdentity, ContactObject};
use crate::track::kalman::BoxKalman;
use crate::track::reid::{associate_exits_to_entries_where, TrackEnd};
use crate::track::scenes;
use crate::track::types::{Detection, ExchangeEvent};
use crate::track::world::{WorldFilter, WorldObservation, WorldState};

/// A tracker whose memory bank holds two swimmers that left the view at `t = 0` at east
/// 0 m and 10 m, with two new tracks of `ages` frames at east `entries_e_m` (14 s later),
/// in frame 1000.
fn two_exits_and_entries(entries_e_m: &[f64], ages: &[u64]) -> Tracker {
    two_exits_and_entries_with(TrackerParams::default(), entries_e_m, ages)
}

fn two_exits_and_entries_with(params: TrackerParams, entries_e_m: &[f64], ages: &[u64]) -> Tracker {
    let mut tr = Tracker::new(params).unwrap();
    let exit_state = |e: f64| WorldState {
        pos_ne_m: Vector2::new(0.0, e),
        vel_ne_m_s: Vector2::zeros(),
        cov: nalgebra::Matrix4::from_diagonal(&nalgebra::Vector4::new(0.25, 0.25, 0.01, 0.01)),
    };
    for (k, e) in [0.0, 10.0].into_iter().enumerate() {
        tr.memory.push(MemoryEntry {
            uid: k as u64 + 1,
            id: k as u64 + 1,
            end_frame: 500,
            exit: track_end(1, 0.0, &exit_state(e), true),
        });
    }
    for (k, (&e, &age)) in entries_e_m.iter().zip(ages).enumerate() {
        let bbox = BBox::from_center(100.0 + 50.0 * k as f64, 100.0, 10.0, 10.0);
        let obs = WorldObservation {
            pos_ne_m: Vector2::new(0.0, e),
            cov_ne_m2: Matrix2::identity() * 0.25,
        };
        tr.tracks.push(Track {
            uid: 10 + k as u64,
            id: 10 + k as u64,
            kf: BoxKalman::initiate(&bbox),
            phase: Phase::Tracked,
            activated: true,
            score: 0.9,
            class_votes: vec![(1, 10)],
            start_frame: 1000 - age,
            end_frame: 1000,
            world: Some(WorldFilter::initiate(&obs, 14.0)),
            last_bbox: bbox,
            last_image_size_px: (1000, 800),
            reid_decided: false,
            provisional_link: None,
            flagged_provisional: false,
            matched_det: None,
            appearance: AppearanceMean::default(),
            contact: ContactIdentity::default(),
            object: ContactObject::default(),
        });
    }
    tr
}

/// A swimmer seen for 10 frames and missed for 3 is seen again 200 px away in the image
/// (a camera jump) at its sea-surface position, so only the world stage can take the
/// box. A low-confidence box brings the lost track back only with
/// `baseline.world_low_confidence_to_lost`; a high-confidence one always does.
#[test]
fn low_confidence_boxes_bring_lost_tracks_back_only_when_allowed() {
    let back_under_first_id = |to_lost: bool, score: f32| {
        let mut p = TrackerParams::default();
        p.reid.enabled = false;
        p.baseline.world_low_confidence_to_lost = to_lost;
        assert!(p.baseline.track_low_thresh < 0.3 && 0.3 < p.baseline.track_high_thresh);
        let mut tr = Tracker::new(p).unwrap();
        let obs = WorldObservation {
            pos_ne_m: Vector2::zeros(),
            cov_ne_m2: Matrix2::identity() * 0.25,
        };
        let frame = |i: u64, det: Option<(f64, f32)>| FrameInput {
            frame_index: i,
            time_s: i as f64 / 30.0,
            image_size_px: (640, 480),
            detections: det
                .map(|(x, score)| Detection {
                    bbox: BBox::from_center(x, 100.0, 20.0, 20.0),
                    score,
                    class_id: 1,
                    world: Some(obs),
                    appearance: None,
                })
                .into_iter()
                .collect(),
            image_motion: None,
        };
        let mut first_id = None;
        for i in 1..=10 {
            let out = tr.step(&frame(i, Some((100.0, 0.9)))).unwrap();
            first_id = out.tracks.first().map(|t| t.id);
        }
        for i in 11..=13 {
            tr.step(&frame(i, None)).unwrap();
        }
        let out = tr.step(&frame(14, Some((300.0, score)))).unwrap();
        assert!(first_id.is_some());
        out.tracks
            .iter()
            .any(|t| Some(t.id) == first_id && t.detection_index == Some(0))
    };
    assert!(!back_under_first_id(false, 0.3));
    assert!(back_under_first_id(true, 0.3));
    assert!(back_under_first_id(false, 0.9));
}

/// Two swimmers of a group come back: the one seen first (east 6 m) is nearer the
/// group-mate's exit (10 m) than its own (0 m), but the group-mate seen a few frames
/// later (11 m) fits that exit far better. The younger, undecided track takes part in
/// the assignment as a rival, so the decision that is due links the first track to its
/// own exit; decided alone it would take the group-mate's.
#[test]
fn an_undecided_rival_keeps_the_due_track_off_a_group_mates_exit() {
    let w = u64::from(TrackerParams::default().reid.window_frames);
    let mut tr = two_exits_and_entries(&[6.0, 11.0], &[w, w / 2]);
    let mut merges = Vec::new();
    tr.online_reid(1000, false, &mut merges);
    assert_eq!(merges.len(), 1, "only the due track is decided: {merges:?}");
    assert_eq!((merges[0].new_id, merges[0].merged_into_id), (10, 1));
    // the rival stays undecided and the group-mate's exit stays in the bank for it
    assert!(!tr.tracks[1].reid_decided);
    assert_eq!(tr.memory.iter().map(|m| m.id).collect::<Vec<_>>(), vec![2]);

    // without the rival (and without waiting for one) the same due track takes the
    // nearer, wrong exit
    let mut params = TrackerParams::default();
    params.reid.defer_margin_chi2 = 0.0;
    let mut alone = two_exits_and_entries_with(params, &[6.0], &[w]);
    let mut merges = Vec::new();
    alone.online_reid(1000, false, &mut merges);
    assert_eq!(merges.len(), 1);
    assert_eq!((merges[0].new_id, merges[0].merged_into_id), (10, 2));
}

/// The due track alone, between its own exit (0 m) and a group-mate's (10 m) that nobody
/// claims: the two links cost nearly the same, so the decision waits (the track stays
/// provisional) until the group-mate comes back and both are decided together, or, if it
/// never does, until `defer_max_frames` have passed.
#[test]
fn a_contested_decision_waits_for_the_group_mate() {
    let p = TrackerParams::default();
    let w = u64::from(p.reid.window_frames);
    let max = u64::from(p.reid.defer_max_frames);
    assert!(p.reid.defer_margin_chi2 > 0.0 && max > 0);
    let entry_e_m = 4.8;
    let mut tr = two_exits_and_entries(&[entry_e_m], &[w]);
    let mut merges = Vec::new();
    tr.online_reid(1000, false, &mut merges);
    tr.flag_provisional();
    assert!(merges.is_empty(), "contested: no decision yet, {merges:?}");
    assert!(!tr.tracks[0].reid_decided);
    assert!(tr.tracks[0].is_provisional());
    assert_eq!(tr.memory.len(), 2);

    // The group-mate comes back at 11 m: the next call decides the waiting track, and
    // jointly, so it takes its own exit.
    let mut both = two_exits_and_entries(&[entry_e_m, 11.0], &[w + 1, 1]);
    let mut merges = Vec::new();
    both.online_reid(1000, false, &mut merges);
    assert_eq!(merges.len(), 1, "{merges:?}");
    assert_eq!((merges[0].new_id, merges[0].merged_into_id), (10, 1));
    assert!(both.tracks[0].reid_decided && !both.tracks[1].reid_decided);

    // Nobody comes: after `defer_max_frames` more the best link is taken.
    let mut late = two_exits_and_entries(&[entry_e_m], &[w + max]);
    let mut merges = Vec::new();
    late.online_reid(1000, false, &mut merges);
    assert_eq!(merges.len(), 1);
    assert!(late.tracks[0].reid_decided);
}

/// An undecided track that once lay within an exit's gate stays provisional while its
/// young entry wanders out of every gate, until its decision; a track that never lay
/// within one is not provisional.
#[test]
fn a_provisional_flag_holds_until_the_decision() {
    let w = u64::from(TrackerParams::default().reid.window_frames);
    let mut tr = two_exits_and_entries(&[0.5, 100.0], &[w / 2, w / 2]);
    tr.flag_provisional();
    assert!(tr.tracks[0].is_provisional());
    assert!(!tr.tracks[1].is_provisional(), "100 m from every exit");

    let far = WorldObservation {
        pos_ne_m: Vector2::new(0.0, 100.0),
        cov_ne_m2: Matrix2::identity() * 0.25,
    };
    tr.tracks[0].world = Some(WorldFilter::initiate(&far, 14.0));
    tr.flag_provisional();
    assert!(
        tr.tracks[0].is_provisional(),
        "the entry left the gate, the flag holds"
    );

    tr.tracks[0].reid_decided = true;
    assert!(
        !tr.tracks[0].is_provisional(),
        "decided: no longer provisional"
    );
}

/// A young track beside a swimmer's exit, not yet due for its decision, is reported
/// under that swimmer's old id, flagged provisional, and the old track's own coasting
/// report gives way to it; with `provisional_old_id` off it keeps its new id.
#[test]
fn an_undecided_track_is_reported_under_the_old_id_it_would_take() {
    let w = u64::from(TrackerParams::default().reid.window_frames);
    assert!(TrackerParams::default().reid.provisional_old_id);
    let mut tr = two_exits_and_entries(&[0.5], &[w / 2]);
    // the old swimmer 1 was lost a frame ago and would still coast
    let mut old = tr.tracks[0].clone();
    (old.uid, old.id, old.phase, old.start_frame, old.end_frame) = (1, 1, Phase::Lost, 400, 999);
    tr.tracks.push(old);
    let input = frame(1000, &[]);
    assert_eq!(
        tr.coasting(&input).count(),
        1,
        "before the provisional link it coasts"
    );

    let mut merges = Vec::new();
    tr.online_reid(1000, false, &mut merges);
    tr.flag_provisional();
    assert!(merges.is_empty(), "not due yet: {merges:?}");
    assert!(!tr.tracks[0].reid_decided);
    let out = tr.tracks[0].output(TrackState::Confirmed, None, tr.tracks[0].is_provisional());
    assert_eq!((out.id, out.provisional), (1, true));
    assert_eq!(tr.coasting(&input).count(), 0, "the old track gives way");

    // once decided (the exit of swimmer 2, 10 m away, is a rival close enough to make
    // the decision wait; at its last frame), it takes that id and the provisional link
    // is gone
    let last_call = w + u64::from(TrackerParams::default().reid.defer_max_frames);
    tr.tracks[0].start_frame = 1000 - last_call;
    tr.online_reid(1000, false, &mut merges);
    tr.flag_provisional();
    assert_eq!(merges.len(), 1);
    assert_eq!((merges[0].new_id, merges[0].merged_into_id), (10, 1));
    assert_eq!(tr.tracks[0].provisional_link, None);
    let out = tr.tracks[0].output(TrackState::Confirmed, None, tr.tracks[0].is_provisional());
    assert_eq!((out.id, out.provisional), (1, false));

    let mut params = TrackerParams::default();
    params.reid.provisional_old_id = false;
    let mut off = two_exits_and_entries_with(params, &[0.5], &[w / 2]);
    off.online_reid(1000, false, &mut merges);
    assert_eq!(off.tracks[0].provisional_link, None);
    let out = off.tracks[0].output(TrackState::Confirmed, None, true);
    assert_eq!(out.id, 10);
}

/// A track one frame old, 20 m beyond a swimmer's exit: its filter's velocity is still
/// the initial guess (10 m/s std), which would carry it back to that exit within the
/// gate, so the provisional old id is sought from its position alone and it gets none.
#[test]
fn a_young_track_gets_no_provisional_id_from_its_unsettled_velocity() {
    let mut tr = two_exits_and_entries(&[30.0], &[1]);
    let mut merges = Vec::new();
    tr.online_reid(1000, false, &mut merges);
    assert!(merges.is_empty());
    assert_eq!(tr.tracks[0].provisional_link, None);

    // control: with its raw entry (the filter's velocity and covariance) the same
    // assignment links it to the nearer exit
    let entry = tr.tracks[0].entry(1).unwrap();
    let exits: Vec<TrackEnd> = tr.memory.iter().map(|m| m.exit).collect();
    let links =
        associate_exits_to_entries_where(&exits, &[entry], &tr.params.reid, &tr.drift, |_, _| true);
    assert_eq!(links, vec![(1, 0)]);
}

/// Memory-bank ids after the tracks of `two_exits_and_entries(entries_e_m, ages)` got
/// their provisional old ids and were all lost.
fn memory_after_loss(params: TrackerParams, entries_e_m: &[f64], ages: &[u64]) -> Vec<u64> {
    let mut tr = two_exits_and_entries_with(params, entries_e_m, ages);
    let mut merges = Vec::new();
    tr.online_reid(1000, false, &mut merges);
    assert!(merges.is_empty(), "{merges:?}");
    for i in 0..tr.tracks.len() {
        tr.mark_lost(i);
    }
    tr.memory.iter().map(|m| m.id).collect()
}

/// A track lost three frames after it appeared beside a swimmer's exit (a glimpse, under
/// that swimmer's provisional id) is forgotten, so the swimmer's next track is offered
/// the swimmer's own exit rather than the glimpse's fresher one; a glimpse far from
/// every exit (no provisional id: a new object's first sighting) and a track that lived
/// past `window_frames` join the memory bank. With `forget_glimpses` off, all do.
#[test]
fn a_glimpse_under_a_provisional_id_is_forgotten_when_lost() {
    let w = u64::from(TrackerParams::default().reid.window_frames);
    let on = memory_after_loss(TrackerParams::default(), &[1.0, 60.0], &[3, 3]);
    assert_eq!(
        on,
        vec![1, 2, 11],
        "the glimpse beside exit 1 (id 10) is forgotten"
    );
    let mut off = TrackerParams::default();
    off.reid.forget_glimpses = false;
    assert_eq!(
        memory_after_loss(off, &[1.0, 60.0], &[3, 3]),
        vec![1, 2, 10, 11]
    );
    // a track past its window with a contested decision still pending is no glimpse
    let mut tr = two_exits_and_entries(&[5.0], &[w + 1]);
    tr.tracks[0].provisional_link = Some(ProvisionalLink { id: 1, uid: 1 });
    tr.mark_lost(0);
    assert_eq!(
        tr.memory.iter().map(|m| m.id).collect::<Vec<_>>(),
        vec![1, 2, 10]
    );
}

/// A frame of 640 x 480 px at 30 fps with swimmer detections at these box centres.
fn frame(index: u64, centres: &[(f64, f64)]) -> FrameInput {
    FrameInput {
        frame_index: index,
        time_s: index as f64 / 30.0,
        image_size_px: (640, 480),
        detections: centres
            .iter()
            .map(|&(x, y)| Detection {
                bbox: BBox::from_center(x, y, 20.0, 20.0),
                score: 0.9,
                class_id: 1,
                world: None,
                appearance: None,
            })
            .collect(),
        image_motion: None,
    }
}

/// Steps a swimmer moving right by 4 px a frame through frames 1-5 at `x0`, then frames
/// 6-9 without detections; returns each frame's reported tracks.
fn missed_after_five(params: TrackerParams, x0: f64) -> Vec<Vec<TrackOutput>> {
    let mut tr = Tracker::new(params).unwrap();
    (1..=9)
        .map(|i| {
            let centres = if i <= 5 {
                vec![(x0 + 4.0 * i as f64, 200.0)]
            } else {
                vec![]
            };
            tr.step(&frame(i, &centres)).unwrap().tracks
        })
        .collect()
}

#[test]
fn a_missed_track_coasts_for_coast_frames_with_its_predicted_box() {
    let out = missed_after_five(TrackerParams::default(), 100.0);
    assert_eq!(TrackerParams::default().baseline.coast_frames, 2);
    let id = out[4][0].id;
    assert_eq!(out[4][0].state, TrackState::Confirmed);
    assert!(out[4][0].detection_index.is_some());
    for f in [5, 6] {
        assert_eq!(out[f].len(), 1, "frame {} coasts", f + 1);
        let t = &out[f][0];
        assert_eq!(
            (t.id, t.state, t.detection_index),
            (id, TrackState::Lost, None)
        );
        // The box keeps moving with the filter's velocity.
        assert!(t.bbox.center().0 > out[f - 1][0].bbox.center().0);
    }
    assert!(
        out[7].is_empty() && out[8].is_empty(),
        "coasting ends after 2 frames"
    );
}

#[test]
fn no_coasting_at_zero_or_out_of_the_image() {
    let mut p = TrackerParams::default();
    p.baseline.coast_frames = 0;
    let out = missed_after_five(p, 100.0);
    assert_eq!(out[4].len(), 1);
    assert!(out[5].is_empty());
    // A swimmer whose predicted box crosses the right border is not reported.
    let out = missed_after_five(TrackerParams::default(), 610.0);
    assert_eq!(out[4].len(), 1);
    assert!(out[4][0].bbox.x + out[4][0].bbox.w <= 640.0);
    assert!(out[5]
        .iter()
        .chain(&out[6])
        .all(|t| t.state == TrackState::Confirmed));
    assert!(out[5].is_empty());
}

/// What [`meet_and_turn_back`] saw: per frame, the reported id nearest the left swimmer
/// and the right one; the ids of the first and second swimmer at frame 5; the contact
/// repairs.
type MeetingIds = (Vec<(u64, u64)>, (u64, u64), Vec<ExchangeEvent>);

/// Steps [`scenes::meet_and_turn_back`] through a tracker.
fn meet_and_turn_back(params: TrackerParams, colours: (usize, usize)) -> MeetingIds {
    let mut tr = Tracker::new(params).unwrap();
    let mut ids = Vec::new();
    let mut first = (0, 0);
    let mut exchanges = Vec::new();
    for (f, (x0, x1)) in scenes::meet_and_turn_back(colours) {
        let out = tr.step(&f).unwrap();
        let by_x =
            |x: f64| scenes::nearest_id(out.tracks.iter().map(|t| (t.id, t.bbox)), x).unwrap_or(0);
        if f.frame_index == 5 {
            first = (by_x(x0), by_x(x1));
        }
        ids.push((by_x(x0.min(x1)), by_x(x0.max(x1))));
        exchanges.extend(out.exchanges);
    }
    (ids, first, exchanges)
}

#[test]
fn a_swap_in_contact_is_repaired_by_the_colours_once_the_two_part() {
    let mut off = TrackerParams::default();
    off.contact.enabled = false;
    let (ids, (red, blue), exchanges) = meet_and_turn_back(off, (0, 8));
    assert_ne!(red, blue);
    // Without the repair the ids swap at the meeting and stay swapped.
    assert_eq!(ids[20], (red, blue));
    assert_eq!(ids[69], (blue, red));
    assert!(exchanges.is_empty());

    let (ids, (red2, blue2), exchanges) = meet_and_turn_back(TrackerParams::default(), (0, 8));
    assert_eq!((red2, blue2), (red, blue));
    assert_eq!(ids[20], (red, blue));
    // Swapped right after the meeting (the boxes still overlap, nothing to judge by) ...
    assert_eq!(ids[35], (blue, red));
    // ... and back from the tenth clean detection after the contact on.
    let repaired = ids.iter().rposition(|&p| p == (blue, red)).unwrap() + 1;
    assert!(
        (40..55).contains(&repaired),
        "repaired at index {repaired}: {ids:?}"
    );
    assert!(ids[repaired..].iter().all(|&p| p == (red, blue)), "{ids:?}");
    // One repair, reported with the frame where the boxes coincided (the swap).
    assert_eq!(exchanges.len(), 1, "{exchanges:?}");
    let e = exchanges[0];
    assert_eq!(e.frame_index, repaired as u64 + 1);
    assert_eq!(e.since_frame_index, 30);
    let mut pair = [e.id, e.other_id];
    pair.sort_unstable();
    assert_eq!(pair, [red.min(blue), red.max(blue)]);
}

#[test]
fn swimmers_of_one_colour_are_not_exchanged() {
    let (ids, (a, b), exchanges) = meet_and_turn_back(TrackerParams::default(), (3, 3));
    assert!(exchanges.is_empty());
    assert_ne!(a, b);
    assert_eq!(ids[20], (a, b));
    assert_eq!(ids[69], (b, a));
}

/// A still swimmer at (200, 200) for frames 1-5, then the camera pans: frame 6 has the
/// homography of a 60 px shift to the right and the swimmer's box there. Returns the
/// ids reported in frames 5 and 6.
fn pan_by_60(params: TrackerParams) -> (Vec<u64>, Vec<u64>) {
    let mut tr = Tracker::new(params).unwrap();
    let mut before = Vec::new();
    for i in 1..=5 {
        before = tr.step(&frame(i, &[(200.0, 200.0)])).unwrap().tracks;
    }
    let mut panned = frame(6, &[(260.0, 200.0)]);
    panned.image_motion = Some(Matrix3::new(1.0, 0.0, 60.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0));
    let after = tr.step(&panned).unwrap().tracks;
    let ids = |v: &[TrackOutput]| -> Vec<u64> {
        v.iter()
            .filter(|t| t.detection_index.is_some())
            .map(|t| t.id)
            .collect()
    };
    (ids(&before), ids(&after))
}

#[test]
fn camera_motion_compensation_carries_tracks_through_a_pan_and_can_be_switched_off() {
    let (before, after) = pan_by_60(TrackerParams::default());
    assert_eq!(before.len(), 1);
    assert_eq!(
        after, before,
        "compensated: the same track matches after the pan"
    );
    let mut p = TrackerParams::default();
    p.baseline.camera_motion_compensation = false;
    let (before, after) = pan_by_60(p);
    assert_eq!(before.len(), 1);
    // The 20 px box moved by 60 px: no overlap with the uncompensated prediction, so the
    // detection starts a new, still tentative track and nothing matched is reported.
    assert!(after.is_empty(), "uncompensated: the pan loses the track");
}

#[test]
fn majority_vote_with_deterministic_ties() {
    let mut v = Vec::new();
    for c in [2, 1, 2, 1, 3] {
        add_vote(&mut v, c);
    }
    assert_eq!(majority_class(&v), 1); // 1 and 2 tie at two votes: lower id
    add_vote(&mut v, 2);
    assert_eq!(majority_class(&v), 2);
    assert_eq!(majority_class(&[]), 0);
}
