//! The errors of the tracking core.

/// Errors of the tracking core.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum TrackError {
    /// A parameter is out of range; `path` names it as in the config file.
    #[error("tracker parameter {path} must be {requirement}")]
    InvalidParam {
        /// Config path of the field, e.g. `reid.classes.2.tau_match_m`.
        path: String,
        /// What the value must satisfy.
        requirement: String,
    },
    /// Frames must come with strictly increasing frame numbers.
    #[error("frame {frame_index} arrived after frame {previous}: frame numbers must increase")]
    FrameOrder {
        /// The rejected frame.
        frame_index: u64,
        /// The frame processed before it.
        previous: u64,
    },
    /// Frame times must be finite and non-decreasing.
    #[error("frame {frame_index} has time {time_s} s: times must be finite and non-decreasing")]
    TimeOrder {
        /// The rejected frame.
        frame_index: u64,
        /// Its time, s.
        time_s: f64,
    },
}
