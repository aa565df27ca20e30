//! Offline mode: the baseline over a whole sequence, then the paper's post-processing
//! (Sec. 5.1): linear interpolation -> metadata-guided ReID -> linear interpolation.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use super::appearance::{Appearance, AppearanceMean};
use super::bbox::BBox;
use super::drift::SeaDrift;
use super::error::TrackError;
use super::online::{add_vote, majority_class, track_end, Tracker};
use super::params::ReidParams;
use super::params::TrackerParams;
use super::reid::{associate_exits_to_entries_where, with_chain_velocity, ChainPoint, TrackEnd};
use super::types::{ExchangeEvent, FrameInput};
use super::world::WorldState;

/// One track box in one frame of the offline result.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SequenceTrack {
    /// Final track id (after ReID).
    pub id: u64,
    /// Box, px.
    pub bbox: BBox,
    /// Confidence (interpolated between the neighbouring observations for filled frames).
    pub score: f32,
    /// Majority class over the whole final track.
    pub class_id: u32,
    /// World state, when the track has world observations (interpolated for filled frames).
    pub world: Option<WorldState>,
    /// Filled in by interpolation rather than tracked.
    pub interpolated: bool,
}

/// All tracks of one input frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SequenceFrame {
    /// Frame number of the input.
    pub frame_index: u64,
    /// Capture time of the input, s.
    pub time_s: f64,
    /// Tracks in this frame, ordered by id; an id appears at most once.
    pub tracks: Vec<SequenceTrack>,
}

/// Result of [`track_sequence`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SequenceResult {
    /// One entry per input frame, in input order.
    pub frames: Vec<SequenceFrame>,
    /// ReID links as `(baseline track id, final id)`, for every baseline track that was
    /// re-labelled.
    pub relabelled: Vec<(u64, u64)>,
}

/// One observation (or interpolated point) of a tracklet.
#[derive(Debug, Clone, Copy)]
struct Point {
    /// Position of the frame in the input slice.
    pos: usize,
    bbox: BBox,
    score: f32,
    /// Class of the matched detection (`None` for interpolated points).
    class_id: Option<u32>,
    /// Filtered world state.
    world: Option<WorldState>,
    /// Colour signature of the matched detection.
    appearance: Option<Appearance>,
    interpolated: bool,
}

/// Runs the tracker over a whole sequence and applies the paper's post-processing:
///
/// 1. the BoT-SORT baseline (online tracker with ReID disabled);
/// 2. linear interpolation of gaps of at most `offline.interp_max_gap_frames` frames inside
///    each baseline tracklet;
/// 3. metadata-guided ReID between all tracklets of the sequence (short-term then long-term,
///    class-wise, long-term gated at `offline.gate_chi2`; every tracklet has at most one
///    predecessor and one successor, so linked tracklets form chains that never overlap in
///    time); a chain takes the id of its first tracklet;
/// 4. linear interpolation again, now also across the gaps between linked tracklets.
///
/// Frames must be in increasing frame order (as for [`Tracker::step`]).
pub fn track_sequence(
    frames: &[FrameInput],
    params: &TrackerParams,
) -> Result<SequenceResult, TrackError> {
    let mut baseline_params = params.clone();
    baseline_params.reid.enabled = false;
    baseline_params.baseline.track_buffer_frames = params.offline.track_buffer_frames;
    // Interpolation fills the holes from both ends; no predicted boxes in the tracklets.
    baseline_params.baseline.coast_frames = 0;
    let mut tracker = Tracker::new(baseline_params)?;

    let mut tracklets: BTreeMap<u64, Vec<Point>> = BTreeMap::new();
    for (pos, frame) in frames.iter().enumerate() {
        let out = tracker.step(frame)?;
        // A contact repair exchanged two tracks' objects in this frame: the frames since
        // their contact, already in the tracklets, go back to the ids they belong to.
        for e in &out.exchanges {
            exchange_since(&mut tracklets, e, frames);
        }
        for t in &out.tracks {
            let det = t.detection_index.and_then(|i| frame.detections.get(i));
            tracklets.entry(t.id).or_default().push(Point {
                pos,
                bbox: t.bbox,
                score: t.score,
                class_id: Some(det.map_or(t.class_id, |d| d.class_id)),
                world: t.world,
                appearance: det.and_then(|d| d.appearance),
                interpolated: false,
            });
        }
    }

    let max_gap = params.offline.interp_max_gap_frames;
    for points in tracklets.values_mut() {
        interpolate(points, frames, max_gap);
    }

    let ids: Vec<u64> = tracklets.keys().copied().collect();
    let mut final_id: BTreeMap<u64, u64> = ids.iter().map(|&id| (id, id)).collect();
    let mut relabelled = Vec::new();
    if params.reid.enabled {
        let window = params.offline.entry_window_frames as usize;
        let mut exits = Vec::new();
        let mut exit_ids = Vec::new();
        // Frame-position span of every tracklet with world observations.
        let mut spans = Vec::new();
        let mut entries = Vec::new();
        let mut entry_ids = Vec::new();
        // First world observation of every tracklet (index shared with exits and entries).
        let mut firsts = Vec::new();
        // Detections of every tracklet (index shared with exits and entries).
        let mut detections = Vec::new();
        // The colour signature of every tracklet, however few detections have one, and
        // whether it is scant (too few for the exits' and entries' own signature).
        let mut signatures: Vec<(Option<Appearance>, bool)> = Vec::new();
        for (&id, points) in &tracklets {
            let class_id = tracklet_class(points);
            let worlds: Vec<(usize, WorldState)> = points
                .iter()
                .filter(|p| !p.interpolated)
                .filter_map(|p| p.world.map(|w| (p.pos, w)))
                .collect();
            let Some(&(last_pos, last)) = worlds.last() else {
                continue;
            };
            let last_point = points.iter().rev().find(|p| p.pos == last_pos);
            let left_view = last_point.is_some_and(|p| {
                p.bbox.touches_border(
                    frames[p.pos].image_size_px,
                    params.reid.exit_border_fraction,
                )
            });
            // Offline the whole tracklet's signature at both ends.
            let mut signature = AppearanceMean::default();
            for a in points.iter().filter_map(|p| p.appearance.as_ref()) {
                signature.add(a);
            }
            let appearance = signature.mean(params.reid.appearance_min_count);
            signatures.push((signature.mean(1), appearance.is_none()));
            exits.push(TrackEnd {
                appearance,
                ..track_end(class_id, frames[last_pos].time_s, &last, left_view)
            });
            exit_ids.push(id);
            // The entry as online takes it: the world state w observations in (or the last
            // one of a shorter tracklet), when the velocity has settled.
            let (entry_pos, entry) = worlds[window.min(worlds.len() - 1)];
            entries.push(TrackEnd {
                appearance,
                ..track_end(class_id, frames[entry_pos].time_s, &entry, false)
            });
            let (first_pos, first) = worlds[0];
            firsts.push(ChainPoint {
                time_s: frames[first_pos].time_s,
                pos_ne_m: first.pos_ne_m,
            });
            entry_ids.push(id);
            detections.push(points.iter().filter(|p| !p.interpolated).count());
            spans.push((
                points.first().map_or(0, |p| p.pos),
                points.last().map_or(0, |p| p.pos),
            ));
        }
        // Exits and entries share indices (one of each per tracklet): a link needs the
        // entry's tracklet to start after the exit's tracklet ended.
        let drift = tracker.sea_drift();
        // Offline has its own long-term gate (`offline.gate_chi2`), the same for every gap.
        let mut reid = params.reid.clone();
        reid.gate_chi2 = params.offline.gate_chi2;
        reid.long_gap_gate_chi2 = params.offline.gate_chi2;
        let scant_gate = params.offline.scant_appearance_gate;
        let colour_distance = |i: usize, j: usize| {
            let ((a, _), (b, _)) = (&signatures[i], &signatures[j]);
            a.as_ref().zip(b.as_ref()).map(|(a, b)| a.distance(b))
        };
        let scant = |i: usize, j: usize| signatures[i].1 || signatures[j].1;
        // Never tighter than the class's own gate on full signatures.
        let colours_apart = |i: usize, j: usize| {
            let gate = params.reid.class(exits[i].class_id).appearance_gate;
            scant(i, j)
                && gate < 1.0
                && colour_distance(i, j).is_some_and(|d| d > scant_gate.max(gate))
        };
        let allowed = |i: usize, j: usize| spans[j].0 > spans[i].1 && !colours_apart(i, j);
        let mut links = associate_exits_to_entries_where(&exits, &entries, &reid, drift, allowed);
        if params.offline.chain_velocity {
            let (exits, entries) = with_chain_velocities(
                &exits,
                &entries,
                &firsts,
                &links,
                &reid,
                params.offline.chain_velocity_min_s,
            );
            // Own motion is carried over the whole gap in this pass (see
            // `offline.chain_velocity`).
            let mut chain_reid = reid.clone();
            for c in std::iter::once(&mut chain_reid.default_class)
                .chain(chain_reid.classes.values_mut())
            {
                c.own_motion_s = f64::INFINITY;
            }
            links = associate_exits_to_entries_where(&exits, &entries, &chain_reid, drift, allowed);
        }
        let weak = params.offline.weak_class_max_detections as usize;
        if weak > 0 || params.offline.stricter_class_orphans {
            let weak = |i: usize| detections[i] <= weak;
            let ends = TrackletEnds {
                ids: &exit_ids,
                exits: &exits,
                entries: &entries,
                spans: &spans,
            };
            link_orphans_as_other_classes(
                &ends,
                weak,
                params.offline.stricter_class_orphans,
                &mut links,
                &reid,
                drift,
            );
        }
        for &(i, j) in &links {
            tracing::debug!(
                exit_id = exit_ids[i],
                entry_id = entry_ids[j],
                exit_frame = frames[spans[i].1].frame_index,
                entry_frame = frames[spans[j].0].frame_index,
                class_id = exits[i].class_id,
                colour_distance = ?colour_distance(i, j),
                scant = scant(i, j),
                "offline ReID link"
            );
        }
        let successor: BTreeMap<u64, u64> = links
            .iter()
            .map(|&(i, j)| (exit_ids[i], entry_ids[j]))
            .collect();
        let has_predecessor: std::collections::BTreeSet<u64> =
            successor.values().copied().collect();
        for &root in ids.iter().filter(|id| !has_predecessor.contains(id)) {
            let mut cur = root;
            // Chains are strictly increasing in time, so this walk ends; the bound guards it.
            for _ in 0..ids.len() {
                let Some(&next) = successor.get(&cur) else {
                    break;
                };
                final_id.insert(next, root);
                relabelled.push((next, root));
                cur = next;
            }
        }
        relabelled.sort_unstable();
    }

    // Merge tracklets under their final ids and interpolate again.
    let mut tracks: BTreeMap<u64, Vec<Point>> = BTreeMap::new();
    for (id, points) in tracklets {
        let fid = final_id.get(&id).copied().unwrap_or(id);
        tracks.entry(fid).or_default().extend(points);
    }
    let mut out_frames: Vec<SequenceFrame> = frames
        .iter()
        .map(|f| SequenceFrame {
            frame_index: f.frame_index,
            time_s: f.time_s,
            tracks: Vec::new(),
        })
        .collect();
    for (id, mut points) in tracks {
        // Linked tracklets never overlap in frames (see the span test above), so positions
        // are unique after sorting.
        points.sort_by_key(|p| p.pos);
        interpolate(&mut points, frames, max_gap);
        let class_id = tracklet_class(&points);
        for p in points {
            out_frames[p.pos].tracks.push(SequenceTrack {
                id,
                bbox: p.bbox,
                score: p.score,
                class_id,
                world: p.world,
                interpolated: p.interpolated,
            });
        }
    }
    for f in &mut out_frames {
        f.tracks.sort_by_key(|t| t.id);
    }
    Ok(SequenceResult {
        frames: out_frames,
        relabelled,
    })
}

/// Exchanges the points of tracklets `e.id` and `e.other_id` from frame
/// `e.since_frame_index` on (a contact repair, see [`ExchangeEvent`]).
fn exchange_since(
    tracklets: &mut BTreeMap<u64, Vec<Point>>,
    e: &ExchangeEvent,
    frames: &[FrameInput],
) {
    let mut tail = |id: u64| {
        tracklets.get_mut(&id).map_or_else(Vec::new, |points| {
            let k = points.partition_point(|p| frames[p.pos].frame_index < e.since_frame_index);
            points.split_off(k)
        })
    };
    let (a, b) = (tail(e.id), tail(e.other_id));
    tracing::debug!(
        id = e.id,
        other_id = e.other_id,
        since = e.since_frame_index,
        frame = e.frame_index,
        points = a.len() + b.len(),
        "offline: frames since a contact exchanged back"
    );
    for (id, points) in [(e.other_id, a), (e.id, b)] {
        if !points.is_empty() {
            tracklets.entry(id).or_default().extend(points);
        }
    }
}

/// The ends of the tracklets (one exit, entry, frame-position span and id per tracklet).
#[derive(Clone, Copy)]
struct TrackletEnds<'a> {
    ids: &'a [u64],
    exits: &'a [TrackEnd],
    entries: &'a [TrackEnd],
    spans: &'a [(usize, usize)],
}

/// Orphans of uncertain class: a tracklet linked to nothing after the assignments may be of
/// another class than its majority says, and is then offered as that class:
///
/// - `weak(i)`: its class rests on few detections (`offline.weak_class_max_detections`),
///   and the other class has the same ReID thresholds (a swimmer's lone detection classed
///   as a life-saving appliance);
/// - `stricter` (`offline.stricter_class_orphans`): any orphan, as a class whose thresholds
///   are no wider than its own
///   ([`no_wider_than`](super::params::ClassReidParams::no_wider_than)), so the link is
///   judged at least as strictly as its own class would judge it (a swimmer half out of the
///   image, boxed as a boat); only where both ends have a colour signature and that class
///   has a colour gate: a change of class needs the colours to agree (a boat that comes to
///   a swimmer's place is not the swimmer).
///
/// As the other class it may go into the gap of a link of that class (both the link's exit
/// to it and it to the link's entry inside the gate, the gap's only such link), or else
/// join a chain's free end: as the exit before a tracklet that has no predecessor, or the
/// entry after one that has no successor, each pair under the usual gate and timing.
/// Classes are tried in ascending id order; the first link found is kept.
fn link_orphans_as_other_classes(
    ends: &TrackletEnds<'_>,
    weak: impl Fn(usize) -> bool,
    stricter: bool,
    links: &mut Vec<(usize, usize)>,
    reid: &ReidParams,
    drift: &SeaDrift,
) {
    let TrackletEnds {
        ids,
        exits,
        entries,
        spans,
    } = *ends;
    let n = exits.len();
    let mut has_predecessor = vec![false; n];
    let mut has_successor = vec![false; n];
    for &(i, j) in links.iter() {
        has_successor[i] = true;
        has_predecessor[j] = true;
    }
    for o in 0..n {
        if has_predecessor[o] || has_successor[o] {
            continue;
        }
        let own = exits[o].class_id;
        let (own_params, weak_o) = (reid.class(own), weak(o));
        // (class, whether the colours must vouch for the link)
        let alternatives: Vec<(u32, bool)> = reid
            .classes
            .keys()
            .copied()
            .filter(|&c| c != own)
            .filter_map(|c| {
                let cp = reid.class(c);
                if cp == own_params {
                    weak_o.then_some((c, false))
                } else {
                    let judged = cp.no_wider_than(own_params) && cp.appearance_gate < 1.0;
                    (stricter && judged).then_some((c, true))
                }
            })
            .collect();
        // Both ends have a colour signature, so the class's gate has judged them.
        let coloured =
            |i: usize, j: usize| exits[i].appearance.is_some() && entries[j].appearance.is_some();
        for (class_id, needs_colours) in alternatives {
            let vouched = |i: usize, j: usize| !needs_colours || coloured(i, j);
            let as_class = |k: usize, end: &TrackEnd| {
                let mut e = *end;
                if k == o {
                    e.class_id = class_id;
                }
                e
            };
            let fits = |i: usize, j: usize| {
                !associate_exits_to_entries_where(
                    &[as_class(i, &exits[i])],
                    &[as_class(j, &entries[j])],
                    reid,
                    drift,
                    |_, _| true,
                )
                .is_empty()
            };
            // Into a link's gap.
            let gaps: Vec<usize> = (0..links.len())
                .filter(|&k| {
                    let (i, j) = links[k];
                    exits[i].class_id == class_id
                        && spans[i].1 < spans[o].0
                        && spans[o].1 < spans[j].0
                })
                .filter(|&k| {
                    let (i, j) = links[k];
                    vouched(i, o) && vouched(o, j) && fits(i, o) && fits(o, j)
                })
                .collect();
            let (new_links, place) = if let [k] = gaps[..] {
                let (i, j) = links.swap_remove(k);
                (vec![(i, o), (o, j)], "into a link's gap")
            } else {
                // The orphan and the free ends it could join, in index order: the only pairs
                // that may link (exit before it with no successor, entry after it with no
                // predecessor).
                let free_exits: Vec<usize> = (0..n)
                    .filter(|&i| i == o || (!has_successor[i] && spans[o].0 > spans[i].1))
                    .collect();
                let free_entries: Vec<usize> = (0..n)
                    .filter(|&j| j == o || (!has_predecessor[j] && spans[j].0 > spans[o].1))
                    .collect();
                let ex: Vec<TrackEnd> =
                    free_exits.iter().map(|&i| as_class(i, &exits[i])).collect();
                let en: Vec<TrackEnd> = free_entries
                    .iter()
                    .map(|&j| as_class(j, &entries[j]))
                    .collect();
                let with_orphan = |a: usize, b: usize| {
                    let (i, j) = (free_exits[a], free_entries[b]);
                    (i == o) != (j == o) && vouched(i, j)
                };
                let found = associate_exits_to_entries_where(&ex, &en, reid, drift, with_orphan);
                let pairs = found
                    .first()
                    .map(|&(a, b)| (free_exits[a], free_entries[b]));
                (pairs.into_iter().collect(), "at a chain's free end")
            };
            if new_links.is_empty() {
                continue;
            }
            for &(i, j) in &new_links {
                tracing::debug!(
                    tracklet = ids[o],
                    class_id,
                    exit_id = ids[i],
                    entry_id = ids[j],
                    place,
                    "offline ReID: an orphan linked as another class"
                );
                has_successor[i] = true;
                has_predecessor[j] = true;
            }
            links.extend(new_links);
            break;
        }
    }
}

/// The ends of a second ReID pass with chain velocities: tracklet `i` has exit `exits[i]`,
/// entry `entries[i]` and first observation `firsts[i]`; `links` (exit, entry) from the
/// first pass make chains. An exit moves with the average velocity from its chain's first
/// observation, an entry with the average velocity to its chain's last observation (its
/// chain's last exit), each where [`with_chain_velocity`] applies.
fn with_chain_velocities(
    exits: &[TrackEnd],
    entries: &[TrackEnd],
    firsts: &[ChainPoint],
    links: &[(usize, usize)],
    reid: &ReidParams,
    min_span_s: f64,
) -> (Vec<TrackEnd>, Vec<TrackEnd>) {
    let n = exits.len();
    let mut successor = vec![None; n];
    let mut predecessor = vec![None; n];
    for &(i, j) in links {
        successor[i] = Some(j);
        predecessor[j] = Some(i);
    }
    // Links go forward in time, so these walks end; the bound guards them.
    let walk = |start: usize, next: &[Option<usize>]| {
        let mut cur = start;
        for _ in 0..n {
            match next[cur] {
                Some(k) => cur = k,
                None => break,
            }
        }
        cur
    };
    let mut new_exits = exits.to_vec();
    let mut new_entries = entries.to_vec();
    for i in 0..n {
        let class = reid.class(exits[i].class_id);
        let chain_first = firsts[walk(i, &predecessor)];
        new_exits[i] = with_chain_velocity(
            &exits[i],
            chain_first,
            ChainPoint::of(&exits[i]),
            class,
            min_span_s,
        );
        let chain_last = ChainPoint::of(&exits[walk(i, &successor)]);
        new_entries[i] = with_chain_velocity(&entries[i], firsts[i], chain_last, class, min_span_s);
    }
    (new_exits, new_entries)
}

fn tracklet_class(points: &[Point]) -> u32 {
    let mut votes = Vec::new();
    for c in points.iter().filter_map(|p| p.class_id) {
        add_vote(&mut votes, c);
    }
    majority_class(&votes)
}

/// Fills the frames between consecutive points of a track (sorted by frame position) by
/// linear interpolation in frame number, when at most `max_gap_frames` frames are missing.
fn interpolate(points: &mut Vec<Point>, frames: &[FrameInput], max_gap_frames: u64) {
    let mut filled = Vec::new();
    for pair in points.windows(2) {
        let (a, b) = (&pair[0], &pair[1]);
        let (fa, fb) = (frames[a.pos].frame_index, frames[b.pos].frame_index);
        let missing = fb.saturating_sub(fa).saturating_sub(1);
        if b.pos <= a.pos + 1 || missing == 0 || missing > max_gap_frames {
            continue;
        }
        for (pos, frame) in frames.iter().enumerate().take(b.pos).skip(a.pos + 1) {
            let s = (frame.frame_index - fa) as f64 / (fb - fa) as f64;
            filled.push(Point {
                pos,
                bbox: a.bbox.lerp(&b.bbox, s),
                score: a.score + (b.score - a.score) * s as f32,
                class_id: None,
                world: match (a.world, b.world) {
                    (Some(wa), Some(wb)) => Some(WorldState {
                        pos_ne_m: wa.pos_ne_m.lerp(&wb.pos_ne_m, s),
                        vel_ne_m_s: wa.vel_ne_m_s.lerp(&wb.vel_ne_m_s, s),
                        cov: wa.cov + (wb.cov - wa.cov) * s,
                    }),
                    _ => None,
                },
                appearance: None,
                interpolated: true,
            });
        }
    }
    if !filled.is_empty() {
        points.extend(filled);
        points.sort_by_key(|p| p.pos);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    fn frame(i: u64) -> FrameInput {
        FrameInput {
            frame_index: i,
            time_s: i as f64 / 30.0,
            image_size_px: (100, 100),
            detections: vec![],
            image_motion: None,
        }
    }

    fn point(pos: usize, x: f64) -> Point {
        Point {
            pos,
            bbox: BBox::new(x, 0.0, 10.0, 10.0),
            score: 0.8,
            class_id: Some(1),
            world: None,
            appearance: None,
            interpolated: false,
        }
    }

    #[test]
    fn interpolation_fills_short_gaps_in_frame_numbers() {
        // frame 3 was dropped from the input: positions 0..=4 are frames 0, 1, 2, 4, 5
        let frames: Vec<_> = [0, 1, 2, 4, 5].into_iter().map(frame).collect();
        let mut pts = vec![point(0, 0.0), point(4, 50.0)];
        interpolate(&mut pts, &frames, 20);
        let xs: Vec<f64> = pts.iter().map(|p| p.bbox.x).collect();
        assert_eq!(
            pts.iter().map(|p| p.pos).collect::<Vec<_>>(),
            vec![0, 1, 2, 3, 4]
        );
        // frame 4 is 4/5 of the way
        assert_relative_eq!(xs[3], 40.0);
        assert_relative_eq!(xs[2], 20.0);
        assert!(pts[1].interpolated && !pts[4].interpolated);
        assert_eq!(pts[1].class_id, None);
    }

    #[test]
    fn empty_sequence_gives_empty_result() {
        let r = track_sequence(&[], &TrackerParams::default()).unwrap();
        assert!(r.frames.is_empty() && r.relabelled.is_empty());
        let frames: Vec<_> = (0..3).map(frame).collect();
        let r = track_sequence(&frames, &TrackerParams::default()).unwrap();
        assert_eq!(r.frames.len(), 3);
        assert!(r.frames.iter().all(|f| f.tracks.is_empty()));
    }

    fn swimmer_end(t: f64, e: f64) -> TrackEnd {
        TrackEnd {
            class_id: 1,
            time_s: t,
            pos_ne_m: nalgebra::Vector2::new(0.0, e),
            vel_ne_m_s: nalgebra::Vector2::zeros(),
            pos_cov_m2: nalgebra::Matrix2::identity(),
            vel_cov_m2_s2: nalgebra::Matrix2::identity(),
            left_view: true,
            appearance: None,
        }
    }

    /// A one-detection tracklet classed 4 (life-saving appliance) just before a swimmer's
    /// tracklet at the same place, and linked to nothing: offered as a swimmer (class 4 has
    /// the swimmer's thresholds) it becomes that tracklet's predecessor; not when its class
    /// is deemed certain, and never as a boat (other thresholds).
    #[test]
    fn an_orphan_of_uncertain_class_joins_a_chain_as_a_class_with_the_same_thresholds() {
        let reid = {
            let mut r = TrackerParams::default().reid;
            r.gate_chi2 = 16.0;
            r.long_gap_gate_chi2 = 16.0;
            r
        };
        let glimpse = TrackEnd {
            class_id: 4,
            ..swimmer_end(1.0, 0.0)
        };
        let exits = [glimpse, swimmer_end(10.0, 0.0)];
        let entries = [glimpse, swimmer_end(2.0, 0.5)];
        let spans = [(30, 30), (60, 300)];
        let ends = TrackletEnds {
            ids: &[7, 8],
            exits: &exits,
            entries: &entries,
            spans: &spans,
        };
        let drift = SeaDrift::default();
        let mut links = Vec::new();
        link_orphans_as_other_classes(&ends, |i| i == 0, false, &mut links, &reid, &drift);
        assert_eq!(links, vec![(0, 1)]);

        let mut certain = Vec::new();
        link_orphans_as_other_classes(&ends, |_| false, false, &mut certain, &reid, &drift);
        assert!(certain.is_empty());

        let boat = TrackEnd {
            class_id: 2,
            ..glimpse
        };
        let (exits, entries) = ([boat, exits[1]], [boat, entries[1]]);
        let ends = TrackletEnds {
            exits: &exits,
            entries: &entries,
            ..ends
        };
        let mut as_boat = Vec::new();
        link_orphans_as_other_classes(&ends, |i| i == 0, false, &mut as_boat, &reid, &drift);
        assert!(as_boat.is_empty(), "a boat is not offered as a swimmer");
    }

    /// A swimmer's chain 0 -> 2 with a boat-classed tracklet 1 in its gap, at the same
    /// place (a swimmer half out of the image boxed as a boat): offered as a swimmer (no
    /// wider thresholds than a boat's) it goes into the gap, 0 -> 1 -> 2; with nothing
    /// after it, it joins the chain's free end. Not with `stricter` off, nor when the colours
    /// disagree or are unknown, and a swimmer-classed tracklet is never offered as a boat
    /// (wider thresholds).
    #[test]
    fn an_orphan_is_offered_as_a_stricter_class_into_a_gap_or_at_a_free_end() {
        let reid = {
            let mut r = TrackerParams::default().reid;
            r.gate_chi2 = 16.0;
            r.long_gap_gate_chi2 = 16.0;
            r
        };
        let drift = SeaDrift::default();
        let as_boat = |e: TrackEnd| TrackEnd { class_id: 2, ..e };
        let orange = |t: f64, e: f64| TrackEnd {
            appearance: Some(crate::track::scenes::colour(2)),
            ..swimmer_end(t, e)
        };
        let exits = [
            orange(10.0, 0.0),
            as_boat(orange(20.0, 0.3)),
            orange(40.0, 0.4),
        ];
        let entries = [
            orange(0.0, 0.0),
            as_boat(orange(12.0, 0.2)),
            orange(25.0, 0.4),
        ];
        let spans = [(0, 300), (360, 600), (750, 1200)];
        let ends = TrackletEnds {
            ids: &[1, 2, 3],
            exits: &exits,
            entries: &entries,
            spans: &spans,
        };
        let mut links = vec![(0, 2)];
        link_orphans_as_other_classes(&ends, |_| false, true, &mut links, &reid, &drift);
        links.sort_unstable();
        assert_eq!(links, vec![(0, 1), (1, 2)]);

        let mut off = vec![(0, 2)];
        link_orphans_as_other_classes(&ends, |_| false, false, &mut off, &reid, &drift);
        assert_eq!(off, vec![(0, 2)]);

        // Colours that disagree, or none: no change of class.
        for appearance in [Some(crate::track::scenes::colour(9)), None] {
            let (mut x, mut n) = (exits, entries);
            x[1].appearance = appearance;
            n[1].appearance = appearance;
            let other = TrackletEnds {
                exits: &x,
                entries: &n,
                ..ends
            };
            let mut kept = vec![(0, 2)];
            link_orphans_as_other_classes(&other, |_| false, true, &mut kept, &reid, &drift);
            assert_eq!(kept, vec![(0, 2)], "{appearance:?}");
        }

        // Without the chain's later tracklet: the orphan joins the free end after 0.
        let two = TrackletEnds {
            ids: &[1, 2],
            exits: &exits[..2],
            entries: &entries[..2],
            spans: &spans[..2],
        };
        let mut free = Vec::new();
        link_orphans_as_other_classes(&two, |_| false, true, &mut free, &reid, &drift);
        assert_eq!(free, vec![(0, 1)]);

        // A boat chain with a swimmer-classed tracklet in its gap: left alone.
        let (bx, bn) = (exits.map(as_boat), entries.map(as_boat));
        let (sx, sn) = (swimmer_end(20.0, 0.3), swimmer_end(12.0, 0.2));
        let (bx, bn) = ([bx[0], sx, bx[2]], [bn[0], sn, bn[2]]);
        let boats = TrackletEnds {
            exits: &bx,
            entries: &bn,
            ..ends
        };
        let mut kept = vec![(0, 2)];
        link_orphans_as_other_classes(&boats, |_| false, true, &mut kept, &reid, &drift);
        assert_eq!(kept, vec![(0, 2)], "a swimmer is not offered as a boat");
    }

    /// Tracklets 0 -> 1 -> 2 linked, 3 alone: an exit averages from its chain's first
    /// observation, an entry to its chain's last exit; a lone tracklet from its own ends.
    #[test]
    fn chain_velocities_follow_the_first_pass_chains() {
        // (first observation, entry, exit) of each tracklet, east m at t s.
        let tracklets = [(0.0, 0.0), (50.0, 10.0), (100.0, 20.0), (0.0, 100.0)];
        let firsts: Vec<ChainPoint> = tracklets
            .iter()
            .map(|&(t, e)| ChainPoint::of(&swimmer_end(t, e)))
            .collect();
        let entries: Vec<TrackEnd> = tracklets
            .iter()
            .map(|&(t, e)| swimmer_end(t + 1.0, e))
            .collect();
        // Each tracklet lasts 20 s and moves 4 m east.
        let exits: Vec<TrackEnd> = tracklets
            .iter()
            .map(|&(t, e)| swimmer_end(t + 20.0, e + 4.0))
            .collect();
        let reid = ReidParams::default();
        let (ex, en) =
            with_chain_velocities(&exits, &entries, &firsts, &[(0, 1), (1, 2)], &reid, 30.0);
        let east = |e: &TrackEnd| e.vel_ne_m_s.y;
        // Exit 0: its chain is itself, 20 s < 30 s: unchanged.
        assert_eq!(ex[0], exits[0]);
        // Exit 1: chain from tracklet 0's first (t 0, 0 m) to itself (t 70, 14 m).
        assert_relative_eq!(east(&ex[1]), 14.0 / 70.0);
        // Exit 2: from t 0, 0 m to t 120, 24 m.
        assert_relative_eq!(east(&ex[2]), 24.0 / 120.0);
        // Entry 0: from its own first (t 0, 0 m) to the chain's last exit (t 120, 24 m).
        assert_relative_eq!(east(&en[0]), 24.0 / 120.0);
        // Entry 1: from t 50, 10 m to t 120, 24 m.
        assert_relative_eq!(east(&en[1]), 14.0 / 70.0);
        // Entry 2 and the lone tracklet 3: 20 s chains, unchanged.
        assert_eq!(en[2], entries[2]);
        assert_eq!((ex[3], en[3]), (exits[3], entries[3]));
    }

    /// Offline, a swap repaired by the colours after the contact is undone back to the frame
    /// where the boxes coincided: each swimmer keeps one id over the whole sequence (the
    /// online output holds the swapped frames, see `online::tests`).
    #[test]
    fn a_repaired_swap_is_undone_back_to_the_contact() {
        use crate::track::scenes;
        let scene = scenes::meet_and_turn_back((0, 8));
        let frames: Vec<FrameInput> = scene.iter().map(|(f, _)| f.clone()).collect();
        let ids_of = |params: &TrackerParams| {
            let result = track_sequence(&frames, params).unwrap();
            // Per frame, the id whose box is nearest the first swimmer's and the second's.
            result
                .frames
                .iter()
                .zip(&scene)
                .map(|(f, (_, (x0, x1)))| {
                    let by_x =
                        |x: f64| scenes::nearest_id(f.tracks.iter().map(|t| (t.id, t.bbox)), x);
                    (by_x(*x0), by_x(*x1))
                })
                .collect::<Vec<_>>()
        };
        let mut off = TrackerParams::default();
        off.contact.enabled = false;
        let swapped = ids_of(&off);
        assert_ne!(swapped[0], swapped[69], "without the repair: {swapped:?}");

        let ids = ids_of(&TrackerParams::default());
        let (first, second) = ids[0];
        assert!(first.is_some() && second.is_some() && first != second);
        // Frames 29-31 (positions 28-30): the boxes are within 6 px, either id is as near.
        for (pos, &pair) in ids.iter().enumerate() {
            if !(28..=30).contains(&pos) {
                assert_eq!(pair, (first, second), "position {pos}: {ids:?}");
            }
        }
    }

    #[test]
    fn interpolation_leaves_long_gaps_open() {
        let frames: Vec<_> = (0..10).map(frame).collect();
        let mut pts = vec![point(0, 0.0), point(9, 90.0)];
        interpolate(&mut pts, &frames, 7);
        assert_eq!(pts.len(), 2);
        interpolate(&mut pts, &frames, 8);
        assert_eq!(pts.len(), 10);
        assert!(pts[1..9].iter().all(|p| p.interpolated));
    }
}
