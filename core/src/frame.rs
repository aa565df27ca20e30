//! One frame between the sensors and the tracker, and a track back to the map: the two steps
//! the onboard runtime (`mgmot run`) and the offline tools (`mgmot track`) share.
//!
//! - [`tracker_input`]: a frame's detections and its camera geometry (when it had a pose) ->
//!   the tracker's [`FrameInput`]: each box geolocated on the sea surface (paper Sec. 3.2's
//!   `X^2D`), and the sea-plane homography from the previous frame for camera-motion
//!   compensation.
//! - [`geo_fix`]: a track's world state (local NED) -> latitude/longitude on the sea surface,
//!   with velocity and its horizontal uncertainty, as the outputs report it.

use crate::geo::{FrameGeometry, Geodetic, LocalTangentFrame};
use crate::track::{Detection, FrameInput, WorldObservation, WorldState};
use nalgebra::Vector3;

/// The tracker's input for one frame. `geometry` is this frame's camera geometry and
/// `previous` the previous frame's (the frame given to the tracker just before); either is
/// `None` without a usable pose, and then the boxes have no world position or there is no
/// motion compensation. Detections' own `world` fields are replaced.
pub fn tracker_input(
    frame_index: u64,
    time_s: f64,
    image_size_px: (u32, u32),
    detections: impl IntoIterator<Item = Detection>,
    geometry: Option<&FrameGeometry<'_>>,
    previous: Option<&FrameGeometry<'_>>,
) -> FrameInput {
    let detections = detections
        .into_iter()
        .map(|d| Detection {
            world: geometry.and_then(|g| WorldObservation::of_box(g, &d.bbox)),
            ..d
        })
        .collect();
    let image_motion = match (previous, geometry) {
        (Some(p), Some(c)) => p.image_motion_to(c).ok(),
        _ => None,
    };
    FrameInput {
        frame_index,
        time_s,
        image_size_px,
        detections,
        image_motion,
    }
}

/// Where a track is on the map.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GeoFix {
    /// Position on the sea surface; `alt_m` is the water level AMSL when it is known.
    pub position: Geodetic,
    /// Velocity north (m/s).
    pub vel_n_mps: f64,
    /// Velocity east (m/s).
    pub vel_e_mps: f64,
    /// Horizontal position standard deviation (m): the DRMS of the position covariance, as
    /// `geo::Geolocation::h_std_m`.
    pub h_std_m: f64,
}

/// A track's world state as a geodetic fix: `reference` is the local frame the tracker's
/// world coordinates are in, `water_amsl_m` the sea surface's altitude (when known; otherwise
/// the reference's altitude is kept).
pub fn geo_fix(
    reference: &LocalTangentFrame,
    world: &WorldState,
    water_amsl_m: Option<f64>,
) -> GeoFix {
    let mut position =
        reference.to_geodetic(&Vector3::new(world.pos_ne_m.x, world.pos_ne_m.y, 0.0));
    if let Some(water) = water_amsl_m {
        position.alt_m = water;
    }
    GeoFix {
        position,
        vel_n_mps: world.vel_ne_m_s.x,
        vel_e_mps: world.vel_ne_m_s.y,
        h_std_m: world.pos_cov_m2().trace().max(0.0).sqrt(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geo::{CameraModel, FrameMetadata, Geolocator, PoseNoise};
    use crate::track::BBox;
    use nalgebra::{Matrix4, Vector2};

    /// 50 m above the sea looking straight down (SeaDronesSee convention: pitch 90 = nadir),
    /// `north_m` north of a fixed point.
    fn meta(north_m: f64) -> FrameMetadata {
        let base = LocalTangentFrame::new(Geodetic {
            lat_deg: 47.0,
            lon_deg: 9.0,
            alt_m: 0.0,
        });
        let p = base.to_geodetic(&Vector3::new(north_m, 0.0, 0.0));
        FrameMetadata::from_seadronessee(p.lat_deg, p.lon_deg, 50.0, 0.0, 90.0).unwrap()
    }

    fn detection(x: f64) -> Detection {
        Detection {
            bbox: BBox::new(x, 300.0, 20.0, 20.0),
            score: 0.9,
            class_id: 1,
            world: None,
        }
    }

    #[test]
    fn boxes_are_geolocated_and_motion_is_compensated_only_with_both_poses() {
        let camera = CameraModel::from_hfov(1280, 720, 60.0).unwrap();
        let g = Geolocator::new(meta(0.0).nadir_on_water(), camera, PoseNoise::default());
        let (m0, m1) = (meta(0.0), meta(2.0));
        let (f0, f1) = (g.frame(&m0).unwrap(), g.frame(&m1).unwrap());
        let dets = [detection(100.0), detection(600.0)];
        let input = tracker_input(7, 1.5, (1280, 720), dets, Some(&f1), Some(&f0));
        assert_eq!(
            (input.frame_index, input.time_s, input.image_size_px),
            (7, 1.5, (1280, 720))
        );
        assert!(input.detections.iter().all(|d| d.world.is_some()));
        assert!(input.image_motion.is_some());
        // The same boxes geolocate where `WorldObservation::of_box` puts them.
        let direct = WorldObservation::of_box(&f1, &dets[1].bbox).unwrap();
        assert_eq!(input.detections[1].world, Some(direct));

        let no_pose = tracker_input(8, 1.6, (1280, 720), dets, None, Some(&f1));
        assert!(no_pose.detections.iter().all(|d| d.world.is_none()));
        assert!(no_pose.image_motion.is_none());
        let first = tracker_input(0, 0.0, (1280, 720), dets, Some(&f0), None);
        assert!(first.image_motion.is_none());
        assert!(first.detections.iter().all(|d| d.world.is_some()));
    }

    #[test]
    fn a_fix_is_the_world_state_on_the_map() {
        let reference = LocalTangentFrame::new(Geodetic {
            lat_deg: 47.0,
            lon_deg: 9.0,
            alt_m: 3.0,
        });
        let mut cov = Matrix4::zeros();
        cov[(0, 0)] = 9.0;
        cov[(1, 1)] = 16.0;
        let world = WorldState {
            pos_ne_m: Vector2::new(111.0, -20.0),
            vel_ne_m_s: Vector2::new(0.5, -0.25),
            cov,
        };
        let fix = geo_fix(&reference, &world, Some(-1.5));
        let expected = reference.to_geodetic(&Vector3::new(111.0, -20.0, 0.0));
        assert_eq!(
            (fix.position.lat_deg, fix.position.lon_deg),
            (expected.lat_deg, expected.lon_deg)
        );
        assert_eq!(fix.position.alt_m, -1.5);
        assert_eq!((fix.vel_n_mps, fix.vel_e_mps), (0.5, -0.25));
        assert!((fix.h_std_m - 5.0).abs() < 1e-12);
        assert_eq!(
            geo_fix(&reference, &world, None).position.alt_m,
            expected.alt_m
        );
    }
}
