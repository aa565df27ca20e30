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
    AttitudeSmoother, AttitudeSmoothing, CameraModel, FrameGeometry, FrameMetadata, Geodetic,
    Geolocator, LocalTangentFrame, PoseNoise,
};
use crate::track::{Detection, FrameInput, WorldObservation, WorldState};
use nalgebra::{Matrix3, Vector3};

/// The tracker's input for one frame. `geometry` is this frame's camera geometry (`None`
/// without a usable pose: the boxes then have no world position) and `image_motion` the
/// sea-plane homography from the previous frame's pixels to this frame's, when there is one
/// (see [`CameraMotion`]). Detections' own `world` fields are replaced.
pub fn tracker_input(
    frame_index: u64,
    time_s: f64,
    image_size_px: (u32, u32),
    detections: impl IntoIterator<Item = Detection>,
    geometry: Option<&FrameGeometry<'_>>,
    image_motion: Option<Matrix3<f64>>,
) -> FrameInput {
    let detections = detections
        .into_iter()
        .map(|d| Detection {
            world: geometry.and_then(|g| WorldObservation::of_box(g, &d.bbox)),
            ..d
        })
        .collect();
    FrameInput {
        frame_index,
        time_s,
        image_size_px,
        detections,
        image_motion,
    }
}

/// Metadata camera-motion compensation between consecutive frames: the sea-plane homography
/// between the poses of the last frame the tracker took and this one, with the camera
/// attitude smoothed ([`AttitudeSmoother`]; the geolocation keeps the measured attitude).
/// [`CameraMotion::image_motion`] stages the smoother's next state and
/// [`CameraMotion::taken`] commits it, so a frame the tracker refused leaves no trace.
#[derive(Debug, Clone)]
pub struct CameraMotion {
    smoother: AttitudeSmoother,
    /// The last frame taken with a pose: its index and pose, attitude smoothed.
    previous: Option<(u64, FrameMetadata)>,
    /// What [`CameraMotion::taken`] commits: the frame's index, the smoother after it and
    /// its smoothed pose.
    pending: Option<(u64, AttitudeSmoother, FrameMetadata)>,
}

impl CameraMotion {
    /// Nothing seen yet.
    pub fn new(smoothing: AttitudeSmoothing) -> Self {
        Self {
            smoother: AttitudeSmoother::new(smoothing),
            previous: None,
            pending: None,
        }
    }

    /// The homography carrying the previous frame's pixels to frame `index`'s (taken at
    /// `time_s`, with pose `meta`), when the previous frame taken is `index - 1` and both
    /// have a pose.
    pub fn image_motion(
        &mut self,
        geolocator: &Geolocator,
        index: u64,
        time_s: f64,
        meta: Option<&FrameMetadata>,
    ) -> Option<Matrix3<f64>> {
        let Some(meta) = meta else {
            self.without_pose();
            return None;
        };
        let (smoother, attitude) = self.smoother.update(time_s, meta.camera_attitude);
        let smoothed = FrameMetadata {
            camera_attitude: attitude,
            ..*meta
        };
        self.pending = Some((index, smoother, smoothed));
        let (prev_index, prev) = self.previous.as_ref()?;
        if prev_index.checked_add(1) != Some(index) {
            return None;
        }
        let from = geolocator.frame(prev).ok()?;
        let to = geolocator.frame(&smoothed).ok()?;
        from.image_motion_to(&to).ok()
    }

    /// The frame being built has no usable pose: once taken, the next frame has no motion
    /// compensation.
    pub fn without_pose(&mut self) {
        self.pending = None;
    }

    /// The tracker took frame `index`: the next frame's motion starts from it (from nothing
    /// when it had no pose).
    pub fn taken(&mut self, index: u64) {
        match self.pending.take() {
            Some((i, smoother, smoothed)) if i == index => {
                self.smoother = smoother;
                self.previous = Some((index, smoothed));
            }
            _ => self.previous = None,
        }
    }
}

/// How [`InputBuilder`] geolocates: the camera's horizontal field of view, the pose noise and
/// the longest range a box is geolocated at; and how it smooths the attitude for the motion
/// compensation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GeoSettings {
    /// Horizontal field of view (deg).
    pub hfov_deg: f64,
    /// Pose noise, for the observations' covariance.
    pub noise: PoseNoise,
    /// Boxes further than this (m) are not geolocated.
    pub max_range_m: f64,
    /// Smoothing of the attitude for the motion compensation (the tracker parameters'
    /// `baseline.cmc_smoothing`).
    pub motion_smoothing: AttitudeSmoothing,
}

/// Builds the tracker's inputs of consecutive frames, remembering what the next frame needs:
/// the geolocator (its local frame is the nadir point of the first frame with a pose), the
/// [`CameraMotion`] state (the pose of the last frame the tracker took: motion compensation
/// only between consecutive frame indices) and the tracker's clock (forced monotonic: a source that restarted
/// continues just after the last frame's time).
#[derive(Debug, Clone)]
pub struct InputBuilder {
    geo: GeoSettings,
    geolocator: Option<Geolocator>,
    motion: CameraMotion,
    last_time_s: Option<f64>,
}

impl InputBuilder {
    /// Nothing seen yet.
    pub fn new(geo: GeoSettings) -> Self {
        Self {
            geo,
            geolocator: None,
            motion: CameraMotion::new(geo.motion_smoothing),
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
            self.motion.without_pose();
            return (
                tracker_input(index, time_s, size, detections, None, None),
                None,
            );
        };
        let geometry = meta.and_then(|m| g.frame(m).ok());
        let image_motion = self.motion.image_motion(g, index, time_s, meta);
        let input = tracker_input(
            index,
            time_s,
            size,
            detections,
            geometry.as_ref(),
            image_motion,
        );
        let camera_ned = geometry.map(|g| g.pose_in_reference().position_ned);
        (input, camera_ned)
    }

    /// The tracker took frame `index` (the last one built): the next frame's motion
    /// compensation starts from it.
    pub fn taken(&mut self, index: u64) {
        self.motion.taken(index);
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
            appearance: None,
        }
    }

    #[test]
    fn boxes_are_geolocated_and_motion_is_compensated_only_with_both_poses() {
        let camera = CameraModel::from_hfov(1280, 720, 60.0).unwrap();
        let g = Geolocator::new(meta(0.0).nadir_on_water(), camera, PoseNoise::default());
        let (m0, m1) = (meta(0.0), meta(2.0));
        let (f0, f1) = (g.frame(&m0).unwrap(), g.frame(&m1).unwrap());
        let dets = [detection(100.0), detection(600.0)];
        let h = f0.image_motion_to(&f1).ok();
        assert!(h.is_some());
        let input = tracker_input(7, 1.5, (1280, 720), dets, Some(&f1), h);
        assert_eq!(
            (input.frame_index, input.time_s, input.image_size_px),
            (7, 1.5, (1280, 720))
        );
        assert!(input.detections.iter().all(|d| d.world.is_some()));
        assert_eq!(input.image_motion, h);
        // The same boxes geolocate where `WorldObservation::of_box` puts them.
        let direct = WorldObservation::of_box(&f1, &dets[1].bbox).unwrap();
        assert_eq!(input.detections[1].world, Some(direct));

        let no_pose = tracker_input(8, 1.6, (1280, 720), dets, None, None);
        assert!(no_pose.detections.iter().all(|d| d.world.is_none()));
        assert!(no_pose.image_motion.is_none());
    }

    /// `meta(north_m)` with the camera tilted by `tilt_deg` about its x axis (image right):
    /// a small attitude error, as the autopilot's noise.
    fn tilted(north_m: f64, tilt_deg: f64) -> FrameMetadata {
        let m = meta(north_m);
        FrameMetadata {
            camera_attitude: m.camera_attitude
                * nalgebra::UnitQuaternion::from_euler_angles(tilt_deg.to_radians(), 0.0, 0.0),
            ..m
        }
    }

    #[test]
    fn camera_motion_smooths_the_attitude_and_commits_only_taken_frames() {
        let camera = CameraModel::from_hfov(1280, 720, 60.0).unwrap();
        let g = Geolocator::new(meta(0.0).nadir_on_water(), camera, PoseNoise::default());
        let raw = |a: &FrameMetadata, b: &FrameMetadata| {
            g.frame(a)
                .unwrap()
                .image_motion_to(&g.frame(b).unwrap())
                .unwrap()
        };
        // A still camera whose attitude reads +-0.1 deg alternately: the raw homography
        // jumps by ~2 px each frame, the smoothed one much less.
        let metas: Vec<_> = (0..40)
            .map(|i| tilted(0.0, if i % 2 == 0 { 0.1 } else { -0.1 }))
            .collect();
        let shift = |h: &Matrix3<f64>| {
            let p = h * Vector3::new(640.0, 360.0, 1.0);
            ((p.x / p.z - 640.0).powi(2) + (p.y / p.z - 360.0).powi(2)).sqrt()
        };
        let mut smooth = CameraMotion::new(AttitudeSmoothing::default());
        let mut off = CameraMotion::new(AttitudeSmoothing {
            enabled: false,
            ..AttitudeSmoothing::default()
        });
        let (mut s_last, mut o_last) = (0.0, 0.0);
        for (i, m) in metas.iter().enumerate() {
            let t = i as f64 / 30.0;
            let hs = smooth.image_motion(&g, i as u64, t, Some(m));
            let ho = off.image_motion(&g, i as u64, t, Some(m));
            assert_eq!(hs.is_some(), i > 0);
            if let (Some(hs), Some(ho)) = (hs, ho) {
                assert_eq!(ho, raw(&metas[i - 1], m));
                (s_last, o_last) = (shift(&hs), shift(&ho));
            }
            smooth.taken(i as u64);
            off.taken(i as u64);
        }
        assert!(o_last > 1.5, "raw shift {o_last} px");
        assert!(
            s_last < 0.5 * o_last,
            "smoothed {s_last} px, raw {o_last} px"
        );

        // A frame built but not taken leaves no trace; one without a pose breaks the chain.
        let mut a = CameraMotion::new(AttitudeSmoothing::default());
        let mut b = a.clone();
        a.image_motion(&g, 0, 0.0, Some(&metas[0]));
        a.taken(0);
        b.image_motion(&g, 0, 0.0, Some(&metas[0]));
        b.taken(0);
        b.image_motion(&g, 1, 0.033, Some(&tilted(3.0, 5.0)));
        assert_eq!(
            a.image_motion(&g, 1, 0.033, Some(&metas[1])),
            b.image_motion(&g, 1, 0.033, Some(&metas[1]))
        );
        a.taken(1);
        assert!(a.image_motion(&g, 2, 0.066, None).is_none());
        a.taken(2);
        assert!(a.image_motion(&g, 3, 0.1, Some(&metas[3])).is_none());
    }

    #[test]
    fn the_builder_sets_the_local_frame_at_the_first_pose_and_keeps_its_clock_monotonic() {
        let geo = GeoSettings {
            hfov_deg: 60.0,
            noise: PoseNoise::default(),
            max_range_m: 1000.0,
            motion_smoothing: AttitudeSmoothing::default(),
        };
        let mut b = InputBuilder::new(geo);
        let dets = [detection(100.0)];
        let (no_pose, cam) = b.build(0, 10.0, (1280, 720), dets, None);
        assert!(no_pose.detections[0].world.is_none() && cam.is_none());
        assert!(b.geolocator().is_none());
        b.taken(0);
        let (first, cam) = b.build(1, 10.1, (1280, 720), dets, Some(&meta(5.0)));
        let reference = b.geolocator().map(|g| g.reference().origin());
        assert_eq!(reference, Some(meta(5.0).nadir_on_water()));
        assert!(first.detections[0].world.is_some() && first.image_motion.is_none());
        assert!(cam.is_some_and(|c| c.x.abs() < 1e-6));
        b.taken(1);
        // Consecutive: motion compensated; the clock going back continues after the last time.
        let (second, _) = b.build(2, 3.0, (1280, 720), dets, Some(&meta(6.0)));
        assert!(second.image_motion.is_some());
        assert!((second.time_s - 10.101).abs() < 1e-9);
        b.taken(2);
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
