//! The telemetry the link's updates build up (pose buffer, clock mapping, home), shared between
//! the link's receive task and the frame step, and the one question the frame step asks of
//! it: where was the camera when this frame was exposed?

use crate::camera::CaptureTime;
use crate::config::{GimbalReport, TelemetrySettings, GNSS_ACCURACY_MAX_AGE_MS};
use crate::geo::attitude::GimbalYawFrame;
use crate::geo::{FrameMetadata, Geodetic};
use crate::mavlink::TelemetryUpdate;
use crate::telemetry::{
    AutopilotTimeUs, ClockSync, CompanionTimeUs, GimbalSample, Implausible, NoPose, PoseBuffer,
    PoseGate, StampVerdict,
};
use nalgebra::UnitQuaternion;

/// An episode of implausible telemetry ends when nothing was refused for this long (µs).
pub(super) const PLAUSIBLE_AGAIN_AFTER_US: u64 = 5_000_000;

/// What the link's telemetry has told so far.
#[derive(Debug)]
pub(super) struct TelemetryState {
    poses: PoseBuffer,
    clock: ClockSync,
    /// Reboots of the autopilot already acted on (the pose history and gate reset).
    reboots_seen: u64,
    /// Refuses samples that cannot be true (`telemetry.plausibility`).
    gate: PoseGate,
    /// The latest refusal: when (companion) and why.
    last_refusal: Option<(CompanionTimeUs, Implausible)>,
    home: Option<Geodetic>,
    /// Companion time of the latest position fix (for "telemetry lost").
    last_position_at: Option<CompanionTimeUs>,
    /// `telemetry.water_level_amsl_m`: the sea surface's altitude, when configured (else the
    /// home altitude).
    water_level_amsl_m: Option<f64>,
    /// `telemetry.camera_latency_ms`: exposure happens this long before the frame's stamp.
    camera_latency_us: u64,
    /// `telemetry.gimbal_report`: what the gimbal's reports mean.
    gimbal_report: GimbalReport,
    /// `telemetry.gnss_accuracy`: the receiver's horizontal accuracy is the position noise.
    use_gnss_accuracy: bool,
    /// The latest GNSS horizontal accuracy (m) and when it arrived.
    gnss_accuracy: Option<(CompanionTimeUs, f64)>,
}

/// What telemetry refused or saw, for the run's counters.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct TelemetryCounters {
    /// Samples the plausibility gate refused.
    pub implausible: u64,
    /// Stamps neither on the autopilot's current timeline nor a confirmed reboot (delayed,
    /// replayed, stray, forged): their messages were not used.
    pub stale_stamps: u64,
    /// Autopilot reboots confirmed.
    pub autopilot_reboots: u64,
}

/// A frame's pose, as far as telemetry knows it.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct FramePose {
    /// The exposure time on the autopilot clock (`None`: the clock mapping is not known yet).
    pub frame_time: Option<AutopilotTimeUs>,
    /// The capture time on the companion clock, when it maps onto it (latency histograms).
    pub captured_at: Option<CompanionTimeUs>,
    /// The camera's metadata for geolocation; `Err` says why there is none.
    pub meta: Result<FrameMetadata, String>,
    /// The sea surface's altitude AMSL, when known.
    pub water_amsl_m: Option<f64>,
}

impl TelemetryState {
    /// Nothing heard yet.
    pub fn new(t: &TelemetrySettings) -> Self {
        let mut poses = PoseBuffer::new(micros(t.max_pose_age));
        if let Some(pitch) = t.fixed_mount_pitch_deg {
            poses = poses.with_fixed_mount(UnitQuaternion::from_euler_angles(
                0.0,
                pitch.to_radians(),
                0.0,
            ));
        }
        Self {
            poses,
            clock: ClockSync::new(),
            reboots_seen: 0,
            gate: PoseGate::new(t.plausibility),
            last_refusal: None,
            home: None,
            last_position_at: None,
            water_level_amsl_m: t.water_level_amsl_m,
            camera_latency_us: micros(t.camera_latency),
            gimbal_report: t.gimbal_report,
            use_gnss_accuracy: t.gnss_accuracy,
            gnss_accuracy: None,
        }
    }

    /// Takes one update from the link. Stamps that are neither current nor a reboot are not
    /// used ([`StampVerdict::Stale`]); a confirmed reboot voids the pose history; samples the
    /// plausibility gate refuses never reach the pose buffer.
    pub fn apply(&mut self, update: TelemetryUpdate) {
        match update {
            TelemetryUpdate::Position { fix, at } => {
                if self.stamp(fix.sample.time, at) == StampVerdict::Stale {
                    return;
                }
                let water = self.water_level_amsl_m;
                match self.gate.check_position(&fix, self.home.as_ref(), water) {
                    Ok(()) => {
                        self.poses.push_position(fix.sample);
                        self.last_position_at = Some(at);
                    }
                    Err(why) => self.last_refusal = Some((at, why)),
                }
            }
            TelemetryUpdate::Attitude { sample, at } => {
                if self.stamp(sample.time, at) != StampVerdict::Stale {
                    self.poses.push_attitude(sample);
                }
            }
            TelemetryUpdate::Gimbal {
                sample,
                quaternion_norm,
                at,
            } => {
                if let Some(Err(why)) = quaternion_norm.map(|n| self.gate.check_quaternion_norm(n))
                {
                    self.last_refusal = Some((at, why));
                    return;
                }
                self.poses.push_gimbal(self.as_mounted(sample));
            }
            TelemetryUpdate::GimbalAtArrival { mut sample, at } => {
                if let Some(time) = self.clock.to_autopilot(at) {
                    sample.time = time;
                    self.poses.push_gimbal(self.as_mounted(sample));
                }
            }
            TelemetryUpdate::Home(h) => self.home = Some(h),
            TelemetryUpdate::GnssAccuracy { h_acc_m, at } => {
                // A receiver's estimate; beyond 10 km it says nothing a fix could be used for.
                if h_acc_m.is_finite() && h_acc_m > 0.0 && h_acc_m <= 10_000.0 {
                    self.gnss_accuracy = Some((at, h_acc_m));
                }
            }
            TelemetryUpdate::TimeSync {
                sent,
                autopilot,
                at,
            } => {
                // Returns the round trip, or None for an inconsistent answer (ignored).
                let _ = self.clock.observe_timesync(sent, autopilot, at);
                self.follow_reboots();
            }
        }
    }

    /// The clock's verdict on a stamped message; a confirmed reboot is acted on.
    fn stamp(&mut self, time: AutopilotTimeUs, at: CompanionTimeUs) -> StampVerdict {
        let verdict = self.clock.observe_arrival(time, at);
        self.follow_reboots();
        verdict
    }

    /// After a reboot the clock confirmed (by any message), the pose history and the gate's
    /// reference are on the old clock: both start again.
    fn follow_reboots(&mut self) {
        let reboots = self.clock.resets();
        if reboots != self.reboots_seen {
            self.reboots_seen = reboots;
            self.poses.clear();
            self.gate.reset();
        }
    }

    /// Whether telemetry has been plausible for [`PLAUSIBLE_AGAIN_AFTER_US`] before `now`,
    /// and if not, why the latest sample was refused.
    pub fn plausibility(&self, now: CompanionTimeUs) -> (bool, Option<Implausible>) {
        match self.last_refusal {
            Some((at, why)) if now.0.saturating_sub(at.0) < PLAUSIBLE_AGAIN_AFTER_US => {
                (false, Some(why))
            }
            _ => (true, None),
        }
    }

    /// Telemetry counters: samples refused as implausible, stamps ignored as stale (neither
    /// current nor a reboot) and autopilot reboots.
    pub fn counters(&self) -> TelemetryCounters {
        TelemetryCounters {
            implausible: self.gate.refused(),
            stale_stamps: self.clock.stale_stamps(),
            autopilot_reboots: self.clock.resets(),
        }
    }

    /// A gimbal report read as `telemetry.gimbal_report` says.
    fn as_mounted(&self, mut g: GimbalSample) -> GimbalSample {
        if self.gimbal_report == GimbalReport::ServoBodyFrame {
            g.frame = GimbalYawFrame::Body;
        }
        g
    }

    /// The receiver's horizontal accuracy for a frame captured at `captured` (companion
    /// clock): the latest report, when `telemetry.gnss_accuracy` is on and it arrived within
    /// [`GNSS_ACCURACY_MAX_AGE_MS`] of the capture.
    fn gnss_accuracy_at(&self, captured: Option<CompanionTimeUs>) -> Option<f64> {
        let (at, h_acc_m) = self.gnss_accuracy.filter(|_| self.use_gnss_accuracy)?;
        let age_us = captured?.0.abs_diff(at.0);
        (age_us <= GNSS_ACCURACY_MAX_AGE_MS * 1000).then_some(h_acc_m)
    }

    /// When the latest position fix arrived.
    pub fn last_position_at(&self) -> Option<CompanionTimeUs> {
        self.last_position_at
    }

    /// The pose at a frame's exposure: its capture time on both clocks (minus the camera's
    /// latency), the camera pose interpolated there and the water level.
    pub fn at_capture(&self, captured: CaptureTime) -> FramePose {
        let captured_at = match captured {
            CaptureTime::Autopilot(a) => self.clock.to_companion(a),
            CaptureTime::Companion(c) => Some(c),
        };
        let frame_time = match captured {
            CaptureTime::Autopilot(a) => Some(a),
            CaptureTime::Companion(c) => self.clock.to_autopilot(c),
        }
        .map(|a| a.saturating_sub_us(self.camera_latency_us));
        let water_amsl_m = self.water_level_amsl_m.or(self.home.map(|h| h.alt_m));
        let meta = match (frame_time.map(|t| self.poses.pose_at(t)), water_amsl_m) {
            (None, _) => Err("autopilot clock not known yet".to_owned()),
            (Some(Err(e)), _) => Err(NoPose::to_string(&e)),
            (Some(Ok(_)), None) => Err("water level unknown (no HOME_POSITION)".to_owned()),
            (Some(Ok(p)), Some(water)) => Ok(FrameMetadata {
                position: p.position,
                height_above_sea_m: p.position.alt_m - water,
                camera_attitude: p.camera_attitude,
                horizontal_accuracy_m: self.gnss_accuracy_at(captured_at),
            }),
        };
        FramePose {
            frame_time,
            captured_at,
            meta,
            water_amsl_m,
        }
    }
}

fn micros(d: std::time::Duration) -> u64 {
    u64::try_from(d.as_micros()).unwrap_or(u64::MAX)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::{Problems, TelemetryConfig};

    fn state(gnss_accuracy: bool) -> TelemetryState {
        let config = TelemetryConfig {
            gnss_accuracy,
            ..TelemetryConfig::default()
        };
        let settings = config.validate(&mut Problems::default()).unwrap();
        TelemetryState::new(&settings)
    }

    /// The latest plausible `h_acc` describes frames captured within
    /// [`GNSS_ACCURACY_MAX_AGE_MS`] of its arrival, and none with `telemetry.gnss_accuracy`
    /// off; values a receiver cannot mean are not taken.
    #[test]
    fn the_receivers_accuracy_describes_frames_near_its_arrival() {
        let at = CompanionTimeUs(100_000_000);
        let within = CompanionTimeUs(at.0 + GNSS_ACCURACY_MAX_AGE_MS * 1000);
        let beyond = CompanionTimeUs(within.0 + 1);
        let mut s = state(true);
        assert_eq!(s.gnss_accuracy_at(Some(at)), None);
        s.apply(TelemetryUpdate::GnssAccuracy { h_acc_m: 1.5, at });
        assert_eq!(s.gnss_accuracy_at(Some(within)), Some(1.5));
        assert_eq!(
            s.gnss_accuracy_at(Some(CompanionTimeUs(at.0 - 1000))),
            Some(1.5)
        );
        assert_eq!(s.gnss_accuracy_at(Some(beyond)), None);
        assert_eq!(s.gnss_accuracy_at(None), None);
        for nonsense in [0.0, -1.0, f64::NAN, f64::INFINITY, 20_000.0] {
            s.apply(TelemetryUpdate::GnssAccuracy {
                h_acc_m: nonsense,
                at,
            });
            assert_eq!(s.gnss_accuracy_at(Some(at)), Some(1.5), "{nonsense}");
        }
        let mut off = state(false);
        off.apply(TelemetryUpdate::GnssAccuracy { h_acc_m: 1.5, at });
        assert_eq!(off.gnss_accuracy_at(Some(at)), None);
    }
}
