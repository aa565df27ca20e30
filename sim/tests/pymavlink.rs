//! The telemetry decoded by a second, independent MAVLink implementation: pymavlink.
//!
//! Starts the real `mgmot-sim` sending `udpout` to a port where
//! `scripts/sim_pymavlink_decode.py` listens with pymavlink, and checks the decoded message
//! set, the rates and the answers to TIMESYNC and REQUEST_MESSAGE. When python3 or pymavlink is
//! missing the test fails and says so (scripts/test.sh installs pymavlink into `.venv`): a
//! missing tool never passes as a skip.

use crate::common::{free_udp_port, sim, Proc};
use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};

fn pymavlink_available() -> Result<(), String> {
    match Command::new("python3")
        .args(["-c", "import pymavlink"])
        .output()
    {
        Err(e) => Err(format!("python3 not runnable: {e}")),
        Ok(o) if !o.status.success() => Err(format!(
            "pymavlink not importable ({}); install it with `pip install -r scripts/requirements-test.txt`",
            String::from_utf8_lossy(&o.stderr).trim()
        )),
        Ok(_) => Ok(()),
    }
}

#[test]
fn pymavlink_decodes_the_telemetry() {
    if let Err(why) = pymavlink_available() {
        panic!(
            "pymavlink_decodes_the_telemetry needs a tool that is missing: {why}. \
             scripts/test.sh provides it (scripts/requirements-test.txt in .venv, on PATH)"
        );
    }
    let script = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../scripts/sim_pymavlink_decode.py"
    );
    let port = free_udp_port();
    let mut py = Proc::start(
        Command::new("python3")
            .args([script, "--port", &port.to_string(), "--seconds", "4"])
            .stdout(Stdio::piped())
            .stderr(Stdio::piped()),
    );
    // Wait until the decoder listens.
    let mut err = BufReader::new(py.take_stderr());
    let mut line = String::new();
    err.read_line(&mut line).unwrap();
    assert_eq!(line.trim(), "ready", "decoder did not start: {line}");

    let simulator = Proc::start(
        sim(&[
            "run",
            "-s",
            "gimbal_swings",
            "--realtime",
            "--duration-s",
            "7",
            "--mavlink",
            &format!("udpout:127.0.0.1:{port}"),
        ])
        .stdout(Stdio::null()),
    );
    let out = py.wait_with_output();
    drop(simulator); // killed
    assert!(out.status.success(), "decoder failed");
    let j: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    println!("{j:#}");
    let count = |n: &str| j["counts"][n].as_u64().unwrap_or(0);
    let rate = |n: &str| j["rates_hz"][n].as_f64().unwrap_or(0.0);
    assert_eq!(count("BAD_DATA"), 0, "pymavlink rejected frames");
    assert_eq!(j["mavlink2"], true);
    for n in [
        "HEARTBEAT",
        "GLOBAL_POSITION_INT",
        "ATTITUDE",
        "GIMBAL_DEVICE_ATTITUDE_STATUS",
        "MOUNT_ORIENTATION",
        "SYSTEM_TIME",
        "HOME_POSITION",
    ] {
        assert!(count(n) > 0, "{n} not decoded");
    }
    // Rates from the autopilot's own timestamps (+-15 %: jitter is 5 %).
    for (n, hz) in [
        ("ATTITUDE", 20.0),
        ("GLOBAL_POSITION_INT", 10.0),
        ("GIMBAL_DEVICE_ATTITUDE_STATUS", 10.0),
    ] {
        assert!((rate(n) - hz).abs() < 0.15 * hz, "{n}: {} Hz", rate(n));
    }
    assert!(count("HEARTBEAT") >= 3, "heartbeat 1 Hz over 4 s");
    // Answers.
    assert_eq!(j["timesync_reply"]["ts1"], 123456789);
    assert!(j["timesync_reply"]["tc1"].as_i64().unwrap() > 0);
    let acks = j["acks"].as_array().unwrap();
    assert!(
        acks.iter().any(|a| a["command"] == 512 && a["result"] == 0),
        "{acks:?}"
    );
    // Position near the scenario origin, scaled as MAVLink says (degE7).
    let lat = j["samples"]["GLOBAL_POSITION_INT"]["lat"].as_f64().unwrap() / 1e7;
    assert!((lat - 47.6721).abs() < 0.01, "{lat}");
    let q = j["samples"]["GIMBAL_DEVICE_ATTITUDE_STATUS"]["q"]
        .as_array()
        .unwrap();
    let norm: f64 = q.iter().map(|v| v.as_f64().unwrap().powi(2)).sum();
    assert!((norm - 1.0).abs() < 1e-4);
}
