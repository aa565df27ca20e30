//! `mgmot run` when its frame source misbehaves (issue "Hardening", items 6-8), with the test
//! as the simulator's frame socket: real process, real Unix socket, real signals.
//!
//! - 6: the source restarts and numbers its frames from 0 again: frames keep being tracked.
//! - 7: the source closes the stream without the end-of-stream header: mgmot reconnects
//!   instead of exiting 0; the header itself ends the run with exit 0.
//! - 8: the source freezes (connected, silent): SIGTERM still ends mgmot promptly, exit 0.

use crate::common;

use common::{free_udp_port, mgmot, mgmot_run, run_config, Proc, TestCommand, TestDir};
use mgmot::camera::sim_framing::{end_of_stream, FrameHeader};
use mgmot::config::FramesConfig;
use std::io::Write;
use std::os::unix::net::{UnixListener, UnixStream};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// A config for `mgmot run` reading frames from `socket`, detections replayed from an empty
/// file (no detector needed: these tests are about the frame path).
fn config(dir: &TestDir, socket: &Path) -> PathBuf {
    config_with(dir, socket, &dir.empty_detections())
}

/// [`config`] with the detections replayed from `detections`.
fn config_with(dir: &TestDir, socket: &Path, detections: &Path) -> PathBuf {
    let mut c = run_config(
        &format!("udpin:127.0.0.1:{}", free_udp_port()),
        socket,
        detections,
    );
    let FramesConfig::Sim {
        frame_timeout_ms,
        reconnect_initial_ms,
        reconnect_max_ms,
        ..
    } = &mut c.frames
    else {
        unreachable!()
    };
    (*frame_timeout_ms, *reconnect_initial_ms, *reconnect_max_ms) = (5000, 100, 200);
    dir.write_config("mgmot.toml", &c)
}

/// `mgmot run` on a frame socket this test serves: the folder, the socket's listener, the
/// stats file and the process (declared in this order, so that the process goes first).
fn start() -> (TestDir, UnixListener, PathBuf, Proc) {
    let dir = TestDir::new();
    let socket = dir.join("frames.sock");
    let listener = UnixListener::bind(&socket).unwrap();
    let stats = dir.join("stats.json");
    let cfg = config(&dir, &socket);
    let mgmot = mgmot_run(&cfg, Some(&stats)).spawn_logged(dir.join("mgmot.log"));
    (dir, listener, stats, mgmot)
}

fn accept(listener: &UnixListener, within: Duration) -> UnixStream {
    listener.set_nonblocking(true).unwrap();
    let until = Instant::now() + within;
    loop {
        match listener.accept() {
            Ok((s, _)) => {
                s.set_nonblocking(false).unwrap();
                return s;
            }
            Err(_) if Instant::now() < until => std::thread::sleep(Duration::from_millis(20)),
            Err(e) => panic!("mgmot did not connect to the frame socket: {e}"),
        }
    }
}

/// Sends frames `0..n` (their own numbering), 64x36, 30 fps stamps; a failed write fails
/// the test with the log of mgmot.
fn send_frames(s: &mut UnixStream, n: u64, mgmot: &Proc) {
    send_frames_from(s, n, 1_000_000, mgmot);
}

/// [`send_frames`] with the first frame stamped `first_us` (the source's clock).
fn send_frames_from(s: &mut UnixStream, n: u64, first_us: u64, mgmot: &Proc) {
    let (w, h) = (64u32, 36u32);
    let px = vec![90u8; (w * h * 3) as usize];
    for k in 0..n {
        let hdr = FrameHeader::rgb24(k, first_us + k * 33_333, w, h);
        if let Err(e) = s.write_all(&hdr.encode()).and_then(|()| s.write_all(&px)) {
            panic!("frame {k}: {e}; mgmot: {}", mgmot.log());
        }
        std::thread::sleep(Duration::from_millis(10));
    }
}

fn stats(path: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap()
}

/// Items 6 and 7: a stream cut without the end-of-stream header is reconnected (mgmot keeps
/// running), the new session numbers its frames from 0 again and they are still tracked
/// (no tracker errors), and the end-of-stream header then ends the run with exit 0.
#[test]
fn a_cut_stream_is_reconnected_and_restarted_numbering_is_tracked() {
    let (_dir, listener, stats_path, mut mgmot) = start();

    let mut s = accept(&listener, Duration::from_secs(20));
    send_frames(&mut s, 20, &mgmot);
    drop(s); // cut: no end-of-stream header
    assert!(
        mgmot.wait_within(Duration::from_millis(1500)).is_none(),
        "mgmot exited when the frame stream was cut"
    );
    let mut s = accept(&listener, Duration::from_secs(10));
    send_frames(&mut s, 20, &mgmot); // numbered from 0 again
    s.write_all(&end_of_stream()).unwrap();
    let status = mgmot
        .wait_within(Duration::from_secs(20))
        .expect("mgmot did not end");
    assert!(status.success(), "{status:?}");
    let st = stats(&stats_path);
    assert_eq!(st["tracker_errors"], 0, "{st}");
    assert_eq!(st["frames_captured"], 40, "{st}");
    assert!(st["frames_processed"].as_u64().unwrap() >= 20, "{st}");
}

/// Two sessions of 90 frames from a source whose second session's clock starts at
/// `second_us` (the first's at 100 s), one swimmer in every frame; the run's stats.
fn two_sessions(second_us: u64) -> serde_json::Value {
    let dir = TestDir::new();
    let socket = dir.join("frames.sock");
    let listener = UnixListener::bind(&socket).unwrap();
    let stats_path = dir.join("stats.json");
    let boxes: Vec<String> = (0..=400)
        .map(|id| format!(r#"{{"image_id":{id},"category_id":1,"bbox":[20,10,6,6],"score":0.9}}"#))
        .collect();
    let dets = dir.write("dets.json", format!("[{}]", boxes.join(",")));
    let cfg = config_with(&dir, &socket, &dets);
    let mut mgmot = mgmot_run(&cfg, Some(&stats_path)).spawn_logged(dir.join("mgmot.log"));
    let mut s = accept(&listener, Duration::from_secs(20));
    send_frames_from(&mut s, 90, 100_000_000, &mgmot);
    drop(s);
    let mut s = accept(&listener, Duration::from_secs(10));
    send_frames_from(&mut s, 90, second_us, &mgmot);
    s.write_all(&end_of_stream()).unwrap();
    let status = mgmot
        .wait_within(Duration::from_secs(20))
        .expect("mgmot did not end");
    assert!(status.success(), "{status:?}: {}", mgmot.log());
    stats(&stats_path)
}

/// Issue 39, item 2: a frame source whose clock goes back (a restarted camera or simulator)
/// gave no MGMOT_TRACK for as long as its clock was behind, with nothing logged. The
/// tracker's clock bridges the jump: the second session reports as many tracks as when the
/// clock runs on, and the jump is counted.
#[test]
fn a_frame_source_whose_clock_goes_back_keeps_reporting_tracks() {
    let control = two_sessions(103_500_000);
    let back = two_sessions(1_000_000);
    for st in [&control, &back] {
        assert_eq!(st["tracker_errors"], 0, "{st}");
        assert_eq!(st["frames_captured"], 180, "{st}");
    }
    let messages = |st: &serde_json::Value| st["track_messages"].as_u64().unwrap_or(0);
    assert!(messages(&control) >= 8, "control: {control}");
    assert!(
        messages(&back) * 10 >= messages(&control) * 9,
        "{} track messages with the clock going back, {} with it running on",
        messages(&back),
        messages(&control)
    );
    assert!(back["clock_jumps"].as_u64() >= Some(1), "{back}");
}

/// Item 8: a frozen source (connected, sending nothing) does not keep SIGTERM from ending
/// mgmot promptly with exit 0 and its stats written.
#[test]
fn sigterm_ends_mgmot_while_the_source_is_frozen() {
    let (_dir, listener, stats_path, mut mgmot) = start();
    let mut s = accept(&listener, Duration::from_secs(20));
    send_frames(&mut s, 3, &mgmot);
    // Frozen from here: the connection stays open, nothing more is sent.
    std::thread::sleep(Duration::from_millis(300));
    let asked = Instant::now();
    mgmot.sigterm();
    let status = mgmot
        .wait_within(Duration::from_secs(5))
        .expect("SIGTERM did not end mgmot");
    assert!(status.success(), "{status:?}");
    assert!(
        asked.elapsed() < Duration::from_secs(3),
        "{:?}",
        asked.elapsed()
    );
    assert!(stats_path.exists(), "no stats written");
    drop(s);
}

/// Item 13: a frame socket the user running mgmot may not open is named at start-up, with
/// the reason, and mgmot exits with an error, instead of reporting "camera lost" for ever.
/// As root (which may open anything) the check runs mgmot as `nobody` with setpriv.
#[test]
fn an_unopenable_frame_socket_is_named_at_start_up() {
    use std::os::unix::fs::PermissionsExt;
    let dir = TestDir::new();
    std::fs::set_permissions(dir.path(), std::fs::Permissions::from_mode(0o755)).unwrap();
    let socket = dir.join("frames.sock");
    let _listener = UnixListener::bind(&socket).unwrap();
    std::fs::set_permissions(&socket, std::fs::Permissions::from_mode(0o600)).unwrap();
    let cfg = config(&dir, &socket);
    for f in [&cfg, &dir.join("dets.json")] {
        std::fs::set_permissions(f, std::fs::Permissions::from_mode(0o644)).unwrap();
    }
    let root = rustix::process::geteuid().is_root();
    let mut cmd = if root {
        let mut c = TestCommand::new("setpriv");
        c.args(["--reuid=65534", "--regid=65534", "--clear-groups"])
            .arg(env!("CARGO_BIN_EXE_mgmot"));
        c
    } else {
        std::fs::set_permissions(&socket, std::fs::Permissions::from_mode(0o000)).unwrap();
        mgmot()
    };
    let out = cmd
        .args(["run", "--config"])
        .arg(&cfg)
        .current_dir(dir.path())
        .output();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "mgmot ran: {err}");
    assert!(
        err.contains("frames.socket") && err.contains("frames.sock") && err.contains("ermission"),
        "{err}"
    );
}

/// Issue 39 item 10: a frame socket that appears after start-up with permissions that refuse
/// mgmot is reported, in the log and by STATUSTEXT, once for the episode, instead of being
/// retried in silence after the first "camera lost".
#[test]
fn a_frame_socket_that_appears_later_without_permission_is_reported_once() {
    use mavlink_core::{MAVLinkV2MessageRaw, MavHeader};
    use mgmot::mavlink::dialect::{MavMessage, HEARTBEAT_DATA};
    use std::os::unix::fs::PermissionsExt;
    let dir = TestDir::new();
    let socket = dir.join("frames.sock");
    let port = free_udp_port();
    let relay = common::Relay::start(port);
    let mut c = run_config(
        &format!("udpin:127.0.0.1:{port}"),
        &socket,
        &dir.empty_detections(),
    );
    let FramesConfig::Sim {
        reconnect_initial_ms,
        reconnect_max_ms,
        ..
    } = &mut c.frames
    else {
        unreachable!()
    };
    (*reconnect_initial_ms, *reconnect_max_ms) = (100, 200);
    let cfg = dir.write_config("mgmot.toml", &c);
    let mut cmd = common::mgmot_bound_by_permissions();
    cmd.args(["run", "--config"]).arg(&cfg);
    let mut mgmot = cmd.spawn_logged(dir.join("mgmot.log"));
    // The autopilot's heartbeat through the relay: mgmot's peer, so its STATUSTEXTs go out.
    let mut raw = MAVLinkV2MessageRaw::new();
    raw.serialize_message(
        MavHeader {
            system_id: 1,
            component_id: 1,
            sequence: 0,
        },
        &MavMessage::HEARTBEAT(HEARTBEAT_DATA::default()),
    );
    let autopilot = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    let started = Instant::now();
    let mut listener = None;
    while started.elapsed() < Duration::from_secs(6) {
        autopilot
            .send_to(raw.raw_bytes(), ("127.0.0.1", relay.listen_port))
            .unwrap();
        if listener.is_none() && started.elapsed() > Duration::from_secs(2) {
            // The socket appears, already without permissions (bound aside, renamed in).
            let aside = dir.join("frames.sock.new");
            let l = UnixListener::bind(&aside).unwrap();
            std::fs::set_permissions(&aside, std::fs::Permissions::from_mode(0o000)).unwrap();
            std::fs::rename(&aside, &socket).unwrap();
            listener = Some(l);
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    mgmot.stop(Duration::from_secs(10));
    let log = mgmot.log();
    let texts = relay.statustexts();
    let denied: Vec<_> = texts
        .iter()
        .filter(|t| t.to_lowercase().contains("permission denied"))
        .collect();
    assert_eq!(denied.len(), 1, "{texts:?}\n{log}");
    assert_eq!(
        log.matches("frame source refuses mgmot").count(),
        1,
        "said once in the log:\n{log}"
    );
    drop(listener);
}
