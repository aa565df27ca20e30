//! One frame between the sensors and the tracker, and a track back to the map: the two steps
//! the onboard runtime (`mgmot run`) and the offline tools (`mgmot track`) share.
//!
//! - [`tracker_input`]: a frame's detections and its camera geometry (when it had a pose) ->
//!   the tracker's [`FrameInput`]: each box geolocated on the sea surface (paper Sec. 3.2's
//!   `X^2D`), and the sea-plane homography from the previous frame for camera-motion
//!   compensation.
//! - [`InputBuilder`]: [`tracker_input`] for consecutive frames, with what it remembers from
//!   one frame to the next (the local frame, set at the first pose; the previous frame's pose;
//!   the tracker's clock, forced monotonic). The live runtime and `mgmot replay` both build
//!   their inputs with it, which is why a replay reproduces the flight exactly.
//! - [`geo_fix`]: a track's world state (local NED) -> latitude/longitude on the sea surface,
//!   with velocity and its horizontal uncertainty, as the outputs report it.

use crate::geo::{
    CameraModel, FrameGeometry, FrameMetadata, Geodetic, Geolocator, LocalTangentFrame, PoseNoise,
};
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

/// How [`InputBuilder`] geolocates: the camera's horizontal field of view, the pose noise and
/// the longest range a box is geolocated at.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GeoSettings {
    /// Horizontal field of view (deg).
    pub hfov_deg: f64,
    /// Pose noise, for the observations' covariance.
    pub noise: PoseNoise,
    /// Boxes further than this (m) are not geolocated.
    pub max_range_m: f64,
}

/// Builds the tracker's inputs of consecutive frames, remembering what the next frame needs:
/// the geolocator (its local frame is the nadir point of the first frame with a pose), the
/// pose of the last frame the tracker took (motion compensation only between consecutive
/// frame indices) and the tracker's clock (forced monotonic: a source that restarted
/// continues just after the last frame's time).
#[derive(Debug, Clone)]
pub struct InputBuilder {
    geo: GeoSettings,
    geolocator: Option<Geolocator>,
    previous: Option<(u64, FrameMetadata)>,
    last_time_s: Option<f64>,
}

impl InputBuilder {
    /// Nothing seen yet.
    pub fn new(geo: GeoSettings) -> Self {
        Self {
            geo,
            geolocator: None,
            previous: None,
            last_time_s: None,
        }
    }

    /// The geolocator, once a frame had a pose.
    pub fn geolocator(&self) -> Option<&Geolocator> {
        self.geolocator.as_ref()
    }

    /// One frame's input: `time_s` is the frame's time on the tracker's clock (made monotonic
    /// here), `meta` its pose when it has one. Also returns the camera's position in the local
    /// frame. Call [`InputBuilder::taken`] once the tracker accepted the input. An empty image
    /// (no camera model) is tracked in the image only.
    pub fn build(
        &mut self,
        index: u64,
        time_s: f64,
        size: (u32, u32),
        detections: impl IntoIterator<Item = Detection>,
        meta: Option<&FrameMetadata>,
    ) -> (FrameInput, Option<Vector3<f64>>) {
        let time_s = match self.last_time_s {
            Some(last) if time_s < last => last + 1e-3,
            _ => time_s,
        };
        self.last_time_s = Some(time_s);
        if let (None, Some(m)) = (&self.geolocator, meta) {
            // A camera model fails only for an empty image: that frame is tracked in the image.
            self.geolocator = CameraModel::from_hfov(size.0, size.1, self.geo.hfov_deg)
                .ok()
                .map(|camera| {
                    Geolocator::new(m.nadir_on_water(), camera, self.geo.noise)
                        .with_max_range_m(self.geo.max_range_m)
                });
        }
        let Some(g) = &self.geolocator else {
            return (
                tracker_input(index, time_s, size, detections, None, None),
                None,
            );
        };
        let geometry = meta.and_then(|m| g.frame(m).ok());
        let previous_geometry = match &self.previous {
            Some((prev, m)) if prev + 1 == index => g.frame(m).ok(),
            _ => None,
        };
        let input = tracker_input(
            index,
            time_s,
            size,
            detections,
            geometry.as_ref(),
            previous_geometry.as_ref(),
        );
        let camera_ned = geometry.map(|g| g.pose_in_reference().position_ned);
        (input, camera_ned)
    }

    /// The tracker took frame `index` (with its pose, if any): the next frame's motion
    /// compensation starts from it.
    pub fn taken(&mut self, index: u64, meta: Option<&FrameMetadata>) {
        self.previous = meta.map(|m| (index, *m));
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
    fn the_builder_sets_the_local_frame_at_the_first_pose_and_keeps_its_clock_monotonic() {
        let geo = GeoSettings {
            hfov_deg: 60.0,
            noise: PoseNoise::default(),
            max_range_m: 1000.0,
        };
        let mut b = InputBuilder::new(geo);
        let dets = [detection(100.0)];
        let (no_pose, cam) = b.build(0, 10.0, (1280, 720), dets, None);
        assert!(no_pose.detections[0].world.is_none() && cam.is_none());
        assert!(b.geolocator().is_none());
        b.taken(0, None);
        let (first, cam) = b.build(1, 10.1, (1280, 720), dets, Some(&meta(5.0)));
        let reference = b.geolocator().map(|g| g.reference().origin());
        assert_eq!(reference, Some(meta(5.0).nadir_on_water()));
        assert!(first.detections[0].world.is_some() && first.image_motion.is_none());
        assert!(cam.is_some_and(|c| c.x.abs() < 1e-6));
        b.taken(1, Some(&meta(5.0)));
        // Consecutive: motion compensated; the clock going back continues after the last time.
        let (second, _) = b.build(2, 3.0, (1280, 720), dets, Some(&meta(6.0)));
        assert!(second.image_motion.is_some());
        assert!((second.time_s - 10.101).abs() < 1e-9);
        b.taken(2, Some(&meta(6.0)));
        // A gap in the indices: no motion compensation across it.
        let (after_gap, _) = b.build(4, 10.3, (1280, 720), dets, Some(&meta(7.0)));
        assert!(after_gap.image_motion.is_none());
        assert_eq!(after_gap.time_s, 10.3);
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
