//! Hardening of `mgmot track`, `geolocate` and `detect` against hostile input, as a user runs
//! them: output files stay inside `--out` whatever the video names in the annotations say, and
//! numbers from the command line and the tracker parameters are finite and in range, with the
//! flag or key named in the error.

use crate::common;

use common::{shared_data as real_data, TestDir};
use std::path::{Path, PathBuf};
use std::process::Output;

fn mgmot(args: &[&str]) -> Output {
    common::mgmot().args(args).output()
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

fn assert_ok(args: &[&str], out: &Output) {
    assert!(
        out.status.success(),
        "mgmot {args:?} failed:\n{}",
        stderr(out)
    );
}

/// Drone metadata looking down at 45 deg from 30 m (every box centre hits the sea).
const META: &str = r#""meta": {"latitude": 47.6, "longitude": 9.2, "height_above_takeoff(meter)": 30.0,
    "gimbal_heading(degrees)": 10.0, "gimbal_pitch(degrees)": 45.0}"#;

/// One video of `frames` 640x360 frames with one object drifting right, as SeaDronesSee JSON
/// (the video's name in `source`, given as the JSON text of its value) and COCO detections.
fn write_dataset(dir: &Path, source: &str, frames: u64) -> (PathBuf, PathBuf) {
    let mut images = Vec::new();
    let mut annotations = Vec::new();
    let mut detections = Vec::new();
    for k in 1..=frames {
        images.push(format!(
            r#"{{"id": {k}, "width": 640, "height": 360, "source": {{{source}, "frame_no": {k}}}, {META}}}"#
        ));
        let x = 300 + 2 * k;
        annotations.push(format!(
            r#"{{"id": {k}, "image_id": {k}, "bbox": [{x}, 170, 20, 20], "category_id": 1}}"#
        ));
        detections.push(format!(
            r#"{{"image_id": {k}, "category_id": 1, "bbox": [{x}, 170, 20, 20], "score": 0.9}}"#
        ));
    }
    let ann = dir.join("ann.json");
    std::fs::write(
        &ann,
        format!(
            r#"{{"images": [{}], "annotations": [{}], "categories": [{{"id": 1, "name": "swimmer"}}]}}"#,
            images.join(","),
            annotations.join(",")
        ),
    )
    .unwrap();
    let det = dir.join("det.json");
    std::fs::write(&det, format!("[{}]", detections.join(","))).unwrap();
    (ann, det)
}

fn track_args<'a>(ann: &'a Path, det: &'a Path, out: &'a Path) -> Vec<&'a str> {
    vec![
        "track",
        "--annotations",
        ann.to_str().unwrap(),
        "--detections",
        det.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]
}

/// Every file under `dir`, recursively.
fn files_under(dir: &Path) -> Vec<PathBuf> {
    let mut found = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                found.push(p);
            }
        }
    }
    found.sort();
    found
}

#[test]
fn track_refuses_video_names_that_leave_the_out_folder() {
    let tmp = TestDir::new();
    // A folder an absolute video name would write into, beside --out.
    let victim = tmp.path().join("victim");
    std::fs::create_dir(&victim).unwrap();
    let absolute = victim.join("abs");
    let cases = [
        (
            r#""folder_name": "../escape""#.to_owned(),
            "../escape",
            "images[0].source.folder_name",
        ),
        (
            format!(r#""folder_name": "{}""#, absolute.display()),
            absolute.to_str().unwrap(),
            "images[0].source.folder_name",
        ),
        (
            r#""folder_name": "..""#.to_owned(),
            "..",
            "images[0].source.folder_name",
        ),
        (
            r#""folder_name": "a/../../escape2""#.to_owned(),
            "a/../../escape2",
            "images[0].source.folder_name",
        ),
        // `source.video` gives its file stem; ".." has none and is kept whole.
        (
            r#""video": "..""#.to_owned(),
            "..",
            "images[0].source.video",
        ),
    ];
    for (source, name, field) in &cases {
        let case = tempfile::tempdir_in(tmp.path()).unwrap();
        let (ann, det) = write_dataset(case.path(), source, 3);
        let out_dir = case.path().join("out");
        let args = track_args(&ann, &det, &out_dir);
        let out = mgmot(&args);
        let err = stderr(&out);
        assert!(!out.status.success(), "{name}: accepted");
        assert!(err.contains(&format!("{name:?}")), "{name}: {err}");
        assert!(err.contains(field), "{name}: {err}");
        // Nothing was written, inside or outside --out.
        let written: Vec<PathBuf> = files_under(tmp.path())
            .into_iter()
            .filter(|p| *p != ann && *p != det)
            .collect();
        assert!(written.is_empty(), "{name}: wrote {written:?}");
    }

    // A name from the optional `videos` list is checked too, and named by that field.
    let case = tmp.path().join("videos");
    std::fs::create_dir(&case).unwrap();
    let ann = case.join("ann.json");
    std::fs::write(
        &ann,
        r#"{"images": [{"id": 1, "width": 64, "height": 64, "video_id": 7}],
            "videos": [{"id": 7, "name": "../../escape3"}]}"#,
    )
    .unwrap();
    let det = case.join("det.json");
    std::fs::write(&det, "[]").unwrap();
    let out = mgmot(&track_args(&ann, &det, &case.join("out")));
    let err = stderr(&out);
    assert!(!out.status.success());
    assert!(
        err.contains("\"../../escape3\"") && err.contains("videos[0].name"),
        "{err}"
    );
    assert!(!tmp.path().join("escape3.txt").exists());
    assert!(!tmp.path().parent().unwrap().join("escape3.txt").exists());
}

#[test]
fn track_writes_plain_video_names_inside_out() {
    let tmp = TestDir::new();
    let (ann, det) = write_dataset(tmp.path(), r#""folder_name": "DJI_0001.v2""#, 5);
    let out_dir = tmp.path().join("out");
    let args = track_args(&ann, &det, &out_dir);
    let out = mgmot(&args);
    assert_ok(&args, &out);
    for f in ["DJI_0001.v2.txt", "DJI_0001.v2_tracks.csv", "summary.json"] {
        assert!(out_dir.join(f).is_file(), "{f} missing");
    }
}

/// Runs `mgmot` expecting clap to refuse `flag`'s value.
fn assert_flag_refused(args: &[&str], flag: &str) {
    let out = mgmot(args);
    let err = stderr(&out);
    assert!(!out.status.success(), "mgmot {args:?} succeeded");
    assert_eq!(out.status.code(), Some(2), "mgmot {args:?}: {err}");
    assert!(err.contains(flag), "mgmot {args:?}: {err}");
}

#[test]
fn geolocate_refuses_non_finite_and_out_of_range_noise() {
    let tmp = TestDir::new();
    let (ann, _) = write_dataset(tmp.path(), r#""folder_name": "v""#, 2);
    let out_csv = tmp.path().join("geo.csv");
    let base = [
        "geolocate",
        "--annotations",
        ann.to_str().unwrap(),
        "--out",
        out_csv.to_str().unwrap(),
    ];
    // Sanity: the data geolocates, with a finite position std.
    let out = mgmot(&base);
    assert_ok(&base, &out);
    let text = std::fs::read_to_string(&out_csv).unwrap();
    let row = text.lines().nth(1).expect("a geolocated row");
    let h_std: f64 = row.rsplit(',').next().unwrap().parse().unwrap();
    assert!(h_std.is_finite() && h_std > 0.0, "{row}");
    std::fs::remove_file(&out_csv).unwrap();

    for (flag, values) in [
        ("--attitude-std-deg", &["nan", "inf", "1e308", "90"][..]),
        ("--altitude-std-m", &["nan", "inf", "1e308"][..]),
        ("--pixel-std-px", &["NaN", "infinity", "1e308"][..]),
        ("--fov-deg", &["nan", "inf", "0", "180"][..]),
    ] {
        for v in values {
            let mut args = base.to_vec();
            args.extend([flag, v]);
            assert_flag_refused(&args, flag);
        }
        // Negative values given with `=` reach the parser (a separate `-1` is taken for a flag).
        for v in ["-1", "-inf"] {
            let with_eq = format!("{flag}={v}");
            let mut args = base.to_vec();
            args.push(&with_eq);
            assert_flag_refused(&args, flag);
        }
    }
    assert!(
        !out_csv.exists(),
        "a refused run wrote {}",
        out_csv.display()
    );
}

#[test]
fn track_refuses_non_finite_and_out_of_range_numbers() {
    let tmp = TestDir::new();
    let (ann, det) = write_dataset(tmp.path(), r#""folder_name": "v""#, 3);
    let out_dir = tmp.path().join("out");
    let base = track_args(&ann, &det, &out_dir);
    for (flag, values) in [
        (
            "--metadata-lag-s",
            &["nan", "inf", "=-inf", "1e308", "=-61"][..],
        ),
        ("--fps", &["0", "nan", "inf", "=-30", "1e308"][..]),
        ("--fov-deg", &["nan", "0", "180", "inf"][..]),
    ] {
        for v in values {
            let mut args = base.clone();
            let joined = format!("{flag}{v}");
            if v.starts_with('=') {
                args.push(&joined);
            } else {
                args.extend([flag, v]);
            }
            assert_flag_refused(&args, flag);
        }
    }
    assert!(!out_dir.exists(), "a refused run created --out");
    // A metadata lead (negative lag) is a real case and still accepted, also as a separate
    // argument.
    let mut args = base.clone();
    args.extend(["--metadata-lag-s", "-0.5", "--fps", "25"]);
    let out = mgmot(&args);
    assert_ok(&args, &out);
}

#[test]
fn detect_refuses_non_finite_thresholds_naming_the_flag() {
    let model = concat!(env!("CARGO_MANIFEST_DIR"), "/models/mgmot-det-fp32.onnx");
    let image = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/fixtures/detect");
    let base = ["detect", "--model", model, image];
    for (flag, v) in [
        ("--score", "nan"),
        ("--score", "1.5"),
        ("--nms-iou", "inf"),
        ("--larger-box-iou", "nan"),
        ("--threads", "0"),
        ("--tile-size", "0"),
    ] {
        let mut args = base.to_vec();
        args.extend([flag, v]);
        assert_flag_refused(&args, flag);
    }
}

/// Runs `mgmot track` on the real SeaDronesSee subset with tracker parameters from a file.
fn track_real_with_params(dir: &Path, params: &str) -> (Output, PathBuf) {
    let config = dir.join("params.toml");
    std::fs::write(&config, params).unwrap();
    let out_dir = dir.join("out");
    let args = [
        "track",
        "--annotations",
        &real_data("val_subset_annotations.json"),
        "--detections",
        &real_data("val_subset_detections.json"),
        "--metadata-lag-s",
        "1.0",
        "--config",
        config.to_str().unwrap(),
        "--out",
        out_dir.to_str().unwrap(),
    ]
    .map(str::to_owned);
    (common::mgmot().args(&args).output(), out_dir)
}

#[test]
fn tracker_parameters_that_overflow_the_filter_are_refused() {
    let tmp = TestDir::new();
    for (params, key) in [
        (
            "[baseline]\nworld_accel_std_m_s2 = 1e308\n",
            "baseline.world_accel_std_m_s2",
        ),
        (
            "[baseline]\nworld_accel_std_m_s2 = inf\n",
            "baseline.world_accel_std_m_s2",
        ),
        ("[reid]\nmemory_max_s = nan\n", "reid.memory_max_s"),
        (
            "[reid.default_class]\nlambda_per_s = 1e300\n",
            "reid.default_class.lambda_per_s",
        ),
        (
            "[reid.classes.2]\ntau_match_m = 10.0\nmax_gate_m = 1e300\n",
            "reid.classes.2.max_gate_m",
        ),
    ] {
        let case = tempfile::tempdir_in(tmp.path()).unwrap();
        let (out, out_dir) = track_real_with_params(case.path(), params);
        let err = stderr(&out);
        assert!(!out.status.success(), "{params} accepted");
        assert!(err.contains(key), "{params}: {err}");
        assert!(!out_dir.exists(), "{params}: wrote results");
    }

    // At the bound the tracks stay finite.
    let (out, out_dir) =
        track_real_with_params(tmp.path(), "[baseline]\nworld_accel_std_m_s2 = 100.0\n");
    assert!(out.status.success(), "{}", stderr(&out));
    let mut rows = 0;
    for f in files_under(&out_dir) {
        if f.to_str().unwrap().ends_with("_tracks.csv") {
            let text = std::fs::read_to_string(&f).unwrap();
            for line in text.lines().skip(1) {
                rows += 1;
                for v in line.split(',') {
                    assert!(
                        v.parse::<f64>().map_or(true, f64::is_finite),
                        "{}: {line}",
                        f.display()
                    );
                }
            }
        }
    }
    assert!(rows > 0, "no geolocated track rows");
}
