//! From per-frame drone metadata to geolocated sea points in a flight-wide reference frame.
//!
//! Each frame is intersected with the sea in a tangent plane at the drone's own nadir (so the
//! flat-sea model is only ever used locally), and the result is carried through WGS84 into the
//! flight's fixed reference frame, where tracks live.

use super::attitude::camera_from_heading_pitch_deg;
use super::camera::{sea_plane_homography, CameraModel, CameraPose, Pixel, SeaPlane};
use super::uncertainty::{geolocation_covariance, PoseNoise};
use super::wgs84::{Geodetic, LocalTangentFrame};
use super::{finite, GeoError};
use nalgebra::{Matrix2, Matrix3, UnitQuaternion, Vector3};

/// Default limit on the camera-to-sea distance (m): beyond about 10 km the flat-sea model
/// and any realistic attitude accuracy no longer give a usable position.
pub const DEFAULT_MAX_RANGE_M: f64 = 10_000.0;

/// What one frame's metadata says about the camera.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameMetadata {
    /// Drone (camera) position; `alt_m` in the same datum as the reference frame's origin.
    pub position: Geodetic,
    /// Height of the camera above the water surface (m).
    pub height_above_sea_m: f64,
    /// Camera attitude: optical frame -> local NED.
    pub camera_attitude: UnitQuaternion<f64>,
    /// The GNSS receiver's own estimate of its horizontal position error at this frame (m,
    /// one sigma per axis; MAVLink GPS_RAW_INT `h_acc`). When known it replaces
    /// [`PoseNoise::horizontal_position_std_m`] in the frame's geolocation covariance.
    pub horizontal_accuracy_m: Option<f64>,
}

impl FrameMetadata {
    /// From SeaDronesSee image metadata: position, `height_above_takeoff(meter)` taken as the
    /// height above the water, `gimbal_heading(degrees)` (compass bearing) and
    /// `gimbal_pitch(degrees)` (below the horizon, 90 = nadir), roll 0.
    pub fn from_seadronessee(
        lat_deg: f64,
        lon_deg: f64,
        height_above_takeoff_m: f64,
        gimbal_heading_deg: f64,
        gimbal_pitch_deg: f64,
    ) -> Result<Self, GeoError> {
        finite("gimbal heading", gimbal_heading_deg)?;
        finite("gimbal pitch", gimbal_pitch_deg)?;
        let position = Geodetic::new(lat_deg, lon_deg, height_above_takeoff_m)?;
        Ok(Self {
            position,
            height_above_sea_m: height_above_takeoff_m,
            camera_attitude: camera_from_heading_pitch_deg(
                gimbal_heading_deg,
                gimbal_pitch_deg,
                0.0,
            ),
            horizontal_accuracy_m: None,
        })
    }

    /// Interpolates between two metadata samples: position and height linearly, attitude by
    /// slerp, the horizontal accuracy the worse of the two known; `s` = 0 gives `self`, 1
    /// gives `other`.
    pub fn interpolate(&self, other: &FrameMetadata, s: f64) -> FrameMetadata {
        let lerp = |a: f64, b: f64| a + (b - a) * s;
        FrameMetadata {
            position: Geodetic {
                lat_deg: lerp(self.position.lat_deg, other.position.lat_deg),
                lon_deg: lerp(self.position.lon_deg, other.position.lon_deg),
                alt_m: lerp(self.position.alt_m, other.position.alt_m),
            },
            height_above_sea_m: lerp(self.height_above_sea_m, other.height_above_sea_m),
            camera_attitude: self
                .camera_attitude
                .try_slerp(&other.camera_attitude, s, 1e-9)
                .unwrap_or(if s < 0.5 {
                    self.camera_attitude
                } else {
                    other.camera_attitude
                }),
            horizontal_accuracy_m: match (self.horizontal_accuracy_m, other.horizontal_accuracy_m) {
                (Some(a), Some(b)) => Some(a.max(b)),
                (a, b) => a.or(b),
            },
        }
    }

    /// The point on the water directly below the camera.
    pub fn nadir_on_water(&self) -> Geodetic {
        Geodetic {
            alt_m: self.position.alt_m - self.height_above_sea_m,
            ..self.position
        }
    }
}

/// A geolocated sea point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Geolocation {
    /// Position in the flight's reference NED frame (m).
    pub ned_m: Vector3<f64>,
    /// WGS84 position.
    pub geodetic: Geodetic,
    /// Distance from the camera to the point (m).
    pub range_m: f64,
    /// Horizontal (north, east) covariance (m^2).
    pub cov_ne_m2: Matrix2<f64>,
}

impl Geolocation {
    /// Horizontal position standard deviation (m): sqrt(var_north + var_east), the DRMS that
    /// GNSS receivers report as horizontal accuracy.
    pub fn h_std_m(&self) -> f64 {
        self.cov_ne_m2.trace().max(0.0).sqrt()
    }
}

/// Geolocates pixels for a whole flight: one camera, one reference frame, one noise model.
#[derive(Debug, Clone)]
pub struct Geolocator {
    reference: LocalTangentFrame,
    camera: CameraModel,
    noise: PoseNoise,
    max_range_m: f64,
}

impl Geolocator {
    /// A geolocator whose reference frame has its origin at `reference` (on the water).
    pub fn new(reference: Geodetic, camera: CameraModel, noise: PoseNoise) -> Self {
        Self {
            reference: LocalTangentFrame::new(reference),
            camera,
            noise,
            max_range_m: DEFAULT_MAX_RANGE_M,
        }
    }

    /// Replaces the camera-to-sea distance limit (m).
    pub fn with_max_range_m(mut self, max_range_m: f64) -> Self {
        self.max_range_m = max_range_m;
        self
    }

    /// The flight's reference frame.
    pub fn reference(&self) -> &LocalTangentFrame {
        &self.reference
    }

    /// The camera model.
    pub fn camera(&self) -> &CameraModel {
        &self.camera
    }

    /// Prepares one frame's geometry (the per-frame work done once, not per box).
    pub fn frame(&self, meta: &FrameMetadata) -> Result<FrameGeometry<'_>, GeoError> {
        finite("height above sea", meta.height_above_sea_m)?;
        let local = LocalTangentFrame::new(meta.nadir_on_water());
        Ok(FrameGeometry {
            geolocator: self,
            local,
            meta: *meta,
            pose_local: CameraPose {
                position_ned: Vector3::new(0.0, 0.0, -meta.height_above_sea_m),
                attitude: meta.camera_attitude,
            },
        })
    }
}

/// One frame's prepared geometry: camera pose in a tangent frame at the drone's nadir.
#[derive(Debug, Clone)]
pub struct FrameGeometry<'a> {
    geolocator: &'a Geolocator,
    local: LocalTangentFrame,
    meta: FrameMetadata,
    pose_local: CameraPose,
}

impl FrameGeometry<'_> {
    /// Geolocates one pixel (usually a box's centre) on the sea surface, with its covariance.
    pub fn locate(&self, px: Pixel) -> Result<Geolocation, GeoError> {
        let g = self.geolocator;
        let sea = SeaPlane::default();
        let local = g.camera.project_to_sea(&self.pose_local, &sea, px)?;
        let range_m = (local - self.pose_local.position_ned).norm();
        if range_m > g.max_range_m {
            return Err(GeoError::BeyondMaxRange {
                range_m,
                max_range_m: g.max_range_m,
            });
        }
        let noise = PoseNoise {
            horizontal_position_std_m: self
                .meta
                .horizontal_accuracy_m
                .unwrap_or(g.noise.horizontal_position_std_m),
            ..g.noise
        };
        let cov_ne_m2 = geolocation_covariance(&g.camera, &self.pose_local, &sea, px, &noise)?;
        let geodetic = self.local.to_geodetic(&local);
        Ok(Geolocation {
            ned_m: g.reference.to_ned(&geodetic),
            geodetic,
            range_m,
            cov_ne_m2,
        })
    }

    /// The camera's footprint on the sea, as a closed ring of WGS84 points (the first not
    /// repeated): the image border of a `width_px` x `height_px` frame sampled at `per_edge`
    /// points per edge, clockwise from the top-left corner. A border point whose ray misses
    /// the sea (above the horizon) or lands beyond the range limit is pulled towards the image
    /// centre until it lands, so an oblique view gives the visible water up to the limit.
    /// Points that land nowhere (the centre itself misses) are left out.
    pub fn footprint(&self, (width_px, height_px): (u32, u32), per_edge: usize) -> Vec<Geodetic> {
        let (w, h) = (f64::from(width_px), f64::from(height_px));
        let n = per_edge.max(1);
        let centre = Pixel::new(w / 2.0, h / 2.0);
        let mut border = Vec::with_capacity(4 * n);
        for i in 0..n {
            let f = i as f64 / n as f64;
            border.push(Pixel::new(f * w, 0.0));
        }
        for i in 0..n {
            let f = i as f64 / n as f64;
            border.push(Pixel::new(w, f * h));
        }
        for i in 0..n {
            let f = i as f64 / n as f64;
            border.push(Pixel::new(w - f * w, h));
        }
        for i in 0..n {
            let f = i as f64 / n as f64;
            border.push(Pixel::new(0.0, h - f * h));
        }
        let land = |px: Pixel| -> Option<Vector3<f64>> {
            let g = self.geolocator;
            let p = g
                .camera
                .project_to_sea(&self.pose_local, &SeaPlane::default(), px)
                .ok()?;
            ((p - self.pose_local.position_ned).norm() <= g.max_range_m).then_some(p)
        };
        border
            .into_iter()
            .filter_map(|b| {
                if let Some(p) = land(b) {
                    return Some(p);
                }
                // Bisection on the segment centre -> border: `lo` lands, `hi` does not.
                let at = |t: f64| {
                    Pixel::new(
                        centre.u + t * (b.u - centre.u),
                        centre.v + t * (b.v - centre.v),
                    )
                };
                let mut best = land(centre)?;
                let (mut lo, mut hi) = (0.0, 1.0);
                for _ in 0..24 {
                    let mid = 0.5 * (lo + hi);
                    match land(at(mid)) {
                        Some(p) => {
                            lo = mid;
                            best = p;
                        }
                        None => hi = mid,
                    }
                }
                Some(best)
            })
            .map(|p| self.local.to_geodetic(&p))
            .collect()
    }

    /// The camera pose in the flight's reference frame.
    pub fn pose_in_reference(&self) -> CameraPose {
        CameraPose {
            position_ned: self.geolocator.reference.to_ned(&self.meta.position),
            attitude: self.meta.camera_attitude,
        }
    }

    /// The pixel where a reference-frame world point appears in this frame.
    pub fn project_to_image(&self, world_ned: &Vector3<f64>) -> Result<Pixel, GeoError> {
        let geodetic = self.geolocator.reference.to_geodetic(world_ned);
        let local = self.local.to_ned(&geodetic);
        self.geolocator
            .camera
            .project_to_image(&self.pose_local, &local)
    }

    /// Camera-motion compensation from metadata: the sea-plane homography mapping this frame's
    /// pixels to `next`'s pixels.
    pub fn image_motion_to(&self, next: &FrameGeometry<'_>) -> Result<Matrix3<f64>, GeoError> {
        let next_pose = CameraPose {
            position_ned: self.local.to_ned(&next.meta.position),
            attitude: next.meta.camera_attitude,
        };
        sea_plane_homography(
            &self.geolocator.camera,
            &self.pose_local,
            &next_pose,
            &SeaPlane::default(),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn locate_round_trips_through_the_reference_frame() {
        let cam = CameraModel::from_hfov(3840, 2160, 70.0).unwrap();
        let origin = Geodetic::new(47.67, 9.27, 0.0).unwrap();
        let g = Geolocator::new(origin, cam, PoseNoise::default());
        let meta = FrameMetadata::from_seadronessee(47.672, 9.268, 40.0, 120.0, 35.0).unwrap();
        let frame = g.frame(&meta).unwrap();
        let px = Pixel::new(2000.0, 1500.0);
        let loc = frame.locate(px).unwrap();
        let back = frame.project_to_image(&loc.ned_m).unwrap();
        assert!((back.u - px.u).abs() < 1e-3 && (back.v - px.v).abs() < 1e-3);
        assert!(loc.range_m > 40.0 && loc.h_std_m() > 0.0);
        assert!(
            loc.ned_m.z.abs() < 0.1,
            "sea stays near down = 0: {}",
            loc.ned_m
        );
    }

    /// The receiver's reported horizontal accuracy replaces the configured position noise in
    /// the covariance, on both axes, and nothing else; the same point is found either way.
    #[test]
    fn a_reported_horizontal_accuracy_is_the_position_noise() {
        let cam = CameraModel::from_hfov(1280, 720, 70.0).unwrap();
        let origin = Geodetic::new(47.67, 9.27, 0.0).unwrap();
        let noise = PoseNoise::default();
        let g = Geolocator::new(origin, cam, noise);
        let meta = FrameMetadata::from_seadronessee(47.672, 9.268, 40.0, 120.0, 60.0).unwrap();
        let px = Pixel::new(700.0, 400.0);
        let configured = g.frame(&meta).unwrap().locate(px).unwrap();
        let reported = |h_acc_m: f64| {
            let meta = FrameMetadata {
                horizontal_accuracy_m: Some(h_acc_m),
                ..meta
            };
            g.frame(&meta).unwrap().locate(px).unwrap()
        };
        let same = reported(noise.horizontal_position_std_m);
        assert_eq!(same.cov_ne_m2, configured.cov_ne_m2);
        let worse = reported(3.0);
        assert_eq!(worse.ned_m, configured.ned_m);
        let added = worse.cov_ne_m2 - configured.cov_ne_m2;
        let expected = 3.0f64.powi(2) - noise.horizontal_position_std_m.powi(2);
        assert!(
            (added - Matrix2::identity() * expected).abs().max() < 1e-9,
            "{added}"
        );
        let rtk = reported(0.02);
        assert!(rtk.h_std_m() < configured.h_std_m());
        // Interpolating keeps the worse of two known accuracies, or the one known.
        let a = FrameMetadata {
            horizontal_accuracy_m: Some(0.5),
            ..meta
        };
        let b = FrameMetadata {
            horizontal_accuracy_m: Some(2.0),
            ..meta
        };
        assert_eq!(a.interpolate(&b, 0.3).horizontal_accuracy_m, Some(2.0));
        assert_eq!(meta.interpolate(&a, 0.3).horizontal_accuracy_m, Some(0.5));
        assert_eq!(meta.interpolate(&meta, 0.3).horizontal_accuracy_m, None);
    }

    #[test]
    fn a_nadir_footprint_is_the_ground_rectangle_and_an_oblique_one_stops_at_the_range_limit() {
        let cam = CameraModel::from_hfov(1280, 720, 90.0).unwrap();
        let origin = Geodetic::new(47.67, 9.27, 0.0).unwrap();
        let g = Geolocator::new(origin, cam, PoseNoise::default()).with_max_range_m(500.0);
        // 50 m up, straight down, heading north: 100 m wide (hfov 90), 56.25 m tall.
        let meta = FrameMetadata::from_seadronessee(47.67, 9.27, 50.0, 0.0, 90.0).unwrap();
        let ring = g.frame(&meta).unwrap().footprint((1280, 720), 2);
        assert_eq!(ring.len(), 8);
        let frame = LocalTangentFrame::new(Geodetic::new(47.67, 9.27, 0.0).unwrap());
        let ned: Vec<Vector3<f64>> = ring.iter().map(|p| frame.to_ned(p)).collect();
        let east = ned.iter().map(|p| p.y.abs()).fold(0.0, f64::max);
        let north = ned.iter().map(|p| p.x.abs()).fold(0.0, f64::max);
        assert!(
            (east - 50.0).abs() < 0.5 && (north - 28.125).abs() < 0.5,
            "{ned:?}"
        );
        // Pitched 10 deg below the horizon: the top of the image sees the sky; the footprint
        // ends at the 500 m limit.
        let meta = FrameMetadata::from_seadronessee(47.67, 9.27, 50.0, 0.0, 10.0).unwrap();
        let ring = g.frame(&meta).unwrap().footprint((1280, 720), 4);
        assert_eq!(ring.len(), 16);
        let far = ring
            .iter()
            .map(|p| frame.to_ned(p).xy().norm())
            .fold(0.0, f64::max);
        assert!(far <= 500.0 && far > 480.0, "farthest point {far} m");
    }

    #[test]
    fn interpolation_takes_the_short_way_round() {
        let a = FrameMetadata::from_seadronessee(47.0, 9.0, 30.0, 350.0, 40.0).unwrap();
        let b = FrameMetadata::from_seadronessee(47.001, 9.002, 40.0, 10.0, 60.0).unwrap();
        let m = a.interpolate(&b, 0.5);
        let expected = FrameMetadata::from_seadronessee(47.0005, 9.001, 35.0, 0.0, 50.0).unwrap();
        assert!(
            (m.position.lat_deg - 47.0005).abs() < 1e-12
                && (m.height_above_sea_m - 35.0).abs() < 1e-12
        );
        assert!(m.camera_attitude.angle_to(&expected.camera_attitude) < 0.02);
        assert!(
            a.interpolate(&b, 0.0)
                .camera_attitude
                .angle_to(&a.camera_attitude)
                < 1e-9
        );
    }

    #[test]
    fn sky_and_far_points_are_rejected() {
        let cam = CameraModel::from_hfov(1280, 720, 70.0).unwrap();
        let g = Geolocator::new(
            Geodetic::new(0.0, 0.0, 0.0).unwrap(),
            cam,
            PoseNoise::default(),
        )
        .with_max_range_m(500.0);
        let meta = FrameMetadata::from_seadronessee(0.0, 0.0, 10.0, 0.0, 0.5).unwrap();
        let f = g.frame(&meta).unwrap();
        assert!(matches!(
            f.locate(Pixel::new(640.0, 10.0)),
            Err(GeoError::AboveHorizon { .. })
        ));
        assert!(matches!(
            f.locate(Pixel::new(640.0, 365.0)),
            Err(GeoError::BeyondMaxRange { .. })
        ));
    }

    #[test]
    fn image_motion_of_a_static_pose_is_identity() {
        let cam = CameraModel::from_hfov(1280, 720, 70.0).unwrap();
        let g = Geolocator::new(
            Geodetic::new(47.0, 9.0, 0.0).unwrap(),
            cam,
            PoseNoise::default(),
        );
        let meta = FrameMetadata::from_seadronessee(47.001, 9.001, 30.0, 45.0, 60.0).unwrap();
        let a = g.frame(&meta).unwrap();
        let h = a.image_motion_to(&g.frame(&meta).unwrap()).unwrap();
        assert!((h - Matrix3::identity()).norm() < 1e-6, "{h}");
    }
}
