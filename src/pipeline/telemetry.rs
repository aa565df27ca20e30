//! The telemetry the link's updates build up (pose buffer, clock mapping, home), shared between
//! the link's receive task and the frame step, and the one question the frame step asks of
//! it: where was the camera when this frame was exposed?

use crate::camera::CaptureTime;
use crate::config::{GimbalReport, TelemetrySettings};
use crate::geo::attitude::GimbalYawFrame;
use crate::geo::{FrameMetadata, Geodetic};
use crate::mavlink::TelemetryUpdate;
use crate::telemetry::{
    AutopilotTimeUs, ClockSync, CompanionTimeUs, GimbalSample, NoPose, PoseBuffer,
};
use nalgebra::UnitQuaternion;

/// What the link's telemetry has told so far.
#[derive(Debug)]
pub(super) struct TelemetryState {
    poses: PoseBuffer,
    clock: ClockSync,
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
            home: None,
            last_position_at: None,
            water_level_amsl_m: t.water_level_amsl_m,
            camera_latency_us: micros(t.camera_latency),
            gimbal_report: t.gimbal_report,
        }
    }

    /// Takes one update from the link.
    pub fn apply(&mut self, update: TelemetryUpdate) {
        match update {
            TelemetryUpdate::Position { sample, at } => {
                self.clock.observe_arrival(sample.time, at);
                self.poses.push_position(sample);
                self.last_position_at = Some(at);
            }
            TelemetryUpdate::Attitude { sample, at } => {
                self.clock.observe_arrival(sample.time, at);
                self.poses.push_attitude(sample);
            }
            TelemetryUpdate::Gimbal(g) => self.poses.push_gimbal(self.as_mounted(g)),
            TelemetryUpdate::GimbalAtArrival { mut sample, at } => {
                if let Some(time) = self.clock.to_autopilot(at) {
                    sample.time = time;
                    self.poses.push_gimbal(self.as_mounted(sample));
                }
            }
            TelemetryUpdate::Home(h) => self.home = Some(h),
            TelemetryUpdate::TimeSync {
                sent,
                autopilot,
                at,
            } => {
                // Returns the round trip, or None for an inconsistent answer (ignored).
                let _ = self.clock.observe_timesync(sent, autopilot, at);
            }
        }
    }

    /// A gimbal report read as `telemetry.gimbal_report` says.
    fn as_mounted(&self, mut g: GimbalSample) -> GimbalSample {
        if self.gimbal_report == GimbalReport::ServoBodyFrame {
            g.frame = GimbalYawFrame::Body;
        }
        g
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
