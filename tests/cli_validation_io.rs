//! Hardening of the commands' input and output files, as a user runs them: a closed stdout
//! ends a command quietly instead of panicking, inputs that are not regular files (devices,
//! FIFOs) or are too large are refused instead of read for ever, and `mgmot run` checks its
//! `--stats-json` file before it starts.
//!
//! Every command runs under a deadline and is killed past it, so that a regression (a read
//! that blocks on a FIFO, a run that never ends) fails the test instead of hanging it.

use crate::common;

use common::{example_config_here, mgmot, mgmot_run, repo_file, run_config, TestCommand, TestDir};
use std::ffi::CString;
use std::os::fd::{FromRawFd, OwnedFd};
use std::path::{Path, PathBuf};
use std::process::{Output, Stdio};
use std::time::{Duration, Instant};

/// Runs `cmd` to completion with stdout and stderr captured, or kills it after 60 s and
/// fails (naming `what`).
fn output(cmd: &mut TestCommand, what: &str) -> Output {
    cmd.output_within(Duration::from_secs(60), what)
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// A FIFO no process ever opens for writing: opening it for reading blocks for ever.
fn fifo(dir: &Path, name: &str) -> PathBuf {
    let p = dir.join(name);
    let c = CString::new(p.to_str().unwrap()).unwrap();
    // SAFETY: `c` is a valid NUL-terminated path.
    assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0, "mkfifo");
    p
}

/// A sparse file of `len` zero bytes (no disk space used).
fn sparse(dir: &Path, name: &str, len: u64) -> PathBuf {
    let p = dir.join(name);
    std::fs::File::create(&p).unwrap().set_len(len).unwrap();
    p
}

/// The write end of a pipe whose read end is already closed: every write gets EPIPE.
fn closed_pipe() -> Stdio {
    let mut fds = [0; 2];
    // SAFETY: `fds` has room for the two descriptors pipe(2) returns.
    assert_eq!(unsafe { libc::pipe(fds.as_mut_ptr()) }, 0, "pipe");
    // SAFETY: both descriptors were just created and are owned here only.
    let (read, write) = unsafe { (OwnedFd::from_raw_fd(fds[0]), OwnedFd::from_raw_fd(fds[1])) };
    drop(read);
    Stdio::from(write)
}

/// A small SeaDronesSee file: one video of 3 frames with drone metadata and one box each,
/// and COCO detections of the same boxes.
fn write_dataset(dir: &Path) -> (PathBuf, PathBuf) {
    let meta = r#""meta": {"latitude": 47.6, "longitude": 9.2, "height_above_takeoff(meter)": 30.0,
        "gimbal_heading(degrees)": 10.0, "gimbal_pitch(degrees)": 45.0}"#;
    let images: Vec<String> = (1..=3)
        .map(|k| {
            format!(
                r#"{{"id": {k}, "width": 640, "height": 360, "source": {{"folder_name": "v", "frame_no": {k}}}, {meta}}}"#
            )
        })
        .collect();
    let boxes: Vec<String> = (1..=3)
        .map(|k| {
            format!(
                r#"{{"id": {k}, "image_id": {k}, "bbox": [310, 170, 20, 20], "category_id": 1}}"#
            )
        })
        .collect();
    let ann = dir.join("ann.json");
    std::fs::write(
        &ann,
        format!(
            r#"{{"images": [{}], "annotations": [{}]}}"#,
            images.join(","),
            boxes.join(",")
        ),
    )
    .unwrap();
    let dets: Vec<String> = (1..=3)
        .map(|k| {
            format!(
                r#"{{"image_id": {k}, "category_id": 1, "bbox": [310, 170, 20, 20], "score": 0.9}}"#
            )
        })
        .collect();
    let det = dir.join("det.json");
    std::fs::write(&det, format!("[{}]", dets.join(","))).unwrap();
    (ann, det)
}

/// A MOTChallenge file of two boxes over two frames.
fn write_mot(dir: &Path, name: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, "1,1,10,10,20,20,1,1,1\n2,1,12,10,20,20,1,1,1\n").unwrap();
    p
}

#[test]
fn every_command_ends_quietly_when_stdout_is_closed() {
    let tmp = TestDir::new();
    let (ann, det) = write_dataset(tmp.path());
    let gt = write_mot(tmp.path(), "gt.txt");
    let pred = write_mot(tmp.path(), "pred.txt");
    let example = example_config_here(&tmp);
    let geo = tmp.join("geo.csv");
    let model = repo_file("models/mgmot-det-fp32.onnx");
    let images = repo_file("tests/fixtures/detect");
    let out_dir = tmp.join("out");
    let commands: Vec<(&str, Vec<&std::ffi::OsStr>)> = vec![
        ("check-config", vec![example.as_os_str()]),
        (
            "eval",
            vec![
                "--gt".as_ref(),
                gt.as_os_str(),
                "--pred".as_ref(),
                pred.as_os_str(),
            ],
        ),
        (
            "eval",
            vec![
                "--json".as_ref(),
                "--gt".as_ref(),
                gt.as_os_str(),
                "--pred".as_ref(),
                pred.as_os_str(),
            ],
        ),
        (
            "geolocate",
            vec![
                "--annotations".as_ref(),
                ann.as_os_str(),
                "--out".as_ref(),
                geo.as_os_str(),
            ],
        ),
        (
            "track",
            vec![
                "--annotations".as_ref(),
                ann.as_os_str(),
                "--detections".as_ref(),
                det.as_os_str(),
                "--out".as_ref(),
                out_dir.as_os_str(),
            ],
        ),
        (
            "detect",
            vec!["--model".as_ref(), model.as_os_str(), images.as_os_str()],
        ),
    ];
    for (command, args) in commands {
        let what = format!("mgmot {command} {args:?} | (closed)");
        let out = mgmot()
            .arg(command)
            .args(&args)
            .stdout(closed_pipe())
            .output_within(Duration::from_secs(120), &what);
        let err = stderr(&out);
        assert!(!err.contains("panicked"), "{what}: {err}");
        assert!(err.is_empty(), "{what}: not quiet: {err}");
        // 141 = 128 + SIGPIPE, what a shell reports for a tool killed by SIGPIPE.
        assert_eq!(out.status.code(), Some(141), "{what}: {err}");
    }
}

#[test]
fn non_regular_input_files_are_refused_not_read() {
    let tmp = TestDir::new();
    let dir = tmp.path();
    let (ann, det) = write_dataset(dir);
    let gt = write_mot(dir, "gt.txt");
    let out_dir = dir.join("out");
    let s = |p: &Path| p.to_str().unwrap().to_owned();
    // (arguments, the refused path)
    let mut cases: Vec<(Vec<String>, PathBuf)> = Vec::new();
    let f = fifo(dir, "ann-fifo.json");
    cases.push((
        vec![
            "track".into(),
            "--annotations".into(),
            s(&f),
            "--detections".into(),
            s(&det),
            "--out".into(),
            s(&out_dir),
        ],
        f,
    ));
    let f = fifo(dir, "det-fifo.json");
    cases.push((
        vec![
            "track".into(),
            "--annotations".into(),
            s(&ann),
            "--detections".into(),
            s(&f),
            "--out".into(),
            s(&out_dir),
        ],
        f,
    ));
    let f = fifo(dir, "det-fifo.txt");
    cases.push((
        vec![
            "track".into(),
            "--annotations".into(),
            s(&ann),
            "--detections".into(),
            s(&f),
            "--out".into(),
            s(&out_dir),
        ],
        f,
    ));
    let f = fifo(dir, "params-fifo.toml");
    cases.push((
        vec![
            "track".into(),
            "--annotations".into(),
            s(&ann),
            "--detections".into(),
            s(&det),
            "--config".into(),
            s(&f),
            "--out".into(),
            s(&out_dir),
        ],
        f,
    ));
    let f = fifo(dir, "geo-ann-fifo.json");
    cases.push((
        vec![
            "geolocate".into(),
            "--annotations".into(),
            s(&f),
            "--out".into(),
            s(&dir.join("g.csv")),
        ],
        f,
    ));
    let f = fifo(dir, "geo-det-fifo.json");
    cases.push((
        vec![
            "geolocate".into(),
            "--annotations".into(),
            s(&ann),
            "--detections".into(),
            s(&f),
            "--out".into(),
            s(&dir.join("g.csv")),
        ],
        f,
    ));
    let f = fifo(dir, "gt-fifo.txt");
    cases.push((
        vec!["eval".into(), "--gt".into(), s(&f), "--pred".into(), s(&gt)],
        f,
    ));
    let f = fifo(dir, "pred-fifo.txt");
    cases.push((
        vec!["eval".into(), "--gt".into(), s(&gt), "--pred".into(), s(&f)],
        f,
    ));
    let f = fifo(dir, "config-fifo.toml");
    cases.push((vec!["check-config".into(), s(&f)], f));
    // /dev/zero never ends; as JSON it is refused before a byte is read.
    let zero = PathBuf::from("/dev/zero");
    cases.push((
        vec![
            "geolocate".into(),
            "--annotations".into(),
            s(&zero),
            "--out".into(),
            s(&dir.join("g.csv")),
        ],
        zero.clone(),
    ));
    cases.push((vec!["check-config".into(), s(&zero)], zero.clone()));
    // A folder of sequences whose ground-truth file is a FIFO (a FIFO in the results folder
    // is not taken for a results file: "no results file").
    let gt_dir = dir.join("gt_dir");
    let pred_dir = dir.join("pred_dir");
    std::fs::create_dir_all(&gt_dir).unwrap();
    std::fs::create_dir_all(&pred_dir).unwrap();
    write_mot(&pred_dir, "seq.txt");
    let f = fifo(&gt_dir, "seq.txt");
    cases.push((
        vec![
            "eval".into(),
            "--gt".into(),
            s(&gt_dir),
            "--pred".into(),
            s(&pred_dir),
        ],
        f,
    ));

    for (args, refused) in cases {
        let what = format!("mgmot {}", args.join(" "));
        let out = output(mgmot().args(&args), &what);
        let err = stderr(&out);
        assert!(!out.status.success(), "{what}: accepted");
        assert!(err.contains(refused.to_str().unwrap()), "{what}: {err}");
        assert!(
            err.contains("FIFO") || err.contains("character device"),
            "{what}: {err}"
        );
        assert!(err.contains("regular file"), "{what}: {err}");
    }
    assert!(!out_dir.exists());
}

#[test]
fn oversized_input_files_are_refused_naming_the_bound() {
    let tmp = TestDir::new();
    let dir = tmp.path();
    let (ann, det) = write_dataset(dir);
    // Sparse files: they take no disk space and are refused before they are read.
    let big_json = sparse(dir, "big.json", (2 << 30) + 1);
    let big_toml = sparse(dir, "big.toml", (16 << 20) + 1);
    let s = |p: &Path| p.to_str().unwrap().to_owned();
    let cases: Vec<(Vec<String>, &Path, &str)> = vec![
        (
            vec![
                "geolocate".into(),
                "--annotations".into(),
                s(&big_json),
                "--out".into(),
                s(&dir.join("g.csv")),
            ],
            &big_json,
            "2 GiB",
        ),
        (
            vec![
                "track".into(),
                "--annotations".into(),
                s(&ann),
                "--detections".into(),
                s(&big_json),
                "--out".into(),
                s(&dir.join("out")),
            ],
            &big_json,
            "2 GiB",
        ),
        (
            vec![
                "track".into(),
                "--annotations".into(),
                s(&ann),
                "--detections".into(),
                s(&det),
                "--config".into(),
                s(&big_toml),
                "--out".into(),
                s(&dir.join("out")),
            ],
            &big_toml,
            "16 MiB",
        ),
        (
            vec!["check-config".into(), s(&big_toml)],
            &big_toml,
            "16 MiB",
        ),
    ];
    for (args, path, bound) in cases {
        let what = format!("mgmot {}", args.join(" "));
        let out = output(mgmot().args(&args), &what);
        let err = stderr(&out);
        assert!(!out.status.success(), "{what}: accepted");
        assert!(err.contains(path.to_str().unwrap()), "{what}: {err}");
        assert!(err.contains(bound), "{what}: {err}");
    }
}

/// A runtime config that runs until stopped: frames from a simulator socket nobody serves
/// (mgmot retries it with backoff), replayed detections, MAVLink out to `gcs_port`.
fn idle_run_config(dir: &TestDir, gcs_port: u16) -> PathBuf {
    let mut c = run_config(
        &format!("udpout:127.0.0.1:{gcs_port}"),
        &dir.join("nobody.sock"),
        &dir.empty_detections(),
    );
    c.mavlink.stream_rate_hz = 0.0;
    dir.write_config("run.toml", &c)
}

#[test]
fn run_checks_its_stats_file_before_starting() {
    let tmp = TestDir::new();
    let gcs = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    let config = idle_run_config(&tmp, gcs.local_addr().unwrap().port());
    let check = mgmot().arg("check-config").arg(&config).output();
    assert!(check.status.success(), "{}", stderr(&check));

    // Unwritable: its folder does not exist. Refused at once, not after the run.
    let stats = tmp.join("no-such-folder/stats.json");
    let started = Instant::now();
    let out = output(
        &mut mgmot_run(&config, Some(&stats)),
        "mgmot run with an unwritable --stats-json",
    );
    let err = stderr(&out);
    assert!(!out.status.success(), "{err}");
    assert!(err.contains(stats.to_str().unwrap()), "{err}");
    assert!(err.contains("--stats-json"), "{err}");
    assert!(
        !err.contains("frames captured"),
        "the run started before the check: {err}"
    );
    assert!(started.elapsed() < Duration::from_secs(30));

    // Writable: the run goes on until SIGTERM and writes the stats at exit.
    let stats = tmp.join("stats.json");
    std::fs::write(&stats, "stale").unwrap();
    let mut run = mgmot_run(&config, Some(&stats)).spawn_logged(tmp.join("run.log"));
    std::thread::sleep(Duration::from_secs(2));
    // Emptied at start-up: no stale stats while running.
    assert_eq!(std::fs::read_to_string(&stats).unwrap(), "");
    run.sigterm();
    let status = run
        .wait_within(Duration::from_secs(30))
        .expect("mgmot run did not stop on SIGTERM");
    assert!(status.success(), "{}", run.log());
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&stats).unwrap()).unwrap();
    assert!(json.get("frames_captured").is_some(), "{json}");
}
