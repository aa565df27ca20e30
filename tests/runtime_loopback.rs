//! `mgmot run` against the real `mgmot-sim` on loopback: MAVLink over UDP through a tap that
//! decodes what mgmot sends (with the generated dialect), frames over the sim's Unix socket,
//! detections from the sim's detection mode (the stand-in until the ONNX detector lands).
//!
//! The simulator binary is `$MGMOT_SIM_BIN`, or `target/debug/mgmot-sim` built here with
//! `cargo build -p mgmot-sim` (a workspace member). Short scenarios in lockstep keep it fast.

use mavlink_core::{MavHeader, MavlinkReader, MavlinkVersion};
use mgmot::mavlink::dialect::{MavMessage, MavType, MgmotTrackFlags};
use std::net::UdpSocket;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// Autopilot clock at sim time 0 (the scenarios' default `telemetry.boot_time_s`).
const BOOT_TIME_S: f64 = 120.0;

fn sim_bin() -> PathBuf {
    if let Some(p) = std::env::var_os("MGMOT_SIM_BIN") {
        return PathBuf::from(p);
    }
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let status = Command::new(env!("CARGO"))
        .args(["build", "-p", "mgmot-sim"])
        .current_dir(root)
        .status()
        .expect("running cargo build -p mgmot-sim");
    assert!(status.success(), "cargo build -p mgmot-sim failed");
    root.join("target/debug/mgmot-sim")
}

/// Forwards datagrams between the sim and mgmot and decodes everything mgmot sends.
struct Tap {
    messages: Arc<Mutex<Vec<(MavHeader, MavMessage)>>>,
    stop: Arc<AtomicBool>,
    thread: Option<std::thread::JoinHandle<()>>,
    listen_port: u16,
}

impl Tap {
    fn start(mgmot_port: u16) -> Tap {
        let up = UdpSocket::bind("127.0.0.1:0").unwrap();
        let down = UdpSocket::bind("127.0.0.1:0").unwrap();
        up.set_read_timeout(Some(Duration::from_millis(1))).unwrap();
        down.set_read_timeout(Some(Duration::from_millis(1)))
            .unwrap();
        let listen_port = up.local_addr().unwrap().port();
        let messages = Arc::new(Mutex::new(Vec::new()));
        let stop = Arc::new(AtomicBool::new(false));
        let (m, s) = (messages.clone(), stop.clone());
        let thread = std::thread::spawn(move || {
            let mut sim = None;
            let mut buf = [0u8; 65536];
            while !s.load(Ordering::Relaxed) {
                if let Ok((n, from)) = up.recv_from(&mut buf) {
                    sim = Some(from);
                    let _ = down.send_to(&buf[..n], ("127.0.0.1", mgmot_port));
                }
                if let Ok(n) = down.recv(&mut buf) {
                    if let Some(sim) = sim {
                        let _ = up.send_to(&buf[..n], sim);
                    }
                    let mut reader = MavlinkReader::new(&buf[..n]);
                    while let Ok(msg) = reader.read_message::<MavMessage>(MavlinkVersion::V2) {
                        m.lock().unwrap().push(msg);
                    }
                }
            }
        });
        Tap {
            messages,
            stop,
            thread: Some(thread),
            listen_port,
        }
    }

    fn finish(mut self) -> Vec<(MavHeader, MavMessage)> {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            t.join().unwrap();
        }
        std::mem::take(&mut *self.messages.lock().unwrap())
    }
}

fn free_udp_port() -> u16 {
    UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

struct Setup {
    _dir: tempfile::TempDir,
    dir: PathBuf,
    sim: PathBuf,
    config: PathBuf,
    mgmot_port: u16,
}

fn setup(scenario: &str, duration_s: f64) -> Setup {
    let sim = sim_bin();
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().to_owned();
    let out = Command::new(&sim)
        .args(["detections", "--scenario", scenario, "--duration-s"])
        .arg(duration_s.to_string())
        .arg("-o")
        .arg(dir.join("dets.json"))
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let mgmot_port = free_udp_port();
    let config = dir.join("run.toml");
    std::fs::write(
        &config,
        format!(
            "[mavlink]\nconnection = \"udpin:127.0.0.1:{mgmot_port}\"\n\
             [frames]\nsource = \"sim\"\nsocket = \"{}\"\n\
             [detector]\nkind = \"replay\"\ndetections = \"{}\"\n",
            dir.join("frames.sock").display(),
            dir.join("dets.json").display()
        ),
    )
    .unwrap();
    Setup {
        _dir: tmp,
        dir,
        sim,
        config,
        mgmot_port,
    }
}

fn start_sim(s: &Setup, scenario: &str, duration_s: f64, tap_port: u16) -> Child {
    Command::new(&s.sim)
        .args(["run", "--scenario", scenario, "--lockstep", "--duration-s"])
        .arg(duration_s.to_string())
        .arg("--mavlink")
        .arg(format!("udpout:127.0.0.1:{tap_port}"))
        .arg("--frames")
        .arg(format!("unix:{}", s.dir.join("frames.sock").display()))
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap()
}

fn start_mgmot(s: &Setup) -> Child {
    Command::new(env!("CARGO_BIN_EXE_mgmot"))
        .args(["run", "--config"])
        .arg(&s.config)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap()
}

fn wait_with_timeout(child: &mut Child, limit: Duration) -> std::process::ExitStatus {
    let start = Instant::now();
    loop {
        if let Some(status) = child.try_wait().unwrap() {
            return status;
        }
        if start.elapsed() > limit {
            let _ = child.kill();
            panic!("process did not finish within {limit:?}");
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// Ground-truth world positions by (time in ms, class name).
fn truth(dir: &Path) -> Vec<(i64, String, f64, f64)> {
    let mut r = csv::Reader::from_path(dir.join("dets_gt/world.csv")).unwrap();
    r.deserialize::<std::collections::HashMap<String, String>>()
        .map(|row| {
            let row = row.unwrap();
            let t_ms = (row["time_s"].parse::<f64>().unwrap() * 1000.0).round() as i64;
            (
                t_ms,
                row["class"].clone(),
                row["lat_deg"].parse().unwrap(),
                row["lon_deg"].parse().unwrap(),
            )
        })
        .collect()
}

#[test]
fn calm_baseline_heartbeat_tracks_and_geolocation_error() {
    let (scenario, duration_s) = ("calm_baseline", 12.0);
    let s = setup(scenario, duration_s);
    let tap = Tap::start(s.mgmot_port);
    let mut sim = start_sim(&s, scenario, duration_s, tap.listen_port);
    let mut mgmot = start_mgmot(&s);
    let status = wait_with_timeout(&mut mgmot, Duration::from_secs(600));
    let _ = wait_with_timeout(&mut sim, Duration::from_secs(30));
    std::thread::sleep(Duration::from_millis(300));
    let messages = tap.finish();
    let stderr = {
        let mut e = String::new();
        use std::io::Read;
        mgmot.stderr.take().unwrap().read_to_string(&mut e).unwrap();
        e
    };
    assert!(status.success(), "mgmot run failed: {stderr}");

    let heartbeat = messages.iter().any(|(h, m)| {
        h.component_id == 191
            && matches!(m, MavMessage::HEARTBEAT(hb) if hb.mavtype == MavType::MAV_TYPE_ONBOARD_CONTROLLER)
    });
    assert!(
        heartbeat,
        "no HEARTBEAT from mgmot among {} messages",
        messages.len()
    );

    let classes = [
        "",
        "swimmer",
        "boat",
        "jetski",
        "life_saving_appliance",
        "buoy",
    ];
    let gt = truth(&s.dir);
    let mut errors = Vec::new();
    for (_, m) in &messages {
        let MavMessage::MGMOT_TRACK(t) = m else {
            continue;
        };
        if !t
            .flags
            .contains(MgmotTrackFlags::MGMOT_TRACK_FLAGS_GEO_VALID)
        {
            continue;
        }
        let t_ms = ((t.time_usec as f64 / 1e6 - BOOT_TIME_S) * 1000.0).round() as i64;
        let class = classes.get(t.object_class as usize).copied().unwrap_or("");
        let (lat, lon) = (f64::from(t.lat) * 1e-7, f64::from(t.lon) * 1e-7);
        let nearest = gt
            .iter()
            .filter(|(gt_ms, c, _, _)| (gt_ms - t_ms).abs() <= 20 && c == class)
            .map(|(_, _, glat, glon)| {
                let dn = (glat - lat) * 111_320.0;
                let de = (glon - lon) * 111_320.0 * lat.to_radians().cos();
                dn.hypot(de)
            })
            .fold(f64::INFINITY, f64::min);
        errors.push(nearest);
    }
    assert!(
        !errors.is_empty(),
        "no geolocated MGMOT_TRACK; mgmot said: {stderr}"
    );
    let worst = errors.iter().copied().fold(0.0, f64::max);
    assert!(worst < 3.0, "geolocation errors {errors:?}");
}

#[test]
fn sigterm_stops_cleanly() {
    let (scenario, duration_s) = ("calm_baseline", 60.0);
    let s = setup(scenario, 2.0);
    let tap = Tap::start(s.mgmot_port);
    let mut sim = start_sim(&s, scenario, duration_s, tap.listen_port);
    let mut mgmot = start_mgmot(&s);
    std::thread::sleep(Duration::from_secs(3));
    let kill = Command::new("kill")
        .args(["-TERM", &mgmot.id().to_string()])
        .status()
        .unwrap();
    assert!(kill.success());
    let status = wait_with_timeout(&mut mgmot, Duration::from_secs(20));
    let _ = sim.kill();
    let _ = sim.wait();
    let messages = tap.finish();
    assert!(status.success(), "exit status after SIGTERM: {status:?}");
    assert!(messages
        .iter()
        .any(|(_, m)| matches!(m, MavMessage::HEARTBEAT(_))));
}
