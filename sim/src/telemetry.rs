//! The simulated autopilot's MAVLink content: which messages go out when (rates with
//! jitter, changeable with MAV_CMD_SET_MESSAGE_INTERVAL), what they contain (the reported,
//! faulty state), and the answers to TIMESYNC, SET_MESSAGE_INTERVAL and REQUEST_MESSAGE.
//! No IO here: the binary moves these messages over a link.

use crate::scenario::{AutopilotKind, GimbalReport, YawFrame};
use crate::world::{World, REBOOT_SILENCE_S};
// MOUNT_ORIENTATION is deprecated in common.xml but still what many gimbal drivers and
// ground stations read; the simulator sends it alongside the gimbal protocol v2 message.
use mavlink::Message;
use mgmot_wire::dialect::{
    GimbalDeviceFlags, GpsFixType, MavAutopilot, MavCmd, MavModeFlag, MavResult, MavState, MavType,
};
#[allow(deprecated)]
use mgmot_wire::dialect::{
    MavMessage, ATTITUDE_DATA, COMMAND_ACK_DATA, COMMAND_LONG_DATA,
    GIMBAL_DEVICE_ATTITUDE_STATUS_DATA, GLOBAL_POSITION_INT_DATA, GPS_RAW_INT_DATA, HEARTBEAT_DATA,
    HOME_POSITION_DATA, MOUNT_ORIENTATION_DATA, SYSTEM_TIME_DATA, TIMESYNC_DATA,
};
use nalgebra::{UnitQuaternion, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// RNG stream of the send-time jitter.
const STREAM_JITTER: u64 = 4;

/// The periodic streams of the simulated autopilot.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stream {
    /// HEARTBEAT, 1 Hz.
    Heartbeat,
    /// GLOBAL_POSITION_INT, 10 Hz.
    GlobalPositionInt,
    /// ATTITUDE, 20 Hz.
    Attitude,
    /// GIMBAL_DEVICE_ATTITUDE_STATUS, 10 Hz.
    GimbalDeviceAttitudeStatus,
    /// MOUNT_ORIENTATION, 10 Hz.
    MountOrientation,
    /// HOME_POSITION, 0.5 Hz.
    HomePosition,
    /// SYSTEM_TIME, 1 Hz.
    SystemTime,
    /// GPS_RAW_INT, 1 Hz: the receiver's fix with its horizontal accuracy (`h_acc`).
    GpsRawInt,
}

/// The smallest horizontal accuracy the simulated receiver claims (m): a receiver never says
/// it is exact, and MAVLink's `h_acc` of 0 means "not reported".
pub const GPS_MIN_H_ACC_M: f64 = 0.01;

impl Stream {
    /// All streams.
    pub const ALL: [Stream; 8] = [
        Stream::Heartbeat,
        Stream::GlobalPositionInt,
        Stream::Attitude,
        Stream::GimbalDeviceAttitudeStatus,
        Stream::MountOrientation,
        Stream::HomePosition,
        Stream::SystemTime,
        Stream::GpsRawInt,
    ];

    /// MAVLink message id.
    pub fn message_id(self) -> u32 {
        match self {
            Stream::Heartbeat => 0,
            Stream::GlobalPositionInt => 33,
            Stream::Attitude => 30,
            Stream::GimbalDeviceAttitudeStatus => 285,
            Stream::MountOrientation => 265,
            Stream::HomePosition => 242,
            Stream::SystemTime => 2,
            Stream::GpsRawInt => 24,
        }
    }

    /// Default interval.
    pub fn default_interval_s(self) -> f64 {
        match self {
            Stream::Heartbeat | Stream::SystemTime | Stream::GpsRawInt => 1.0,
            Stream::GlobalPositionInt
            | Stream::GimbalDeviceAttitudeStatus
            | Stream::MountOrientation => 0.1,
            Stream::Attitude => 0.05,
            Stream::HomePosition => 2.0,
        }
    }

    fn from_message_id(id: u32) -> Option<Stream> {
        Stream::ALL.into_iter().find(|s| s.message_id() == id)
    }

    /// The interval the stream has when nobody asked for another (`None`: off). ArduCopter's
    /// default stream rates are 0: only its HEARTBEAT flows unasked.
    pub fn start_interval_s(self, kind: AutopilotKind) -> Option<f64> {
        match kind {
            AutopilotKind::Generic => Some(self.default_interval_s()),
            AutopilotKind::Ardupilot => {
                (self == Stream::Heartbeat).then(|| self.default_interval_s())
            }
        }
    }

    /// Whether the autopilot can send this stream at all. ArduPilot has no MOUNT_ORIENTATION
    /// in its message set ("No ap_message for mavlink id (265)").
    fn offered_by(self, kind: AutopilotKind) -> bool {
        !(kind == AutopilotKind::Ardupilot && self == Stream::MountOrientation)
    }
}

/// When each stream is next due, and at which interval.
#[derive(Debug, Clone)]
pub struct Scheduler {
    /// Per stream: interval (`None` = disabled) and the next due time (sim seconds).
    entries: Vec<(Stream, Option<f64>, f64)>,
    jitter: f64,
    rng: ChaCha8Rng,
    kind: AutopilotKind,
    /// `faults.reboots_s` in order, and how many of them have happened.
    reboots: Vec<f64>,
    rebooted: usize,
}

impl Scheduler {
    /// Default rates; first messages at small staggered offsets.
    pub fn new(world: &World) -> Scheduler {
        let mut rng = ChaCha8Rng::seed_from_u64(world.seed);
        rng.set_stream(world.scenario.vehicle_stream(STREAM_JITTER));
        let kind = world.scenario.telemetry.autopilot;
        let mut reboots = world.scenario.faults.reboots_s.clone();
        reboots.sort_by(f64::total_cmp);
        let mut scheduler = Scheduler {
            entries: Vec::new(),
            jitter: world.scenario.telemetry.rate_jitter,
            rng,
            kind,
            reboots,
            rebooted: 0,
        };
        scheduler.restart(0.0);
        scheduler
    }

    /// Every stream back at its start-up interval, the first messages at `t_s` (staggered).
    fn restart(&mut self, t_s: f64) {
        let kind = self.kind;
        self.entries = Stream::ALL
            .iter()
            .enumerate()
            .map(|(i, s)| (*s, s.start_interval_s(kind), t_s + 0.001 * i as f64))
            .collect();
    }

    /// Pops every message due at or before `t_s`, in time order, as `(send_time_s, stream)`.
    /// A reboot (`faults.reboots_s`) on the way forgets every interval asked for; the
    /// autopilot speaks again [`REBOOT_SILENCE_S`] later.
    pub fn due(&mut self, t_s: f64) -> Vec<(f64, Stream)> {
        while let Some(&r) = self.reboots.get(self.rebooted).filter(|r| **r <= t_s) {
            self.rebooted += 1;
            self.restart(r + REBOOT_SILENCE_S);
        }
        let mut out = Vec::new();
        loop {
            let next = self
                .entries
                .iter_mut()
                .filter(|e| e.1.is_some() && e.2 <= t_s)
                .min_by(|a, b| a.2.total_cmp(&b.2));
            let Some(entry) = next else { break };
            let interval = entry.1.unwrap_or(1.0);
            out.push((entry.2, entry.0));
            let j = if self.jitter > 0.0 {
                self.rng.random_range(-self.jitter..=self.jitter)
            } else {
                0.0
            };
            entry.2 += interval * (1.0 + j);
        }
        out
    }

    /// Time of the next due message.
    pub fn next_due_s(&self) -> Option<f64> {
        self.entries
            .iter()
            .filter(|e| e.1.is_some())
            .map(|e| e.2)
            .min_by(|a, b| a.total_cmp(b))
    }

    /// MAV_CMD_SET_MESSAGE_INTERVAL: `interval_us` -1 disables, 0 restores the default.
    pub fn set_interval(&mut self, message_id: u32, interval_us: f64, now_s: f64) -> MavResult {
        let Some(stream) = Stream::from_message_id(message_id) else {
            return MavResult::MAV_RESULT_UNSUPPORTED;
        };
        if !stream.offered_by(self.kind) {
            // What ArduPilot answers for a message id it has no sender for.
            return MavResult::MAV_RESULT_DENIED;
        }
        let interval = if interval_us < -0.5 {
            None
        } else if interval_us < 0.5 {
            stream.start_interval_s(self.kind)
        } else if interval_us < 1000.0 {
            // Faster than 1 kHz is not something a real autopilot accepts.
            return MavResult::MAV_RESULT_DENIED;
        } else {
            Some(interval_us / 1e6)
        };
        for e in &mut self.entries {
            if e.0 == stream {
                e.1 = interval;
                e.2 = now_s;
            }
        }
        MavResult::MAV_RESULT_ACCEPTED
    }
}

/// Who sends a reply: the vehicle (its autopilot or gimbal component), or a ground station
/// whose messages the autopilot forwards.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Sender {
    /// The simulated vehicle.
    Vehicle,
    /// A ground station (system 255, component 190).
    GroundStation,
}

/// A message to send in answer to one received.
#[derive(Debug, Clone)]
pub struct Reply {
    /// Who sends it.
    pub sender: Sender,
    /// The message.
    pub msg: MavMessage,
}

/// Builds the autopilot's messages from the world.
#[derive(Debug, Clone)]
pub struct Autopilot<'w> {
    world: &'w World,
    frame: mgmot_core::geo::LocalTangentFrame,
}

impl<'w> Autopilot<'w> {
    /// For `world`; errors when the origin is not a valid geodetic position.
    pub fn new(world: &'w World) -> Result<Autopilot<'w>, mgmot_core::geo::GeoError> {
        let o = &world.scenario.origin;
        let origin = mgmot_core::geo::Geodetic::new(o.lat_deg, o.lon_deg, o.alt_amsl_m)?;
        Ok(Autopilot {
            world,
            frame: mgmot_core::geo::LocalTangentFrame::new(origin),
        })
    }

    fn time_boot_ms(&self, t_s: f64) -> u32 {
        (self.world.autopilot_time_us(t_s) / 1000) as u32
    }

    /// The message of `stream` sent at `send_s`; it describes the state `telemetry_latency`
    /// earlier.
    #[allow(deprecated)] // MOUNT_ORIENTATION, see the import.
    pub fn message(&self, stream: Stream, send_s: f64) -> MavMessage {
        let w = self.world;
        let t = send_s - w.scenario.faults.telemetry_latency_ms / 1000.0;
        let rep = w.reported(t);
        let boot_ms = self.time_boot_ms(t);
        match stream {
            Stream::Heartbeat => MavMessage::HEARTBEAT(HEARTBEAT_DATA {
                custom_mode: 0,
                mavtype: MavType::MAV_TYPE_QUADROTOR,
                autopilot: MavAutopilot::MAV_AUTOPILOT_GENERIC,
                base_mode: MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED
                    | MavModeFlag::MAV_MODE_FLAG_GUIDED_ENABLED
                    | MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
                system_status: MavState::MAV_STATE_ACTIVE,
                mavlink_version: 3,
            }),
            Stream::GlobalPositionInt => {
                let g = self.frame.to_geodetic(&Vector3::from(rep.pos_ned_m));
                let [vn, ve, vd] = rep.vel_ned_mps;
                MavMessage::GLOBAL_POSITION_INT(GLOBAL_POSITION_INT_DATA {
                    time_boot_ms: boot_ms,
                    lat: (g.lat_deg * 1e7).round() as i32,
                    lon: (g.lon_deg * 1e7).round() as i32,
                    alt: (g.alt_m * 1000.0).round() as i32,
                    relative_alt: (rep.altitude_m() * 1000.0).round() as i32,
                    vx: (vn * 100.0).round() as i16,
                    vy: (ve * 100.0).round() as i16,
                    vz: (vd * 100.0).round() as i16,
                    hdg: ((rep.yaw_deg * 100.0).round() as u16) % 36000,
                })
            }
            Stream::Attitude => {
                let prev = w.reported(t - 0.05);
                let rate =
                    |a: f64, b: f64| (crate::motion::wrap_180(a - b)).to_radians() as f32 / 0.05;
                MavMessage::ATTITUDE(ATTITUDE_DATA {
                    time_boot_ms: boot_ms,
                    roll: rep.roll_deg.to_radians() as f32,
                    pitch: rep.pitch_deg.to_radians() as f32,
                    yaw: crate::motion::wrap_180(rep.yaw_deg).to_radians() as f32,
                    rollspeed: rate(rep.roll_deg, prev.roll_deg),
                    pitchspeed: rate(rep.pitch_deg, prev.pitch_deg),
                    yawspeed: rate(rep.yaw_deg, prev.yaw_deg),
                })
            }
            Stream::GimbalDeviceAttitudeStatus => {
                // Gimbal FRD attitude: roll 0 (stabilised), pitch = -depression, yaw per frame.
                let truth = w.truth(t);
                let pitch = -rep.cam_pitch_deg.to_radians();
                let (yaw, flags) = match w.scenario.telemetry.gimbal_yaw_frame {
                    YawFrame::Earth => (
                        rep.cam_heading_deg.to_radians(),
                        GimbalDeviceFlags::GIMBAL_DEVICE_FLAGS_YAW_IN_EARTH_FRAME
                            | GimbalDeviceFlags::GIMBAL_DEVICE_FLAGS_YAW_LOCK,
                    ),
                    YawFrame::Vehicle => {
                        // The encoder measures yaw relative to the vehicle; only the gimbal
                        // faults apply to it (a vehicle yaw bias enters when composed).
                        let rel = truth.gimbal_yaw_vehicle_deg()
                            + crate::motion::wrap_180(rep.cam_heading_deg - truth.cam_heading_deg);
                        (
                            rel.to_radians(),
                            GimbalDeviceFlags::GIMBAL_DEVICE_FLAGS_YAW_IN_VEHICLE_FRAME,
                        )
                    }
                };
                let (q, flags) = match w.scenario.telemetry.gimbal_report {
                    GimbalReport::AsFlagged => {
                        (UnitQuaternion::from_euler_angles(0.0, pitch, yaw), flags)
                    }
                    GimbalReport::ServoBodyFrame => {
                        // The servos hold the camera's earth-frame pointing by leaning against
                        // the vehicle: what they are commanded is the camera relative to the
                        // body, vehicle^-1 * camera, which ArduPilot reports under flags for
                        // earth-frame roll and pitch and a vehicle-frame yaw.
                        let vehicle = UnitQuaternion::from_euler_angles(
                            rep.roll_deg.to_radians(),
                            rep.pitch_deg.to_radians(),
                            rep.yaw_deg.to_radians(),
                        );
                        let camera = UnitQuaternion::from_euler_angles(
                            0.0,
                            pitch,
                            rep.cam_heading_deg.to_radians(),
                        );
                        (
                            vehicle.inverse() * camera,
                            GimbalDeviceFlags::GIMBAL_DEVICE_FLAGS_YAW_IN_VEHICLE_FRAME,
                        )
                    }
                };
                MavMessage::GIMBAL_DEVICE_ATTITUDE_STATUS(GIMBAL_DEVICE_ATTITUDE_STATUS_DATA {
                    time_boot_ms: boot_ms,
                    q: [q.w as f32, q.i as f32, q.j as f32, q.k as f32],
                    angular_velocity_x: f32::NAN,
                    angular_velocity_y: f32::NAN,
                    angular_velocity_z: f32::NAN,
                    flags: flags
                        | GimbalDeviceFlags::GIMBAL_DEVICE_FLAGS_ROLL_LOCK
                        | GimbalDeviceFlags::GIMBAL_DEVICE_FLAGS_PITCH_LOCK,
                    // ArduPilot numbers its mounts from 1 and sends as the autopilot; a gimbal
                    // device speaking for itself (component 154) sends 0.
                    gimbal_device_id: u8::from(
                        w.scenario.telemetry.autopilot == AutopilotKind::Ardupilot,
                    ),
                    ..Default::default()
                })
            }
            Stream::MountOrientation => MavMessage::MOUNT_ORIENTATION(MOUNT_ORIENTATION_DATA {
                time_boot_ms: boot_ms,
                roll: 0.0,
                pitch: -rep.cam_pitch_deg as f32,
                yaw: rep.gimbal_yaw_vehicle_deg() as f32,
                yaw_absolute: rep.cam_heading_deg as f32,
            }),
            Stream::HomePosition => {
                let o = &w.scenario.origin;
                MavMessage::HOME_POSITION(HOME_POSITION_DATA {
                    latitude: (o.lat_deg * 1e7).round() as i32,
                    longitude: (o.lon_deg * 1e7).round() as i32,
                    altitude: (o.alt_amsl_m * 1000.0).round() as i32,
                    x: 0.0,
                    y: 0.0,
                    z: 0.0,
                    q: [1.0, 0.0, 0.0, 0.0],
                    approach_x: 0.0,
                    approach_y: 0.0,
                    approach_z: 0.0,
                    ..Default::default()
                })
            }
            Stream::SystemTime => MavMessage::SYSTEM_TIME(SYSTEM_TIME_DATA {
                time_unix_usec: ((w.scenario.origin.start_unix_s + t) * 1e6).round() as u64,
                time_boot_ms: boot_ms,
            }),
            Stream::GpsRawInt => {
                // The reported (noisy) position, as GLOBAL_POSITION_INT; `h_acc` is the
                // receiver's 1-sigma horizontal error, `faults.gps_noise_m`, in mm.
                let g = self.frame.to_geodetic(&Vector3::from(rep.pos_ned_m));
                let [vn, ve, _] = rep.vel_ned_mps;
                let h_acc_m = w.scenario.faults.gps_noise_m.max(GPS_MIN_H_ACC_M);
                MavMessage::GPS_RAW_INT(GPS_RAW_INT_DATA {
                    time_usec: u64::from(boot_ms) * 1000,
                    lat: (g.lat_deg * 1e7).round() as i32,
                    lon: (g.lon_deg * 1e7).round() as i32,
                    alt: (g.alt_m * 1000.0).round() as i32,
                    eph: 80,
                    epv: 120,
                    vel: (vn.hypot(ve) * 100.0).round().min(65534.0) as u16,
                    cog: ((ve.atan2(vn).to_degrees().rem_euclid(360.0) * 100.0).round() as u16)
                        % 36000,
                    fix_type: GpsFixType::GPS_FIX_TYPE_3D_FIX,
                    satellites_visible: 14,
                    h_acc: (h_acc_m * 1000.0).round() as u32,
                    ..Default::default()
                })
            }
        }
    }

    /// The answer to an incoming message at sim time `now_s`: replies to send (TIMESYNC,
    /// COMMAND_ACK, requested messages). Interval changes are applied to `scheduler`.
    /// `from` is the sender's (system id, component id), the target of the replies.
    pub fn handle(
        &self,
        msg: &MavMessage,
        from: (u8, u8),
        now_s: f64,
        scheduler: &mut Scheduler,
    ) -> Vec<Reply> {
        let vehicle = |msg| Reply {
            sender: Sender::Vehicle,
            msg,
        };
        match msg {
            MavMessage::TIMESYNC(ts) if ts.tc1 == 0 => {
                let now_ns = (self.world.autopilot_time_us(now_s) as i64).saturating_mul(1000);
                let answer = |tc1: i64| {
                    MavMessage::TIMESYNC(TIMESYNC_DATA {
                        tc1,
                        ts1: ts.ts1,
                        target_system: from.0,
                        target_component: from.1,
                    })
                };
                let mut replies = vec![vehicle(answer(now_ns))];
                if self.world.scenario.faults.gcs_timesync_answers {
                    // The ground station answers with its own clock (UNIX time).
                    let unix_s = self.world.scenario.origin.start_unix_s + now_s;
                    replies.push(Reply {
                        sender: Sender::GroundStation,
                        msg: answer((unix_s * 1e9) as i64),
                    });
                }
                replies
            }
            MavMessage::COMMAND_LONG(cmd) => self
                .command(cmd, from, now_s, scheduler)
                .into_iter()
                .map(vehicle)
                .collect(),
            _ => Vec::new(),
        }
    }

    fn command(
        &self,
        cmd: &COMMAND_LONG_DATA,
        from: (u8, u8),
        now_s: f64,
        scheduler: &mut Scheduler,
    ) -> Vec<MavMessage> {
        let sys = self.world.scenario.telemetry.system_id;
        if cmd.target_system != 0 && cmd.target_system != sys {
            return Vec::new();
        }
        let ack = |result: MavResult| {
            MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
                command: cmd.command,
                result,
                target_system: from.0,
                target_component: from.1,
                ..Default::default()
            })
        };
        match cmd.command {
            MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL => {
                let result =
                    scheduler.set_interval(cmd.param1 as u32, f64::from(cmd.param2), now_s);
                vec![ack(result)]
            }
            MavCmd::MAV_CMD_REQUEST_MESSAGE => match Stream::from_message_id(cmd.param1 as u32)
                .filter(|s| s.offered_by(self.world.scenario.telemetry.autopilot))
            {
                Some(stream) => vec![
                    ack(MavResult::MAV_RESULT_ACCEPTED),
                    self.message(stream, now_s),
                ],
                None => vec![ack(MavResult::MAV_RESULT_UNSUPPORTED)],
            },
            _ => vec![ack(MavResult::MAV_RESULT_UNSUPPORTED)],
        }
    }
}

/// Name of a message, for logs and tests.
pub fn message_name(msg: &MavMessage) -> &'static str {
    msg.message_name()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::Scenario;
    use mgmot_core::geo::attitude::{
        camera_from_gimbal_quaternion, camera_from_heading_pitch_deg, GimbalYawFrame,
    };

    /// The gimbal attitude a GIMBAL_DEVICE_ATTITUDE_STATUS carries.
    fn sent_quaternion(g: &GIMBAL_DEVICE_ATTITUDE_STATUS_DATA) -> UnitQuaternion<f64> {
        UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
            f64::from(g.q[0]),
            f64::from(g.q[1]),
            f64::from(g.q[2]),
            f64::from(g.q[3]),
        ))
    }

    fn world(name: &str) -> World {
        let s = Scenario::load(name).unwrap();
        let seed = s.seed;
        World::new(s, seed)
    }

    #[test]
    fn default_rates() {
        let w = world("calm_baseline");
        let mut sch = Scheduler::new(&w);
        let msgs = sch.due(10.0);
        let count = |s: Stream| msgs.iter().filter(|(_, m)| *m == s).count() as f64;
        assert!((count(Stream::Attitude) - 200.0).abs() <= 10.0);
        assert!((count(Stream::GlobalPositionInt) - 100.0).abs() <= 5.0);
        assert!((count(Stream::Heartbeat) - 10.0).abs() <= 1.0);
        assert!(msgs.windows(2).all(|p| p[0].0 <= p[1].0));
    }

    /// GPS_RAW_INT carries the reported position and the receiver's 1-sigma horizontal error,
    /// `faults.gps_noise_m`, as `h_acc` in mm (at least [`GPS_MIN_H_ACC_M`]), with a 3D fix.
    #[test]
    fn gps_raw_int_reports_the_scenarios_gps_noise() {
        for (name, h_acc_mm) in [("gimbal_pitch_bias", 800), ("calm_baseline", 10)] {
            let w = world(name);
            let ap = Autopilot::new(&w).unwrap();
            let MavMessage::GPS_RAW_INT(g) = ap.message(Stream::GpsRawInt, 3.0) else {
                panic!("not GPS_RAW_INT");
            };
            let MavMessage::GLOBAL_POSITION_INT(p) = ap.message(Stream::GlobalPositionInt, 3.0)
            else {
                panic!("not GLOBAL_POSITION_INT");
            };
            assert_eq!(g.h_acc, h_acc_mm, "{name}");
            assert_eq!(g.fix_type, GpsFixType::GPS_FIX_TYPE_3D_FIX);
            assert_eq!((g.lat, g.lon, g.alt), (p.lat, p.lon, p.alt), "{name}");
            assert_eq!(g.time_usec, u64::from(p.time_boot_ms) * 1000);
        }
    }

    #[test]
    fn set_interval_and_disable() {
        let w = world("calm_baseline");
        let mut sch = Scheduler::new(&w);
        assert_eq!(
            sch.set_interval(30, 200_000.0, 0.0),
            MavResult::MAV_RESULT_ACCEPTED
        );
        assert_eq!(
            sch.set_interval(33, -1.0, 0.0),
            MavResult::MAV_RESULT_ACCEPTED
        );
        assert_eq!(
            sch.set_interval(9999, 1e5, 0.0),
            MavResult::MAV_RESULT_UNSUPPORTED
        );
        let msgs = sch.due(10.0);
        let att = msgs.iter().filter(|(_, m)| *m == Stream::Attitude).count();
        assert!((48..=53).contains(&att), "{att}");
        assert!(!msgs.iter().any(|(_, m)| *m == Stream::GlobalPositionInt));
    }

    #[test]
    fn gimbal_quaternion_decodes_to_true_camera_in_both_frames() {
        for frame in [YawFrame::Earth, YawFrame::Vehicle] {
            let mut s = Scenario::load("camera_desync").unwrap();
            s.telemetry.gimbal_yaw_frame = frame;
            s.faults = Default::default();
            let w = World::new(s, 3);
            let ap = Autopilot::new(&w).unwrap();
            let t = 12.3;
            let MavMessage::GIMBAL_DEVICE_ATTITUDE_STATUS(g) =
                ap.message(Stream::GimbalDeviceAttitudeStatus, t)
            else {
                panic!()
            };
            let q = sent_quaternion(&g);
            let truth = w.truth(t);
            let vehicle = UnitQuaternion::from_euler_angles(
                truth.roll_deg.to_radians(),
                truth.pitch_deg.to_radians(),
                truth.yaw_deg.to_radians(),
            );
            let yf = match frame {
                YawFrame::Earth => GimbalYawFrame::Earth,
                YawFrame::Vehicle => GimbalYawFrame::Vehicle,
            };
            let cam = camera_from_gimbal_quaternion(&q, yf, &vehicle);
            let want =
                camera_from_heading_pitch_deg(truth.cam_heading_deg, truth.cam_pitch_deg, 0.0);
            assert!(
                cam.angle_to(&want) < 1e-5,
                "{frame:?}: {}",
                cam.angle_to(&want)
            );
        }
    }

    #[test]
    fn servo_body_frame_report_composes_with_the_vehicle_to_the_true_camera() {
        let mut s = Scenario::load("ardupilot_servo").unwrap();
        s.faults = Default::default();
        let w = World::new(s, 5);
        let ap = Autopilot::new(&w).unwrap();
        let mut leaning = 0;
        for k in 0..300 {
            let t = 0.1 * f64::from(k);
            let MavMessage::GIMBAL_DEVICE_ATTITUDE_STATUS(g) =
                ap.message(Stream::GimbalDeviceAttitudeStatus, t)
            else {
                panic!()
            };
            assert_eq!(g.gimbal_device_id, 1);
            let q = sent_quaternion(&g);
            let truth = w.truth(t);
            let vehicle = UnitQuaternion::from_euler_angles(
                truth.roll_deg.to_radians(),
                truth.pitch_deg.to_radians(),
                truth.yaw_deg.to_radians(),
            );
            let want =
                camera_from_heading_pitch_deg(truth.cam_heading_deg, truth.cam_pitch_deg, 0.0);
            let body = camera_from_gimbal_quaternion(&q, GimbalYawFrame::Body, &vehicle);
            assert!(
                body.angle_to(&want) < 1e-5,
                "t {t}: {}",
                body.angle_to(&want)
            );
            let flagged = camera_from_gimbal_quaternion(&q, GimbalYawFrame::Vehicle, &vehicle);
            if truth.pitch_deg.abs() > 5.0 || truth.roll_deg.abs() > 5.0 {
                leaning += 1;
                assert!(flagged.angle_to(&want) > 2f64.to_radians(), "t {t}");
            }
        }
        assert!(leaning > 100, "the scenario leans: {leaning}");
    }

    #[test]
    fn answers_timesync_and_request_message() {
        let w = world("calm_baseline");
        let ap = Autopilot::new(&w).unwrap();
        let mut sch = Scheduler::new(&w);
        let r = ap.handle(
            &MavMessage::TIMESYNC(TIMESYNC_DATA {
                tc1: 0,
                ts1: 42,
                ..Default::default()
            }),
            (255, 190),
            1.0,
            &mut sch,
        );
        let MavMessage::TIMESYNC(ts) = &r[0].msg else {
            panic!()
        };
        assert_eq!(ts.ts1, 42);
        assert_eq!(ts.tc1, (121_000_000i64) * 1000);
        let req = MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
            command: MavCmd::MAV_CMD_REQUEST_MESSAGE,
            param1: 242.0,
            ..Default::default()
        });
        let r = ap.handle(&req, (255, 190), 1.0, &mut sch);
        assert_eq!(r.len(), 2);
        assert!(
            matches!(&r[0].msg, MavMessage::COMMAND_ACK(a) if a.result == MavResult::MAV_RESULT_ACCEPTED)
        );
        assert!(matches!(&r[1].msg, MavMessage::HOME_POSITION(_)));
    }
}
