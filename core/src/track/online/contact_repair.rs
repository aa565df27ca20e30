//! Contact repair in the online step: finds this frame's contacts and clean detections,
//! feeds the identities' and objects' colour signatures, and exchanges the objects of two
//! tracks when the colours say they were swapped (the judgement is in
//! [`crate::track::contact`]).

use super::track::{Phase, Track};
use super::Tracker;
use crate::track::contact::{overlaps, SwapEvidence};
use crate::track::types::{ExchangeEvent, FrameInput};

impl Tracker {
    /// Contact repair (see [`crate::track::contact`]): contacts between this frame's tracked boxes
    /// join their identities in a group; clean detections feed the identity's signature
    /// (outside a group) or the followed object's (inside); a track in a group with enough
    /// clean detections since its last contact is decided, exchanging objects with the
    /// group member whose anchor its colours fit, if the colours say so; each exchange is
    /// pushed to `exchanges`.
    pub(super) fn repair_contacts(
        &mut self,
        input: &FrameInput,
        exchanges: &mut Vec<ExchangeEvent>,
    ) {
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
}
