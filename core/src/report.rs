//! What the runtime reports about its tracks: one report per track and frame, and the status
//! of the track an operator selected. Plain values; the MAVLink edge encodes them.

use crate::frame::GeoFix;
use crate::telemetry::AutopilotTimeUs;
use crate::track::{BBox, TrackOutput, TrackState};

/// One confirmed track as the outputs report it (MGMOT_TRACK, TARGET_ABSOLUTE).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackReport {
    /// Capture time of the frame the state belongs to.
    pub time: AutopilotTimeUs,
    /// Track id.
    pub track_id: u64,
    /// The id a re-identified track had before it was merged into this one, in this frame.
    pub merged_from_id: Option<u64>,
    /// Class id (SeaDronesSee numbering).
    pub class_id: u32,
    /// Detector confidence (0..1).
    pub confidence: f32,
    /// Box (x, y, w, h) as fractions of the image size.
    pub bbox_norm: [f32; 4],
    /// Matched in this frame (`false`: predicted, the track is lost for now).
    pub tracked: bool,
    /// Geolocation, when the frame had a usable pose.
    pub geo: Option<GeoFix>,
    /// The track's ReID decision is pending and it may still become an older track
    /// ([`TrackOutput::provisional`]).
    pub provisional: bool,
}

/// How the operator selected the tracked target; the image status reports it the same way.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TrackingMode {
    /// By a point: reported as the box centre and a radius.
    Point,
    /// By a rectangle: reported as the box.
    Rectangle,
}

/// The operator-selected track, for CAMERA_TRACKING_IMAGE_STATUS and
/// CAMERA_TRACKING_GEO_STATUS.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackingStatus {
    /// How it was selected.
    pub mode: TrackingMode,
    /// Box (x, y, w, h) as fractions of the image size.
    pub bbox_norm: [f32; 4],
    /// Image width / height, to express the point radius as a fraction of the width.
    pub aspect: f32,
    /// Not detected in the latest frame: box and position are the filters' predictions.
    pub coasting: bool,
    /// Geolocation, when the frame had a usable pose.
    pub geo: Option<GeoFix>,
    /// Standard deviation of the velocity (m/s), per axis (the root mean of the north and
    /// east variances); `None` when unknown.
    pub vel_std_mps: Option<f64>,
    /// Distance from the camera to the object (m); `None` when unknown.
    pub range_m: Option<f64>,
}

/// A box (x, y, w, h) in pixels as fractions of the image size.
pub fn normalised_box(b: &BBox, (width_px, height_px): (u32, u32)) -> [f32; 4] {
    let (w, h) = (f64::from(width_px), f64::from(height_px));
    [
        (b.x / w) as f32,
        (b.y / h) as f32,
        (b.w / w) as f32,
        (b.h / h) as f32,
    ]
}

impl TrackReport {
    /// The report of a tracker output `t` in a frame of `image_size_px` captured at `time`.
    pub fn new(
        time: AutopilotTimeUs,
        t: &TrackOutput,
        image_size_px: (u32, u32),
        merged_from_id: Option<u64>,
        geo: Option<GeoFix>,
    ) -> Self {
        Self {
            time,
            track_id: t.id,
            merged_from_id,
            class_id: t.class_id,
            confidence: t.score,
            bbox_norm: normalised_box(&t.bbox, image_size_px),
            tracked: t.detection_index.is_some(),
            geo,
            provisional: t.provisional,
        }
    }
}

impl TrackingStatus {
    /// The status of the selected track `t`; `geo` is its fix (when the frame had a pose) and
    /// `range_m` its distance from the camera.
    pub fn new(
        mode: TrackingMode,
        t: &TrackOutput,
        image_size_px: (u32, u32),
        geo: Option<GeoFix>,
        range_m: Option<f64>,
    ) -> Self {
        Self {
            mode,
            bbox_norm: normalised_box(&t.bbox, image_size_px),
            aspect: (f64::from(image_size_px.0) / f64::from(image_size_px.1)) as f32,
            coasting: t.state != TrackState::Confirmed || t.detection_index.is_none(),
            vel_std_mps: geo.and(t.world).map(|ws| {
                let (vn, ve) = (ws.cov[(2, 2)], ws.cov[(3, 3)]);
                ((vn + ve) / 2.0).max(0.0).sqrt()
            }),
            geo,
            range_m,
        }
    }
}
