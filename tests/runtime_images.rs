//! `mgmot run` with `frames.source = "images"`: frames rendered by the real `mgmot-sim render`
//! (JPEG files), detections from `mgmot-sim detections` for the same scenario (the replay
//! detector looks them up by frame index), MAVLink out over UDP to this test. The run must
//! play the whole directory at its nominal rate, send MGMOT_TRACK messages whose boxes fit the
//! decoded images, and exit 0 at the end of the directory.
//!
//! No telemetry is sent to mgmot, so tracks are image-only (no geolocation): what is under
//! test is the frame source, not the pose path (`runtime_loopback.rs` covers that).
//!
//! The simulator binary is `$MGMOT_SIM_BIN`, or `target/debug/mgmot-sim` built here.

use crate::common;

use common::{mgmot_run, run_config, sim, Scenario, TestDir};
use mavlink_core::{MavlinkReader, MavlinkVersion};
use mgmot::config::FramesConfig;
use mgmot::mavlink::dialect::MavMessage;
use std::net::UdpSocket;
use std::time::{Duration, Instant};

#[test]
fn plays_a_directory_tracks_and_stops_at_its_end() {
    // swimmer_group: its swimmers are in view from the first frame (calm_baseline's come later).
    let (scenario, fps) = (Scenario::new("swimmer_group", 2.0), 30.0);
    let dir = TestDir::new();
    sim()
        .arg("render")
        .args(scenario.args())
        .args(["--format", "jpg", "-o"])
        .arg(dir.join("seq"))
        .ok();
    scenario.detections(&dir.join("dets.json"));
    let images = std::fs::read_dir(dir.join("seq/img1")).unwrap().count() as u64;
    assert!(images >= 50, "{images} rendered images");

    let gcs = UdpSocket::bind("127.0.0.1:0").unwrap();
    gcs.set_read_timeout(Some(Duration::from_millis(50)))
        .unwrap();
    let mut c = run_config(
        &format!("udpout:127.0.0.1:{}", gcs.local_addr().unwrap().port()),
        &dir.join("unused.sock"),
        &dir.join("dets.json"),
    );
    c.mavlink.stream_rate_hz = 0.0;
    c.frames = FramesConfig::Images {
        directory: dir.join("seq/img1"),
        fps,
        looping: false,
    };
    let config = dir.write_config("run.toml", &c);
    let started = Instant::now();
    let mut mgmot = mgmot_run(&config, None).spawn_logged(dir.join("mgmot.log"));
    let mut messages = Vec::new();
    let mut buf = [0u8; 65536];
    let status = loop {
        if let Ok(n) = gcs.recv(&mut buf) {
            let mut reader = MavlinkReader::new(&buf[..n]);
            while let Ok((_, m)) = reader.read_message::<MavMessage>(MavlinkVersion::V2) {
                messages.push(m);
            }
        }
        if let Some(status) = mgmot.exited() {
            break status;
        }
        if started.elapsed() > Duration::from_secs(120) {
            panic!("mgmot run did not stop at the end of the directory");
        }
    };
    let elapsed = started.elapsed();
    // Datagrams sent just before exit.
    while let Ok(n) = gcs.recv(&mut buf) {
        let mut reader = MavlinkReader::new(&buf[..n]);
        while let Ok((_, m)) = reader.read_message::<MavMessage>(MavlinkVersion::V2) {
            messages.push(m);
        }
    }
    let stderr = mgmot.log();
    assert!(status.success(), "mgmot run failed: {stderr}");

    // Every image was shown, at the nominal rate (not faster).
    let summary = stderr
        .lines()
        .find(|l| l.starts_with("mgmot run:"))
        .unwrap_or_else(|| panic!("no summary line in: {stderr}"));
    let numbers: Vec<u64> = summary
        .split(|c: char| !c.is_ascii_digit())
        .filter_map(|w| w.parse().ok())
        .collect();
    let (captured, processed, dropped) = (numbers[0], numbers[1], numbers[3]);
    assert_eq!(captured, images, "{summary}");
    assert_eq!(processed + dropped, captured, "{summary}");
    assert!(processed > 0, "{summary}");
    let playback_s = (images - 1) as f64 / fps;
    assert!(
        elapsed.as_secs_f64() >= playback_s,
        "{images} images at {fps} fps took only {elapsed:?}"
    );

    // Tracks, with boxes normalised by the decoded image size.
    let tracks: Vec<_> = messages
        .iter()
        .filter_map(|m| match m {
            MavMessage::MGMOT_TRACK(t) => Some(t),
            _ => None,
        })
        .collect();
    assert!(!tracks.is_empty(), "no MGMOT_TRACK; mgmot said: {stderr}");
    for t in &tracks {
        let inside = |v: f32| (-0.05..=1.05).contains(&v);
        assert!(
            inside(t.bbox_x)
                && inside(t.bbox_y)
                && inside(t.bbox_x + t.bbox_w)
                && inside(t.bbox_y + t.bbox_h)
                && t.bbox_w > 0.0,
            "box outside the image: {t:?}"
        );
    }
    // A directory never loses its camera.
    let lost = messages.iter().any(|m| {
        matches!(m, MavMessage::STATUSTEXT(s) if s.text.to_str().is_ok_and(|t| t.contains("camera lost")))
    });
    assert!(!lost, "an image directory reported \"camera lost\"");
}

#[test]
fn a_missing_directory_fails_at_start_naming_it() {
    let dir = TestDir::new();
    let mut c = run_config(
        "udpout:127.0.0.1:9",
        &dir.join("unused.sock"),
        &dir.empty_detections(),
    );
    c.frames = FramesConfig::Images {
        directory: "/nonexistent/mgmot-frames".into(),
        fps: 30.0,
        looping: false,
    };
    let config = dir.write_config("run.toml", &c);
    let o = mgmot_run(&config, None).output();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(
        stderr.contains("/nonexistent/mgmot-frames"),
        "error does not name the path: {stderr}"
    );
}
