//! `mgmot check-config` on the shipped example and on broken files, as a user runs it.

use crate::common;

use common::{example_config_here, example_config_with_detector, mgmot, repo_file, TestDir};
use std::path::Path;

#[test]
fn example_config_is_ok() {
    let dir = TestDir::new();
    let example = example_config_here(&dir);
    let out = mgmot().arg("check-config").arg(&example).output();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(stdout.contains(": ok"), "{stdout}");
    assert!(stdout.contains("udpin:127.0.0.1:14551"), "{stdout}");
}

#[test]
fn errors_name_the_file_and_the_keys() {
    let dir = TestDir::new();
    let bad = dir.path().join("bad.toml");
    std::fs::write(
        &bad,
        r#"
[mavlink]
connection = "serial:/dev/ttyS0:fast"
[telemetry]
max_pose_age_ms = -1
[frames]
source = "v4l2"
device = "/dev/video0"
pixel_format = "H264"
width_px = 1280
height_px = 720
fps = 30
[detector]
kind = "replay"
detections = "d.json"
"#,
    )
    .unwrap();
    let out = mgmot().arg("check-config").arg(&bad).output();
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    for needle in [
        "bad.toml",
        "`mavlink.connection`",
        "baud rate",
        "`telemetry.max_pose_age_ms`",
        "`frames.pixel_format`",
        "H264",
    ] {
        assert!(stderr.contains(needle), "missing {needle:?} in {stderr}");
    }

    let typo = dir.path().join("typo.toml");
    std::fs::write(
        &typo,
        "[mavlink]\nconnection = \"udpin:0.0.0.0:1\"\nrate = 3\n",
    )
    .unwrap();
    let out = mgmot().arg("check-config").arg(&typo).output();
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("typo.toml") && stderr.contains("rate"),
        "{stderr}"
    );
}

/// Issue 39 item 12: `check-config` said ok although the model file did not exist; `mgmot
/// run` then failed at start.
#[test]
fn flight_day_12_check_config_fails_on_a_missing_model() {
    let dir = TestDir::new();
    let missing = dir.join("models/gone.onnx");
    let config = example_config_with_detector(&dir, &missing, "tract", None);
    let out = mgmot().arg("check-config").arg(&config).output();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success(),
        "check-config passed: {}{stderr}",
        String::from_utf8_lossy(&out.stdout)
    );
    assert!(
        stderr.contains(&missing.display().to_string()) && stderr.contains("`detector.model`"),
        "{stderr}"
    );
    // A directory where the model should be is no model either.
    std::fs::create_dir_all(&missing).unwrap();
    let out = mgmot().arg("check-config").arg(&config).output();
    assert!(!out.status.success());
}

/// Runs `mgmot check-config` on `config` with `ORT_DYLIB_PATH` set to `ort_dylib` (or unset),
/// fails the test if it passes, and returns what it said on stderr.
fn check_config_refused(config: &Path, ort_dylib: Option<&Path>) -> String {
    let mut cmd = mgmot();
    cmd.arg("check-config").arg(config);
    match ort_dylib {
        Some(p) => cmd.env("ORT_DYLIB_PATH", p),
        None => cmd.env_remove("ORT_DYLIB_PATH"),
    };
    let out = cmd.output();
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(!out.status.success(), "check-config passed: {stderr}");
    stderr
}

/// Issue 39 item 12: the ONNX Runtime library of `backend = "onnxruntime"`, configured or
/// from `ORT_DYLIB_PATH`, must exist for `check-config` to say ok.
#[test]
fn flight_day_12_check_config_fails_on_a_missing_onnxruntime_library() {
    let dir = TestDir::new();
    let model = repo_file("models/mgmot-det-int8.onnx");
    let missing = dir.join("lib/libonnxruntime.so");
    let config = example_config_with_detector(&dir, &model, "onnxruntime", Some(&missing));
    let stderr = check_config_refused(&config, None);
    assert!(
        stderr.contains(&missing.display().to_string())
            && stderr.contains("`detector.ort_library`"),
        "{stderr}"
    );
    // Not configured: ORT_DYLIB_PATH names it, or nothing does.
    let config = example_config_with_detector(&dir, &model, "onnxruntime", None);
    let stderr = check_config_refused(&config, Some(&missing));
    assert!(
        stderr.contains(&missing.display().to_string()) && stderr.contains("ORT_DYLIB_PATH"),
        "{stderr}"
    );
    let stderr = check_config_refused(&config, None);
    assert!(stderr.contains("ORT_DYLIB_PATH"), "{stderr}");
    // tract needs no library.
    let config = example_config_with_detector(&dir, &model, "tract", Some(&missing));
    let out = mgmot().arg("check-config").arg(&config).output();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// Issue 39 item 12: `mgmot run`'s start-up error was printed three times over (each error
/// of the chain repeated its cause); it is said once.
#[test]
fn flight_day_12_run_says_its_start_up_error_once() {
    let dir = TestDir::new();
    let missing = dir.join("gone.onnx");
    let config = example_config_with_detector(&dir, &missing, "tract", None);
    let out = mgmot()
        .args(["run", "--config"])
        .arg(&config)
        .output_within(std::time::Duration::from_secs(60), "mgmot run");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{stderr}");
    let path = missing.display().to_string();
    assert_eq!(stderr.matches(&path).count(), 1, "{stderr}");
    assert_eq!(
        stderr.matches("No such file or directory").count(),
        1,
        "{stderr}"
    );
}

const INT8: &str = "models/mgmot-det-int8.onnx";
const FP32: &str = "models/mgmot-det-fp32.onnx";

/// `[detector] alternatives`: each must be a readable model with the main model's class names
/// and input size; `check-config` names the file under the key.
#[test]
fn check_config_refuses_a_missing_or_mismatched_alternative() {
    let dir = TestDir::new();
    let missing = dir.join("models/gone.onnx");
    let renamed = common::model_with_swimmer_renamed(&dir, FP32, "renamed.onnx");
    let config = example_config_with_detector(&dir, &repo_file(INT8), "auto", None);
    let with = |alternatives: &[&Path]| {
        let list: Vec<String> = alternatives
            .iter()
            .map(|p| format!("{:?}", p.display().to_string()))
            .collect();
        let text = std::fs::read_to_string(&config).unwrap().replace(
            "\nbackend = \"auto\"\n",
            &format!(
                "\nalternatives = [{}]\nbackend = \"auto\"\n",
                list.join(", ")
            ),
        );
        assert!(text.contains("alternatives = ["), "{text}");
        dir.write("alternatives.toml", text)
    };
    let ok = mgmot()
        .arg("check-config")
        .arg(with(&[&repo_file(FP32)]))
        .env_remove("ORT_DYLIB_PATH")
        .output();
    assert!(
        ok.status.success(),
        "{}",
        String::from_utf8_lossy(&ok.stderr)
    );
    let stderr = check_config_refused(&with(&[&repo_file(FP32), &missing, &renamed]), None);
    assert_eq!(
        stderr.matches("`detector.alternatives`").count(),
        2,
        "{stderr}"
    );
    assert!(
        stderr.contains(&missing.display().to_string()) && stderr.contains("no such file"),
        "{stderr}"
    );
    assert!(
        stderr.contains(&renamed.display().to_string()) && stderr.contains("class names"),
        "{stderr}"
    );
    assert!(!stderr.contains("mgmot-det-fp32.onnx"), "{stderr}");
}

/// `mgmot run` with `backend = "auto"`, the int8 model and its fp32 alternative, on the
/// detector fixture frames, with `ORT_DYLIB_PATH` set to `ort` (or unset): its stderr (INFO)
/// and its `--stats-json`.
fn auto_run(ort: Option<&Path>) -> (String, serde_json::Value) {
    use mgmot::config::{DetectorConfig, FramesConfig, OnnxDetectorConfig};
    let dir = TestDir::new();
    let frames = dir.join("frames");
    std::fs::create_dir_all(&frames).unwrap();
    // The detector fixtures' frames (the directory also holds models and ground truth).
    for entry in std::fs::read_dir(repo_file("tests/fixtures/detect")).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "jpg") {
            std::fs::copy(&path, frames.join(path.file_name().unwrap())).unwrap();
        }
    }
    let gcs = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    let mut c = common::run_config(
        &format!("udpout:127.0.0.1:{}", gcs.local_addr().unwrap().port()),
        &dir.join("unused.sock"),
        &dir.empty_detections(),
    );
    c.mavlink.stream_rate_hz = 0.0;
    c.frames = FramesConfig::Images {
        directory: frames,
        fps: 10.0,
        looping: false,
    };
    let mut onnx: OnnxDetectorConfig =
        toml::from_str("model = \"\"").expect("the ONNX detector's defaults");
    onnx.model = repo_file(INT8);
    onnx.alternatives = vec![repo_file(FP32)];
    onnx.tile = mgmot::config::TileChoice::Auto;
    c.detector = DetectorConfig::Onnx(onnx);
    let config = dir.write_config("run.toml", &c);
    let stats = dir.join("stats.json");
    let mut run = common::mgmot_run(&config, Some(&stats));
    run.env("RUST_LOG", "info");
    match ort {
        Some(lib) => run.env("ORT_DYLIB_PATH", lib),
        None => run.env_remove("ORT_DYLIB_PATH"),
    };
    let out = run.output_within(std::time::Duration::from_secs(120), "mgmot run (auto)");
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "{stderr}");
    let stats: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&stats).unwrap()).unwrap();
    (stderr, stats)
}

/// The INFO line of the choice, and the stats' `detector` entry: every candidate measured,
/// the fastest chosen. Returns the chosen backend.
fn assert_chose_the_fastest(stderr: &str, stats: &serde_json::Value, backends: &[&str]) -> String {
    let line = stderr
        .lines()
        .find(|l| l.contains("INFO") && l.contains("detector: chose"))
        .unwrap_or_else(|| panic!("no INFO line of the choice: {stderr}"));
    let d = &stats["detector"];
    let measured = d["measurements"].as_array().unwrap();
    assert_eq!(measured.len(), 2 * backends.len(), "{d}");
    for backend in backends {
        for model in ["mgmot-det-int8.onnx", "mgmot-det-fp32.onnx"] {
            let named = format!("{backend} {model} ");
            let at = line
                .find(&named)
                .unwrap_or_else(|| panic!("{named:?} not in {line}"));
            let ms: f64 = line[at + named.len()..]
                .split(" ms")
                .next()
                .and_then(|v| v.parse().ok())
                .unwrap_or_else(|| panic!("no time after {named:?} in {line}"));
            assert!(ms > 0.0, "{line}");
        }
    }
    let fastest = measured
        .iter()
        .min_by_key(|m| m["median_us"].as_u64().unwrap())
        .unwrap();
    assert_eq!(d["backend"], fastest["backend"], "{d}");
    assert_eq!(d["model"], fastest["model"], "{d}");
    assert_eq!(d["requested"], "auto", "{d}");
    assert!(d["measuring_us"].as_u64().unwrap() > 0, "{d}");
    d["backend"].as_str().unwrap().to_owned()
}

/// `tile = "auto"`: one INFO line for the fixtures' 1280x720 frames, tiling them or not, and
/// its arithmetic agrees with its decision (5 model runs against the 15 frames/s budget).
fn assert_tiling_decided(stderr: &str) {
    let lines: Vec<&str> = stderr
        .lines()
        .filter(|l| l.contains("INFO") && l.contains("tiling 1280x720 frames"))
        .collect();
    assert_eq!(lines.len(), 1, "one decision per frame size: {stderr}");
    let line = lines[0];
    let number_after = |key: &str| -> f64 {
        let at = line
            .find(key)
            .unwrap_or_else(|| panic!("{key:?} not in {line}"));
        line[at + key.len()..]
            .split_whitespace()
            .next()
            .and_then(|v| v.parse().ok())
            .unwrap_or_else(|| panic!("no number after {key:?} in {line}"))
    };
    assert_eq!(number_after("frames: "), 5.0, "{line}");
    let run_ms = number_after("model runs of ");
    let budget_ms = number_after(" the ");
    assert_eq!(budget_ms, 67.0, "{line}");
    let tiles = !line.contains("not tiling");
    // The line rounds the run time to 0.1 ms: decide with a margin.
    if (5.0 * run_ms - budget_ms).abs() > 0.5 {
        assert_eq!(tiles, 5.0 * run_ms <= budget_ms, "{line}");
    }
}

/// `backend = "auto"` where ONNX Runtime is found: all four (backend, model) pairs are timed,
/// the log names both backends' times, and the fastest runs.
#[test]
fn run_with_backend_auto_times_both_backends_and_runs_the_fastest() {
    let lib = std::env::var_os("ORT_DYLIB_PATH")
        .map(std::path::PathBuf::from)
        .filter(|p| p.is_file())
        .unwrap_or_else(|| {
            common::missing_tool(
                "backend auto with ONNX Runtime",
                "ORT_DYLIB_PATH naming libonnxruntime.so (scripts/detect_fetch_onnxruntime.sh)",
            )
        });
    let (stderr, stats) = auto_run(Some(&lib));
    let chosen = assert_chose_the_fastest(&stderr, &stats, &["tract", "onnxruntime"]);
    // The chosen backend is the one the process then loads.
    assert!(
        stderr.contains(&format!("backend={chosen}"))
            || stderr.contains(&format!("backend: {chosen}")),
        "{stderr}"
    );
    assert!(stats["frames_processed"].as_u64().unwrap() > 0, "{stats}");
    assert_tiling_decided(&stderr);
}

/// `backend = "auto"` without ONNX Runtime: the log says why it is not a candidate, and tract
/// runs the faster of the two models.
#[test]
fn run_with_backend_auto_without_onnxruntime_times_tract_only() {
    let (stderr, stats) = auto_run(None);
    let said = stderr
        .lines()
        .find(|l| l.contains("not a candidate") && l.contains("onnxruntime"))
        .unwrap_or_else(|| panic!("no line on onnxruntime's absence: {stderr}"));
    assert!(said.contains("ORT_DYLIB_PATH"), "{said}");
    assert_eq!(
        assert_chose_the_fastest(&stderr, &stats, &["tract"]),
        "tract"
    );
    assert_tiling_decided(&stderr);
}
