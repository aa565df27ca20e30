//! `[outputs]`: what is sent to the autopilot and GCS, and how often.

use super::cot::{CotConfig, CotSettings};
use super::problems::{period, Problems};
use crate::digest::DigestSettings;
use crate::operator::DEFAULT_POINT_RADIUS;
use serde::{Deserialize, Serialize};
use std::time::Duration;

/// Outputs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct OutputsConfig {
    /// MGMOT_TRACK messages per confirmed track per second.
    pub track_rate_hz: f64,
    /// Also send TARGET_ABSOLUTE for each geolocated track.
    pub target_absolute: bool,
    /// HEARTBEATs per second.
    pub heartbeat_hz: f64,
    /// CAMERA_TRACKING_IMAGE_STATUS + CAMERA_TRACKING_GEO_STATUS per second while an operator
    /// has selected a track (MAV_CMD_CAMERA_TRACK_POINT / _RECTANGLE).
    pub camera_tracking_hz: f64,
    /// How far from a track's box a MAV_CMD_CAMERA_TRACK_POINT may land and still select it,
    /// as a fraction of the image width, when the command's own radius (param 3) is 0.
    pub track_point_radius: f64,
    /// For a ground station that only hears the autopilot's telemetry radio (which forwards
    /// no MGMOT_TRACK): a STATUSTEXT per newly found object with its position, and every this
    /// many seconds a count by class with the latest positions. 0 turns the digest off.
    pub radio_digest_every_s: f64,
    /// Positions listed in each periodic digest (the most recently seen tracks).
    pub radio_digest_positions: usize,
    /// CAMERA_FOV_STATUS per second: the camera's position, attitude and fields of view, from
    /// which a ground station (QGroundControl's camera view, `mgmot ground`'s map) draws the
    /// footprint on the sea. 0 turns it off.
    pub camera_fov_hz: f64,
    /// Cursor-on-Target events for TAK maps (`[outputs.cot]`, off by default).
    pub cot: CotConfig,
}

impl Default for OutputsConfig {
    fn default() -> Self {
        Self {
            track_rate_hz: 2.0,
            target_absolute: true,
            heartbeat_hz: 1.0,
            camera_tracking_hz: 5.0,
            track_point_radius: DEFAULT_POINT_RADIUS,
            radio_digest_every_s: 15.0,
            radio_digest_positions: 3,
            camera_fov_hz: 1.0,
            cot: CotConfig::default(),
        }
    }
}

/// The validated output settings: rates as the periods the senders wait.
#[derive(Debug, Clone, PartialEq)]
pub struct OutputSettings {
    /// Between two MGMOT_TRACK messages of one track (at least 10 ms).
    pub track_every: Duration,
    /// Also send TARGET_ABSOLUTE.
    pub target_absolute: bool,
    /// Between two HEARTBEATs (0.1 s to 5 s).
    pub heartbeat_every: Duration,
    /// Between two camera-tracking status pairs (at least 10 ms).
    pub camera_tracking_every: Duration,
    /// Selection radius of MAV_CMD_CAMERA_TRACK_POINT (fraction of the image width, 0..=1).
    pub track_point_radius: f64,
    /// The STATUSTEXT digest of the tracks; `None`: off.
    pub radio_digest: Option<DigestSettings>,
    /// Between two CAMERA_FOV_STATUS messages; `None`: off.
    pub camera_fov_every: Option<Duration>,
    /// Cursor-on-Target events; `None`: off.
    pub cot: Option<CotSettings>,
}

impl OutputsConfig {
    /// The output settings, or the section's problems pushed onto `p`.
    pub fn validate(&self, p: &mut Problems) -> Option<OutputSettings> {
        const TRACK: &str = "outputs.track_rate_hz";
        const HEARTBEAT: &str = "outputs.heartbeat_hz";
        const CAMERA_TRACKING: &str = "outputs.camera_tracking_hz";
        let track_every = p
            .within_open(TRACK, self.track_rate_hz, 0.0, 100.0)
            .and_then(|hz| period(p, TRACK, hz));
        // MAVLink components send HEARTBEAT at about 1 Hz; a GCS counts one silent for 3-5 s
        // as gone.
        let heartbeat_every = p
            .within_closed(HEARTBEAT, self.heartbeat_hz, 0.2, 10.0)
            .and_then(|hz| period(p, HEARTBEAT, hz));
        let camera_tracking_every = p
            .within_open(CAMERA_TRACKING, self.camera_tracking_hz, 0.0, 100.0)
            .and_then(|hz| period(p, CAMERA_TRACKING, hz));
        let radius = self.track_point_radius;
        let track_point_radius = p.check(
            radius.is_finite() && (0.0..=1.0).contains(&radius),
            "outputs.track_point_radius",
            "must be in 0..=1 (a fraction of the image width)",
            radius,
        );
        const DIGEST: &str = "outputs.radio_digest_every_s";
        let every = self.radio_digest_every_s;
        let radio_digest = p
            .check(
                every.is_finite() && (every == 0.0 || (1.0..=3600.0).contains(&every)),
                DIGEST,
                "must be 0 (off) or 1..=3600 seconds",
                every,
            )
            .map(|every| {
                (every > 0.0).then_some(DigestSettings {
                    every_us: (every * 1e6) as u64,
                    max_positions: self.radio_digest_positions,
                })
            });
        let positions = p.check(
            self.radio_digest_positions <= 20,
            "outputs.radio_digest_positions",
            "must be at most 20 (each is one STATUSTEXT on the radio)",
            self.radio_digest_positions,
        );
        const FOV: &str = "outputs.camera_fov_hz";
        let camera_fov_every = p
            .check(
                self.camera_fov_hz.is_finite() && (0.0..=50.0).contains(&self.camera_fov_hz),
                FOV,
                "must be 0 (off) to 50 per second",
                self.camera_fov_hz,
            )
            .map(|hz| (hz > 0.0).then(|| Duration::from_secs_f64(1.0 / hz)));
        let cot = self.cot.validate(p);
        Some(OutputSettings {
            track_every: track_every?,
            target_absolute: self.target_absolute,
            heartbeat_every: heartbeat_every?,
            camera_tracking_every: camera_tracking_every?,
            track_point_radius: track_point_radius?,
            radio_digest: positions.and(radio_digest)?,
            camera_fov_every: camera_fov_every?,
            cot: cot?,
        })
    }
}
