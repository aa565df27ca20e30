//! Flight recording (`[recording]`): one folder per flight with the MAVLink traffic
//! (`flight.tlog`), the per-frame record (`frames.ndjson`: times, pose, detections, tracks,
//! merges), the effective configuration and the detector's identity, written off the frame
//! path ([`Recorder`]) and read back by `mgmot replay` and `mgmot review` ([`Flight`]).

pub mod flight;
pub mod format;
mod keyframe;
mod recorder;
pub mod tlog;

pub use flight::Flight;
pub use keyframe::KeyframeImage;
pub use recorder::{unix_us_now, Announce, Closed, RecordSink, Recorder, RETRY_EVERY};

use std::path::PathBuf;

/// Why a flight cannot be recorded or read.
#[derive(Debug, thiserror::Error)]
pub enum RecordError {
    /// A file or folder cannot be created, written or read.
    #[error("{path}: {source}")]
    Io {
        /// The file or folder.
        path: PathBuf,
        /// The IO error.
        source: std::io::Error,
    },
    /// A file is not what mgmot writes.
    #[error("{path}: {message}")]
    Format {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
}
