//! `mgmot review` on flight folders written here through the record's own types (a drifting
//! swimmer, a boat lost and re-identified by a ReID merge, keyframes, a tlog with TIMESYNC
//! and a telemetry gap), run as the real binary; the report is opened in Debian's headless
//! Chromium, which must be installed (`scripts/test.sh` installs it): its script must draw
//! the map and the timeline without an error. Also: the GeoJSON and KML beside it, a flight
//! cut short, an empty flight, a folder that is no flight, and the error against a truth.

use mavlink_core::{MavHeader, MavlinkVersion};
use mgmot::geo::attitude::camera_from_heading_pitch_deg;
use mgmot::geo::{Geodetic, LocalTangentFrame};
use mgmot::mavlink::dialect::{MavMessage, ATTITUDE_DATA, HEARTBEAT_DATA, TIMESYNC_DATA};
use mgmot::record::format::{
    DetectorIdentity, EndRecord, FlightInfo, FrameRecord, GeoRecord, PoseRecord, Record,
    TrackRecord, FORMAT, VERSION,
};
use mgmot::record::tlog::write_entry;
use mgmot::track::{BBox, Detection, ExchangeEvent, MergeEvent, TrackOutput, TrackState};
use nalgebra::Vector3;
use serde_json::Value;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use crate::common::{mgmot, TestDir};

const START_US: u64 = 1_796_162_170_000_000;
const FRAMES: u64 = 60;
const FPS: f64 = 10.0;
const LAT0: f64 = 47.6721;
const LON0: f64 = 9.2679;
const WATER_AMSL_M: f64 = 395.0;

fn water() -> LocalTangentFrame {
    LocalTangentFrame::new(Geodetic::new(LAT0, LON0, WATER_AMSL_M).unwrap())
}

/// A geolocated track output at local north/east `ne` (m) drifting at `vel` (m/s).
fn track(
    id: u64,
    class_id: u32,
    ne: [f64; 2],
    vel: [f64; 2],
    det: usize,
) -> (TrackRecord, Detection) {
    let g = water().to_geodetic(&Vector3::new(ne[0], ne[1], 0.0));
    let bbox = BBox {
        x: 600.0 + ne[1] * 10.0,
        y: 300.0 - ne[0] * 5.0,
        w: 20.0,
        h: 16.0,
    };
    (
        TrackRecord {
            track: TrackOutput {
                id,
                bbox,
                score: 0.8,
                class_id,
                state: TrackState::Confirmed,
                world: None,
                detection_index: Some(det),
                provisional: false,
            },
            geo: Some(GeoRecord {
                lat_deg: g.lat_deg,
                lon_deg: g.lon_deg,
                alt_m: g.alt_m,
                vel_n_mps: vel[0],
                vel_e_mps: vel[1],
                h_std_m: 1.5,
            }),
        },
        Detection {
            bbox,
            score: 0.8,
            class_id,
            world: None,
            appearance: None,
        },
    )
}

/// The swimmer (track 1): drifts east at 0.3 m/s from 40 m north; absent in frames 25-29.
fn swimmer_ne(frame: u64) -> [f64; 2] {
    [40.0, 0.3 * frame as f64 / FPS]
}

/// The boat: track 2 in frames 0-19, lost, back in frame 40 as track 3, merged into 2 in
/// frame 45; moves north-east at 2 m/s from (60, -20).
fn boat_ne(frame: u64) -> [f64; 2] {
    let t = frame as f64 / FPS;
    [60.0 + 1.4 * t, -20.0 + 1.4 * t]
}

fn frame_record(n: u64) -> FrameRecord {
    let t_us = START_US + n * 100_000;
    let q = camera_from_heading_pitch_deg(0.0, 40.0, 0.0);
    let mut tracks = Vec::new();
    let mut detections = Vec::new();
    let mut push = |(r, d): (TrackRecord, Detection)| {
        tracks.push(r);
        detections.push(d);
    };
    if !(25..30).contains(&n) {
        push(track(1, 1, swimmer_ne(n), [0.0, 0.3], 0));
    }
    let boat_id = match n {
        0..=19 => Some(2),
        40..=44 => Some(3),
        45.. => Some(2),
        _ => None,
    };
    if let Some(id) = boat_id {
        let i = usize::from(!(25..30).contains(&n));
        push(track(id, 2, boat_ne(n), [1.4, 1.4], i));
    }
    // A detection no track reported.
    detections.push(Detection {
        bbox: BBox {
            x: 100.0,
            y: 500.0,
            w: 12.0,
            h: 12.0,
        },
        score: 0.3,
        class_id: 1,
        world: None,
        appearance: None,
    });
    FrameRecord {
        frame: n,
        time_s: 120.0 + n as f64 / FPS,
        autopilot_time_us: Some(120_000_000 + n * 100_000),
        captured_unix_us: Some(t_us),
        processed_unix_us: t_us + 80_000,
        width_px: 1280,
        height_px: 720,
        pose: Some(PoseRecord {
            lat_deg: LAT0 + n as f64 * 1e-6,
            lon_deg: LON0,
            alt_m: WATER_AMSL_M + 30.0,
            height_above_sea_m: 30.0,
            attitude_wxyz: [q.w, q.i, q.j, q.k],
            horizontal_accuracy_m: None,
        }),
        no_pose: None,
        water_amsl_m: Some(WATER_AMSL_M),
        detections,
        tracks,
        merges: if n == 45 {
            vec![MergeEvent {
                new_id: 3,
                merged_into_id: 2,
                frame_index: n,
            }]
        } else {
            Vec::new()
        },
        // A contact repair between the two (a display fixture: they never touch here).
        exchanges: if n == 15 {
            vec![ExchangeEvent {
                id: 1,
                other_id: 2,
                since_frame_index: 10,
                frame_index: n,
            }]
        } else {
            Vec::new()
        },
        frames_dropped: n / 4,
        keyframe: (n % 30 == 0).then(|| format!("{n:08}.jpg")),
    }
}

fn packet(component_id: u8, message: &MavMessage) -> Vec<u8> {
    let mut buf = Vec::new();
    let header = MavHeader {
        system_id: 1,
        component_id,
        sequence: 0,
    };
    mavlink_core::write_versioned_msg(&mut buf, MavlinkVersion::V2, header, message).unwrap();
    buf
}

/// The tlog: autopilot HEARTBEAT at 1 Hz and ATTITUDE at 10 Hz, silent from 2.0 to 3.5 s;
/// mgmot's TIMESYNC every second, answered 4 ms later by an autopilot clock 1000 s ahead.
fn tlog() -> Vec<u8> {
    let mut out = Vec::new();
    for i in 0..60u64 {
        let us = START_US + i * 100_000;
        if (20..35).contains(&i) {
            continue;
        }
        let attitude = MavMessage::ATTITUDE(ATTITUDE_DATA::default());
        write_entry(&mut out, us, &packet(1, &attitude)).unwrap();
        if i % 10 == 0 {
            let hb = MavMessage::HEARTBEAT(HEARTBEAT_DATA::default());
            write_entry(&mut out, us + 10, &packet(1, &hb)).unwrap();
            let ts1 = 5_000_000_000 + (i as i64) * 100_000_000;
            let request = MavMessage::TIMESYNC(TIMESYNC_DATA {
                tc1: 0,
                ts1,
                ..Default::default()
            });
            write_entry(&mut out, us + 20, &packet(191, &request)).unwrap();
            let answer = MavMessage::TIMESYNC(TIMESYNC_DATA {
                tc1: ts1 + 1_000_000_000_000 + 2_000_000,
                ts1,
                ..Default::default()
            });
            write_entry(&mut out, us + 4_020, &packet(1, &answer)).unwrap();
        }
    }
    out
}

const CONFIG: &str = r#"[mavlink]
connection = "udpin:127.0.0.1:14550"
[frames]
source = "sim"
socket = "/tmp/frames.sock"
[camera]
hfov_deg = 70.0
[detector]
kind = "onnx"
model = "model.onnx"
"#;

/// A flight folder; `frames`: how many frame records, `end`: with the end record.
fn write_flight(dir: &Path, frames: u64, end: bool) -> PathBuf {
    let flight = dir.join("20261201T213821Z-sys1");
    std::fs::create_dir_all(flight.join("keyframes")).unwrap();
    let info = FlightInfo {
        format: FORMAT.to_owned(),
        version: VERSION,
        mgmot_version: "test".to_owned(),
        started_utc: "2026-12-01T21:38:21Z".to_owned(),
        started_unix_us: START_US,
        system_id: 1,
        component_id: 191,
        detector: DetectorIdentity {
            kind: "onnx".to_owned(),
            file: "model.onnx".to_owned(),
            sha256: "00".repeat(32),
            bytes: 1,
        },
        tile_detector: None,
        config_file: "config.toml".to_owned(),
    };
    std::fs::write(
        flight.join("flight.json"),
        serde_json::to_string_pretty(&info).unwrap(),
    )
    .unwrap();
    std::fs::write(flight.join("config.toml"), CONFIG).unwrap();
    let mut ndjson = Vec::new();
    for n in 0..frames {
        let f = frame_record(n);
        if let Some(k) = &f.keyframe {
            let img = image::RgbImage::from_pixel(64, 36, image::Rgb([20, 60, 90]));
            img.save(flight.join("keyframes").join(k)).unwrap();
        }
        serde_json::to_writer(&mut ndjson, &Record::Frame(Box::new(f))).unwrap();
        ndjson.push(b'\n');
    }
    if end {
        let e = Record::End(EndRecord {
            unix_us: START_US + frames * 100_000,
            frames_written: frames,
            frames_dropped_queue: 0,
            packets_dropped_queue: 0,
            frames_lost_stopped: 0,
            keyframes: 2,
            run_stats: None,
        });
        serde_json::to_writer(&mut ndjson, &e).unwrap();
        ndjson.push(b'\n');
    }
    std::fs::write(flight.join("frames.ndjson"), ndjson).unwrap();
    std::fs::write(flight.join("flight.tlog"), tlog()).unwrap();
    flight
}

fn review(args: &[&str]) -> Output {
    mgmot().arg("review").args(args).output()
}

fn ok(out: &Output) -> String {
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "mgmot review failed: {}\n{stdout}\n{}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    stdout
}

/// The report's DOM after its script ran, and Chromium's console messages.
fn chromium_dom(report: &Path) -> (String, String) {
    let exists = Command::new("sh")
        .args(["-c", "command -v chromium"])
        .output()
        .is_ok_and(|o| o.status.success());
    assert!(
        exists,
        "chromium is not installed: tests/review.rs opens the report in Debian's headless \
         Chromium (apt-get install chromium; scripts/test.sh installs it)"
    );
    let profile = TestDir::new();
    let out = Command::new("timeout")
        .arg("90")
        .arg("chromium")
        .args([
            "--headless=new",
            "--no-sandbox",
            "--disable-gpu",
            "--no-first-run",
            "--enable-logging=stderr",
            "--v=0",
            "--virtual-time-budget=3000",
        ])
        .arg(format!("--user-data-dir={}", profile.path().display()))
        .arg("--dump-dom")
        .arg(format!("file://{}", report.display()))
        .output()
        .expect("running chromium");
    assert!(
        out.status.success(),
        "chromium failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    (
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// The part of `dom` inside the element with id `id` up to the next section.
fn inside<'a>(dom: &'a str, id: &str) -> &'a str {
    let start = dom
        .find(&format!("id=\"{id}\""))
        .unwrap_or_else(|| panic!("no #{id} in the DOM"));
    let rest = &dom[start..];
    let end = rest.find("</section>").unwrap_or(rest.len());
    &rest[..end]
}

/// What the page wrote to the console (Chromium logs it as `INFO:CONSOLE`): the page logs
/// nothing, so any line is an error (an uncaught exception, a resource refused).
fn console_errors(stderr: &str) -> Vec<&str> {
    stderr.lines().filter(|l| l.contains(":CONSOLE")).collect()
}

/// References to anything outside the file: src=/href= with a scheme other than data: or a
/// fragment, CSS url() or @import.
fn external_references(html: &str) -> Vec<String> {
    let lower = html.to_lowercase();
    let mut found = Vec::new();
    for attr in ["src=", "href=", "url(", "@import"] {
        let mut from = 0;
        while let Some(i) = lower[from..].find(attr) {
            let at = from + i + attr.len();
            let value: String = lower[at..]
                .trim_start_matches(['"', '\'', ' '])
                .chars()
                .take(12)
                .collect();
            if attr == "@import" || !(value.starts_with('#') || value.starts_with("data:")) {
                found.push(format!("{attr}{value}"));
            }
            from = at;
        }
    }
    found
}

#[test]
fn the_report_is_self_contained_and_chromium_draws_it_without_errors() {
    let tmp = TestDir::new();
    let flight = write_flight(tmp.path(), FRAMES, true);
    let report = tmp.path().join("out").join("report.html");
    let stdout = ok(&review(&[
        flight.to_str().unwrap(),
        "--out",
        report.to_str().unwrap(),
    ]));
    assert!(stdout.contains("60 frames, 2 tracks"), "{stdout}");
    assert!(stdout.contains(&report.display().to_string()), "{stdout}");
    assert!(
        stdout.contains("tracks.geojson") && stdout.contains("tracks.kml"),
        "{stdout}"
    );
    let html = std::fs::read_to_string(&report).unwrap();
    // Nothing from the network: no CDN, no fonts, no images by URL.
    let external = external_references(&html);
    assert!(external.is_empty(), "external references: {external:?}");
    for scheme in [
        "src=\"http",
        "href=\"http",
        "src='http",
        "href='http",
        "//cdn",
    ] {
        assert!(!html.contains(scheme), "{scheme} in the report");
    }
    for id in [
        "map",
        "timeline",
        "tracks",
        "health",
        "keyframes",
        "review-data",
    ] {
        assert!(html.contains(&format!("id=\"{id}\"")), "no #{id}");
    }
    // Keyframes are embedded.
    assert_eq!(html.matches("data:image/jpeg;base64,").count(), 2);
    assert!(!html.contains("did not end cleanly\", id") && html.contains("\"clean_end\":true"));

    let (dom, console) = chromium_dom(&report);
    assert!(
        dom.contains("data-rendered=\"ok\""),
        "the page's script did not finish; console:\n{console}"
    );
    assert!(!dom.contains("data-error="), "script error: {}", dom);
    let errors = console_errors(&console);
    assert!(errors.is_empty(), "console errors: {errors:?}");
    let map = inside(&dom, "map");
    assert!(map.contains("<svg"), "no map drawn");
    assert!(
        map.contains("id=\"footprint-now\"") && map.contains("<polygon"),
        "no footprint"
    );
    assert!(
        map.matches("<polyline").count() >= 5,
        "drone path and track paths"
    );
    assert!(
        map.matches("class=\"track-now\"").count() == 2,
        "a marker per track"
    );
    assert!(map.contains("N</text>"), "lat graticule labels");
    let timeline = inside(&dom, "timeline");
    assert!(timeline.contains("seg-detected"));
    assert!(
        timeline.contains("seg-coasting"),
        "the swimmer's 0.5 s absence"
    );
    assert!(timeline.contains("seg-lost"), "the boat's 2 s absence");
    assert_eq!(
        timeline.matches("class=\"merge\"").count(),
        1,
        "the ReID merge"
    );
    assert_eq!(
        timeline.matches("class=\"exchange\"").count(),
        1,
        "the contact repair"
    );
    let summary = inside(&dom, "summary");
    assert!(
        summary.contains("ids 1 and 2 swapped 1.0–1.5 s"),
        "the contact repair in the summary"
    );
    let tracks = inside(&dom, "tracks");
    assert!(tracks.contains("id=\"track-row-1\"") && tracks.contains("id=\"track-row-2\""));
    assert!(!tracks.contains("track-row-3"), "track 3 was merged into 2");
    assert!(tracks.contains("swimmer") && tracks.contains("boat"));
    assert!(tracks.contains("47°40."), "D°M.mmm' positions");
    let health = inside(&dom, "health");
    assert!(health.contains("id=\"timesync-chart\"") && health.contains("id=\"dropped-chart\""));
    assert!(health.contains("ATTITUDE") && health.contains("TIMESYNC"));
    assert!(health.contains("1 silence(s)"), "the 1.5 s telemetry gap");
    let keyframes = inside(&dom, "keyframes");
    assert_eq!(keyframes.matches("<image").count(), 2);
    assert!(
        keyframes.matches("<rect").count() >= 4,
        "boxes over the keyframes"
    );
    assert!(!dom.contains("id=\"truth\""), "no truth given");
}

#[test]
fn geojson_and_kml_hold_each_track_with_times_and_its_last_position() {
    let tmp = TestDir::new();
    let flight = write_flight(tmp.path(), FRAMES, true);
    let report = tmp.path().join("report.html");
    ok(&review(&[
        flight.to_str().unwrap(),
        "--out",
        report.to_str().unwrap(),
    ]));

    let geojson: Value =
        serde_json::from_str(&std::fs::read_to_string(tmp.path().join("tracks.geojson")).unwrap())
            .unwrap();
    assert_eq!(geojson["type"], "FeatureCollection");
    let features = geojson["features"].as_array().unwrap();
    let lines: Vec<&Value> = features
        .iter()
        .filter(|f| f["geometry"]["type"] == "LineString")
        .collect();
    let points: Vec<&Value> = features
        .iter()
        .filter(|f| f["geometry"]["type"] == "Point")
        .collect();
    assert_eq!((lines.len(), points.len()), (2, 2), "{geojson:#}");
    for f in features {
        assert_eq!(f["type"], "Feature");
        assert!(f["properties"]["track_id"].is_u64());
        assert!(f["properties"]["class"].is_string());
    }
    for l in &lines {
        let coords = l["geometry"]["coordinates"].as_array().unwrap();
        let times = l["properties"]["times"].as_array().unwrap();
        assert_eq!(coords.len(), times.len());
        for c in coords {
            let c = c.as_array().unwrap();
            assert_eq!(c.len(), 2);
            let (lon, lat) = (c[0].as_f64().unwrap(), c[1].as_f64().unwrap());
            assert!(
                (lon - LON0).abs() < 0.01 && (lat - LAT0).abs() < 0.01,
                "[lon, lat] order"
            );
        }
        let mut prev = String::new();
        for t in times {
            let t = t.as_str().unwrap();
            assert!(chrono::DateTime::parse_from_rfc3339(t).is_ok(), "{t}");
            assert!(t > prev.as_str(), "times ascend");
            prev = t.to_owned();
        }
    }
    let boat = lines
        .iter()
        .find(|l| l["properties"]["track_id"] == 2)
        .unwrap();
    assert_eq!(boat["properties"]["ids"], serde_json::json!([2, 3]));
    // 20 frames as 2, 5 as 3, 15 as 2 again.
    assert_eq!(
        boat["geometry"]["coordinates"].as_array().unwrap().len(),
        40
    );
    let last = points
        .iter()
        .find(|p| p["properties"]["track_id"] == 1)
        .unwrap();
    assert_eq!(last["properties"]["h_std_m"], 1.5);
    assert_eq!(last["properties"]["last_seen"], "2026-12-01T21:56:15.900Z");
    let g = water().to_geodetic(&Vector3::new(40.0, 0.3 * 5.9, 0.0));
    let c = last["geometry"]["coordinates"].as_array().unwrap();
    assert!((c[0].as_f64().unwrap() - g.lon_deg).abs() < 1e-7);
    assert!((c[1].as_f64().unwrap() - g.lat_deg).abs() < 1e-7);

    // The KML through an XML parser (Python's xml.etree).
    let script = r#"
import sys, xml.etree.ElementTree as ET
ns = {"k": "http://www.opengis.net/kml/2.2"}
root = ET.parse(sys.argv[1]).getroot()
pms = root.findall(".//k:Placemark", ns)
lines = [p for p in pms if p.find("k:LineString", ns) is not None]
points = [p for p in pms if p.find("k:Point", ns) is not None]
for p in lines:
    assert p.find("k:TimeSpan/k:begin", ns).text < p.find("k:TimeSpan/k:end", ns).text
    for c in p.find("k:LineString/k:coordinates", ns).text.split():
        lon, lat, alt = map(float, c.split(","))
        assert abs(lat - 47.6721) < 0.01 and abs(lon - 9.2679) < 0.01
for p in points:
    assert p.find("k:TimeStamp/k:when", ns).text.endswith("Z")
print(len(lines), len(points))
"#;
    let out = Command::new("python3")
        .arg("-c")
        .arg(script)
        .arg(tmp.path().join("tracks.kml"))
        .output()
        .expect("python3 runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(String::from_utf8_lossy(&out.stdout).trim(), "2 2");
}

#[test]
fn a_flight_cut_short_and_an_empty_flight_still_get_a_report() {
    let tmp = TestDir::new();
    let cut = write_flight(&tmp.path().join("cut"), 30, false);
    // A crash cuts the last line short.
    let mut f = std::fs::OpenOptions::new()
        .append(true)
        .open(cut.join("frames.ndjson"))
        .unwrap();
    f.write_all(b"{\"type\":\"frame\",\"frame\":30,\"ti")
        .unwrap();
    let report = tmp.path().join("cut.html");
    let stdout = ok(&review(&[
        cut.to_str().unwrap(),
        "--out",
        report.to_str().unwrap(),
    ]));
    assert!(stdout.contains("the run did not end cleanly"), "{stdout}");
    let (dom, console) = chromium_dom(&report);
    assert!(dom.contains("data-rendered=\"ok\""), "{console}");
    assert!(console_errors(&console).is_empty(), "{console}");
    assert!(dom.contains("id=\"unclean\"") && dom.contains("The run did not end cleanly"));
    assert!(dom.contains("1 line(s) of frames.ndjson could not be read"));

    let empty = write_flight(&tmp.path().join("empty"), 0, true);
    std::fs::write(empty.join("flight.tlog"), b"").unwrap();
    let report = tmp.path().join("empty").join("report.html");
    let stdout = ok(&review(&[
        empty.to_str().unwrap(),
        "--out",
        report.to_str().unwrap(),
    ]));
    assert!(stdout.contains("0 frames, 0 tracks"), "{stdout}");
    let (dom, console) = chromium_dom(&report);
    assert!(dom.contains("data-rendered=\"ok\""), "{console}");
    assert!(console_errors(&console).is_empty(), "{console}");
    assert!(!dom.contains("data-error="), "{dom}");
    assert!(dom.contains("id=\"empty\"") && dom.contains("No confirmed tracks"));
    let geojson: Value = serde_json::from_str(
        &std::fs::read_to_string(tmp.path().join("empty").join("tracks.geojson")).unwrap(),
    )
    .unwrap();
    assert_eq!(geojson["features"], serde_json::json!([]));
}

#[test]
fn a_folder_that_is_no_flight_is_a_clear_error() {
    let tmp = TestDir::new();
    let out = review(&[
        tmp.path().to_str().unwrap(),
        "--out",
        tmp.path().join("r.html").to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("is not a readable mgmot flight folder") && stderr.contains("flight.json"),
        "{stderr}"
    );
    assert!(!tmp.path().join("r.html").exists());
}

/// A truth folder as `mgmot-sim run --truth-out` writes it: the swimmer's true position 1 m
/// north of where it was reported, the boat's 3 m east; a third object never reported.
fn write_truth(dir: &Path) {
    std::fs::create_dir_all(dir).unwrap();
    let mut camera = String::from("frame,time_s,frame_stamp_us,lat_deg,lon_deg,alt_amsl_m,north_m,east_m,down_m,heading_deg,pitch_below_horizon_deg,qw,qx,qy,qz,vehicle_roll_deg,vehicle_pitch_deg,vehicle_yaw_deg\n");
    let mut world = String::from("frame,time_s,id,class,lat_deg,lon_deg,north_m,east_m,down_m,speed_mps,heading_deg,box_x,box_y,box_w,box_h,visibility\n");
    // The simulator runs at 30 fps; mgmot took every third frame.
    for k in 0..(FRAMES * 3) {
        let t = k as f64 / 30.0;
        let stamp = 120_000_000 + (t * 1e6).round() as u64;
        camera.push_str(&format!(
            "{},{t:.4},{stamp},0,0,0,0,0,0,0,0,1,0,0,0,0,0,0\n",
            k + 1
        ));
        let objects = [
            (1, "swimmer", [40.0 + 1.0, 0.3 * t]),
            (2, "boat", [60.0 + 1.4 * t, -20.0 + 1.4 * t + 3.0]),
            (3, "swimmer", [-200.0, 0.0]),
        ];
        for (id, class, ne) in objects {
            let g = water().to_geodetic(&Vector3::new(ne[0], ne[1], 0.0));
            world.push_str(&format!(
                "{},{t:.4},{id},{class},{:.9},{:.9},{},{},0,0,0,0,0,1,1,1\n",
                k + 1,
                g.lat_deg,
                g.lon_deg,
                ne[0],
                ne[1]
            ));
        }
    }
    std::fs::write(dir.join("camera.csv"), camera).unwrap();
    std::fs::write(dir.join("world.csv"), world).unwrap();
}

#[test]
fn with_the_truth_the_report_shows_the_error_per_true_object() {
    let tmp = TestDir::new();
    let flight = write_flight(tmp.path(), FRAMES, true);
    let truth = tmp.path().join("truth");
    write_truth(&truth);
    let report = tmp.path().join("report.html");
    let stdout = ok(&review(&[
        flight.to_str().unwrap(),
        "--out",
        report.to_str().unwrap(),
        "--truth",
        truth.to_str().unwrap(),
    ]));
    // 55 swimmer reports at 1 m, 40 boat reports at 3 m.
    assert!(
        stdout.contains("truth: 95 reports matched, error median 1.00 m, p95 3.00 m, max 3.00 m"),
        "{stdout}"
    );
    let html = std::fs::read_to_string(&report).unwrap();
    let data_at = html.find("id=\"review-data\">").unwrap();
    let data = &html[data_at + "id=\"review-data\">".len()..];
    let data: Value = serde_json::from_str(&data[..data.find("</script>").unwrap()]).unwrap();
    let objects = data["truth"]["objects"].as_array().unwrap();
    assert_eq!(objects.len(), 3);
    assert_eq!(objects[0]["track_ids"], serde_json::json!([1]));
    assert_eq!(
        objects[1]["track_ids"],
        serde_json::json!([2]),
        "after the merge"
    );
    assert_eq!(objects[2]["stats"]["n"], 0, "never reported");
    assert!((objects[1]["stats"]["median_m"].as_f64().unwrap() - 3.0).abs() < 0.01);
    let (dom, console) = chromium_dom(&report);
    assert!(dom.contains("data-rendered=\"ok\""), "{console}");
    assert!(console_errors(&console).is_empty(), "{console}");
    let truth_dom = inside(&dom, "truth");
    assert!(truth_dom.contains("id=\"truth-table\""));
    assert_eq!(
        truth_dom.matches("class=\"chart\"").count(),
        2,
        "a chart per reported object"
    );
    assert!(truth_dom.contains("never reported"));
}
