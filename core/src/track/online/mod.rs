//! The online tracker: BoT-SORT-style association per frame plus MG-MOT ReID, decided once a
//! new track has lived `w` frames and reported as a merge event.
//!
//! [`Tracker::step`] runs the stages of a frame, each in its own module:
//!
//! - `association`: detection selection, prediction and camera-motion compensation, the
//!   BoT-SORT association stages and the world stage, new tracks;
//! - `contact_repair`: contact repair (see [`crate::track::contact`]) wired into the step;
//! - `pending`: the memory bank and the pending ReID decisions (due, deferred, provisional
//!   old ids, glimpses);
//! - `track`: what the tracker keeps per track and per memory-bank entry.
//!
//! This module holds the tracker itself, its public API, the frame step, coasting, expiry
//! and the drift observations.

mod association;
mod contact_repair;
mod pending;
#[cfg(test)]
mod tests;
mod track;

use nalgebra::Vector2;

use self::track::{MemoryEntry, Phase, Track};
use super::bbox::BBox;
use super::drift::SeaDrift;
use super::error::TrackError;
use super::params::TrackerParams;
use super::types::{FrameInput, FrameOutput, MergeEvent, TrackOutput, TrackState};

pub(crate) use self::track::{add_vote, majority_class, track_end};

/// Buffers reused across frames so a step does not allocate per detection or track.
#[derive(Debug, Clone, Default)]
struct Scratch {
    boxes: Vec<BBox>,
    candidates: Vec<usize>,
    kept: Vec<usize>,
    high: Vec<usize>,
    low: Vec<usize>,
    det_used: Vec<bool>,
    rows: Vec<usize>,
    cols: Vec<usize>,
    cost: Vec<f64>,
    pairs: Vec<(usize, usize)>,
    track_matched: Vec<bool>,
    /// Majority class per row of an IoU stage.
    classes: Vec<u32>,
    /// Contact repair: the boxes of the frame's candidate detections, their order by left
    /// edge, each one's largest IoU with another, the pairs in contact, the tracked track of
    /// each (`usize::MAX`: none), each detection's candidate position, whether each track is
    /// in contact.
    candidate_boxes: Vec<BBox>,
    order: Vec<usize>,
    max_iou: Vec<f64>,
    contact_pairs: Vec<(usize, usize)>,
    live: Vec<usize>,
    det_pos: Vec<usize>,
    in_contact: Vec<bool>,
}

/// The online tracker: feed it frames in order with [`Tracker::step`].
///
/// Per frame: prefer-larger NMS, camera-motion compensation with the caller's homography,
/// BoT-SORT's three association stages (high-confidence detections against confirmed and
/// lost tracks, low-confidence detections against the remaining tracked ones, high against
/// tentative tracks), new tracks, lost-track expiry. Every matched detection with a world
/// observation updates the track's world filter. A track that had been reported and is lost
/// enters the memory bank; a new track that has lived `w` frames is matched against the bank
/// (short-term, then long-term ReID) and, if linked, takes the old id from then on, with a
/// [`MergeEvent`].
#[derive(Debug, Clone)]
pub struct Tracker {
    /// Validated parameters, fixed for the tracker's life.
    params: TrackerParams,
    /// Tentative, confirmed and lost tracks (removed ones are dropped at the end of a step).
    tracks: Vec<Track>,
    /// The MG-MOT memory bank: exits of reported tracks that were lost, waiting for ReID.
    memory: Vec<MemoryEntry>,
    /// Next baseline id; ids are never reused.
    next_uid: u64,
    /// Steps so far: BoT-SORT activates the tracks of the very first frame at once.
    steps: u64,
    /// Frame number of the previous step: frame gaps drive prediction and the lost buffer.
    last_frame_index: Option<u64>,
    /// Time of the previous step, s: rejects time going backwards; world predictions.
    last_time_s: f64,
    /// Sea drift per class, estimated from the settled tracks of classes adrift.
    drift: SeaDrift,
    /// Reused buffers.
    scratch: Scratch,
}

impl Tracker {
    /// A tracker with validated parameters.
    pub fn new(params: TrackerParams) -> Result<Self, TrackError> {
        params.validate()?;
        Ok(Self {
            drift: SeaDrift::new(params.reid.drift.clone()),
            params,
            tracks: Vec::new(),
            memory: Vec::new(),
            next_uid: 1,
            steps: 0,
            last_frame_index: None,
            last_time_s: f64::NEG_INFINITY,
            scratch: Scratch::default(),
        })
    }

    /// The parameters in use.
    pub fn params(&self) -> &TrackerParams {
        &self.params
    }

    /// The sea drift estimated so far (see [`SeaDrift`]).
    pub fn sea_drift(&self) -> &SeaDrift {
        &self.drift
    }

    /// Number of tracks currently kept (tentative, confirmed and lost).
    pub fn live_track_count(&self) -> usize {
        self.tracks.len()
    }

    /// Whether the ReID memory bank still holds an ended track reported as `id`, so that a
    /// new track may yet be re-identified as it and take `id` back (with a [`MergeEvent`]).
    /// An ended track stays there until a track takes its id, IoU matching resumes it, or
    /// `reid.memory_max_s` has passed; never while ReID (short- or long-term) is off.
    pub fn remembers(&self, id: u64) -> bool {
        let reid = &self.params.reid;
        reid.enabled
            && (reid.short_term || reid.long_term)
            && self.memory.iter().any(|m| m.id == id)
    }

    /// Every track the tracker keeps after the last step, in any state (the step output
    /// holds the confirmed ones only): lost tracks report their Kalman-predicted box and
    /// their world state predicted to the last frame's time, with no detection.
    pub fn live_tracks(&self) -> impl Iterator<Item = TrackOutput> + '_ {
        let accel = self.params.baseline.world_accel_std_m_s2;
        self.tracks.iter().map(move |t| {
            let state = match (t.phase, t.activated) {
                (Phase::Tracked, true) => TrackState::Confirmed,
                (Phase::Tracked, false) => TrackState::Tentative,
                (Phase::Lost, _) => TrackState::Lost,
                (Phase::Removed, _) => TrackState::Removed,
            };
            let world = t
                .world
                .as_ref()
                .map(|w| w.predicted(self.last_time_s, accel));
            t.output(state, world, false)
        })
    }

    /// Processes one frame. Frames must come in increasing `frame_index` order; an
    /// out-of-order frame is rejected without changing the tracker.
    pub fn step(&mut self, input: &FrameInput) -> Result<FrameOutput, TrackError> {
        if let Some(last) = self.last_frame_index {
            if input.frame_index <= last {
                return Err(TrackError::FrameOrder {
                    frame_index: input.frame_index,
                    previous: last,
                });
            }
        }
        if !input.time_s.is_finite() || input.time_s < self.last_time_s {
            return Err(TrackError::TimeOrder {
                frame_index: input.frame_index,
                time_s: input.time_s,
            });
        }
        let dt_frames = self
            .last_frame_index
            .map_or(1.0, |last| (input.frame_index - last) as f64);
        self.last_frame_index = Some(input.frame_index);
        self.last_time_s = input.time_s;
        self.steps += 1;

        self.select_detections(&input.detections);
        self.predict_and_compensate(dt_frames, input);
        self.associate(input);
        let mut exchanges = Vec::new();
        if self.params.contact.enabled {
            self.repair_contacts(input, &mut exchanges);
        }
        self.expire(input);
        self.observe_drift(input.time_s);

        let mut merges = Vec::new();
        if self.params.reid.enabled {
            self.online_reid(input.frame_index, false, &mut merges);
        }
        self.tracks.retain(|t| t.phase != Phase::Removed);
        self.flag_provisional();

        let mut tracks: Vec<TrackOutput> = self
            .tracks
            .iter()
            .filter(|t| t.phase == Phase::Tracked && t.activated)
            .map(|t| {
                let world = t.world.as_ref().map(|w| *w.state());
                t.output(TrackState::Confirmed, world, t.is_provisional())
            })
            .collect();
        // A coasting track whose provisional link went stale (its old id was since taken by a
        // track in view) is not reported: ids are unique in a frame.
        for c in self.coasting(input) {
            if !tracks.iter().any(|o| o.id == c.id) {
                tracks.push(c);
            }
        }
        tracks.sort_by_key(|t| t.id);
        Ok(FrameOutput {
            frame_index: input.frame_index,
            tracks,
            merges,
            exchanges,
        })
    }

    /// Lost tracks still reported in this frame (`baseline.coast_frames`): reported before,
    /// missed for at most `coast_frames` frames, their predicted box wholly inside the image.
    fn coasting<'a>(&'a self, input: &'a FrameInput) -> impl Iterator<Item = TrackOutput> + 'a {
        let coast = self.params.baseline.coast_frames;
        let accel = self.params.baseline.world_accel_std_m_s2;
        let (w, h) = input.image_size_px;
        self.tracks
            .iter()
            .filter(move |t| {
                t.phase == Phase::Lost
                    && t.activated
                    && input.frame_index.saturating_sub(t.end_frame) <= coast
                    && !self
                        .tracks
                        .iter()
                        .any(|o| o.provisional_link.is_some_and(|l| l.uid == t.uid))
            })
            .filter_map(move |t| {
                let b = t.kf.bbox();
                let inside = b.x >= 0.0
                    && b.y >= 0.0
                    && b.x + b.w <= f64::from(w)
                    && b.y + b.h <= f64::from(h);
                inside.then(|| {
                    let world = t.world.as_ref().map(|wf| wf.predicted(input.time_s, accel));
                    t.output(TrackState::Lost, world, t.is_provisional())
                })
            })
    }

    /// Ends the sequence: tracks younger than `w` frames get their ReID decision now (with
    /// the observations they have). Returns the resulting merges; the tracker may keep going
    /// afterwards.
    pub fn finish(&mut self) -> Vec<MergeEvent> {
        let mut merges = Vec::new();
        if self.params.reid.enabled {
            let frame_index = self.last_frame_index.unwrap_or(0);
            self.online_reid(frame_index, true, &mut merges);
        }
        self.tracks.retain(|t| t.phase != Phase::Removed);
        merges
    }

    /// Feeds the velocities of this frame's matched, settled tracks of classes adrift to the
    /// drift estimate.
    fn observe_drift(&mut self, time_s: f64) {
        let reid = &self.params.reid;
        let samples: Vec<(u32, u64, Vector2<f64>)> = self
            .tracks
            .iter()
            .filter(|t| t.phase == Phase::Tracked && t.activated && t.matched_det.is_some())
            .filter_map(|t| {
                let class_id = t.class_id();
                let w = t.world.as_ref()?.state();
                let vel_cov = w.cov.fixed_view::<2, 2>(2, 2).into_owned();
                (reid.class(class_id).adrift && self.drift.is_settled(&vel_cov)).then_some((
                    class_id,
                    t.uid,
                    w.vel_ne_m_s,
                ))
            })
            .collect();
        self.drift.observe(time_s, &samples);
    }

    /// Lost-track buffer, duplicate removal, memory-bank expiry.
    fn expire(&mut self, input: &FrameInput) {
        let buffer = self.params.baseline.track_buffer_frames;
        for t in &mut self.tracks {
            if t.phase == Phase::Lost && input.frame_index.saturating_sub(t.end_frame) > buffer {
                t.phase = Phase::Removed;
            }
        }
        // BoT-SORT remove_duplicate_stracks: a tracked and a lost track on the same box.
        let thr = self.params.baseline.duplicate_iou_dist;
        let n = self.tracks.len();
        for p in 0..n {
            if self.tracks[p].phase != Phase::Tracked {
                continue;
            }
            for q in 0..n {
                if self.tracks[q].phase != Phase::Lost {
                    continue;
                }
                let (tp, tq) = (&self.tracks[p], &self.tracks[q]);
                if 1.0 - tp.kf.bbox().iou(&tq.kf.bbox()) < thr {
                    let age_p = input.frame_index - tp.start_frame;
                    let age_q = input.frame_index - tq.start_frame;
                    if age_p > age_q {
                        self.tracks[q].phase = Phase::Removed;
                    } else {
                        self.tracks[p].phase = Phase::Removed;
                        break;
                    }
                }
            }
        }
        let max_s = self.params.reid.memory_max_s;
        self.memory
            .retain(|m| input.time_s - m.exit.time_s <= max_s);
    }
}
