//! `[geolocation]`: the noise model of the position uncertainty, and the range limit.

use super::problems::Problems;
use crate::geo::PoseNoise;
use serde::{Deserialize, Serialize};

/// Default limit on the camera-to-sea distance (m), the geolocator's own default: beyond about
/// 10 km the flat-sea model and realistic attitude accuracy give no usable position.
pub const DEFAULT_MAX_RANGE_M: f64 = 10_000.0;

/// Geolocation.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct GeolocationConfig {
    /// Noise of the pose and the boxes, for the position uncertainty.
    pub noise: PoseNoise,
    /// Points further than this from the camera are not geolocated (m).
    pub max_range_m: f64,
}

impl Default for GeolocationConfig {
    fn default() -> Self {
        Self {
            noise: PoseNoise::default(),
            max_range_m: DEFAULT_MAX_RANGE_M,
        }
    }
}

/// The validated geolocation settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GeolocationSettings {
    /// Noise figures, each finite and bounded (attitude at most 90 deg, the others 1000).
    pub noise: PoseNoise,
    /// Range limit (m, in (0, 100 km]).
    pub max_range_m: f64,
}

impl GeolocationConfig {
    /// The geolocation settings, or the section's problems pushed onto `p`.
    pub fn validate(&self, p: &mut Problems) -> Option<GeolocationSettings> {
        let max_range_m =
            p.within_open("geolocation.max_range_m", self.max_range_m, 0.0, 100_000.0);
        let n = &self.noise;
        let mut noise_ok = true;
        for (key, v, hi) in [
            (
                "geolocation.noise.attitude_std_deg",
                n.attitude_std_deg,
                90.0,
            ),
            ("geolocation.noise.altitude_std_m", n.altitude_std_m, 1000.0),
            ("geolocation.noise.pixel_std_px", n.pixel_std_px, 1000.0),
            (
                "geolocation.noise.horizontal_position_std_m",
                n.horizontal_position_std_m,
                1000.0,
            ),
        ] {
            noise_ok &= p.within_closed(key, v, 0.0, hi).is_some();
        }
        Some(GeolocationSettings {
            noise: noise_ok.then_some(self.noise)?,
            max_range_m: max_range_m?,
        })
    }
}
