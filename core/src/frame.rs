//! One frame between the sensors and the tracker, and a track back to the map: the two steps
//! the onboard runtime (`mgmot run`) and the offline tools (`mgmot track`) share.
//!
//! - [`tracker_input`]: a frame's detections and its camera geometry (when it had a pose) ->
//!   the tracker's [`FrameInput`]: each box geolocated on the sea surface (paper Sec. 3.2's
//!   `X^2D`), and the sea-plane homography from the previous frame for camera-motion
//!   compensation.
//! - [`InputBuilder`]: [`tracker_input`] for consecutive frames, with what it remembers from
//!   one frame to the next (the local frame, set at the first pose; the previous frame's pose;
//!   the tracker's clock, [`TrackerClock`]). The live runtime and `mgmot replay` both build
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

/// How far a frame source's time may disagree with the reference clock between two frames
/// before the source's clock is taken to have jumped (s). Frames are delivered with jitter of
/// milliseconds to a few hundred (a stalled camera, a busy machine); a clock that restarted or
/// jumped disagrees by seconds.
pub const CLOCK_JUMP_TOLERANCE_S: f64 = 1.0;

/// The smallest step of the tracker's clock when the source's went back and there is no
/// reference clock to say how much time passed (s).
pub const CLOCK_MIN_STEP_S: f64 = 1e-3;

/// A jump of the source's clock that [`TrackerClock`] bridged.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClockJump {
    /// The previous frame's source time (s).
    pub previous_source_s: f64,
    /// The source time it jumped to (s).
    pub source_s: f64,
    /// The tracker's time given to the frame (s).
    pub tracker_s: f64,
}

/// The tracker's clock: a frame source's time (the exposure on the autopilot's clock, a file's
/// timestamps), made continuous. Velocities, Kalman predictions, ReID gaps and report rates all
/// run on it, so it must never go back, stall or leap, whatever the source does.
///
/// It follows the source's clock plus an offset. When a frame's source time disagrees with the
/// reference clock by more than [`CLOCK_JUMP_TOLERANCE_S`] (the autopilot rebooted and its
/// clock restarted near zero; a restarted camera or simulator; the clock mapping found
/// mid-flight), the offset is re-anchored so that the frame's tracker time is the previous
/// one plus the time the reference clock says passed, and the source's own steps are followed
/// again from there. The reference is a clock that never restarts: the companion computer's
/// monotonic clock at each frame's delivery, live. Without one (files), a source time that
/// goes back re-anchors at [`CLOCK_MIN_STEP_S`] after the previous frame.
#[derive(Debug, Clone, Default)]
pub struct TrackerClock {
    /// Tracker time minus source time (s).
    offset_s: f64,
    /// The previous frame: its tracker time and reference time.
    last: Option<(f64, Option<f64>)>,
    /// Jumps bridged so far.
    jumps: u64,
}

impl TrackerClock {
    /// Nothing seen yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// The tracker's time of a frame whose source time is `source_s` and whose reference time
    /// is `reference_s` (both s); the jump, when this frame's source clock jumped. A
    /// non-finite source time is returned as it is (the tracker refuses it) and changes
    /// nothing.
    pub fn time(&mut self, source_s: f64, reference_s: Option<f64>) -> (f64, Option<ClockJump>) {
        if !source_s.is_finite() {
            return (source_s, None);
        }
        let candidate = source_s + self.offset_s;
        let Some((last_s, last_ref)) = self.last else {
            self.last = Some((candidate, reference_s));
            return (candidate, None);
        };
        let elapsed_ref = match (reference_s, last_ref) {
            (Some(now), Some(then)) if now.is_finite() && then.is_finite() => Some(now - then),
            _ => None,
        };
        let jumped = candidate < last_s
            || elapsed_ref.is_some_and(|e| (candidate - last_s - e).abs() > CLOCK_JUMP_TOLERANCE_S);
        if !jumped {
            self.last = Some((candidate, reference_s));
            return (candidate, None);
        }
        let tracker_s = last_s + elapsed_ref.unwrap_or(0.0).max(CLOCK_MIN_STEP_S);
        let jump = ClockJump {
            previous_source_s: last_s - self.offset_s,
            source_s,
            tracker_s,
        };
        self.offset_s = tracker_s - source_s;
        self.last = Some((tracker_s, reference_s));
        self.jumps += 1;
        (tracker_s, Some(jump))
    }

    /// Jumps of the source's clock bridged so far.
    pub fn jumps(&self) -> u64 {
        self.jumps
    }
}

/// Builds the tracker's inputs of consecutive frames, remembering what the next frame needs:
/// the geolocator (its local frame is the nadir point of the first frame with a pose), the
/// [`CameraMotion`] state (the pose of the last frame the tracker took: motion compensation
/// only between consecutive frame indices) and the tracker's clock ([`TrackerClock`]).
#[derive(Debug, Clone)]
pub struct InputBuilder {
    geo: GeoSettings,
    geolocator: Option<Geolocator>,
    motion: CameraMotion,
    clock: TrackerClock,
}

/// A frame's time as its source gives it (s), and the reference clock's at the frame (s;
/// `None` without one): see [`TrackerClock`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameClock {
    /// The source's time: the exposure on the autopilot clock, a file's timestamp.
    pub source_s: f64,
    /// A clock that never restarts (the companion's monotonic clock at delivery), live.
    pub reference_s: Option<f64>,
}

impl FrameClock {
    /// A source time without a reference (files, replays).
    pub fn source(source_s: f64) -> Self {
        Self {
            source_s,
            reference_s: None,
        }
    }
}

impl InputBuilder {
    /// Nothing seen yet.
    pub fn new(geo: GeoSettings) -> Self {
        Self {
            geo,
            geolocator: None,
            motion: CameraMotion::new(geo.motion_smoothing),
            clock: TrackerClock::new(),
        }
    }

    /// Jumps of the source's clock the tracker's clock bridged so far.
    pub fn clock_jumps(&self) -> u64 {
        self.clock.jumps()
    }

    /// The geolocator, once a frame had a pose.
    pub fn geolocator(&self) -> Option<&Geolocator> {
        self.geolocator.as_ref()
    }

    /// One frame's input: `time` is the frame's time (made the tracker's by [`TrackerClock`];
    /// the input's `time_s` is the result), `meta` its pose when it has one. Also returns the
    /// camera's position in the local frame, and the source clock's jump when this frame's
    /// was bridged. Call [`InputBuilder::taken`] once the tracker accepted the input. An empty
    /// image (no camera model) is tracked in the image only.
    pub fn build(
        &mut self,
        index: u64,
        time: FrameClock,
        size: (u32, u32),
        detections: impl IntoIterator<Item = Detection>,
        meta: Option<&FrameMetadata>,
    ) -> (FrameInput, Option<Vector3<f64>>, Option<ClockJump>) {
        let (time_s, jump) = self.clock.time(time.source_s, time.reference_s);
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
                jump,
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
        (input, camera_ned, jump)
    }

    /// The tracker took frame `index` (the last one built): the next frame's motion
    /// compensation starts from it.
    pub fn taken(&mut self, index: u64) {
        self.motion.taken(index);
    }
}

/// The 95 % circular error of a covariance; when it has none (not finite, not positive
/// semi-definite) the conservative bound from its trace: 1.96 DRMS covers 95 % for any ratio
/// of the axes.
pub fn ce95_of(cov: &nalgebra::Matrix2<f64>) -> f64 {
    crate::geo::circular_error_m(cov, 0.95).unwrap_or_else(|| 1.959_964 * cov.trace().abs().sqrt())
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
    /// Radius (m) of the circle that holds the position with 95 % probability, from the
    /// position covariance ([`crate::geo::circular_error_m`]): Cursor-on-Target's `ce`.
    pub ce95_m: f64,
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
        ce95_m: ce95_of(&world.pos_cov_m2()),
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
        let at = FrameClock::source;
        let (no_pose, cam, _) = b.build(0, at(10.0), (1280, 720), dets, None);
        assert!(no_pose.detections[0].world.is_none() && cam.is_none());
        assert!(b.geolocator().is_none());
        b.taken(0);
        let (first, cam, _) = b.build(1, at(10.1), (1280, 720), dets, Some(&meta(5.0)));
        let reference = b.geolocator().map(|g| g.reference().origin());
        assert_eq!(reference, Some(meta(5.0).nadir_on_water()));
        assert!(first.detections[0].world.is_some() && first.image_motion.is_none());
        assert!(cam.is_some_and(|c| c.x.abs() < 1e-6));
        b.taken(1);
        // Consecutive: motion compensated; the clock going back continues after the last time.
        let (second, _, jump) = b.build(2, at(3.0), (1280, 720), dets, Some(&meta(6.0)));
        assert!(second.image_motion.is_some());
        assert!((second.time_s - 10.101).abs() < 1e-9);
        assert!(jump.is_some_and(|j| j.previous_source_s == 10.1 && j.source_s == 3.0));
        b.taken(2);
        // A gap in the indices: no motion compensation across it. The clock follows the
        // source's steps from the new anchor.
        let (after_gap, _, jump) = b.build(4, at(3.2), (1280, 720), dets, Some(&meta(7.0)));
        assert!(after_gap.image_motion.is_none());
        assert!((after_gap.time_s - 10.301).abs() < 1e-9);
        assert_eq!((jump, b.clock_jumps()), (None, 1));
    }

    /// Frames at 30 fps whose source time is `source(k)`; the reference clock runs true.
    fn run_clock(frames: u64, source: impl Fn(u64) -> f64) -> Vec<(f64, bool)> {
        let mut c = TrackerClock::new();
        (0..frames)
            .map(|k| {
                let (t, jump) = c.time(source(k), Some(1000.0 + k as f64 / 30.0));
                (t, jump.is_some())
            })
            .collect()
    }

    /// Issue 39, item 1: after an autopilot reboot (the exposure times restart near zero) the
    /// tracker's clock kept crawling at 1 ms a frame; it must run at the source's pace.
    #[test]
    fn after_an_autopilot_reboot_the_clock_runs_at_the_sources_pace() {
        // 181.4 s on the old boot, then 3 s of silence and the new boot's clock from 0.5 s.
        let reboot_at = 300u64;
        let times = run_clock(300 + 5100, |k| {
            if k < reboot_at {
                171.4 + k as f64 / 30.0
            } else {
                0.5 + (k - reboot_at) as f64 / 30.0
            }
        });
        let jumps: Vec<usize> = (0..times.len()).filter(|&k| times[k].1).collect();
        assert_eq!(jumps, vec![reboot_at as usize]);
        // Every step is a frame period, across the reboot too.
        for w in times.windows(2) {
            assert!((w[1].0 - w[0].0 - 1.0 / 30.0).abs() < 1e-6, "{w:?}");
        }
        // 170 s of flight after the reboot are 170 s of tracker time (was 4.8 s).
        let after = times[times.len() - 1].0 - times[reboot_at as usize].0;
        assert!((after - 5099.0 / 30.0).abs() < 1e-6, "{after}");
    }

    /// Issue 39, item 2: a frame source whose clock went back (a restarted camera or
    /// simulator), or leapt forward (the clock mapping found mid-flight), is bridged once.
    #[test]
    fn a_source_clock_that_goes_back_or_leaps_is_bridged_once() {
        let times = run_clock(900, |k| match k {
            0..300 => k as f64 / 30.0,
            300..600 => 40.0 + k as f64 / 30.0,
            _ => (k - 600) as f64 / 30.0,
        });
        assert_eq!(times.iter().filter(|t| t.1).count(), 2);
        for w in times.windows(2) {
            assert!((w[1].0 - w[0].0 - 1.0 / 30.0).abs() < 1e-6, "{w:?}");
        }
    }

    #[test]
    fn jitter_within_the_tolerance_is_the_sources_own() {
        let mut c = TrackerClock::new();
        assert_eq!(c.time(5.0, Some(100.0)), (5.0, None));
        // Delivered 0.6 s late (a stalled camera catching up): the exposure time is kept.
        assert_eq!(c.time(5.1, Some(100.7)), (5.1, None));
        assert_eq!(c.time(5.2, Some(100.72)), (5.2, None));
        // A NaN changes nothing.
        assert!(c.time(f64::NAN, Some(100.75)).0.is_nan());
        assert_eq!(c.time(5.3, Some(100.8)), (5.3, None));
    }

    proptest::proptest! {
        /// Whatever the source does, the tracker's clock never goes back, and its steps are the
        /// source's or, when those disagree with the reference, the reference's.
        #[test]
        fn the_clock_never_goes_back(
            steps in proptest::collection::vec((-500.0f64..500.0, 0.0f64..2.0, proptest::bool::ANY), 1..200)
        ) {
            let mut c = TrackerClock::new();
            let (mut source, mut reference) = (100.0, 0.0);
            let mut last: Option<f64> = None;
            for (source_step, reference_step, with_reference) in steps {
                source += source_step;
                reference += reference_step;
                let r = with_reference.then_some(reference);
                let (t, _) = c.time(source, r);
                if let Some(l) = last {
                    proptest::prop_assert!(t >= l, "{t} < {l}");
                }
                last = Some(t);
            }
        }
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
