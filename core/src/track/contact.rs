//! Identity swaps inside a close group, repaired by colour once the group parts.
//!
//! While two swimmers' boxes overlap for seconds (a group drifting together, IoU 0.6-0.9),
//! IoU association cannot tell them apart and may hand each one's id to the other (the
//! simulator's `swimmer_group`: three swimmers 2 px apart). Their colour signatures cannot
//! either while they overlap: both boxes hold the same pixels. But before the contact and
//! after it each box holds one object's pixels, and those are what this compares:
//!
//! - Each identity (a reported id) keeps the mean signature of its *clean* detections (no
//!   other detection of the frame overlapping it at IoU `clean_iou` or more).
//! - Two tracks whose boxes overlap at IoU `contact_iou` or more are *in contact*. Each
//!   freezes its clean mean as its *anchor* (what the identity looked like before) and
//!   joins a contact group (groups merge transitively: A touched B, B touched C).
//! - From its last contact on, a track collects the clean signatures of the object it now
//!   follows (its *post* signature). Once it has `post_count` of them it is decided: if its
//!   post signature is nearer (by `margin`) to another group member's anchor than to its
//!   own, the two tracks exchange the objects they follow (box filter, world filter, life
//!   cycle), so each id goes back to the object it belonged to. When that member has a post
//!   signature of its own (`partner_min_count` clean detections since the contact), both
//!   sides' distances are summed: the repair must fit both objects, not one.
//! - Either way the decided identity leaves the group and starts a new clean mean from its
//!   post signature.
//!
//! Each repair is reported as an [`super::ExchangeEvent`] from the frame of the contact's
//! largest overlap (where the swap most likely happened: the boxes were hardest to tell
//! apart). Online the frames between the swap and its repair keep the wrong ids (they were
//! reported); from the repair on the ids are right. Offline the frames since that peak are
//! relabelled too. Measured: docs/benchmark.md, "Contact repair".

use serde::{Deserialize, Serialize};

use super::appearance::{Appearance, AppearanceMean};
use super::bbox::BBox;

/// Contact-repair parameters (`[tracker.contact]`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ContactParams {
    /// Repair swaps at all. Needs detections with colour signatures
    /// ([`super::Detection::appearance`]); without them nothing happens.
    pub enabled: bool,
    /// Two tracked boxes overlapping at this IoU or more are in contact (a swap is possible).
    /// 0.5, measured (12 seeds, docs/benchmark.md "Contact repair"): the swaps seen happen at IoU 0.6-0.8;
    /// 0.3 gave the same results but for one crossing it left unrepaired (`boats_crossing`
    /// seed 15: the two swimmers stayed near each other after it, so their group of the
    /// earlier, lighter contact never had clean detections to decide on), 0.2 missed a
    /// repair.
    pub contact_iou: f64,
    /// A detection overlapping no other detection of the frame at this IoU or more is clean:
    /// its signature is one object's (a tracked box is its detection's box, so that covers the
    /// tracks too). 0.1, measured (at contact IoU 0.3): 0.05 missed the repair on
    /// `swimmer_group` seed 31337 and cost `sector_search` seed 13 0.016 IDF1; 0.2 gained
    /// 0.0001 on the mean but cost `sector_search` seed 18 offline 0.008.
    pub clean_iou: f64,
    /// Clean detections an identity needs before its first contact for an anchor (fewer: it
    /// takes part in no repair).
    pub anchor_min_count: u32,
    /// Clean detections after the contact before a track is decided. 5 and 20 gave nearly
    /// the same results as 10.
    pub post_count: u32,
    /// Clean detections a partner needs after the contact for its side to count too.
    pub partner_min_count: u32,
    /// How much nearer (Hellinger distance, summed over the sides that count) the exchanged
    /// assignment must be than the kept one. 0.05 gave the same results, 0.2 missed the
    /// repair on `swimmer_group` seed 31337 (0.73 against 0.54, one side).
    pub margin: f64,
}

impl Default for ContactParams {
    fn default() -> Self {
        Self {
            enabled: true,
            contact_iou: 0.5,
            clean_iou: 0.1,
            anchor_min_count: 5,
            post_count: 10,
            partner_min_count: 3,
            margin: 0.1,
        }
    }
}

/// What an identity looked like: stays with the reported id when two tracks exchange their
/// objects.
#[derive(Debug, Clone, Default)]
pub(crate) struct ContactIdentity {
    /// Clean signatures since the identity was born or last decided.
    clean: AppearanceMean,
    /// The clean mean frozen at the first contact since then.
    anchor: Option<Appearance>,
    /// Contact group; `None` when not in one.
    group: Option<u64>,
}

impl ContactIdentity {
    /// The contact group, if in one.
    pub(crate) fn group(&self) -> Option<u64> {
        self.group
    }

    /// The anchor, if the identity had enough clean detections before its contact.
    pub(crate) fn anchor(&self) -> Option<&Appearance> {
        self.anchor.as_ref()
    }

    /// A contact begins (or goes on): the first one since the last decision freezes the
    /// anchor and puts the identity in `group`. Returns the group it is in.
    pub(crate) fn touch(&mut self, group: u64, anchor_min_count: u32) -> u64 {
        if let Some(g) = self.group {
            return g;
        }
        self.anchor = self.clean.mean(anchor_min_count);
        self.group = Some(group);
        group
    }

    /// Moves the identity from group `from` to group `to` (two groups met).
    pub(crate) fn regroup(&mut self, from: u64, to: u64) {
        if self.group == Some(from) {
            self.group = Some(to);
        }
    }

    /// One clean signature outside any contact group.
    pub(crate) fn add_clean(&mut self, a: &Appearance) {
        self.clean.add(a);
    }

    /// Decided: out of the group; the post signature starts the new clean mean.
    pub(crate) fn decide(&mut self, post: AppearanceMean) {
        self.group = None;
        self.anchor = None;
        self.clean = post;
    }
}

/// What the followed object looked like since the track's last contact: moves with the box
/// state when two tracks exchange their objects.
#[derive(Debug, Clone, Default)]
pub(crate) struct ContactObject {
    post: AppearanceMean,
    /// The largest IoU the object's box had with another in its contacts since its last
    /// decision, and the frame of it: where the two tracks most likely exchanged objects.
    peak: Option<(f64, u64)>,
}

impl ContactObject {
    /// In contact in frame `frame_index`, its box overlapping another at `iou`: the
    /// object's post signature starts again.
    pub(crate) fn reset(&mut self, frame_index: u64, iou: f64) {
        self.post = AppearanceMean::default();
        if self.peak.is_none_or(|(peak, _)| iou >= peak) {
            self.peak = Some((iou, frame_index));
        }
    }

    /// The frame of the largest overlap in the contacts since the last decision (where a
    /// swap most likely happened: the boxes were hardest to tell apart).
    pub(crate) fn peak_frame(&self) -> Option<u64> {
        self.peak.map(|(_, frame)| frame)
    }

    /// One clean signature while in a contact group.
    pub(crate) fn add(&mut self, a: &Appearance) {
        self.post.add(a);
    }

    /// The post signature once it has `min_count` detections.
    pub(crate) fn post(&self, min_count: u32) -> Option<Appearance> {
        self.post.mean(min_count)
    }

    /// Takes the post signature (for [`ContactIdentity::decide`]); the contacts are over.
    pub(crate) fn take(&mut self) -> AppearanceMean {
        self.peak = None;
        std::mem::take(&mut self.post)
    }
}

/// The colour evidence for one decision: a track's post signature against its own anchor
/// and against a group member's, and, when that member has a post signature too, the
/// member's side.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct SwapEvidence {
    /// Own post signature to own anchor.
    pub own: f64,
    /// Own post signature to the member's anchor.
    pub crossed: f64,
    /// The member's post signature to its own anchor and to ours.
    pub member: Option<(f64, f64)>,
}

impl SwapEvidence {
    /// Gathers the distances; `None` without both anchors.
    pub(crate) fn new(
        own_anchor: Option<&Appearance>,
        own_post: &Appearance,
        member_anchor: Option<&Appearance>,
        member_post: Option<&Appearance>,
    ) -> Option<Self> {
        let (own_anchor, member_anchor) = (own_anchor?, member_anchor?);
        Some(Self {
            own: own_anchor.distance(own_post),
            crossed: member_anchor.distance(own_post),
            member: member_post.map(|p| (member_anchor.distance(p), own_anchor.distance(p))),
        })
    }

    /// Whether exchanging the two objects fits the colours better than keeping them, by
    /// `margin`.
    pub(crate) fn favours_exchange(&self, margin: f64) -> bool {
        let (kept, exchanged) = match self.member {
            Some((member_own, member_crossed)) => {
                (self.own + member_own, self.crossed + member_crossed)
            }
            None => (self.own, self.crossed),
        };
        exchanged + margin < kept
    }
}

/// Overlaps among `boxes`: each box's largest IoU with any other (`max_iou`, 0 when none
/// overlaps it) and the pairs `(a, b)`, `a < b`, at `pair_iou` or more (`pairs`). A sweep
/// over the boxes sorted by their left edge (`order`, a reused buffer) compares only boxes
/// that overlap horizontally: a frame's boxes are small against the image, so this is
/// about linear where all pairs would be quadratic.
pub(crate) fn overlaps(
    boxes: &[BBox],
    pair_iou: f64,
    order: &mut Vec<usize>,
    max_iou: &mut Vec<f64>,
    pairs: &mut Vec<(usize, usize)>,
) {
    order.clear();
    order.extend(0..boxes.len());
    order.sort_unstable_by(|&a, &b| boxes[a].x.total_cmp(&boxes[b].x));
    max_iou.clear();
    max_iou.resize(boxes.len(), 0.0);
    pairs.clear();
    for (k, &a) in order.iter().enumerate() {
        let right = boxes[a].x + boxes[a].w;
        for &b in &order[k + 1..] {
            if boxes[b].x >= right {
                break;
            }
            let iou = boxes[a].iou(&boxes[b]);
            max_iou[a] = max_iou[a].max(iou);
            max_iou[b] = max_iou[b].max(iou);
            if iou >= pair_iou {
                pairs.push((a.min(b), a.max(b)));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::track::appearance::BINS;

    use crate::track::scenes::colour as sig;

    fn mix(a: usize, b: usize, wa: f32) -> Appearance {
        let mut bins = [0.0; BINS];
        bins[a] = wa;
        bins[b] += 1.0 - wa;
        Appearance { bins }
    }

    #[test]
    fn one_sided_evidence_needs_the_margin() {
        let (red, blue) = (sig(0), sig(8));
        // Our post looks like the member's anchor: exchange.
        let e = SwapEvidence::new(Some(&red), &blue, Some(&blue), None).unwrap();
        assert!(e.favours_exchange(0.1));
        // Our post looks like our own anchor: keep.
        let e = SwapEvidence::new(Some(&red), &red, Some(&blue), None).unwrap();
        assert!(!e.favours_exchange(0.1));
        // Mixed colours, slightly nearer the member: within the margin, keep.
        let post = mix(0, 8, 0.45);
        let e = SwapEvidence::new(Some(&red), &post, Some(&blue), None).unwrap();
        assert!(e.crossed < e.own);
        assert!(!e.favours_exchange(0.1));
        // No anchor on either side: no evidence.
        assert!(SwapEvidence::new(None, &blue, Some(&blue), None).is_none());
        assert!(SwapEvidence::new(Some(&red), &blue, None, None).is_none());
    }

    #[test]
    fn the_members_side_can_overrule_ours() {
        let (red, blue) = (sig(0), sig(8));
        // Our post leans to the member's anchor, but the member's post is plainly its own.
        let post = mix(0, 8, 0.3);
        let one = SwapEvidence::new(Some(&red), &post, Some(&blue), None).unwrap();
        assert!(one.favours_exchange(0.1));
        let both = SwapEvidence::new(Some(&red), &post, Some(&blue), Some(&blue)).unwrap();
        assert!(!both.favours_exchange(0.1));
        // Both posts crossed: exchange.
        let both = SwapEvidence::new(Some(&red), &blue, Some(&blue), Some(&red)).unwrap();
        assert!(both.favours_exchange(0.1));
    }

    #[test]
    fn the_anchor_is_frozen_at_the_first_contact_and_renewed_by_the_decision() {
        let (red, blue) = (sig(0), sig(8));
        let mut id = ContactIdentity::default();
        for _ in 0..4 {
            id.add_clean(&red);
        }
        // Too few clean detections for an anchor.
        assert_eq!(id.touch(7, 5), 7);
        assert!(id.anchor().is_none());
        let mut id = ContactIdentity::default();
        for _ in 0..5 {
            id.add_clean(&red);
        }
        assert_eq!(id.touch(7, 5), 7);
        // A later contact keeps the first group and anchor.
        assert_eq!(id.touch(9, 5), 7);
        assert_eq!(id.anchor(), Some(&red));
        id.regroup(7, 3);
        assert_eq!(id.group(), Some(3));
        let mut obj = ContactObject::default();
        for _ in 0..5 {
            obj.add(&blue);
        }
        assert_eq!(obj.post(6), None);
        assert_eq!(obj.post(5), Some(blue));
        id.decide(obj.take());
        assert_eq!(id.group(), None);
        assert_eq!(obj.post(1), None);
        // The next contact's anchor is the post signature.
        id.touch(4, 5);
        assert_eq!(id.anchor(), Some(&blue));
    }

    #[test]
    fn overlaps_of_a_few_boxes() {
        let boxes = [
            BBox::from_center(10.0, 10.0, 10.0, 10.0),
            BBox::from_center(40.0, 10.0, 10.0, 10.0),
            BBox::from_center(18.0, 10.0, 10.0, 10.0), // IoU 2/18 with the first
            BBox::from_center(11.0, 10.0, 10.0, 10.0), // IoU 9/11 with the first
        ];
        let (mut order, mut max_iou, mut pairs) = (Vec::new(), Vec::new(), Vec::new());
        overlaps(&boxes, 0.5, &mut order, &mut max_iou, &mut pairs);
        assert_eq!(pairs, vec![(0, 3)]);
        assert!((max_iou[0] - 9.0 / 11.0).abs() < 1e-12);
        assert_eq!(max_iou[1], 0.0);
        assert!((max_iou[2] - boxes[2].iou(&boxes[3])).abs() < 1e-12);
    }

    proptest::proptest! {
        #[test]
        fn the_sweep_finds_what_all_pairs_find(
            raw in proptest::collection::vec((0.0..200.0f64, 0.0..100.0f64, 1.0..40.0f64, 1.0..40.0f64), 0..40),
            pair_iou in 0.05..0.9f64,
        ) {
            let boxes: Vec<BBox> = raw.iter().map(|&(x, y, w, h)| BBox::new(x, y, w, h)).collect();
            let (mut order, mut max_iou, mut pairs) = (Vec::new(), Vec::new(), Vec::new());
            overlaps(&boxes, pair_iou, &mut order, &mut max_iou, &mut pairs);
            pairs.sort_unstable();
            let mut want = Vec::new();
            for a in 0..boxes.len() {
                let best = (0..boxes.len())
                    .filter(|&b| b != a)
                    .map(|b| boxes[a].iou(&boxes[b]))
                    .fold(0.0f64, f64::max);
                proptest::prop_assert!((max_iou[a] - best).abs() < 1e-12);
                for b in a + 1..boxes.len() {
                    if boxes[a].iou(&boxes[b]) >= pair_iou {
                        want.push((a, b));
                    }
                }
            }
            proptest::prop_assert_eq!(pairs, want);
        }
    }
}
