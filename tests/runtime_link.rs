//! `mgmot run` as a ground station sees it: the real `mgmot-sim` is the autopilot and the frame
//! source, and this test is the GCS on the same UDP link. It selects a swimmer with
//! MAV_CMD_CAMERA_TRACK_POINT and follows it through CAMERA_TRACKING_GEO_STATUS /
//! CAMERA_TRACKING_IMAGE_STATUS, checks MAVLink 2 signing end to end, and watches the
//! STATUSTEXT of a telemetry dropout.
//!
//! The simulator binary is `$MGMOT_SIM_BIN`, or `target/debug/mgmot-sim` built here with
//! `cargo build -p mgmot-sim` (tests/common). Frames are made small (640x360) to keep the
//! debug-build simulator quick; the detections are simulated at the same size.

use crate::common;

use common::{
    distance_m, free_udp_port, mgmot_run, read_truth, run_config, track_time_ms, Proc, Relay,
    Scenario, Sent, TestDir,
};
use mavlink_core::{
    MAVLinkMessageRaw, MavHeader, MavlinkReader, MavlinkVersion, MessageData, SigningConfig,
    SigningData,
};
use mgmot::config::Config;
use mgmot::mavlink::dialect::*;
use sha2::{Digest, Sha256};
use std::path::PathBuf;
use std::time::{Duration, SystemTime, UNIX_EPOCH};

/// The GCS's system and component ids.
const GCS: (u8, u8) = (255, 190);
/// mgmot's system and component ids (the defaults).
const MGMOT: (u8, u8) = (1, 191);
/// Frame size for the simulator (and its detections).
const SIZE: (u32, u32) = (640, 360);
const KEY: [u8; 32] = [
    0x4d, 0x47, 0x4d, 0x4f, 0x54, 0x2d, 0x6b, 0x65, 0x79, 0x2d, 0x66, 0x6f, 0x72, 0x2d, 0x74, 0x65,
    0x73, 0x74, 0x73, 0x2d, 0x6f, 0x6e, 0x6c, 0x79, 0x2d, 0x30, 0x31, 0x32, 0x33, 0x34, 0x35, 0x36,
];

/// The simulator <-> mgmot relay, with the test's GCS on it: it sends the GCS's commands to
/// mgmot from the relay's own socket.
struct Link {
    relay: Relay,
    gcs_signing: SigningData,
    wrong_signing: SigningData,
}

impl Link {
    fn start(mgmot_port: u16) -> Link {
        Link {
            relay: Relay::start(mgmot_port),
            gcs_signing: SigningData::from_config(SigningConfig::new(KEY, 0, true, false)),
            wrong_signing: SigningData::from_config(SigningConfig::new([9; 32], 0, true, false)),
        }
    }

    /// Sends a message as the GCS; `Some(true)`: signed with the shared key, `Some(false)`:
    /// signed with a wrong key, `None`: unsigned.
    fn send(&self, msg: &MavMessage, signed: Option<bool>) {
        let header = MavHeader {
            system_id: u32::from(GCS.0),
            component_id: GCS.1,
            sequence: 0,
        };
        let signing = match signed {
            Some(true) => Some(&self.gcs_signing),
            Some(false) => Some(&self.wrong_signing),
            None => None,
        };
        let mut buf = Vec::new();
        mavlink_core::write_versioned_msg_signed(
            &mut buf,
            MavlinkVersion::V2,
            header,
            msg,
            signing,
        )
        .unwrap();
        self.relay
            .to_mgmot
            .send_to(&buf, ("127.0.0.1", self.relay.mgmot_port))
            .unwrap();
    }

    /// Sends a message as `from` (system, component) in MAVLink `version`, unsigned: a
    /// forger, or a stray message, with the autopilot's own ids.
    fn send_as(&self, msg: &MavMessage, from: (u8, u8), version: MavlinkVersion) {
        let header = MavHeader {
            system_id: u32::from(from.0),
            component_id: from.1,
            sequence: 0,
        };
        let mut buf = Vec::new();
        mavlink_core::write_versioned_msg(&mut buf, version, header, msg).unwrap();
        self.relay
            .to_mgmot
            .send_to(&buf, ("127.0.0.1", self.relay.mgmot_port))
            .unwrap();
    }

    fn finish(self) -> Vec<Sent> {
        self.relay.finish()
    }
}

/// The relay's `mark`, `since` and `wait_for`.
impl std::ops::Deref for Link {
    type Target = Relay;
    fn deref(&self) -> &Relay {
        &self.relay
    }
}

struct Setup {
    dir: TestDir,
    scenario: Scenario,
    config: PathBuf,
    mgmot_port: u16,
}

/// Simulated detections of `scenario` in `dir`, and the configuration `mgmot run` reads them
/// with, as `edit` leaves it.
fn setup(dir: TestDir, scenario: &str, duration_s: f64, edit: impl FnOnce(&mut Config)) -> Setup {
    let scenario = Scenario::new(scenario, duration_s).size(SIZE.0, SIZE.1);
    scenario.detections(&dir.join("dets.json"));
    let mgmot_port = free_udp_port();
    let mut config = run_config(
        &format!("udpin:127.0.0.1:{mgmot_port}"),
        &dir.join("frames.sock"),
        &dir.join("dets.json"),
    );
    edit(&mut config);
    let config = dir.write_config("run.toml", &config);
    Setup {
        dir,
        scenario,
        config,
        mgmot_port,
    }
}

/// The simulator in real time: the operator's steps take wall-clock time, and in lockstep an
/// optimised build can play the whole scenario before the last of them.
fn start_sim(s: &Setup, link: &Link) -> Proc {
    s.scenario
        .run(true, link.listen_port, &s.dir.join("frames.sock"))
        .spawn()
}

fn start_mgmot(s: &Setup) -> Proc {
    mgmot_run(&s.config, Some(&s.dir.join("stats.json"))).spawn_logged(s.dir.join("mgmot.log"))
}

/// How long mgmot may take to stop after SIGTERM.
const STOP_LIMIT: Duration = Duration::from_secs(20);

fn track_point(x: f32, y: f32) -> MavMessage {
    MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
        target_system: MGMOT.0,
        target_component: MGMOT.1,
        command: MavCmd::MAV_CMD_CAMERA_TRACK_POINT,
        param1: x,
        param2: y,
        ..Default::default()
    })
}

fn stop_tracking() -> MavMessage {
    MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
        target_system: MGMOT.0,
        target_component: MGMOT.1,
        command: MavCmd::MAV_CMD_CAMERA_STOP_TRACKING,
        ..Default::default()
    })
}

fn is_ack_for(m: &MavMessage, command: MavCmd) -> bool {
    matches!(m, MavMessage::COMMAND_ACK(a) if a.command == command
        && (a.target_system, a.target_component) == GCS)
}

fn ack_result(s: &Sent) -> MavResult {
    match &s.msg {
        MavMessage::COMMAND_ACK(a) => a.result,
        other => panic!("not an ack: {other:?}"),
    }
}

/// A swimmer track mgmot reports as geolocated and matched in its frame, with its box well
/// inside the image.
fn geolocated_swimmer(m: &MavMessage) -> bool {
    matches!(m, MavMessage::MGMOT_TRACK(t)
        if t.flags.contains(MgmotTrackFlags::MGMOT_TRACK_FLAGS_GEO_VALID)
            && t.state == MgmotTrackState::MGMOT_TRACK_STATE_TRACKED
            && t.object_class == MgmotObjectClass::MGMOT_OBJECT_CLASS_SWIMMER
            && (0.1..0.9).contains(&(t.bbox_x + t.bbox_w / 2.0))
            && (0.1..0.9).contains(&(t.bbox_y + t.bbox_h / 2.0)))
}

fn track_of(s: &Sent) -> MGMOT_TRACK_DATA {
    match &s.msg {
        MavMessage::MGMOT_TRACK(t) => t.clone(),
        other => panic!("not a track: {other:?}"),
    }
}

fn active(flags: CameraTrackingStatusFlags) -> bool {
    flags.contains(CameraTrackingStatusFlags::CAMERA_TRACKING_STATUS_FLAGS_ACTIVE)
}

/// The latest MGMOT_TRACK of `track_id` before position `before`.
fn latest_track(sent: &[Sent], before: usize, track_id: u32) -> Option<MGMOT_TRACK_DATA> {
    sent[..before].iter().rev().find_map(|s| match &s.msg {
        MavMessage::MGMOT_TRACK(t) if t.track_id == track_id => Some(t.clone()),
        _ => None,
    })
}

/// A point of the image at least 0.15 (of width / height) from every box of the tracks mgmot
/// reported in the last `window` messages before `before`.
fn empty_sea(sent: &[Sent], before: usize) -> (f32, f32) {
    let boxes: Vec<[f32; 4]> = sent[before.saturating_sub(400)..before]
        .iter()
        .filter_map(|s| match &s.msg {
            MavMessage::MGMOT_TRACK(t) => Some([t.bbox_x, t.bbox_y, t.bbox_w, t.bbox_h]),
            _ => None,
        })
        .collect();
    let clearance = |(x, y): (f32, f32)| {
        boxes
            .iter()
            .map(|[bx, by, bw, bh]| {
                let dx = (bx - x).max(x - (bx + bw)).max(0.0);
                let dy = (by - y).max(y - (by + bh)).max(0.0);
                dx.max(dy)
            })
            .fold(f32::INFINITY, f32::min)
    };
    let grid = (1..10).flat_map(|i| (1..10).map(move |j| (i as f32 / 10.0, j as f32 / 10.0)));
    let best = grid
        .max_by(|a, b| clearance(*a).total_cmp(&clearance(*b)))
        .unwrap();
    assert!(clearance(best) >= 0.15, "no empty sea among {boxes:?}");
    best
}

#[test]
fn operator_selects_a_swimmer_and_follows_it_until_stopped() {
    let s = setup(TestDir::new(), "calm_baseline", 60.0, |_| {});
    let link = Link::start(s.mgmot_port);
    let _sim = start_sim(&s, &link);
    let mut mgmot = start_mgmot(&s);
    let truth: Vec<_> = read_truth(&s.dir.join("dets_gt/world.csv"))
        .into_iter()
        .filter(|g| g.class == "swimmer")
        .collect();
    let limit = Duration::from_secs(120);

    // A swimmer on the operator's screen: click the centre of its box.
    let (_, seen) = link
        .wait_for(0, limit, geolocated_swimmer)
        .unwrap_or_else(|| panic!("no geolocated swimmer; mgmot: {}", mgmot.log()));
    let clicked = track_of(&seen);

    // A GCS asks what this "camera" is: the answer has the tracking capabilities and, frames
    // flowing, their size.
    let mark = link.mark();
    link.send(
        &MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
            target_system: MGMOT.0,
            target_component: MGMOT.1,
            command: MavCmd::MAV_CMD_REQUEST_MESSAGE,
            param1: CAMERA_INFORMATION_DATA::ID as f32,
            ..Default::default()
        }),
        None,
    );
    let (_, info) = link
        .wait_for(mark, Duration::from_secs(10), |m| {
            matches!(m, MavMessage::CAMERA_INFORMATION(_))
        })
        .expect("no CAMERA_INFORMATION");
    let MavMessage::CAMERA_INFORMATION(info) = info.msg else {
        unreachable!()
    };
    assert_eq!((info.resolution_h, info.resolution_v), (640, 360));

    let mark = link.mark();
    link.send(
        &track_point(
            clicked.bbox_x + clicked.bbox_w / 2.0,
            clicked.bbox_y + clicked.bbox_h / 2.0,
        ),
        None,
    );
    let (_, ack) = link
        .wait_for(mark, Duration::from_secs(10), |m| {
            is_ack_for(m, MavCmd::MAV_CMD_CAMERA_TRACK_POINT)
        })
        .expect("no COMMAND_ACK for TRACK_POINT");
    assert_eq!(ack_result(&ack), MavResult::MAV_RESULT_ACCEPTED);
    assert_eq!(ack.header.component_id, MGMOT.1);

    // Status of the selected swimmer, several times: on the true swimmer within a few metres,
    // the same object as the clicked track, its box where the track's box is.
    let mut geo_checked = 0;
    let mut image_checked = 0;
    let mut from = mark;
    while geo_checked < 3 || image_checked < 3 {
        let (i, status) = link
            .wait_for(from, Duration::from_secs(30), |m| {
                matches!(
                    m,
                    MavMessage::CAMERA_TRACKING_GEO_STATUS(_)
                        | MavMessage::CAMERA_TRACKING_IMAGE_STATUS(_)
                )
            })
            .expect("no tracking status after ACCEPTED");
        from = i + 1;
        let sent = link.since(0);
        let track = latest_track(&sent, i, clicked.track_id)
            .expect("the clicked track is no longer reported");
        match &status.msg {
            MavMessage::CAMERA_TRACKING_GEO_STATUS(g) => {
                assert!(active(g.tracking_status), "{g:?}");
                if g.tracking_status
                    .contains(CameraTrackingStatusFlags::CAMERA_TRACKING_STATUS_FLAGS_ERROR)
                {
                    continue;
                }
                let p = (f64::from(g.lat) * 1e-7, f64::from(g.lon) * 1e-7);
                let t_ms = track_time_ms(track.time_usec);
                let to_truth = truth
                    .iter()
                    .filter(|g| (g.t_ms - t_ms).abs() <= 500)
                    .map(|g| distance_m(p, (g.lat, g.lon)))
                    .fold(f64::INFINITY, f64::min);
                assert!(
                    to_truth < 3.0,
                    "GEO_STATUS {to_truth:.1} m from any swimmer: {g:?}"
                );
                let to_track = distance_m(
                    p,
                    (f64::from(track.lat) * 1e-7, f64::from(track.lon) * 1e-7),
                );
                assert!(
                    to_track < 2.0,
                    "GEO_STATUS {to_track:.1} m from the clicked track"
                );
                assert!(g.h_acc > 0.0 && g.h_acc < 10.0, "h_acc {}", g.h_acc);
                assert!(g.dist > 20.0 && g.dist < 200.0, "dist {}", g.dist);
                assert_eq!(g.vel_d, 0.0);
                geo_checked += 1;
            }
            MavMessage::CAMERA_TRACKING_IMAGE_STATUS(im) => {
                assert!(active(im.tracking_status), "{im:?}");
                assert_eq!(
                    im.tracking_mode,
                    CameraTrackingMode::CAMERA_TRACKING_MODE_POINT
                );
                let margin = 0.02;
                assert!(
                    (track.bbox_x - margin..=track.bbox_x + track.bbox_w + margin)
                        .contains(&im.point_x)
                        && (track.bbox_y - margin..=track.bbox_y + track.bbox_h + margin)
                            .contains(&im.point_y),
                    "IMAGE_STATUS point ({}, {}) not on the track's box {track:?}",
                    im.point_x,
                    im.point_y
                );
                image_checked += 1;
            }
            _ => unreachable!(),
        }
    }

    // A click on empty sea is refused; the selection stays.
    let mark = link.mark();
    let (x, y) = empty_sea(&link.since(0), mark);
    link.send(&track_point(x, y), None);
    let (_, ack) = link
        .wait_for(mark, Duration::from_secs(10), |m| {
            is_ack_for(m, MavCmd::MAV_CMD_CAMERA_TRACK_POINT)
        })
        .expect("no COMMAND_ACK for the empty-sea TRACK_POINT");
    assert_eq!(ack_result(&ack), MavResult::MAV_RESULT_FAILED);

    // Stop: accepted, one IDLE status of each kind, then silence.
    let mark = link.mark();
    link.send(&stop_tracking(), None);
    let (_, ack) = link
        .wait_for(mark, Duration::from_secs(10), |m| {
            is_ack_for(m, MavCmd::MAV_CMD_CAMERA_STOP_TRACKING)
        })
        .expect("no COMMAND_ACK for STOP_TRACKING");
    assert_eq!(ack_result(&ack), MavResult::MAV_RESULT_ACCEPTED);
    let (idle_at, _) = link
        .wait_for(mark, Duration::from_secs(10), |m| {
            matches!(m, MavMessage::CAMERA_TRACKING_IMAGE_STATUS(i)
                if i.tracking_status.is_empty()
                    && i.tracking_mode == CameraTrackingMode::CAMERA_TRACKING_MODE_NONE)
        })
        .expect("no IDLE image status after STOP_TRACKING");
    let frames_before = link
        .since(0)
        .iter()
        .filter(|s| matches!(s.msg, MavMessage::MGMOT_TRACK(_)))
        .count();
    std::thread::sleep(Duration::from_secs(2));
    let after = link.since(idle_at + 1);
    let frames_after = link
        .since(0)
        .iter()
        .filter(|s| matches!(s.msg, MavMessage::MGMOT_TRACK(_)))
        .count();
    assert!(
        frames_after > frames_before,
        "mgmot stopped producing tracks"
    );
    let active_after = after.iter().any(|s| match &s.msg {
        MavMessage::CAMERA_TRACKING_IMAGE_STATUS(i) => active(i.tracking_status),
        MavMessage::CAMERA_TRACKING_GEO_STATUS(g) => active(g.tracking_status),
        _ => false,
    });
    assert!(
        !active_after,
        "tracking status still active after STOP_TRACKING"
    );

    // A rectangle round a track's box, as COMMAND_INT: accepted, reported as a rectangle.
    let (_, seen) = link
        .wait_for(link.mark(), limit, geolocated_swimmer)
        .expect("no swimmer to draw a rectangle round");
    let t = track_of(&seen);
    let mark = link.mark();
    link.send(
        &MavMessage::COMMAND_INT(COMMAND_INT_DATA {
            target_system: MGMOT.0,
            target_component: MGMOT.1,
            command: MavCmd::MAV_CMD_CAMERA_TRACK_RECTANGLE,
            param1: t.bbox_x - 0.01,
            param2: t.bbox_y - 0.01,
            param3: t.bbox_x + t.bbox_w + 0.01,
            param4: t.bbox_y + t.bbox_h + 0.01,
            ..Default::default()
        }),
        None,
    );
    let (_, ack) = link
        .wait_for(mark, Duration::from_secs(10), |m| {
            is_ack_for(m, MavCmd::MAV_CMD_CAMERA_TRACK_RECTANGLE)
        })
        .expect("no COMMAND_ACK for TRACK_RECTANGLE");
    assert_eq!(ack_result(&ack), MavResult::MAV_RESULT_ACCEPTED);
    link.wait_for(mark, Duration::from_secs(10), |m| {
        matches!(m, MavMessage::CAMERA_TRACKING_IMAGE_STATUS(i)
            if active(i.tracking_status)
                && i.tracking_mode == CameraTrackingMode::CAMERA_TRACKING_MODE_RECTANGLE
                && i.rec_bottom_x > i.rec_top_x)
    })
    .expect("no rectangle status after TRACK_RECTANGLE");

    let status = mgmot.stop(STOP_LIMIT);
    let _ = link.finish();
    assert!(status.success(), "mgmot: {}", mgmot.log());
}

/// The 6-byte signature of a signed MAVLink 2 frame, recomputed from the key (SHA-256 of the
/// key followed by the frame up to the signature), as the MAVLink signing spec defines it.
fn expected_signature(key: &[u8; 32], frame: &[u8]) -> [u8; 6] {
    let signed_len = frame.len() - 6;
    let digest = Sha256::new()
        .chain_update(key)
        .chain_update(&frame[..signed_len])
        .finalize();
    let mut sig = [0u8; 6];
    sig.copy_from_slice(&digest[..6]);
    sig
}

#[test]
fn signing_signs_everything_and_refuses_unsigned_commands_only() {
    let dir = TestDir::new();
    let state_file = dir.join("signing-state.json");
    let s = setup(dir, "calm_baseline", 60.0, |c| {
        c.mavlink.signing = Some(mgmot::config::SigningConfig {
            key_hex: KEY.iter().map(|b| format!("{b:02x}")).collect(),
            link_id: 5,
            state_file,
            // The simulator's telemetry is unsigned (the default, said here as it is relied on).
            accept_unsigned_telemetry: true,
        });
    });
    let link = Link::start(s.mgmot_port);
    let _sim = start_sim(&s, &link);
    let mut mgmot = start_mgmot(&s);

    // The simulator's telemetry is unsigned, and still geolocates tracks.
    let (_, seen) = link
        .wait_for(0, Duration::from_secs(120), geolocated_swimmer)
        .unwrap_or_else(|| panic!("no geolocated swimmer; mgmot: {}", mgmot.log()));
    let t = track_of(&seen);
    let (x, y) = (t.bbox_x + t.bbox_w / 2.0, t.bbox_y + t.bbox_h / 2.0);

    // Unsigned command: refused with DENIED, nothing tracked.
    let mark = link.mark();
    link.send(&track_point(x, y), None);
    let (_, ack) = link
        .wait_for(mark, Duration::from_secs(10), |m| {
            is_ack_for(m, MavCmd::MAV_CMD_CAMERA_TRACK_POINT)
        })
        .expect("no COMMAND_ACK for the unsigned command");
    assert_eq!(ack_result(&ack), MavResult::MAV_RESULT_DENIED);

    // Signed with the wrong key: dropped by the link, no answer at all.
    let mark = link.mark();
    link.send(&track_point(x, y), Some(false));
    std::thread::sleep(Duration::from_millis(1500));
    let answered = link.since(mark).iter().any(|s| {
        is_ack_for(&s.msg, MavCmd::MAV_CMD_CAMERA_TRACK_POINT)
            || matches!(s.msg, MavMessage::CAMERA_TRACKING_IMAGE_STATUS(_))
    });
    assert!(!answered, "a command with a forged signature was answered");

    // Signed with the shared key: accepted and tracked. The click uses the newest box the GCS
    // has seen; on a loaded machine that box can be a few frames old and miss (FAILED: nothing
    // there), so the operator clicks again, as a person would. DENIED would fail at once.
    let mut mark = link.mark();
    let mut result = MavResult::MAV_RESULT_FAILED;
    for _ in 0..5 {
        let (_, seen) = link
            .wait_for(link.mark(), Duration::from_secs(60), geolocated_swimmer)
            .expect("no swimmer for the signed command");
        let t = track_of(&seen);
        mark = link.mark();
        link.send(
            &track_point(t.bbox_x + t.bbox_w / 2.0, t.bbox_y + t.bbox_h / 2.0),
            Some(true),
        );
        let (_, ack) = link
            .wait_for(mark, Duration::from_secs(10), |m| {
                is_ack_for(m, MavCmd::MAV_CMD_CAMERA_TRACK_POINT)
            })
            .expect("no COMMAND_ACK for the signed command");
        result = ack_result(&ack);
        if result != MavResult::MAV_RESULT_FAILED {
            break;
        }
    }
    assert_eq!(result, MavResult::MAV_RESULT_ACCEPTED);
    link.wait_for(
        mark,
        Duration::from_secs(10),
        |m| matches!(m, MavMessage::CAMERA_TRACKING_GEO_STATUS(g) if active(g.tracking_status)),
    )
    .expect("no tracking status after the signed command");

    let status = mgmot.stop(STOP_LIMIT);
    let sent = link.finish();
    assert!(status.success(), "mgmot: {}", mgmot.log());

    // Every frame mgmot sent is signed with the key and link id 5; timestamps (10 us units
    // since 2015-01-01) increase and are near now.
    let now_10us = (SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .unwrap()
        .as_micros()
        - 1_420_070_400_000_000)
        / 10;
    let mut last_timestamp = 0u64;
    assert!(sent.len() > 20, "only {} messages", sent.len());
    for s in &sent {
        let mut reader = MavlinkReader::new(&s.bytes[..]);
        let raw = reader
            .read_raw_message::<MavMessage>(MavlinkVersion::V2)
            .unwrap();
        let MAVLinkMessageRaw::V2(v2) = raw else {
            panic!("MAVLink 1 frame from mgmot")
        };
        assert_eq!(v2.incompatibility_flags() & 1, 1, "unsigned {:?}", s.msg);
        assert_eq!(v2.signature_link_id(), 5);
        assert_eq!(
            v2.signature_value(),
            expected_signature(&KEY, &s.bytes),
            "bad signature on {:?}",
            s.msg
        );
        let ts = v2.signature_timestamp();
        assert!(ts > last_timestamp, "timestamp not increasing");
        last_timestamp = ts;
        assert!(
            (ts as i128 - now_10us as i128).abs() < 100 * 60 * 10_000,
            "timestamp {ts} far from now {now_10us}"
        );
    }
}

#[test]
fn telemetry_dropout_is_announced_once_and_tracking_goes_on() {
    // The shipped telemetry_dropout scenario, with its 5 s dropout moved to t = 6 s so the
    // run is short; in real time, as telemetry loss is a matter of wall-clock time.
    let shipped = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/sim/scenarios/telemetry_dropout.toml"
    ))
    .unwrap();
    assert!(shipped.contains("dropouts = [[20.0, 5.0]]"));
    let dir = TestDir::new();
    let scenario = dir.write(
        "dropout_early.toml",
        shipped.replace("dropouts = [[20.0, 5.0]]", "dropouts = [[6.0, 5.0]]"),
    );
    let s = setup(dir, scenario.to_str().unwrap(), 16.0, |c| {
        c.telemetry.lost_after_ms = 1500.0;
    });
    let link = Link::start(s.mgmot_port);
    let mut sim = start_sim(&s, &link);
    let mut mgmot = start_mgmot(&s);
    sim.wait_within(Duration::from_secs(90))
        .expect("the simulator did not finish");
    let status = mgmot.stop(STOP_LIMIT);
    let sent = link.finish();
    assert!(status.success(), "mgmot: {}", mgmot.log());

    let texts: Vec<(usize, String)> = sent
        .iter()
        .enumerate()
        .filter_map(|(i, s)| match &s.msg {
            MavMessage::STATUSTEXT(t) => Some((i, t.text.to_str().unwrap().to_owned())),
            _ => None,
        })
        .filter(|(_, t)| t.contains("telemetry"))
        .collect();
    let only_texts: Vec<&str> = texts.iter().map(|(_, t)| t.as_str()).collect();
    assert_eq!(
        only_texts,
        [
            "mgmot: no telemetry, geolocation invalid",
            "mgmot: telemetry ok"
        ],
        "mgmot: {}",
        mgmot.log()
    );
    let (lost_at, back_at) = (texts[0].0, texts[1].0);
    let geo_valid = |range: std::ops::Range<usize>| -> (usize, usize) {
        sent[range]
            .iter()
            .fold((0, 0), |(valid, invalid), s| match &s.msg {
                MavMessage::MGMOT_TRACK(t) => {
                    if t.flags
                        .contains(MgmotTrackFlags::MGMOT_TRACK_FLAGS_GEO_VALID)
                    {
                        (valid + 1, invalid)
                    } else {
                        (valid, invalid + 1)
                    }
                }
                _ => (valid, invalid),
            })
    };
    // Geolocated before the dropout and after it; tracked in the image during it, flagged
    // "geolocation invalid".
    assert!(
        geo_valid(0..lost_at).0 > 0,
        "no geolocated track before the dropout"
    );
    let (_, invalid) = geo_valid(lost_at..back_at);
    assert!(invalid > 0, "no image-only track during the dropout");
    assert!(
        geo_valid(back_at..sent.len()).0 > 0,
        "no geolocated track after it"
    );
    // The tracker is reset neither when the pose goes away nor when it comes back: the same
    // ids are sent across each edge of the gap.
    let ids = |range: std::ops::Range<usize>| -> std::collections::BTreeSet<u32> {
        sent[range]
            .iter()
            .filter_map(|s| match &s.msg {
                MavMessage::MGMOT_TRACK(t) => Some(t.track_id),
                _ => None,
            })
            .collect()
    };
    let (b, d, a) = (
        ids(0..lost_at),
        ids(lost_at..back_at),
        ids(back_at..sent.len()),
    );
    assert!(
        b.intersection(&d).next().is_some() && d.intersection(&a).next().is_some(),
        "track ids not kept across the gap's edges: before {b:?}, during {d:?}, after {a:?}"
    );
    // In real time the capture stamps map onto the companion clock (TIMESYNC), so frame age
    // and end-to-end latency are measured, and the latter once per geolocated message at most.
    let stats: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(s.dir.join("stats.json")).unwrap()).unwrap();
    let count = |stage: &str| stats["latency"][stage]["count"].as_u64().unwrap_or(0);
    assert!(
        count("frame_age") > 0
            && count("end_to_end") > 0
            && count("end_to_end") <= stats["track_messages"].as_u64().unwrap_or(0),
        "{stats}"
    );
}

/// The simulated autopilot's ids (the scenario's system id, MAV_COMP_ID_AUTOPILOT1) and its
/// gimbal's.
const AUTOPILOT: (u8, u8) = (1, 1);
const GIMBAL: (u8, u8) = (1, 154);

/// GLOBAL_POSITION_INT stamped `time_boot_ms` at (lat, lon, alt AMSL).
fn position(time_boot_ms: u32, lat: f64, lon: f64, alt_m: f64) -> MavMessage {
    MavMessage::GLOBAL_POSITION_INT(GLOBAL_POSITION_INT_DATA {
        time_boot_ms,
        lat: (lat * 1e7) as i32,
        lon: (lon * 1e7) as i32,
        alt: (alt_m * 1e3) as i32,
        relative_alt: 30_000,
        ..Default::default()
    })
}

fn geo_valid(t: &MGMOT_TRACK_DATA) -> bool {
    t.flags
        .contains(MgmotTrackFlags::MGMOT_TRACK_FLAGS_GEO_VALID)
}

/// The tracks mgmot sent from `sent[from..]`.
fn tracks_in(sent: &[Sent], from: usize) -> Vec<MGMOT_TRACK_DATA> {
    sent[from..]
        .iter()
        .filter_map(|s| match &s.msg {
            MavMessage::MGMOT_TRACK(t) => Some(t.clone()),
            _ => None,
        })
        .collect()
}

/// The autopilot's clock now, as mgmot's latest track says (its frame's exposure time, ms
/// since the simulated autopilot's boot), and the latest geolocated position.
fn autopilot_now(link: &Link) -> Option<(u32, f64, f64)> {
    let sent = link.since(0);
    sent.iter().rev().find_map(|s| match &s.msg {
        MavMessage::MGMOT_TRACK(t) if geo_valid(t) => Some((
            (t.time_usec / 1000) as u32,
            f64::from(t.lat) * 1e-7,
            f64::from(t.lon) * 1e-7,
        )),
        _ => None,
    })
}

/// WARN lines in mgmot's log.
fn warnings(log: &str) -> usize {
    log.lines().filter(|l| l.contains(" WARN ")).count()
}

/// Issue 39, item 3: stray or forged MAVLink 1 positions with the autopilot's ids, stamped
/// near zero every 100 ms, counted as an autopilot reboot each: no report geolocated, a WARN
/// line and a stream request per message. They are stale stamps now: not used, counted, and
/// tracking goes on geolocated.
#[test]
fn forged_positions_stamped_near_zero_are_no_reboot() {
    let s = setup(TestDir::new(), "calm_baseline", 22.0, |_| {});
    let link = Link::start(s.mgmot_port);
    let mut sim = start_sim(&s, &link);
    let mut mgmot = start_mgmot(&s);
    let (first, _) = link
        .wait_for(
            0,
            Duration::from_secs(60),
            |m| matches!(m, MavMessage::MGMOT_TRACK(t) if geo_valid(t)),
        )
        .unwrap_or_else(|| panic!("no geolocated track; mgmot: {}", mgmot.log()));
    let (_, lat, lon) = autopilot_now(&link).unwrap();
    let from = link.mark().max(first);
    let forging = std::time::Instant::now();
    let mut k = 0u32;
    while forging.elapsed() < Duration::from_secs(10) {
        link.send_as(
            &position(k * 100, lat, lon, 430.0),
            AUTOPILOT,
            MavlinkVersion::V1,
        );
        k += 1;
        std::thread::sleep(Duration::from_millis(100));
    }
    let until = link.mark();
    sim.wait_within(Duration::from_secs(90))
        .expect("the simulator did not finish");
    let status = mgmot.stop(STOP_LIMIT);
    let sent = link.finish();
    let log = mgmot.log();
    assert!(status.success(), "mgmot: {log}");
    let during = tracks_in(&sent[..until], from);
    let geolocated = during.iter().filter(|t| geo_valid(t)).count();
    assert!(
        during.len() >= 20 && geolocated * 10 >= during.len() * 9,
        "{geolocated} of {} reports geolocated while forged stamps came; mgmot: {log}",
        during.len()
    );
    let stats: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(s.dir.join("stats.json")).unwrap()).unwrap();
    assert_eq!(stats["telemetry"]["autopilot_reboots"], 0, "{stats}");
    assert_eq!(stats["link"]["autopilot_restarts"], 0, "{stats}");
    assert!(
        stats["telemetry"]["stale_stamps"].as_u64() >= Some(u64::from(k) * 8 / 10),
        "{k} forged: {stats}"
    );
    assert!(
        stats["link"]["stream_requests"].as_u64() <= Some(30),
        "{stats}"
    );
    assert!(warnings(&log) <= 10, "{} WARN lines: {log}", warnings(&log));
}

/// Issue 39, item 4: impossible telemetry with the autopilot's own ids was used as it came
/// (tracks kilometres off, new ids, nothing said). Positions 50 km off among the true ones,
/// fuzzed positions anywhere on earth, a skewed gimbal quaternion and an altitude of -1000 m,
/// one after the other for 12 s: every one is refused, the operator is told once when it
/// starts and once when telemetry is plausible again, and no geolocated report moves off the
/// truth.
#[test]
fn implausible_telemetry_is_refused_reported_once_and_moves_no_track() {
    let s = setup(TestDir::new(), "calm_baseline", 30.0, |_| {});
    let truth = read_truth(&s.dir.join("dets_gt/world.csv"));
    let link = Link::start(s.mgmot_port);
    let mut sim = start_sim(&s, &link);
    let mut mgmot = start_mgmot(&s);
    link.wait_for(
        0,
        Duration::from_secs(60),
        |m| matches!(m, MavMessage::MGMOT_TRACK(t) if geo_valid(t)),
    )
    .unwrap_or_else(|| panic!("no geolocated track; mgmot: {}", mgmot.log()));
    let (t0_ms, lat, lon) = autopilot_now(&link).unwrap();
    let forging = std::time::Instant::now();
    let mut fuzz = 0x2545_f491_4f6c_dd1du64;
    let mut forged = 0u64;
    while forging.elapsed() < Duration::from_secs(12) {
        let e = forging.elapsed();
        let now_ms = t0_ms + e.as_millis() as u32;
        let msg = match e.as_secs() {
            // 50 km north, interleaved with the true positions.
            0..=2 => position(now_ms, lat + 0.45, lon, 430.0),
            // Anywhere on earth.
            3..=5 => {
                fuzz ^= fuzz << 13;
                fuzz ^= fuzz >> 7;
                fuzz ^= fuzz << 17;
                let lat = (fuzz % 17_000) as f64 / 100.0 - 85.0;
                let lon = ((fuzz >> 20) % 35_000) as f64 / 100.0 - 175.0;
                position(now_ms, lat, lon, (fuzz >> 40) as f64 % 5000.0)
            }
            // A gimbal quaternion that is no rotation (norm 1.36).
            6..=8 => {
                MavMessage::GIMBAL_DEVICE_ATTITUDE_STATUS(GIMBAL_DEVICE_ATTITUDE_STATUS_DATA {
                    time_boot_ms: now_ms,
                    q: [1.3, 0.4, 0.0, 0.0],
                    ..Default::default()
                })
            }
            // Under the sea.
            _ => position(now_ms, lat, lon, -1000.0),
        };
        let from = if matches!(msg, MavMessage::GIMBAL_DEVICE_ATTITUDE_STATUS(_)) {
            GIMBAL
        } else {
            AUTOPILOT
        };
        link.send_as(&msg, from, MavlinkVersion::V2);
        forged += 1;
        std::thread::sleep(Duration::from_millis(50));
    }
    sim.wait_within(Duration::from_secs(90))
        .expect("the simulator did not finish");
    let status = mgmot.stop(STOP_LIMIT);
    let sent = link.finish();
    let log = mgmot.log();
    assert!(status.success(), "mgmot: {log}");

    // No geolocated report off the truth (calm_baseline geolocates within a few metres).
    let tracks = tracks_in(&sent, 0);
    let mut worst = 0.0f64;
    for t in tracks.iter().filter(|t| geo_valid(t)) {
        let t_ms = track_time_ms(t.time_usec);
        let (lat, lon) = (f64::from(t.lat) * 1e-7, f64::from(t.lon) * 1e-7);
        let d = truth
            .iter()
            .filter(|g| (g.t_ms - t_ms).abs() <= 5)
            .map(|g| distance_m((lat, lon), (g.lat, g.lon)))
            .fold(f64::INFINITY, f64::min);
        worst = worst.max(d);
    }
    assert!(
        worst < 15.0,
        "a geolocated report {worst:.0} m from any true object; mgmot: {log}"
    );
    // Told once when it started, once when it ended.
    let texts: Vec<String> = sent
        .iter()
        .filter_map(|s| match &s.msg {
            MavMessage::STATUSTEXT(t) => Some(t.text.to_str().unwrap_or("").to_owned()),
            _ => None,
        })
        .filter(|t| t.contains("telemetry"))
        .collect();
    let refused = texts
        .iter()
        .filter(|t| t.starts_with("mgmot: telemetry refused"))
        .count();
    let again = texts
        .iter()
        .filter(|t| *t == "mgmot: telemetry plausible again")
        .count();
    assert_eq!((refused, again), (1, 1), "{texts:?}");
    let stats: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(s.dir.join("stats.json")).unwrap()).unwrap();
    assert!(
        stats["telemetry"]["implausible"].as_u64() >= Some(forged * 8 / 10),
        "{forged} forged: {stats}"
    );
    assert!(warnings(&log) <= 10, "{} WARN lines: {log}", warnings(&log));
}
