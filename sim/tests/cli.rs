//! End-to-end tests of the `mgmot-sim` binary: listing, bad input, determinism of the
//! ground truth, and the output formats.

use crate::common::{free_tcp_port, run_sim, sim, stderr_text, Proc, TestDir};
use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::Duration;

fn assert_clean_failure(o: &Output, needle: &str) {
    let err = stderr_text(o);
    assert!(!o.status.success(), "expected failure, stderr: {err}");
    assert!(!err.contains("panicked"), "panic: {err}");
    assert!(err.contains(needle), "`{needle}` not in: {err}");
}

#[test]
fn lists_the_shipped_scenarios() {
    let o = run_sim(&["list"]);
    assert!(o.status.success());
    let out = String::from_utf8_lossy(&o.stdout);
    for name in [
        "calm_baseline",
        "fast_drone",
        "gimbal_swings",
        "leave_and_return",
        "high_altitude_tiny",
        "swimmer_group",
        "boats_crossing",
        "camera_desync",
        "gimbal_pitch_bias",
        "telemetry_dropout",
        "mixed_mission_soak",
        "ardupilot_servo",
        "lawnmower_search",
        "expanding_square",
        "sector_search",
        "two_drones",
        "two_drones_abreast",
    ] {
        assert!(out.contains(name), "{name} missing from:\n{out}");
    }
}

#[test]
fn help_documents_every_mode() {
    let o = run_sim(&["--help"]);
    let out = String::from_utf8_lossy(&o.stdout);
    for word in [
        "run",
        "render",
        "detections",
        "list",
        "udpout",
        "Unix socket",
    ] {
        assert!(out.contains(word), "{word} missing from --help:\n{out}");
    }
}

#[test]
fn unknown_scenario_is_a_clear_error() {
    let dir = TestDir::new();
    let out = dir.join("x");
    let o = run_sim(&[
        "render",
        "-s",
        "no_such_scenario",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_clean_failure(&o, "unknown scenario `no_such_scenario`");
}

/// `--vehicle K` flies one drone of a scenario with several (each sees the world from its
/// own path: other detections); a vehicle the scenario does not have is a clear error. (That
/// the world is the same for both: the `two_drones` unit test in sim/src/scenario/shipped.rs.)
#[test]
fn each_vehicle_of_two_drones_flies_its_own_path() {
    let dir = TestDir::new();
    let mut detections = Vec::new();
    for k in ["0", "1"] {
        let out = dir.join(format!("v{k}.json"));
        let o = run_sim(&[
            "detections",
            "-s",
            "two_drones",
            "--vehicle",
            k,
            "--duration-s",
            "20",
            "-o",
            out.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", stderr_text(&o));
        detections.push(std::fs::read_to_string(&out).expect("the detections"));
    }
    assert!(
        detections.iter().all(|d| d.len() > 100),
        "detections were written"
    );
    assert_ne!(detections[0], detections[1], "two paths, two views");
    let o = run_sim(&[
        "detections",
        "-s",
        "two_drones",
        "--vehicle",
        "2",
        "-o",
        dir.join("v2.json").to_str().unwrap(),
    ]);
    assert_clean_failure(&o, "has 2 vehicle(s) (0 to 1), not vehicle 2");
}

#[test]
fn invalid_toml_names_file_line_and_field() {
    let dir = TestDir::new();
    let bad = dir.join("bad.toml");
    std::fs::write(&bad, "name = \"x\"\nduration_s = 10\n[origin]\nlat_deg = 1\nlon_deg = 2\n[drone]\nsped_mps = 3\n[drone.path]\nkind = \"hover\"\nat_ne_m = [0, 0]\n").unwrap();
    let o = run_sim(&[
        "detections",
        "-s",
        bad.to_str().unwrap(),
        "-o",
        dir.join("d.json").to_str().unwrap(),
    ]);
    assert_clean_failure(&o, "sped_mps");
    assert_clean_failure(&o, "bad.toml");
    assert_clean_failure(&o, "line 7");

    std::fs::write(&bad, "name = \"x\"\nduration_s = [\n").unwrap();
    let o = run_sim(&[
        "render",
        "-s",
        bad.to_str().unwrap(),
        "-o",
        dir.join("r").to_str().unwrap(),
    ]);
    assert_clean_failure(&o, "bad.toml");
}

#[test]
fn bad_addresses_are_clear_errors() {
    let o = run_sim(&[
        "run",
        "-s",
        "calm_baseline",
        "--duration-s",
        "0.2",
        "--mavlink",
        "carrier-pigeon:1",
    ]);
    assert_clean_failure(&o, "invalid --mavlink address");
    let o = run_sim(&[
        "run",
        "-s",
        "calm_baseline",
        "--duration-s",
        "0.2",
        "--frames",
        "tcp:1",
    ]);
    assert_clean_failure(&o, "invalid --frames");
    let o = run_sim(&[
        "run",
        "-s",
        "calm_baseline",
        "--duration-s",
        "0.2",
        "--frames",
        "unix:/nonexistent-dir/x.sock",
    ]);
    assert_clean_failure(&o, "cannot listen on /nonexistent-dir/x.sock");
}

#[test]
fn unreachable_tcp_peer_is_retried_not_fatal() {
    // Nothing listens on this port: the link retries in the background and the run ends
    // normally.
    let port = free_tcp_port();
    let addr = format!("tcpout:127.0.0.1:{port}");
    let o = run_sim(&[
        "-v",
        "run",
        "-s",
        "calm_baseline",
        "--duration-s",
        "1.5",
        "--mavlink",
        &addr,
    ]);
    let err = stderr_text(&o);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("retrying"), "{err}");
}

#[test]
fn sigint_stops_a_run_and_writes_what_ran() {
    // A 60 s real-time run, interrupted after about 1.5 s: exit 0 within a second or two, the
    // truth of the frames that ran written out.
    let out = TestDir::new();
    let mut child = Proc::start(
        sim(&["run", "-s", "calm_baseline", "--realtime", "--truth-out"])
            .arg(out.path())
            .stderr(Stdio::piped()),
    );
    std::thread::sleep(Duration::from_millis(1500));
    let kill = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(kill.success());
    let status = child
        .wait_within(Duration::from_secs(10))
        .expect("mgmot-sim did not stop within 10 s of SIGINT");
    let o = child.wait_with_output();
    let err = stderr_text(&o);
    assert!(status.success(), "{err}");
    assert!(err.contains("interrupted"), "{err}");
    // camera.csv has a row per frame (gt.txt only rows with objects in view).
    let camera = std::fs::read_to_string(out.join("camera.csv")).unwrap();
    let last_frame = camera
        .lines()
        .skip(1)
        .filter_map(|l| l.split(',').next()?.parse::<u32>().ok())
        .max();
    // 30 fps: a few dozen frames ran, far from the scenario's 1800.
    assert!(
        last_frame.is_some_and(|f| (10..600).contains(&f)),
        "last frame in the truth: {last_frame:?}"
    );
}

fn render_truth(dir: &Path, seed: &str) {
    let o = run_sim(&[
        "render",
        "-s",
        "swimmer_group",
        "--seed",
        seed,
        "--duration-s",
        "8",
        "--format",
        "none",
        "-o",
        dir.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr_text(&o));
}

#[test]
fn same_seed_gives_byte_identical_ground_truth() {
    let a = TestDir::new();
    let b = TestDir::new();
    let c = TestDir::new();
    render_truth(a.path(), "42");
    render_truth(b.path(), "42");
    render_truth(c.path(), "43");
    for f in ["gt/gt.txt", "world.csv", "camera.csv", "annotations.json"] {
        let x = std::fs::read(a.join(f)).unwrap();
        let y = std::fs::read(b.join(f)).unwrap();
        assert!(!x.is_empty(), "{f} empty");
        assert_eq!(x, y, "{f} differs between identical runs");
    }
    let x = std::fs::read(a.join("gt/gt.txt")).unwrap();
    let z = std::fs::read(c.join("gt/gt.txt")).unwrap();
    assert_ne!(x, z, "another seed should move the swimmers");
}

#[test]
fn seadronessee_json_has_the_dataset_layout() {
    let dir = TestDir::new();
    render_truth(dir.path(), "1");
    let text = std::fs::read_to_string(dir.join("annotations.json")).unwrap();
    let j: serde_json::Value = serde_json::from_str(&text).unwrap();
    let img = &j["images"][0];
    for key in [
        "latitude",
        "longitude",
        "height_above_takeoff(meter)",
        "speed(m/s)",
        "xspeed(m/s)",
        "yspeed(m/s)",
        "zspeed(m/s)",
        "compass_heading(degrees)",
        "gimbal_heading(degrees)",
        "gimbal_pitch(degrees)",
        "datetime(utc)",
    ] {
        assert!(img["meta"].get(key).is_some(), "meta.{key} missing");
    }
    assert_eq!(img["source"]["folder_name"], "swimmer_group");
    assert!(j["annotations"][0]["track_id"].as_u64().unwrap() >= 1);
    let cats: Vec<(u64, String)> = j["categories"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| {
            (
                c["id"].as_u64().unwrap(),
                c["name"].as_str().unwrap().to_string(),
            )
        })
        .collect();
    assert!(cats.contains(&(1, "swimmer".into())) && cats.contains(&(5, "buoy".into())));
    // MOT gt: frame,id,x,y,w,h,1,class,visibility
    let gt = std::fs::read_to_string(dir.join("gt/gt.txt")).unwrap();
    let first: Vec<&str> = gt.lines().next().unwrap().split(',').collect();
    assert_eq!(first.len(), 9);
    assert_eq!(first[6], "1");
    // The life jacket dropped at 20 s does not exist in an 8 s run; the swimmers do.
    assert!(gt.lines().all(|l| l.split(',').nth(7) == Some("1")));
}

#[test]
fn detections_in_both_formats() {
    let dir = TestDir::new();
    let json = dir.join("det.json");
    let o = run_sim(&[
        "detections",
        "-s",
        "boats_crossing",
        "--duration-s",
        "5",
        "-o",
        json.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr_text(&o));
    let dets: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let dets = dets.as_array().unwrap();
    assert!(!dets.is_empty());
    for d in dets {
        let s = d["score"].as_f64().unwrap();
        assert!(s > 0.0 && s < 1.0);
        assert_eq!(d["bbox"].as_array().unwrap().len(), 4);
    }
    assert!(dir.join("det_gt/gt/gt.txt").exists());
    let txt = dir.join("det.txt");
    let o = run_sim(&[
        "detections",
        "-s",
        "boats_crossing",
        "--duration-s",
        "5",
        "-o",
        txt.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr_text(&o));
    let lines = std::fs::read_to_string(&txt).unwrap();
    assert_eq!(
        lines.lines().count(),
        dets.len(),
        "same seed, same detections in both formats"
    );
    assert!(lines.lines().all(|l| l.split(',').count() == 10));
    let o = run_sim(&[
        "detections",
        "-s",
        "boats_crossing",
        "-o",
        dir.join("d.csv").to_str().unwrap(),
    ]);
    assert_clean_failure(&o, "must end in .json");
}

#[test]
fn renders_png_and_jpg_images() {
    let dir = TestDir::new();
    for fmt in ["png", "jpg"] {
        let out = dir.join(fmt);
        let o = run_sim(&[
            "render",
            "-s",
            "calm_baseline",
            "--duration-s",
            "1",
            "--every",
            "10",
            "--width",
            "320",
            "--height",
            "180",
            "--format",
            fmt,
            "-o",
            out.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", stderr_text(&o));
        let img = image::open(out.join(format!("img1/000011.{fmt}"))).unwrap();
        assert_eq!((img.width(), img.height()), (320, 180));
        assert!(out.join("seqinfo.ini").exists());
    }
}

#[test]
fn missing_v4l2_device_is_a_clear_error() {
    let o = run_sim(&[
        "run",
        "-s",
        "calm_baseline",
        "--duration-s",
        "0.2",
        "--frames",
        "v4l2:/dev/video-does-not-exist",
    ]);
    if cfg!(feature = "v4l2") {
        assert_clean_failure(&o, "no V4L2 device /dev/video-does-not-exist");
    } else {
        assert_clean_failure(&o, "`v4l2` cargo feature");
    }
}
