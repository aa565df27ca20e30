//! Multi-object tracking: the BoT-SORT-style baseline and the MG-MOT metadata-guided
//! re-identification (paper Sec. 3.2 and 5.1), online and offline.
//!
//! Pure and synchronous: the caller does the geometry (`mgmot::geo`) and hands over plain
//! numbers per frame ([`FrameInput`]): boxes in pixels, optional sea-surface positions in the
//! sequence's local NED frame (north/east metres), and optionally the image homography from
//! the previous frame (camera-motion compensation). Without any metadata the tracker is the
//! plain BoT-SORT baseline (without appearance features).
//!
//! - Online: [`Tracker::step`] per frame returns the confirmed tracks; ReID links are
//!   decided once a new track has lived `w` frames and reported as [`MergeEvent`]s;
//!   [`Tracker::live_tracks`] lists every kept track with its [`TrackState`] (lost ones
//!   included); [`Tracker::finish`] decides the pending links at the end of a sequence.
//! - Both estimate the sea drift of the classes adrift from their own tracks ([`SeaDrift`]),
//!   which long-term ReID uses to carry a track across a gap of minutes.
//! - Offline: [`track_sequence`] runs the baseline over a whole sequence and then the paper's
//!   post-processing, interpolation -> ReID -> interpolation.
//! - The paper's equations: [`reid::extrapolate`] (Eq. 7),
//!   [`reid::extrapolate_bidirectional`] (BiME), [`reid::expanded_match_threshold`] (MTE,
//!   Eq. 9), [`reid::short_term_cost`] (Eq. 6); [`nms_prefer_larger`] (Sec. 5.1).

pub mod appearance;
pub(crate) mod assign;
mod bbox;
mod contact;
pub mod drift;
mod error;
mod kalman;
mod nms;
mod offline;
mod online;
mod params;
pub mod reid;
#[cfg(test)]
mod scenes;
mod types;
mod world;

pub use appearance::{Appearance, RgbImage};
pub use bbox::BBox;
pub use contact::ContactParams;
pub use drift::{DriftEstimate, DriftParams, SeaDrift};
pub use error::TrackError;
pub use kalman::BoxKalman;
pub use nms::nms_prefer_larger;
pub use offline::{track_sequence, SequenceFrame, SequenceResult, SequenceTrack};
pub use online::Tracker;
pub use params::{
    BaselineParams, ClassReidParams, LongTermGate, OfflineParams, ReidParams, TrackerParams,
};
pub use types::{
    Detection, ExchangeEvent, FrameInput, FrameOutput, MergeEvent, TrackOutput, TrackState,
};
pub use world::{WorldFilter, WorldObservation, WorldState};
