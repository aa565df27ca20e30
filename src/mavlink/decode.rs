//! Incoming messages -> typed domain samples.

use super::dialect::{self, GimbalDeviceFlags, MavCmd, MavMessage, CAMERA_INFORMATION_DATA};
use crate::geo::attitude::GimbalYawFrame;
use crate::geo::Geodetic;
use crate::telemetry::{
    AttitudeSample, AutopilotTimeUs, GimbalSample, PositionFix, PositionSample,
};
use mavlink_core::MessageData as _;
use nalgebra::{Quaternion, UnitQuaternion, Vector3};

/// An operator's camera-tracking command (MAV_CMD_CAMERA_TRACK_*), in normalised image
/// coordinates (0..1, top-left origin) as the commands define them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum CameraCommand {
    /// MAV_CMD_CAMERA_TRACK_POINT: track what is at (x, y).
    TrackPoint {
        /// Horizontal position (0 = left).
        x: f32,
        /// Vertical position (0 = top).
        y: f32,
        /// How far from the point the target may be, as a fraction of the image width
        /// (0: the receiver's default).
        radius: f32,
    },
    /// MAV_CMD_CAMERA_TRACK_RECTANGLE: track what is inside the rectangle.
    TrackRectangle {
        /// Top-left x.
        x0: f32,
        /// Top-left y.
        y0: f32,
        /// Bottom-right x.
        x1: f32,
        /// Bottom-right y.
        y1: f32,
    },
    /// MAV_CMD_CAMERA_STOP_TRACKING.
    Stop,
}

/// What an incoming message means to mgmot.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Incoming {
    /// The autopilot is alive (HEARTBEAT from an autopilot component).
    AutopilotHeartbeat,
    /// GLOBAL_POSITION_INT, with its velocity.
    Position(PositionFix),
    /// ATTITUDE.
    Attitude(AttitudeSample),
    /// GIMBAL_DEVICE_ATTITUDE_STATUS, MOUNT_ORIENTATION or MOUNT_STATUS.
    Gimbal {
        /// The attitude (normalised).
        sample: GimbalSample,
        /// The quaternion's norm as sent, for the plausibility gate (`None`: sent as angles).
        quaternion_norm: Option<f64>,
    },
    /// HOME_POSITION (altitude AMSL).
    Home(Geodetic),
    /// GPS_RAW_INT with a fix and a horizontal accuracy (`h_acc`, sent as mm; 0, what a sender
    /// that does not fill the MAVLink 2 extension leaves, is "not reported").
    GnssAccuracy {
        /// The receiver's horizontal position accuracy (m).
        h_acc_m: f64,
    },
    /// A TIMESYNC answer to our request: `ts1_ns` is the companion time we sent, `tc1_ns`
    /// the autopilot's.
    TimeSyncAnswer {
        /// Autopilot time (ns).
        tc1_ns: i64,
        /// Our request's time (ns).
        ts1_ns: i64,
    },
    /// A camera tracking command addressed to us.
    Command {
        /// The command.
        command: CameraCommand,
        /// Its MAV_CMD number (for the COMMAND_ACK).
        mav_cmd: MavCmd,
    },
    /// MAV_CMD_REQUEST_MESSAGE for CAMERA_INFORMATION, addressed to us.
    CameraInformationRequest,
    /// A command sent to our component explicitly (not broadcast) that mgmot does not
    /// implement: the sender is owed a COMMAND_ACK saying so.
    UnsupportedCommand {
        /// Its MAV_CMD number.
        mav_cmd: MavCmd,
    },
}

impl Incoming {
    /// Whether this is a command (acted on or refused), as opposed to telemetry: with signing
    /// on, only signed commands are obeyed.
    pub fn is_command(&self) -> bool {
        matches!(
            self,
            Incoming::Command { .. }
                | Incoming::CameraInformationRequest
                | Incoming::UnsupportedCommand { .. }
        )
    }

    /// The MAV_CMD of a command (what its COMMAND_ACK names); `None` for telemetry.
    pub fn mav_cmd(&self) -> Option<MavCmd> {
        match self {
            Incoming::Command { mav_cmd, .. } | Incoming::UnsupportedCommand { mav_cmd } => {
                Some(*mav_cmd)
            }
            Incoming::CameraInformationRequest => Some(MavCmd::MAV_CMD_REQUEST_MESSAGE),
            _ => None,
        }
    }
}

/// A quaternion as sent, normalised, and its norm as sent; `None` for MAVLink's "no data"
/// marker (NaN, or all zeros). Whether the norm is plausible is the pose gate's call.
fn quaternion(q: [f32; 4]) -> Option<(UnitQuaternion<f64>, f64)> {
    let [w, x, y, z] = q.map(f64::from);
    if ![w, x, y, z].iter().all(|v| v.is_finite()) {
        return None;
    }
    let q = Quaternion::new(w, x, y, z);
    let norm = q.norm();
    (norm > 1e-6).then(|| (UnitQuaternion::from_quaternion(q), norm))
}

fn euler_rad(roll: f64, pitch: f64, yaw: f64) -> Option<UnitQuaternion<f64>> {
    [roll, pitch, yaw]
        .iter()
        .all(|v| v.is_finite())
        .then(|| UnitQuaternion::from_euler_angles(roll, pitch, yaw))
}

/// The yaw frame of a GIMBAL_DEVICE_ATTITUDE_STATUS (gimbal protocol v2): the explicit
/// YAW_IN_* flags when present, else YAW_LOCK means earth frame and follow mode vehicle frame.
fn gimbal_yaw_frame(flags: GimbalDeviceFlags) -> GimbalYawFrame {
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

fn geodetic(lat_e7: i32, lon_e7: i32, alt_mm: i32) -> Option<Geodetic> {
    Geodetic::new(
        f64::from(lat_e7) * 1e-7,
        f64::from(lon_e7) * 1e-7,
        f64::from(alt_mm) * 1e-3,
    )
    .ok()
}

/// Decodes one message from system `from_system`, component `from_component`. `our_system`
/// is the system id mgmot uses (commands must target it and our component, or broadcast).
/// Messages mgmot has no use for, and samples with invalid values (NaN attitude, no fix), give
/// `None`.
// MOUNT_ORIENTATION is deprecated in common.xml but ArduPilot still sends it for legacy gimbals.
#[allow(deprecated)]
pub fn decode(
    msg: &MavMessage,
    from_component: u8,
    our_system: u8,
    our_component: u8,
) -> Option<Incoming> {
    match msg {
        MavMessage::HEARTBEAT(h) => (from_component == 1
            || h.autopilot != dialect::MavAutopilot::MAV_AUTOPILOT_INVALID)
            .then_some(Incoming::AutopilotHeartbeat),
        MavMessage::GLOBAL_POSITION_INT(p) => {
            if p.lat == 0 && p.lon == 0 {
                return None; // no fix
            }
            Some(Incoming::Position(PositionFix {
                sample: PositionSample {
                    time: AutopilotTimeUs::from_boot_ms(p.time_boot_ms),
                    position: geodetic(p.lat, p.lon, p.alt)?,
                },
                // cm/s, NED.
                velocity_ned_mps: Some(Vector3::new(
                    f64::from(p.vx) / 100.0,
                    f64::from(p.vy) / 100.0,
                    f64::from(p.vz) / 100.0,
                )),
            }))
        }
        MavMessage::GPS_RAW_INT(g) => {
            let fixed = (g.fix_type as u8) >= (dialect::GpsFixType::GPS_FIX_TYPE_2D_FIX as u8);
            (fixed && g.h_acc > 0).then(|| Incoming::GnssAccuracy {
                h_acc_m: f64::from(g.h_acc) / 1000.0,
            })
        }
        MavMessage::ATTITUDE(a) => Some(Incoming::Attitude(AttitudeSample {
            time: AutopilotTimeUs::from_boot_ms(a.time_boot_ms),
            attitude: euler_rad(a.roll.into(), a.pitch.into(), a.yaw.into())?,
        })),
        MavMessage::GIMBAL_DEVICE_ATTITUDE_STATUS(g) => {
            let (attitude, norm) = quaternion(g.q)?;
            Some(Incoming::Gimbal {
                sample: GimbalSample {
                    time: AutopilotTimeUs::from_boot_ms(g.time_boot_ms),
                    attitude,
                    frame: gimbal_yaw_frame(g.flags),
                },
                quaternion_norm: Some(norm),
            })
        }
        MavMessage::MOUNT_ORIENTATION(m) => Some(Incoming::Gimbal {
            sample: GimbalSample {
                time: AutopilotTimeUs::from_boot_ms(m.time_boot_ms),
                // Roll and pitch relative to the horizon, yaw relative to the vehicle (deg).
                attitude: euler_rad(
                    f64::from(m.roll).to_radians(),
                    f64::from(m.pitch).to_radians(),
                    f64::from(m.yaw).to_radians(),
                )?,
                frame: GimbalYawFrame::Vehicle,
            },
            quaternion_norm: None,
        }),
        // ArduPilot's MOUNT_STATUS carries no timestamp; the link stamps it on arrival, so
        // it is decoded by `decode_mount_status`.
        MavMessage::HOME_POSITION(h) => {
            geodetic(h.latitude, h.longitude, h.altitude).map(Incoming::Home)
        }
        MavMessage::TIMESYNC(t) if t.tc1 != 0 => Some(Incoming::TimeSyncAnswer {
            tc1_ns: t.tc1,
            ts1_ns: t.ts1,
        }),
        MavMessage::COMMAND_LONG(c) => command(
            c.command,
            [
                c.param1, c.param2, c.param3, c.param4, c.param5, c.param6, c.param7,
            ],
            (c.target_system, c.target_component),
            (our_system, our_component),
        ),
        // COMMAND_INT carries params 5 and 6 as integers (x, y); none of the commands mgmot
        // obeys uses them as positions.
        MavMessage::COMMAND_INT(c) => command(
            c.command,
            [
                c.param1, c.param2, c.param3, c.param4, c.x as f32, c.y as f32, c.z,
            ],
            (c.target_system, c.target_component),
            (our_system, our_component),
        ),
        _ => None,
    }
}

/// A COMMAND_LONG / COMMAND_INT with `params` 1..=7 sent to `target` (system, component).
/// Commands for our system (or every system) and our component (or every component) are
/// ours; of those, the camera-tracking ones must also name us (or every camera, 0) in their
/// "target camera id" parameter. A command for our component alone that mgmot does not
/// implement gives [`Incoming::UnsupportedCommand`]; broadcast ones are left to the
/// components that implement them.
fn command(
    mav_cmd: MavCmd,
    params: [f32; 7],
    (target_system, target_component): (u8, u8),
    (our_system, our_component): (u8, u8),
) -> Option<Incoming> {
    let for_us = (target_system == 0 || target_system == our_system)
        && (target_component == 0 || target_component == our_component);
    if !for_us {
        return None;
    }
    // Target camera id: 0 (or unset) = every camera; 7..=255 = a MAVLink camera's component.
    let for_this_camera = |p: f32| p.is_nan() || p == 0.0 || p == f32::from(our_component);
    let [p1, p2, p3, p4, p5, ..] = params;
    let command = match mav_cmd {
        MavCmd::MAV_CMD_CAMERA_TRACK_POINT if for_this_camera(p4) => CameraCommand::TrackPoint {
            x: p1,
            y: p2,
            radius: p3,
        },
        MavCmd::MAV_CMD_CAMERA_TRACK_RECTANGLE if for_this_camera(p5) => {
            CameraCommand::TrackRectangle {
                x0: p1,
                y0: p2,
                x1: p3,
                y1: p4,
            }
        }
        MavCmd::MAV_CMD_CAMERA_STOP_TRACKING if for_this_camera(p1) => CameraCommand::Stop,
        MavCmd::MAV_CMD_CAMERA_TRACK_POINT
        | MavCmd::MAV_CMD_CAMERA_TRACK_RECTANGLE
        | MavCmd::MAV_CMD_CAMERA_STOP_TRACKING => return None,
        MavCmd::MAV_CMD_REQUEST_MESSAGE if p1 == CAMERA_INFORMATION_DATA::ID as f32 => {
            return Some(Incoming::CameraInformationRequest);
        }
        _ => {
            return (target_component == our_component)
                .then_some(Incoming::UnsupportedCommand { mav_cmd });
        }
    };
    Some(Incoming::Command { command, mav_cmd })
}

/// ArduPilot's MOUNT_STATUS (centidegrees: a = pitch, b = roll, c = yaw relative to the
/// vehicle), stamped with `time` (the arrival time mapped onto the autopilot clock, as the
/// message has no stamp of its own).
pub fn decode_mount_status(msg: &MavMessage, time: AutopilotTimeUs) -> Option<GimbalSample> {
    let MavMessage::MOUNT_STATUS(m) = msg else {
        return None;
    };
    let cdeg = |v: i32| (f64::from(v) / 100.0).to_radians();
    Some(GimbalSample {
        time,
        attitude: euler_rad(cdeg(m.pointing_b), cdeg(m.pointing_a), cdeg(m.pointing_c))?,
        frame: GimbalYawFrame::Vehicle,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geo::attitude::camera_from_gimbal_quaternion;
    use dialect::*;

    #[test]
    fn global_position_int() {
        let m = MavMessage::GLOBAL_POSITION_INT(GLOBAL_POSITION_INT_DATA {
            time_boot_ms: 1500,
            lat: 476_721_000,
            lon: 92_679_000,
            alt: 425_000,
            ..Default::default()
        });
        let Some(Incoming::Position(p)) = decode(&m, 1, 1, 191) else {
            panic!("not a position");
        };
        assert_eq!(p.sample.time, AutopilotTimeUs(1_500_000));
        assert!((p.sample.position.lat_deg - 47.6721).abs() < 1e-9);
        assert!((p.sample.position.alt_m - 425.0).abs() < 1e-9);
        assert_eq!(p.velocity_ned_mps, Some(Vector3::zeros()));
        let no_fix = MavMessage::GLOBAL_POSITION_INT(GLOBAL_POSITION_INT_DATA::default());
        assert_eq!(decode(&no_fix, 1, 1, 191), None);
    }

    /// GPS_RAW_INT gives the receiver's horizontal accuracy (mm -> m) when it has a fix and
    /// filled the field; 0 (a sender without the MAVLink 2 extension) is not reported.
    #[test]
    fn gps_raw_int_horizontal_accuracy() {
        let mk = |fix_type, h_acc| {
            MavMessage::GPS_RAW_INT(GPS_RAW_INT_DATA {
                fix_type,
                h_acc,
                lat: 476_721_000,
                lon: 92_679_000,
                ..Default::default()
            })
        };
        assert_eq!(
            decode(&mk(GpsFixType::GPS_FIX_TYPE_3D_FIX, 1500), 1, 1, 191),
            Some(Incoming::GnssAccuracy { h_acc_m: 1.5 })
        );
        assert_eq!(
            decode(&mk(GpsFixType::GPS_FIX_TYPE_RTK_FIXED, 12), 1, 1, 191),
            Some(Incoming::GnssAccuracy { h_acc_m: 0.012 })
        );
        assert_eq!(
            decode(&mk(GpsFixType::GPS_FIX_TYPE_3D_FIX, 0), 1, 1, 191),
            None
        );
        assert_eq!(
            decode(&mk(GpsFixType::GPS_FIX_TYPE_NO_FIX, 1500), 1, 1, 191),
            None
        );
    }

    #[test]
    fn gimbal_flags_pick_the_yaw_frame() {
        let q = UnitQuaternion::from_euler_angles(0.0, -0.8, 0.3);
        let mk = |flags| {
            MavMessage::GIMBAL_DEVICE_ATTITUDE_STATUS(GIMBAL_DEVICE_ATTITUDE_STATUS_DATA {
                time_boot_ms: 10,
                q: [q.w as f32, q.i as f32, q.j as f32, q.k as f32],
                flags,
                ..Default::default()
            })
        };
        let frame = |flags| match decode(&mk(flags), 154, 1, 191) {
            Some(Incoming::Gimbal { sample, .. }) => sample.frame,
            other => panic!("{other:?}"),
        };
        assert_eq!(
            frame(GimbalDeviceFlags::GIMBAL_DEVICE_FLAGS_YAW_IN_EARTH_FRAME),
            GimbalYawFrame::Earth
        );
        assert_eq!(
            frame(GimbalDeviceFlags::GIMBAL_DEVICE_FLAGS_YAW_IN_VEHICLE_FRAME),
            GimbalYawFrame::Vehicle
        );
        assert_eq!(
            frame(GimbalDeviceFlags::GIMBAL_DEVICE_FLAGS_YAW_LOCK),
            GimbalYawFrame::Earth
        );
        assert_eq!(frame(GimbalDeviceFlags::empty()), GimbalYawFrame::Vehicle);
        // NaN quaternion = no data.
        let nan = MavMessage::GIMBAL_DEVICE_ATTITUDE_STATUS(GIMBAL_DEVICE_ATTITUDE_STATUS_DATA {
            q: [f32::NAN; 4],
            ..Default::default()
        });
        assert_eq!(decode(&nan, 154, 1, 191), None);
        // A skewed quaternion is decoded with its norm: the pose gate refuses it.
        let skewed =
            MavMessage::GIMBAL_DEVICE_ATTITUDE_STATUS(GIMBAL_DEVICE_ATTITUDE_STATUS_DATA {
                q: [1.2, 0.0, 0.0, 0.0],
                ..Default::default()
            });
        let Some(Incoming::Gimbal {
            quaternion_norm, ..
        }) = decode(&skewed, 154, 1, 191)
        else {
            panic!("not a gimbal attitude");
        };
        assert!(quaternion_norm.is_some_and(|n| (n - 1.2).abs() < 1e-6));
    }

    #[test]
    #[allow(deprecated)]
    fn mount_status_and_orientation_agree() {
        let status = MavMessage::MOUNT_STATUS(MOUNT_STATUS_DATA {
            pointing_a: -4500,
            pointing_b: 0,
            pointing_c: 1000,
            ..Default::default()
        });
        let a = decode_mount_status(&status, AutopilotTimeUs(5)).unwrap();
        let orient = MavMessage::MOUNT_ORIENTATION(MOUNT_ORIENTATION_DATA {
            time_boot_ms: 0,
            roll: 0.0,
            pitch: -45.0,
            yaw: 10.0,
            ..Default::default()
        });
        let Some(Incoming::Gimbal { sample: b, .. }) = decode(&orient, 1, 1, 191) else {
            panic!()
        };
        assert!(a.attitude.angle_to(&b.attitude) < 1e-6);
        assert_eq!(a.frame, GimbalYawFrame::Vehicle);
        // Vehicle heading east, gimbal 10 deg right of it, 45 deg down.
        let vehicle = UnitQuaternion::from_euler_angles(0.0, 0.0, 90f64.to_radians());
        let cam = camera_from_gimbal_quaternion(&a.attitude, a.frame, &vehicle);
        let expected = crate::geo::attitude::camera_from_heading_pitch_deg(100.0, 45.0, 0.0);
        assert!(cam.angle_to(&expected) < 1e-6);
    }

    #[test]
    fn commands_only_when_addressed_to_us() {
        let cmd = |target_system, target_component, command| {
            MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
                target_system,
                target_component,
                command,
                param1: 0.25,
                param2: 0.5,
                ..Default::default()
            })
        };
        assert_eq!(
            decode(
                &cmd(1, 191, MavCmd::MAV_CMD_CAMERA_TRACK_POINT),
                190,
                1,
                191
            ),
            Some(Incoming::Command {
                command: CameraCommand::TrackPoint {
                    x: 0.25,
                    y: 0.5,
                    radius: 0.0
                },
                mav_cmd: MavCmd::MAV_CMD_CAMERA_TRACK_POINT
            })
        );
        assert_eq!(
            decode(
                &cmd(1, 100, MavCmd::MAV_CMD_CAMERA_TRACK_POINT),
                190,
                1,
                191
            ),
            None
        );
        // STOP_TRACKING's param 1 is the target camera id: 0 = every camera.
        let stop = MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
            command: MavCmd::MAV_CMD_CAMERA_STOP_TRACKING,
            ..Default::default()
        });
        assert!(matches!(
            decode(&stop, 190, 1, 191),
            Some(Incoming::Command {
                command: CameraCommand::Stop,
                ..
            })
        ));
    }

    #[test]
    fn command_int_rectangle_and_target_camera_id() {
        let rect = |target_component, camera_id| {
            MavMessage::COMMAND_INT(COMMAND_INT_DATA {
                target_system: 1,
                target_component,
                command: MavCmd::MAV_CMD_CAMERA_TRACK_RECTANGLE,
                param1: 0.1,
                param2: 0.2,
                param3: 0.3,
                param4: 0.4,
                x: camera_id,
                ..Default::default()
            })
        };
        let expected = Some(Incoming::Command {
            command: CameraCommand::TrackRectangle {
                x0: 0.1,
                y0: 0.2,
                x1: 0.3,
                y1: 0.4,
            },
            mav_cmd: MavCmd::MAV_CMD_CAMERA_TRACK_RECTANGLE,
        });
        assert_eq!(decode(&rect(191, 0), 190, 1, 191), expected);
        assert_eq!(decode(&rect(0, 191), 190, 1, 191), expected);
        // For another camera (component 100) behind a broadcast: not ours.
        assert_eq!(decode(&rect(0, 100), 190, 1, 191), None);
    }

    #[test]
    fn camera_information_request_and_unsupported_commands() {
        let long = |target_component, command, param1| {
            MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
                target_system: 1,
                target_component,
                command,
                param1,
                ..Default::default()
            })
        };
        let request = long(191, MavCmd::MAV_CMD_REQUEST_MESSAGE, 259.0);
        assert_eq!(
            decode(&request, 190, 1, 191),
            Some(Incoming::CameraInformationRequest)
        );
        assert!(decode(&request, 190, 1, 191).unwrap().is_command());
        // Another message, for us explicitly: unsupported; broadcast: someone else's.
        let other = |target| long(target, MavCmd::MAV_CMD_REQUEST_MESSAGE, 148.0);
        assert_eq!(
            decode(&other(191), 190, 1, 191),
            Some(Incoming::UnsupportedCommand {
                mav_cmd: MavCmd::MAV_CMD_REQUEST_MESSAGE
            })
        );
        assert_eq!(decode(&other(0), 190, 1, 191), None);
        assert!(!Incoming::AutopilotHeartbeat.is_command());
    }

    #[test]
    fn timesync_requests_are_not_answers() {
        let req = MavMessage::TIMESYNC(TIMESYNC_DATA {
            tc1: 0,
            ts1: 5,
            ..Default::default()
        });
        assert_eq!(decode(&req, 1, 1, 191), None);
    }
}
