//! Issue "Hardening", item 10: the heartbeat runs at the configured rate (it ran at 0.75 Hz
//! when 1 Hz was configured, and 2e9 Hz sent heartbeats as fast as it could), and rates that
//! `mgmot run` cannot keep are refused by `check-config`, naming the key. Real process, real
//! UDP socket: the test is the autopilot's end of a `udpout` link.

use crate::common;

use common::{mgmot, mgmot_run, run_config, TestDir};
use mavlink_core::{MavlinkReader, MavlinkVersion};
use mgmot::mavlink::dialect::{MavMessage, MavType};
use std::net::UdpSocket;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// A config sending to `port` with `heartbeat_hz`; frames from a socket nobody serves (the
/// camera stays lost, which must not hold up the heartbeat).
fn config(dir: &TestDir, port: u16, heartbeat_hz: f64) -> PathBuf {
    let mut c = run_config(
        &format!("udpout:127.0.0.1:{port}"),
        &dir.join("nobody.sock"),
        &dir.empty_detections(),
    );
    c.outputs.heartbeat_hz = heartbeat_hz;
    dir.write_config("mgmot.toml", &c)
}

/// How long mgmot run may take to send its first heartbeat (process start on a loaded
/// 2-core machine: the listening window below starts only then, so start-up never counts).
const START_UP: Duration = Duration::from_secs(20);

/// Arrival times on `socket` of the heartbeats of mgmot run with `config`, over `listen`
/// from the first one.
fn heartbeats(socket: &UdpSocket, config: &Path, listen: Duration) -> Vec<Instant> {
    socket
        .set_read_timeout(Some(Duration::from_millis(50)))
        .unwrap();
    let _mgmot = mgmot_run(config, None).spawn();
    let mut at: Vec<Instant> = Vec::new();
    let mut buf = [0u8; 2048];
    let start = Instant::now();
    loop {
        match at.first() {
            Some(first) if first.elapsed() >= listen => break,
            None if start.elapsed() >= START_UP => break,
            _ => {}
        }
        let Ok(n) = socket.recv(&mut buf) else {
            continue;
        };
        let now = Instant::now();
        let mut reader = MavlinkReader::new(&buf[..n]);
        while let Ok((h, m)) = reader.read_message::<MavMessage>(MavlinkVersion::V2) {
            if h.component_id == 191
                && matches!(m, MavMessage::HEARTBEAT(hb) if hb.mavtype == MavType::MAV_TYPE_ONBOARD_CONTROLLER)
            {
                at.push(now);
            }
        }
    }
    at
}

fn check_rate(hz: f64) {
    let dir = TestDir::new();
    let socket = UdpSocket::bind("127.0.0.1:0").unwrap();
    let port = socket.local_addr().unwrap().port();
    let cfg = config(&dir, port, hz);
    let at = heartbeats(&socket, &cfg, Duration::from_secs_f64(6.5 / hz));
    assert!(at.len() >= 5, "{} heartbeats at {hz} Hz", at.len());
    // From the first to the last: the mean interval, free of start-up time.
    let span = at[at.len() - 1].duration_since(at[0]).as_secs_f64();
    let mean = span / (at.len() - 1) as f64;
    let want = 1.0 / hz;
    assert!(
        (mean - want).abs() <= 0.05 * want,
        "{hz} Hz configured: mean interval {mean:.3} s over {} heartbeats",
        at.len()
    );
}

#[test]
fn heartbeat_runs_at_the_configured_rate() {
    check_rate(1.0);
    check_rate(4.0);
}

#[test]
fn check_config_refuses_heartbeat_rates_run_cannot_keep() {
    let dir = TestDir::new();
    for bad in [1e-300, 1e300, 2e9, f64::NAN, 0.0, -1.0] {
        let cfg = config(&dir, 14550, bad);
        let out = mgmot().arg("check-config").arg(&cfg).output();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "heartbeat_hz = {bad:?} accepted");
        assert!(
            stderr.contains("outputs.heartbeat_hz"),
            "heartbeat_hz = {bad:?}: the error does not name the key: {stderr}"
        );
    }
}
