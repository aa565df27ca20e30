//! `[telemetry]`: how telemetry is turned into a camera pose per frame.

use super::problems::{millis, Problems};
use crate::telemetry::PlausibilityLimits;
use serde::{Deserialize, Serialize};
use std::time::Duration;

/// Telemetry -> camera pose.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TelemetryConfig {
    /// A frame whose nearest sample of any needed stream is further than this from its
    /// capture time gets no pose (no geolocation) rather than a stale one (ms).
    pub max_pose_age_ms: f64,
    /// Delay from the real exposure to the frame's timestamp (ms); the pose is taken at
    /// `timestamp - camera_latency_ms`.
    pub camera_latency_ms: f64,
    /// Water surface altitude AMSL (m); absent: the home position is at the waterline.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub water_level_amsl_m: Option<f64>,
    /// Telemetry is reported lost (STATUSTEXT) when no position arrives for this long (ms).
    pub lost_after_ms: f64,
    /// Camera hard-mounted to the body instead of on a gimbal: its pitch (deg, negative =
    /// down) relative to the body; absent: the gimbal's telemetry is used.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fixed_mount_pitch_deg: Option<f64>,
    /// What the gimbal's attitude report means: `as_flagged` (a gimbal reporting its own
    /// attitude, read as its flags say) or `servo_body_frame` (ArduPilot's servo mount,
    /// `MNT1_TYPE 1`: the servo angles relative to the vehicle body, whatever the flags say).
    pub gimbal_report: GimbalReport,
    /// `[telemetry.plausibility]`: what the vehicle can do; samples beyond it are refused.
    pub plausibility: PlausibilityConfig,
    /// Use the GNSS receiver's own horizontal accuracy (GPS_RAW_INT `h_acc`, when the
    /// autopilot reports it with a fix, no older than [`GNSS_ACCURACY_MAX_AGE_MS`]) as the
    /// drone position's noise in each frame's geolocation covariance, instead of
    /// `geolocation.noise.horizontal_position_std_m` (which stays the fallback).
    pub gnss_accuracy: bool,
}

/// GPS_RAW_INT's `h_acc` describes frames captured at most this long from its arrival (ms).
pub const GNSS_ACCURACY_MAX_AGE_MS: u64 = 5_000;

/// `[telemetry.plausibility]`: telemetry that cannot be true is refused (counted, reported to
/// the operator once per episode) and never moves a track. See `mgmot_core::telemetry`'s
/// `PoseGate`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PlausibilityConfig {
    /// Fastest horizontal speed of the vehicle (m/s).
    pub max_speed_mps: f64,
    /// Fastest climb or descent (m/s).
    pub max_vertical_speed_mps: f64,
    /// Largest acceleration (m/s²), between reported velocities.
    pub max_accel_mps2: f64,
    /// Furthest the vehicle flies from home (m).
    pub max_distance_from_home_m: f64,
    /// Lowest height above the sea surface (m; negative: below it, for GNSS altitude error).
    pub min_height_above_water_m: f64,
    /// Highest height above home (m).
    pub max_height_above_home_m: f64,
}

impl Default for PlausibilityConfig {
    fn default() -> Self {
        let d = PlausibilityLimits::default();
        Self {
            max_speed_mps: d.max_speed_mps,
            max_vertical_speed_mps: d.max_vertical_speed_mps,
            max_accel_mps2: d.max_accel_mps2,
            max_distance_from_home_m: d.max_distance_from_home_m,
            min_height_above_water_m: d.min_height_above_water_m,
            max_height_above_home_m: d.max_height_above_home_m,
        }
    }
}

impl PlausibilityConfig {
    fn validate(&self, p: &mut Problems) -> Option<PlausibilityLimits> {
        let key = |k: &str| format!("telemetry.plausibility.{k}");
        let max_speed_mps = p.within_open(&key("max_speed_mps"), self.max_speed_mps, 0.0, 1000.0);
        let max_vertical_speed_mps = p.within_open(
            &key("max_vertical_speed_mps"),
            self.max_vertical_speed_mps,
            0.0,
            1000.0,
        );
        let max_accel_mps2 =
            p.within_open(&key("max_accel_mps2"), self.max_accel_mps2, 0.0, 1000.0);
        let max_distance_from_home_m = p.within_open(
            &key("max_distance_from_home_m"),
            self.max_distance_from_home_m,
            0.0,
            20_000_000.0,
        );
        let min_height_above_water_m = p.within_closed(
            &key("min_height_above_water_m"),
            self.min_height_above_water_m,
            -1000.0,
            0.0,
        );
        let max_height_above_home_m = p.within_open(
            &key("max_height_above_home_m"),
            self.max_height_above_home_m,
            0.0,
            20_000.0,
        );
        Some(PlausibilityLimits {
            max_speed_mps: max_speed_mps?,
            max_vertical_speed_mps: max_vertical_speed_mps?,
            max_accel_mps2: max_accel_mps2?,
            max_distance_from_home_m: max_distance_from_home_m?,
            min_height_above_water_m: min_height_above_water_m?,
            max_height_above_home_m: max_height_above_home_m?,
        })
    }
}

/// What a gimbal attitude report (GIMBAL_DEVICE_ATTITUDE_STATUS, MOUNT_STATUS) means.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum GimbalReport {
    /// As its flags say: roll and pitch relative to the horizon, yaw relative to north or to
    /// the vehicle's heading (a MAVLink gimbal, ArduPilot's brushless mounts).
    #[default]
    AsFlagged,
    /// Relative to the vehicle body on all three axes. ArduPilot's servo mount (upstream
    /// 90700977c5, `AP_Mount_Servo::get_attitude_quaternion`) reports the servo angles after
    /// its own lean compensation, under flags that claim earth-frame roll and pitch: read as
    /// flagged, a leaning vehicle moves every position by metres.
    ServoBodyFrame,
}

impl Default for TelemetryConfig {
    fn default() -> Self {
        Self {
            max_pose_age_ms: 200.0,
            camera_latency_ms: 0.0,
            water_level_amsl_m: None,
            lost_after_ms: 2000.0,
            fixed_mount_pitch_deg: None,
            gimbal_report: GimbalReport::AsFlagged,
            plausibility: PlausibilityConfig::default(),
            gnss_accuracy: true,
        }
    }
}

/// The validated telemetry settings.
#[derive(Debug, Clone, PartialEq)]
pub struct TelemetrySettings {
    /// Oldest usable sample, relative to a frame's capture time (> 0, at most 60 s).
    pub max_pose_age: Duration,
    /// Delay from the real exposure to the frame's timestamp (at most 10 s).
    pub camera_latency: Duration,
    /// Water surface altitude AMSL (m, -500..=9000); `None`: the home position's.
    pub water_level_amsl_m: Option<f64>,
    /// Telemetry is reported lost after this long without a position (> 0, at most 1 h).
    pub lost_after: Duration,
    /// Pitch of a hard-mounted camera (deg, -90..=90); `None`: on a gimbal.
    pub fixed_mount_pitch_deg: Option<f64>,
    /// What the gimbal's attitude report means.
    pub gimbal_report: GimbalReport,
    /// What the vehicle can do: samples beyond it are refused.
    pub plausibility: PlausibilityLimits,
    /// Whether the receiver's reported horizontal accuracy is the position noise.
    pub gnss_accuracy: bool,
}

impl TelemetryConfig {
    /// The telemetry settings, or the section's problems pushed onto `p`.
    pub fn validate(&self, p: &mut Problems) -> Option<TelemetrySettings> {
        let max_pose_age = p
            .within_open(
                "telemetry.max_pose_age_ms",
                self.max_pose_age_ms,
                0.0,
                60_000.0,
            )
            .and_then(|ms| millis(p, "telemetry.max_pose_age_ms", ms));
        let camera_latency = p
            .within_closed(
                "telemetry.camera_latency_ms",
                self.camera_latency_ms,
                0.0,
                10_000.0,
            )
            .and_then(|ms| millis(p, "telemetry.camera_latency_ms", ms));
        let lost_after = p
            .within_open(
                "telemetry.lost_after_ms",
                self.lost_after_ms,
                0.0,
                3_600_000.0,
            )
            .and_then(|ms| millis(p, "telemetry.lost_after_ms", ms));
        // The Dead Sea shore to far above any sea.
        let water_level_amsl_m = match self.water_level_amsl_m {
            Some(v) => p
                .within_closed("telemetry.water_level_amsl_m", v, -500.0, 9000.0)
                .map(Some),
            None => Some(None),
        };
        let pitch = self.fixed_mount_pitch_deg;
        let fixed_mount_pitch_deg = p.check(
            pitch.is_none_or(|v| v.is_finite() && (-90.0..=90.0).contains(&v)),
            "telemetry.fixed_mount_pitch_deg",
            "must be in -90..=90",
            pitch,
        );
        let plausibility = self.plausibility.validate(p);
        Some(TelemetrySettings {
            plausibility: plausibility?,
            max_pose_age: max_pose_age?,
            camera_latency: camera_latency?,
            water_level_amsl_m: water_level_amsl_m?,
            lost_after: lost_after?,
            fixed_mount_pitch_deg: fixed_mount_pitch_deg?,
            gimbal_report: self.gimbal_report,
            gnss_accuracy: self.gnss_accuracy,
        })
    }
}
