//! What the online tracker keeps: each track's record and life-cycle phase, the provisional
//! link of an undecided one, and the memory-bank entry of a lost one.

use crate::track::appearance::AppearanceMean;
use crate::track::bbox::BBox;
use crate::track::contact::{ContactIdentity, ContactObject};
use crate::track::kalman::BoxKalman;
use crate::track::reid::TrackEnd;
use crate::track::types::{TrackOutput, TrackState};
use crate::track::world::{WorldFilter, WorldObservation, WorldState};

/// Where a live track is in the BoT-SORT life cycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Phase {
    Tracked,
    Lost,
    Removed,
}

/// One track as the tracker keeps it.
#[derive(Debug, Clone)]
pub(super) struct Track {
    /// Baseline identity: never changes, keys the memory bank.
    pub(super) uid: u64,
    /// Reported id; becomes the old id when online ReID links this track.
    pub(super) id: u64,
    /// Image-plane box state.
    pub(super) kf: BoxKalman,
    /// Life-cycle state.
    pub(super) phase: Phase,
    /// BoT-SORT `is_activated`: matched at least twice (or born in the first frame).
    pub(super) activated: bool,
    /// Score of the last matched detection (the reported confidence).
    pub(super) score: f32,
    /// (class id, count) of every matched detection, for the majority vote.
    pub(super) class_votes: Vec<(u32, u32)>,
    /// Frame the track was born in (age for duplicates and the ReID window).
    pub(super) start_frame: u64,
    /// Last frame with a matched detection.
    pub(super) end_frame: u64,
    /// World position/velocity filter, from the first world observation on.
    pub(super) world: Option<WorldFilter>,
    /// Last matched detection box and the image size it was seen in (did it leave the view?).
    pub(super) last_bbox: BBox,
    /// Image size of the frame `last_bbox` was seen in.
    pub(super) last_image_size_px: (u32, u32),
    /// Online ReID has been tried for this track (once, at `w` frames).
    pub(super) reid_decided: bool,
    /// Detection matched in the current frame.
    pub(super) matched_det: Option<usize>,
    /// While undecided: the memory entry ReID would link this track to now, whose id it is
    /// reported under (`reid.provisional_old_id`).
    pub(super) provisional_link: Option<ProvisionalLink>,
    /// While undecided: it has been reported provisional (it lay within the gate of an exit
    /// in the memory bank, or carried a provisional old id) and stays so until its decision.
    pub(super) flagged_provisional: bool,
    /// Mean colour signature of the matched detections that had one.
    pub(super) appearance: AppearanceMean,
    /// Contact repair: what this identity looked like before its contact.
    pub(super) contact: ContactIdentity,
    /// Contact repair: what the followed object looked like since its last contact.
    pub(super) object: ContactObject,
}

/// The old track an undecided track is reported as while its decision is pending.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct ProvisionalLink {
    /// Reported id of the old track.
    pub(super) id: u64,
    /// Baseline identity of the old track (its coasting report gives way).
    pub(super) uid: u64,
}

impl Track {
    /// Exchanges the objects two tracks follow (contact repair): the box and world filters,
    /// the life cycle and the last detection go with the object; the identity (ids, class
    /// votes, start, ReID state, appearance mean, contact anchor) stays.
    pub(super) fn exchange_objects(&mut self, other: &mut Track) {
        std::mem::swap(&mut self.kf, &mut other.kf);
        std::mem::swap(&mut self.world, &mut other.world);
        std::mem::swap(&mut self.phase, &mut other.phase);
        std::mem::swap(&mut self.activated, &mut other.activated);
        std::mem::swap(&mut self.score, &mut other.score);
        std::mem::swap(&mut self.end_frame, &mut other.end_frame);
        std::mem::swap(&mut self.last_bbox, &mut other.last_bbox);
        std::mem::swap(&mut self.last_image_size_px, &mut other.last_image_size_px);
        std::mem::swap(&mut self.matched_det, &mut other.matched_det);
        std::mem::swap(&mut self.object, &mut other.object);
    }

    /// Whether the track is reported provisional (see [`TrackOutput::provisional`]):
    /// undecided and flagged by [`Tracker::flag_provisional`](super::Tracker::flag_provisional) (which flags nothing with ReID
    /// off).
    pub(super) fn is_provisional(&self) -> bool {
        !self.reid_decided && self.flagged_provisional
    }

    /// Majority class of the matched detections (see [`majority_class`]).
    pub(super) fn class_id(&self) -> u32 {
        majority_class(&self.class_votes)
    }

    /// The track's exit as seen by ReID: its world filter's state at the last observation,
    /// if it has had world observations.
    pub(super) fn exit(&self, border_fraction: f64, appearance_min_count: u32) -> Option<TrackEnd> {
        let w = self.world.as_ref()?;
        Some(TrackEnd {
            appearance: self.appearance.mean(appearance_min_count),
            ..track_end(
                self.class_id(),
                w.time_s(),
                w.state(),
                self.last_bbox
                    .touches_border(self.last_image_size_px, border_fraction),
            )
        })
    }

    /// The track as reported: its Kalman box and the detection matched in this frame (none
    /// when it was missed), with the given state, world state and provisional flag, under
    /// its provisional old id while it has one.
    pub(super) fn output(
        &self,
        state: TrackState,
        world: Option<WorldState>,
        provisional: bool,
    ) -> TrackOutput {
        TrackOutput {
            id: self.provisional_link.map_or(self.id, |l| l.id),
            bbox: self.kf.bbox(),
            score: self.score,
            class_id: self.class_id(),
            state,
            world,
            detection_index: self.matched_det,
            provisional,
        }
    }

    /// The track's entry as seen by ReID: its world filter's state now (when the ReID
    /// decision is taken, `w` frames after the track started, so the velocity has had
    /// those observations to settle).
    pub(super) fn entry(&self, appearance_min_count: u32) -> Option<TrackEnd> {
        let w = self.world.as_ref()?;
        Some(TrackEnd {
            appearance: self.appearance.mean(appearance_min_count),
            ..track_end(self.class_id(), w.time_s(), w.state(), false)
        })
    }
}

/// A [`TrackEnd`] from a world state at `time_s`.
pub(crate) fn track_end(
    class_id: u32,
    time_s: f64,
    state: &WorldState,
    left_view: bool,
) -> TrackEnd {
    TrackEnd {
        class_id,
        time_s,
        pos_ne_m: state.pos_ne_m,
        vel_ne_m_s: state.vel_ne_m_s,
        pos_cov_m2: state.pos_cov_m2(),
        vel_cov_m2_s2: state.cov.fixed_view::<2, 2>(2, 2).into_owned(),
        left_view,
        appearance: None,
    }
}

/// Majority vote; ties go to the lower class id so the result is deterministic.
pub(crate) fn majority_class(votes: &[(u32, u32)]) -> u32 {
    votes
        .iter()
        .max_by(|a, b| a.1.cmp(&b.1).then(b.0.cmp(&a.0)))
        .map_or(0, |v| v.0)
}

/// Counts one more detection of `class_id` in `votes` (see [`majority_class`]).
pub(crate) fn add_vote(votes: &mut Vec<(u32, u32)>, class_id: u32) {
    match votes.iter_mut().find(|v| v.0 == class_id) {
        Some(v) => v.1 += 1,
        None => votes.push((class_id, 1)),
    }
}

/// A finished (lost or removed) track waiting in the memory bank for re-identification.
#[derive(Debug, Clone)]
pub(super) struct MemoryEntry {
    /// Baseline identity of the lost track (to drop the entry if IoU matching resumes it).
    pub(super) uid: u64,
    /// Reported id a linked track will take over.
    pub(super) id: u64,
    /// Last frame the track was matched in: a candidate must start after it.
    pub(super) end_frame: u64,
    /// Where, when and how fast it was last seen.
    pub(super) exit: TrackEnd,
}

/// Feeds a matched detection's world observation to the track's world filter.
pub(super) fn record_world(
    t: &mut Track,
    obs: Option<&WorldObservation>,
    time_s: f64,
    accel_std_m_s2: f64,
) {
    let Some(obs) = obs else {
        return;
    };
    if !(obs.pos_ne_m.iter().all(|v| v.is_finite()) && obs.cov_ne_m2.iter().all(|v| v.is_finite()))
    {
        return;
    }
    match &mut t.world {
        Some(f) => {
            f.predict(time_s, accel_std_m_s2);
            f.update(obs);
        }
        None => t.world = Some(WorldFilter::initiate(obs, time_s)),
    }
}
