//! Issue 11, part 3: `mgmot run` as the `Type=notify` service of `systemd/mgmot.service`. The
//! test is systemd's end: it binds the `NOTIFY_SOCKET` datagram socket, sets `WATCHDOG_USEC`
//! and starts the unit's own `ExecStart=` command line (and `Environment=`), with the simulator
//! as the autopilot and the camera. Real processes, real sockets, real signals:
//!
//! - `READY=1` only once telemetry and frames flow: not at start-up, not with only one of them;
//! - `WATCHDOG=1` every half `WATCHDOG_USEC` while frames are processed, none while the
//!   simulator is stopped (SIGSTOP: no frames), again after SIGCONT;
//! - `STOPPING=1` on SIGTERM, exit 0.

use crate::common;

use common::{free_udp_port, repo_file, run_config, Proc, Scenario, TestCommand, TestDir};
use mgmot::config::{Config, FramesConfig};
use std::os::unix::net::UnixDatagram;
use std::path::Path;
use std::time::{Duration, Instant};

/// `WATCHDOG_USEC` given to mgmot: pings due every second.
const WATCHDOG: Duration = Duration::from_secs(2);

/// One notification datagram, with its arrival time.
#[derive(Debug, Clone)]
struct Note {
    at: Instant,
    text: String,
}

impl Note {
    /// Whether one of its lines is exactly `line`.
    fn has(&self, line: &str) -> bool {
        self.text.lines().any(|l| l == line)
    }

    /// Its `STATUS=` text, if any.
    fn status(&self) -> Option<&str> {
        self.text.lines().find_map(|l| l.strip_prefix("STATUS="))
    }
}

/// systemd's end of `NOTIFY_SOCKET`.
struct NotifySocket {
    socket: UnixDatagram,
    path: std::path::PathBuf,
}

impl NotifySocket {
    fn bind(dir: &TestDir) -> NotifySocket {
        let path = dir.join("notify.sock");
        let socket = UnixDatagram::bind(&path).unwrap();
        socket
            .set_read_timeout(Some(Duration::from_millis(50)))
            .unwrap();
        NotifySocket { socket, path }
    }

    /// The datagrams arriving within `within`, or up to the first one `stop` accepts.
    fn collect(&self, within: Duration, stop: impl Fn(&Note) -> bool) -> Vec<Note> {
        let until = Instant::now() + within;
        let mut notes = Vec::new();
        let mut buf = [0u8; 4096];
        while Instant::now() < until {
            let Ok(n) = self.socket.recv(&mut buf) else {
                continue;
            };
            let note = Note {
                at: Instant::now(),
                text: String::from_utf8_lossy(&buf[..n]).into_owned(),
            };
            let done = stop(&note);
            notes.push(note);
            if done {
                break;
            }
        }
        notes
    }
}

fn count(notes: &[Note], line: &str) -> usize {
    notes.iter().filter(|n| n.has(line)).count()
}

fn statuses(notes: &[Note]) -> Vec<&str> {
    notes.iter().filter_map(Note::status).collect()
}

/// The unit's `ExecStart=` command line with the built binary and `config` in place of
/// `/usr/local/bin/mgmot` and `/etc/mgmot/mgmot.toml`, its `Environment=` set, and systemd's
/// notification variables.
fn exec_start(config: &Path, notify: &NotifySocket) -> TestCommand {
    let unit = std::fs::read_to_string(repo_file("systemd/mgmot.service")).unwrap();
    let value = |key: &str| -> Vec<String> {
        unit.lines()
            .filter_map(|l| l.strip_prefix(key))
            .map(str::to_owned)
            .collect()
    };
    let exec = value("ExecStart=");
    assert_eq!(exec.len(), 1, "one ExecStart= in the unit: {exec:?}");
    let argv: Vec<&str> = exec[0].split_whitespace().collect();
    assert_eq!(argv[0], "/usr/local/bin/mgmot", "{argv:?}");
    assert!(argv.contains(&"/etc/mgmot/mgmot.toml"), "{argv:?}");
    let mut cmd = TestCommand::new(env!("CARGO_BIN_EXE_mgmot"));
    for arg in &argv[1..] {
        if *arg == "/etc/mgmot/mgmot.toml" {
            cmd.arg(config);
        } else {
            cmd.arg(arg);
        }
    }
    for env in value("Environment=") {
        let (k, v) = env.split_once('=').expect("Environment=KEY=VALUE");
        cmd.env(k, v);
    }
    cmd.env("NOTIFY_SOCKET", &notify.path)
        .env("WATCHDOG_USEC", WATCHDOG.as_micros().to_string())
        .env_remove("WATCHDOG_PID");
    cmd
}

/// A config for mgmot on UDP `port`, frames from `socket`; a frozen source is waited for
/// 30 s before reconnecting (the SIGSTOP below lasts less).
fn config(dir: &TestDir, port: u16, socket: &Path, edit: impl FnOnce(&mut Config)) -> Config {
    let mut c = run_config(
        &format!("udpin:127.0.0.1:{port}"),
        socket,
        &dir.empty_detections(),
    );
    let FramesConfig::Sim {
        frame_timeout_ms, ..
    } = &mut c.frames
    else {
        unreachable!("the harness reads frames from the simulator")
    };
    *frame_timeout_ms = 30_000;
    edit(&mut c);
    c
}

/// The simulator in real time: autopilot to `port`, camera on `frames`, small frames.
fn simulator(dir: &TestDir, port: u16, frames: &Path) -> Proc {
    Scenario::new("calm_baseline", 120.0)
        .size(320, 180)
        .run(true, port, frames)
        .spawn_logged(dir.join("sim.log"))
}

fn signal(p: &Proc, sig: rustix::process::Signal) {
    let pid = rustix::process::Pid::from_raw(p.id() as i32).expect("a child's pid");
    rustix::process::kill_process(pid, sig).expect("kill");
}

#[test]
fn ready_after_telemetry_and_frames_and_watchdog_pings_follow_frames() {
    let dir = TestDir::new();
    let port = free_udp_port();
    let frames = dir.join("frames.sock");
    let cfg = dir.write_config("mgmot.toml", &config(&dir, port, &frames, |_| {}));
    let notify = NotifySocket::bind(&dir);
    let mut mgmot = exec_start(&cfg, &notify).spawn_logged(dir.join("mgmot.log"));

    // Start-up without autopilot and camera: waiting, extending the start timeout, not ready.
    let waiting = notify.collect(Duration::from_millis(2500), |_| false);
    assert_eq!(count(&waiting, "READY=1"), 0, "{waiting:?}");
    assert_eq!(count(&waiting, "WATCHDOG=1"), 0, "{waiting:?}");
    assert!(
        count(
            &waiting,
            &format!("EXTEND_TIMEOUT_USEC={}", WATCHDOG.as_micros())
        ) >= 1,
        "{waiting:?}"
    );
    assert!(
        statuses(&waiting).contains(&"waiting for telemetry and frames"),
        "{waiting:?}; mgmot: {}",
        mgmot.log()
    );

    // The simulator brings both: READY.
    let sim = simulator(&dir, port, &frames);
    let started = Instant::now();
    let before = notify.collect(Duration::from_secs(30), |n| n.has("READY=1"));
    assert!(
        before.last().is_some_and(|n| n.has("READY=1")),
        "no READY=1 within 30 s of the simulator's start: {before:?}; mgmot: {}\nsim: {}",
        mgmot.log(),
        sim.log()
    );
    eprintln!(
        "READY=1 {:?} after the simulator's start",
        started.elapsed()
    );
    assert_eq!(
        count(&before, "WATCHDOG=1"),
        0,
        "pinged before READY: {before:?}"
    );

    // Frames flow: a ping every half WATCHDOG_USEC.
    let flowing = notify.collect(Duration::from_secs(5), |_| false);
    let pings: Vec<Instant> = flowing
        .iter()
        .filter(|n| n.has("WATCHDOG=1"))
        .map(|n| n.at)
        .collect();
    assert!(
        pings.len() >= 4,
        "{} pings in 5 s: {flowing:?}",
        pings.len()
    );
    let gaps = pings.windows(2).map(|w| w[1] - w[0]);
    assert!(
        gaps.clone().all(|g| g < WATCHDOG),
        "a gap of WATCHDOG_USEC or more between pings: {:?}",
        gaps.collect::<Vec<_>>()
    );
    assert!(
        statuses(&flowing)
            .iter()
            .any(|s| s.starts_with("tracking: ")),
        "{flowing:?}"
    );
    assert_eq!(count(&flowing, "READY=1"), 0, "READY=1 twice: {flowing:?}");

    // The simulator stops (SIGSTOP): no frames, so no pings past the one that may be due.
    signal(&sim, rustix::process::Signal::STOP);
    let stopped = Instant::now();
    let stall = notify.collect(Duration::from_secs(5), |_| false);
    let late: Vec<Duration> = stall
        .iter()
        .filter(|n| n.has("WATCHDOG=1"))
        .map(|n| n.at - stopped)
        .collect();
    assert!(
        late.iter()
            .all(|&at| at <= WATCHDOG / 2 + Duration::from_millis(300)),
        "pings while no frames came (since SIGSTOP): {late:?}"
    );
    assert!(
        statuses(&stall)
            .iter()
            .any(|s| s.starts_with("no frames for")),
        "{stall:?}"
    );

    // The simulator goes on (SIGCONT): frames, and pings, again.
    signal(&sim, rustix::process::Signal::CONT);
    let resumed = notify.collect(Duration::from_secs(10), |n| n.has("WATCHDOG=1"));
    assert!(
        resumed.last().is_some_and(|n| n.has("WATCHDOG=1")),
        "no ping within 10 s of SIGCONT: {resumed:?}; mgmot: {}",
        mgmot.log()
    );

    // SIGTERM: STOPPING=1, exit 0.
    mgmot.sigterm();
    let stopping = notify.collect(Duration::from_secs(10), |n| n.has("STOPPING=1"));
    assert!(
        stopping.last().is_some_and(|n| n.has("STOPPING=1")),
        "{stopping:?}"
    );
    let status = mgmot.wait_or_fail(Duration::from_secs(10));
    assert!(status.success(), "{status:?}: {}", mgmot.log());
}

/// Telemetry without frames, and frames without telemetry: never READY, and STATUS= says what
/// is missing.
#[test]
fn not_ready_with_only_telemetry_or_only_frames() {
    for (case, want) in [
        ("telemetry only", "waiting for frames (telemetry flows)"),
        ("frames only", "waiting for telemetry (frames flow)"),
    ] {
        let dir = TestDir::new();
        let port = free_udp_port();
        let served = dir.join("frames.sock");
        let cfg = config(&dir, port, &served, |c| {
            if case == "telemetry only" {
                // mgmot reads a socket the simulator does not serve.
                let FramesConfig::Sim { socket, .. } = &mut c.frames else {
                    unreachable!()
                };
                *socket = dir.join("nobody.sock");
            } else {
                // mgmot answers one peer only, and not the simulator.
                c.mavlink.udp_peer = Some(([127, 0, 0, 1], 9).into());
            }
        });
        let cfg = dir.write_config("mgmot.toml", &cfg);
        let notify = NotifySocket::bind(&dir);
        let mgmot = exec_start(&cfg, &notify).spawn_logged(dir.join("mgmot.log"));
        let sim = simulator(&dir, port, &served);
        let notes = notify.collect(Duration::from_secs(15), |n| n.status() == Some(want));
        assert!(
            notes.last().and_then(Note::status) == Some(want),
            "{case}: no STATUS={want} within 15 s: {notes:?}; mgmot: {}\nsim: {}",
            mgmot.log(),
            sim.log()
        );
        // And it stays so a while longer.
        let more = notify.collect(Duration::from_secs(3), |_| false);
        assert_eq!(
            count(&notes, "READY=1") + count(&more, "READY=1"),
            0,
            "{case}"
        );
        assert!(statuses(&more).contains(&want), "{case}: {more:?}");
    }
}
