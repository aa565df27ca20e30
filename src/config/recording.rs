//! `[recording]`: the flight record (`mgmot::record`): where, how large, keyframes.

use super::problems::Problems;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;
use std::time::Duration;

/// Flight recording. Off unless `dir` is set.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RecordingConfig {
    /// Folder that holds one sub-folder per flight (created if missing). Unset: no recording.
    pub dir: Option<PathBuf>,
    /// Cap on all flights in `dir` together (MB): the oldest flights are deleted to stay
    /// under it; a single flight that outgrows it stops recording. 0: no cap.
    pub max_total_mb: u64,
    /// A downscaled JPEG of the frame every this many seconds, and at every new track id.
    /// 0: no keyframes.
    pub keyframe_every_s: f64,
    /// Width of the keyframes (px; the height follows the frame's aspect).
    pub keyframe_width_px: u32,
    /// Records waiting for the disk; beyond this they are dropped and counted (never the
    /// frames or the MAVLink traffic).
    pub queue: usize,
}

impl Default for RecordingConfig {
    fn default() -> Self {
        Self {
            dir: None,
            max_total_mb: 4096,
            keyframe_every_s: 10.0,
            keyframe_width_px: 640,
            queue: 4096,
        }
    }
}

/// The validated recording settings.
#[derive(Debug, Clone, PartialEq)]
pub struct RecordingSettings {
    /// Folder of the flights.
    pub dir: PathBuf,
    /// Cap on all flights together (bytes); `None`: no cap.
    pub max_total_bytes: Option<u64>,
    /// Keyframe period; `None`: no keyframes.
    pub keyframe_every: Option<Duration>,
    /// Keyframe width (px).
    pub keyframe_width_px: u32,
    /// Queue length (records).
    pub queue: usize,
}

impl RecordingConfig {
    /// `Some(Some(settings))` when recording is on, `Some(None)` when it is off, `None` with
    /// the section's problems pushed onto `p`.
    pub fn validate(&self, p: &mut Problems) -> Option<Option<RecordingSettings>> {
        let every = self.keyframe_every_s;
        let keyframe_every = p.check(
            every.is_finite() && (every == 0.0 || (0.5..=3600.0).contains(&every)),
            "recording.keyframe_every_s",
            "must be 0 (no keyframes) or 0.5..=3600 seconds",
            every,
        );
        let width = p.check(
            (64..=4096).contains(&self.keyframe_width_px),
            "recording.keyframe_width_px",
            "must be 64..=4096 pixels",
            self.keyframe_width_px,
        );
        let queue = p.check(
            (16..=1_000_000).contains(&self.queue),
            "recording.queue",
            "must be 16..=1000000 records",
            self.queue,
        );
        let max_mb = p.check(
            self.max_total_mb == 0 || self.max_total_mb >= 16,
            "recording.max_total_mb",
            "must be 0 (no cap) or at least 16 MB",
            self.max_total_mb,
        );
        let dir = match &self.dir {
            Some(d) if d.as_os_str().is_empty() => {
                p.push(
                    "recording.dir",
                    "must not be empty (leave it out to record nothing)",
                );
                None
            }
            d => Some(d.clone()),
        };
        let (every, width, queue, max_mb, dir) = (keyframe_every?, width?, queue?, max_mb?, dir?);
        Some(dir.map(|dir| RecordingSettings {
            dir,
            max_total_bytes: (max_mb > 0).then(|| max_mb.saturating_mul(1 << 20)),
            keyframe_every: (every > 0.0).then(|| Duration::from_secs_f64(every)),
            keyframe_width_px: width,
            queue,
        }))
    }
}
