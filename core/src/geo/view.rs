//! What a camera looks at, as MAVLink's CAMERA_FOV_STATUS tells it: the camera's position,
//! its attitude (the gimbal's FRD frame in NED, MAVLink's convention) and its fields of view.
//! A drone sends it; a ground station turns it back into the footprint on the sea.

use super::attitude::optical_to_frd;
use super::{finite, CameraModel, FrameMetadata, GeoError, Geodetic, Geolocator, PoseNoise};
use nalgebra::UnitQuaternion;

/// Width (px) of the notional image a footprint is sampled on; the height follows from the
/// two fields of view (square pixels).
const NOTIONAL_WIDTH_PX: u32 = 1000;

/// A camera's view of the sea.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraView {
    /// The camera's position (`alt_m` above mean sea level).
    pub camera: Geodetic,
    /// Height of the camera above the water (m).
    pub height_above_sea_m: f64,
    /// The camera's FRD frame (x along the optical axis, y right, z down) in NED: identity is
    /// a level camera looking north. MAVLink's gimbal and CAMERA_FOV_STATUS convention.
    pub attitude_frd: UnitQuaternion<f64>,
    /// Horizontal field of view (deg).
    pub hfov_deg: f64,
    /// Vertical field of view (deg).
    pub vfov_deg: f64,
}

impl CameraView {
    /// The view of a frame: its camera metadata (optical frame, see [`FrameMetadata`]) and
    /// fields of view.
    pub fn of_frame(meta: &FrameMetadata, hfov_deg: f64, vfov_deg: f64) -> Self {
        Self {
            camera: meta.position,
            height_above_sea_m: meta.height_above_sea_m,
            attitude_frd: meta.camera_attitude * optical_to_frd().inverse(),
            hfov_deg,
            vfov_deg,
        }
    }

    /// The camera's footprint on the sea as a ring of WGS84 points (clockwise from the
    /// image's top-left corner, the first not repeated), `per_edge` points per image edge,
    /// cut at `max_range_m` from the camera as [`super::FrameGeometry::footprint`] does.
    /// Empty when the camera sees no water (it looks above the horizon).
    pub fn footprint(&self, max_range_m: f64, per_edge: usize) -> Result<Vec<Geodetic>, GeoError> {
        let (h, v) = (
            finite("hfov", self.hfov_deg)?,
            finite("vfov", self.vfov_deg)?,
        );
        for (what, deg) in [("hfov", h), ("vfov", v)] {
            if !(deg > 0.0 && deg < 179.0) {
                return Err(GeoError::InvalidParameter { what, value: deg });
            }
        }
        let ratio = (v.to_radians() / 2.0).tan() / (h.to_radians() / 2.0).tan();
        let height_px = (f64::from(NOTIONAL_WIDTH_PX) * ratio)
            .round()
            .clamp(1.0, 1e5) as u32;
        let camera = CameraModel::from_hfov(NOTIONAL_WIDTH_PX, height_px, h)?;
        let geolocator = Geolocator::new(self.camera, camera, PoseNoise::default())
            .with_max_range_m(finite("max range", max_range_m)?);
        let meta = FrameMetadata {
            position: self.camera,
            height_above_sea_m: self.height_above_sea_m,
            camera_attitude: self.attitude_frd * optical_to_frd(),
            horizontal_accuracy_m: None,
        };
        Ok(geolocator
            .frame(&meta)?
            .footprint((NOTIONAL_WIDTH_PX, height_px), per_edge))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geo::attitude::camera_from_heading_pitch_deg;
    use crate::geo::LocalTangentFrame;
    use nalgebra::Vector3;

    fn view(heading_deg: f64, pitch_below_deg: f64, height_m: f64) -> CameraView {
        let meta = FrameMetadata {
            position: Geodetic::new(54.18, 7.89, height_m).unwrap(),
            height_above_sea_m: height_m,
            camera_attitude: camera_from_heading_pitch_deg(heading_deg, pitch_below_deg, 0.0),
            horizontal_accuracy_m: None,
        };
        CameraView::of_frame(
            &meta,
            70.0,
            2.0 * (35f64.to_radians().tan() * 9.0 / 16.0).atan().to_degrees(),
        )
    }

    #[test]
    fn the_frd_attitude_is_mavlinks_level_camera_looking_north_at_identity() {
        let v = view(0.0, 0.0, 50.0);
        assert!(v.attitude_frd.angle() < 1e-9, "{:?}", v.attitude_frd);
        // Looking straight down: FRD x (the optical axis) points down.
        let nadir = view(30.0, 90.0, 50.0);
        let axis = nadir.attitude_frd * Vector3::x();
        assert!((axis - Vector3::z()).norm() < 1e-9, "{axis}");
    }

    #[test]
    fn a_nadir_footprint_is_the_field_of_view_on_the_water() {
        // 50 m up, looking down, heading north: 2 * 50 * tan(35 deg) = 70.0 m across (east),
        // 9/16 of it along (north).
        let v = view(0.0, 90.0, 50.0);
        let ring = v.footprint(1500.0, 4).unwrap();
        assert_eq!(ring.len(), 16);
        let frame = LocalTangentFrame::new(Geodetic::new(54.18, 7.89, 0.0).unwrap());
        let ned: Vec<Vector3<f64>> = ring.iter().map(|g| frame.to_ned(g)).collect();
        let (mut n_min, mut n_max, mut e_min, mut e_max) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
        for p in &ned {
            n_min = n_min.min(p.x);
            n_max = n_max.max(p.x);
            e_min = e_min.min(p.y);
            e_max = e_max.max(p.y);
        }
        assert!(((e_max - e_min) - 70.02).abs() < 0.1, "{e_min} {e_max}");
        assert!(
            ((n_max - n_min) - 70.02 * 9.0 / 16.0).abs() < 0.1,
            "{n_min} {n_max}"
        );
        assert!((n_max + n_min).abs() < 0.05 && (e_max + e_min).abs() < 0.05);
    }

    #[test]
    fn an_oblique_footprint_reaches_out_ahead_and_stops_at_the_range_limit() {
        let v = view(90.0, 30.0, 50.0);
        let frame = LocalTangentFrame::new(Geodetic::new(54.18, 7.89, 0.0).unwrap());
        let ned: Vec<Vector3<f64>> = v
            .footprint(400.0, 4)
            .unwrap()
            .iter()
            .map(|g| frame.to_ned(g))
            .collect();
        let far = ned.iter().map(|p| p.y).fold(f64::MIN, f64::max);
        let near = ned.iter().map(|p| p.y).fold(f64::MAX, f64::min);
        // Looking east, 30 deg down with a 43.0 deg vertical field: the near edge (the image's
        // bottom row, a line across the heading) at 50 / tan(51.5 deg) = 39.8 m east; the top
        // corners' rays land beyond 400 m from the camera and are pulled in to the limit.
        assert!((near - 39.8).abs() < 0.5, "{near}");
        assert!(far > 300.0 && far <= 400.0, "{far}");
    }

    #[test]
    fn a_camera_looking_at_the_sky_has_no_footprint_and_bad_fields_of_view_are_refused() {
        let mut v = view(0.0, -30.0, 50.0);
        assert!(v.footprint(1500.0, 4).unwrap().is_empty());
        v.hfov_deg = f64::NAN;
        assert!(v.footprint(1500.0, 4).is_err());
        v.hfov_deg = 0.0;
        assert!(v.footprint(1500.0, 4).is_err());
    }
}
