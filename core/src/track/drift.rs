//! Sea drift estimated from the tracks themselves, per class.
//!
//! Everything adrift in one area moves with the same surface current plus its class's wind
//! leeway (IAMSAR Vol. II): swimmers in a group drift together. Over the minute between two
//! passes of a search pattern that common drift moves a whole group by metres to tens of
//! metres, more than the spacing inside the group, while each swimmer's own motion about it
//! stays small and undirected. Long-term ReID therefore carries an exit forward (and an
//! entry backward) by the drift over the whole gap, and only by the object's own velocity
//! relative to the drift for `tau_memory` (see
//! [`mahalanobis_long_term_cost`](super::reid::mahalanobis_long_term_cost)).
//!
//! The drift of a class is the time-weighted mean world velocity of its confirmed tracks
//! whose velocity has settled, with exponential forgetting (the current turns with the tide
//! over hours, not minutes). The swimmers' own motions average out over a group; what does
//! not average out stays in the estimate's covariance.

use std::collections::{BTreeMap, HashMap};

use nalgebra::{Matrix2, Vector2};
use serde::{Deserialize, Serialize};

/// Drift estimation parameters (`[reid.drift]`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DriftParams {
    /// Estimate and use the drift at all (false: long-term ReID extrapolates each end by its
    /// own velocity only, for at most `tau_memory_s`).
    pub enabled: bool,
    /// Forgetting time constant, s: samples older than this weigh `1/e` as much.
    pub time_constant_s: f64,
    /// Track-seconds of settled samples a class needs before its drift is used, s.
    pub min_sample_s: f64,
    /// A track's velocity is a sample only once its standard deviation (root of the mean
    /// of the two axes' variances) is below this, m/s.
    pub max_vel_std_m_s: f64,
}

impl Default for DriftParams {
    fn default() -> Self {
        Self {
            enabled: true,
            time_constant_s: 300.0,
            min_sample_s: 20.0,
            max_vel_std_m_s: 0.3,
        }
    }
}

/// The drift of one class: a velocity over ground and the covariance of that estimate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DriftEstimate {
    /// Mean velocity over ground of the class's objects, north/east m/s.
    pub vel_ne_m_s: Vector2<f64>,
    /// Covariance of `vel_ne_m_s`, m^2/s^2: the spread of the samples about the mean over
    /// the number of distinct tracks that gave them (one track's samples are one object's
    /// own motion, which does not average out over time).
    pub cov_m2_s2: Matrix2<f64>,
}

/// Exponentially forgetting weighted sums of one class's samples.
#[derive(Debug, Clone, Copy, Default)]
struct Accumulator {
    /// Sum of weights (track-seconds).
    weight: f64,
    /// Weighted sum of velocities.
    sum: Vector2<f64>,
    /// Weighted sum of velocity outer products.
    sum_sq: Matrix2<f64>,
    /// Forgetting count of the distinct tracks that gave samples.
    objects: f64,
}

/// Per-class drift estimator; [`SeaDrift::default`] estimates nothing (zero drift).
#[derive(Debug, Clone, Default)]
pub struct SeaDrift {
    params: DriftParams,
    classes: BTreeMap<u32, Accumulator>,
    /// Tracks that gave samples, by id, with the time of their last sample.
    seen: HashMap<u64, f64>,
    /// Time `seen` was last pruned of tracks silent for over `time_constant_s`.
    pruned_s: f64,
    last_time_s: Option<f64>,
}

impl SeaDrift {
    /// An estimator with these parameters.
    pub fn new(params: DriftParams) -> Self {
        Self {
            params,
            classes: BTreeMap::new(),
            seen: HashMap::new(),
            pruned_s: f64::NEG_INFINITY,
            last_time_s: None,
        }
    }

    /// Whether a track's velocity, with this covariance, is settled enough to be a sample.
    pub fn is_settled(&self, vel_cov_m2_s2: &Matrix2<f64>) -> bool {
        let max = self.params.max_vel_std_m_s;
        vel_cov_m2_s2.trace() / 2.0 <= max * max
    }

    /// Adds one frame at `time_s`: `samples` are the `(class id, track id, velocity)` of
    /// the settled tracks of classes that drift. Frames must come in time order; a frame at
    /// the same time as the last one weighs nothing. A track counts as a new object when it
    /// first gives a sample, and again after `time_constant_s` without one.
    pub fn observe(&mut self, time_s: f64, samples: &[(u32, u64, Vector2<f64>)]) {
        if !self.params.enabled || !time_s.is_finite() {
            return;
        }
        let dt = self
            .last_time_s
            .map_or(0.0, |last| (time_s - last).clamp(0.0, 10.0));
        self.last_time_s = Some(time_s);
        let keep = (-dt / self.params.time_constant_s).exp();
        for acc in self.classes.values_mut() {
            acc.weight *= keep;
            acc.sum *= keep;
            acc.sum_sq *= keep;
            acc.objects *= keep;
        }
        if dt <= 0.0 {
            return;
        }
        let horizon = self.params.time_constant_s;
        for &(class_id, track_id, v) in samples {
            if !v.iter().all(|x| x.is_finite()) {
                continue;
            }
            let acc = self.classes.entry(class_id).or_default();
            acc.weight += dt;
            acc.sum += v * dt;
            acc.sum_sq += v * v.transpose() * dt;
            let last = self.seen.insert(track_id, time_s);
            if last.is_none_or(|t| time_s - t > horizon) {
                acc.objects += 1.0;
            }
        }
        if time_s - self.pruned_s > horizon {
            self.pruned_s = time_s;
            self.seen.retain(|_, t| time_s - *t <= horizon);
        }
    }

    /// The drift of a class; `None` until it has `min_sample_s` of samples, or when
    /// estimation is off.
    pub fn estimate(&self, class_id: u32) -> Option<DriftEstimate> {
        let acc = self.classes.get(&class_id)?;
        if !self.params.enabled || acc.weight < self.params.min_sample_s {
            return None;
        }
        let mean = acc.sum / acc.weight;
        let spread = acc.sum_sq / acc.weight - mean * mean.transpose();
        let n = acc.objects.max(1.0);
        Some(DriftEstimate {
            vel_ne_m_s: mean,
            cov_m2_s2: (spread + spread.transpose()) / (2.0 * n),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn mean_of_a_group_with_symmetric_own_motion_is_the_drift() {
        let mut d = SeaDrift::new(DriftParams::default());
        let drift = Vector2::new(0.1, -0.05);
        let own = [
            Vector2::new(0.2, 0.0),
            Vector2::new(-0.2, 0.0),
            Vector2::new(0.0, 0.3),
            Vector2::new(0.0, -0.3),
        ];
        for k in 0..900 {
            let s: Vec<(u32, u64, Vector2<f64>)> = own
                .iter()
                .zip(1..)
                .map(|(o, id)| (1, id, drift + o))
                .collect();
            d.observe(f64::from(k) / 30.0, &s);
        }
        let e = d.estimate(1).unwrap();
        assert_relative_eq!(e.vel_ne_m_s, drift, epsilon = 1e-9);
        // Spread 0.02 (n) and 0.045 (e) over four objects (counted once each, then
        // forgotten over 30 s: 4 e^-0.1).
        let n = 4.0 * (-30.0f64 / 300.0).exp();
        assert_relative_eq!(e.cov_m2_s2[(0, 0)], 0.02 / n, max_relative = 0.01);
        assert_relative_eq!(e.cov_m2_s2[(1, 1)], 0.045 / n, max_relative = 0.01);
        // Another class saw nothing.
        assert_eq!(d.estimate(2), None);
    }

    #[test]
    fn nothing_is_used_before_enough_samples_or_when_off() {
        let mut d = SeaDrift::new(DriftParams::default());
        for k in 0..300 {
            d.observe(f64::from(k) / 30.0, &[(1, 1, Vector2::new(1.0, 0.0))]);
        }
        // 10 track-seconds < 20.
        assert_eq!(d.estimate(1), None);
        let mut off = SeaDrift::new(DriftParams {
            enabled: false,
            ..DriftParams::default()
        });
        for k in 0..3000 {
            off.observe(f64::from(k) / 30.0, &[(1, 1, Vector2::new(1.0, 0.0))]);
        }
        assert_eq!(off.estimate(1), None);
        assert_eq!(SeaDrift::default().estimate(1), None);
    }

    #[test]
    fn old_samples_are_forgotten() {
        let mut d = SeaDrift::new(DriftParams {
            time_constant_s: 60.0,
            ..DriftParams::default()
        });
        let mut t = 0.0;
        for _ in 0..(600 * 30) {
            d.observe(t, &[(1, 1, Vector2::new(1.0, 0.0))]);
            t += 1.0 / 30.0;
        }
        for _ in 0..(600 * 30) {
            d.observe(t, &[(1, 1, Vector2::new(0.0, 1.0))]);
            t += 1.0 / 30.0;
        }
        let e = d.estimate(1).unwrap().vel_ne_m_s;
        assert!(e.x < 1e-3 && e.y > 0.999, "{e:?}");
    }

    #[test]
    fn non_finite_samples_and_times_are_ignored() {
        let mut d = SeaDrift::new(DriftParams::default());
        for k in 0..900 {
            let t = f64::from(k) / 30.0;
            d.observe(
                t,
                &[
                    (1, 1, Vector2::new(0.5, 0.5)),
                    (1, 2, Vector2::new(f64::NAN, 0.0)),
                ],
            );
            d.observe(f64::NAN, &[(1, 1, Vector2::new(9.0, 9.0))]);
        }
        assert_relative_eq!(
            d.estimate(1).unwrap().vel_ne_m_s,
            Vector2::new(0.5, 0.5),
            epsilon = 1e-9
        );
    }
}
