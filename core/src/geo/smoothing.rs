//! Smoothing of the camera attitude for camera-motion compensation.
//!
//! The metadata homography between two consecutive frames (see
//! [`FrameGeometry::image_motion_to`](super::FrameGeometry::image_motion_to)) differences two
//! attitude samples 1/30 s apart, so the attitude's frame-to-frame noise (the autopilot's
//! estimate, the gimbal's encoders, the sample nearest the exposure) goes into it in full: a
//! tenth of a degree is 2 px at 1280 px and 70 deg field of view, as wide as half a far
//! swimmer's box. The camera's true attitude moves smoothly between gimbal commands, so an
//! alpha-beta filter on the attitude (a rotation and a body rate, innovations as rotation
//! vectors) removes most of that noise, and where the attitude really jumps (a gimbal slew
//! starting, a fast turn) the filter snaps to the measurement instead of lagging behind it.
//!
//! Only the motion compensation uses the smoothed attitude: geolocation keeps the measured
//! pose, whose error is already in every observation's covariance.

use nalgebra::{UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

/// Parameters of [`AttitudeSmoother`]. The gains are per frame (the filter runs once per
/// frame the tracker takes), tuned at 30 fps.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AttitudeSmoothing {
    /// Smooth at all; `false` uses every measured attitude as it is.
    pub enabled: bool,
    /// Weight of the measurement in the attitude update, in (0, 1] (1: no smoothing).
    pub alpha: f64,
    /// Weight of the innovation in the body-rate update, in [0, 1).
    pub beta: f64,
    /// Smallest innovation, deg, at which the filter takes the measurement as it is (a real
    /// jump, not noise).
    pub snap_deg: f64,
    /// Also snap when the innovation exceeds this many times its running RMS (exponential
    /// average over the last ~30 frames that did not snap; floor 0.05 deg), so the threshold
    /// follows the attitude's actual noise and a quiet camera's real motion is not smoothed
    /// away; 0 uses `snap_deg` alone, as does an attitude whose innovation was always
    /// exactly 0.
    pub snap_rms_factor: f64,
    /// A gap between frames longer than this, s, restarts the filter at the measurement. The
    /// gains are per frame at about 30 fps, so the default 0.2 s (a few dropped frames)
    /// keeps a sparse sequence (SeaDronesSee's annotated frames are 0.5 s apart) on the
    /// measured attitude instead of smoothing real motion away.
    pub max_gap_s: f64,
}

impl Default for AttitudeSmoothing {
    fn default() -> Self {
        Self {
            enabled: true,
            alpha: 0.2,
            beta: 0.127,
            snap_deg: 1.0,
            snap_rms_factor: 4.0,
            max_gap_s: 0.2,
        }
    }
}

impl AttitudeSmoothing {
    /// The first parameter out of range, as `(name, requirement)`.
    pub fn invalid(&self) -> Option<(&'static str, &'static str)> {
        let finite = |x: f64| x.is_finite();
        if !(finite(self.alpha) && self.alpha > 0.0 && self.alpha <= 1.0) {
            return Some(("alpha", "in (0, 1]"));
        }
        if !(finite(self.beta) && (0.0..1.0).contains(&self.beta)) {
            return Some(("beta", "in [0, 1)"));
        }
        if !(finite(self.snap_deg) && self.snap_deg > 0.0 && self.snap_deg <= 180.0) {
            return Some(("snap_deg", "in (0, 180]"));
        }
        if !(finite(self.snap_rms_factor) && (0.0..=1e3).contains(&self.snap_rms_factor)) {
            return Some(("snap_rms_factor", "in [0, 1000]"));
        }
        if !(finite(self.max_gap_s) && self.max_gap_s > 0.0 && self.max_gap_s <= 3600.0) {
            return Some(("max_gap_s", "in (0, 3600]"));
        }
        None
    }
}

/// Floor of the adaptive snap threshold, rad (0.05 deg): below it the innovation is
/// numerical, and snapping at it would undo the smoothing of a noise-free attitude.
const MIN_ADAPTIVE_SNAP_RAD: f64 = 0.05 * std::f64::consts::PI / 180.0;
/// Weight of one frame in the running mean square of the innovation (about 30 frames).
const RMS_WEIGHT: f64 = 1.0 / 30.0;

/// An alpha-beta filter on the camera attitude: state = attitude and body rate at the last
/// frame's time. Pure and `Copy`: [`AttitudeSmoother::update`] returns the next state, so a
/// caller can commit it only once the frame was taken.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AttitudeSmoother {
    params: AttitudeSmoothing,
    state: Option<SmootherState>,
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct SmootherState {
    time_s: f64,
    attitude: UnitQuaternion<f64>,
    /// Body rate (rad/s, in the camera frame: `attitude * exp(rate * dt)` predicts).
    rate: Vector3<f64>,
    /// Running mean square of the innovation's angle, rad^2 (0 before the first).
    innovation_ms: f64,
}

impl AttitudeSmoother {
    /// Nothing seen yet.
    pub fn new(params: AttitudeSmoothing) -> Self {
        Self {
            params,
            state: None,
        }
    }

    /// The filter after the measurement `measured` at `time_s`, and the smoothed attitude at
    /// that time. The first measurement, one after a gap longer than `max_gap_s` or one at
    /// a time not after the last restart the filter at the measurement; disabled, the
    /// measurement is returned as it is.
    pub fn update(
        &self,
        time_s: f64,
        measured: UnitQuaternion<f64>,
    ) -> (AttitudeSmoother, UnitQuaternion<f64>) {
        let p = &self.params;
        let restart = |s: &Self| {
            let state = SmootherState {
                time_s,
                attitude: measured,
                rate: Vector3::zeros(),
                innovation_ms: s.state.map_or(0.0, |st| st.innovation_ms),
            };
            (
                AttitudeSmoother {
                    params: s.params,
                    state: Some(state),
                },
                measured,
            )
        };
        if !p.enabled || !time_s.is_finite() {
            return (*self, measured);
        }
        let Some(s) = self.state else {
            return restart(self);
        };
        let dt = time_s - s.time_s;
        if !(dt > 0.0 && dt <= p.max_gap_s) {
            return restart(self);
        }
        let predicted = s.attitude * UnitQuaternion::from_scaled_axis(s.rate * dt);
        let innovation = (predicted.inverse() * measured).scaled_axis();
        let angle = innovation.norm();
        let mut snap_rad = p.snap_deg.to_radians();
        if p.snap_rms_factor > 0.0 && s.innovation_ms > 0.0 {
            snap_rad = snap_rad
                .min((p.snap_rms_factor * s.innovation_ms.sqrt()).max(MIN_ADAPTIVE_SNAP_RAD));
        }
        let snapped = angle > snap_rad;
        let (attitude, innovation_ms) = if snapped {
            (measured, s.innovation_ms)
        } else {
            let ms = if s.innovation_ms > 0.0 {
                s.innovation_ms + RMS_WEIGHT * (angle * angle - s.innovation_ms)
            } else {
                angle * angle
            };
            (
                predicted * UnitQuaternion::from_scaled_axis(innovation * p.alpha),
                ms,
            )
        };
        let rate = s.rate + innovation * (p.beta / dt);
        let next = SmootherState {
            time_s,
            attitude,
            rate,
            innovation_ms,
        };
        (
            AttitudeSmoother {
                params: self.params,
                state: Some(next),
            },
            attitude,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn deg(q: &UnitQuaternion<f64>, r: &UnitQuaternion<f64>) -> f64 {
        q.angle_to(r).to_degrees()
    }

    /// A deterministic stand-in for white noise: a fixed pseudo-random sequence in [-1, 1].
    fn noise(i: u64, axis: u64) -> f64 {
        let mut x =
            i.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ axis.wrapping_mul(0xD1B5_4A32_D192_ED03);
        x ^= x >> 31;
        x = x.wrapping_mul(0xBF58_476D_1CE4_E5B9);
        x ^= x >> 29;
        (x >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    }

    fn truth(t: f64) -> UnitQuaternion<f64> {
        // A slow yaw (3 deg/s) with the camera pitched down 60 deg.
        UnitQuaternion::from_euler_angles(0.0, 0.0, (3.0 * t).to_radians())
            * UnitQuaternion::from_euler_angles(60f64.to_radians(), 0.0, 0.0)
    }

    fn noisy(t: f64, i: u64, sigma_deg: f64) -> UnitQuaternion<f64> {
        let e = Vector3::new(noise(i, 0), noise(i, 1), noise(i, 2)) * sigma_deg.to_radians();
        truth(t) * UnitQuaternion::from_scaled_axis(e)
    }

    /// Frame-to-frame rotation error: how far the smoothed (or measured) rotation between two
    /// consecutive frames is from the true one, deg, as the homography sees it.
    fn step_error(seq: &[UnitQuaternion<f64>], times: &[f64]) -> f64 {
        let mut sum = 0.0;
        for k in 1..seq.len() {
            let est = seq[k - 1].inverse() * seq[k];
            let tru = truth(times[k - 1]).inverse() * truth(times[k]);
            sum += deg(&est, &tru).powi(2);
        }
        (sum / (seq.len() - 1) as f64).sqrt()
    }

    #[test]
    fn smoothing_cuts_the_frame_to_frame_noise_of_a_slow_turn() {
        let times: Vec<f64> = (0..600).map(|i| i as f64 / 30.0).collect();
        let measured: Vec<_> = times
            .iter()
            .enumerate()
            .map(|(i, &t)| noisy(t, i as u64, 0.15))
            .collect();
        let mut f = AttitudeSmoother::new(AttitudeSmoothing::default());
        let mut smoothed = Vec::new();
        for (&t, q) in times.iter().zip(&measured) {
            let (next, s) = f.update(t, *q);
            f = next;
            smoothed.push(s);
        }
        // Skip the filter's first second (it starts at rest while the truth turns).
        let raw = step_error(&measured[30..], &times[30..]);
        let smooth = step_error(&smoothed[30..], &times[30..]);
        assert!(raw > 0.1, "raw frame-to-frame error {raw} deg");
        assert!(
            smooth < 0.5 * raw,
            "smoothed {smooth} deg against raw {raw} deg"
        );
        // And it follows the turn: no lag building up.
        let last = smoothed.len() - 1;
        assert!(deg(&smoothed[last], &truth(times[last])) < 0.15);
    }

    #[test]
    fn a_jump_beyond_the_snap_threshold_is_taken_at_once() {
        let params = AttitudeSmoothing {
            snap_rms_factor: 0.0,
            ..AttitudeSmoothing::default()
        };
        let mut f = AttitudeSmoother::new(params);
        let level = UnitQuaternion::from_euler_angles(1.0, 0.0, 0.0);
        for i in 0..30 {
            f = f.update(i as f64 / 30.0, level).0;
        }
        let slewed = level * UnitQuaternion::from_euler_angles(0.0, 0.0, 5f64.to_radians());
        let (_, out) = f.update(1.0, slewed);
        assert_eq!(out, slewed);
        // A small step is smoothed: the output moves by the gain alpha times the step.
        let nudged = level * UnitQuaternion::from_euler_angles(0.0, 0.0, 0.5f64.to_radians());
        let (_, out) = f.update(1.0, nudged);
        let moved = deg(&level, &out);
        let expected = params.alpha * 0.5;
        assert!(
            (moved - expected).abs() < 0.01,
            "moved {moved} deg of 0.5, expected {expected}"
        );
    }

    #[test]
    fn disabled_gaps_and_time_going_back_return_the_measurement() {
        let q0 = UnitQuaternion::from_euler_angles(0.3, 0.2, 0.1);
        let q1 = q0 * UnitQuaternion::from_euler_angles(0.0, 0.005, 0.0);
        let off = AttitudeSmoother::new(AttitudeSmoothing {
            enabled: false,
            ..AttitudeSmoothing::default()
        });
        assert_eq!(off.update(0.0, q0).0.update(0.033, q1).1, q1);
        let on = AttitudeSmoother::new(AttitudeSmoothing::default());
        let after_first = on.update(0.0, q0).0;
        assert_ne!(after_first.update(0.033, q1).1, q1);
        assert_eq!(after_first.update(2.0, q1).1, q1, "gap restarts");
        assert_eq!(
            after_first.update(-1.0, q1).1,
            q1,
            "time going back restarts"
        );
        assert_eq!(after_first.update(f64::NAN, q1).1, q1);
    }

    #[test]
    fn the_adaptive_threshold_snaps_where_the_noise_is_low() {
        // Noise-free hover: the running RMS is tiny, so a 0.3 deg step (below the fixed
        // 1 deg) is a real motion and is taken at once; with the fixed threshold alone it
        // is smoothed.
        let level = UnitQuaternion::from_euler_angles(1.0, 0.0, 0.0);
        let step = level * UnitQuaternion::from_euler_angles(0.0, 0.3f64.to_radians(), 0.0);
        let run = |params: AttitudeSmoothing| {
            let mut f = AttitudeSmoother::new(params);
            for i in 0..60 {
                let q = level
                    * UnitQuaternion::from_euler_angles(
                        0.0,
                        0.0,
                        0.01f64.to_radians() * noise(i, 0),
                    );
                f = f.update(i as f64 / 30.0, q).0;
            }
            f.update(2.0, step).1
        };
        let adaptive = run(AttitudeSmoothing::default());
        assert_eq!(adaptive, step);
        let fixed = run(AttitudeSmoothing {
            snap_rms_factor: 0.0,
            ..AttitudeSmoothing::default()
        });
        assert!(deg(&fixed, &step) > 0.05);
    }

    #[test]
    fn validation_names_the_bad_parameter() {
        assert_eq!(AttitudeSmoothing::default().invalid(), None);
        let bad = |f: fn(&mut AttitudeSmoothing)| {
            let mut p = AttitudeSmoothing::default();
            f(&mut p);
            p.invalid().map(|(name, _)| name)
        };
        assert_eq!(bad(|p| p.alpha = 0.0), Some("alpha"));
        assert_eq!(bad(|p| p.beta = f64::NAN), Some("beta"));
        assert_eq!(bad(|p| p.snap_deg = -1.0), Some("snap_deg"));
        assert_eq!(
            bad(|p| p.snap_rms_factor = f64::INFINITY),
            Some("snap_rms_factor")
        );
        assert_eq!(bad(|p| p.max_gap_s = 0.0), Some("max_gap_s"));
    }

    proptest! {
        /// Whatever the measurements, the output is a unit quaternion within the snap
        /// threshold of the measurement (the filter never drifts away from the sensor).
        #[test]
        fn output_stays_within_the_snap_threshold_of_the_measurement(
            steps in prop::collection::vec((0.001f64..0.2, -0.05f64..0.05, -0.05f64..0.05, -0.05f64..0.05), 1..80),
            rms_factor in prop::sample::select(vec![0.0, 4.0]),
        ) {
            let params = AttitudeSmoothing { snap_rms_factor: rms_factor, ..AttitudeSmoothing::default() };
            let mut f = AttitudeSmoother::new(params);
            let mut t = 0.0;
            let mut q = UnitQuaternion::from_euler_angles(1.0, 0.0, 0.5);
            for (dt, a, b, c) in steps {
                t += dt;
                q *= UnitQuaternion::from_scaled_axis(Vector3::new(a, b, c));
                let (next, out) = f.update(t, q);
                f = next;
                prop_assert!((out.norm() - 1.0).abs() < 1e-9);
                prop_assert!(out.angle_to(&q) <= params.snap_deg.to_radians() * (1.0 - params.alpha) + 1e-9);
            }
        }
    }
}
