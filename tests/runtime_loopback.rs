//! `mgmot run` against the real `mgmot-sim` on loopback: MAVLink over UDP through a tap that
//! decodes what mgmot sends (with the generated dialect), frames over the sim's Unix socket.
//! The identity tests (gimbal swings, leave and return) and one calm run use the real ONNX
//! detector on rendered 1280x720 frames; the others use the replay detector (the simulator's
//! detection mode, keyed by frame, so the tracker sees the simulator's detector model).
//!
//! The simulator binary is `$MGMOT_SIM_BIN`, or `target/debug/mgmot-sim` built here with
//! `cargo build -p mgmot-sim` (a workspace member). The simulator runs in lockstep (as fast as
//! mgmot reads frames), on shortened scenarios, at a reduced frame size where the pixels are
//! not looked at, to keep the suite within the CI budget on a 2-core machine.

mod common;

use common::{free_udp_port, sim_bin, sim_to, Relay, BOOT_TIME_S};
use mavlink_core::MavHeader;
use mgmot::mavlink::dialect::{
    MavMessage, MavSeverity, MavType, MgmotTrackFlags, MgmotTrackState, MGMOT_TRACK_DATA,
};
use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

/// Metres per degree of latitude (spherical approximation; the distances here are tens of
/// metres, where it is good to millimetres).
const M_PER_DEG: f64 = 111_320.0;

/// Stops the relay: what mgmot sent, message by message.
fn finish(tap: Relay) -> Vec<(MavHeader, MavMessage)> {
    tap.finish()
        .into_iter()
        .map(|s| (s.header, s.msg))
        .collect()
}

/// Which detector mgmot runs.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Det {
    /// The simulator's detections of the same scenario, replayed by frame.
    Replay,
    /// The shipped fp32 model on rendered frames: on ONNX Runtime where `ORT_DYLIB_PATH`
    /// names it, else on tract (pure Rust: runs anywhere).
    Onnx,
}

/// One loopback run.
struct Spec {
    /// A shipped scenario name, or the path of a scenario file.
    scenario: String,
    duration_s: f64,
    /// Frame size override (the replay detector does not look at the pixels; smaller frames
    /// render and travel faster).
    size_px: Option<(u32, u32)>,
    detector: Det,
}

impl Spec {
    fn sim_args(&self) -> Vec<String> {
        let mut a = vec![
            "--scenario".to_string(),
            self.scenario.clone(),
            "--duration-s".into(),
            self.duration_s.to_string(),
        ];
        if let Some((w, h)) = self.size_px {
            a.extend([
                "--width".into(),
                w.to_string(),
                "--height".into(),
                h.to_string(),
            ]);
        }
        a
    }
}

/// One ground-truth object in one streamed frame.
#[derive(Debug, Clone)]
struct Truth {
    t_ms: i64,
    id: u64,
    class: String,
    lat: f64,
    lon: f64,
}

struct Outcome {
    _dir: tempfile::TempDir,
    status: ExitStatus,
    stderr: String,
    messages: Vec<(MavHeader, MavMessage)>,
    truth: Vec<Truth>,
    stats: serde_json::Value,
}

impl Outcome {
    fn tracks(&self) -> impl Iterator<Item = &MGMOT_TRACK_DATA> {
        self.messages.iter().filter_map(|(_, m)| match m {
            MavMessage::MGMOT_TRACK(t) => Some(t),
            _ => None,
        })
    }

    fn assert_success(&self) {
        assert!(self.status.success(), "mgmot run failed: {}", self.stderr);
    }
}

fn write_config(dir: &Path, mgmot_port: u16, detector: Det) -> PathBuf {
    let detector = match detector {
        Det::Replay => format!(
            "kind = \"replay\"\ndetections = \"{}\"\n",
            dir.join("dets.json").display()
        ),
        // The fp32 model: tract and ONNX Runtime give the same detections with it (parity test
        // in tests/detect_cli.rs), ONNX Runtime about 3.5x faster, where ORT_DYLIB_PATH names it
        // (scripts/test.sh fetches it).
        Det::Onnx => format!(
            "kind = \"onnx\"\nmodel = \"{}/models/mgmot-det-fp32.onnx\"\nbackend = \"{}\"\n",
            env!("CARGO_MANIFEST_DIR"),
            if onnxruntime_available() {
                "onnxruntime"
            } else {
                "tract"
            }
        ),
    };
    let config = dir.join("run.toml");
    std::fs::write(
        &config,
        format!(
            "[mavlink]\nconnection = \"udpin:127.0.0.1:{mgmot_port}\"\n\
             [frames]\nsource = \"sim\"\nsocket = \"{}\"\n\
             [detector]\n{detector}",
            dir.join("frames.sock").display(),
        ),
    )
    .unwrap();
    config
}

/// Whether `ORT_DYLIB_PATH` names an ONNX Runtime library (mgmot then uses it).
fn onnxruntime_available() -> bool {
    std::env::var_os("ORT_DYLIB_PATH").is_some_and(|p| Path::new(&p).is_file())
}

fn start_sim(sim: &Path, spec: &Spec, dir: &Path, tap_port: u16, truth: bool) -> Child {
    let mut c = Command::new(sim);
    c.arg("run")
        .args(spec.sim_args())
        .arg("--lockstep")
        .arg("--mavlink")
        .arg(format!("udpout:127.0.0.1:{tap_port}"))
        .arg("--frames")
        .arg(format!("unix:{}", dir.join("frames.sock").display()));
    if truth {
        c.arg("--truth-out").arg(dir.join("truth"));
    }
    c.stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap()
}

fn start_mgmot(config: &Path, stats: &Path) -> Child {
    Command::new(env!("CARGO_BIN_EXE_mgmot"))
        .args(["run", "--config"])
        .arg(config)
        .arg("--stats-json")
        .arg(stats)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap()
}

fn wait_with_timeout(child: &mut Child, limit: Duration) -> ExitStatus {
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

/// Ground truth of the frames the simulator streamed (`--truth-out`).
fn read_truth(dir: &Path) -> Vec<Truth> {
    let mut r = csv::Reader::from_path(dir.join("truth/world.csv")).unwrap();
    r.deserialize::<HashMap<String, String>>()
        .map(|row| {
            let row = row.unwrap();
            Truth {
                t_ms: (row["time_s"].parse::<f64>().unwrap() * 1000.0).round() as i64,
                id: row["id"].parse().unwrap(),
                class: row["class"].clone(),
                lat: row["lat_deg"].parse().unwrap(),
                lon: row["lon_deg"].parse().unwrap(),
            }
        })
        .collect()
}

/// Runs the simulator (lockstep) and `mgmot run` to the end of the scenario.
fn run_loopback(spec: &Spec) -> Outcome {
    let sim = sim_bin();
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().to_owned();
    if spec.detector == Det::Replay {
        let args = [vec!["detections".to_string()], spec.sim_args()].concat();
        sim_to(&sim, &args, &dir.join("dets.json"));
    }
    let mgmot_port = free_udp_port();
    let config = write_config(&dir, mgmot_port, spec.detector);
    let tap = Relay::start(mgmot_port);
    let mut sim_child = start_sim(&sim, spec, &dir, tap.listen_port, true);
    let stats_path = dir.join("stats.json");
    let mut mgmot = start_mgmot(&config, &stats_path);
    // Read stderr while it runs: a full pipe would block mgmot's logging.
    let mut err_pipe = mgmot.stderr.take().unwrap();
    let stderr_reader = std::thread::spawn(move || {
        let mut e = String::new();
        use std::io::Read;
        let _ = err_pipe.read_to_string(&mut e);
        e
    });
    let status = wait_with_timeout(&mut mgmot, Duration::from_secs(600));
    let _ = wait_with_timeout(&mut sim_child, Duration::from_secs(30));
    std::thread::sleep(Duration::from_millis(300));
    let messages = finish(tap);
    let stderr = stderr_reader.join().unwrap();
    let stats = std::fs::read_to_string(&stats_path)
        .ok()
        .and_then(|s| serde_json::from_str(&s).ok())
        .unwrap_or(serde_json::Value::Null);
    let truth = read_truth(&dir);
    Outcome {
        _dir: tmp,
        status,
        stderr,
        messages,
        truth,
        stats,
    }
}

/// Sim time (ms) of the frame a track message describes.
fn track_time_ms(t: &MGMOT_TRACK_DATA) -> i64 {
    ((t.time_usec as f64 / 1e6 - BOOT_TIME_S) * 1000.0).round() as i64
}

fn distance_m(lat_a: f64, lon_a: f64, lat_b: f64, lon_b: f64) -> f64 {
    let dn = (lat_a - lat_b) * M_PER_DEG;
    let de = (lon_a - lon_b) * M_PER_DEG * lat_b.to_radians().cos();
    dn.hypot(de)
}

/// The truth objects of the frame a geolocated track message describes, nearest first, with
/// their distance from the message's position.
fn nearest_truth<'a>(t: &MGMOT_TRACK_DATA, truth: &'a [Truth]) -> Vec<(f64, &'a Truth)> {
    let t_ms = track_time_ms(t);
    let (lat, lon) = (f64::from(t.lat) * 1e-7, f64::from(t.lon) * 1e-7);
    let mut near: Vec<(f64, &Truth)> = truth
        .iter()
        .filter(|g| (g.t_ms - t_ms).abs() <= 5)
        .map(|g| (distance_m(lat, lon, g.lat, g.lon), g))
        .collect();
    near.sort_by(|a, b| a.0.total_cmp(&b.0));
    near
}

fn geo_valid(t: &MGMOT_TRACK_DATA) -> bool {
    t.flags
        .contains(MgmotTrackFlags::MGMOT_TRACK_FLAGS_GEO_VALID)
}

/// The object class names of MGMOT_OBJECT_CLASS (SeaDronesSee's category ids).
const CLASSES: [&str; 6] = [
    "",
    "swimmer",
    "boat",
    "jetski",
    "life_saving_appliance",
    "buoy",
];

/// Geolocation error of every geolocated track message: the distance to the nearest truth
/// object of the same frame (of the same class when `same_class`).
fn geolocation_errors(o: &Outcome, same_class: bool) -> Vec<f64> {
    o.tracks()
        .filter(|t| geo_valid(t))
        .map(|t| {
            let class = CLASSES.get(t.object_class as usize).copied().unwrap_or("");
            nearest_truth(t, &o.truth)
                .into_iter()
                .find(|(_, g)| !same_class || g.class == class)
                .map_or(f64::INFINITY, |(d, _)| d)
        })
        .collect()
}

/// Track ids after re-identification: `merged_from_id` -> `track_id` links, followed to the
/// end (a merged-into id can itself be merged later).
fn final_ids(o: &Outcome) -> HashMap<u32, u32> {
    let mut into: HashMap<u32, u32> = HashMap::new();
    for t in o.tracks() {
        if t.flags.contains(MgmotTrackFlags::MGMOT_TRACK_FLAGS_MERGED) && t.merged_from_id != 0 {
            into.insert(t.merged_from_id, t.track_id);
        }
    }
    let ids: BTreeSet<u32> = o.tracks().map(|t| t.track_id).collect();
    ids.into_iter()
        .map(|id| {
            let mut f = id;
            let mut hops = 0;
            while let Some(&next) = into.get(&f) {
                f = next;
                hops += 1;
                assert!(hops < 1000, "merge cycle through track {id}");
            }
            (id, f)
        })
        .collect()
}

/// Identity per ground-truth object, from what mgmot sent.
///
/// A track message is attributed to a truth object when it is geolocated, its track matched a
/// detection in that frame (state TRACKED: a coasting track's position is a prediction), the
/// nearest truth object of that frame is within `GATE_M` and the second nearest is at least
/// `MARGIN_M` further (unambiguous). Track ids are resolved through the re-identification
/// merges (`final_ids`). A final id counts for an object when at least `MIN_MESSAGES` of its
/// messages were attributed to that object (a stray box for half a second is not an identity);
/// objects with fewer than `MIN_MESSAGES` attributed messages are left out (seen too briefly).
/// Returns, per object, the final ids and their message counts.
fn identities(o: &Outcome) -> BTreeMap<u64, BTreeMap<u32, usize>> {
    const GATE_M: f64 = 4.0;
    const MARGIN_M: f64 = 2.0;
    const MIN_MESSAGES: usize = 3;
    let finals = final_ids(o);
    let mut per_object: BTreeMap<u64, BTreeMap<u32, usize>> = BTreeMap::new();
    for t in o.tracks() {
        if !geo_valid(t) || t.state != MgmotTrackState::MGMOT_TRACK_STATE_TRACKED {
            continue;
        }
        let near = nearest_truth(t, &o.truth);
        let Some(&(d, g)) = near.first() else {
            continue;
        };
        let second = near.get(1).map_or(f64::INFINITY, |n| n.0);
        if d > GATE_M || second < d + MARGIN_M {
            continue;
        }
        *per_object
            .entry(g.id)
            .or_default()
            .entry(finals[&t.track_id])
            .or_default() += 1;
    }
    per_object
        .into_iter()
        .filter_map(|(obj, ids)| {
            let ids: BTreeMap<u32, usize> = ids
                .into_iter()
                .filter(|&(_, n)| n >= MIN_MESSAGES)
                .collect();
            (!ids.is_empty()).then_some((obj, ids))
        })
        .collect()
}

/// The re-identification scenarios: every object keeps one id after the merges.
fn assert_ids_survive(o: &Outcome, min_objects: usize) {
    o.assert_success();
    let ids = identities(o);
    let merges = o
        .tracks()
        .filter(|t| t.flags.contains(MgmotTrackFlags::MGMOT_TRACK_FLAGS_MERGED))
        .count();
    eprintln!("identities per truth object: {ids:?}; {merges} merge messages");
    eprintln!("stats: {}", o.stats);
    assert!(
        ids.len() >= min_objects,
        "only {} truth objects were tracked and geolocated ({ids:?}); mgmot said: {}",
        ids.len(),
        o.stderr
    );
    let split: Vec<_> = ids.iter().filter(|(_, v)| v.len() > 1).collect();
    assert!(
        split.is_empty(),
        "objects with more than one final track id: {split:?} (all: {ids:?})"
    );
}

#[test]
fn calm_baseline_heartbeat_tracks_and_geolocation_error() {
    let o = run_loopback(&Spec {
        scenario: "calm_baseline".into(),
        duration_s: 12.0,
        size_px: Some((640, 360)),
        detector: Det::Replay,
    });
    o.assert_success();
    let heartbeat = o.messages.iter().any(|(h, m)| {
        h.component_id == 191
            && matches!(m, MavMessage::HEARTBEAT(hb) if hb.mavtype == MavType::MAV_TYPE_ONBOARD_CONTROLLER)
    });
    assert!(
        heartbeat,
        "no HEARTBEAT from mgmot among {} messages",
        o.messages.len()
    );
    let errors = geolocation_errors(&o, true);
    assert!(
        !errors.is_empty(),
        "no geolocated MGMOT_TRACK; mgmot said: {}",
        o.stderr
    );
    let worst = errors.iter().copied().fold(0.0, f64::max);
    assert!(worst < 3.0, "geolocation errors {errors:?}");
    // The stats file: counters and the end-to-end latency of the messages the tap received.
    assert_eq!(
        o.stats["frames_processed"].as_u64().map(|n| n > 0),
        Some(true)
    );
    assert_eq!(
        o.stats["track_messages"].as_u64(),
        Some(o.tracks().count() as u64),
        "every queued MGMOT_TRACK reached the tap: {}",
        o.stats
    );
    // Frame age and end to end are measured from the capture stamp, on the autopilot clock,
    // mapped onto the companion clock. In lockstep the simulator's clock runs at whatever
    // speed mgmot reads frames, not in real time, so the mapping (from the TIMESYNC with the
    // shortest round trip) can put a capture in the future; such samples are skipped, and how
    // many remain depends on the machine's load. Here: only that the counts are consistent.
    // The real-time test in tests/runtime_link.rs requires them.
    let count = |stage: &str| o.stats["latency"][stage]["count"].as_u64().unwrap_or(0);
    assert!(
        count("end_to_end") <= o.stats["track_messages"].as_u64().unwrap_or(0)
            && count("frame_age") <= o.stats["frames_processed"].as_u64().unwrap_or(0),
        "{}",
        o.stats
    );
    for stage in ["detect", "pose_geolocate", "track", "encode", "processing"] {
        assert!(count(stage) > 0, "no {stage} latency in {}", o.stats);
    }
}

/// The real detector on rendered frames: tracks arrive and are geolocated within 3 m of a
/// true object. Class-agnostic: the shipped model knows swimmers and boats only, so a buoy
/// seen as a swimmer is still a correct position.
#[test]
fn onnx_detector_on_rendered_frames_calm_baseline() {
    let o = run_loopback(&Spec {
        scenario: "calm_baseline".into(),
        duration_s: 10.0,
        size_px: None,
        detector: Det::Onnx,
    });
    o.assert_success();
    eprintln!("stats: {}", o.stats);
    let errors = geolocation_errors(&o, false);
    assert!(
        !errors.is_empty(),
        "no geolocated MGMOT_TRACK from the ONNX detector; mgmot said: {}",
        o.stderr
    );
    let worst = errors.iter().copied().fold(0.0, f64::max);
    assert!(worst < 3.0, "geolocation errors {errors:?}");
    assert!(
        o.stats["latency"]["detect_inference"]["count"].as_u64() > Some(0),
        "the ONNX detector reports its model time: {}",
        o.stats
    );
    assert_eq!(o.stats["detector_errors"].as_u64(), Some(0));
}

/// Sudden gimbal swings (180 deg/s every 4 s), the real detector on rendered 1280x720 frames:
/// the camera-motion compensation from the pose and the re-identification keep one id per
/// object.
#[test]
fn ids_survive_gimbal_swings() {
    let o = run_loopback(&Spec {
        scenario: "gimbal_swings".into(),
        duration_s: 20.0,
        size_px: None,
        detector: Det::Onnx,
    });
    assert_ids_survive(&o, 3);
}

/// The gimbal pans away from the swimmers and back (they are out of view for about 18 s), the
/// real detector on rendered 1280x720 frames: long-term re-identification gives them their old
/// ids again.
#[test]
fn ids_survive_leave_and_return() {
    let o = run_loopback(&Spec {
        scenario: "leave_and_return".into(),
        duration_s: 32.0,
        size_px: None,
        detector: Det::Onnx,
    });
    assert_ids_survive(&o, 3);
}

/// The telemetry link drops out for 5 s (nothing sent) while frames keep coming: tracks keep
/// their ids and are sent without a position during the gap, geolocated again after it, and
/// the loss and the recovery are each reported once by STATUSTEXT.
#[test]
fn telemetry_dropout_keeps_tracking_and_flags_geolocation() {
    // The shipped scenario with its dropout moved from 20 s to 8 s, to keep the run short.
    let shipped = Command::new(sim_bin())
        .args(["list", "--show", "telemetry_dropout"])
        .output()
        .unwrap();
    assert!(shipped.status.success());
    let text = String::from_utf8(shipped.stdout).unwrap();
    assert!(text.contains("dropouts = [[20.0, 5.0]]"), "{text}");
    let dir = tempfile::tempdir().unwrap();
    let scenario = dir.path().join("dropout.toml");
    std::fs::write(
        &scenario,
        text.replace("dropouts = [[20.0, 5.0]]", "dropouts = [[8.0, 5.0]]"),
    )
    .unwrap();
    let (gap_start, gap_end) = (8_000, 13_000);
    let o = run_loopback(&Spec {
        scenario: scenario.display().to_string(),
        duration_s: 17.0,
        size_px: Some((640, 360)),
        detector: Det::Replay,
    });
    o.assert_success();
    // Poses stay usable for `max_pose_age_ms` (200 ms) after the last sample.
    let before: Vec<_> = o
        .tracks()
        .filter(|t| track_time_ms(t) < gap_start)
        .collect();
    let during: Vec<_> = o
        .tracks()
        .filter(|t| (gap_start + 300..gap_end).contains(&track_time_ms(t)))
        .collect();
    let after: Vec<_> = o
        .tracks()
        .filter(|t| track_time_ms(t) >= gap_end + 500)
        .collect();
    eprintln!(
        "messages before/during/after: {}/{}/{}; stats {}",
        before.len(),
        during.len(),
        after.len(),
        o.stats
    );
    assert!(
        before.iter().any(|t| geo_valid(t)),
        "no geolocated track before the gap"
    );
    assert!(!during.is_empty(), "tracking stopped during the dropout");
    let geo_during: Vec<_> = during.iter().filter(|t| geo_valid(t)).collect();
    assert!(
        geo_during.is_empty(),
        "geolocated during the dropout: {geo_during:?}"
    );
    assert!(
        after.iter().any(|t| geo_valid(t)),
        "no geolocation after the gap"
    );
    // Tracking continued through both edges of the gap: the tracker is not reset when the pose
    // goes away, nor when it comes back (the same ids are sent across each transition; the
    // drone flies a lawnmower, so the objects in view before and long after may differ).
    let ids = |v: &[&MGMOT_TRACK_DATA]| v.iter().map(|t| t.track_id).collect::<BTreeSet<_>>();
    let (b, d, a) = (ids(&before), ids(&during), ids(&after));
    assert!(
        b.intersection(&d).next().is_some() && d.intersection(&a).next().is_some(),
        "track ids not kept across the gap's edges: before {b:?}, during {d:?}, after {a:?}"
    );
    // Once it ends, geolocation is right again: every message with a true object in the frame
    // is within 3 m. A message may have none: the truth lists the objects in view, and a track
    // whose object left the view (the drone flies a lawnmower) is still reported for a while in
    // state LOST from the filter's prediction; seen here: 9 of 41, so at most 1 in 3.
    let errors = geolocation_errors(&o, true);
    let unmatched = errors.iter().filter(|e| !e.is_finite()).count();
    assert!(
        !errors.is_empty()
            && unmatched * 3 <= errors.len()
            && errors.iter().filter(|e| e.is_finite()).all(|&e| e < 3.0),
        "geolocation errors {errors:?}"
    );
    let texts: Vec<(MavSeverity, String)> = o
        .messages
        .iter()
        .filter_map(|(_, m)| match m {
            MavMessage::STATUSTEXT(s) => {
                Some((s.severity, s.text.to_str().unwrap_or_default().to_string()))
            }
            _ => None,
        })
        .collect();
    let lost = texts
        .iter()
        .filter(|(_, t)| t.contains("no telemetry"))
        .count();
    let back = texts
        .iter()
        .filter(|(_, t)| t.contains("telemetry ok"))
        .count();
    assert_eq!((lost, back), (1, 1), "STATUSTEXTs: {texts:?}");
}

#[test]
fn sigterm_stops_cleanly() {
    let spec = Spec {
        scenario: "calm_baseline".into(),
        duration_s: 60.0,
        size_px: Some((320, 180)),
        detector: Det::Replay,
    };
    let sim = sim_bin();
    let dir = tempfile::tempdir().unwrap();
    // No detections: this test is about stopping.
    std::fs::write(dir.path().join("dets.json"), "[]").unwrap();
    let mgmot_port = free_udp_port();
    let config = write_config(dir.path(), mgmot_port, Det::Replay);
    let tap = Relay::start(mgmot_port);
    let mut sim_child = start_sim(&sim, &spec, dir.path(), tap.listen_port, false);
    let stats = dir.path().join("stats.json");
    let mut mgmot = start_mgmot(&config, &stats);
    std::thread::sleep(Duration::from_secs(3));
    let kill = Command::new("kill")
        .args(["-TERM", &mgmot.id().to_string()])
        .status()
        .unwrap();
    assert!(kill.success());
    let status = wait_with_timeout(&mut mgmot, Duration::from_secs(20));
    let _ = sim_child.kill();
    let _ = sim_child.wait();
    let messages = finish(tap);
    assert!(status.success(), "exit status after SIGTERM: {status:?}");
    assert!(messages
        .iter()
        .any(|(_, m)| matches!(m, MavMessage::HEARTBEAT(_))));
    // The stats are written on a signalled stop too.
    let stats: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(stats).unwrap()).unwrap();
    assert!(stats["frames_captured"].as_u64().is_some(), "{stats}");
}
