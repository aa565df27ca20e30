//! Scoring a picture (fused, or one drone's) against the simulator's truth.
//!
//! At every sample time the picture's tracks are matched one to one to the true objects of
//! their class within `match_m` (minimum total distance). Over the run:
//! - **ids per object:** each track id's identity is the object it was matched to most often
//!   (the usual dominant-truth rule of identity metrics); for each true object matched at
//!   least once, the number of track ids whose identity it is. 1.0 is one id per object for
//!   the whole run. A track briefly matched to a neighbour (swimmers metres apart) does not
//!   count as a second id of that neighbour; `ids_per_object_any` counts every id ever
//!   matched, for comparison;
//! - **position error:** the distance of every matched pair, median and 95th percentile;
//! - **unmatched tracks:** tracks with no object of their class within `match_m` (a second
//!   id on one object shows up here too, beside the first).
//!
//! The caller chooses which objects count (for the fused picture: those seen by both
//! drones) with [`TruthObject::counts`]. The others stay in the truth, so a track of an
//! object that does not count is matched to it, not to a neighbour that counts.

use std::collections::{BTreeMap, BTreeSet};

use nalgebra::Vector2;
use serde::Serialize;

use crate::track::assign::solve_gated;

/// A true object at one sample time, in a local frame (north, east, m) shared with the
/// picture.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TruthObject {
    /// The object's id in the truth.
    pub id: u64,
    /// Class id (SeaDronesSee numbering).
    pub class_id: u32,
    /// Position north, east (m).
    pub pos_ne_m: Vector2<f64>,
    /// Whether the object is scored (ids, errors); an object that does not count is still
    /// matched.
    pub counts: bool,
}

/// The picture and the truth at one time.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PictureSample {
    /// The picture's tracks: (id, class id, position north/east in m).
    pub tracks: Vec<(u64, u32, Vector2<f64>)>,
    /// The objects that count at this time.
    pub truth: Vec<TruthObject>,
}

/// How tracks are matched to objects.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScoreParams {
    /// A track further than this (m) from an object is not that object.
    pub match_m: f64,
}

impl Default for ScoreParams {
    fn default() -> Self {
        Self { match_m: 10.0 }
    }
}

/// A picture's score over a run.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FusedScore {
    /// Samples scored.
    pub samples: usize,
    /// True objects matched at least once.
    pub objects: usize,
    /// Mean over the matched objects of the track ids whose identity (most often matched
    /// object) is that object.
    pub ids_per_object: f64,
    /// The most ids any object had (by identity).
    pub max_ids: usize,
    /// Mean of the distinct ids ever matched to each object (a stricter, noisier count).
    pub ids_per_object_any: f64,
    /// Matched (track, object) pairs over all samples.
    pub matches: usize,
    /// Tracks with no object within `match_m`, over all samples.
    pub unmatched_tracks: usize,
    /// Median distance of the matched pairs (m); NaN without matches.
    pub error_median_m: f64,
    /// 95th percentile of the distances (m); NaN without matches.
    pub error_p95_m: f64,
}

/// The `q` quantile (0..=1) of sorted values, by the nearest rank; NaN if empty.
fn quantile(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let rank = (q * sorted.len() as f64).ceil().max(1.0) as usize;
    sorted[rank.min(sorted.len()) - 1]
}

/// The one-to-one matches of one sample: (track id, object id, distance in m).
pub fn match_sample(s: &PictureSample, params: ScoreParams) -> Vec<(u64, u64, f64)> {
    let mut cost = Vec::with_capacity(s.tracks.len() * s.truth.len());
    for (_, class, pos) in &s.tracks {
        for o in &s.truth {
            let d = (pos - o.pos_ne_m).norm();
            let ok = o.class_id == *class && d <= params.match_m;
            cost.push(if ok { d } else { f64::INFINITY });
        }
    }
    let mut pairs = Vec::new();
    solve_gated(s.tracks.len(), s.truth.len(), &mut cost, &mut pairs);
    pairs
        .into_iter()
        .map(|(r, c)| {
            let (id, _, pos) = s.tracks[r];
            let o = &s.truth[c];
            (id, o.id, (pos - o.pos_ne_m).norm())
        })
        .collect()
}

/// Scores `samples`.
pub fn score_picture(samples: &[PictureSample], params: ScoreParams) -> FusedScore {
    let mut ever: BTreeMap<u64, BTreeSet<u64>> = BTreeMap::new();
    // (track id, object id) -> samples matched.
    let mut counts: BTreeMap<(u64, u64), usize> = BTreeMap::new();
    let mut errors = Vec::new();
    let mut unmatched = 0;
    for s in samples {
        let pairs = match_sample(s, params);
        unmatched += s.tracks.len() - pairs.len();
        for (track, object, d) in pairs {
            *counts.entry((track, object)).or_default() += 1;
            if s.truth.iter().any(|o| o.id == object && o.counts) {
                ever.entry(object).or_default().insert(track);
                errors.push(d);
            }
        }
    }
    // Each track's identity: its most often matched object (the lower id on a tie).
    let mut identity: BTreeMap<u64, (usize, u64)> = BTreeMap::new();
    for ((track, object), n) in &counts {
        let best = identity.entry(*track).or_insert((*n, *object));
        if *n > best.0 {
            *best = (*n, *object);
        }
    }
    let mut ids: BTreeMap<u64, usize> = ever.keys().map(|o| (*o, 0)).collect();
    for (_, object) in identity.values() {
        if let Some(n) = ids.get_mut(object) {
            *n += 1;
        }
    }
    errors.sort_by(f64::total_cmp);
    let objects = ever.len();
    let mean = |total: usize| {
        if objects == 0 {
            f64::NAN
        } else {
            total as f64 / objects as f64
        }
    };
    FusedScore {
        samples: samples.len(),
        objects,
        ids_per_object: mean(ids.values().sum()),
        max_ids: ids.values().copied().max().unwrap_or(0),
        ids_per_object_any: mean(ever.values().map(BTreeSet::len).sum()),
        matches: errors.len(),
        unmatched_tracks: unmatched,
        error_median_m: quantile(&errors, 0.5),
        error_p95_m: quantile(&errors, 0.95),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn obj(id: u64, class_id: u32, n: f64, e: f64) -> TruthObject {
        TruthObject {
            id,
            class_id,
            pos_ne_m: Vector2::new(n, e),
            counts: true,
        }
    }

    #[test]
    fn one_id_per_object_and_errors() {
        let truth = vec![obj(1, 1, 0.0, 0.0), obj(2, 2, 50.0, 0.0)];
        let samples: Vec<PictureSample> = (0..4)
            .map(|k| PictureSample {
                tracks: vec![
                    (10, 1, Vector2::new(1.0, 0.0)),
                    (11, 2, Vector2::new(50.0, f64::from(k))),
                ],
                truth: truth.clone(),
            })
            .collect();
        let s = score_picture(&samples, ScoreParams::default());
        assert_eq!(s.objects, 2);
        assert_eq!(s.ids_per_object, 1.0);
        assert_eq!(s.matches, 8);
        assert_eq!(s.unmatched_tracks, 0);
        // Errors: four 1.0 (track 10), then 0, 1, 2, 3 (track 11).
        assert_eq!(s.error_median_m, 1.0);
        assert_eq!(s.error_p95_m, 3.0);
    }

    #[test]
    fn an_id_switch_and_a_duplicate_are_counted() {
        let truth = vec![obj(1, 1, 0.0, 0.0)];
        let samples = vec![
            PictureSample {
                tracks: vec![(10, 1, Vector2::new(0.5, 0.0))],
                truth: truth.clone(),
            },
            // Two ids on one object: the nearer is matched, the other is unmatched.
            PictureSample {
                tracks: vec![
                    (10, 1, Vector2::new(2.0, 0.0)),
                    (11, 1, Vector2::new(0.2, 0.0)),
                ],
                truth: truth.clone(),
            },
            // A track of another class on the object, and one too far away.
            PictureSample {
                tracks: vec![
                    (12, 5, Vector2::new(0.0, 0.0)),
                    (13, 1, Vector2::new(30.0, 0.0)),
                ],
                truth,
            },
        ];
        let s = score_picture(&samples, ScoreParams::default());
        assert_eq!(s.objects, 1);
        // Both ids are the object's by identity (each matched only to it).
        assert_eq!(s.ids_per_object, 2.0);
        assert_eq!(s.ids_per_object_any, 2.0);
        assert_eq!(s.max_ids, 2);
        assert_eq!(s.unmatched_tracks, 3);
        assert_eq!(s.matches, 2);
    }

    #[test]
    fn a_brief_match_to_a_neighbour_is_not_a_second_id() {
        let truth = vec![obj(1, 1, 0.0, 0.0), obj(2, 1, 6.0, 0.0)];
        let mut samples: Vec<PictureSample> = (0..5)
            .map(|_| PictureSample {
                tracks: vec![
                    (10, 1, Vector2::new(0.3, 0.0)),
                    (11, 1, Vector2::new(6.2, 0.0)),
                ],
                truth: truth.clone(),
            })
            .collect();
        // Once, track 11 strays towards object 1 while track 10 is missing.
        samples.push(PictureSample {
            tracks: vec![(11, 1, Vector2::new(2.0, 0.0))],
            truth: truth.clone(),
        });
        let s = score_picture(&samples, ScoreParams::default());
        assert_eq!(s.ids_per_object, 1.0);
        assert_eq!(s.ids_per_object_any, 1.5);
    }

    #[test]
    fn an_object_that_does_not_count_still_takes_its_own_track() {
        let mut other = obj(2, 1, 5.0, 0.0);
        other.counts = false;
        let truth = vec![obj(1, 1, 0.0, 0.0), other];
        let samples = vec![PictureSample {
            tracks: vec![
                (10, 1, Vector2::new(0.2, 0.0)),
                (11, 1, Vector2::new(4.0, 0.0)),
            ],
            truth,
        }];
        let s = score_picture(&samples, ScoreParams::default());
        assert_eq!((s.objects, s.matches), (1, 1));
        assert_eq!(s.ids_per_object, 1.0);
        assert!((s.error_median_m - 0.2).abs() < 1e-9);
    }

    #[test]
    fn nothing_to_score_is_nan_not_a_pass() {
        let s = score_picture(&[], ScoreParams::default());
        assert_eq!(s.objects, 0);
        assert!(s.ids_per_object.is_nan());
        assert!(s.error_median_m.is_nan());
    }
}
