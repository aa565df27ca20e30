//! Hardening of the commands' input and output files, as a user runs them: a closed stdout
//! ends a command quietly instead of panicking, inputs that are not regular files (devices,
//! FIFOs) or are too large are refused instead of read for ever, and `mgmot run` checks its
//! `--stats-json` file before it starts.
//!
//! Every command runs under a deadline and is killed past it, so that a regression (a read
//! that blocks on a FIFO, a run that never ends) fails the test instead of hanging it.

use std::ffi::CString;
use std::os::fd::{FromRawFd, OwnedFd};
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn mgmot() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_mgmot"));
    c.stdin(Stdio::null());
    c
}

/// Runs `cmd` to completion, or kills it after `limit` and panics (naming `what`).
fn run_with_deadline(mut cmd: Command, limit: Duration, what: &str) -> Output {
    let child = cmd.stderr(Stdio::piped()).spawn().unwrap();
    let pid = child.id();
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        let _ = tx.send(child.wait_with_output());
    });
    match rx.recv_timeout(limit) {
        Ok(out) => out.unwrap(),
        Err(_) => {
            // SAFETY: `pid` is the child this test spawned and has not reaped yet.
            unsafe { libc::kill(pid as libc::pid_t, libc::SIGKILL) };
            let _ = rx.recv();
            panic!("{what}: still running after {limit:?} (killed)");
        }
    }
}

/// A command with stdout and stderr captured, run under a 60 s deadline.
fn output(mut cmd: Command, what: &str) -> Output {
    cmd.stdout(Stdio::piped());
    run_with_deadline(cmd, Duration::from_secs(60), what)
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
    let tmp = tempfile::tempdir().unwrap();
    let (ann, det) = write_dataset(tmp.path());
    let gt = write_mot(tmp.path(), "gt.txt");
    let pred = write_mot(tmp.path(), "pred.txt");
    let example = root().join("systemd/mgmot.example.toml");
    let geo = tmp.path().join("geo.csv");
    let model = root().join("models/mgmot-det-fp32.onnx");
    let images = root().join("tests/fixtures/detect");
    let out_dir = tmp.path().join("out");
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
        let mut cmd = mgmot();
        cmd.arg(command).args(&args).stdout(closed_pipe());
        let what = format!("mgmot {command} {args:?} | (closed)");
        let out = run_with_deadline(cmd, Duration::from_secs(120), &what);
        let err = stderr(&out);
        assert!(!err.contains("panicked"), "{what}: {err}");
        assert!(err.is_empty(), "{what}: not quiet: {err}");
        // 141 = 128 + SIGPIPE, what a shell reports for a tool killed by SIGPIPE.
        assert_eq!(out.status.code(), Some(141), "{what}: {err}");
    }
}

#[test]
fn non_regular_input_files_are_refused_not_read() {
    let tmp = tempfile::tempdir().unwrap();
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
        let mut cmd = mgmot();
        cmd.args(&args);
        let out = output(cmd, &what);
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
    let tmp = tempfile::tempdir().unwrap();
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
        let mut cmd = mgmot();
        cmd.args(&args);
        let out = output(cmd, &what);
        let err = stderr(&out);
        assert!(!out.status.success(), "{what}: accepted");
        assert!(err.contains(path.to_str().unwrap()), "{what}: {err}");
        assert!(err.contains(bound), "{what}: {err}");
    }
}

/// A runtime config that runs until stopped: frames from a simulator socket nobody serves
/// (mgmot retries it with backoff), replayed detections, MAVLink out to `gcs_port`.
fn idle_run_config(dir: &Path, gcs_port: u16) -> PathBuf {
    let dets = dir.join("dets.json");
    std::fs::write(&dets, "[]").unwrap();
    let config = dir.join("run.toml");
    std::fs::write(
        &config,
        format!(
            "[mavlink]\nconnection = \"udpout:127.0.0.1:{gcs_port}\"\nstream_rate_hz = 0\n\
             [frames]\nsource = \"sim\"\nsocket = \"{}\"\n\
             [detector]\nkind = \"replay\"\ndetections = \"{}\"\n",
            dir.join("nobody.sock").display(),
            dets.display()
        ),
    )
    .unwrap();
    config
}

#[test]
fn run_checks_its_stats_file_before_starting() {
    let tmp = tempfile::tempdir().unwrap();
    let gcs = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    let config = idle_run_config(tmp.path(), gcs.local_addr().unwrap().port());
    let check = mgmot().arg("check-config").arg(&config).output().unwrap();
    assert!(check.status.success(), "{}", stderr(&check));

    // Unwritable: its folder does not exist. Refused at once, not after the run.
    let stats = tmp.path().join("no-such-folder/stats.json");
    let mut cmd = mgmot();
    cmd.arg("run")
        .arg("--config")
        .arg(&config)
        .arg("--stats-json")
        .arg(&stats);
    let started = Instant::now();
    let out = output(cmd, "mgmot run with an unwritable --stats-json");
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
    let stats = tmp.path().join("stats.json");
    std::fs::write(&stats, "stale").unwrap();
    let child = mgmot()
        .arg("run")
        .arg("--config")
        .arg(&config)
        .arg("--stats-json")
        .arg(&stats)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let pid = child.id();
    std::thread::sleep(Duration::from_secs(2));
    // Emptied at start-up: no stale stats while running.
    assert_eq!(std::fs::read_to_string(&stats).unwrap(), "");
    // SAFETY: `pid` is the child spawned above, not yet reaped.
    unsafe { libc::kill(pid as libc::pid_t, libc::SIGTERM) };
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        let _ = tx.send(child.wait_with_output());
    });
    let Ok(out) = rx.recv_timeout(Duration::from_secs(30)) else {
        // SAFETY: as above.
        unsafe { libc::kill(pid as libc::pid_t, libc::SIGKILL) };
        panic!("mgmot run did not stop on SIGTERM");
    };
    let out = out.unwrap();
    assert!(out.status.success(), "{}", stderr(&out));
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&stats).unwrap()).unwrap();
    assert!(json.get("frames_captured").is_some(), "{json}");
}
