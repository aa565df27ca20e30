//! Camera attitude: unit quaternions that rotate camera-frame vectors (OpenCV optical frame)
//! into local NED, built from the attitude sources a drone provides.
//!
//! A gimbal reports the attitude of its FRD frame (x forward along the lens, y right, z down).
//! The optical frame differs from FRD by a fixed axis permutation ([`optical_to_frd`]).

use nalgebra::{Matrix3, Rotation3, UnitQuaternion};
use serde::{Deserialize, Serialize};

/// Rotation taking optical-frame vectors (x right, y down, z forward) to the gimbal's FRD frame.
pub fn optical_to_frd() -> UnitQuaternion<f64> {
    // Columns: optical x -> FRD y (right), optical y -> FRD z (down), optical z -> FRD x (forward).
    let m = Matrix3::new(0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0);
    UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(m))
}

/// Camera attitude from aerospace yaw / pitch / roll of the gimbal's FRD frame (radians,
/// intrinsic Z-Y-X: yaw clockwise from north seen from above, pitch positive nose-up, roll
/// positive right-wing-down).
pub fn camera_from_ypr_rad(yaw_rad: f64, pitch_rad: f64, roll_rad: f64) -> UnitQuaternion<f64> {
    UnitQuaternion::from_euler_angles(roll_rad, pitch_rad, yaw_rad) * optical_to_frd()
}

/// Camera attitude in the SeaDronesSee metadata convention (paper Eq. 2, with the dataset's
/// angle reading): `heading_deg` is a compass bearing clockwise from north, `pitch_below_horizon_deg`
/// is the depression of the optical axis (90 = nadir), `roll_deg` is usually 0.
///
/// The paper writes the rotation with alpha = 90 deg - heading and beta = pitch in an ENU-like
/// world; in NED this is the same rotation expressed as yaw = heading, pitch = -depression.
pub fn camera_from_heading_pitch_deg(
    heading_deg: f64,
    pitch_below_horizon_deg: f64,
    roll_deg: f64,
) -> UnitQuaternion<f64> {
    camera_from_ypr_rad(
        heading_deg.to_radians(),
        -pitch_below_horizon_deg.to_radians(),
        roll_deg.to_radians(),
    )
}

/// Yaw, pitch and roll (radians, aerospace Z-Y-X of the FRD frame) of a camera attitude:
/// the inverse of [`camera_from_ypr_rad`] away from gimbal lock.
pub fn camera_to_ypr_rad(camera: &UnitQuaternion<f64>) -> (f64, f64, f64) {
    let frd = camera * optical_to_frd().inverse();
    let (roll, pitch, yaw) = frd.euler_angles();
    (yaw, pitch, roll)
}

/// How a gimbal quaternion (MAVLink gimbal protocol v2, `GIMBAL_DEVICE_ATTITUDE_STATUS.q`) is
/// referenced.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum GimbalYawFrame {
    /// Earth frame: the quaternion is the gimbal's attitude in NED (flag YAW_IN_EARTH_FRAME).
    Earth,
    /// Roll and pitch relative to the horizon, yaw relative to the vehicle's heading
    /// (flag YAW_IN_VEHICLE_FRAME): the vehicle's yaw is composed in.
    Vehicle,
    /// Fully body-referenced (e.g. a hard-mounted camera or MOUNT_ORIENTATION relative
    /// angles): the vehicle's whole attitude is composed in.
    Body,
}

/// Gimbal FRD attitude in NED from a gimbal quaternion and the vehicle attitude (FRD body to
/// NED, e.g. from `ATTITUDE` / `ATTITUDE_QUATERNION`).
pub fn gimbal_to_ned(
    q_gimbal: &UnitQuaternion<f64>,
    frame: GimbalYawFrame,
    vehicle_attitude: &UnitQuaternion<f64>,
) -> UnitQuaternion<f64> {
    match frame {
        GimbalYawFrame::Earth => *q_gimbal,
        GimbalYawFrame::Vehicle => {
            let (_, _, vehicle_yaw) = vehicle_attitude.euler_angles();
            UnitQuaternion::from_euler_angles(0.0, 0.0, vehicle_yaw) * q_gimbal
        }
        GimbalYawFrame::Body => vehicle_attitude * q_gimbal,
    }
}

/// Camera attitude (optical -> NED) from a gimbal quaternion (gimbal protocol v2) composed with
/// the vehicle attitude as its yaw frame requires.
pub fn camera_from_gimbal_quaternion(
    q_gimbal_frd: &UnitQuaternion<f64>,
    frame: GimbalYawFrame,
    vehicle_attitude: &UnitQuaternion<f64>,
) -> UnitQuaternion<f64> {
    gimbal_to_ned(q_gimbal_frd, frame, vehicle_attitude) * optical_to_frd()
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    fn close(a: Vector3<f64>, b: Vector3<f64>) -> bool {
        (a - b).norm() < 1e-9
    }

    #[test]
    fn level_camera_looking_north() {
        let q = camera_from_heading_pitch_deg(0.0, 0.0, 0.0);
        assert!(close(q * Vector3::z(), Vector3::new(1.0, 0.0, 0.0))); // forward = north
        assert!(close(q * Vector3::x(), Vector3::new(0.0, 1.0, 0.0))); // right = east
        assert!(close(q * Vector3::y(), Vector3::new(0.0, 0.0, 1.0))); // image down = down
    }

    #[test]
    fn nadir_camera_top_of_image_points_along_heading() {
        let q = camera_from_heading_pitch_deg(90.0, 90.0, 0.0);
        assert!(close(q * Vector3::z(), Vector3::new(0.0, 0.0, 1.0)));
        // Image "up" (-y) points along the heading (east).
        assert!(close(q * -Vector3::y(), Vector3::new(0.0, 1.0, 0.0)));
    }

    #[test]
    fn pitch_45_looks_down_at_45() {
        let q = camera_from_heading_pitch_deg(0.0, 45.0, 0.0);
        let f = q * Vector3::z();
        let s = std::f64::consts::FRAC_1_SQRT_2;
        assert!(close(f, Vector3::new(s, 0.0, s)));
    }

    #[test]
    fn ypr_round_trip() {
        let q = camera_from_ypr_rad(1.0, -0.7, 0.1);
        let (y, p, r) = camera_to_ypr_rad(&q);
        assert!((y - 1.0).abs() < 1e-9 && (p + 0.7).abs() < 1e-9 && (r - 0.1).abs() < 1e-9);
    }

    #[test]
    fn vehicle_frame_yaw_adds_vehicle_heading() {
        let vehicle = UnitQuaternion::from_euler_angles(0.05, -0.02, 1.2);
        let gimbal = UnitQuaternion::from_euler_angles(0.0, -0.5, 0.3);
        let cam = camera_from_gimbal_quaternion(&gimbal, GimbalYawFrame::Vehicle, &vehicle);
        let (y, p, _) = camera_to_ypr_rad(&cam);
        assert!((y - 1.5).abs() < 1e-9 && (p + 0.5).abs() < 1e-9);
        let earth = camera_from_gimbal_quaternion(&gimbal, GimbalYawFrame::Earth, &vehicle);
        let (y, _, _) = camera_to_ypr_rad(&earth);
        assert!((y - 0.3).abs() < 1e-9);
        let body = camera_from_gimbal_quaternion(&gimbal, GimbalYawFrame::Body, &vehicle);
        assert!(body.angle_to(&((vehicle * gimbal) * optical_to_frd())) < 1e-12);
    }
}
