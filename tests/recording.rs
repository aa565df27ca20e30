//! The flight record (issue "Flights"): a real `mgmot run` against `mgmot-sim run` over real
//! sockets records its flight; the record replays exactly (`mgmot replay`), its tlog opens in
//! pymavlink, and a run killed with SIGKILL (a record cut short) still replays up to its last
//! whole frame.

use crate::common;

use common::{free_udp_port, mgmot, mgmot_run, require_python, run_config, Scenario, TestDir};
use mgmot::record::format::FrameRecord;
use mgmot::record::Flight;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

/// Records a simulated flight of `scenario` (replayed detections, real time); with
/// `kill_after`, mgmot is killed with SIGKILL that long after the start. Returns the test's
/// folder and the flight's folder.
fn record(scenario: &Scenario, kill_after: Option<Duration>) -> (TestDir, PathBuf) {
    let dir = TestDir::new();
    let dets = dir.join("dets.json");
    scenario.detections(&dets);
    let socket = dir.join("frames.sock");
    let port = free_udp_port();
    let mut c = run_config(&format!("udpin:127.0.0.1:{port}"), &socket, &dets);
    c.recording.dir = Some(dir.join("flights"));
    c.recording.keyframe_every_s = 2.0;
    let cfg = dir.write_config("mgmot.toml", &c);
    let mut mgmot = mgmot_run(&cfg, None).spawn_logged(dir.join("mgmot.log"));
    let mut sim = scenario
        .run(true, port, &socket)
        .spawn_logged(dir.join("sim.log"));
    match kill_after {
        Some(after) => {
            std::thread::sleep(after);
            // SIGKILL: no chance to flush or write the end record.
            Command::new("kill")
                .args(["-KILL", &mgmot.id().to_string()])
                .status()
                .expect("kill");
            assert!(mgmot.wait_within(Duration::from_secs(5)).is_some());
        }
        None => {
            sim.wait_or_fail(Duration::from_secs(scenario.duration_s as u64 + 60));
            let status = mgmot.wait_or_fail(Duration::from_secs(20));
            assert!(status.success(), "mgmot run: {status}\n{}", mgmot.log());
        }
    }
    drop(sim);
    let flights: Vec<PathBuf> = std::fs::read_dir(dir.join("flights"))
        .expect("the recording folder")
        .map(|e| e.unwrap().path())
        .collect();
    assert_eq!(flights.len(), 1, "one flight folder: {flights:?}");
    let flight = flights[0].clone();
    (dir, flight)
}

/// `mgmot replay FLIGHT --out OUT --json [extra]`: its summary.
fn replay(flight: &Path, out: &Path, extra: &[&str]) -> serde_json::Value {
    let o = mgmot()
        .arg("replay")
        .arg(flight)
        .arg("--out")
        .arg(out)
        .arg("--json")
        .args(extra)
        .ok();
    serde_json::from_slice(&o.stdout).expect("replay --json prints JSON")
}

/// The MOTChallenge rows of a replay, per frame number: (id, x, y, w, h).
fn mot_rows(path: &Path) -> Vec<(u64, u64, [f64; 4])> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .map(|l| {
            let v: Vec<&str> = l.split(',').collect();
            let f = |i: usize| v[i].parse::<f64>().unwrap();
            (
                v[0].parse().unwrap(),
                v[1].parse().unwrap(),
                [f(2), f(3), f(4), f(5)],
            )
        })
        .collect()
}

/// The recorded tracks as the same rows (frame number = index + 1).
fn recorded_rows(frames: &[FrameRecord]) -> Vec<(u64, u64, [f64; 4])> {
    frames
        .iter()
        .flat_map(|f| {
            f.tracks.iter().map(move |t| {
                let b = t.track.bbox;
                (f.frame + 1, t.track.id, [b.x, b.y, b.w, b.h])
            })
        })
        .collect()
}

/// pymavlink's `mavutil` reads the tlog: (messages, HEARTBEATs from mgmot, positions from
/// the autopilot, whether the timestamps are the tlog's wall-clock times).
fn pymavlink_read(tlog: &Path) -> (u64, u64, u64, bool) {
    require_python("recording", &["pymavlink"]);
    let script = r#"
import sys, time
from pymavlink import mavutil
m = mavutil.mavlink_connection(sys.argv[1], dialect="common")
n = hb = pos = 0
stamps_ok = True
while True:
    msg = m.recv_match()
    if msg is None:
        break
    n += 1
    if msg.get_type() == "HEARTBEAT" and msg.get_srcComponent() == 191:
        hb += 1
    if msg.get_type() == "GLOBAL_POSITION_INT" and msg.get_srcSystem() == 1:
        pos += 1
    if abs(msg._timestamp - time.time()) > 3600:
        stamps_ok = False
print(n, hb, pos, int(stamps_ok))
"#;
    let o = Command::new("python3")
        .args(["-c", script])
        .arg(tlog)
        .output()
        .expect("python3");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: Vec<u64> = String::from_utf8_lossy(&o.stdout)
        .split_whitespace()
        .map(|x| x.parse().unwrap())
        .collect();
    (v[0], v[1], v[2], v[3] == 1)
}

#[test]
fn a_recorded_flight_replays_exactly_and_its_tlog_opens_in_pymavlink() {
    let scenario = Scenario::new("calm_baseline", 14.0).size(640, 360);
    let (dir, flight_dir) = record(&scenario, None);
    let flight = Flight::load(&flight_dir).unwrap();
    let end = flight
        .end
        .clone()
        .expect("a clean run writes the end record");
    assert!(flight.bad_lines.is_empty(), "{:?}", flight.bad_lines);
    assert!(flight.frames.len() > 100, "{} frames", flight.frames.len());
    assert_eq!(end.frames_written, flight.frames.len() as u64);
    assert_eq!(end.frames_dropped_queue, 0);
    assert!(end.run_stats.is_some());
    assert_eq!(flight.info.detector.kind, "replay");
    assert_eq!(flight.info.detector.sha256.len(), 64);
    let with_pose = flight.frames.iter().filter(|f| f.pose.is_some()).count();
    assert!(
        with_pose * 10 > flight.frames.len() * 9,
        "{with_pose} frames with a pose"
    );
    // The simulator's receiver reports its accuracy in GPS_RAW_INT (calm_baseline has no GPS
    // noise: the receiver's floor, 1 cm); the poses carry it from the first report on, and the
    // replay below geolocates with it.
    let accuracies: Vec<Option<f64>> = flight
        .frames
        .iter()
        .filter_map(|f| f.pose.as_ref())
        .map(|p| p.horizontal_accuracy_m)
        .collect();
    let reported = accuracies.iter().filter(|a| **a == Some(0.01)).count();
    assert!(
        reported * 10 > accuracies.len() * 9
            && accuracies.iter().all(|a| a.is_none_or(|m| m == 0.01)),
        "{reported} of {} poses with the receiver's accuracy: {:?}",
        accuracies.len(),
        accuracies
            .iter()
            .filter(|a| **a != Some(0.01))
            .take(5)
            .collect::<Vec<_>>()
    );
    let geolocated = flight
        .frames
        .iter()
        .flat_map(|f| &f.tracks)
        .filter(|t| t.geo.is_some())
        .count();
    assert!(geolocated > 100, "{geolocated} geolocated track boxes");
    assert!(flight.frames.iter().any(|f| f.keyframe.is_some()));
    for f in flight.frames.iter().filter_map(|f| f.keyframe.as_ref()) {
        let jpeg = std::fs::read(flight_dir.join("keyframes").join(f)).unwrap();
        assert_eq!(&jpeg[..2], &[0xFF, 0xD8], "{f} is a JPEG");
    }

    // Online replay with the flight's own parameters: the same tracks, bit for bit.
    let s = replay(&flight_dir, &dir.join("online"), &[]);
    let c = &s["reproduces_recording"];
    assert_eq!(c["first_difference"], serde_json::Value::Null, "{s}");
    assert_eq!(c["frames_identical"], flight.frames.len());
    // And independently of replay's own check: its MOTChallenge rows are the recorded tracks.
    let recorded = recorded_rows(&flight.frames);
    assert!(!recorded.is_empty());
    assert_eq!(mot_rows(&dir.join("online/flight.txt")), recorded);

    // Other parameters change the outcome (the comparison is not vacuous): a tracker that
    // never confirms a track reports none.
    let strict = dir.write(
        "strict.toml",
        "[baseline]\ntrack_high_thresh = 0.99\nnew_track_thresh = 0.99\n",
    );
    let s = replay(
        &flight_dir,
        &dir.join("strict"),
        &["--config", strict.to_str().unwrap()],
    );
    assert_eq!(s["reproduces_recording"], serde_json::Value::Null);
    assert!(
        s["track_boxes"].as_u64().unwrap() < recorded.len() as u64 / 2,
        "{s}"
    );

    // Offline: the paper's post-processing over the same inputs.
    let s = replay(&flight_dir, &dir.join("offline"), &["--mode", "offline"]);
    assert!(
        s["track_boxes"].as_u64().unwrap() >= recorded.len() as u64 / 2,
        "{s}"
    );
    assert!(dir.join("offline/flight_tracks.csv").is_file());

    // The tlog: every packet in and out, readable by pymavlink with its wall-clock stamps.
    let (entries, clean) = flight.tlog().unwrap();
    assert!(clean);
    let (n, heartbeats, positions, stamps_ok) = pymavlink_read(&flight_dir.join("flight.tlog"));
    assert!(
        n as usize >= entries.len() * 9 / 10,
        "{n} of {}",
        entries.len()
    );
    assert!(heartbeats >= 10, "{heartbeats} HEARTBEATs from mgmot");
    assert!(positions >= 100, "{positions} GLOBAL_POSITION_INT");
    assert!(stamps_ok);
}

#[test]
fn a_flight_killed_with_sigkill_replays_up_to_its_last_whole_frame() {
    let scenario = Scenario::new("calm_baseline", 30.0).size(640, 360);
    let (dir, flight_dir) = record(&scenario, Some(Duration::from_secs(9)));
    let flight = Flight::load(&flight_dir).unwrap();
    assert!(flight.end.is_none(), "killed: no end record");
    assert!(flight.bad_lines.len() <= 1, "{:?}", flight.bad_lines);
    assert!(flight.frames.len() > 50, "{} frames", flight.frames.len());
    let (entries, _) = flight.tlog().unwrap();
    assert!(entries.len() > 500, "{} packets", entries.len());

    let s = replay(&flight_dir, &dir.join("replay"), &[]);
    assert_eq!(s["ended_cleanly"], false);
    let c = &s["reproduces_recording"];
    assert_eq!(c["first_difference"], serde_json::Value::Null, "{s}");

    // A record cut in the middle of its last frame line (power lost mid-write) loses exactly
    // that frame.
    let frames = flight_dir.join("frames.ndjson");
    let text = std::fs::read(&frames).unwrap();
    let last_start = text[..text.len() - 1]
        .iter()
        .rposition(|&b| b == b'\n')
        .unwrap()
        + 1;
    std::fs::write(&frames, &text[..last_start + (text.len() - last_start) / 2]).unwrap();
    let cut = Flight::load(&flight_dir).unwrap();
    assert_eq!(cut.frames.len(), flight.frames.len() - 1);
    assert_eq!(cut.bad_lines.len(), 1);
    let s = replay(&flight_dir, &dir.join("cut"), &[]);
    assert_eq!(
        s["reproduces_recording"]["first_difference"],
        serde_json::Value::Null
    );
    assert_eq!(s["frames"], flight.frames.len() - 1);
}

/// A recorded `calm_baseline` run behind the relay (which sees what mgmot sends): its folder,
/// scenario (640x360, `seconds` long), frame socket, relay, the recording's parent folder
/// `rec` (created) and the run's configuration recording into `rec/flights`.
struct Relayed {
    dir: TestDir,
    scenario: Scenario,
    socket: PathBuf,
    relay: common::Relay,
    rec: PathBuf,
    config: mgmot::config::Config,
}

fn relayed(seconds: f64) -> Relayed {
    let dir = TestDir::new();
    let scenario = Scenario::new("calm_baseline", seconds).size(640, 360);
    let dets = dir.join("dets.json");
    scenario.detections(&dets);
    let socket = dir.join("frames.sock");
    let port = free_udp_port();
    let relay = common::Relay::start(port);
    let rec = dir.join("rec");
    std::fs::create_dir_all(&rec).unwrap();
    let mut config = run_config(&format!("udpin:127.0.0.1:{port}"), &socket, &dets);
    config.recording.dir = Some(rec.join("flights"));
    Relayed {
        dir,
        scenario,
        socket,
        relay,
        rec,
        config,
    }
}

/// A real full disk: an 8 MB tmpfs, mounted in a private mount namespace (`unshare`, no root
/// needed where unprivileged user namespaces are on, as on Debian), filled up but for about
/// 400 kB. mgmot records until the disk is full, says so once (log and STATUSTEXT) and
/// goes on tracking and sending; the test frees the space and recording resumes with a gap
/// record; the record stays whole (cut back to its last whole record) and replays.
#[test]
fn a_full_disk_stops_recording_without_stopping_tracking_and_recording_resumes() {
    let probe = Command::new("unshare")
        .args(["-rm", "sh", "-c", "mount -t tmpfs -o size=64k tmpfs /mnt"])
        .output();
    match probe {
        Ok(o) if o.status.success() => {}
        Ok(o) => common::missing_tool(
            "a_full_disk",
            &format!(
                "a tmpfs in a user namespace (`unshare -rm`, mount): {}",
                String::from_utf8_lossy(&o.stderr).trim()
            ),
        ),
        Err(e) => common::missing_tool("a_full_disk", &format!("unshare (util-linux): {e}")),
    }
    let Relayed {
        dir,
        scenario,
        socket,
        relay,
        rec,
        config: mut c,
    } = relayed(30.0);
    c.recording.keyframe_every_s = 0.0;
    let cfg = dir.write_config("mgmot.toml", &c);
    let log = dir.join("mgmot.log");
    let script = r#"
set -e
mount -t tmpfs -o size=8m tmpfs "$REC"
head -c 7800k /dev/zero > "$REC/filler"
"$MGMOT" run --config "$CFG" 2> "$LOG" &
pid=$!
while [ ! -e "$CTL/free" ]; do sleep 0.1; done
rm "$REC/filler"
status=0
wait $pid || status=$?
cp -r "$REC/flights" "$OUT/"
exit $status
"#;
    let mut ns = common::TestCommand::new("unshare");
    ns.args(["-rm", "sh", "-c", script])
        .env("REC", &rec)
        .env("MGMOT", env!("CARGO_BIN_EXE_mgmot"))
        .env("CFG", &cfg)
        .env("LOG", &log)
        .env("CTL", dir.path())
        .env("OUT", dir.path());
    let mut mgmot = ns.spawn_logged(dir.join("unshare.log"));
    let mut sim = scenario
        .run(true, relay.listen_port, &socket)
        .spawn_logged(dir.join("sim.log"));
    let read_log = || std::fs::read_to_string(&log).unwrap_or_default();
    let wait_log = |what: &str, limit: Duration| {
        let until = std::time::Instant::now() + limit;
        while !read_log().contains(what) {
            assert!(
                std::time::Instant::now() < until,
                "no {what:?} in mgmot's log within {limit:?}:\n{}",
                read_log()
            );
            std::thread::sleep(Duration::from_millis(100));
        }
    };
    wait_log("flight recording stopped", Duration::from_secs(25));
    let tracks_before = relay.sent.lock().unwrap().len();
    std::thread::sleep(Duration::from_secs(2));
    dir.write("free", "");
    wait_log("flight recording resumed", Duration::from_secs(15));
    sim.wait_or_fail(Duration::from_secs(60));
    let status = mgmot.wait_or_fail(Duration::from_secs(20));
    assert!(
        status.success(),
        "{status}\n{}\n{}",
        mgmot.log(),
        read_log()
    );
    let sent_total = relay.sent.lock().unwrap().len();
    assert!(
        sent_total > tracks_before + 20,
        "mgmot kept sending while the disk was full"
    );

    // Said once each, over MAVLink and in the log.
    let texts = relay.statustexts();
    let stopped: Vec<_> = texts
        .iter()
        .filter(|t| t.contains("recording stopped"))
        .collect();
    assert_eq!(stopped.len(), 1, "{texts:?}");
    assert!(stopped[0].contains("disk full"), "{stopped:?}");
    assert_eq!(
        texts
            .iter()
            .filter(|t| t.contains("recording resumed"))
            .count(),
        1,
        "{texts:?}"
    );
    assert_eq!(read_log().matches("flight recording stopped").count(), 1);

    // The record: whole lines only, a gap where the disk was full, an end record, frames on
    // both sides of the gap, and it replays exactly up to the gap.
    let flights: Vec<PathBuf> = std::fs::read_dir(dir.join("flights"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    let flight = Flight::load(&flights[0]).unwrap();
    assert!(flight.bad_lines.is_empty(), "{:?}", flight.bad_lines);
    assert_eq!(flight.gaps.len(), 1, "{:?}", flight.gaps);
    let gap = &flight.gaps[0];
    assert!(gap.frames_lost > 10 && gap.packets_lost > 100, "{gap:?}");
    let end = flight.end.as_ref().expect("end record");
    assert_eq!(end.frames_lost_stopped, gap.frames_lost);
    let before = flight
        .frames
        .iter()
        .filter(|f| f.processed_unix_us < gap.stopped_unix_us)
        .count();
    let after = flight
        .frames
        .iter()
        .filter(|f| f.processed_unix_us > gap.resumed_unix_us)
        .count();
    assert!(
        before > 10 && after > 10,
        "{before} frames before, {after} after"
    );
    let (_, clean) = flight.tlog().unwrap();
    assert!(clean, "the tlog was cut back to whole packets");
    let s = replay(&flights[0], &dir.join("replay"), &[]);
    let identical = s["reproduces_recording"]["frames_identical"]
        .as_u64()
        .unwrap();
    assert!(identical as usize >= before, "{s}");
}

/// Issue 39 item 10: a recording folder that cannot be written at start (read-only) is said
/// to the operator by STATUSTEXT once the link has its peer, not only in the log; the flight
/// goes on without a record.
#[test]
fn a_read_only_recording_folder_at_start_is_said_to_the_operator() {
    use std::os::unix::fs::PermissionsExt;
    let Relayed {
        dir,
        scenario,
        socket,
        relay,
        rec,
        config: c,
    } = relayed(8.0);
    std::fs::set_permissions(&rec, std::fs::Permissions::from_mode(0o555)).unwrap();
    let cfg = dir.write_config("mgmot.toml", &c);
    let mut mgmot = common::mgmot_bound_by_permissions();
    mgmot.args(["run", "--config"]).arg(&cfg);
    let mut mgmot = mgmot.spawn_logged(dir.join("mgmot.log"));
    let mut sim = scenario
        .run(true, relay.listen_port, &socket)
        .spawn_logged(dir.join("sim.log"));
    sim.wait_or_fail(Duration::from_secs(60));
    let status = mgmot.wait_or_fail(Duration::from_secs(20));
    assert!(status.success(), "mgmot run: {status}\n{}", mgmot.log());
    let log = mgmot.log();
    assert!(log.contains("cannot record this flight"), "{log}");
    assert!(!rec.join("flights").exists());
    let texts = relay.statustexts();
    let off: Vec<_> = texts
        .iter()
        .filter(|t| t.contains("recording off"))
        .collect();
    assert_eq!(off.len(), 1, "{texts:?}\n{log}");
    assert!(
        relay.sent.lock().unwrap().len() > 20,
        "the flight went on without a record"
    );
}
