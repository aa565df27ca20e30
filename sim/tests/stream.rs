//! `mgmot-sim run` over real sockets: frames on a Unix socket (lockstep and real time, a
//! consumer that disconnects), telemetry over UDP decoded with the mavlink crate, and the
//! autopilot's answers to TIMESYNC, SET_MESSAGE_INTERVAL and REQUEST_MESSAGE.

use crate::common::{
    connect_frames, free_udp_port, read_frame, read_frames, spawn_sim, stderr_text, TestDir,
};
use mavlink::dialects::common::{MavCmd, MavMessage, MavResult, COMMAND_LONG_DATA, TIMESYNC_DATA};
use mavlink::MavConnection;
use std::collections::HashMap;
use std::net::UdpSocket;
use std::time::{Duration, Instant};

/// Parses every MAVLink 2 message in the datagrams received until `stop`, and then those
/// still queued in the socket (a loaded machine can read behind the sender; stopping at `stop`
/// itself, CI once counted 32 ATTITUDE of a lockstep run's 38-44).
fn collect_udp(sock: &UdpSocket, stop: impl Fn() -> bool) -> Vec<MavMessage> {
    sock.set_read_timeout(Some(Duration::from_millis(100)))
        .unwrap();
    let mut msgs = Vec::new();
    let mut buf = [0u8; 2048];
    let deadline = Instant::now() + Duration::from_secs(60);
    while Instant::now() < deadline {
        let stopped = stop();
        let n = match sock.recv(&mut buf) {
            Ok(n) => n,
            // Nothing for 100 ms after `stop`: the queue is drained.
            Err(_) if stopped => break,
            Err(_) => continue,
        };
        let mut reader = mavlink::MavlinkReader::new(&buf[..n]);
        while let Ok((_, m)) = reader.read_message::<MavMessage>(mavlink::MavlinkVersion::V2) {
            msgs.push(m);
        }
    }
    msgs
}

#[test]
fn lockstep_frames_and_udp_telemetry() {
    let dir = TestDir::new();
    let sock_path = dir.join("frames.sock");
    let udp = UdpSocket::bind("127.0.0.1:0").unwrap();
    let port = udp.local_addr().unwrap().port();
    let frames_arg = format!("unix:{}", sock_path.display());
    let mav_arg = format!("udpout:127.0.0.1:{port}");
    let mut child = spawn_sim(&[
        "run",
        "-s",
        "camera_desync",
        "--lockstep",
        "--duration-s",
        "2",
        "--width",
        "160",
        "--height",
        "90",
        "--frames",
        &frames_arg,
        "--mavlink",
        &mav_arg,
    ]);
    let mut s = connect_frames(&sock_path);
    let reader = std::thread::spawn(move || read_frames(&mut s));
    let msgs = collect_udp(&udp, || reader.is_finished());
    let frames = reader.join().unwrap();
    let status = child.wait();
    assert!(status.success());

    assert_eq!(frames.len(), 60, "2 s at 30 fps");
    for (k, f) in frames.iter().enumerate() {
        let (h, px) = (&f.header, &f.pixels);
        assert_eq!(h.index, k as u64);
        assert_eq!((h.width, h.height, &h.fourcc), (160, 90, b"RGB3"));
        assert_eq!(px.len(), 160 * 90 * 3);
        // Autopilot clock: boot at 120 s, 30 fps, camera clock 200 ms late (the scenario's
        // desync fault).
        let want_us = 120_000_000 + (k as u64 * 1_000_000) / 30 + 200_000;
        assert!(
            h.capture_time_us.abs_diff(want_us) <= 1,
            "{} vs {want_us}",
            h.capture_time_us
        );
    }
    assert_ne!(frames[0].pixels, frames[59].pixels, "the picture changes");

    let mut counts: HashMap<&str, usize> = HashMap::new();
    for m in &msgs {
        *counts.entry(mavlink::Message::message_name(m)).or_default() += 1;
    }
    // Lockstep emits the telemetry of the simulated 2 s (+ capture latency), whatever the
    // wall-clock speed.
    let c = |n: &str| counts.get(n).copied().unwrap_or(0);
    assert!((38..=44).contains(&c("ATTITUDE")), "{counts:?}");
    assert!((19..=22).contains(&c("GLOBAL_POSITION_INT")), "{counts:?}");
    assert!(
        (19..=22).contains(&c("GIMBAL_DEVICE_ATTITUDE_STATUS")),
        "{counts:?}"
    );
    assert!((19..=22).contains(&c("MOUNT_ORIENTATION")), "{counts:?}");
    assert!((2..=3).contains(&c("HEARTBEAT")), "{counts:?}");
    assert!(
        c("SYSTEM_TIME") >= 2 && c("HOME_POSITION") >= 1,
        "{counts:?}"
    );
}

#[test]
fn realtime_survives_a_consumer_that_disconnects() {
    let dir = TestDir::new();
    let sock_path = dir.join("rt.sock");
    let frames_arg = format!("unix:{}", sock_path.display());
    let child = spawn_sim(&[
        "run",
        "-s",
        "calm_baseline",
        "--realtime",
        "--duration-s",
        "2.5",
        "--width",
        "96",
        "--height",
        "64",
        "--frames",
        &frames_arg,
    ]);
    let mut s = connect_frames(&sock_path);
    let h = read_frame(&mut s).unwrap().header;
    let h2 = read_frame(&mut s).unwrap().header;
    assert_eq!(h2.index, h.index + 1);
    drop(s);
    // A second consumer gets later frames.
    std::thread::sleep(Duration::from_millis(300));
    let mut s = connect_frames(&sock_path);
    let h3 = read_frame(&mut s).unwrap().header;
    assert!(h3.index > h2.index + 2, "{} then {}", h2.index, h3.index);
    drop(s);
    let out = child.wait_with_output();
    let err = stderr_text(&out);
    assert!(out.status.success(), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    assert!(!sock_path.exists(), "socket file removed at exit");
}

#[test]
fn answers_timesync_and_commands_over_udpin() {
    let port = free_udp_port();
    let mav_arg = format!("udpin:127.0.0.1:{port}");
    let child = spawn_sim(&[
        "run",
        "-s",
        "calm_baseline",
        "--realtime",
        "--duration-s",
        "20",
        "--mavlink",
        &mav_arg,
    ]);
    let cfg = mavlink::UdpConfig::new(format!("127.0.0.1:{port}"), mavlink::UdpMode::Udpout)
        .read_timeout(Duration::from_millis(200));
    let mut conn = mavlink::Connectable::connect::<MavMessage>(&cfg).unwrap();
    conn.set_protocol_version(mavlink::MavlinkVersion::V2);
    let header = mavlink::MavHeader {
        system_id: 255,
        component_id: 190,
        sequence: 0,
    };
    let requests = [
        MavMessage::TIMESYNC(TIMESYNC_DATA {
            tc1: 0,
            ts1: 777,
            ..Default::default()
        }),
        MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
            command: MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL,
            param1: 30.0,
            param2: 500_000.0,
            target_system: 1,
            ..Default::default()
        }),
        MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
            command: MavCmd::MAV_CMD_REQUEST_MESSAGE,
            param1: 242.0,
            target_system: 1,
            ..Default::default()
        }),
    ];
    let (mut timesync, mut acks, mut attitude_after) = (false, Vec::new(), Vec::new());
    let start = Instant::now();
    let mut sent_at: Option<Instant> = None;
    let mut last_try = Instant::now() - Duration::from_secs(1);
    while start.elapsed() < Duration::from_secs(15) {
        if sent_at.is_some_and(|t| t.elapsed() > Duration::from_secs(4)) {
            break;
        }
        // udpin learns our address from the first datagram; repeat until the sim is up.
        if (!timesync || acks.len() < 2) && last_try.elapsed() > Duration::from_millis(300) {
            for r in &requests {
                conn.send(&header, r).unwrap();
            }
            last_try = Instant::now();
        }
        let Ok((_, m)) = conn.recv() else { continue };
        if sent_at.is_none() {
            sent_at = Some(last_try);
        }
        match m {
            MavMessage::TIMESYNC(t) if t.ts1 == 777 && t.tc1 > 0 => timesync = true,
            MavMessage::COMMAND_ACK(a) => acks.push((a.command, a.result)),
            MavMessage::ATTITUDE(_)
                if sent_at.is_some_and(|t| t.elapsed() > Duration::from_secs(1)) =>
            {
                attitude_after.push(Instant::now())
            }
            _ => {}
        }
    }
    drop(child); // killed
    assert!(timesync, "no TIMESYNC answer");
    assert!(
        acks.contains(&(
            MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL,
            MavResult::MAV_RESULT_ACCEPTED
        )),
        "{acks:?}"
    );
    assert!(
        acks.contains(&(
            MavCmd::MAV_CMD_REQUEST_MESSAGE,
            MavResult::MAV_RESULT_ACCEPTED
        )),
        "{acks:?}"
    );
    // ATTITUDE slowed from 20 Hz to 2 Hz: at most ~8 in the last ~4 s.
    assert!(
        (4..=10).contains(&attitude_after.len()),
        "{} ATTITUDE after the change",
        attitude_after.len()
    );
}
