//! Frame sources. Each delivers [`Frame`]s (RGB24) with a capture timestamp through the
//! [`FrameSource`] trait:
//!
//! - [`V4l2Source`]: a V4L2 capture device (MJPG, YUYV or NV12, mmap streaming, kernel buffer
//!   timestamps on `CLOCK_MONOTONIC`), decoded to RGB by [`decode`].
//! - [`SimSocketSource`]: the simulator's Unix-socket stream ([`sim_framing`]).
//! - [`ImageDirectory`]: image files of a directory in name order, paced at a nominal rate.
//!
//! Losing a source and getting it back is the capture loop's business
//! (`pipeline::capture`), driven by the pure [`Reconnect`] state machine.

pub mod decode;
mod images;
mod reconnect;
pub use mgmot_wire::sim_framing;
mod sim_socket;
mod v4l2;

pub use decode::{DecodeError, FrameLayout, PixelFormat, YuvMatrix, YuvRange};
pub use images::{FrameClock, ImageDirectory, MonotonicClock};
pub use reconnect::{Backoff, CameraStatus, Reconnect};
pub use sim_socket::{read_sim_frame, SimFramingError, SimSocketSource};
pub use v4l2::{V4l2Settings, V4l2Source};

use crate::telemetry::{AutopilotTimeUs, CompanionTimeUs};
use std::path::PathBuf;

/// Header length of the simulator's frame stream in bytes.
pub const SIM_HEADER_LEN: usize = sim_framing::HEADER_LEN;

/// When a frame was captured, on whichever clock its source stamps.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CaptureTime {
    /// The companion's monotonic clock (`CLOCK_MONOTONIC`, as V4L2 buffer timestamps).
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

/// A source of frames, opened by its own constructor.
pub trait FrameSource: Send {
    /// Blocks until the next frame. `Ok(None)` when the source has ended for good (the
    /// simulator finished, the last image of a directory was shown). An error with
    /// [`CameraError::is_frame_error`] spoils one frame only; any other error means the source
    /// is lost and must be reopened.
    fn next_frame(&mut self) -> Result<Option<Frame>, CameraError>;
}

impl<S: FrameSource + ?Sized> FrameSource for Box<S> {
    fn next_frame(&mut self) -> Result<Option<Frame>, CameraError> {
        (**self).next_frame()
    }
}

/// What went wrong with a frame source. Every variant names the device, socket or file.
#[derive(Debug, thiserror::Error)]
pub enum CameraError {
    /// A V4L2 call failed (`ENOENT` at open: no such node; `ENODEV`: unplugged).
    #[error("{}: {action}: {source}", device.display())]
    Device {
        /// The device node.
        device: PathBuf,
        /// What was being done, e.g. `VIDIOC_DQBUF`.
        action: &'static str,
        /// The OS error.
        source: std::io::Error,
    },
    /// The device works but cannot give what the configuration asks for.
    #[error("{}: {problem}", device.display())]
    Unsupported {
        /// The device node.
        device: PathBuf,
        /// What it cannot do.
        problem: String,
    },
    /// One buffer could not be decoded (the next may be fine).
    #[error("{}: frame {index}: {source}", device.display())]
    Decode {
        /// The device node.
        device: PathBuf,
        /// The frame's index.
        index: u64,
        /// The decoder's error.
        source: DecodeError,
    },
    /// The driver flagged one buffer as bad (the next may be fine).
    #[error("{}: frame {index}: {problem}", device.display())]
    Buffer {
        /// The device node.
        device: PathBuf,
        /// The frame's index.
        index: u64,
        /// What is wrong.
        problem: String,
    },
    /// The simulator's stream failed.
    #[error(transparent)]
    Sim(#[from] SimFramingError),
    /// The image directory cannot be listed or has no images.
    #[error("{}: {problem}", directory.display())]
    Directory {
        /// The directory.
        directory: PathBuf,
        /// What is wrong.
        problem: String,
    },
    /// One image file could not be read or decoded (the next may be fine).
    #[error("{}: {problem}", path.display())]
    Image {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        problem: String,
    },
}

impl CameraError {
    /// True when the source is there but this user may not open it.
    pub fn is_permission_denied(&self) -> bool {
        let io = match self {
            CameraError::Device { source, .. } => source,
            CameraError::Sim(SimFramingError::Io { source, .. }) => source,
            _ => return false,
        };
        io.kind() == std::io::ErrorKind::PermissionDenied
    }

    /// True when only one frame is spoiled and the source can go on.
    pub fn is_frame_error(&self) -> bool {
        matches!(
            self,
            CameraError::Decode { .. } | CameraError::Buffer { .. } | CameraError::Image { .. }
        )
    }
}
