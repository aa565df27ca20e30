//! Telemetry over a serial link: a pseudo-terminal stands in for the UART. The simulator
//! opens the slave side as `serial:/dev/pts/N:57600`; the test reads the master side and
//! decodes MAVLink 2 with the mavlink crate.

use crate::common::{sim, Proc};
use mavlink::dialects::common::MavMessage;
use std::collections::HashMap;
use std::fs::File;
use std::process::Stdio;
use std::time::{Duration, Instant};

#[test]
fn telemetry_over_a_pseudo_terminal() {
    let pty = nix::pty::openpty(None, None).expect("openpty");
    // The slave's path, as ttyname(3) finds it: the link /proc keeps for the descriptor.
    let slave_path = std::fs::read_link(format!(
        "/proc/self/fd/{}",
        std::os::fd::AsRawFd::as_raw_fd(&pty.slave)
    ))
    .expect("the pty slave's path");
    // Raw mode on the slave so the line discipline does not rewrite bytes before the
    // simulator configures the port.
    let mut tio = nix::sys::termios::tcgetattr(&pty.slave).unwrap();
    nix::sys::termios::cfmakeraw(&mut tio);
    nix::sys::termios::tcsetattr(&pty.slave, nix::sys::termios::SetArg::TCSANOW, &tio).unwrap();
    let addr = format!("serial:{}:57600", slave_path.display());
    let mut child = Proc::start(
        sim(&[
            "run",
            "-s",
            "calm_baseline",
            "--realtime",
            "--duration-s",
            "3",
            "--mavlink",
            &addr,
        ])
        .stdout(Stdio::null())
        .stderr(Stdio::piped()),
    );
    let master = File::from(pty.master);
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let mut reader = mavlink::MavlinkReader::new(master);
        while let Ok((_, m)) = reader.read_message::<MavMessage>(mavlink::MavlinkVersion::V2) {
            if tx.send(m).is_err() {
                break;
            }
        }
    });
    let mut counts: HashMap<&'static str, usize> = HashMap::new();
    let deadline = Instant::now() + Duration::from_secs(8);
    while Instant::now() < deadline {
        match rx.recv_timeout(Duration::from_millis(200)) {
            Ok(m) => {
                *counts
                    .entry(mavlink::Message::message_name(&m))
                    .or_default() += 1
            }
            Err(_) if child.exited().is_some() => break,
            Err(_) => {}
        }
    }
    let out = child.wait_with_output();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for name in [
        "HEARTBEAT",
        "ATTITUDE",
        "GLOBAL_POSITION_INT",
        "GIMBAL_DEVICE_ATTITUDE_STATUS",
    ] {
        assert!(
            counts.get(name).copied().unwrap_or(0) > 0,
            "{name} missing: {counts:?}"
        );
    }
    // 3 s at 20 Hz, minus start-up: most of the ATTITUDE stream arrives intact.
    assert!(counts["ATTITUDE"] >= 40, "{counts:?}");
}
