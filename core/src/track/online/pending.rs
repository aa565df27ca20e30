//! Pending ReID decisions of the online tracker: lost tracks entering the memory bank,
//! decisions once a new track has lived `w` frames (deferred while contested), provisional
//! old ids and the provisional flag of undecided tracks, and the links themselves.

use nalgebra::{Matrix2, Vector2};

use super::track::{MemoryEntry, Phase, ProvisionalLink};
use super::Tracker;
use crate::track::reid::{
    associate_exits_to_entries_where, link_is_contested, within_gate, TrackEnd,
};
use crate::track::types::MergeEvent;

impl Tracker {
    /// Flags the undecided tracks that may still be linked to an old one: a track is flagged
    /// once it carries a provisional old id or its entry lies within the gate of an exit in
    /// the memory bank, and it stays flagged until its decision. Without the latch a young
    /// track's entry, taken from its position alone, drifts in and out of a gate from frame
    /// to frame, and the frames outside it were reported under its own new id: a glimpse an
    /// operator saw for a few frames as a second id.
    pub(super) fn flag_provisional(&mut self) {
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

    /// A track lost from view goes to the memory bank; one still waiting on a contested ReID
    /// decision goes there undecided, under its own id (docs/benchmark.md, "A contested
    /// decision waits"). A glimpse (lost before its decision was due, while it carried a
    /// provisional old id) does not, under `reid.forget_glimpses`.
    pub(super) fn mark_lost(&mut self, i: usize) {
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

    /// Links tracks that have lived `w` frames (all undecided ones with `force`) to the memory
    /// bank. A due track whose link is contested (see [`link_is_contested`]) waits, up to
    /// `reid.defer_max_frames` more, for the rival exit's own entry. Then, with
    /// `reid.provisional_old_id`, the tracks still undecided get their provisional old ids.
    pub(super) fn online_reid(
        &mut self,
        frame_index: u64,
        force: bool,
        merges: &mut Vec<MergeEvent>,
    ) {
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
