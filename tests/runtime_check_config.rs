//! `mgmot check-config` on the shipped example and on broken files, as a user runs it.

mod common;

use common::{mgmot, repo_file, TestDir};

#[test]
fn example_config_is_ok() {
    let example = repo_file("systemd/mgmot.example.toml");
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
