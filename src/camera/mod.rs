//! Frame sources. Each delivers [`Frame`]s (RGB24) with a capture timestamp.
//!
//! Status: the simulator's Unix-socket stream is implemented ([`SimSocketSource`]); the image
//! directory and V4L2 sources are not written yet.

mod sim_socket;

pub use sim_socket::{SimFramingError, SimSocketSource, SIM_HEADER_LEN};

use crate::telemetry::{AutopilotTimeUs, CompanionTimeUs};

/// When a frame was captured, on whichever clock its source stamps.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CaptureTime {
    /// The companion's monotonic clock (V4L2 buffer timestamps).
    Companion(CompanionTimeUs),
    /// The autopilot's clock (the simulator stamps frames with its `time_boot`).
    Autopilot(AutopilotTimeUs),
}

/// One captured frame.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Frame {
    /// Index from the source (0-based; gaps mean frames the source dropped).
    pub index: u64,
    /// Capture time.
    pub captured: CaptureTime,
    /// Width (px).
    pub width_px: u32,
    /// Height (px).
    pub height_px: u32,
    /// Packed RGB24, rows not padded: `width_px * height_px * 3` bytes.
    pub rgb: Vec<u8>,
}
