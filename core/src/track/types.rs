//! Plain data exchanged with the tracker: what the caller hands in per frame and what comes
//! back. The caller does all geometry (`mgmot::geo`); the tracker sees numbers only.

use nalgebra::Matrix3;
use serde::{Deserialize, Serialize};

use super::appearance::Appearance;
use super::bbox::BBox;
use super::world::{WorldObservation, WorldState};

/// One detector output.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Detection {
    /// Box in image pixels, top-left origin.
    pub bbox: BBox,
    /// Detector confidence in [0, 1].
    pub score: f32,
    /// Detector class id (SeaDronesSee: 1 swimmer, 2 boat, 3 jetski, 4 life-saving appliance,
    /// 5 buoy).
    pub class_id: u32,
    /// Sea-surface position of the box, when the frame has a camera pose. `None` (no
    /// metadata) still tracks, without world-distance ReID.
    pub world: Option<WorldObservation>,
    /// Colour signature of the box's pixels, when the caller had them (long-gap ReID's
    /// appearance gate, `reid.appearance_gate`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub appearance: Option<Appearance>,
}

/// Everything the tracker needs about one frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FrameInput {
    /// Frame number in the sequence; strictly increasing, gaps mean dropped frames (the
    /// image-plane Kalman filter predicts across them, the lost-track buffer counts them).
    pub frame_index: u64,
    /// Capture time, s, on one monotonic clock. ReID uses real time because frame rate is
    /// not constant and frames can be dropped.
    pub time_s: f64,
    /// Image width and height, px (decides whether a track left the view).
    pub image_size_px: (u32, u32),
    /// The detections of this frame.
    pub detections: Vec<Detection>,
    /// Homography mapping the pixels of the previous frame given to the tracker (dropped
    /// frames are skipped, not composed by the tracker) to this frame's: the sea-plane
    /// homography between the two camera poses. `None`: no camera-motion compensation, the
    /// plain baseline.
    pub image_motion: Option<Matrix3<f64>>,
}

/// Life-cycle state of a track (BoT-SORT's, with "unconfirmed" named Tentative).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum TrackState {
    /// Created from one detection, not yet matched a second time; never reported.
    Tentative,
    /// Matched in this frame and reported.
    Confirmed,
    /// Not matched recently; kept for the lost-track buffer so IoU matching can resume it.
    Lost,
    /// Finished; it may still be re-identified by the MG-MOT memory bank.
    Removed,
}

/// A reported track in one frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TrackOutput {
    /// Track id as reported now (after any online ReID re-label).
    pub id: u64,
    /// Kalman-filtered box, px.
    pub bbox: BBox,
    /// Confidence: the score of the detection matched in this frame.
    pub score: f32,
    /// Majority vote over the classes of all detections matched so far.
    pub class_id: u32,
    /// Track state: [`TrackState::Confirmed`] for a track matched in this frame,
    /// [`TrackState::Lost`] for one reported while coasting (`baseline.coast_frames`).
    pub state: TrackState,
    /// World position, velocity and covariance, when the track has had a world observation.
    pub world: Option<WorldState>,
    /// Index into [`FrameInput::detections`] of the detection matched in this frame. Set for
    /// the confirmed tracks of [`FrameOutput::tracks`]; `None` for coasting tracks there and
    /// for lost tracks from `Tracker::live_tracks`.
    pub detection_index: Option<usize>,
    /// The track is new and may still turn out to be a track the memory bank holds: its
    /// ReID decision is pending (it has lived fewer than `reid.window_frames` frames, or its
    /// best link is contested and it waits, see `reid.defer_margin_chi2`) and some ended
    /// track of its class is, or was at some frame since it started, within the ReID gate
    /// (once set, the flag holds until the decision). Its id may still change to the old
    /// one; an operator display should not show it as a new object yet.
    #[serde(default)]
    pub provisional: bool,
}

/// An online ReID decision: a new track turned out to be an old one.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct MergeEvent {
    /// The id the new track was reported under until now.
    pub new_id: u64,
    /// The old id it carries from now on.
    pub merged_into_id: u64,
    /// Frame in which the decision was taken.
    pub frame_index: u64,
}

/// A contact repair (see `[tracker.contact]`): two tracks had exchanged the objects they
/// follow while their boxes overlapped, and exchange them back in this frame. From
/// `since_frame_index` (the frame of the contact's largest overlap, where the swap most
/// likely happened) up to this frame each id followed the other's object; from this frame
/// on each follows its own. Online those frames were reported already; offline they are
/// relabelled.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct ExchangeEvent {
    /// One of the two ids.
    pub id: u64,
    /// The other.
    pub other_id: u64,
    /// The contact's frame of largest overlap: the swapped frames start here.
    pub since_frame_index: u64,
    /// Frame in which the repair was decided.
    pub frame_index: u64,
}

/// Result of one online tracker step.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct FrameOutput {
    /// Frame number of the input.
    pub frame_index: u64,
    /// Reported tracks with their current ids, ordered by id: the confirmed ones and the
    /// coasting ones (state [`TrackState::Lost`], see `baseline.coast_frames`).
    pub tracks: Vec<TrackOutput>,
    /// Re-labels decided in this frame.
    pub merges: Vec<MergeEvent>,
    /// Contact repairs decided in this frame.
    #[serde(default)]
    pub exchanges: Vec<ExchangeEvent>,
}
