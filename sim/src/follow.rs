//! The pure parts of `mgmot-sim follow`, the frame-only mode in which a real autopilot flies
//! and the simulator only renders what its camera would see: the camera pose interpolated
//! from the autopilot's telemetry, the autopilot clock estimated from it, and the scenario's
//! world placed around the autopilot's home. No IO, no clock: the binary feeds the messages
//! and the local times in.
//!
//! Follow reads the pose on its own (it is "the world"), independently of mgmot's decoders,
//! so that a misreading in mgmot shows up as geolocation error.

use crate::motion::{wrap_360, DroneState};
use crate::world::World;
use mgmot_core::geo::attitude::{camera_from_gimbal_quaternion, camera_to_ypr_rad, GimbalYawFrame};
use mgmot_core::geo::{CameraPose, Geodetic, LocalTangentFrame};
use mgmot_wire::dialect::GimbalDeviceFlags;
use nalgebra::{Quaternion, UnitQuaternion, Vector3};
use std::collections::VecDeque;

/// Samples older than this behind the newest one of their stream are forgotten (µs).
pub const KEEP_US: u64 = 5_000_000;

/// Two neighbouring samples further apart than this are not interpolated between (a
/// telemetry gap): the pose there is unknown (µs).
pub const MAX_GAP_US: u64 = 1_000_000;

/// A time up to this far after a stream's newest sample takes that sample (µs): frames are
/// rendered slightly in the past (the capture latency), but a late message must not blank
/// the video.
pub const MAX_HOLD_US: u64 = 250_000;

/// The autopilot clock going back by more than this means the autopilot rebooted (µs);
/// smaller steps are messages of different streams arriving out of order.
pub const REBOOT_STEP_US: u64 = 1_000_000;

/// How the quaternion of GIMBAL_DEVICE_ATTITUDE_STATUS is referenced.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GimbalReport {
    /// As the message's flags say (gimbal protocol v2): YAW_IN_EARTH_FRAME -> earth,
    /// YAW_IN_VEHICLE_FRAME -> roll/pitch earth, yaw vehicle; without either, YAW_LOCK means
    /// earth and follow mode vehicle.
    Flags,
    /// The whole quaternion relative to the vehicle body, whatever the flags claim: what
    /// ArduPilot really sends for a servo mount (MNT1_TYPE = 1), the servo angles after its
    /// own lean compensation.
    Body,
}

/// The yaw frame of a gimbal quaternion with `flags`, as `report` says to read it.
pub fn gimbal_yaw_frame(flags: GimbalDeviceFlags, report: GimbalReport) -> GimbalYawFrame {
    match report {
        GimbalReport::Body => GimbalYawFrame::Body,
        GimbalReport::Flags => {
            if flags.contains(GimbalDeviceFlags::GIMBAL_DEVICE_FLAGS_YAW_IN_EARTH_FRAME) {
                GimbalYawFrame::Earth
            } else if flags.contains(GimbalDeviceFlags::GIMBAL_DEVICE_FLAGS_YAW_IN_VEHICLE_FRAME) {
                GimbalYawFrame::Vehicle
            } else if flags.contains(GimbalDeviceFlags::GIMBAL_DEVICE_FLAGS_YAW_LOCK) {
                GimbalYawFrame::Earth
            } else {
                GimbalYawFrame::Vehicle
            }
        }
    }
}

/// A unit quaternion from MAVLink's `[w, x, y, z]`; `None` for NaN ("no data") or a
/// quaternion far from unit length.
pub fn quaternion_wxyz(q: [f32; 4]) -> Option<UnitQuaternion<f64>> {
    let [w, x, y, z] = q.map(f64::from);
    if ![w, x, y, z].iter().all(|v| v.is_finite()) {
        return None;
    }
    let q = Quaternion::new(w, x, y, z);
    (q.norm() > 0.5 && q.norm() < 1.5).then(|| UnitQuaternion::from_quaternion(q))
}

/// The vehicle attitude (FRD body -> NED) of an ATTITUDE message (radians); `None` when not
/// finite.
pub fn vehicle_attitude(roll: f32, pitch: f32, yaw: f32) -> Option<UnitQuaternion<f64>> {
    let (r, p, y) = (f64::from(roll), f64::from(pitch), f64::from(yaw));
    [r, p, y]
        .iter()
        .all(|v| v.is_finite())
        .then(|| UnitQuaternion::from_euler_angles(r, p, y))
}

/// One GLOBAL_POSITION_INT, in SI units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PositionFix {
    /// Latitude (deg).
    pub lat_deg: f64,
    /// Longitude (deg).
    pub lon_deg: f64,
    /// Altitude AMSL (m).
    pub alt_amsl_m: f64,
    /// Altitude above home (m).
    pub relative_alt_m: f64,
    /// Velocity north, east, down (m/s).
    pub vel_ned_mps: [f64; 3],
}

impl PositionFix {
    /// From GLOBAL_POSITION_INT's integer fields; `None` without a fix (lat = lon = 0) or
    /// with an impossible latitude.
    pub fn from_mavlink(
        lat_e7: i32,
        lon_e7: i32,
        alt_mm: i32,
        relative_alt_mm: i32,
        vel_cm_s: [i16; 3],
    ) -> Option<PositionFix> {
        if lat_e7 == 0 && lon_e7 == 0 {
            return None;
        }
        let lat_deg = f64::from(lat_e7) * 1e-7;
        if !(-90.0..=90.0).contains(&lat_deg) {
            return None;
        }
        Some(PositionFix {
            lat_deg,
            lon_deg: f64::from(lon_e7) * 1e-7,
            alt_amsl_m: f64::from(alt_mm) * 1e-3,
            relative_alt_m: f64::from(relative_alt_mm) * 1e-3,
            vel_ned_mps: vel_cm_s.map(|v| f64::from(v) * 0.01),
        })
    }

    /// The home this fix implies when the autopilot sends no HOME_POSITION: straight below
    /// it at `alt - relative_alt` (the autopilot's home altitude).
    pub fn implied_home(&self) -> Option<Geodetic> {
        Geodetic::new(
            self.lat_deg,
            self.lon_deg,
            self.alt_amsl_m - self.relative_alt_m,
        )
        .ok()
    }
}

/// One GIMBAL_DEVICE_ATTITUDE_STATUS: the quaternion and how to read it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GimbalFix {
    /// Gimbal FRD attitude in the frame `frame`.
    pub q: UnitQuaternion<f64>,
    /// Its reference frame.
    pub frame: GimbalYawFrame,
}

/// Linear interpolation between two samples (`f` in [0, 1]).
trait Lerp: Sized + Copy {
    fn lerp(&self, other: &Self, f: f64) -> Self;
}

impl Lerp for PositionFix {
    fn lerp(&self, o: &Self, f: f64) -> Self {
        let l = |a: f64, b: f64| a + (b - a) * f;
        PositionFix {
            lat_deg: l(self.lat_deg, o.lat_deg),
            // Across the antimeridian the short way round.
            lon_deg: self.lon_deg + crate::motion::wrap_180(o.lon_deg - self.lon_deg) * f,
            alt_amsl_m: l(self.alt_amsl_m, o.alt_amsl_m),
            relative_alt_m: l(self.relative_alt_m, o.relative_alt_m),
            vel_ned_mps: [
                l(self.vel_ned_mps[0], o.vel_ned_mps[0]),
                l(self.vel_ned_mps[1], o.vel_ned_mps[1]),
                l(self.vel_ned_mps[2], o.vel_ned_mps[2]),
            ],
        }
    }
}

/// Shortest-path slerp; the nearer sample where it is undefined (opposite rotations).
fn slerp(a: &UnitQuaternion<f64>, b: &UnitQuaternion<f64>, f: f64) -> UnitQuaternion<f64> {
    let b = if a.coords.dot(&b.coords) < 0.0 {
        UnitQuaternion::new_unchecked(-b.into_inner())
    } else {
        *b
    };
    a.try_slerp(&b, f, 1e-9)
        .unwrap_or(if f < 0.5 { *a } else { b })
}

impl Lerp for UnitQuaternion<f64> {
    fn lerp(&self, o: &Self, f: f64) -> Self {
        slerp(self, o, f)
    }
}

impl Lerp for GimbalFix {
    fn lerp(&self, o: &Self, f: f64) -> Self {
        if self.frame != o.frame {
            // The frame changed between the samples: no meaningful blend.
            return if f < 0.5 { *self } else { *o };
        }
        GimbalFix {
            q: slerp(&self.q, &o.q, f),
            frame: self.frame,
        }
    }
}

/// The recent samples of one stream, in autopilot time order.
#[derive(Debug, Clone)]
struct Series<T> {
    samples: VecDeque<(u64, T)>,
}

impl<T> Default for Series<T> {
    fn default() -> Self {
        Series {
            samples: VecDeque::new(),
        }
    }
}

impl<T: Lerp> Series<T> {
    fn push(&mut self, t_us: u64, v: T) {
        // Usually appended; a late message is inserted in order, a duplicate time replaced.
        let i = self.samples.partition_point(|(t, _)| *t < t_us);
        match self.samples.get_mut(i) {
            Some(s) if s.0 == t_us => s.1 = v,
            _ => self.samples.insert(i, (t_us, v)),
        }
        let newest = self.samples.back().map_or(t_us, |s| s.0);
        while self.samples.front().is_some_and(|s| s.0 + KEEP_US < newest) {
            self.samples.pop_front();
        }
    }

    fn at(&self, t_us: u64) -> Option<T> {
        let i = self.samples.partition_point(|(t, _)| *t < t_us);
        match (
            i.checked_sub(1).and_then(|k| self.samples.get(k)),
            self.samples.get(i),
        ) {
            (_, Some((tb, b))) if *tb == t_us => Some(*b),
            (Some((ta, a)), Some((tb, b))) => {
                if tb - ta > MAX_GAP_US {
                    return None;
                }
                let f = (t_us - ta) as f64 / (tb - ta) as f64;
                Some(a.lerp(b, f))
            }
            (Some((ta, a)), None) => (t_us - ta <= MAX_HOLD_US).then_some(*a),
            // Before the first sample nothing is known (e.g. a frame captured just before the
            // telemetry started).
            (None, _) => None,
        }
    }

    fn newest_us(&self) -> Option<u64> {
        self.samples.back().map(|s| s.0)
    }
}

/// Which part of the pose is missing at an instant.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Missing {
    /// No GLOBAL_POSITION_INT around that time.
    Position,
    /// No ATTITUDE around that time.
    Attitude,
    /// No GIMBAL_DEVICE_ATTITUDE_STATUS around that time.
    Gimbal,
}

impl std::fmt::Display for Missing {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Missing::Position => "GLOBAL_POSITION_INT",
            Missing::Attitude => "ATTITUDE",
            Missing::Gimbal => "GIMBAL_DEVICE_ATTITUDE_STATUS",
        })
    }
}

/// The camera pose at one instant, as follow renders it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FollowPose {
    /// Camera position in the local NED frame around home, and its attitude.
    pub camera: CameraPose,
    /// The vehicle's attitude (FRD body -> NED).
    pub vehicle_attitude: UnitQuaternion<f64>,
    /// The vehicle's velocity (NED, m/s).
    pub vel_ned_mps: [f64; 3],
    /// How the gimbal quaternion was read.
    pub gimbal_frame: GimbalYawFrame,
}

impl FollowPose {
    /// The pose in the ground truth's terms ([`DroneState`]): camera heading and depression
    /// from the camera attitude, vehicle roll/pitch/yaw from the vehicle attitude.
    pub fn drone_state(&self) -> DroneState {
        let (roll, pitch, yaw) = self.vehicle_attitude.euler_angles();
        let (cam_yaw, cam_pitch, _) = camera_to_ypr_rad(&self.camera.attitude);
        let p = self.camera.position_ned;
        DroneState {
            pos_ned_m: [p.x, p.y, p.z],
            vel_ned_mps: self.vel_ned_mps,
            roll_deg: roll.to_degrees(),
            pitch_deg: pitch.to_degrees(),
            yaw_deg: wrap_360(yaw.to_degrees()),
            cam_heading_deg: wrap_360(cam_yaw.to_degrees()),
            cam_pitch_deg: -cam_pitch.to_degrees(),
        }
    }
}

/// The recent telemetry of the vehicle pose, by autopilot time (µs since its boot).
#[derive(Debug, Clone, Default)]
pub struct PoseBuffer {
    position: Series<PositionFix>,
    attitude: Series<UnitQuaternion<f64>>,
    gimbal: Series<GimbalFix>,
}

impl PoseBuffer {
    /// Adds a GLOBAL_POSITION_INT sample.
    pub fn push_position(&mut self, t_us: u64, fix: PositionFix) {
        self.position.push(t_us, fix);
    }

    /// Adds an ATTITUDE sample.
    pub fn push_attitude(&mut self, t_us: u64, attitude: UnitQuaternion<f64>) {
        self.attitude.push(t_us, attitude);
    }

    /// Adds a GIMBAL_DEVICE_ATTITUDE_STATUS sample.
    pub fn push_gimbal(&mut self, t_us: u64, fix: GimbalFix) {
        self.gimbal.push(t_us, fix);
    }

    /// Forgets everything (the autopilot rebooted: its clock started again).
    pub fn clear(&mut self) {
        *self = PoseBuffer::default();
    }

    /// The newest sample time of the three streams (position, attitude, gimbal).
    pub fn newest_us(&self) -> [Option<u64>; 3] {
        [
            self.position.newest_us(),
            self.attitude.newest_us(),
            self.gimbal.newest_us(),
        ]
    }

    /// The position at `t_us`, if known.
    pub fn position_at(&self, t_us: u64) -> Option<PositionFix> {
        self.position.at(t_us)
    }

    /// The camera pose at autopilot time `t_us` in the local NED frame `frame` (around home):
    /// each stream interpolated at that instant (slerp for the attitudes), the gimbal
    /// quaternion composed with the vehicle attitude as its frame requires. The camera sits at
    /// the vehicle's position.
    pub fn pose_at(&self, t_us: u64, frame: &LocalTangentFrame) -> Result<FollowPose, Missing> {
        let pos = self.position.at(t_us).ok_or(Missing::Position)?;
        let att = self.attitude.at(t_us).ok_or(Missing::Attitude)?;
        let gim = self.gimbal.at(t_us).ok_or(Missing::Gimbal)?;
        let g = Geodetic::new(pos.lat_deg, pos.lon_deg, pos.alt_amsl_m)
            .map_err(|_| Missing::Position)?;
        Ok(FollowPose {
            camera: CameraPose {
                position_ned: frame.to_ned(&g),
                attitude: camera_from_gimbal_quaternion(&gim.q, gim.frame, &att),
            },
            vehicle_attitude: att,
            vel_ned_mps: pos.vel_ned_mps,
            gimbal_frame: gim.frame,
        })
    }
}

/// Estimates the autopilot clock from the telemetry: each message gives
/// `d = local receive time - its time_boot`, which is the clock offset plus the message's
/// transport delay; the minimum over a sliding window is the offset with the least delay.
/// (Equivalently, the autopilot time is the maximum of `time_boot - local` over the window.)
#[derive(Debug, Clone)]
pub struct ClockSync {
    window_us: i64,
    /// Monotonic deque of `(local_us, d_us)`: increasing `d` from front to back, so the
    /// front is the window's minimum.
    mins: VecDeque<(i64, i64)>,
    last_autopilot_us: Option<u64>,
}

impl ClockSync {
    /// An estimator taking the minimum over the last `window_s` seconds (a window long
    /// enough to include a message with a short delay, short enough to follow clock drift).
    pub fn new(window_s: f64) -> ClockSync {
        ClockSync {
            window_us: (window_s * 1e6) as i64,
            mins: VecDeque::new(),
            last_autopilot_us: None,
        }
    }

    /// A message stamped `autopilot_us` arrived at local time `local_us`. Returns true when
    /// the autopilot clock went back by more than [`REBOOT_STEP_US`] (a reboot): the
    /// estimate then starts again from this message.
    pub fn observe(&mut self, autopilot_us: u64, local_us: i64) -> bool {
        let rebooted = self
            .last_autopilot_us
            .is_some_and(|last| autopilot_us + REBOOT_STEP_US < last);
        if rebooted {
            self.mins.clear();
            self.last_autopilot_us = None;
        }
        self.last_autopilot_us = Some(
            self.last_autopilot_us
                .map_or(autopilot_us, |l| l.max(autopilot_us)),
        );
        let d = local_us.saturating_sub(i64::try_from(autopilot_us).unwrap_or(i64::MAX));
        while self.mins.back().is_some_and(|b| b.1 >= d) {
            self.mins.pop_back();
        }
        self.mins.push_back((local_us, d));
        while self
            .mins
            .front()
            .is_some_and(|f| f.0 < local_us - self.window_us)
        {
            self.mins.pop_front();
        }
        rebooted
    }

    /// The offset estimate `local - autopilot` (µs), once a message arrived.
    pub fn offset_us(&self) -> Option<i64> {
        self.mins.front().map(|f| f.1)
    }

    /// The autopilot time at local time `local_us` (µs since its boot), once known; `None`
    /// also before the autopilot's boot.
    pub fn autopilot_us(&self, local_us: i64) -> Option<u64> {
        u64::try_from(local_us.checked_sub(self.offset_us()?)?).ok()
    }

    /// The local time of autopilot time `autopilot_us`, once known.
    pub fn local_us(&self, autopilot_us: u64) -> Option<i64> {
        i64::try_from(autopilot_us)
            .ok()?
            .checked_add(self.offset_us()?)
    }
}

/// Places `world` around the autopilot's home: the scenario origin's latitude and longitude
/// become home's, and sea level (the origin's altitude, the plane down = 0) home's altitude.
/// The objects keep their positions relative to the origin (local NED), so they are now
/// where the scenario puts them relative to home.
pub fn place_world(world: &mut World, home: &Geodetic) {
    let o = &mut world.scenario.origin;
    o.lat_deg = home.lat_deg;
    o.lon_deg = home.lon_deg;
    o.alt_amsl_m = home.alt_m;
}

/// Horizontal distance between two positions (m), for "home moved" checks.
pub fn horizontal_distance_m(a: &Geodetic, b: &Geodetic) -> f64 {
    let frame = LocalTangentFrame::new(*a);
    let d: Vector3<f64> = frame.to_ned(b);
    d.xy().norm()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::Scenario;
    use mgmot_core::geo::attitude::camera_from_heading_pitch_deg;

    fn fix(lat: f64, lon: f64, alt: f64) -> PositionFix {
        PositionFix {
            lat_deg: lat,
            lon_deg: lon,
            alt_amsl_m: alt,
            relative_alt_m: alt - 100.0,
            vel_ned_mps: [1.0, 0.0, 0.0],
        }
    }

    fn level() -> UnitQuaternion<f64> {
        UnitQuaternion::identity()
    }

    fn earth_gimbal(heading_deg: f64, pitch_below_deg: f64) -> GimbalFix {
        GimbalFix {
            q: UnitQuaternion::from_euler_angles(
                0.0,
                -pitch_below_deg.to_radians(),
                heading_deg.to_radians(),
            ),
            frame: GimbalYawFrame::Earth,
        }
    }

    fn home() -> LocalTangentFrame {
        LocalTangentFrame::new(Geodetic::new(47.0, 9.0, 100.0).unwrap())
    }

    #[test]
    fn flags_pick_the_frame_and_body_overrides_them() {
        let f = |flags| gimbal_yaw_frame(flags, GimbalReport::Flags);
        assert_eq!(
            f(GimbalDeviceFlags::GIMBAL_DEVICE_FLAGS_YAW_IN_EARTH_FRAME
                | GimbalDeviceFlags::GIMBAL_DEVICE_FLAGS_YAW_LOCK),
            GimbalYawFrame::Earth
        );
        assert_eq!(
            f(GimbalDeviceFlags::GIMBAL_DEVICE_FLAGS_YAW_IN_VEHICLE_FRAME),
            GimbalYawFrame::Vehicle
        );
        assert_eq!(
            f(GimbalDeviceFlags::GIMBAL_DEVICE_FLAGS_YAW_LOCK),
            GimbalYawFrame::Earth
        );
        assert_eq!(f(GimbalDeviceFlags::empty()), GimbalYawFrame::Vehicle);
        assert_eq!(
            gimbal_yaw_frame(
                GimbalDeviceFlags::GIMBAL_DEVICE_FLAGS_YAW_IN_EARTH_FRAME,
                GimbalReport::Body
            ),
            GimbalYawFrame::Body
        );
    }

    #[test]
    fn position_interpolates_between_samples_and_holds_briefly() {
        let mut b = PoseBuffer::default();
        b.push_position(1_000_000, fix(47.0, 9.0, 130.0));
        b.push_position(1_100_000, fix(47.0001, 9.0, 140.0));
        let mid = b.position_at(1_050_000).unwrap();
        assert!((mid.lat_deg - 47.00005).abs() < 1e-12);
        assert!((mid.alt_amsl_m - 135.0).abs() < 1e-9);
        // Held for MAX_HOLD after the newest sample, unknown beyond.
        assert_eq!(
            b.position_at(1_100_000 + MAX_HOLD_US).unwrap().alt_amsl_m,
            140.0
        );
        assert!(b.position_at(1_100_001 + MAX_HOLD_US).is_none());
        assert!(b.position_at(999_999).is_none());
        // A late message is inserted in order.
        b.push_position(1_020_000, fix(47.0, 9.0, 200.0));
        assert_eq!(b.position_at(1_020_000).unwrap().alt_amsl_m, 200.0);
        // No interpolation across a gap.
        b.push_position(1_100_000 + MAX_GAP_US + 1, fix(47.0, 9.0, 130.0));
        assert!(b.position_at(1_200_000).is_none());
    }

    #[test]
    fn old_samples_are_forgotten() {
        let mut b = PoseBuffer::default();
        for k in 0..200u64 {
            b.push_attitude(k * 100_000, level());
        }
        assert!(b.attitude.samples.len() as u64 <= KEEP_US / 100_000 + 1);
        assert!(b.attitude.at(0).is_none());
    }

    #[test]
    fn pose_composes_gimbal_and_vehicle_and_slerps() {
        let frame = home();
        let mut b = PoseBuffer::default();
        assert_eq!(b.pose_at(0, &frame).unwrap_err(), Missing::Position);
        let p = fix(47.0, 9.0, 130.0);
        b.push_position(0, p);
        b.push_position(100_000, p);
        assert_eq!(b.pose_at(50_000, &frame).unwrap_err(), Missing::Attitude);
        let yawed = UnitQuaternion::from_euler_angles(0.0, 0.0, 0.5);
        b.push_attitude(0, yawed);
        b.push_attitude(100_000, yawed);
        assert_eq!(b.pose_at(50_000, &frame).unwrap_err(), Missing::Gimbal);
        b.push_gimbal(0, earth_gimbal(10.0, 40.0));
        b.push_gimbal(100_000, earth_gimbal(30.0, 60.0));
        let pose = b.pose_at(50_000, &frame).unwrap();
        // Halfway along the single rotation between the two gimbal attitudes (which is close
        // to, not exactly, the midpoint of their Euler angles).
        let a = camera_from_heading_pitch_deg(10.0, 40.0, 0.0);
        let c = camera_from_heading_pitch_deg(30.0, 60.0, 0.0);
        let m = pose.camera.attitude;
        assert!((m.angle_to(&a) - a.angle_to(&c) / 2.0).abs() < 1e-9);
        assert!((m.angle_to(&c) - a.angle_to(&c) / 2.0).abs() < 1e-9);
        assert!((pose.camera.position_ned.z + 30.0).abs() < 1e-6);
        let s = pose.drone_state();
        assert!((s.yaw_deg - 0.5f64.to_degrees()).abs() < 1e-9);
        assert!((s.altitude_m() - 30.0).abs() < 1e-6);
        assert!((s.cam_heading_deg - 20.0).abs() < 1.5 && (s.cam_pitch_deg - 50.0).abs() < 1.5);

        // Vehicle frame: the vehicle's yaw is added; body frame: its whole attitude.
        let mut v = b.clone();
        let rel = GimbalFix {
            q: UnitQuaternion::from_euler_angles(0.0, -0.7, 0.2),
            frame: GimbalYawFrame::Vehicle,
        };
        v.push_gimbal(200_000, rel);
        v.push_position(200_000, p);
        let tilted = UnitQuaternion::from_euler_angles(0.1, -0.05, 0.5);
        v.push_attitude(200_000, tilted);
        let (yaw, pitch, _) =
            camera_to_ypr_rad(&v.pose_at(200_000, &frame).unwrap().camera.attitude);
        assert!((yaw - 0.7).abs() < 1e-9 && (pitch + 0.7).abs() < 1e-9);
        v.push_gimbal(
            200_000,
            GimbalFix {
                frame: GimbalYawFrame::Body,
                ..rel
            },
        );
        let body = v.pose_at(200_000, &frame).unwrap().camera.attitude;
        let want = camera_from_gimbal_quaternion(&rel.q, GimbalYawFrame::Body, &tilted);
        assert!(body.angle_to(&want) < 1e-12);
    }

    #[test]
    fn slerp_takes_the_short_way_for_the_double_cover() {
        let a = UnitQuaternion::from_euler_angles(0.0, 0.0, 0.1);
        let b = UnitQuaternion::new_unchecked(
            -UnitQuaternion::from_euler_angles(0.0, 0.0, 0.3).into_inner(),
        );
        let m = slerp(&a, &b, 0.5);
        assert!(m.angle_to(&UnitQuaternion::from_euler_angles(0.0, 0.0, 0.2)) < 1e-9);
    }

    #[test]
    fn mavlink_inputs_are_checked() {
        assert!(quaternion_wxyz([f32::NAN, 0.0, 0.0, 0.0]).is_none());
        assert!(quaternion_wxyz([0.0, 0.0, 0.0, 0.0]).is_none());
        assert!(quaternion_wxyz([1.0, 0.0, 0.0, 0.0]).is_some());
        assert!(vehicle_attitude(f32::NAN, 0.0, 0.0).is_none());
        assert!(PositionFix::from_mavlink(0, 0, 0, 0, [0; 3]).is_none());
        assert!(PositionFix::from_mavlink(i32::MAX, 0, 0, 0, [0; 3]).is_none());
        let f = PositionFix::from_mavlink(470_000_000, 90_000_000, 130_000, 30_000, [100, -50, 0])
            .unwrap();
        assert_eq!(f.vel_ned_mps, [1.0, -0.5, 0.0]);
        let h = f.implied_home().unwrap();
        assert!((h.alt_m - 100.0).abs() < 1e-9 && (h.lat_deg - 47.0).abs() < 1e-12);
    }

    #[test]
    fn clock_takes_the_least_delayed_message_and_resets_on_reboot() {
        let mut c = ClockSync::new(10.0);
        assert!(c.autopilot_us(0).is_none());
        // True offset: local = autopilot + 5 s; delays 3, 1, 7 ms.
        for (ap, delay) in [
            (100_000_000u64, 3_000i64),
            (100_020_000, 1_000),
            (100_040_000, 7_000),
        ] {
            assert!(!c.observe(ap, ap as i64 + 5_000_000 + delay));
        }
        assert_eq!(c.offset_us(), Some(5_001_000));
        assert_eq!(c.autopilot_us(105_101_000), Some(100_100_000));
        assert_eq!(c.local_us(100_100_000), Some(105_101_000));
        // Out of order by a few ms is not a reboot.
        assert!(!c.observe(100_030_000, 105_045_000));
        // The 1 ms message leaves the window after 10 s; the estimate follows newer ones.
        assert!(!c.observe(100_040_000 + 11_000_000, 116_042_000));
        assert_eq!(c.offset_us(), Some(5_002_000));
        // Reboot: the clock goes back; the estimate restarts from the new message.
        assert!(c.observe(2_000_000, 120_000_000));
        assert_eq!(c.offset_us(), Some(118_000_000));
        assert!(!c.observe(2_020_000, 120_020_000));
    }

    #[test]
    fn world_is_placed_around_home() {
        let s = Scenario::load("gimbal_swings").unwrap();
        let mut w = World::new(s, 3);
        let before = w.objects_at(10.0);
        let home = Geodetic::new(-35.363261, 149.165230, 584.0).unwrap();
        place_world(&mut w, &home);
        let o = &w.scenario.origin;
        assert_eq!(
            (o.lat_deg, o.lon_deg, o.alt_amsl_m),
            (-35.363261, 149.165230, 584.0)
        );
        // Objects keep their place relative to the origin.
        assert_eq!(w.objects_at(10.0), before);
        let optics = crate::truth::Optics::new(&w.scenario).unwrap();
        assert_eq!(optics.frame.origin(), home);
        let there = Geodetic::new(-35.363261, 149.166230, 584.0).unwrap();
        let d = horizontal_distance_m(&home, &there);
        assert!((d - 90.8).abs() < 1.0, "{d}");
    }
}
