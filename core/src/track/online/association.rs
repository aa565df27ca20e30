//! The association stages of a frame: detection selection (prefer-larger NMS, high/low
//! confidence), prediction with camera-motion compensation, BoT-SORT's IoU stages, the
//! metadata world stage, new tracks, and the update of a matched track.

use super::track::{add_vote, record_world, Phase, Track};
use super::Tracker;
use crate::track::appearance::AppearanceMean;
use crate::track::assign::{apply_gate, solve_gated};
use crate::track::contact::{ContactIdentity, ContactObject};
use crate::track::kalman::BoxKalman;
use crate::track::nms::nms_prefer_larger_into;
use crate::track::types::{Detection, FrameInput};
use crate::track::world::{mahalanobis2, WorldState};

impl Tracker {
    /// Valid detections above the low threshold, NMS, split into high and low confidence.
    pub(super) fn select_detections(&mut self, detections: &[Detection]) {
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

    /// Predicts the boxes of the confirmed and lost tracks over `dt_frames` (a lost track
    /// keeps its size) and, with `baseline.camera_motion_compensation`, moves every track's
    /// box by the caller's homography.
    pub(super) fn predict_and_compensate(&mut self, dt_frames: f64, input: &FrameInput) {
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

    /// BoT-SORT's association stages and the world stage (see [`Tracker`]): tracked tracks
    /// left unmatched are lost, tentative ones removed; the high-confidence detections left
    /// over start new tracks.
    pub(super) fn associate(&mut self, input: &FrameInput) {
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

    /// Updates track `i` with detection `j`: box filter, life cycle, class vote, appearance
    /// and world filter; a lost track that comes back leaves the memory bank.
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
}
