//! `mgmot ground` end to end: two `mgmot-sim` drones of the `two_drones` scenario (one world,
//! system ids 1 and 2, overlapping patterns), each with its own `mgmot run`, their MAVLink
//! copied to one `mgmot ground` (as mavlink-router copies everything to a ground station).
//! The fused picture is scored against the simulator's truth: fused ids per true object
//! (every object both drones saw) and the fused position error against each drone's own. The
//! live map is opened in headless Chromium, the fused CoT checked against the schema, and
//! the recording opened by `mgmot review`.
//!
//! `MGMOT_GROUND_SEED=N` flies another seed (the validation seeds of scripts/bench_ground.sh).

use crate::common;

use common::{
    free_tcp_port, free_udp_port, mgmot, mgmot_run, read_truth, require_python, run_config, Relay,
    Scenario, Sent, TestDir, Truth, M_PER_DEG,
};
use mgmot::config::FramesConfig;
use mgmot::mavlink::dialect::{MavMessage, MgmotTrackFlags, MgmotTrackState};
use mgmot_core::fuse::{
    match_sample, score_picture, FusedScore, PictureSample, ScoreParams, TruthObject,
};
use nalgebra::Vector2;
use std::collections::{BTreeMap, BTreeSet};
use std::io::Read;
use std::net::TcpListener;
use std::process::Command;
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// `two_drones`' start time (the simulator's default `origin.start_unix_s`): its SYSTEM_TIME,
/// hence the ground picture's clock, is this plus the scenario time.
const START_UNIX_S: f64 = 1_717_243_200.0;
const ORIGIN: (f64, f64) = (54.1790, 7.8890);

/// North, east (m) of a position from the scenario's origin (flat: the area is 300 m).
fn ne(lat: f64, lon: f64) -> Vector2<f64> {
    Vector2::new(
        (lat - ORIGIN.0) * M_PER_DEG,
        (lon - ORIGIN.1) * M_PER_DEG * ORIGIN.0.to_radians().cos(),
    )
}

fn class_id(name: &str) -> u32 {
    ["object", "swimmer", "boat", "jetski", "lifebuoy", "buoy"]
        .iter()
        .position(|c| *c == name)
        .map_or(0, |i| i as u32)
}

/// The world's truth, object by object: each drone's `world.csv` lists the objects in its
/// view, frame by frame; together they say where each object was while either drone saw it.
struct WorldTruth {
    /// Object id -> sim time (ms) -> its row.
    objects: BTreeMap<u64, BTreeMap<i64, TruthRow>>,
}

/// An object in one frame's truth: class id, position north/east (m), velocity (m/s).
type TruthRow = (u32, Vector2<f64>, Vector2<f64>);

/// How far (ms) from a row the truth of an object is carried with its velocity: the picture
/// keeps an object that just left both views, and the truth must too.
const TRUTH_CARRY_MS: i64 = 5_000;

fn world_truth(per_drone: &[Vec<Truth>]) -> WorldTruth {
    let mut objects: BTreeMap<u64, BTreeMap<i64, _>> = BTreeMap::new();
    for t in per_drone.iter().flatten() {
        objects.entry(t.id).or_default().insert(
            t.t_ms,
            (
                class_id(&t.class),
                ne(t.lat, t.lon),
                Vector2::new(t.vel_ne.0, t.vel_ne.1),
            ),
        );
    }
    WorldTruth { objects }
}

/// Where every object was at sim time `t_ms`: its nearest row within [`TRUTH_CARRY_MS`],
/// carried to `t_ms` with its velocity; with `only`, the others do not count (they are still
/// matched, so their tracks are not taken for a neighbour's). `None` when no object is near
/// that time.
fn truth_at(w: &WorldTruth, t_ms: i64, only: Option<&BTreeSet<u64>>) -> Option<Vec<TruthObject>> {
    let objects: Vec<TruthObject> = w
        .objects
        .iter()
        .filter_map(|(id, rows)| {
            let before = rows.range(..=t_ms).next_back();
            let after = rows.range(t_ms..).next();
            let (at, (class_id, pos, vel)) = [before, after]
                .into_iter()
                .flatten()
                .min_by_key(|(k, _)| (**k - t_ms).abs())?;
            let dt_ms = t_ms - at;
            (dt_ms.abs() <= TRUTH_CARRY_MS).then(|| TruthObject {
                id: *id,
                class_id: *class_id,
                pos_ne_m: pos + vel * (dt_ms as f64 / 1000.0),
                counts: only.is_none_or(|s| s.contains(id)),
            })
        })
        .collect();
    (!objects.is_empty()).then_some(objects)
}

/// One drone's picture: its tracked, geolocated, settled MGMOT_TRACKs grouped by frame.
fn drone_samples(
    sent: &[Sent],
    by: &WorldTruth,
    only: Option<&BTreeSet<u64>>,
) -> Vec<(i64, PictureSample)> {
    let mut frames: BTreeMap<u64, Vec<(u64, u32, Vector2<f64>)>> = BTreeMap::new();
    for s in sent {
        let MavMessage::MGMOT_TRACK(t) = &s.msg else {
            continue;
        };
        let usable = t
            .flags
            .contains(MgmotTrackFlags::MGMOT_TRACK_FLAGS_GEO_VALID)
            && !t
                .flags
                .contains(MgmotTrackFlags::MGMOT_TRACK_FLAGS_PROVISIONAL)
            && t.state == MgmotTrackState::MGMOT_TRACK_STATE_TRACKED;
        if usable {
            frames.entry(t.time_usec).or_default().push((
                u64::from(t.track_id),
                t.object_class as u32,
                ne(f64::from(t.lat) / 1e7, f64::from(t.lon) / 1e7),
            ));
        }
    }
    frames
        .into_iter()
        .filter_map(|(time_usec, tracks)| {
            let t_ms = common::track_time_ms(time_usec);
            let truth = truth_at(by, t_ms, only)?;
            Some((t_ms, PictureSample { tracks, truth }))
        })
        .collect()
}

/// The fused picture's samples from the recording: its tracked fused tracks at each update.
fn fused_samples(
    lines: &[serde_json::Value],
    by: &WorldTruth,
    only: &BTreeSet<u64>,
) -> Vec<(i64, PictureSample)> {
    lines
        .iter()
        .filter_map(|p| {
            let unix_ms = p["properties"]["time_unix_ms"].as_i64()?;
            let t_ms = unix_ms - (START_UNIX_S * 1000.0) as i64;
            let tracks = p["features"]
                .as_array()?
                .iter()
                .filter(|f| {
                    f["properties"]["kind"] == "track" && f["properties"]["state"] == "tracked"
                })
                .filter_map(|f| {
                    let c = f["geometry"]["coordinates"].as_array()?;
                    Some((
                        f["properties"]["fused_id"].as_u64()?,
                        f["properties"]["class_id"].as_u64()? as u32,
                        ne(c[1].as_f64()?, c[0].as_f64()?),
                    ))
                })
                .collect();
            Some((
                t_ms,
                PictureSample {
                    tracks,
                    truth: truth_at(by, t_ms, Some(only))?,
                },
            ))
        })
        .collect()
}

/// The objects a drone's picture matched at least once.
fn seen_objects(samples: &[(i64, PictureSample)]) -> BTreeSet<u64> {
    samples
        .iter()
        .flat_map(|(_, s)| match_sample(s, ScoreParams::default()))
        .map(|(_, object, _)| object)
        .collect()
}

/// A TCP server that keeps every byte of every connection (the fused CoT stream).
fn cot_server() -> (u16, Arc<Mutex<Vec<u8>>>) {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let port = listener.local_addr().unwrap().port();
    let got = Arc::new(Mutex::new(Vec::new()));
    let sink = got.clone();
    std::thread::spawn(move || {
        for stream in listener.incoming() {
            let Ok(mut stream) = stream else { return };
            let sink = sink.clone();
            std::thread::spawn(move || {
                let mut buf = [0u8; 65536];
                while let Ok(n) = stream.read(&mut buf) {
                    if n == 0 {
                        return;
                    }
                    sink.lock().unwrap().extend_from_slice(&buf[..n]);
                }
            });
        }
    });
    (port, got)
}

/// Untimed samples.
fn untimed(samples: Vec<(i64, PictureSample)>) -> Vec<PictureSample> {
    samples.into_iter().map(|(_, s)| s).collect()
}

/// Each object's matches over time: object -> (sim time ms, error m).
fn matches_by_object(samples: &[(i64, PictureSample)]) -> BTreeMap<u64, BTreeMap<i64, f64>> {
    let mut by: BTreeMap<u64, BTreeMap<i64, f64>> = BTreeMap::new();
    for (t, s) in samples {
        for (_, object, d) in match_sample(s, ScoreParams::default()) {
            if s.truth.iter().any(|o| o.id == object && o.counts) {
                by.entry(object).or_default().insert(*t, d);
            }
        }
    }
    by
}

/// The error nearest `t_ms` (within 300 ms: the drones report at 2 Hz) of `object` in `by`.
fn error_near(by: &BTreeMap<u64, BTreeMap<i64, f64>>, object: u64, t_ms: i64) -> Option<f64> {
    by.get(&object)?
        .range(t_ms - 300..=t_ms + 300)
        .min_by_key(|(t, _)| (**t - t_ms).abs())
        .map(|(_, d)| *d)
}

/// Median and 95th percentile (nearest rank).
fn median_p95(mut v: Vec<f64>) -> (f64, f64) {
    v.sort_by(f64::total_cmp);
    let q = |p: f64| v[((p * v.len() as f64).ceil() as usize).clamp(1, v.len()) - 1];
    (q(0.5), q(0.95))
}

fn print_score(name: &str, s: &FusedScore) {
    eprintln!(
        "{name}: {} objects, {:.3} ids/object (max {}, any match {:.3}), error median {:.2} m p95 {:.2} m, {} matches, {} unmatched",
        s.objects, s.ids_per_object, s.max_ids, s.ids_per_object_any, s.error_median_m, s.error_p95_m, s.matches, s.unmatched_tracks
    );
}

/// What one two-drone flight left behind.
struct Flown {
    dir: TestDir,
    stats: serde_json::Value,
    sent: Vec<Vec<Sent>>,
    record: std::path::PathBuf,
    cot_bytes: Arc<Mutex<Vec<u8>>>,
}

/// Flies both vehicles of scenario `name` for `duration_s` in real time, each with its own
/// `mgmot run`, their MAVLink copied to one `mgmot ground` (map, recording, GeoJSON file, CoT
/// to a local TCP server). With `map_check_at`, the live map is checked in headless Chromium
/// that far into the flight.
fn fly(name: &str, duration_s: f64, map_check_at: Option<Duration>) -> Flown {
    require_python("ground", &["lxml"]);
    let chromium = std::env::var("MGMOT_CHROMIUM").unwrap_or_else(|_| "chromium".into());
    if Command::new(&chromium).arg("--version").output().is_err() {
        common::missing_tool("ground", "chromium (apt install chromium)");
    }
    let seed = std::env::var("MGMOT_GROUND_SEED")
        .ok()
        .map(|s| s.parse::<u64>().expect("MGMOT_GROUND_SEED is a number"));
    let dir = TestDir::new();
    let ground_port = free_udp_port();
    let http_port = free_tcp_port();
    let (cot_port, cot_bytes) = cot_server();
    let record = dir.join("ground.jsonl");
    let mut ground = mgmot()
        .arg("ground")
        .arg("--connection")
        .arg(format!("udpin:127.0.0.1:{ground_port}"))
        .arg("--http")
        .arg(format!("127.0.0.1:{http_port}"))
        .arg("--record")
        .arg(&record)
        .arg("--geojson")
        .arg(dir.join("ground.geojson"))
        .arg("--cot")
        .arg(format!("tcp://127.0.0.1:{cot_port}"))
        .arg("--stats-json")
        .arg(dir.join("ground_stats.json"))
        .spawn_logged(dir.join("ground.log"));

    let mut relays = Vec::new();
    let mut runs = Vec::new();
    let mut sims = Vec::new();
    // Both drones fly on the simulator's clock from `origin.start_unix_s`, as real drones fly
    // on GNSS time: the two simulators must start together (within a frame or so), so
    // everything they need is made first.
    let mut pending = Vec::new();
    for k in 0..2usize {
        let scenario = Scenario::new(name, duration_s)
            .size(640, 360)
            .vehicle(k)
            .seed(seed);
        let dets = dir.join(format!("dets{k}.json"));
        scenario.detections(&dets);
        let port = free_udp_port();
        let frames = dir.join(format!("frames{k}.sock"));
        let mut c = run_config(&format!("udpin:127.0.0.1:{port}"), &frames, &dets);
        c.mavlink.system_id = k as u8 + 1;
        if let FramesConfig::Sim {
            wait_for_detector, ..
        } = &mut c.frames
        {
            *wait_for_detector = true;
        }
        let config = dir.write_config(&format!("run{k}.toml"), &c);
        let relay = Relay::start_teed(port, Some(ground_port));
        runs.push(mgmot_run(&config, None).spawn_logged(dir.join(format!("run{k}.log"))));
        let mut sim = scenario.run(true, relay.listen_port, &frames);
        sim.arg("--truth-out").arg(dir.join(format!("truth{k}")));
        pending.push(sim);
        relays.push(relay);
    }
    for mut sim in pending {
        sims.push(sim.spawn());
    }

    if let Some(at) = map_check_at {
        std::thread::sleep(at);
        let map = Command::new("python3")
            .arg(common::repo_file("scripts/ground_map_check.py"))
            .arg("--url")
            .arg(format!("http://127.0.0.1:{http_port}/"))
            .args([
                "--min-tracks",
                "1",
                "--min-drones",
                "2",
                "--min-footprints",
                "2",
                "--chromium",
                &chromium,
            ])
            .output()
            .expect("run python3");
        let map_report = String::from_utf8_lossy(&map.stdout).to_string()
            + &String::from_utf8_lossy(&map.stderr);
        assert!(
            map.status.success(),
            "the live map check failed: {map_report}"
        );
    }
    for (k, run) in runs.iter_mut().enumerate() {
        let status = run.wait_or_fail(Duration::from_secs(180));
        assert!(status.success(), "mgmot run {k} failed: {}", run.log());
    }
    for sim in &mut sims {
        let _ = sim.wait_or_fail(Duration::from_secs(30));
    }
    ground.sigterm();
    let status = ground.wait_or_fail(Duration::from_secs(20));
    assert!(status.success(), "mgmot ground failed: {}", ground.log());
    let sent: Vec<Vec<Sent>> = relays.into_iter().map(Relay::finish).collect();

    // The ground heard both drones and used their tracks.
    let stats: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("ground_stats.json")).unwrap())
            .unwrap();
    assert_eq!(stats["drones"], 2, "{stats}");
    assert!(
        stats["ingest"]["track_reports_used"].as_u64().unwrap() > 100,
        "{stats}"
    );
    // Each drone's mgmot run sent CAMERA_FOV_STATUS at 1 Hz, and each made a footprint.
    let footprints = stats["ingest"]["footprints"].as_u64().unwrap();
    assert!(
        footprints as f64 >= 2.0 * duration_s * 0.8,
        "{footprints} footprints in {duration_s} s: {stats}"
    );
    assert_eq!(stats["ingest"]["bad_footprints"], 0, "{stats}");

    Flown {
        dir,
        stats,
        sent,
        record,
        cot_bytes,
    }
}

/// Scores a flight: prints the fused picture's and each drone's scores on the objects both
/// drones saw and checks one fused id per object; returns the errors at the moments both drones reported an object (fused, drone 1,
/// drone 2).
struct Scores {
    paired: [Vec<f64>; 3],
    pictures: Vec<serde_json::Value>,
}

fn score(f: &Flown) -> Scores {
    let (dir, sent, record) = (&f.dir, &f.sent, &f.record);
    // Each drone's MGMOT_TRACK as sent, beside the ground's recording (a kept test folder,
    // `MGMOT_KEEP_TEST_DIRS=1`, then holds what each drone said).
    for (k, messages) in sent.iter().enumerate() {
        let lines: Vec<String> = messages
            .iter()
            .filter_map(|s| match &s.msg {
                MavMessage::MGMOT_TRACK(t) => Some(
                    serde_json::json!({
                        "time_usec": t.time_usec,
                        "track_id": t.track_id,
                        "class": t.object_class as u32,
                        "state": t.state as u32,
                        "flags": t.flags.bits(),
                        "lat": t.lat,
                        "lon": t.lon,
                    })
                    .to_string(),
                ),
                _ => None,
            })
            .collect();
        dir.write(format!("sent{k}.jsonl"), lines.join("\n"));
    }
    // Scoring against the truth.
    let by = world_truth(&[
        read_truth(&dir.join("truth0/world.csv")),
        read_truth(&dir.join("truth1/world.csv")),
    ]);
    let drones: Vec<Vec<(i64, PictureSample)>> =
        sent.iter().map(|s| drone_samples(s, &by, None)).collect();
    let seen: Vec<BTreeSet<u64>> = drones.iter().map(|d| seen_objects(d)).collect();
    let both: BTreeSet<u64> = seen[0].intersection(&seen[1]).copied().collect();
    eprintln!(
        "objects seen: drone 1 {}, drone 2 {}, both {}",
        seen[0].len(),
        seen[1].len(),
        both.len()
    );
    assert!(
        both.len() >= 3,
        "the drones saw too few objects in common: {both:?}"
    );
    let (_, pictures) = mgmot::ground::record::read(record).unwrap();
    assert!(pictures.len() > 60, "{} updates recorded", pictures.len());
    let fused_timed = fused_samples(&pictures, &by, &both);
    let drones_both: Vec<Vec<(i64, PictureSample)>> = sent
        .iter()
        .map(|s| drone_samples(s, &by, Some(&both)))
        .collect();
    let fused = score_picture(&untimed(fused_timed.clone()), ScoreParams::default());
    let single: Vec<FusedScore> = drones_both
        .iter()
        .map(|d| score_picture(&untimed(d.clone()), ScoreParams::default()))
        .collect();
    print_score("fused", &fused);
    print_score("drone 1", &single[0]);
    print_score("drone 2", &single[1]);
    // Position error where fusion has something to fuse: the moments both drones report the
    // object (within 300 ms of a picture update), fused against each drone at those moments.
    let per_drone: Vec<_> = drones_both.iter().map(|d| matches_by_object(d)).collect();
    let mut paired: [Vec<f64>; 3] = Default::default();
    for (t, s) in &fused_timed {
        for (_, object, d) in match_sample(s, ScoreParams::default()) {
            if !s.truth.iter().any(|o| o.id == object && o.counts) {
                continue;
            }
            if let (Some(e1), Some(e2)) = (
                error_near(&per_drone[0], object, *t),
                error_near(&per_drone[1], object, *t),
            ) {
                paired[0].push(d);
                paired[1].push(e1);
                paired[2].push(e2);
            }
        }
    }
    // The errors are printed before the ids are checked.
    if !paired[0].is_empty() {
        let [fu, d1, d2] = paired.clone().map(median_p95);
        eprintln!(
            "both drones at once ({} samples): fused median {:.2} p95 {:.2} m; drone 1 {:.2} / {:.2}; drone 2 {:.2} / {:.2}",
            paired[0].len(),
            fu.0, fu.1, d1.0, d1.1, d2.0, d2.1
        );
    }
    assert_eq!(
        fused.objects,
        both.len(),
        "every object seen by both is in the picture"
    );
    assert!(
        fused.ids_per_object <= 1.1,
        "fused ids per object {}",
        fused.ids_per_object
    );
    Scores { paired, pictures }
}

/// Distance (m) from `p` to polygon `ring` (0 inside).
fn outside_by(p: Vector2<f64>, ring: &[Vector2<f64>]) -> f64 {
    let n = ring.len();
    let mut inside = false;
    let mut nearest = f64::MAX;
    for i in 0..n {
        let (a, b) = (ring[i], ring[(i + 1) % n]);
        if (a.y > p.y) != (b.y > p.y) && p.x < (b.x - a.x) * (p.y - a.y) / (b.y - a.y) + a.x {
            inside = !inside;
        }
        let ab = b - a;
        let t = ((p - a).dot(&ab) / ab.norm_squared().max(1e-12)).clamp(0.0, 1.0);
        nearest = nearest.min((a + ab * t - p).norm());
    }
    if inside {
        0.0
    } else {
        nearest
    }
}

/// The drones' camera footprints on the map (from their CAMERA_FOV_STATUS) hold what they
/// see: in each recorded picture, a fused track seen within the last second, that a drone's
/// track holds as seen, lies in that drone's footprint, give or take 15 m: what the drone flew
/// since the footprint (1 Hz at 6.5 m/s) and since the sighting, and the geolocation error.
/// A footprint in the wrong place (a quaternion convention mixed up) fails this.
fn check_footprints(pictures: &[serde_json::Value]) {
    let (mut pairs, mut near) = (0usize, 0usize);
    for p in pictures {
        let features = p["features"].as_array().unwrap();
        let rings: BTreeMap<u64, Vec<Vector2<f64>>> = features
            .iter()
            .filter(|f| f["properties"]["kind"] == "footprint")
            .filter_map(|f| {
                let ring = f["geometry"]["coordinates"][0].as_array()?;
                Some((
                    f["properties"]["system_id"].as_u64()?,
                    ring.iter()
                        .map(|c| ne(c[1].as_f64().unwrap(), c[0].as_f64().unwrap()))
                        .collect(),
                ))
            })
            .collect();
        let now_ms = p["properties"]["time_unix_ms"].as_i64().unwrap();
        let recent = |f: &&serde_json::Value| {
            f["properties"]["last_seen_unix_ms"]
                .as_i64()
                .is_some_and(|seen| now_ms - seen <= 1000)
        };
        for f in features
            .iter()
            .filter(|f| f["properties"]["kind"] == "track")
            .filter(recent)
        {
            let c = f["geometry"]["coordinates"].as_array().unwrap();
            let at = ne(c[1].as_f64().unwrap(), c[0].as_f64().unwrap());
            for m in f["properties"]["members"].as_array().unwrap() {
                if m["state"] != "tracked" {
                    continue;
                }
                let Some(ring) = rings.get(&m["system_id"].as_u64().unwrap()) else {
                    continue;
                };
                pairs += 1;
                if outside_by(at, ring) <= 15.0 {
                    near += 1;
                }
            }
        }
    }
    eprintln!("footprints: {near} of {pairs} tracks seen in the last second in (or within 15 m of) their drone's footprint");
    assert!(pairs >= 50, "only {pairs} seen tracks with a footprint");
    assert!(
        near as f64 >= 0.95 * pairs as f64,
        "{} of {pairs} seen tracks lie outside their drone's footprint",
        pairs - near
    );
}

/// `two_drones`: the drones pass over the same water at different times. One fused id per
/// object across both drones; the live map, the fused CoT and the review of the recording.
#[test]
fn two_drones_passing_at_different_times_keep_one_fused_id_per_object() {
    let f = fly("two_drones", 180.0, Some(Duration::from_secs(120)));
    let Scores { pictures, .. } = score(&f);
    check_footprints(&pictures);
    let (dir, stats, record) = (&f.dir, &f.stats, &f.record);
    let cot_bytes = &f.cot_bytes;
    // The fused CoT stream passes the schema; every fused id of the picture was sent.
    let stream = String::from_utf8(cot_bytes.lock().unwrap().clone()).unwrap();
    let events: Vec<String> = stream
        .split("<?xml")
        .filter(|e| !e.trim().is_empty())
        .map(|e| format!("<?xml{e}"))
        .collect();
    crate::runtime_cot::schema_check(dir, "ground_cot.xml", &events);
    let last = pictures.last().unwrap();
    for f in last["features"].as_array().unwrap() {
        if f["properties"]["kind"] == "track" {
            let uid_tail = format!(".{}\"", f["properties"]["fused_id"]);
            assert!(
                events
                    .iter()
                    .any(|e| e.contains("how=\"m-f\"") && e.contains(&uid_tail)),
                "fused id {} never sent as CoT",
                f["properties"]["fused_id"]
            );
        }
    }

    // `mgmot review` opens the recording: one row per fused id, their paths as GeoJSON.
    let report = dir.join("review/ground.html");
    let out = mgmot()
        .arg("review")
        .arg(record)
        .arg("--out")
        .arg(&report)
        .ok();
    let said = String::from_utf8_lossy(&out.stdout).to_string();
    let ids = stats["fused_ids"].as_u64().unwrap();
    let retired = stats["retired"].as_u64().unwrap();
    assert!(said.contains("fused ids"), "{said}");
    let html = std::fs::read_to_string(&report).unwrap();
    let rows = html.matches("<tr><td>#").count() as u64;
    // Every id given is a row, except those merged away before any update showed them.
    assert!(
        rows > 0 && rows <= ids && rows + retired >= ids,
        "{rows} rows, {ids} ids, {retired} retired"
    );
    let paths: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.join("review/ground_tracks.geojson")).unwrap(),
    )
    .unwrap();
    assert!(!paths["features"].as_array().unwrap().is_empty());
}

/// `two_drones_abreast`: both drones see the same objects at the same moments. One fused id
/// per object; at those moments the fused position lies within the drones' own errors (a
/// weighted mean of the two is never further from the truth than the worse of them, but for
/// the prediction to the picture's time). Whether it beats the better drone (the issue's
/// target) is printed, not asserted, as 20-50 moments make a noisy median: measured, it does
/// on seeds 31 and 202 (docs/ground.md).
#[test]
fn two_drones_abreast_fuse_within_the_drones_errors() {
    let f = fly("two_drones_abreast", 90.0, None);
    let Scores { paired, pictures } = score(&f);
    let n = paired[0].len();
    assert!(n >= 20, "only {n} moments with both drones on one object");
    let within = (0..n)
        .filter(|&i| paired[0][i] <= paired[1][i].max(paired[2][i]) + 0.25)
        .count();
    eprintln!("fused within the worse drone's error + 0.25 m at {within} of {n} moments");
    check_footprints(&pictures);
    assert!(
        within as f64 >= 0.9 * n as f64,
        "the fused position is outside the drones' errors at {} of {n} moments",
        n - within
    );
}
