//! First-order propagation of pose and pixel noise into the horizontal position of a sea point.

use super::camera::{ray_to_sea, CameraModel, CameraPose, Pixel, SeaPlane};
use super::GeoError;
use nalgebra::{Matrix2, UnitQuaternion, Vector2, Vector3};
use serde::{Deserialize, Serialize};

/// One-sigma noise of the inputs to geolocation.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PoseNoise {
    /// Camera attitude noise about each axis (deg). A stabilised gimbal's reported angles are
    /// typically good to about a degree once mounting and time alignment are included.
    pub attitude_std_deg: f64,
    /// Height-above-sea noise (m): barometric / takeoff-relative altitude drifts by about this.
    pub altitude_std_m: f64,
    /// Pixel noise of the box's reference point (px): detector box jitter.
    pub pixel_std_px: f64,
    /// Horizontal GNSS noise of the drone's position (m), added to each axis; a frame whose
    /// [`super::FrameMetadata::horizontal_accuracy_m`] is known uses that instead.
    pub horizontal_position_std_m: f64,
}

impl Default for PoseNoise {
    fn default() -> Self {
        Self {
            attitude_std_deg: 1.0,
            altitude_std_m: 0.5,
            pixel_std_px: 2.0,
            horizontal_position_std_m: 1.0,
        }
    }
}

/// Finite-difference steps: small enough for the first-order model, large enough for f64.
const ROTATION_STEP_RAD: f64 = 1e-6;
const ALTITUDE_STEP_M: f64 = 1e-4;
const PIXEL_STEP_PX: f64 = 1e-3;

/// Horizontal (north, east) covariance (m^2) of the sea point seen at `px`, propagated to
/// first order from [`PoseNoise`] by central differences: attitude about the north, east and
/// down axes, height above sea, pixel u and v, plus the GNSS horizontal noise.
pub fn geolocation_covariance(
    model: &CameraModel,
    pose: &CameraPose,
    sea: &SeaPlane,
    px: Pixel,
    noise: &PoseNoise,
) -> Result<Matrix2<f64>, GeoError> {
    let ray_cam = model.pixel_to_ray(px)?;
    let locate = |pose: &CameraPose, ray_cam: &Vector3<f64>| -> Result<Vector2<f64>, GeoError> {
        Ok(ray_to_sea(pose, sea, &(pose.attitude * ray_cam))?.xy())
    };
    let mut cov = Matrix2::identity() * noise.horizontal_position_std_m.powi(2);
    let mut add = |plus: Vector2<f64>, minus: Vector2<f64>, step: f64, sigma: f64| {
        let column = (plus - minus) / (2.0 * step) * sigma;
        cov += column * column.transpose();
    };
    let att_sigma = noise.attitude_std_deg.to_radians();
    for axis in [Vector3::x_axis(), Vector3::y_axis(), Vector3::z_axis()] {
        let perturbed = |sign: f64| CameraPose {
            attitude: UnitQuaternion::from_axis_angle(&axis, sign * ROTATION_STEP_RAD)
                * pose.attitude,
            ..*pose
        };
        add(
            locate(&perturbed(1.0), &ray_cam)?,
            locate(&perturbed(-1.0), &ray_cam)?,
            ROTATION_STEP_RAD,
            att_sigma,
        );
    }
    let raised = |dz: f64| CameraPose {
        position_ned: pose.position_ned - Vector3::new(0.0, 0.0, dz),
        ..*pose
    };
    add(
        locate(&raised(ALTITUDE_STEP_M), &ray_cam)?,
        locate(&raised(-ALTITUDE_STEP_M), &ray_cam)?,
        ALTITUDE_STEP_M,
        noise.altitude_std_m,
    );
    for (du, dv) in [(PIXEL_STEP_PX, 0.0), (0.0, PIXEL_STEP_PX)] {
        let plus = model.pixel_to_ray(Pixel::new(px.u + du, px.v + dv))?;
        let minus = model.pixel_to_ray(Pixel::new(px.u - du, px.v - dv))?;
        add(
            locate(pose, &plus)?,
            locate(pose, &minus)?,
            PIXEL_STEP_PX,
            noise.pixel_std_px,
        );
    }
    Ok(cov)
}

#[cfg(test)]
mod tests {
    use super::super::attitude::camera_from_heading_pitch_deg;
    use super::*;

    fn nadir(h: f64) -> CameraPose {
        CameraPose {
            position_ned: Vector3::new(0.0, 0.0, -h),
            attitude: camera_from_heading_pitch_deg(0.0, 90.0, 0.0),
        }
    }

    #[test]
    fn nadir_closed_form() {
        // At nadir, centre pixel: d(pos)/d(angle) = h per radian for both tilt axes, height has
        // no effect, a pixel moves the point by h / f.
        let cam = CameraModel::from_hfov(1000, 1000, 90.0).unwrap();
        let h = 100.0;
        let noise = PoseNoise {
            attitude_std_deg: 1.0,
            altitude_std_m: 3.0,
            pixel_std_px: 2.0,
            horizontal_position_std_m: 0.5,
        };
        let cov = geolocation_covariance(
            &cam,
            &nadir(h),
            &SeaPlane::default(),
            Pixel::new(500.0, 500.0),
            &noise,
        )
        .unwrap();
        let f = 500.0;
        let expected = (h * 1f64.to_radians()).powi(2) + (h / f * 2.0).powi(2) + 0.25;
        assert!((cov[(0, 0)] - expected).abs() < 1e-4 * expected, "{cov}");
        assert!((cov[(1, 1)] - expected).abs() < 1e-4 * expected, "{cov}");
        assert!(cov[(0, 1)].abs() < 1e-6);
    }

    #[test]
    fn oblique_view_is_longer_along_the_line_of_sight() {
        let cam = CameraModel::from_hfov(1280, 720, 70.0).unwrap();
        let pose = CameraPose {
            position_ned: Vector3::new(0.0, 0.0, -30.0),
            attitude: camera_from_heading_pitch_deg(0.0, 20.0, 0.0),
        };
        let cov = geolocation_covariance(
            &cam,
            &pose,
            &SeaPlane::default(),
            Pixel::new(640.0, 360.0),
            &PoseNoise::default(),
        )
        .unwrap();
        assert!(cov[(0, 0)] > 4.0 * cov[(1, 1)], "{cov}");
        assert!(cov.symmetric_eigenvalues().iter().all(|&e| e > 0.0));
    }
}
