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
