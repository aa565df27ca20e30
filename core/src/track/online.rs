//! The online tracker: BoT-SORT-style association per frame plus MG-MOT ReID, decided once a
//! new track has lived `w` frames and reported as a merge event.

use nalgebra::{Matrix2, Vector2};

use super::appearance::AppearanceMean;
use super::assign::{apply_gate, solve_gated};
use super::bbox::BBox;
use super::contact::{overlaps, ContactIdentity, ContactObject, SwapEvidence};
use super::drift::SeaDrift;
use super::kalman::BoxKalman;
use super::nms::nms_prefer_larger_into;
use super::params::TrackerParams;
use super::reid::{associate_exits_to_entries_where, link_is_contested, within_gate, TrackEnd};
use super::types::{
    Detection, ExchangeEvent, FrameInput, FrameOutput, MergeEvent, TrackOutput, TrackState,
};
use super::world::{WorldFilter, WorldObservation, WorldState};
use super::TrackError;

/// Where a live track is in the BoT-SORT life cycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Phase {
    Tracked,
    Lost,
    Removed,
}

/// One track as the tracker keeps it.
#[derive(Debug, Clone)]
struct Track {
    /// Baseline identity: never changes, keys the memory bank.
    uid: u64,
    /// Reported id; becomes the old id when online ReID links this track.
    id: u64,
    /// Image-plane box state.
    kf: BoxKalman,
    /// Life-cycle state.
    phase: Phase,
    /// BoT-SORT `is_activated`: matched at least twice (or born in the first frame).
    activated: bool,
    /// Score of the last matched detection (the reported confidence).
    score: f32,
    /// (class id, count) of every matched detection, for the majority vote.
    class_votes: Vec<(u32, u32)>,
    /// Frame the track was born in (age for duplicates and the ReID window).
    start_frame: u64,
    /// Last frame with a matched detection.
    end_frame: u64,
    /// World position/velocity filter, from the first world observation on.
    world: Option<WorldFilter>,
    /// Last matched detection box and the image size it was seen in (did it leave the view?).
    last_bbox: BBox,
    /// Image size of the frame `last_bbox` was seen in.
    last_image_size_px: (u32, u32),
    /// Online ReID has been tried for this track (once, at `w` frames).
    reid_decided: bool,
    /// Detection matched in the current frame.
    matched_det: Option<usize>,
    /// While undecided: the memory entry ReID would link this track to now, whose id it is
    /// reported under (`reid.provisional_old_id`).
    provisional_link: Option<ProvisionalLink>,
    /// While undecided: it has been reported provisional (it lay within the gate of an exit
    /// in the memory bank, or carried a provisional old id) and stays so until its decision.
    flagged_provisional: bool,
    /// Mean colour signature of the matched detections that had one.
    appearance: AppearanceMean,
    /// Contact repair: what this identity looked like before its contact.
    contact: ContactIdentity,
    /// Contact repair: what the followed object looked like since its last contact.
    object: ContactObject,
}

/// The old track an undecided track is reported as while its decision is pending.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct ProvisionalLink {
    /// Reported id of the old track.
    id: u64,
    /// Baseline identity of the old track (its coasting report gives way).
    uid: u64,
}

impl Track {
    /// Exchanges the objects two tracks follow (contact repair): the box and world filters,
    /// the life cycle and the last detection go with the object; the identity (ids, class
    /// votes, start, ReID state, appearance mean, contact anchor) stays.
    fn exchange_objects(&mut self, other: &mut Track) {
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
    /// undecided and flagged by [`Tracker::flag_provisional`] (which flags nothing with ReID
    /// off).
    fn is_provisional(&self) -> bool {
        !self.reid_decided && self.flagged_provisional
    }

    fn class_id(&self) -> u32 {
        majority_class(&self.class_votes)
    }

    /// The track's exit as seen by ReID: its world filter's state at the last observation,
    /// if it has had world observations.
    fn exit(&self, border_fraction: f64, appearance_min_count: u32) -> Option<TrackEnd> {
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
    fn output(
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
    fn entry(&self, appearance_min_count: u32) -> Option<TrackEnd> {
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

pub(crate) fn add_vote(votes: &mut Vec<(u32, u32)>, class_id: u32) {
    match votes.iter_mut().find(|v| v.0 == class_id) {
        Some(v) => v.1 += 1,
        None => votes.push((class_id, 1)),
    }
}

/// A finished (lost or removed) track waiting in the memory bank for re-identification.
#[derive(Debug, Clone)]
struct MemoryEntry {
    /// Baseline identity of the lost track (to drop the entry if IoU matching resumes it).
    uid: u64,
    /// Reported id a linked track will take over.
    id: u64,
    /// Last frame the track was matched in: a candidate must start after it.
    end_frame: u64,
    /// Where, when and how fast it was last seen.
    exit: TrackEnd,
}

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

    /// Flags the undecided tracks that may still be linked to an old one: a track is flagged
    /// once it carries a provisional old id or its entry lies within the gate of an exit in
    /// the memory bank, and it stays flagged until its decision. Without the latch a young
    /// track's entry, taken from its position alone, drifts in and out of a gate from frame
    /// to frame, and the frames outside it were reported under its own new id: a glimpse an
    /// operator saw for a few frames as a second id.
    fn flag_provisional(&mut self) {
        if !self.params.reid.enabled || self.memory.is_empty() {
            return;
        }
        let (memory, reid, drift) = (&self.memory, &self.params.reid, &self.drift);
        for t in &mut self.tracks {
            if t.reid_decided || t.flagged_provisional {
                continue;
            }
            let Some(entry) = t.entry(reid.appearance_min_count) else {
                continue;
            };
            t.flagged_provisional = t.provisional_link.is_some()
                || memory.iter().any(|m| {
                    m.end_frame < t.start_frame && within_gate(&m.exit, &entry, reid, drift)
                });
        }
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

    /// Contact repair (see [`super::contact`]): contacts between this frame's tracked boxes
    /// join their identities in a group; clean detections feed the identity's signature
    /// (outside a group) or the followed object's (inside); a track in a group with enough
    /// clean detections since its last contact is decided, exchanging objects with the
    /// group member whose anchor its colours fit, if the colours say so; each exchange is
    /// pushed to `exchanges`.
    fn repair_contacts(&mut self, input: &FrameInput, exchanges: &mut Vec<ExchangeEvent>) {
        let cp = self.params.contact.clone();
        let dets = &input.detections;
        let s = &mut self.scratch;
        // Every tracked track was matched in this frame (the unmatched ones are lost), so the
        // tracked boxes are detection boxes: one sweep over the frame's detections finds both
        // the contacts and the clean detections.
        s.candidate_boxes.clear();
        s.candidate_boxes
            .extend(s.candidates.iter().map(|&j| dets[j].bbox));
        overlaps(
            &s.candidate_boxes,
            cp.contact_iou,
            &mut s.order,
            &mut s.max_iou,
            &mut s.contact_pairs,
        );
        // Candidate position -> tracked track.
        s.live.clear();
        s.live.resize(s.candidates.len(), usize::MAX);
        s.det_pos.clear();
        s.det_pos.resize(dets.len(), usize::MAX);
        for (p, &j) in s.candidates.iter().enumerate() {
            s.det_pos[j] = p;
        }
        for (i, t) in self.tracks.iter().enumerate() {
            if t.phase == Phase::Tracked && t.activated {
                if let Some(p) = t
                    .matched_det
                    .map(|j| s.det_pos[j])
                    .filter(|&p| p != usize::MAX)
                {
                    s.live[p] = i;
                }
            }
        }
        s.in_contact.clear();
        s.in_contact.resize(self.tracks.len(), false);
        for &(a, b) in &s.contact_pairs {
            let (ia, ib) = (s.live[a], s.live[b]);
            if ia == usize::MAX || ib == usize::MAX {
                continue;
            }
            s.in_contact[ia] = true;
            s.in_contact[ib] = true;
            let mut touch = |i: usize| {
                let t = &mut self.tracks[i];
                t.contact.touch(t.uid, cp.anchor_min_count)
            };
            let (ga, gb) = (touch(ia), touch(ib));
            if ga != gb {
                for t in &mut self.tracks {
                    t.contact.regroup(gb, ga);
                }
            }
        }
        for (p, &i) in s.live.iter().enumerate() {
            if i == usize::MAX {
                continue;
            }
            let t = &mut self.tracks[i];
            if s.in_contact[i] {
                t.object.reset(input.frame_index, s.max_iou[p]);
                continue;
            }
            let Some(sig) = dets[s.candidates[p]].appearance.as_ref() else {
                continue;
            };
            if s.max_iou[p] >= cp.clean_iou {
                continue;
            }
            if t.contact.group().is_none() {
                t.contact.add_clean(sig);
            } else {
                t.object.add(sig);
            }
        }
        let mut live = std::mem::take(&mut s.live);
        live.retain(|&i| i != usize::MAX);

        let reid_on = self.params.reid.enabled;
        for &i in &live {
            let Some(group) = self.tracks[i].contact.group() else {
                continue;
            };
            let Some(post) = self.tracks[i].object.post(cp.post_count) else {
                continue;
            };
            // A young track's world filter is its ReID entry: it exchanges nothing before
            // its decision.
            let settled = |t: &Track| !reid_on || t.reid_decided;
            let own = &self.tracks[i];
            let member = settled(own)
                .then(|| {
                    live.iter()
                        .copied()
                        .filter(|&q| q != i)
                        .filter(|&q| {
                            let m = &self.tracks[q];
                            m.phase == Phase::Tracked
                                && m.contact.group() == Some(group)
                                && settled(m)
                        })
                        .filter_map(|q| {
                            let m = &self.tracks[q];
                            let e = SwapEvidence::new(
                                own.contact.anchor(),
                                &post,
                                m.contact.anchor(),
                                m.object.post(cp.partner_min_count).as_ref(),
                            )?;
                            Some((q, e))
                        })
                        .min_by(|x, y| x.1.crossed.total_cmp(&y.1.crossed))
                })
                .flatten()
                .filter(|(_, e)| e.favours_exchange(cp.margin));
            let decided = match member {
                Some((q, e)) => {
                    tracing::debug!(
                        frame = input.frame_index,
                        id = self.tracks[i].id,
                        member_id = self.tracks[q].id,
                        own = e.own,
                        crossed = e.crossed,
                        member = ?e.member,
                        "contact repair: objects exchanged"
                    );
                    exchanges.push(ExchangeEvent {
                        id: self.tracks[i].id,
                        other_id: self.tracks[q].id,
                        since_frame_index: self.tracks[i]
                            .object
                            .peak_frame()
                            .unwrap_or(input.frame_index),
                        frame_index: input.frame_index,
                    });
                    let (lo, hi) = (i.min(q), i.max(q));
                    let (head, tail) = self.tracks.split_at_mut(hi);
                    head[lo].exchange_objects(&mut tail[0]);
                    // The member now follows the object whose colours were judged.
                    q
                }
                None => i,
            };
            let t = &mut self.tracks[decided];
            let post = t.object.take();
            t.contact.decide(post);
        }

        self.scratch.live = live;
    }

    /// Valid detections above the low threshold, NMS, split into high and low confidence.
    fn select_detections(&mut self, detections: &[Detection]) {
        let b = &self.params.baseline;
        let s = &mut self.scratch;
        s.boxes.clear();
        s.boxes.extend(detections.iter().map(|d| d.bbox));
        s.candidates.clear();
        s.candidates.extend((0..detections.len()).filter(|&i| {
            let d = &detections[i];
            d.bbox.is_valid() && d.score.is_finite() && d.score >= b.track_low_thresh
        }));
        if let Some(thr) = b.nms_iou_threshold {
            nms_prefer_larger_into(&s.boxes, thr, &mut s.candidates, &mut s.kept);
            std::mem::swap(&mut s.candidates, &mut s.kept);
        }
        s.high.clear();
        s.low.clear();
        for &i in &s.candidates {
            if detections[i].score >= b.track_high_thresh {
                s.high.push(i);
            } else {
                s.low.push(i);
            }
        }
        s.det_used.clear();
        s.det_used.resize(detections.len(), false);
    }

    fn predict_and_compensate(&mut self, dt_frames: f64, input: &FrameInput) {
        let cmc = self.params.baseline.camera_motion_compensation;
        for t in &mut self.tracks {
            t.matched_det = None;
            let in_pool = t.phase == Phase::Lost || (t.phase == Phase::Tracked && t.activated);
            if in_pool {
                if t.phase != Phase::Tracked {
                    // BoT-SORT: a coasting track keeps its size.
                    t.kf.mean[6] = 0.0;
                    t.kf.mean[7] = 0.0;
                }
                t.kf.predict(dt_frames);
            }
            if let Some(h) = input.image_motion.as_ref().filter(|_| cmc) {
                t.kf.apply_homography(h);
            }
        }
    }

    fn associate(&mut self, input: &FrameInput) {
        let dets = &input.detections;
        let b = self.params.baseline.clone();
        let n = self.tracks.len();
        self.scratch.track_matched.clear();
        self.scratch.track_matched.resize(n, false);

        // Stage 1: confirmed + lost tracks against high-confidence detections.
        let rows: Vec<usize> = std::mem::take(&mut self.scratch.rows);
        let mut rows = rows;
        rows.clear();
        rows.extend((0..n).filter(|&i| {
            let t = &self.tracks[i];
            t.phase == Phase::Lost || (t.phase == Phase::Tracked && t.activated)
        }));
        let high = std::mem::take(&mut self.scratch.high);
        self.match_stage(&rows, &high, dets, b.match_thresh, b.fuse_score, input);

        // Stage 2: still-unmatched tracked tracks against low-confidence detections.
        rows.retain(|&i| !self.scratch.track_matched[i] && self.tracks[i].phase == Phase::Tracked);
        let low = std::mem::take(&mut self.scratch.low);
        self.match_stage(&rows, &low, dets, b.second_match_thresh, false, input);

        // Stage 2b (metadata): what is left, by world position.
        if let Some(gate) = b.world_gate_chi2 {
            self.world_stage(&high, &low, dets, gate, input);
        }
        rows.retain(|&i| !self.scratch.track_matched[i] && self.tracks[i].phase == Phase::Tracked);
        for &i in &rows {
            if !self.scratch.track_matched[i] {
                self.mark_lost(i);
            }
        }

        // Stage 3: tentative tracks against the remaining high-confidence detections.
        rows.clear();
        rows.extend((0..n).filter(|&i| {
            let t = &self.tracks[i];
            t.phase == Phase::Tracked && !t.activated
        }));
        let mut rest: Vec<usize> = std::mem::take(&mut self.scratch.cols);
        rest.clear();
        rest.extend(high.iter().copied().filter(|&j| !self.scratch.det_used[j]));
        self.match_stage(
            &rows,
            &rest,
            dets,
            b.unconfirmed_match_thresh,
            b.fuse_score,
            input,
        );
        for &i in &rows {
            if !self.scratch.track_matched[i] {
                self.tracks[i].phase = Phase::Removed;
            }
        }

        // Stage 4: new tracks.
        let first_frame = self.steps == 1;
        for &j in &rest {
            if self.scratch.det_used[j] || dets[j].score < b.new_track_thresh {
                continue;
            }
            self.scratch.det_used[j] = true;
            let uid = self.next_uid;
            self.next_uid += 1;
            let mut t = Track {
                uid,
                id: uid,
                kf: BoxKalman::initiate(&dets[j].bbox),
                phase: Phase::Tracked,
                activated: first_frame,
                score: dets[j].score,
                class_votes: Vec::with_capacity(2),
                start_frame: input.frame_index,
                end_frame: input.frame_index,
                world: None,
                last_bbox: dets[j].bbox,
                last_image_size_px: input.image_size_px,
                reid_decided: false,
                provisional_link: None,
                flagged_provisional: false,
                matched_det: Some(j),
                appearance: AppearanceMean::default(),
                contact: ContactIdentity::default(),
                object: ContactObject::default(),
            };
            add_vote(&mut t.class_votes, dets[j].class_id);
            if let Some(a) = &dets[j].appearance {
                t.appearance.add(a);
            }
            record_world(
                &mut t,
                dets[j].world.as_ref(),
                input.time_s,
                self.params.baseline.world_accel_std_m_s2,
            );
            self.tracks.push(t);
        }

        self.scratch.rows = rows;
        self.scratch.high = high;
        self.scratch.low = low;
        self.scratch.cols = rest;
    }

    /// One gated assignment stage between `rows` (track indices) and `cols` (detection
    /// indices); matched tracks are updated.
    fn match_stage(
        &mut self,
        rows: &[usize],
        cols: &[usize],
        dets: &[Detection],
        gate: f64,
        fuse_score: bool,
        input: &FrameInput,
    ) {
        let cols_free = cols.iter().filter(|&&j| !self.scratch.det_used[j]).count();
        if rows.is_empty() || cols_free == 0 {
            return;
        }
        let mismatch = self.params.baseline.class_mismatch_cost;
        let s = &mut self.scratch;
        s.classes.clear();
        s.classes
            .extend(rows.iter().map(|&i| self.tracks[i].class_id()));
        let classes = &s.classes;
        s.cost.clear();
        for (r, &i) in rows.iter().enumerate() {
            let tb = self.tracks[i].kf.bbox();
            for &j in cols {
                if s.det_used[j] {
                    s.cost.push(f64::INFINITY);
                    continue;
                }
                let mut sim = tb.iou(&dets[j].bbox);
                if fuse_score {
                    sim *= f64::from(dets[j].score);
                }
                let class_cost = if dets[j].class_id == classes[r] {
                    0.0
                } else {
                    mismatch
                };
                s.cost.push(1.0 - sim + class_cost);
            }
        }
        apply_gate(&mut s.cost, gate);
        let mut pairs = std::mem::take(&mut s.pairs);
        solve_gated(rows.len(), cols.len(), &mut s.cost, &mut pairs);
        for &(r, c) in &pairs {
            let (i, j) = (rows[r], cols[c]);
            self.scratch.track_matched[i] = true;
            self.scratch.det_used[j] = true;
            self.update_track(i, j, &dets[j], input);
        }
        self.scratch.pairs = pairs;
    }

    /// Matches the detections no IoU stage took to the confirmed and lost tracks no stage
    /// matched, by the squared Mahalanobis distance of the detection's sea-surface position
    /// from the track's predicted world position, gated at `gate_chi2`; tracks and
    /// detections of different classes are never paired. Low-confidence detections go to
    /// tracks matched in the previous frame only, unless
    /// `baseline.world_low_confidence_to_lost`.
    fn world_stage(
        &mut self,
        high: &[usize],
        low: &[usize],
        dets: &[Detection],
        gate_chi2: f64,
        input: &FrameInput,
    ) {
        let accel = self.params.baseline.world_accel_std_m_s2;
        let rows: Vec<(usize, WorldState, u32)> = (0..self.tracks.len())
            .filter(|&i| !self.scratch.track_matched[i])
            .filter_map(|i| {
                let t = &self.tracks[i];
                let pooled = t.phase == Phase::Lost || (t.phase == Phase::Tracked && t.activated);
                let w = t.world.as_ref().filter(|_| pooled)?;
                Some((i, w.predicted(input.time_s, accel), t.class_id()))
            })
            .collect();
        if rows.is_empty() {
            return;
        }
        let free = |j: &usize| !self.scratch.det_used[*j] && dets[*j].world.is_some();
        let mut cols: Vec<usize> = high.iter().copied().filter(free).collect();
        let n_high = cols.len();
        cols.extend(low.iter().copied().filter(free));
        if cols.is_empty() {
            return;
        }
        let s = &mut self.scratch;
        s.cost.clear();
        let low_to_lost = self.params.baseline.world_low_confidence_to_lost;
        for (i, state, class_id) in &rows {
            let lost = self.tracks[*i].phase == Phase::Lost;
            for (k, &j) in cols.iter().enumerate() {
                let c = match &dets[j].world {
                    // `cols` lists the high-confidence detections first.
                    _ if lost && !low_to_lost && k >= n_high => f64::INFINITY,
                    Some(obs) if dets[j].class_id == *class_id => mahalanobis2(
                        obs.pos_ne_m - state.pos_ne_m,
                        state.pos_cov_m2() + obs.cov_ne_m2,
                    )
                    .filter(|&d2| d2 <= gate_chi2)
                    .unwrap_or(f64::INFINITY),
                    _ => f64::INFINITY,
                };
                s.cost.push(c);
            }
        }
        let mut pairs = std::mem::take(&mut s.pairs);
        solve_gated(rows.len(), cols.len(), &mut s.cost, &mut pairs);
        for &(r, c) in &pairs {
            let (i, j) = (rows[r].0, cols[c]);
            self.scratch.track_matched[i] = true;
            self.scratch.det_used[j] = true;
            self.update_track(i, j, &dets[j], input);
        }
        self.scratch.pairs = pairs;
    }

    fn update_track(&mut self, i: usize, j: usize, det: &Detection, input: &FrameInput) {
        let accel = self.params.baseline.world_accel_std_m_s2;
        let t = &mut self.tracks[i];
        let was_lost = t.phase == Phase::Lost;
        t.kf.update(&det.bbox);
        t.phase = Phase::Tracked;
        t.activated = true;
        t.score = det.score;
        t.end_frame = input.frame_index;
        t.last_bbox = det.bbox;
        t.last_image_size_px = input.image_size_px;
        t.matched_det = Some(j);
        add_vote(&mut t.class_votes, det.class_id);
        if let Some(a) = &det.appearance {
            t.appearance.add(a);
        }
        record_world(t, det.world.as_ref(), input.time_s, accel);
        if was_lost {
            let uid = t.uid;
            self.memory.retain(|m| m.uid != uid);
        }
    }

    /// A track lost from view goes to the memory bank; one still waiting on a contested ReID
    /// decision goes there undecided, under its own id (docs/benchmark.md, "A contested decision waits").
    /// A glimpse (lost before its decision was due, while it carried a provisional old id)
    /// does not, under `reid.forget_glimpses`.
    fn mark_lost(&mut self, i: usize) {
        let reid = &self.params.reid;
        let t = &mut self.tracks[i];
        t.phase = Phase::Lost;
        if !reid.enabled {
            return;
        }
        let young = t.end_frame.saturating_sub(t.start_frame) < u64::from(reid.window_frames);
        if reid.forget_glimpses && !t.reid_decided && young && t.provisional_link.is_some() {
            tracing::debug!(
                id = t.id,
                start_frame = t.start_frame,
                "ReID glimpse forgotten"
            );
            return;
        }
        if let Some(exit) = t.exit(reid.exit_border_fraction, reid.appearance_min_count) {
            self.memory.push(MemoryEntry {
                uid: t.uid,
                id: t.id,
                end_frame: t.end_frame,
                exit,
            });
        }
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

    /// Links tracks that have lived `w` frames (all undecided ones with `force`) to the memory
    /// bank. A due track whose link is contested (see [`link_is_contested`]) waits, up to
    /// `reid.defer_max_frames` more, for the rival exit's own entry. Then, with
    /// `reid.provisional_old_id`, the tracks still undecided get their provisional old ids.
    fn online_reid(&mut self, frame_index: u64, force: bool, merges: &mut Vec<MergeEvent>) {
        let w = u64::from(self.params.reid.window_frames);
        let last_call = w + u64::from(self.params.reid.defer_max_frames);
        let min_count = self.params.reid.appearance_min_count;
        let mut cand = Vec::new();
        let mut cand_start = Vec::new();
        let mut due = Vec::new();
        let mut final_call = Vec::new();
        let mut entries = Vec::new();
        for (k, t) in self.tracks.iter_mut().enumerate() {
            // A lost track keeps its provisional link while it coasts (in the memory bank it
            // waits under its own id); the others get theirs anew.
            if t.phase != Phase::Lost {
                t.provisional_link = None;
            }
            if t.reid_decided || t.phase != Phase::Tracked || !t.activated {
                continue;
            }
            let age = frame_index.saturating_sub(t.start_frame);
            let is_due = force || age >= w;
            match t.entry(min_count) {
                Some(e) => {
                    cand.push(k);
                    cand_start.push(t.start_frame);
                    due.push(is_due);
                    final_call.push(force || age >= last_call);
                    entries.push(e);
                }
                // Without a world position there is nothing to link.
                None => t.reid_decided |= is_due,
            }
        }
        if due.iter().any(|&d| d) {
            self.decide(
                &cand,
                &cand_start,
                &due,
                &final_call,
                &entries,
                frame_index,
                merges,
            );
        }
        if self.params.reid.provisional_old_id && !force {
            self.provisional_links(&cand, &cand_start, &due, &entries);
        }
    }

    /// The decisions of the due tracks (`due`), in one assignment with the undecided ones as
    /// rivals; contested ones wait unless it is their `final_call`.
    #[allow(clippy::too_many_arguments)]
    fn decide(
        &mut self,
        cand: &[usize],
        cand_start: &[u64],
        due: &[bool],
        final_call: &[bool],
        entries: &[TrackEnd],
        frame_index: u64,
        merges: &mut Vec<MergeEvent>,
    ) {
        let exits: Vec<TrackEnd> = self.memory.iter().map(|m| m.exit).collect();
        let memory = &self.memory;
        let links = associate_exits_to_entries_where(
            &exits,
            entries,
            &self.params.reid,
            &self.drift,
            |i, j| cand_start[j] > memory[i].end_frame,
        );
        let mut claimed = vec![false; exits.len()];
        for &(mi, _) in &links {
            claimed[mi] = true;
        }
        let mut deferred = vec![false; cand.len()];
        for &(mi, ci) in links.iter().filter(|&&(_, ci)| due[ci] && !final_call[ci]) {
            deferred[ci] = link_is_contested(
                &exits,
                &entries[ci],
                mi,
                &claimed,
                &self.params.reid,
                &self.drift,
                |i| cand_start[ci] > memory[i].end_frame,
            );
        }
        for (ci, &k) in cand.iter().enumerate() {
            if due[ci] && !deferred[ci] {
                self.tracks[k].reid_decided = true;
            }
        }
        let mut consumed = vec![false; self.memory.len()];
        for &(mi, ci) in links.iter().filter(|&&(_, ci)| due[ci] && !deferred[ci]) {
            consumed[mi] = true;
            merges.push(self.take_link(cand[ci], mi, frame_index));
        }
        let mut k = 0;
        self.memory.retain(|_| {
            let keep = !consumed[k];
            k += 1;
            keep
        });
        merges.sort_by_key(|m| m.new_id);
    }

    /// Provisional old ids (`reid.provisional_old_id`): the candidates still undecided are
    /// assigned to the memory bank as at a decision, and each linked one is reported under
    /// its exit's id. A track not yet due enters with its position only (its velocity taken
    /// as the class's own-speed prior around zero): over its first frames the filter's
    /// velocity is still too uncertain to carry it anywhere, and would open the gate to
    /// exits far away.
    fn provisional_links(
        &mut self,
        cand: &[usize],
        cand_start: &[u64],
        due: &[bool],
        entries: &[TrackEnd],
    ) {
        if self.memory.is_empty() {
            return;
        }
        let mut undecided = Vec::new();
        let mut guess_entries = Vec::new();
        for (ci, &k) in cand.iter().enumerate() {
            if self.tracks[k].reid_decided {
                continue;
            }
            let mut e = entries[ci];
            if !due[ci] {
                let sd = self.params.reid.class(e.class_id).own_speed_std_m_s;
                e.vel_ne_m_s = Vector2::zeros();
                e.vel_cov_m2_s2 = Matrix2::identity() * (sd * sd);
            }
            undecided.push(ci);
            guess_entries.push(e);
        }
        if undecided.is_empty() {
            return;
        }
        let exits: Vec<TrackEnd> = self.memory.iter().map(|m| m.exit).collect();
        let memory = &self.memory;
        let links = associate_exits_to_entries_where(
            &exits,
            &guess_entries,
            &self.params.reid,
            &self.drift,
            |i, j| cand_start[undecided[j]] > memory[i].end_frame,
        );
        for (mi, j) in links {
            let m = &self.memory[mi];
            self.tracks[cand[undecided[j]]].provisional_link = Some(ProvisionalLink {
                id: m.id,
                uid: m.uid,
            });
        }
    }

    /// Links track `k` to memory entry `mi`: the track takes the old id, and the old track, if
    /// still in the lost buffer, is removed so it cannot come back through IoU under the same
    /// id. The caller drops the memory entry.
    fn take_link(&mut self, k: usize, mi: usize, frame_index: u64) -> MergeEvent {
        let (old_uid, old_id) = (self.memory[mi].uid, self.memory[mi].id);
        let t = &mut self.tracks[k];
        let merge = MergeEvent {
            new_id: t.id,
            merged_into_id: old_id,
            frame_index,
        };
        tracing::debug!(
            new_id = t.id,
            merged_into_id = old_id,
            frame_index,
            "ReID merge"
        );
        t.id = old_id;
        for o in &mut self.tracks {
            if o.uid == old_uid && o.phase == Phase::Lost {
                o.phase = Phase::Removed;
            }
        }
        merge
    }
}

/// Squared Mahalanobis distance `d^T S^-1 d`; `None` when `S` is singular or the result is
/// not finite.
pub(crate) fn mahalanobis2(d: Vector2<f64>, s: Matrix2<f64>) -> Option<f64> {
    let d2 = d.dot(&(s.try_inverse()? * d));
    (d2.is_finite() && d2 >= 0.0).then_some(d2)
}

/// Feeds a matched detection's world observation to the track's world filter.
fn record_world(t: &mut Track, obs: Option<&WorldObservation>, time_s: f64, accel_std_m_s2: f64) {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::track::scenes;
    use nalgebra::Matrix3;

    /// A tracker whose memory bank holds two swimmers that left the view at `t = 0` at east
    /// 0 m and 10 m, with two new tracks of `ages` frames at east `entries_e_m` (14 s later),
    /// in frame 1000.
    fn two_exits_and_entries(entries_e_m: &[f64], ages: &[u64]) -> Tracker {
        two_exits_and_entries_with(TrackerParams::default(), entries_e_m, ages)
    }

    fn two_exits_and_entries_with(
        params: TrackerParams,
        entries_e_m: &[f64],
        ages: &[u64],
    ) -> Tracker {
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
        (old.uid, old.id, old.phase, old.start_frame, old.end_frame) =
            (1, 1, Phase::Lost, 400, 999);
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
        let links = associate_exits_to_entries_where(
            &exits,
            &[entry],
            &tr.params.reid,
            &tr.drift,
            |_, _| true,
        );
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
            let by_x = |x: f64| {
                scenes::nearest_id(out.tracks.iter().map(|t| (t.id, t.bbox)), x).unwrap_or(0)
            };
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
}
