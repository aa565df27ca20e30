//! The counters of one run.

use super::latency::LatencyReport;
use crate::mavlink::LinkStats;

/// Counters and latency percentiles of one run, logged and returned at the end (`mgmot run
/// --stats-json` writes them).
#[derive(Debug, Default, Clone, PartialEq, Eq, serde::Serialize)]
pub struct RunStats {
    /// Frames the source delivered.
    pub frames_captured: u64,
    /// Frames overwritten in the newest-frame slot before inference took them.
    pub frames_dropped: u64,
    /// Frames through detector and tracker.
    pub frames_processed: u64,
    /// Frames processed without a usable pose (tracked in the image only).
    pub frames_without_pose: u64,
    /// MGMOT_TRACK messages queued.
    pub track_messages: u64,
    /// Outgoing messages dropped because the link queue was full.
    pub messages_dropped: u64,
    /// Frames the detector failed on (reported by STATUSTEXT when it starts and stops failing).
    pub detector_errors: u64,
    /// Frames the tracker rejected.
    pub tracker_errors: u64,
    /// Jumps of the frame source's clock the tracker's clock bridged (an autopilot reboot, a
    /// restarted camera or simulator, the clock mapping found mid-flight).
    pub clock_jumps: u64,
    /// What telemetry refused or saw (implausible samples, stale stamps, reboots).
    pub telemetry: super::telemetry::TelemetryCounters,
    /// From the first frame taken by inference to the end of the last one processed (µs):
    /// `frames_processed / active_us` is the sustained rate.
    pub active_us: u64,
    /// Per-stage latency percentiles over the whole run (see [`super::latency`]).
    pub latency: LatencyReport,
    /// The MAVLink link's counters (frames, refusals, reconnects, stream requests).
    pub link: LinkStats,
    /// How the ONNX detector's (backend, model) pair was chosen: each candidate's measured
    /// time under `backend = "auto"` or with `alternatives`, and the choice (absent for the
    /// replay detector).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub detector: Option<crate::detect::Selection>,
    /// The Cursor-on-Target output's counters (absent when `[outputs.cot]` is off).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cot: Option<super::cot_step::CotCounters>,
}
