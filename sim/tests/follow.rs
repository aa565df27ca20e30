//! `mgmot-sim follow` against a stand-in autopilot (`mgmot-sim run`, telemetry only) over
//! real sockets: follow subscribes (its SET_MESSAGE_INTERVAL requests are acknowledged and
//! honoured), renders at the scenario's frame rate once telemetry flows and not before, stamps
//! the frames on the autopilot clock, and the camera pose it used (its truth camera.csv) is
//! the stand-in's true camera pose at those stamps.

use crate::common::{
    connect_frames, free_tcp_port, free_udp_port, read_frame, spawn_sim, stderr_text, TestDir,
};
use mgmot_sim::framing::{FrameHeader, HEADER_LEN};
use mgmot_sim::scenario::Scenario;
use mgmot_sim::truth::Optics;
use mgmot_sim::world::World;
use nalgebra::{Quaternion, UnitQuaternion, Vector3};
use std::io::Read;
use std::os::unix::net::UnixStream;
use std::path::Path;
use std::time::{Duration, Instant};

const SCENARIO: &str = "gimbal_swings";

/// Every frame up to the end of the stream: header and arrival (the pixels are not kept).
fn read_headers(s: &mut UnixStream) -> Vec<(FrameHeader, Instant)> {
    let mut frames = Vec::new();
    while let Some(f) = read_frame(s) {
        frames.push((f.header, f.arrived));
    }
    frames
}

/// Agreement of follow's camera.csv with the stand-in's true pose.
struct Agreement {
    frames: usize,
    pos_max_m: f64,
    pos_p95_m: f64,
    ang_max_deg: f64,
    ang_p99_deg: f64,
    ang_p95_deg: f64,
    ang_median_deg: f64,
    stamps_us: Vec<u64>,
}

fn pct(v: &[f64], q: f64) -> f64 {
    let mut v = v.to_vec();
    v.sort_by(f64::total_cmp);
    v[((v.len() - 1) as f64 * q).round() as usize]
}

/// Compares every row of follow's camera.csv with the scenario's own flight (what the
/// stand-in autopilot reports, without faults in this scenario) at the row's stamp.
fn pose_agreement(camera_csv: &Path) -> Agreement {
    let s = Scenario::load(SCENARIO).unwrap();
    let optics = Optics::new(&s).unwrap();
    let boot_s = s.telemetry.boot_time_s;
    let world = World::new(s.clone(), s.seed);
    let text = std::fs::read_to_string(camera_csv).unwrap();
    let mut lines = text.lines();
    let head: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| head.iter().position(|h| *h == name).unwrap();
    let (c_stamp, c_n, c_qw) = (col("frame_stamp_us"), col("north_m"), col("qw"));
    let (mut pos, mut ang, mut stamps) = (Vec::new(), Vec::new(), Vec::new());
    for line in lines {
        let f: Vec<&str> = line.split(',').collect();
        let num = |i: usize| f[i].parse::<f64>().unwrap();
        let stamp: u64 = f[c_stamp].parse().unwrap();
        let t = stamp as f64 / 1e6 - boot_s;
        let truth = optics.pose(&world.truth(t));
        let p = Vector3::new(num(c_n), num(c_n + 1), num(c_n + 2));
        let q = UnitQuaternion::from_quaternion(Quaternion::new(
            num(c_qw),
            num(c_qw + 1),
            num(c_qw + 2),
            num(c_qw + 3),
        ));
        pos.push((p - truth.position_ned).norm());
        ang.push(q.angle_to(&truth.attitude).to_degrees());
        stamps.push(stamp);
    }
    assert!(!pos.is_empty(), "follow wrote no camera pose");
    Agreement {
        frames: pos.len(),
        pos_max_m: pct(&pos, 1.0),
        pos_p95_m: pct(&pos, 0.95),
        ang_max_deg: pct(&ang, 1.0),
        ang_p99_deg: pct(&ang, 0.99),
        ang_p95_deg: pct(&ang, 0.95),
        ang_median_deg: pct(&ang, 0.5),
        stamps_us: stamps,
    }
}

/// The number in `key=N` on the first log line containing `line_has`.
fn logged_number(log: &str, line_has: &str, key: &str) -> Option<u64> {
    let line = log.lines().find(|l| l.contains(line_has))?;
    let rest = &line[line.find(&format!("{key}="))? + key.len() + 1..];
    rest.split(|c: char| !c.is_ascii_digit())
        .next()?
        .parse()
        .ok()
}

#[test]
fn follow_renders_the_stand_in_autopilots_pose_on_its_clock() {
    let dir = TestDir::new();
    let sock = dir.join("follow.sock");
    let port = free_tcp_port();
    let run_truth = dir.join("run_truth");
    let follow_truth = dir.join("follow_truth");
    let run_spawned = Instant::now();
    let run = spawn_sim(&[
        "run",
        "-s",
        SCENARIO,
        "--realtime",
        "--duration-s",
        "11",
        "--mavlink",
        &format!("tcpin:127.0.0.1:{port}"),
        "--truth-out",
        run_truth.to_str().unwrap(),
    ]);
    let follow = spawn_sim(&[
        "follow",
        "-s",
        SCENARIO,
        "--mavlink",
        &format!("tcpout:127.0.0.1:{port}"),
        "--frames",
        &format!("unix:{}", sock.display()),
        "--duration-s",
        "7",
        "--width",
        "320",
        "--height",
        "180",
        "--truth-out",
        follow_truth.to_str().unwrap(),
    ]);
    let mut s = connect_frames(&sock);
    let frames = read_headers(&mut s);
    let out = follow.wait_with_output();
    let log = stderr_text(&out);
    assert!(out.status.success(), "{log}");
    let run_out = run.wait_with_output();
    assert!(run_out.status.success());

    // Subscribed: every request acknowledged, and the 50 Hz it asked for honoured (the
    // stand-in's default is 10-20 Hz).
    for name in [
        "GLOBAL_POSITION_INT",
        "ATTITUDE",
        "GIMBAL_DEVICE_ATTITUDE_STATUS",
    ] {
        assert!(
            log.contains(&format!(
                "SET_MESSAGE_INTERVAL acknowledged stream={name} result=MAV_RESULT_ACCEPTED"
            )),
            "{name} not acknowledged:\n{log}"
        );
        let received = logged_number(&log, &format!("stream stream={name}"), "received")
            .unwrap_or_else(|| panic!("no count of {name}:\n{log}"));
        assert!(
            received >= 40 * 7,
            "{name}: {received} in about 7 s:\n{log}"
        );
    }

    // Frames at the scenario's 30 fps, indices increasing.
    assert!(frames.len() >= 150, "{} frames:\n{log}", frames.len());
    let span = frames[frames.len() - 1].1 - frames[0].1;
    let fps = (frames.len() - 1) as f64 / span.as_secs_f64();
    assert!((27.0..=33.0).contains(&fps), "{fps} fps");
    for w in frames.windows(2) {
        assert!(
            w[1].0.index > w[0].0.index,
            "{} then {}",
            w[0].0.index,
            w[1].0.index
        );
        assert!(w[1].0.capture_time_us > w[0].0.capture_time_us);
    }
    assert_eq!((frames[0].0.width, frames[0].0.height), (320, 180));

    // Stamps on the autopilot clock: the stand-in's clock is its boot time (120 s) plus the
    // time since it started (a little after it was spawned); a frame is stamped at its
    // capture, the scenario's 40 ms latency before it is sent.
    for (h, arrived) in &frames {
        let ap_at_arrival_us = 120_000_000 + arrived.duration_since(run_spawned).as_micros() as i64;
        let early_us = ap_at_arrival_us - h.capture_time_us as i64;
        assert!(
            (0..=400_000).contains(&early_us),
            "frame {} stamped {} us, the autopilot clock at arrival about {ap_at_arrival_us} us",
            h.index,
            h.capture_time_us
        );
    }
    // ... and within the stand-in's own truth timeline (its camera.csv stamps are its clock).
    let run_csv = std::fs::read_to_string(run_truth.join("camera.csv")).unwrap();
    let run_stamps: Vec<u64> = run_csv
        .lines()
        .skip(1)
        .map(|l| l.split(',').nth(2).unwrap().parse().unwrap())
        .collect();
    let (first, last) = (run_stamps[0], run_stamps[run_stamps.len() - 1]);
    assert!(frames
        .iter()
        .all(|(h, _)| (first..=last).contains(&h.capture_time_us)));

    // The pose follow rendered from is the stand-in's true pose at each frame's stamp.
    let a = pose_agreement(&follow_truth.join("camera.csv"));
    eprintln!(
        "follow vs truth over {} frames: position max {:.3} m (p95 {:.3}); angle max {:.3} deg, \
         p99 {:.3}, p95 {:.3}, median {:.4}",
        a.frames,
        a.pos_max_m,
        a.pos_p95_m,
        a.ang_max_deg,
        a.ang_p99_deg,
        a.ang_p95_deg,
        a.ang_median_deg
    );
    assert!(a.frames >= frames.len(), "truth for every frame sent");
    let sent: Vec<u64> = frames.iter().map(|(h, _)| h.capture_time_us).collect();
    assert!(
        sent.iter().all(|s| a.stamps_us.contains(s)),
        "truth rows carry the frames' stamps"
    );
    assert!(a.pos_max_m < 1.0, "position off by {} m", a.pos_max_m);
    assert!(a.ang_p99_deg < 1.0, "angle p99 {} deg", a.ang_p99_deg);
    // A frame whose telemetry came late on a loaded machine holds the last sample; during a
    // 180 deg/s swing that costs a few degrees, never more.
    assert!(a.ang_max_deg < 10.0, "angle max {} deg", a.ang_max_deg);
    assert!(follow_truth.join("world.csv").exists() && follow_truth.join("gt/gt.txt").exists());
}

#[test]
fn follow_waits_for_telemetry_then_subscribes_over_udp() {
    let dir = TestDir::new();
    let sock = dir.join("follow.sock");
    let port = free_udp_port();
    // Follow first: nobody to talk to, so no pose and no frames.
    let follow = spawn_sim(&[
        "follow",
        "-s",
        SCENARIO,
        "--mavlink",
        &format!("udpout:127.0.0.1:{port}"),
        "--frames",
        &format!("unix:{}", sock.display()),
        "--duration-s",
        "3",
        "--width",
        "160",
        "--height",
        "90",
    ]);
    let mut s = connect_frames(&sock);
    s.set_read_timeout(Some(Duration::from_millis(1500)))
        .unwrap();
    let mut h = [0u8; HEADER_LEN];
    let e = s.read_exact(&mut h).unwrap_err();
    assert!(
        matches!(
            e.kind(),
            std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
        ),
        "{e}"
    );
    s.set_read_timeout(Some(Duration::from_secs(20))).unwrap();
    // The stand-in on udpin only knows where to send once follow's heartbeat reached it.
    let run = spawn_sim(&[
        "run",
        "-s",
        SCENARIO,
        "--realtime",
        "--duration-s",
        "8",
        "--mavlink",
        &format!("udpin:127.0.0.1:{port}"),
    ]);
    let frames = read_headers(&mut s);
    let out = follow.wait_with_output();
    let log = stderr_text(&out);
    assert!(out.status.success(), "{log}");
    drop(run); // killed
    assert!(log.contains("no pose: no frames"), "{log}");
    assert!(
        log.contains(
            "SET_MESSAGE_INTERVAL acknowledged stream=ATTITUDE result=MAV_RESULT_ACCEPTED"
        ),
        "{log}"
    );
    assert!(frames.len() >= 60, "{} frames in 3 s:\n{log}", frames.len());
    assert!(
        frames[0].0.capture_time_us >= 120_000_000,
        "autopilot clock"
    );
}
