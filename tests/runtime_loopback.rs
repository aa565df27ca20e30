//! `mgmot run` against the real `mgmot-sim` on loopback: MAVLink over UDP through a tap that
//! decodes what mgmot sends (with the generated dialect), frames over the sim's Unix socket.
//! The identity tests (gimbal swings, leave and return) and one calm run use the real ONNX
//! detector on rendered 1280x720 frames; the others use the replay detector (the simulator's
//! detection mode, keyed by frame, so the tracker sees the simulator's detector model).
//!
//! The simulator binary is `$MGMOT_SIM_BIN`, or `target/debug/mgmot-sim` built here with
//! `cargo build -p mgmot-sim` (a workspace member; tests/common). The runs with the real detector are in
//! real time, as flown; the others in lockstep (as fast as mgmot reads frames;
//! `frames.wait_for_detector` makes mgmot read the next one only once the detector took the
//! last, so every frame is processed on a fast or a slow build alike), on shortened scenarios,
//! at a reduced frame size where the pixels are not looked at, to keep the suite within the CI
//! budget on a 2-core machine.

use crate::common;

use common::{
    distance_m, free_udp_port, mgmot_run, read_truth, run_config, track_time_ms, Relay, Scenario,
    Sent, TestDir, Truth,
};
use mgmot::config::{DetectorConfig, FramesConfig, GimbalReport, OnnxDetectorConfig};
use mgmot::detect::BackendKind;
use mgmot::mavlink::dialect::{
    MavMessage, MavType, MgmotTrackFlags, MgmotTrackState, MGMOT_TRACK_DATA,
};
use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::path::PathBuf;
use std::process::ExitStatus;
use std::time::Duration;

/// Which detector mgmot runs.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Det {
    /// The simulator's detections of the same scenario, replayed by frame.
    Replay,
    /// The shipped fp32 model on rendered frames, on the named backend. ONNX Runtime must be
    /// where `ORT_DYLIB_PATH` names it (`scripts/test.sh` fetches it); a case that names it
    /// fails when it is missing, rather than running on tract under its name.
    Onnx(BackendKind),
}

/// One loopback run.
struct Spec {
    /// The scenario; a frame size is set where the replay detector does not look at the
    /// pixels (smaller frames render and travel faster).
    scenario: Scenario,
    detector: Det,
    /// In real time, as flown (the identity tests), instead of lockstep with
    /// `frames.wait_for_detector` (every frame processed, as fast as the machine goes).
    realtime: bool,
    /// mgmot's `telemetry.gimbal_report`.
    gimbal_report: GimbalReport,
}

struct Outcome {
    _dir: TestDir,
    status: ExitStatus,
    stderr: String,
    messages: Vec<Sent>,
    truth: Vec<Truth>,
    stats: serde_json::Value,
}

impl Outcome {
    fn tracks(&self) -> impl Iterator<Item = &MGMOT_TRACK_DATA> {
        self.messages.iter().filter_map(|s| match &s.msg {
            MavMessage::MGMOT_TRACK(t) => Some(t),
            _ => None,
        })
    }

    fn assert_success(&self) {
        assert!(self.status.success(), "mgmot run failed: {}", self.stderr);
    }
}

fn write_config(dir: &TestDir, mgmot_port: u16, spec: &Spec) -> PathBuf {
    let (detector, realtime) = (spec.detector, spec.realtime);
    let mut c = run_config(
        &format!("udpin:127.0.0.1:{mgmot_port}"),
        &dir.join("frames.sock"),
        &dir.join("dets.json"),
    );
    let FramesConfig::Sim {
        wait_for_detector, ..
    } = &mut c.frames
    else {
        unreachable!()
    };
    *wait_for_detector = !realtime;
    c.telemetry.gimbal_report = spec.gimbal_report;
    if let Det::Onnx(backend) = detector {
        // The fp32 model: tract and ONNX Runtime give the same detections with it (parity test
        // in tests/detect_cli.rs), ONNX Runtime about 3.5x faster.
        let mut onnx: OnnxDetectorConfig =
            toml::from_str("model = \"\"").expect("the ONNX detector's defaults");
        onnx.model = common::repo_file("models/mgmot-det-fp32.onnx");
        onnx.backend = backend.into();
        if backend == BackendKind::OnnxRuntime {
            let lib = std::env::var_os("ORT_DYLIB_PATH")
                .map(PathBuf::from)
                .filter(|p| p.is_file())
                .unwrap_or_else(|| {
                    common::missing_tool(
                        "runtime_loopback (ONNX Runtime cases)",
                        "ORT_DYLIB_PATH naming libonnxruntime.so (scripts/detect_fetch_onnxruntime.sh)",
                    )
                });
            onnx.ort_library = Some(lib);
        }
        c.detector = DetectorConfig::Onnx(onnx);
    }
    dir.write_config("run.toml", &c)
}

/// Runs the simulator and `mgmot run` to the end of the scenario.
fn run_loopback(spec: &Spec) -> Outcome {
    let dir = TestDir::new();
    if spec.detector == Det::Replay {
        spec.scenario.detections(&dir.join("dets.json"));
    }
    let mgmot_port = free_udp_port();
    let config = write_config(&dir, mgmot_port, spec);
    let tap = Relay::start(mgmot_port);
    let mut sim = spec
        .scenario
        .run(spec.realtime, tap.listen_port, &dir.join("frames.sock"))
        .arg("--truth-out")
        .arg(dir.join("truth"))
        .spawn();
    let stats_path = dir.join("stats.json");
    let mut mgmot = mgmot_run(&config, Some(&stats_path)).spawn_logged(dir.join("mgmot.log"));
    let status = mgmot.wait_or_fail(Duration::from_secs(600));
    let _ = sim.wait_or_fail(Duration::from_secs(30));
    std::thread::sleep(Duration::from_millis(300));
    let messages = tap.finish();
    let stderr = mgmot.log();
    let stats = std::fs::read_to_string(&stats_path)
        .ok()
        .and_then(|s| serde_json::from_str(&s).ok())
        .unwrap_or(serde_json::Value::Null);
    let truth = read_truth(&dir.join("truth/world.csv"));
    Outcome {
        _dir: dir,
        status,
        stderr,
        messages,
        truth,
        stats,
    }
}

/// Sim time (ms) of the frame a track message describes. The autopilot's clock restarts at a
/// reboot (the `ardupilot_servo` scenario's, at [`REBOOT_S`]): a stamp below the clock at the
/// start is on the rebooted clock.
fn time_ms(t: &MGMOT_TRACK_DATA) -> i64 {
    if (t.time_usec as f64) < common::BOOT_TIME_S * 1e6 {
        (REBOOT_S * 1000.0) as i64 + (t.time_usec / 1000) as i64
    } else {
        track_time_ms(t.time_usec)
    }
}

/// The reboot in the `ardupilot_servo` scenario (its `faults.reboots_s`).
const REBOOT_S: f64 = 14.0;

/// The truth objects of the frame a geolocated track message describes, nearest first, with
/// their distance from the message's position.
fn nearest_truth<'a>(t: &MGMOT_TRACK_DATA, truth: &'a [Truth]) -> Vec<(f64, &'a Truth)> {
    let t_ms = time_ms(t);
    let (lat, lon) = (f64::from(t.lat) * 1e-7, f64::from(t.lon) * 1e-7);
    let mut near: Vec<(f64, &Truth)> = truth
        .iter()
        .filter(|g| (g.t_ms - t_ms).abs() <= 5)
        .map(|g| (distance_m((lat, lon), (g.lat, g.lon)), g))
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

/// Velocity error (m/s) of every geolocated, tracked message whose nearest truth object (same
/// class) is unambiguous and seen for a second: before `split_ms` (sim time) and after it plus
/// five seconds (a new track's velocity needs a few seconds to settle).
fn velocity_errors(o: &Outcome, split_ms: i64) -> (Vec<f64>, Vec<f64>) {
    let (mut before, mut after) = (Vec::new(), Vec::new());
    for t in o.tracks() {
        if !geo_valid(t) || t.state != MgmotTrackState::MGMOT_TRACK_STATE_TRACKED {
            continue;
        }
        let class = CLASSES.get(t.object_class as usize).copied().unwrap_or("");
        let near = nearest_truth(t, &o.truth);
        let mut same = near.iter().filter(|(_, g)| g.class == class);
        let (Some(&(d, g)), second) = (same.next(), same.next()) else {
            continue;
        };
        if d > 4.0 || second.is_some_and(|s| s.0 < d + 2.0) {
            continue;
        }
        let err = (f64::from(t.vel_n) - g.vel_ne.0).hypot(f64::from(t.vel_e) - g.vel_ne.1);
        let t_ms = time_ms(t);
        if t_ms < split_ms {
            before.push(err);
        } else if t_ms > split_ms + 5_000 {
            after.push(err);
        }
    }
    (before, after)
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

/// The re-identification scenarios: every object keeps one id after the merges, except at
/// most `max_split` of them (a known miss, see the caller).
fn assert_ids_survive(o: &Outcome, min_objects: usize, max_split: usize) {
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
        split.len() <= max_split,
        "objects with more than one final track id: {split:?} (all: {ids:?})"
    );
}

#[test]
fn calm_baseline_tracks_and_geolocation_error() {
    // (The heartbeat is checked in the ONNX run below: with the replay detector an optimised
    // build plays these 12 s in less than the heartbeat's 1 s period.)
    let o = run_loopback(&Spec {
        scenario: Scenario::new("calm_baseline", 12.0).size(640, 360),
        detector: Det::Replay,
        realtime: false,
        gimbal_report: GimbalReport::AsFlagged,
    });
    o.assert_success();
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
        scenario: Scenario::new("calm_baseline", 10.0),
        // tract: the backend that needs nothing installed, `mgmot run`'s default.
        detector: Det::Onnx(BackendKind::Tract),
        realtime: true,
        gimbal_report: GimbalReport::AsFlagged,
    });
    o.assert_success();
    let heartbeat = o.messages.iter().any(|s| {
        s.header.component_id == 191
            && matches!(&s.msg, MavMessage::HEARTBEAT(hb) if hb.mavtype == MavType::MAV_TYPE_ONBOARD_CONTROLLER)
    });
    assert!(
        heartbeat,
        "no HEARTBEAT from mgmot among {} messages",
        o.messages.len()
    );
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
        scenario: Scenario::new("gimbal_swings", 20.0),
        detector: Det::Onnx(BackendKind::OnnxRuntime),
        realtime: true,
        gimbal_report: GimbalReport::AsFlagged,
    });
    // Known misses: after a swing, an object sometimes comes back under a new id that
    // long-term ReID does not merge. Which object, and whether it happens, depends on which
    // frames the real-time loop drops. In 9 runs on 2026-12-01 (a fresh-clone CI run and 8
    // local ones, the same build), 2 split two objects each (truth ids 2 and 7; 4 and 6), 4
    // split none and 3 passed with at most one (their ids were not printed). Earlier sessions
    // saw truth id 2 alone in about one run in three. This is open, with the identity work of
    // the "long-gap identity" issue. Until then at most two of the seven objects may split;
    // the rest must hold.
    assert_ids_survive(&o, 3, 2);
}

/// The gimbal pans away from the swimmers and back (they are out of view for about 18 s), the
/// real detector on rendered 1280x720 frames: long-term re-identification gives them their old
/// ids again.
#[test]
fn ids_survive_leave_and_return() {
    let o = run_loopback(&Spec {
        scenario: Scenario::new("leave_and_return", 32.0),
        detector: Det::Onnx(BackendKind::OnnxRuntime),
        realtime: true,
        gimbal_report: GimbalReport::AsFlagged,
    });
    assert_ids_survive(&o, 3, 0);
}

// The telemetry dropout (STATUSTEXT once each way, image-only tracks with the same ids during
// the gap, geolocated again after it) is tested in real time in tests/runtime_link.rs:
// telemetry loss is a matter of wall-clock time, which lockstep does not keep.

#[test]
fn sigterm_stops_cleanly() {
    let scenario = Scenario::new("calm_baseline", 60.0).size(320, 180);
    let dir = TestDir::new();
    // No detections: this test is about stopping.
    dir.empty_detections();
    let mgmot_port = free_udp_port();
    let config = write_config(
        &dir,
        mgmot_port,
        &Spec {
            scenario: scenario.clone(),
            detector: Det::Replay,
            realtime: false,
            gimbal_report: GimbalReport::AsFlagged,
        },
    );
    let tap = Relay::start(mgmot_port);
    let sim = scenario
        .run(false, tap.listen_port, &dir.join("frames.sock"))
        .spawn();
    let stats = dir.join("stats.json");
    let mut mgmot = mgmot_run(&config, Some(&stats)).spawn_logged(dir.join("mgmot.log"));
    std::thread::sleep(Duration::from_secs(3));
    let status = mgmot.stop(Duration::from_secs(20));
    drop(sim);
    let messages = tap.finish();
    assert!(status.success(), "exit status after SIGTERM: {status:?}");
    assert!(messages
        .iter()
        .any(|s| matches!(s.msg, MavMessage::HEARTBEAT(_))));
    // The stats are written on a signalled stop too.
    let stats: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(stats).unwrap()).unwrap();
    assert!(stats["frames_captured"].as_u64().is_some(), "{stats}");
}

/// ArduCopter's habits (the `ardupilot_servo` scenario; issue "On a real autopilot", mismatches
/// 2-6): no stream until asked for, MOUNT_ORIENTATION refused, a reboot at 14 s that forgets
/// the streams and restarts the clock, a ground station answering every TIMESYNC request with
/// its own clock, and a servo gimbal reporting body-frame angles while the drone leans in
/// fast flight and turns. With `telemetry.gimbal_report = "servo_body_frame"` mgmot geolocates
/// before and after the reboot within the calm baseline's error; read as flagged, the same
/// flight is metres off. In real time: the link's stream requests, reboot detection and
/// silence are a matter of wall-clock time, which lockstep does not keep.
#[test]
fn ardupilot_habits_servo_gimbal_reboot_and_gcs_timesync() {
    let run = |gimbal_report| {
        run_loopback(&Spec {
            scenario: Scenario::new("ardupilot_servo", 36.0).size(640, 360),
            detector: Det::Replay,
            realtime: true,
            gimbal_report,
        })
    };
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v.get(v.len() / 2).copied().unwrap_or(f64::INFINITY)
    };
    let body = run(GimbalReport::ServoBodyFrame);
    body.assert_success();
    let geolocated: Vec<i64> = body
        .tracks()
        .filter(|t| geo_valid(t))
        .map(time_ms)
        .collect();
    let reboot_ms = (REBOOT_S * 1000.0) as i64;
    let before = geolocated.iter().filter(|&&t| t < reboot_ms).count();
    let after = geolocated
        .iter()
        .filter(|&&t| t > reboot_ms + 3_000)
        .count();
    assert!(
        before >= 8 && after >= 8,
        "geolocated tracks before / after the reboot: {before} / {after}; mgmot said: {}",
        body.stderr
    );
    let mut errors = geolocation_errors(&body, true);
    errors.sort_by(f64::total_cmp);
    // The tail is the turns (60 deg/s at 12 m/s, the gimbal's report interpolated between
    // 50 Hz samples) and the first frames after the reboot.
    let p95 = errors[(errors.len() * 95 / 100).min(errors.len() - 1)];
    let m_body = errors[errors.len() / 2];
    assert!(
        m_body < 1.0 && p95 < 6.0,
        "median {m_body:.2} m, p95 {p95:.2} m; errors {errors:?}"
    );
    // Issue 39, item 1: after the reboot the tracker's clock crawled at 1 ms a frame, and the
    // velocities came out tens of times too fast. They must be as good after it as before.
    let (before, after) = velocity_errors(&body, reboot_ms);
    let (m_before, m_after) = (median(before.clone()), median(after.clone()));
    eprintln!(
        "velocity error, median: before the reboot {m_before:.2} m/s ({} messages), after {m_after:.2} m/s ({})",
        before.len(),
        after.len()
    );
    assert!(
        after.len() >= 8 && m_after <= (1.5 * m_before).max(m_before + 0.3),
        "velocity error median after the reboot {m_after:.2} m/s vs {m_before:.2} m/s before; after: {after:?}"
    );
    // Tracks are geolocated again soon after the autopilot speaks again: the simulated
    // ArduCopter is silent for 3 s after the reboot and has forgotten its streams, so this
    // includes asking for them again, one at a time (measured: 2.8 s).
    let first_after = geolocated
        .iter()
        .filter(|&&t| t > reboot_ms)
        .min()
        .copied()
        .unwrap_or(i64::MAX);
    let speaks_again_ms = reboot_ms + 3_000;
    eprintln!(
        "first geolocated track {} ms after the autopilot spoke again",
        first_after - speaks_again_ms
    );
    assert!(
        first_after - speaks_again_ms <= 3_500,
        "first geolocated track {} ms after the autopilot spoke again",
        first_after - speaks_again_ms
    );
    let flagged = run(GimbalReport::AsFlagged);
    flagged.assert_success();
    let m_flagged = median(geolocation_errors(&flagged, true));
    assert!(
        m_flagged > 2.0 * m_body && m_flagged > 1.0,
        "median error read as flagged {m_flagged:.2} m vs servo body frame {m_body:.2} m"
    );
    eprintln!(
        "servo body frame: median {m_body:.2} m, p95 {p95:.2} m, {} geolocated; as flagged: median {m_flagged:.2} m",
        errors.len()
    );
}
