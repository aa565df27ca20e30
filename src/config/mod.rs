//! The runtime configuration: one TOML file (`systemd/mgmot.example.toml` documents every key).
//!
//! Two layers, as in ripgrep's flags (low-level arguments, then high-level settings):
//!
//! - the TOML layer, one struct per section ([`MavlinkConfig`], [`FramesConfig`], ...) in its
//!   own file with its defaults and docs; parsing rejects unknown keys (the parser's error names
//!   the line and the key);
//! - the settings layer, [`Settings`]: what the runtime consumes, typed (durations, parsed pixel
//!   formats, the signing key's bytes, the detector's settings), produced once by
//!   [`Config::validate`], which collects every [`Problem`] under its dotted key instead of
//!   stopping at the first.

mod camera;
mod cot;
mod detector;
mod frames;
mod geolocation;
mod mavlink;
mod outputs;
mod problems;
mod recording;
mod telemetry;
#[cfg(test)]
mod tests;

pub use camera::{CameraConfig, CameraSettings};
pub use cot::{CotConfig, CotEndpoint, CotSettings, CotTlsConfig, CotTypes};
pub use detector::{
    DetectorConfig, DetectorSettings, OnnxDetectorConfig, OnnxSettings, TileChoice,
};
pub use frames::{FrameSettings, FramesConfig, ReconnectDelays};
pub use geolocation::{GeolocationConfig, GeolocationSettings, DEFAULT_MAX_RANGE_M};
pub use mavlink::{MavlinkConfig, MavlinkSettings, SigningConfig, SigningSettings};
pub use outputs::{OutputSettings, OutputsConfig};
pub use problems::{Problem, Problems};
pub use recording::{RecordingConfig, RecordingSettings};
pub use telemetry::{
    GimbalReport, PlausibilityConfig, TelemetryConfig, TelemetrySettings, GNSS_ACCURACY_MAX_AGE_MS,
};

use crate::track::TrackerParams;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Why a configuration cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    /// The file cannot be read.
    #[error("{path}: {source}")]
    Read {
        /// The file.
        path: PathBuf,
        /// The IO error.
        source: std::io::Error,
    },
    /// Not valid TOML, an unknown key, or a value of the wrong type.
    #[error("{path}: {message}")]
    Parse {
        /// The file.
        path: PathBuf,
        /// The parser's message (with line, column and key).
        message: String,
    },
    /// Values that parse but cannot work.
    #[error("{path}: {}", .problems.iter().map(ToString::to_string).collect::<Vec<_>>().join("; "))]
    Invalid {
        /// The file.
        path: PathBuf,
        /// Every problem found.
        problems: Vec<Problem>,
    },
}

/// The whole configuration file (the TOML layer).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Config {
    /// The MAVLink link to the autopilot (or mavlink-router).
    pub mavlink: MavlinkConfig,
    /// How telemetry is turned into a camera pose per frame.
    #[serde(default)]
    pub telemetry: TelemetryConfig,
    /// Where frames come from.
    pub frames: FramesConfig,
    /// The camera's optics.
    #[serde(default)]
    pub camera: CameraConfig,
    /// What finds objects in frames.
    pub detector: DetectorConfig,
    /// Geolocation noise model and limits.
    #[serde(default)]
    pub geolocation: GeolocationConfig,
    /// What is sent, and how often.
    #[serde(default)]
    pub outputs: OutputsConfig,
    /// The flight record (off unless `recording.dir` is set).
    #[serde(default)]
    pub recording: RecordingConfig,
    /// Tracker parameters (the paper's values by default).
    #[serde(default)]
    pub tracker: TrackerParams,
}

/// The validated configuration, typed for its consumers (the settings layer).
#[derive(Debug, Clone, PartialEq)]
pub struct Settings {
    /// The MAVLink link.
    pub mavlink: MavlinkSettings,
    /// Telemetry -> camera pose.
    pub telemetry: TelemetrySettings,
    /// The frame source.
    pub frames: FrameSettings,
    /// The camera's optics.
    pub camera: CameraSettings,
    /// The detector.
    pub detector: DetectorSettings,
    /// Geolocation.
    pub geolocation: GeolocationSettings,
    /// Outputs and their periods.
    pub outputs: OutputSettings,
    /// The flight record; `None`: off.
    pub recording: Option<RecordingSettings>,
    /// Tracker parameters (checked by [`TrackerParams::validate`]).
    pub tracker: TrackerParams,
}

impl Config {
    /// Reads, parses and validates a file: the configuration as written, and its settings.
    pub fn load(path: &Path) -> Result<(Config, Settings), ConfigError> {
        let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Read {
            path: path.to_owned(),
            source,
        })?;
        let config = Config::parse(&text).map_err(|message| ConfigError::Parse {
            path: path.to_owned(),
            message,
        })?;
        let settings = config.validate().map_err(|problems| ConfigError::Invalid {
            path: path.to_owned(),
            problems,
        })?;
        Ok((config, settings))
    }

    /// Parses TOML text (no validation).
    pub fn parse(text: &str) -> Result<Config, String> {
        toml::from_str(text).map_err(|e| e.to_string())
    }

    /// The typed settings, or every problem with the values, each naming its dotted key (in
    /// the order of the sections: mavlink, telemetry, frames, detector, camera, geolocation,
    /// outputs, recording, tracker).
    pub fn validate(&self) -> Result<Settings, Vec<Problem>> {
        let mut problems = Problems::default();
        let p = &mut problems;
        let mavlink = self.mavlink.validate(p);
        let telemetry = self.telemetry.validate(p);
        let frames = self.frames.validate(p);
        let detector = self.detector.validate(p);
        let camera = self.camera.validate(p);
        let geolocation = self.geolocation.validate(p);
        let outputs = self.outputs.validate(p);
        let recording = self.recording.validate(p);
        if let Err(e) = self.tracker.validate() {
            p.push("tracker", e.to_string());
        }
        match (
            mavlink,
            telemetry,
            frames,
            detector,
            camera,
            geolocation,
            outputs,
            recording,
        ) {
            (
                Some(mavlink),
                Some(telemetry),
                Some(frames),
                Some(detector),
                Some(camera),
                Some(geolocation),
                Some(outputs),
                Some(recording),
            ) if problems.is_empty() => Ok(Settings {
                mavlink,
                telemetry,
                frames,
                camera,
                detector,
                geolocation,
                outputs,
                recording,
                tracker: self.tracker.clone(),
            }),
            _ => Err(problems.into_vec()),
        }
    }
}
