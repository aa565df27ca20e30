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

mod common;

use common::{sim_bin, sim_to};
use mavlink_core::{MavlinkReader, MavlinkVersion};
use mgmot::mavlink::dialect::MavMessage;
use std::net::UdpSocket;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

fn sim(args: &[&str], out: &Path) {
    sim_to(&sim_bin(), args, out);
}

#[test]
fn plays_a_directory_tracks_and_stops_at_its_end() {
    // swimmer_group: its swimmers are in view from the first frame (calm_baseline's come later).
    let (scenario, duration_s, fps) = ("swimmer_group", "2", 30.0);
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    sim(
        &[
            "render",
            "--scenario",
            scenario,
            "--duration-s",
            duration_s,
            "--format",
            "jpg",
        ],
        &dir.join("seq"),
    );
    sim(
        &[
            "detections",
            "--scenario",
            scenario,
            "--duration-s",
            duration_s,
        ],
        &dir.join("dets.json"),
    );
    let images = std::fs::read_dir(dir.join("seq/img1")).unwrap().count() as u64;
    assert!(images >= 50, "{images} rendered images");

    let gcs = UdpSocket::bind("127.0.0.1:0").unwrap();
    gcs.set_read_timeout(Some(Duration::from_millis(50)))
        .unwrap();
    let config = dir.join("run.toml");
    std::fs::write(
        &config,
        format!(
            "[mavlink]\nconnection = \"udpout:127.0.0.1:{}\"\nstream_rate_hz = 0\n\
             [frames]\nsource = \"images\"\ndirectory = \"{}\"\nfps = {fps}\n\
             [detector]\nkind = \"replay\"\ndetections = \"{}\"\n",
            gcs.local_addr().unwrap().port(),
            dir.join("seq/img1").display(),
            dir.join("dets.json").display()
        ),
    )
    .unwrap();
    let started = Instant::now();
    let mut mgmot = Command::new(env!("CARGO_BIN_EXE_mgmot"))
        .args(["run", "--config"])
        .arg(&config)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut messages = Vec::new();
    let mut buf = [0u8; 65536];
    let status = loop {
        if let Ok(n) = gcs.recv(&mut buf) {
            let mut reader = MavlinkReader::new(&buf[..n]);
            while let Ok((_, m)) = reader.read_message::<MavMessage>(MavlinkVersion::V2) {
                messages.push(m);
            }
        }
        if let Some(status) = mgmot.try_wait().unwrap() {
            break status;
        }
        if started.elapsed() > Duration::from_secs(120) {
            let _ = mgmot.kill();
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
    let stderr = {
        use std::io::Read;
        let mut e = String::new();
        mgmot.stderr.take().unwrap().read_to_string(&mut e).unwrap();
        e
    };
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
    let tmp = tempfile::tempdir().unwrap();
    let config = tmp.path().join("run.toml");
    let dets = tmp.path().join("dets.json");
    std::fs::write(&dets, "[]").unwrap();
    std::fs::write(
        &config,
        format!(
            "[mavlink]\nconnection = \"udpout:127.0.0.1:9\"\n\
             [frames]\nsource = \"images\"\ndirectory = \"/nonexistent/mgmot-frames\"\n\
             fps = 30.0\n[detector]\nkind = \"replay\"\ndetections = \"{}\"\n",
            dets.display()
        ),
    )
    .unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_mgmot"))
        .args(["run", "--config"])
        .arg(&config)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(
        stderr.contains("/nonexistent/mgmot-frames"),
        "error does not name the path: {stderr}"
    );
}
