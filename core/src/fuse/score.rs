//! Scoring a picture (fused, or one drone's) against the simulator's truth.
//!
//! At every sample time the picture's tracks are matched one to one to the true objects of
//! their class within `match_m` (minimum total distance). Over the run:
//! - **ids per object:** for each true object that was matched at least once, the number of
//!   distinct track ids it was matched to; 1.0 is one id per object for the whole run;
//! - **position error:** the distance of every matched pair, median and 95th percentile;
//! - **unmatched tracks:** tracks with no object of their class within `match_m` (a second
//!   id on one object shows up here too, beside the first).
//!
//! The caller chooses which objects count (for the fused picture: those seen by both
//! drones) by leaving the others out of the samples' truth.

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
    /// Mean of the distinct ids per matched object.
    pub ids_per_object: f64,
    /// The most distinct ids any object had.
    pub max_ids: usize,
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

/// Scores `samples`.
pub fn score_picture(samples: &[PictureSample], params: ScoreParams) -> FusedScore {
    let mut ids: BTreeMap<u64, BTreeSet<u64>> = BTreeMap::new();
    let mut errors = Vec::new();
    let mut unmatched = 0;
    let (mut cost, mut pairs) = (Vec::new(), Vec::new());
    for s in samples {
        cost.clear();
        for (_, class, pos) in &s.tracks {
            for o in &s.truth {
                let d = (pos - o.pos_ne_m).norm();
                let ok = o.class_id == *class && d <= params.match_m;
                cost.push(if ok { d } else { f64::INFINITY });
            }
        }
        solve_gated(s.tracks.len(), s.truth.len(), &mut cost, &mut pairs);
        unmatched += s.tracks.len() - pairs.len();
        for (r, c) in &pairs {
            let (id, _, pos) = s.tracks[*r];
            let o = &s.truth[*c];
            ids.entry(o.id).or_default().insert(id);
            errors.push((pos - o.pos_ne_m).norm());
        }
    }
    errors.sort_by(f64::total_cmp);
    let objects = ids.len();
    let total_ids: usize = ids.values().map(BTreeSet::len).sum();
    FusedScore {
        samples: samples.len(),
        objects,
        ids_per_object: if objects == 0 {
            f64::NAN
        } else {
            total_ids as f64 / objects as f64
        },
        max_ids: ids.values().map(BTreeSet::len).max().unwrap_or(0),
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
        assert_eq!(s.ids_per_object, 2.0);
        assert_eq!(s.max_ids, 2);
        assert_eq!(s.unmatched_tracks, 3);
        assert_eq!(s.matches, 2);
    }

    #[test]
    fn nothing_to_score_is_nan_not_a_pass() {
        let s = score_picture(&[], ScoreParams::default());
        assert_eq!(s.objects, 0);
        assert!(s.ids_per_object.is_nan());
        assert!(s.error_median_m.is_nan());
    }
}
