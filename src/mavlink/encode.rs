//! The messages mgmot sends, built from domain values.

use super::dialect::*;
use crate::geo::{CameraView, Geodetic};
use crate::report::{TrackReport, TrackingMode, TrackingStatus};
use crate::telemetry::{AutopilotTimeUs, CompanionTimeUs};
use mavlink_core::MessageData;
use std::num::NonZeroU16;

// MOUNT_ORIENTATION is deprecated in common.xml; some gimbal bridges still send it. ArduPilot
// (upstream 90700977c5) refuses it (DENIED: "No ap_message for mavlink id (265)"), so it is
// not asked of ArduPilot at all (`link::streams::not_sent_by`).
#[allow(deprecated)]
/// Telemetry streams requested from the autopilot with MAV_CMD_SET_MESSAGE_INTERVAL, and their
/// rates (Hz); `None`: the pose streams, at `mavlink.stream_rate_hz` (50 Hz by default: fast
/// enough that interpolating between samples at a frame's time is accurate; a drone at 15 m/s
/// moves 30 cm in 20 ms). Home rarely changes; SYSTEM_TIME's `time_boot_ms` shows a reboot
/// even while the other streams are still off, once a second is enough for that. GPS_RAW_INT
/// carries the receiver's horizontal accuracy (`h_acc`), which changes slowly: 2 Hz.
pub const STREAMS: [(u32, Option<f32>); 7] = [
    (GLOBAL_POSITION_INT_DATA::ID, None),
    (ATTITUDE_DATA::ID, None),
    (GIMBAL_DEVICE_ATTITUDE_STATUS_DATA::ID, None),
    (MOUNT_ORIENTATION_DATA::ID, None),
    (HOME_POSITION_DATA::ID, Some(0.2)),
    (SYSTEM_TIME_DATA::ID, Some(1.0)),
    (GPS_RAW_INT_DATA::ID, Some(2.0)),
];

/// STATUSTEXT severities mgmot uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Severity {
    /// Something stopped working (telemetry lost, camera gone, detector failing).
    Warning,
    /// Something came back or changed state normally.
    Info,
    /// Normal but significant (an object found).
    Notice,
}

/// HEARTBEAT of mgmot as an onboard computer component.
pub fn heartbeat() -> MavMessage {
    MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        custom_mode: 0,
        mavtype: MavType::MAV_TYPE_ONBOARD_CONTROLLER,
        autopilot: MavAutopilot::MAV_AUTOPILOT_INVALID,
        base_mode: MavModeFlag::empty(),
        system_status: MavState::MAV_STATE_ACTIVE,
        mavlink_version: 3,
    })
}

/// Bytes of text one STATUSTEXT carries.
pub const STATUSTEXT_CHUNK_BYTES: usize = 50;
/// The longest text sent, in bytes (longer ones are cut at a char boundary): four chunks hold
/// every notice mgmot makes, an OS error's text included, without letting one notice take the
/// link's bandwidth.
pub const STATUSTEXT_MAX_BYTES: usize = 4 * STATUSTEXT_CHUNK_BYTES;

/// STATUSTEXT for `text`. Up to 50 bytes: one message, `id` 0 (shown at once). Longer: MAVLink
/// 2's chunked STATUSTEXT, which QGroundControl and MAVProxy reassemble: 50-byte chunks sharing
/// the non-zero `id`, `chunk_seq` counting from 0, the last one shorter than 50 bytes (NUL
/// after the text; an empty chunk follows a text that ends on a chunk boundary). A ground
/// station that does not reassemble shows each chunk as a line. Text beyond
/// [`STATUSTEXT_MAX_BYTES`] is cut at a char boundary. `id` must differ from the previous
/// chunked texts' (a counter, see `Outputs::notice`).
pub fn statustext(severity: Severity, text: &str, id: NonZeroU16) -> Vec<MavMessage> {
    let severity = match severity {
        Severity::Warning => MavSeverity::MAV_SEVERITY_WARNING,
        Severity::Info => MavSeverity::MAV_SEVERITY_INFO,
        Severity::Notice => MavSeverity::MAV_SEVERITY_NOTICE,
    };
    let message = |id: u16, chunk_seq: u8, chunk: &[u8]| {
        let mut bytes = [0u8; STATUSTEXT_CHUNK_BYTES];
        bytes[..chunk.len()].copy_from_slice(chunk);
        MavMessage::STATUSTEXT(STATUSTEXT_DATA {
            severity,
            text: bytes.into(),
            id,
            chunk_seq,
        })
    };
    let mut end = text.len().min(STATUSTEXT_MAX_BYTES);
    while !text.is_char_boundary(end) {
        end -= 1;
    }
    let bytes = &text.as_bytes()[..end];
    if bytes.len() <= STATUSTEXT_CHUNK_BYTES {
        return vec![message(0, 0, bytes)];
    }
    // Chunks split bytes, not characters: a receiver joins bytes, and only the last chunk may
    // be short.
    let mut chunks: Vec<&[u8]> = bytes.chunks(STATUSTEXT_CHUNK_BYTES).collect();
    if bytes.len() % STATUSTEXT_CHUNK_BYTES == 0 {
        chunks.push(&[]);
    }
    chunks
        .into_iter()
        .zip(0u8..)
        .map(|(chunk, seq)| message(id.get(), seq, chunk))
        .collect()
}

/// MAV_CMD_SET_MESSAGE_INTERVAL for message `message_id` at `rate_hz` to the autopilot.
pub fn message_interval_request(
    target_system: u8,
    target_component: u8,
    message_id: u32,
    rate_hz: f32,
) -> MavMessage {
    let interval_us = if rate_hz > 0.0 { 1e6 / rate_hz } else { -1.0 };
    MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
        target_system,
        target_component,
        command: MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL,
        confirmation: 0,
        param1: message_id as f32,
        param2: interval_us,
        ..Default::default()
    })
}

/// A TIMESYNC request carrying our time `now` (ns on the wire).
pub fn timesync_request(now: CompanionTimeUs) -> MavMessage {
    MavMessage::TIMESYNC(TIMESYNC_DATA {
        tc1: 0,
        ts1: i64::try_from(now.0.saturating_mul(1000)).unwrap_or(i64::MAX),
        ..Default::default()
    })
}

/// The result of a command, as COMMAND_ACK reports it (MAV_RESULT).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AckResult {
    /// Done (MAV_RESULT_ACCEPTED).
    Accepted,
    /// Cannot be done now, may work later: the command queue is full
    /// (MAV_RESULT_TEMPORARILY_REJECTED).
    TemporarilyRejected,
    /// Invalid parameters, or refused (unsigned while signing is required) (MAV_RESULT_DENIED).
    Denied,
    /// Not implemented by mgmot (MAV_RESULT_UNSUPPORTED).
    Unsupported,
    /// Valid, but it did not work: nothing to track there (MAV_RESULT_FAILED).
    Failed,
}

/// COMMAND_ACK for a command from `target_system` / `target_component` (the sender).
pub fn command_ack(
    command: MavCmd,
    result: AckResult,
    target_system: u8,
    target_component: u8,
) -> MavMessage {
    MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
        command,
        result: match result {
            AckResult::Accepted => MavResult::MAV_RESULT_ACCEPTED,
            AckResult::TemporarilyRejected => MavResult::MAV_RESULT_TEMPORARILY_REJECTED,
            AckResult::Denied => MavResult::MAV_RESULT_DENIED,
            AckResult::Unsupported => MavResult::MAV_RESULT_UNSUPPORTED,
            AckResult::Failed => MavResult::MAV_RESULT_FAILED,
        },
        progress: 0,
        result_param2: 0,
        target_system,
        target_component,
    })
}

fn deg_e7(deg: f64) -> i32 {
    (deg * 1e7).round().clamp(i32::MIN as f64, i32::MAX as f64) as i32
}

fn id32(id: u64) -> u32 {
    // Ids beyond u32 would need 136 years of one new track per second.
    u32::try_from(id).unwrap_or(u32::MAX)
}

/// MGMOT_TRACK for a report.
pub fn mgmot_track(r: &TrackReport) -> MavMessage {
    let mut flags = MgmotTrackFlags::empty();
    if r.geo.is_some() {
        flags |= MgmotTrackFlags::MGMOT_TRACK_FLAGS_GEO_VALID;
    }
    if r.merged_from_id.is_some() {
        flags |= MgmotTrackFlags::MGMOT_TRACK_FLAGS_MERGED;
    }
    if r.provisional {
        flags |= MgmotTrackFlags::MGMOT_TRACK_FLAGS_PROVISIONAL;
    }
    let object_class = match r.class_id {
        1 => MgmotObjectClass::MGMOT_OBJECT_CLASS_SWIMMER,
        2 => MgmotObjectClass::MGMOT_OBJECT_CLASS_BOAT,
        3 => MgmotObjectClass::MGMOT_OBJECT_CLASS_JETSKI,
        4 => MgmotObjectClass::MGMOT_OBJECT_CLASS_LIFE_SAVING_APPLIANCE,
        5 => MgmotObjectClass::MGMOT_OBJECT_CLASS_BUOY,
        _ => MgmotObjectClass::MGMOT_OBJECT_CLASS_UNKNOWN,
    };
    let (lat, lon, alt, vel_n, vel_e, h_std) = match &r.geo {
        Some(g) => (
            deg_e7(g.position.lat_deg),
            deg_e7(g.position.lon_deg),
            (g.position.alt_m * 1000.0).round() as i32,
            g.vel_n_mps as f32,
            g.vel_e_mps as f32,
            g.h_std_m as f32,
        ),
        None => (0, 0, 0, f32::NAN, f32::NAN, f32::NAN),
    };
    MavMessage::MGMOT_TRACK(MGMOT_TRACK_DATA {
        time_usec: r.time.0,
        track_id: id32(r.track_id),
        merged_from_id: r.merged_from_id.map_or(0, id32),
        lat,
        lon,
        alt,
        vel_n,
        vel_e,
        h_std,
        confidence: r.confidence,
        bbox_x: r.bbox_norm[0],
        bbox_y: r.bbox_norm[1],
        bbox_w: r.bbox_norm[2],
        bbox_h: r.bbox_norm[3],
        object_class,
        state: if r.tracked {
            MgmotTrackState::MGMOT_TRACK_STATE_TRACKED
        } else {
            MgmotTrackState::MGMOT_TRACK_STATE_LOST
        },
        flags,
    })
}

/// Altitude (m) as CAMERA_FOV_STATUS's millimetres.
fn alt_mm(alt_m: f64) -> i32 {
    (alt_m * 1000.0)
        .round()
        .clamp(f64::from(i32::MIN), f64::from(i32::MAX)) as i32
}

/// CAMERA_FOV_STATUS: where the camera is and looks, for a ground station's footprint. `time`
/// is the frame's exposure on the autopilot clock; `centre` where the image centre meets the
/// sea (`None`: at or above the horizon, sent as INT32_MIN, "at infinity"). The image centre's
/// altitude is the sea surface's.
pub fn camera_fov_status(
    time: AutopilotTimeUs,
    view: &CameraView,
    centre: Option<&Geodetic>,
) -> MavMessage {
    let q = view.attitude_frd.quaternion();
    let (lat_image, lon_image, alt_image) = match centre {
        Some(c) => (
            deg_e7(c.lat_deg),
            deg_e7(c.lon_deg),
            alt_mm(view.camera.alt_m - view.height_above_sea_m),
        ),
        None => (i32::MIN, i32::MIN, i32::MIN),
    };
    MavMessage::CAMERA_FOV_STATUS(CAMERA_FOV_STATUS_DATA {
        time_boot_ms: (time.0 / 1000) as u32,
        lat_camera: deg_e7(view.camera.lat_deg),
        lon_camera: deg_e7(view.camera.lon_deg),
        alt_camera: alt_mm(view.camera.alt_m),
        lat_image,
        lon_image,
        alt_image,
        q: [q.w as f32, q.i as f32, q.j as f32, q.k as f32],
        hfov: view.hfov_deg as f32,
        vfov: view.vfov_deg as f32,
        camera_device_id: 0,
    })
}

/// TARGET_ABSOLUTE (development.xml) for a geolocated report; `None` without geolocation
/// (the message has no way to say "position unknown"). Its `id` is 8 bits: the low byte of the
/// track id, so generic consumers see ids wrap after 256 tracks; MGMOT_TRACK has the full id.
pub fn target_absolute(r: &TrackReport) -> Option<MavMessage> {
    let g = r.geo?;
    let nan3 = [f32::NAN; 3];
    Some(MavMessage::TARGET_ABSOLUTE(TARGET_ABSOLUTE_DATA {
        timestamp: r.time.0,
        id: (r.track_id & 0xff) as u8,
        sensor_capabilities:
            TargetAbsoluteSensorCapabilityFlags::TARGET_ABSOLUTE_SENSOR_CAPABILITY_POSITION
                | TargetAbsoluteSensorCapabilityFlags::TARGET_ABSOLUTE_SENSOR_CAPABILITY_VELOCITY,
        lat: deg_e7(g.position.lat_deg),
        lon: deg_e7(g.position.lon_deg),
        alt: g.position.alt_m as f32,
        vel: [g.vel_n_mps as f32, g.vel_e_mps as f32, 0.0],
        acc: nan3,
        q_target: [f32::NAN; 4],
        rates: nan3,
        position_std: [g.h_std_m as f32, f32::NAN],
        vel_std: nan3,
        acc_std: nan3,
    }))
}

fn nan_or(v: Option<f64>) -> f32 {
    v.map_or(f32::NAN, |v| v as f32)
}

fn tracking_flags(s: &TrackingStatus) -> CameraTrackingStatusFlags {
    let mut flags = CameraTrackingStatusFlags::CAMERA_TRACKING_STATUS_FLAGS_ACTIVE;
    if s.coasting {
        flags |= CameraTrackingStatusFlags::CAMERA_TRACKING_STATUS_FLAGS_COASTING;
    }
    flags
}

/// "Not tracking": status IDLE, mode NONE, every coordinate NaN.
fn image_status_idle() -> CAMERA_TRACKING_IMAGE_STATUS_DATA {
    let nan = f32::NAN;
    CAMERA_TRACKING_IMAGE_STATUS_DATA {
        tracking_status: CameraTrackingStatusFlags::CAMERA_TRACKING_STATUS_FLAGS_IDLE,
        tracking_mode: CameraTrackingMode::CAMERA_TRACKING_MODE_NONE,
        target_data: CameraTrackingTargetData::empty(),
        point_x: nan,
        point_y: nan,
        radius: nan,
        rec_top_x: nan,
        rec_top_y: nan,
        rec_bottom_x: nan,
        rec_bottom_y: nan,
        camera_device_id: 0,
    }
}

/// "Not tracking": status IDLE, lat = lon = 0, every other field NaN.
fn geo_status_idle() -> CAMERA_TRACKING_GEO_STATUS_DATA {
    let nan = f32::NAN;
    CAMERA_TRACKING_GEO_STATUS_DATA {
        tracking_status: CameraTrackingStatusFlags::CAMERA_TRACKING_STATUS_FLAGS_IDLE,
        lat: 0,
        lon: 0,
        alt: nan,
        h_acc: nan,
        v_acc: nan,
        vel_n: nan,
        vel_e: nan,
        vel_d: nan,
        vel_acc: nan,
        dist: nan,
        hdg: nan,
        hdg_acc: nan,
        camera_device_id: 0,
    }
}

/// CAMERA_TRACKING_IMAGE_STATUS: the selected track's box (`Some`), or "not tracking"
/// (`None`: status IDLE, mode NONE, every coordinate NaN).
pub fn camera_tracking_image_status(s: Option<&TrackingStatus>) -> MavMessage {
    let mut m = image_status_idle();
    if let Some(s) = s {
        let [x, y, w, h] = s.bbox_norm;
        m.tracking_status = tracking_flags(s);
        m.target_data = CameraTrackingTargetData::CAMERA_TRACKING_TARGET_DATA_IN_STATUS;
        match s.mode {
            TrackingMode::Point => {
                m.tracking_mode = CameraTrackingMode::CAMERA_TRACKING_MODE_POINT;
                m.point_x = x + w / 2.0;
                m.point_y = y + h / 2.0;
                // Half the larger side, as a fraction of the image width.
                m.radius = w.max(h / s.aspect) / 2.0;
            }
            TrackingMode::Rectangle => {
                m.tracking_mode = CameraTrackingMode::CAMERA_TRACKING_MODE_RECTANGLE;
                m.rec_top_x = x;
                m.rec_top_y = y;
                m.rec_bottom_x = x + w;
                m.rec_bottom_y = y + h;
            }
        }
    }
    MavMessage::CAMERA_TRACKING_IMAGE_STATUS(m)
}

/// CAMERA_TRACKING_IMAGE_STATUS of a selection whose track is lost, waiting for
/// re-identification to bring it back: ACTIVE | ERROR (tracking on, target not found) in the
/// selection's mode, no target data, every coordinate NaN ("unknown").
pub fn camera_tracking_image_status_lost(mode: TrackingMode) -> MavMessage {
    let mut m = image_status_idle();
    m.tracking_status = CameraTrackingStatusFlags::CAMERA_TRACKING_STATUS_FLAGS_ACTIVE
        | CameraTrackingStatusFlags::CAMERA_TRACKING_STATUS_FLAGS_ERROR;
    m.tracking_mode = match mode {
        TrackingMode::Point => CameraTrackingMode::CAMERA_TRACKING_MODE_POINT,
        TrackingMode::Rectangle => CameraTrackingMode::CAMERA_TRACKING_MODE_RECTANGLE,
    };
    MavMessage::CAMERA_TRACKING_IMAGE_STATUS(m)
}

/// CAMERA_TRACKING_GEO_STATUS of a selection whose track is lost, waiting for
/// re-identification: ACTIVE | ERROR with lat = lon = 0 and every other field NaN, as for a
/// selected track without geolocation.
pub fn camera_tracking_geo_status_lost() -> MavMessage {
    let mut m = geo_status_idle();
    m.tracking_status = CameraTrackingStatusFlags::CAMERA_TRACKING_STATUS_FLAGS_ACTIVE
        | CameraTrackingStatusFlags::CAMERA_TRACKING_STATUS_FLAGS_ERROR;
    MavMessage::CAMERA_TRACKING_GEO_STATUS(m)
}

/// CAMERA_TRACKING_GEO_STATUS: the selected track's position on the sea (`Some`), or "not
/// tracking" (`None`: status IDLE). A selected track without geolocation (no telemetry pose)
/// is reported ACTIVE | ERROR with lat = lon = 0 and every other field NaN: the message has
/// no other way to say "position unknown". The object is on the sea surface: `vel_d` = 0,
/// `alt` = the water level; `h_acc` is the DRMS of the position (as in MGMOT_TRACK);
/// the heading is that of the velocity, NaN while the speed is within its own uncertainty.
pub fn camera_tracking_geo_status(s: Option<&TrackingStatus>) -> MavMessage {
    let mut m = geo_status_idle();
    let Some(s) = s else {
        return MavMessage::CAMERA_TRACKING_GEO_STATUS(m);
    };
    m.tracking_status = tracking_flags(s);
    match &s.geo {
        None => {
            m.tracking_status |= CameraTrackingStatusFlags::CAMERA_TRACKING_STATUS_FLAGS_ERROR;
        }
        Some(g) => {
            m.lat = deg_e7(g.position.lat_deg);
            m.lon = deg_e7(g.position.lon_deg);
            m.alt = g.position.alt_m as f32;
            m.h_acc = g.h_std_m as f32;
            m.vel_n = g.vel_n_mps as f32;
            m.vel_e = g.vel_e_mps as f32;
            m.vel_d = 0.0;
            m.vel_acc = nan_or(s.vel_std_mps);
            m.dist = nan_or(s.range_m);
            let speed = g.vel_n_mps.hypot(g.vel_e_mps);
            if let Some(std) = s.vel_std_mps.filter(|std| speed > *std) {
                m.hdg = g
                    .vel_e_mps
                    .atan2(g.vel_n_mps)
                    .rem_euclid(std::f64::consts::TAU) as f32;
                m.hdg_acc = (std / speed).atan() as f32;
            }
        }
    }
    MavMessage::CAMERA_TRACKING_GEO_STATUS(m)
}

/// CAMERA_INFORMATION describing mgmot as a tracking "camera" (answer to
/// MAV_CMD_REQUEST_MESSAGE): the capability flags tell a GCS that point and rectangle tracking
/// and the geo status are available. Image size 0 = not known yet.
pub fn camera_information(time_boot_ms: u32, image_size_px: Option<(u32, u32)>) -> MavMessage {
    let mut vendor_name = [0u8; 32];
    vendor_name[..5].copy_from_slice(b"mgmot");
    let mut model_name = [0u8; 32];
    let model = b"mgmot tracker";
    model_name[..model.len()].copy_from_slice(model);
    let (w, h) = image_size_px.unwrap_or((0, 0));
    MavMessage::CAMERA_INFORMATION(CAMERA_INFORMATION_DATA {
        time_boot_ms,
        vendor_name,
        model_name,
        firmware_version: 0,
        focal_length: f32::NAN,
        sensor_size_h: f32::NAN,
        sensor_size_v: f32::NAN,
        resolution_h: u16::try_from(w).unwrap_or(0),
        resolution_v: u16::try_from(h).unwrap_or(0),
        lens_id: 0,
        flags: CameraCapFlags::CAMERA_CAP_FLAGS_HAS_TRACKING_POINT
            | CameraCapFlags::CAMERA_CAP_FLAGS_HAS_TRACKING_RECTANGLE
            | CameraCapFlags::CAMERA_CAP_FLAGS_HAS_TRACKING_GEO_STATUS,
        cam_definition_version: 0,
        cam_definition_uri: "".into(),
        gimbal_device_id: 0,
        camera_device_id: 0,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frame::GeoFix;
    use crate::geo::Geodetic;
    use crate::telemetry::AutopilotTimeUs;
    use mavlink_core::{MavHeader, MavlinkVersion, Message as _};

    fn report(geo: bool) -> TrackReport {
        TrackReport {
            time: AutopilotTimeUs(12_345_000),
            track_id: 7,
            merged_from_id: Some(12),
            class_id: 1,
            confidence: 0.8,
            bbox_norm: [0.1, 0.2, 0.05, 0.04],
            tracked: true,
            geo: geo.then_some(GeoFix {
                position: Geodetic {
                    lat_deg: 47.6721234,
                    lon_deg: 9.2679876,
                    alt_m: 395.0,
                },
                vel_n_mps: 0.3,
                vel_e_mps: -0.1,
                h_std_m: 1.5,
                ce95_m: 2.6,
            }),
            provisional: false,
        }
    }

    /// Serialises and parses a message back through the wire format.
    fn round_trip(m: &MavMessage) -> MavMessage {
        let mut buf = Vec::new();
        mavlink_core::write_versioned_msg(&mut buf, MavlinkVersion::V2, MavHeader::default(), m)
            .unwrap();
        let mut reader = mavlink_core::MavlinkReader::new(&buf[..]);
        let (_, back) = reader
            .read_message::<MavMessage>(MavlinkVersion::V2)
            .unwrap();
        back
    }

    #[test]
    fn mgmot_track_fields_and_wire_round_trip() {
        let m = mgmot_track(&report(true));
        assert_eq!(m.message_id(), 43000);
        let MavMessage::MGMOT_TRACK(t) = round_trip(&m) else {
            panic!("wrong message back")
        };
        assert_eq!(t.track_id, 7);
        assert_eq!(t.merged_from_id, 12);
        assert_eq!(t.lat, 476_721_234);
        assert_eq!(t.lon, 92_679_876);
        assert_eq!(t.alt, 395_000);
        assert_eq!(t.object_class, MgmotObjectClass::MGMOT_OBJECT_CLASS_SWIMMER);
        assert!(t
            .flags
            .contains(MgmotTrackFlags::MGMOT_TRACK_FLAGS_GEO_VALID));
        assert!(t.flags.contains(MgmotTrackFlags::MGMOT_TRACK_FLAGS_MERGED));
        assert_eq!(t.time_usec, 12_345_000);
    }

    #[test]
    fn no_geolocation_is_flagged_and_has_no_target_absolute() {
        let r = report(false);
        let MavMessage::MGMOT_TRACK(t) = mgmot_track(&r) else {
            panic!()
        };
        assert!(!t
            .flags
            .contains(MgmotTrackFlags::MGMOT_TRACK_FLAGS_GEO_VALID));
        assert!(t.h_std.is_nan());
        assert!(target_absolute(&r).is_none());
        let Some(MavMessage::TARGET_ABSOLUTE(a)) = target_absolute(&report(true)) else {
            panic!()
        };
        assert_eq!(a.id, 7);
        assert_eq!(a.position_std[0], 1.5);
    }

    fn tracking(mode: TrackingMode, geo: bool) -> TrackingStatus {
        TrackingStatus {
            mode,
            bbox_norm: [0.5, 0.25, 0.1, 0.2],
            aspect: 2.0,
            coasting: false,
            geo: report(geo).geo,
            vel_std_mps: Some(0.1),
            range_m: Some(42.0),
        }
    }

    #[test]
    fn image_status_point_rectangle_and_idle() {
        let MavMessage::CAMERA_TRACKING_IMAGE_STATUS(p) = round_trip(
            &camera_tracking_image_status(Some(&tracking(TrackingMode::Point, true))),
        ) else {
            panic!()
        };
        assert_eq!(
            p.tracking_status,
            CameraTrackingStatusFlags::CAMERA_TRACKING_STATUS_FLAGS_ACTIVE
        );
        assert_eq!(
            p.tracking_mode,
            CameraTrackingMode::CAMERA_TRACKING_MODE_POINT
        );
        assert_eq!(
            p.target_data,
            CameraTrackingTargetData::CAMERA_TRACKING_TARGET_DATA_IN_STATUS
        );
        assert!((p.point_x - 0.55).abs() < 1e-6 && (p.point_y - 0.35).abs() < 1e-6);
        // Box 0.1 of the width wide and 0.2 of the height = 0.1 of the width high.
        assert!((p.radius - 0.05).abs() < 1e-6);
        assert!(p.rec_top_x.is_nan());

        let mut coasting = tracking(TrackingMode::Rectangle, true);
        coasting.coasting = true;
        let MavMessage::CAMERA_TRACKING_IMAGE_STATUS(r) =
            camera_tracking_image_status(Some(&coasting))
        else {
            panic!()
        };
        assert_eq!(
            r.tracking_mode,
            CameraTrackingMode::CAMERA_TRACKING_MODE_RECTANGLE
        );
        assert!(r
            .tracking_status
            .contains(CameraTrackingStatusFlags::CAMERA_TRACKING_STATUS_FLAGS_COASTING));
        assert_eq!(
            [r.rec_top_x, r.rec_top_y, r.rec_bottom_x, r.rec_bottom_y],
            [0.5, 0.25, 0.6, 0.45]
        );
        assert!(r.point_x.is_nan());

        let MavMessage::CAMERA_TRACKING_IMAGE_STATUS(i) = camera_tracking_image_status(None) else {
            panic!()
        };
        assert_eq!(
            i.tracking_status,
            CameraTrackingStatusFlags::CAMERA_TRACKING_STATUS_FLAGS_IDLE
        );
        assert_eq!(
            i.tracking_mode,
            CameraTrackingMode::CAMERA_TRACKING_MODE_NONE
        );
    }

    #[test]
    fn geo_status_with_and_without_geolocation() {
        let MavMessage::CAMERA_TRACKING_GEO_STATUS(g) = round_trip(&camera_tracking_geo_status(
            Some(&tracking(TrackingMode::Point, true)),
        )) else {
            panic!()
        };
        assert_eq!(
            g.tracking_status,
            CameraTrackingStatusFlags::CAMERA_TRACKING_STATUS_FLAGS_ACTIVE
        );
        assert_eq!((g.lat, g.lon), (476_721_234, 92_679_876));
        assert_eq!((g.alt, g.h_acc, g.dist), (395.0, 1.5, 42.0));
        assert_eq!(
            (g.vel_n, g.vel_e, g.vel_d, g.vel_acc),
            (0.3, -0.1, 0.0, 0.1)
        );
        // Moving north-north-west: heading atan2(-0.1, 0.3) = 341.6 deg.
        assert!(
            (f64::from(g.hdg).to_degrees() - 341.565).abs() < 0.01,
            "{}",
            g.hdg
        );
        assert!(g.hdg_acc > 0.0 && g.hdg_acc < 0.5);
        assert!(g.v_acc.is_nan());

        // Slower than its own uncertainty: no heading.
        let mut slow = tracking(TrackingMode::Point, true);
        slow.vel_std_mps = Some(1.0);
        let MavMessage::CAMERA_TRACKING_GEO_STATUS(g) = camera_tracking_geo_status(Some(&slow))
        else {
            panic!()
        };
        assert!(g.hdg.is_nan() && g.hdg_acc.is_nan());

        let MavMessage::CAMERA_TRACKING_GEO_STATUS(g) =
            camera_tracking_geo_status(Some(&tracking(TrackingMode::Point, false)))
        else {
            panic!()
        };
        assert_eq!(
            g.tracking_status,
            CameraTrackingStatusFlags::CAMERA_TRACKING_STATUS_FLAGS_ACTIVE
                | CameraTrackingStatusFlags::CAMERA_TRACKING_STATUS_FLAGS_ERROR
        );
        assert_eq!((g.lat, g.lon), (0, 0));
        assert!(g.alt.is_nan() && g.h_acc.is_nan() && g.vel_n.is_nan());

        let MavMessage::CAMERA_TRACKING_GEO_STATUS(g) = camera_tracking_geo_status(None) else {
            panic!()
        };
        assert_eq!(
            g.tracking_status,
            CameraTrackingStatusFlags::CAMERA_TRACKING_STATUS_FLAGS_IDLE
        );
    }

    #[test]
    fn a_lost_selection_is_active_with_an_error_and_no_target() {
        let MavMessage::CAMERA_TRACKING_IMAGE_STATUS(i) =
            round_trip(&camera_tracking_image_status_lost(TrackingMode::Point))
        else {
            panic!()
        };
        let active_error = CameraTrackingStatusFlags::CAMERA_TRACKING_STATUS_FLAGS_ACTIVE
            | CameraTrackingStatusFlags::CAMERA_TRACKING_STATUS_FLAGS_ERROR;
        assert_eq!(i.tracking_status, active_error);
        assert_eq!(
            i.tracking_mode,
            CameraTrackingMode::CAMERA_TRACKING_MODE_POINT
        );
        assert_eq!(i.target_data, CameraTrackingTargetData::empty());
        assert!(i.point_x.is_nan() && i.radius.is_nan() && i.rec_top_x.is_nan());
        let MavMessage::CAMERA_TRACKING_IMAGE_STATUS(r) =
            camera_tracking_image_status_lost(TrackingMode::Rectangle)
        else {
            panic!()
        };
        assert_eq!(
            r.tracking_mode,
            CameraTrackingMode::CAMERA_TRACKING_MODE_RECTANGLE
        );
        let MavMessage::CAMERA_TRACKING_GEO_STATUS(g) =
            round_trip(&camera_tracking_geo_status_lost())
        else {
            panic!()
        };
        assert_eq!(g.tracking_status, active_error);
        assert_eq!((g.lat, g.lon), (0, 0));
        assert!(g.alt.is_nan() && g.h_acc.is_nan() && g.vel_n.is_nan() && g.dist.is_nan());
    }

    #[test]
    fn command_ack_results_and_camera_information() {
        let MavMessage::COMMAND_ACK(a) = command_ack(
            MavCmd::MAV_CMD_CAMERA_TRACK_POINT,
            AckResult::Failed,
            255,
            190,
        ) else {
            panic!()
        };
        assert_eq!(a.result, MavResult::MAV_RESULT_FAILED);
        assert_eq!((a.target_system, a.target_component), (255, 190));
        let MavMessage::CAMERA_INFORMATION(c) =
            round_trip(&camera_information(1000, Some((1280, 720))))
        else {
            panic!()
        };
        assert!(c.flags.contains(
            CameraCapFlags::CAMERA_CAP_FLAGS_HAS_TRACKING_POINT
                | CameraCapFlags::CAMERA_CAP_FLAGS_HAS_TRACKING_RECTANGLE
                | CameraCapFlags::CAMERA_CAP_FLAGS_HAS_TRACKING_GEO_STATUS
        ));
        assert_eq!((c.resolution_h, c.resolution_v), (1280, 720));
        assert_eq!(&c.vendor_name[..6], b"mgmot\0");
    }

    /// The texts of `messages` (STATUSTEXT), with their ids and chunk numbers.
    fn chunks(messages: &[MavMessage]) -> Vec<(u16, u8, Vec<u8>)> {
        messages
            .iter()
            .map(|m| {
                let MavMessage::STATUSTEXT(s) = round_trip(m) else {
                    panic!("{m:?}")
                };
                let bytes: [u8; 50] = s.text.into();
                let end = bytes.iter().position(|&b| b == 0).unwrap_or(50);
                (s.id, s.chunk_seq, bytes[..end].to_vec())
            })
            .collect()
    }

    const ID: NonZeroU16 = NonZeroU16::MIN.saturating_add(6);

    #[test]
    fn statustext_up_to_50_bytes_is_one_message() {
        for text in ["", "short", &"x".repeat(50)] {
            let got = chunks(&statustext(Severity::Warning, text, ID));
            assert_eq!(got, [(0, 0, text.as_bytes().to_vec())]);
        }
    }

    #[test]
    fn statustext_longer_than_50_bytes_goes_in_chunks() {
        let text = "mgmot: recording stopped: Input/output error (os error 5)";
        let got = chunks(&statustext(Severity::Warning, text, ID));
        assert_eq!(
            got,
            [
                (7, 0, text.as_bytes()[..50].to_vec()),
                (7, 1, text.as_bytes()[50..].to_vec())
            ]
        );
        // Ending on a chunk boundary: an empty chunk says it ended.
        let text = "y".repeat(100);
        let got = chunks(&statustext(Severity::Info, &text, ID));
        let lens: Vec<(u8, usize)> = got.iter().map(|(_, s, b)| (*s, b.len())).collect();
        assert_eq!(lens, [(0, 50), (1, 50), (2, 0)]);
        // Multi-byte characters are split between chunks and join again.
        let text = "é".repeat(40);
        let joined: Vec<u8> = chunks(&statustext(Severity::Info, &text, ID))
            .into_iter()
            .flat_map(|(_, _, b)| b)
            .collect();
        assert_eq!(String::from_utf8(joined).unwrap(), text);
    }

    #[test]
    fn statustext_is_cut_on_a_char_boundary_at_its_maximum() {
        let text = "é".repeat(STATUSTEXT_MAX_BYTES);
        let joined: Vec<u8> = chunks(&statustext(Severity::Warning, &text, ID))
            .into_iter()
            .flat_map(|(_, _, b)| b)
            .collect();
        let joined = String::from_utf8(joined).unwrap();
        assert_eq!(joined.chars().count(), STATUSTEXT_MAX_BYTES / 2);
    }

    #[test]
    fn message_interval_is_in_microseconds() {
        let MavMessage::COMMAND_LONG(c) = message_interval_request(1, 1, 33, 50.0) else {
            panic!()
        };
        assert_eq!(c.command, MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL);
        assert_eq!((c.param1, c.param2), (33.0, 20_000.0));
    }
}
