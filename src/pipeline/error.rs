//! Why the runtime stopped with an error.

use super::detect_stage::DetectStageError;
use crate::mavlink::link::LinkError;

/// Why the runtime stopped with an error.
#[derive(Debug, thiserror::Error)]
pub enum PipelineError {
    /// The MAVLink link could not be set up (bad connection string, unusable signing state).
    #[error("MAVLink link: {0}")]
    Link(#[from] LinkError),
    /// The frame source cannot be used (an image directory that is missing or empty).
    #[error(transparent)]
    Frames(#[from] crate::camera::CameraError),
    /// The detector could not be set up.
    #[error(transparent)]
    Detector(#[from] DetectStageError),
    /// The tracker parameters are invalid.
    #[error("tracker: {0}")]
    Tracker(String),
    /// A configuration this version cannot run yet.
    #[error("{0} is not implemented in this version")]
    Unsupported(&'static str),
    /// A thread of the pipeline panicked.
    #[error("the {0} thread panicked")]
    Panicked(&'static str),
}
