//! The harness the runtime tests share: the simulator binary, free ports, child processes that
//! die with the test, and the UDP relay that sits between the simulator (autopilot) and
//! `mgmot run`, recording everything mgmot sends.
//!
//! Each test file is its own crate and uses a part of this, hence the `dead_code` allowance.
#![allow(dead_code)]

use mavlink_core::{MavHeader, MavlinkReader, MavlinkVersion};
use mgmot::mavlink::dialect::MavMessage;
use std::net::UdpSocket;
use std::path::{Path, PathBuf};
use std::process::{Child, Command};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

/// Autopilot clock at sim time 0 (the scenarios' default `telemetry.boot_time_s`).
pub const BOOT_TIME_S: f64 = 120.0;

/// The simulator binary: `$MGMOT_SIM_BIN`, or the one `cargo build -p mgmot-sim` builds here
/// in this test build's profile (a workspace member): `target/debug/mgmot-sim`, or
/// `target/release/mgmot-sim` under `cargo test --release`.
pub fn sim_bin() -> PathBuf {
    if let Some(p) = std::env::var_os("MGMOT_SIM_BIN") {
        return PathBuf::from(p);
    }
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let release = !cfg!(debug_assertions);
    let mut build = Command::new(env!("CARGO"));
    build.args(["build", "-p", "mgmot-sim"]).current_dir(root);
    if release {
        build.arg("--release");
    }
    let status = build.status().expect("running cargo build -p mgmot-sim");
    assert!(status.success(), "cargo build -p mgmot-sim failed");
    root.join(if release {
        "target/release/mgmot-sim"
    } else {
        "target/debug/mgmot-sim"
    })
}

/// Runs `sim ARGS -o OUT` (a batch mode: `render`, `detections`) to the end; a failure fails
/// the test with the simulator's stderr.
pub fn sim_to<S: AsRef<std::ffi::OsStr> + std::fmt::Debug>(sim: &Path, args: &[S], out: &Path) {
    let o = Command::new(sim)
        .args(args)
        .arg("-o")
        .arg(out)
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "mgmot-sim {args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
}

/// A UDP port free right now on loopback.
pub fn free_udp_port() -> u16 {
    UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// A child process killed when the test ends, passed or not.
pub struct Proc(pub Child);

impl Drop for Proc {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// One message mgmot sent, with the datagram it came in.
#[derive(Clone)]
pub struct Sent {
    /// The whole datagram (for signature checks).
    pub bytes: Vec<u8>,
    /// Its MAVLink header.
    pub header: MavHeader,
    /// The decoded message (the project's dialect).
    pub msg: MavMessage,
}

/// The UDP link between the simulator and mgmot: the simulator sends to `listen_port`, the
/// relay forwards to mgmot's `udpin` port and mgmot's answers back to the simulator, and
/// records every message mgmot sends. `to_mgmot` is the relay's mgmot-side socket: what a
/// test sends from it reaches mgmot from the peer it answers (a `udpin` link answers its
/// latest peer).
pub struct Relay {
    /// Everything mgmot sent so far.
    pub sent: Arc<Mutex<Vec<Sent>>>,
    /// The port the simulator sends to.
    pub listen_port: u16,
    /// mgmot's `udpin` port.
    pub mgmot_port: u16,
    /// A clone of the socket that talks to mgmot.
    pub to_mgmot: UdpSocket,
    stop: Arc<AtomicBool>,
    threads: Vec<JoinHandle<()>>,
}

impl Relay {
    /// Starts relaying to mgmot at `127.0.0.1:mgmot_port`.
    pub fn start(mgmot_port: u16) -> Relay {
        // One thread per direction, each blocking on its socket (the timeout only lets it see
        // `stop`): at 50 Hz per stream the simulator sends a few hundred datagrams a second,
        // and one thread polling both sockets in turn fell behind on a loaded machine.
        let up = UdpSocket::bind("127.0.0.1:0").unwrap();
        let down = UdpSocket::bind("127.0.0.1:0").unwrap();
        up.set_read_timeout(Some(Duration::from_millis(50)))
            .unwrap();
        down.set_read_timeout(Some(Duration::from_millis(50)))
            .unwrap();
        let listen_port = up.local_addr().unwrap().port();
        let to_mgmot = down.try_clone().unwrap();
        let sent = Arc::new(Mutex::new(Vec::new()));
        let stop = Arc::new(AtomicBool::new(false));
        let sim: Arc<Mutex<Option<std::net::SocketAddr>>> = Arc::new(Mutex::new(None));
        let upstream = {
            let (up, down, s, sim) = (
                up.try_clone().unwrap(),
                down.try_clone().unwrap(),
                stop.clone(),
                sim.clone(),
            );
            std::thread::spawn(move || {
                let mut buf = [0u8; 65536];
                while !s.load(Ordering::Relaxed) {
                    if let Ok((n, from)) = up.recv_from(&mut buf) {
                        *sim.lock().unwrap() = Some(from);
                        let _ = down.send_to(&buf[..n], ("127.0.0.1", mgmot_port));
                    }
                }
            })
        };
        let downstream = {
            let (log, s) = (sent.clone(), stop.clone());
            std::thread::spawn(move || {
                let mut buf = [0u8; 65536];
                while !s.load(Ordering::Relaxed) {
                    if let Ok(n) = down.recv(&mut buf) {
                        let to_sim = *sim.lock().unwrap();
                        if let Some(to_sim) = to_sim {
                            let _ = up.send_to(&buf[..n], to_sim);
                        }
                        let mut reader = MavlinkReader::new(&buf[..n]);
                        while let Ok((header, msg)) =
                            reader.read_message::<MavMessage>(MavlinkVersion::V2)
                        {
                            log.lock().unwrap().push(Sent {
                                bytes: buf[..n].to_vec(),
                                header,
                                msg,
                            });
                        }
                    }
                }
            })
        };
        Relay {
            sent,
            listen_port,
            mgmot_port,
            to_mgmot,
            stop,
            threads: vec![upstream, downstream],
        }
    }

    /// Stops relaying; everything mgmot sent.
    pub fn finish(mut self) -> Vec<Sent> {
        self.stop.store(true, Ordering::Relaxed);
        for t in self.threads.drain(..) {
            t.join().unwrap();
        }
        std::mem::take(&mut *self.sent.lock().unwrap())
    }
}

impl Drop for Relay {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
    }
}
