//! `[camera]`: the camera's optics.

use super::problems::Problems;
use serde::{Deserialize, Serialize};

/// The camera's optics.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CameraConfig {
    /// Horizontal field of view (deg), for an ideal pinhole with the principal point at the
    /// centre.
    pub hfov_deg: f64,
}

impl Default for CameraConfig {
    fn default() -> Self {
        Self { hfov_deg: 70.0 }
    }
}

/// The validated optics.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraSettings {
    /// Horizontal field of view (deg, in (0, 180)).
    pub hfov_deg: f64,
}

impl CameraConfig {
    /// The optics, or the section's problem pushed onto `p`.
    pub fn validate(&self, p: &mut Problems) -> Option<CameraSettings> {
        let hfov_deg = self.hfov_deg;
        p.check(
            hfov_deg.is_finite() && hfov_deg > 0.0 && hfov_deg < 180.0,
            "camera.hfov_deg",
            "must be in (0, 180)",
            CameraSettings { hfov_deg },
        )
    }
}
