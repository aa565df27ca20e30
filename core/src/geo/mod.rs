//! Geometry: the camera model of the MG-MOT paper (Sec. 3.1) and the frames around it.
//!
//! Pure and synchronous: no IO, no global state. Conventions (those of the project's design
//! notes, stated here in full):
//!
//! - **World**: local NED metres ([`LocalTangentFrame`]) around a reference origin; WGS84
//!   ([`Geodetic`]) only at the edges. The sea surface is the plane `down = SeaPlane::down_m`.
//! - **Camera**: OpenCV optical frame (x right, y down, z forward). A [`CameraPose`]'s attitude
//!   rotates camera-frame vectors into NED.
//! - **Image**: continuous pixel coordinates with (0, 0) at the top-left corner of the image,
//!   so a box `(x, y, w, h)` has its centre at `(x + w/2, y + h/2)`.
//!
//! The paper's equations map to: Eq. 1 [`Intrinsics::from_hfov`], Eq. 2
//! [`attitude::camera_from_heading_pitch_deg`], Eq. 3 [`CameraModel::pixel_to_ray`],
//! Eq. 4 [`CameraModel::project_to_sea`].

pub mod attitude;
mod camera;
mod circular_error;
mod geolocate;
mod smoothing;
mod uncertainty;
mod view;
mod wgs84;

pub use camera::{
    sea_plane_homography, CameraModel, CameraPose, Distortion, Intrinsics, Pixel, SeaPlane,
};
pub use circular_error::circular_error_m;
pub use geolocate::{FrameGeometry, FrameMetadata, Geolocation, Geolocator};
pub use smoothing::{AttitudeSmoother, AttitudeSmoothing};
pub use uncertainty::{geolocation_covariance, PoseNoise};
pub use view::CameraView;
pub use wgs84::{Geodetic, LocalTangentFrame};

/// Why a geometric computation has no answer. Never NaN, never a point behind the camera.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GeoError {
    /// The viewing ray points at or above the horizon, so it never meets the sea.
    #[error(
        "ray at or above the horizon (depression {depression_deg:.3} deg): it never meets the sea"
    )]
    AboveHorizon {
        /// Angle of the ray below the horizontal plane; <= 0 means at or above the horizon.
        depression_deg: f64,
    },
    /// The camera is at or below the sea surface, so no downward ray can meet it in front.
    #[error("camera is not above the sea surface (height {height_m:.3} m)")]
    CameraBelowSea {
        /// Height of the camera above the sea plane (<= 0 here).
        height_m: f64,
    },
    /// The world point lies behind the image plane and has no pixel.
    #[error("point is behind the camera")]
    BehindCamera,
    /// The sea point is farther than the configured limit of the flat-sea model.
    #[error("sea point is {range_m:.0} m from the camera, beyond the {max_range_m:.0} m limit")]
    BeyondMaxRange {
        /// Distance from the camera to the intersection.
        range_m: f64,
        /// The configured limit.
        max_range_m: f64,
    },
    /// A parameter is out of its valid range or not finite.
    #[error("invalid {what}: {value}")]
    InvalidParameter {
        /// Which parameter.
        what: &'static str,
        /// Its value.
        value: f64,
    },
    /// Iterative point undistortion did not converge (the point is far outside the calibrated area).
    #[error("point undistortion did not converge")]
    UndistortionDiverged,
    /// The requested mapping is singular (e.g. a camera lying in the sea plane).
    #[error("degenerate geometry: {0}")]
    Degenerate(&'static str),
}

/// Checks that `value` is finite, returning [`GeoError::InvalidParameter`] otherwise.
pub(crate) fn finite(what: &'static str, value: f64) -> Result<f64, GeoError> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(GeoError::InvalidParameter { what, value })
    }
}
