//! Pinhole camera with optional Brown-Conrady distortion, and its relation to the sea plane.

use super::{finite, GeoError};
use nalgebra::{Matrix2, Matrix3, UnitQuaternion, Vector2, Vector3};
use serde::{Deserialize, Serialize};

/// Smallest depression (as the down component of a unit ray) that still counts as meeting the
/// sea: about 0.00006 deg. Anything flatter is treated as at the horizon.
const MIN_RAY_DOWN: f64 = 1e-6;
/// Smallest depth in front of the camera (m) that has a pixel.
const MIN_DEPTH_M: f64 = 1e-9;

/// A point in the image: continuous pixel coordinates, (0, 0) at the image's top-left corner.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Pixel {
    /// Column coordinate (px), growing to the right.
    pub u: f64,
    /// Row coordinate (px), growing downwards.
    pub v: f64,
}

impl Pixel {
    /// A pixel at `(u, v)`.
    pub fn new(u: f64, v: f64) -> Self {
        Self { u, v }
    }
}

/// Pinhole intrinsics (paper Eq. 1, with K\[2\]\[2\] = 1).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Intrinsics {
    /// Focal length along x (px).
    pub fx: f64,
    /// Focal length along y (px).
    pub fy: f64,
    /// Principal point x (px).
    pub cx: f64,
    /// Principal point y (px).
    pub cy: f64,
    /// Image width (px).
    pub width_px: u32,
    /// Image height (px).
    pub height_px: u32,
}

impl Intrinsics {
    /// Paper Eq. 1: fx = fy = w / (2 tan(fov/2)), principal point at the image centre.
    pub fn from_hfov(width_px: u32, height_px: u32, hfov_deg: f64) -> Result<Self, GeoError> {
        finite("horizontal field of view", hfov_deg)?;
        if !(hfov_deg > 0.0 && hfov_deg < 180.0) {
            return Err(GeoError::InvalidParameter {
                what: "horizontal field of view (deg, 0..180)",
                value: hfov_deg,
            });
        }
        if width_px == 0 || height_px == 0 {
            return Err(GeoError::InvalidParameter {
                what: "image size (px)",
                value: f64::from(width_px.min(height_px)),
            });
        }
        let w = f64::from(width_px);
        let f = w / (2.0 * (hfov_deg.to_radians() / 2.0).tan());
        Ok(Self {
            fx: f,
            fy: f,
            cx: w / 2.0,
            cy: f64::from(height_px) / 2.0,
            width_px,
            height_px,
        })
    }

    /// From a calibration (fx, fy, cx, cy in px).
    pub fn from_calibration(
        fx: f64,
        fy: f64,
        cx: f64,
        cy: f64,
        width_px: u32,
        height_px: u32,
    ) -> Result<Self, GeoError> {
        for (what, v) in [("fx", fx), ("fy", fy), ("cx", cx), ("cy", cy)] {
            finite(what, v)?;
        }
        if fx <= 0.0 || fy <= 0.0 {
            return Err(GeoError::InvalidParameter {
                what: "focal length (px, > 0)",
                value: fx.min(fy),
            });
        }
        Ok(Self {
            fx,
            fy,
            cx,
            cy,
            width_px,
            height_px,
        })
    }

    /// The 3x3 camera matrix K.
    pub fn matrix(&self) -> Matrix3<f64> {
        Matrix3::new(self.fx, 0.0, self.cx, 0.0, self.fy, self.cy, 0.0, 0.0, 1.0)
    }

    /// Whether a pixel lies inside the image.
    pub fn contains(&self, p: Pixel) -> bool {
        p.u >= 0.0
            && p.v >= 0.0
            && p.u <= f64::from(self.width_px)
            && p.v <= f64::from(self.height_px)
    }
}

/// Brown-Conrady lens distortion (OpenCV's k1, k2, p1, p2, k3) on normalised coordinates.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Distortion {
    /// Radial coefficient r^2.
    pub k1: f64,
    /// Radial coefficient r^4.
    pub k2: f64,
    /// Tangential coefficient 1.
    pub p1: f64,
    /// Tangential coefficient 2.
    pub p2: f64,
    /// Radial coefficient r^6.
    pub k3: f64,
}

impl Distortion {
    /// Distorts an ideal normalised point, with the Jacobian d(distorted)/d(ideal).
    fn distort_with_jacobian(&self, p: Vector2<f64>) -> (Vector2<f64>, Matrix2<f64>) {
        let (x, y) = (p.x, p.y);
        let r2 = x * x + y * y;
        let radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
        let d_radial = self.k1 + r2 * (2.0 * self.k2 + 3.0 * self.k3 * r2);
        let xd = x * radial + 2.0 * self.p1 * x * y + self.p2 * (r2 + 2.0 * x * x);
        let yd = y * radial + self.p1 * (r2 + 2.0 * y * y) + 2.0 * self.p2 * x * y;
        let cross = 2.0 * x * y * d_radial;
        let j = Matrix2::new(
            radial + 2.0 * x * x * d_radial + 2.0 * self.p1 * y + 6.0 * self.p2 * x,
            cross + 2.0 * self.p1 * x + 2.0 * self.p2 * y,
            cross + 2.0 * self.p1 * x + 2.0 * self.p2 * y,
            radial + 2.0 * y * y * d_radial + 6.0 * self.p1 * y + 2.0 * self.p2 * x,
        );
        (Vector2::new(xd, yd), j)
    }

    /// Applies the distortion to an ideal normalised point.
    pub fn distort(&self, p: Vector2<f64>) -> Vector2<f64> {
        self.distort_with_jacobian(p).0
    }

    /// Removes the distortion from a distorted normalised point (Newton iterations).
    pub fn undistort(&self, distorted: Vector2<f64>) -> Result<Vector2<f64>, GeoError> {
        let mut p = distorted;
        for _ in 0..30 {
            let (d, j) = self.distort_with_jacobian(p);
            let residual = d - distorted;
            if residual.norm() < 1e-14 {
                return Ok(p);
            }
            let step = j.try_inverse().ok_or(GeoError::UndistortionDiverged)? * residual;
            p -= step;
            if !p.x.is_finite() || !p.y.is_finite() {
                return Err(GeoError::UndistortionDiverged);
            }
        }
        if (self.distort(p) - distorted).norm() < 1e-10 {
            Ok(p)
        } else {
            Err(GeoError::UndistortionDiverged)
        }
    }
}

/// The camera's position and attitude in the local NED world frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraPose {
    /// Optical centre in local NED (m).
    pub position_ned: Vector3<f64>,
    /// Rotates camera-frame (optical) vectors into NED.
    pub attitude: UnitQuaternion<f64>,
}

/// The sea surface: the horizontal plane `down = down_m` of the local NED frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SeaPlane {
    /// Down coordinate of the water surface (m); 0 when the frame's origin is on the water.
    pub down_m: f64,
}

impl Default for SeaPlane {
    fn default() -> Self {
        Self { down_m: 0.0 }
    }
}

/// A calibrated camera: intrinsics and optional distortion.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CameraModel {
    /// Pinhole intrinsics.
    pub intrinsics: Intrinsics,
    /// Lens distortion, if calibrated; `None` is an ideal pinhole.
    pub distortion: Option<Distortion>,
}

impl CameraModel {
    /// An ideal pinhole from the horizontal field of view (paper Eq. 1).
    pub fn from_hfov(width_px: u32, height_px: u32, hfov_deg: f64) -> Result<Self, GeoError> {
        Ok(Self {
            intrinsics: Intrinsics::from_hfov(width_px, height_px, hfov_deg)?,
            distortion: None,
        })
    }

    /// Paper Eq. 3: the unit viewing ray of a pixel in the camera frame (K^-1 x, undistorted).
    pub fn pixel_to_ray(&self, px: Pixel) -> Result<Vector3<f64>, GeoError> {
        finite("pixel u", px.u)?;
        finite("pixel v", px.v)?;
        let k = &self.intrinsics;
        let mut n = Vector2::new((px.u - k.cx) / k.fx, (px.v - k.cy) / k.fy);
        if let Some(d) = &self.distortion {
            n = d.undistort(n)?;
        }
        Ok(Vector3::new(n.x, n.y, 1.0).normalize())
    }

    /// The pixel of a point given in the camera frame.
    pub fn camera_to_pixel(&self, p_cam: &Vector3<f64>) -> Result<Pixel, GeoError> {
        if p_cam.z.is_nan() || p_cam.z <= MIN_DEPTH_M {
            return Err(GeoError::BehindCamera);
        }
        let mut n = Vector2::new(p_cam.x / p_cam.z, p_cam.y / p_cam.z);
        if let Some(d) = &self.distortion {
            n = d.distort(n);
        }
        let k = &self.intrinsics;
        Ok(Pixel::new(k.fx * n.x + k.cx, k.fy * n.y + k.cy))
    }

    /// Paper Eq. 4: intersects a pixel's viewing ray with the sea plane; the world point (NED).
    ///
    /// Errors (never NaN, never a point behind the camera): the camera is not above the sea,
    /// or the ray is at or above the horizon.
    pub fn project_to_sea(
        &self,
        pose: &CameraPose,
        sea: &SeaPlane,
        px: Pixel,
    ) -> Result<Vector3<f64>, GeoError> {
        let ray = pose.attitude * self.pixel_to_ray(px)?;
        ray_to_sea(pose, sea, &ray)
    }

    /// The inverse of [`CameraModel::project_to_sea`]: the pixel where a world point appears.
    pub fn project_to_image(
        &self,
        pose: &CameraPose,
        world_ned: &Vector3<f64>,
    ) -> Result<Pixel, GeoError> {
        let p_cam = pose
            .attitude
            .inverse_transform_vector(&(world_ned - pose.position_ned));
        self.camera_to_pixel(&p_cam)
    }
}

/// Intersects a unit ray given in NED from the camera's optical centre with the sea plane.
pub(crate) fn ray_to_sea(
    pose: &CameraPose,
    sea: &SeaPlane,
    ray_ned: &Vector3<f64>,
) -> Result<Vector3<f64>, GeoError> {
    let height_m = sea.down_m - pose.position_ned.z;
    if height_m.is_nan() || height_m <= 0.0 {
        return Err(GeoError::CameraBelowSea { height_m });
    }
    if ray_ned.z.is_nan() || ray_ned.z <= MIN_RAY_DOWN {
        return Err(GeoError::AboveHorizon {
            depression_deg: ray_ned.z.clamp(-1.0, 1.0).asin().to_degrees(),
        });
    }
    let t = height_m / ray_ned.z;
    let mut p = pose.position_ned + ray_ned * t;
    p.z = sea.down_m;
    Ok(p)
}

/// Maps sea-plane coordinates (north, east, 1) to homogeneous pixels of an ideal pinhole:
/// G = K R^T [e1 e2 (0, 0, s) - C].
fn sea_to_pixel_matrix(k: &Matrix3<f64>, pose: &CameraPose, sea: &SeaPlane) -> Matrix3<f64> {
    let c = pose.position_ned;
    let plane = Matrix3::new(1.0, 0.0, -c.x, 0.0, 1.0, -c.y, 0.0, 0.0, sea.down_m - c.z);
    k * pose.attitude.to_rotation_matrix().matrix().transpose() * plane
}

/// The plane-induced homography that maps pixels of the image taken at `from` to pixels of
/// the image taken at `to`, for points on the sea surface (ideal pinhole: distortion ignored).
///
/// Used for camera-motion compensation between consecutive frames. Errors when either camera
/// is not above the sea (the mapping is singular then).
pub fn sea_plane_homography(
    model: &CameraModel,
    from: &CameraPose,
    to: &CameraPose,
    sea: &SeaPlane,
) -> Result<Matrix3<f64>, GeoError> {
    for pose in [from, to] {
        let height_m = sea.down_m - pose.position_ned.z;
        if height_m.is_nan() || height_m <= 0.0 {
            return Err(GeoError::CameraBelowSea { height_m });
        }
    }
    let k = model.intrinsics.matrix();
    let g_from = sea_to_pixel_matrix(&k, from, sea);
    let g_to = sea_to_pixel_matrix(&k, to, sea);
    let inv = g_from
        .try_inverse()
        .ok_or(GeoError::Degenerate("sea-plane homography is singular"))?;
    let h = g_to * inv;
    let scale = h[(2, 2)];
    if scale.abs() < 1e-12 || !h.iter().all(|v| v.is_finite()) {
        return Err(GeoError::Degenerate("sea-plane homography is singular"));
    }
    Ok(h / scale)
}

#[cfg(test)]
mod tests {
    use super::super::attitude::{camera_from_heading_pitch_deg, camera_from_ypr_rad};
    use super::*;
    use proptest::prelude::*;

    fn pose(h: f64, heading: f64, pitch: f64) -> CameraPose {
        CameraPose {
            position_ned: Vector3::new(0.0, 0.0, -h),
            attitude: camera_from_heading_pitch_deg(heading, pitch, 0.0),
        }
    }

    #[test]
    fn intrinsics_from_fov_match_eq1() {
        let k = Intrinsics::from_hfov(3840, 2160, 70.0).unwrap();
        let f = 3840.0 / (2.0 * 35f64.to_radians().tan());
        assert!((k.fx - f).abs() < 1e-9 && (k.fy - f).abs() < 1e-9);
        assert_eq!((k.cx, k.cy), (1920.0, 1080.0));
        assert_eq!(k.matrix()[(2, 2)], 1.0);
        assert!(Intrinsics::from_hfov(100, 100, 180.0).is_err());
        assert!(Intrinsics::from_hfov(0, 100, 60.0).is_err());
    }

    #[test]
    fn nadir_centre_pixel_is_below_the_drone() {
        let cam = CameraModel::from_hfov(1280, 720, 90.0).unwrap();
        let p = cam
            .project_to_sea(
                &pose(50.0, 0.0, 90.0),
                &SeaPlane::default(),
                Pixel::new(640.0, 360.0),
            )
            .unwrap();
        assert!(p.xy().norm() < 1e-9 && p.z == 0.0);
        // With a 90 deg hfov the right edge of the image is 50 m east at 50 m height.
        let edge = cam
            .project_to_sea(
                &pose(50.0, 0.0, 90.0),
                &SeaPlane::default(),
                Pixel::new(1280.0, 360.0),
            )
            .unwrap();
        assert!(
            (edge - Vector3::new(0.0, 50.0, 0.0)).norm() < 1e-9,
            "{edge}"
        );
        // Image top points north at heading 0.
        let top = cam
            .project_to_sea(
                &pose(50.0, 0.0, 90.0),
                &SeaPlane::default(),
                Pixel::new(640.0, 0.0),
            )
            .unwrap();
        assert!(top.x > 0.0 && top.y.abs() < 1e-9);
    }

    #[test]
    fn pitch_45_centre_is_at_distance_equal_to_height() {
        let cam = CameraModel::from_hfov(1280, 720, 70.0).unwrap();
        let p = cam
            .project_to_sea(
                &pose(30.0, 0.0, 45.0),
                &SeaPlane::default(),
                Pixel::new(640.0, 360.0),
            )
            .unwrap();
        assert!((p - Vector3::new(30.0, 0.0, 0.0)).norm() < 1e-9, "{p}");
    }

    #[test]
    fn yaw_90_rotates_to_east() {
        let cam = CameraModel::from_hfov(1280, 720, 70.0).unwrap();
        let p = cam
            .project_to_sea(
                &pose(30.0, 90.0, 45.0),
                &SeaPlane::default(),
                Pixel::new(640.0, 360.0),
            )
            .unwrap();
        assert!((p - Vector3::new(0.0, 30.0, 0.0)).norm() < 1e-9, "{p}");
    }

    #[test]
    fn horizon_and_below_sea_are_typed_errors() {
        let cam = CameraModel::from_hfov(1280, 720, 70.0).unwrap();
        let sea = SeaPlane::default();
        // Level camera: the upper half of the image is sky.
        let e = cam.project_to_sea(&pose(30.0, 0.0, 0.0), &sea, Pixel::new(640.0, 100.0));
        assert!(matches!(e, Err(GeoError::AboveHorizon { .. })));
        let e = cam.project_to_sea(&pose(30.0, 0.0, 0.0), &sea, Pixel::new(640.0, 360.0));
        assert!(matches!(e, Err(GeoError::AboveHorizon { .. })));
        let e = cam.project_to_sea(&pose(-1.0, 0.0, 90.0), &sea, Pixel::new(640.0, 360.0));
        assert!(matches!(e, Err(GeoError::CameraBelowSea { .. })));
        let e = cam.project_to_sea(&pose(10.0, 0.0, 90.0), &sea, Pixel::new(f64::NAN, 1.0));
        assert!(matches!(e, Err(GeoError::InvalidParameter { .. })));
        let behind = cam.project_to_image(&pose(30.0, 0.0, 45.0), &Vector3::new(-100.0, 0.0, 0.0));
        assert_eq!(behind, Err(GeoError::BehindCamera));
    }

    #[test]
    fn undistortion_inverts_distortion() {
        let d = Distortion {
            k1: -0.28,
            k2: 0.07,
            p1: 0.001,
            p2: -0.0005,
            k3: 0.0,
        };
        for &(x, y) in &[(0.0, 0.0), (0.3, -0.2), (-0.5, 0.4), (0.6, 0.3)] {
            let p = Vector2::new(x, y);
            let back = d.undistort(d.distort(p)).unwrap();
            assert!((back - p).norm() < 1e-10);
        }
    }

    #[test]
    fn homography_matches_point_transfer() {
        let cam = CameraModel::from_hfov(1280, 720, 70.0).unwrap();
        let sea = SeaPlane::default();
        let a = pose(40.0, 10.0, 60.0);
        let mut b = pose(42.0, 14.0, 55.0);
        b.position_ned += Vector3::new(3.0, -2.0, 0.0);
        let h = sea_plane_homography(&cam, &a, &b, &sea).unwrap();
        for &(u, v) in &[(100.0, 600.0), (640.0, 360.0), (1100.0, 500.0)] {
            let w = cam.project_to_sea(&a, &sea, Pixel::new(u, v)).unwrap();
            let expected = cam.project_to_image(&b, &w).unwrap();
            let m = h * Vector3::new(u, v, 1.0);
            assert!((m.x / m.z - expected.u).abs() < 1e-6 && (m.y / m.z - expected.v).abs() < 1e-6);
        }
    }

    proptest! {
        #[test]
        fn world_pixel_world_round_trip_within_1_mm(
            height in 5.0f64..300.0,
            yaw in -3.2f64..3.2, pitch_down in 0.15f64..1.57, roll in -0.3f64..0.3,
            n0 in -2000.0f64..2000.0, e0 in -2000.0f64..2000.0,
            u in 0.0f64..1.0, v in 0.0f64..1.0,
            k1 in -0.3f64..0.1, p1 in -0.002f64..0.002,
        ) {
            let cam = CameraModel {
                intrinsics: Intrinsics::from_hfov(1920, 1080, 80.0).unwrap(),
                distortion: Some(Distortion { k1, k2: 0.01, p1, p2: 0.0, k3: 0.0 }),
            };
            let pose = CameraPose {
                position_ned: Vector3::new(n0, e0, -height),
                attitude: camera_from_ypr_rad(yaw, -pitch_down, roll),
            };
            let sea = SeaPlane::default();
            let px = Pixel::new(u * 1920.0, v * 1080.0);
            // Pick a sea point in view (skip sky pixels), then go world -> pixel -> world.
            if let Ok(world) = cam.project_to_sea(&pose, &sea, px) {
                prop_assume!((world - pose.position_ned).norm() < 20_000.0);
                let back_px = cam.project_to_image(&pose, &world).unwrap();
                prop_assert!((back_px.u - px.u).abs() < 1e-5 && (back_px.v - px.v).abs() < 1e-5);
                let back = cam.project_to_sea(&pose, &sea, back_px).unwrap();
                prop_assert!((back - world).norm() < 1e-3, "{} vs {}", back, world);
            }
        }
    }
}
