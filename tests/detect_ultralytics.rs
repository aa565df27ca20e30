//! An Ultralytics YOLOv8 / YOLO11 export drops into `mgmot detect` and `mgmot run` unchanged:
//! class NAMES, not class indices, decide the SeaDronesSee category ids.
//!
//! `scripts/detect_make_ultralytics.py` (python3 from PATH with `onnx` and numpy:
//! scripts/requirements-test.txt, `.venv/bin` in scripts/test.sh) writes the shipped fp32
//! model with its class rows permuted by a Gather on `output0` and Ultralytics' metadata
//! (`names` as a Python dict literal in the new order). Both files must give the same boxes
//! with the same `category_id`, on both backends. The class counts come from the shipped
//! model's metadata (two classes today, SeaDronesSee's five after the retraining).
//!
//! The ONNX Runtime test needs its library named by `ORT_DYLIB_PATH`; without it, or
//! without python3 and `onnx`, the tests fail saying so (never a skip).

use crate::common;

use common::{mgmot, missing_tool, repo_file, require_python, TestCommand, TestDir};
use mgmot::camera::{CaptureTime, Frame};
use mgmot::detect::model::read_metadata;
use mgmot::detect::{Detector, DetectorConfig, ModelInfo};
use mgmot::pipeline::{DetectStage, OnnxStage};
use mgmot::telemetry::AutopilotTimeUs;
use serde_json::Value;
use std::path::{Path, PathBuf};

const FP32: &str = "models/mgmot-det-fp32.onnx";
const SCRIPT: &str = "scripts/detect_make_ultralytics.py";

/// SeaDronesSee's categories in id order (id = index + 1), written out here rather than taken
/// from the code under test.
const SEADRONESSEE: [&str; 5] = [
    "swimmer",
    "boat",
    "jetski",
    "life_saving_appliances",
    "buoy",
];

fn fixtures() -> PathBuf {
    repo_file("tests/fixtures/detect")
}

/// The class names in a model file's metadata.
fn names_of(model: &Path) -> Vec<String> {
    let bytes = std::fs::read(model).unwrap_or_else(|e| panic!("{}: {e}", model.display()));
    read_metadata(model, &bytes)
        .unwrap()
        .class_names
        .unwrap_or_else(|| panic!("{}: no `names` metadata", model.display()))
}

/// Runs the script on the shipped fp32 model, writing `dir/name`; its path.
fn make_model(test: &str, dir: &TestDir, name: &str, extra: &[&str]) -> PathBuf {
    require_python(test, &["onnx", "numpy"]);
    let out = dir.path().join(name);
    let run = TestCommand::new("python3")
        .arg(repo_file(SCRIPT))
        .arg("--model")
        .arg(repo_file(FP32))
        .arg("--out")
        .arg(&out)
        .args(extra)
        .output();
    assert!(
        run.status.success() && out.is_file(),
        "{test}: {SCRIPT} failed (python3 from PATH needs onnx and numpy, \
         scripts/requirements-test.txt, e.g. .venv/bin/python3): {}\n{}",
        run.status,
        String::from_utf8_lossy(&run.stderr)
    );
    out
}

/// The permuted model and, for each of its classes, the shipped model's index of that class
/// (new class j = shipped class `perm[j]`). Asserts the order really differs, so that a
/// detector mapping indices instead of names would fail the comparisons.
fn permuted_model(test: &str, dir: &TestDir) -> (PathBuf, Vec<usize>) {
    let model = make_model(test, dir, "yolo_export.onnx", &[]);
    let shipped = names_of(&repo_file(FP32));
    let permuted = names_of(&model);
    assert_eq!(permuted.len(), shipped.len(), "{permuted:?} vs {shipped:?}");
    let perm: Vec<usize> = permuted
        .iter()
        .map(|n| {
            shipped
                .iter()
                .position(|s| s == n)
                .unwrap_or_else(|| panic!("class {n} of the export is not in {shipped:?}"))
        })
        .collect();
    assert!(
        perm.iter().enumerate().any(|(j, &i)| i != j),
        "the export lists the classes in the shipped order {shipped:?}: nothing is tested"
    );
    // The metadata is Ultralytics': a Python dict literal, and its other keys.
    let bytes = std::fs::read(&model).unwrap();
    let text = String::from_utf8_lossy(&bytes);
    let dict = permuted
        .iter()
        .enumerate()
        .map(|(i, n)| format!("{i}: '{n}'"))
        .collect::<Vec<_>>()
        .join(", ");
    for needle in [
        format!("{{{dict}}}"),
        "Ultralytics".into(),
        "[448, 800]".into(),
    ] {
        assert!(
            text.contains(&needle),
            "the export's metadata lacks {needle}"
        );
    }
    (model, perm)
}

/// `mgmot detect --json` on the fixture frames.
fn detect_json(model: &Path, backend: &str, extra: &[&str]) -> Vec<Value> {
    let out = mgmot()
        .args(["detect", "--json", "--model"])
        .arg(model)
        .arg(fixtures())
        .args(["--backend", backend])
        .args(extra)
        .output();
    assert!(
        out.status.success(),
        "mgmot detect --model {} --backend {backend} failed: {}",
        model.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice::<Value>(&out.stdout)
        .unwrap()
        .as_array()
        .unwrap()
        .clone()
}

/// Each detection as (image, category id, category name, box, score), sorted.
fn keyed(results: &[Value]) -> Vec<(u64, u64, String, [f64; 4], f64)> {
    let mut v: Vec<_> = results
        .iter()
        .map(|r| {
            let b = |i: usize| r["bbox"][i].as_f64().unwrap();
            (
                r["image_id"].as_u64().unwrap(),
                r["category_id"].as_u64().unwrap(),
                r["category_name"].as_str().unwrap().to_string(),
                [b(0), b(1), b(2), b(3)],
                r["score"].as_f64().unwrap(),
            )
        })
        .collect();
    v.sort_by(|a, b| {
        (a.0, a.1)
            .cmp(&(b.0, b.1))
            .then(a.3.partial_cmp(&b.3).unwrap())
    });
    v
}

/// Same boxes (1e-3 px), scores (1e-5), category ids and names, one for one.
fn assert_same_detections(shipped: &[Value], export: &[Value], what: &str) {
    let (a, b) = (keyed(shipped), keyed(export));
    assert!(!a.is_empty(), "{what}: no detections to compare");
    assert_eq!(a.len(), b.len(), "{what}: {a:?}\nvs\n{b:?}");
    for (x, y) in a.iter().zip(&b) {
        let close = (0..4).all(|i| (x.3[i] - y.3[i]).abs() <= 1e-3) && (x.4 - y.4).abs() <= 1e-5;
        assert!(
            x.0 == y.0 && x.1 == y.1 && x.2 == y.2 && close,
            "{what}: shipped {x:?} vs export {y:?}"
        );
    }
}

/// The detections really cover a class whose index differs between the two models (else
/// index + 1 would pass as well).
fn assert_a_moved_class_was_detected(results: &[Value], shipped: &[String], export: &[String]) {
    let moved = results.iter().any(|r| {
        let name = r["category_name"].as_str().unwrap();
        shipped.iter().position(|n| n == name) != export.iter().position(|n| n == name)
    });
    assert!(
        moved,
        "no detection of a class whose index moved ({shipped:?} -> {export:?}): {results:?}"
    );
}

fn cli_parity(test: &str, backend: &str, extra: &[&str]) {
    let dir = TestDir::new();
    let (export, _) = permuted_model(test, &dir);
    let shipped = detect_json(&repo_file(FP32), backend, extra);
    let permuted = detect_json(&export, backend, extra);
    assert_same_detections(&shipped, &permuted, &format!("{test} ({backend})"));
    assert_a_moved_class_was_detected(&shipped, &names_of(&repo_file(FP32)), &names_of(&export));
    // The ids are SeaDronesSee's for the names.
    for r in &shipped {
        let name = r["category_name"].as_str().unwrap();
        let id = SEADRONESSEE.iter().position(|n| *n == name).unwrap() + 1;
        assert_eq!(r["category_id"].as_u64(), Some(id as u64), "{r}");
    }
}

#[test]
fn an_ultralytics_export_in_another_class_order_detects_the_same_on_tract() {
    cli_parity("detect_ultralytics tract", "tract", &[]);
}

#[test]
fn an_ultralytics_export_in_another_class_order_detects_the_same_on_onnxruntime() {
    const TEST: &str = "detect_ultralytics onnxruntime";
    let lib = match std::env::var_os("ORT_DYLIB_PATH").filter(|v| !v.is_empty()) {
        Some(p) if Path::new(&p).is_file() => PathBuf::from(p),
        Some(p) => missing_tool(
            TEST,
            &format!("ORT_DYLIB_PATH={} is not a file", Path::new(&p).display()),
        ),
        None => missing_tool(TEST, "ORT_DYLIB_PATH is not set"),
    };
    cli_parity(TEST, "onnxruntime", &["--ort-lib", lib.to_str().unwrap()]);
}

fn load(model: &Path) -> ModelInfo {
    Detector::load(DetectorConfig::new(model))
        .unwrap_or_else(|e| panic!("{}: {e}", model.display()))
        .model()
        .clone()
}

/// The category id SeaDronesSee gives `name` (by this test's own table).
fn seadronessee_id(name: &str) -> u32 {
    SEADRONESSEE
        .iter()
        .position(|n| *n == name)
        .map_or(0, |i| i as u32 + 1)
}

#[test]
fn the_loaded_export_reports_category_ids_from_its_names() {
    let dir = TestDir::new();
    let (export, perm) = permuted_model("detect_ultralytics category ids", &dir);
    let shipped = load(&repo_file(FP32));
    let permuted = load(&export);
    let expected: Vec<u32> = shipped
        .class_names
        .iter()
        .map(|n| seadronessee_id(n))
        .collect();
    assert!(!expected.contains(&0), "{:?}", shipped.class_names);
    assert_eq!(shipped.category_ids, expected);
    let expected: Vec<u32> = perm.iter().map(|&i| shipped.category_ids[i]).collect();
    assert_eq!(
        permuted.category_ids, expected,
        "{:?}",
        permuted.class_names
    );
    assert_ne!(permuted.category_ids, shipped.category_ids);
    for (j, &i) in perm.iter().enumerate() {
        assert_eq!(permuted.category_id(j), shipped.category_id(i));
    }
}

/// The fixture frames (every `.jpg` of tests/fixtures/detect).
fn fixture_frames() -> Vec<PathBuf> {
    let mut frames: Vec<PathBuf> = std::fs::read_dir(fixtures())
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "jpg"))
        .collect();
    frames.sort();
    assert!(!frames.is_empty(), "no .jpg in {}", fixtures().display());
    frames
}

/// A fixture frame as the runtime's capture hands it over.
fn fixture_frame(path: &Path) -> Frame {
    let image = image::open(path).unwrap().to_rgb8();
    Frame {
        index: 0,
        captured: CaptureTime::Autopilot(AutopilotTimeUs(0)),
        width_px: image.width(),
        height_px: image.height(),
        rgb: image.into_raw(),
    }
}

/// `mgmot run`'s detect stage: the export gives the tracker the same SeaDronesSee class ids.
#[test]
fn the_runtime_detect_stage_gives_the_export_the_same_class_ids() {
    let dir = TestDir::new();
    let (export, perm) = permuted_model("detect_ultralytics runtime stage", &dir);
    let mut shipped = OnnxStage::load(DetectorConfig::new(repo_file(FP32))).unwrap();
    let mut permuted = OnnxStage::load(DetectorConfig::new(&export)).unwrap();
    let mut ids_seen = Vec::new();
    for path in fixture_frames() {
        let name = path.display();
        let key =
            |d: &mgmot::track::Detection| (d.class_id, d.bbox.x, d.bbox.y, d.bbox.w, d.bbox.h);
        let mut a: Vec<_> = shipped.detect(fixture_frame(&path)).unwrap();
        let mut b: Vec<_> = permuted.detect(fixture_frame(&path)).unwrap();
        a.sort_by(|x, y| key(x).partial_cmp(&key(y)).unwrap());
        b.sort_by(|x, y| key(x).partial_cmp(&key(y)).unwrap());
        assert_eq!(a.len(), b.len(), "{name}: {a:?}\nvs\n{b:?}");
        for (x, y) in a.iter().zip(&b) {
            assert_eq!(x.class_id, y.class_id, "{name}: {x:?} vs {y:?}");
            for (p, q) in [
                (x.bbox.x, y.bbox.x),
                (x.bbox.y, y.bbox.y),
                (x.bbox.w, y.bbox.w),
                (x.bbox.h, y.bbox.h),
            ] {
                assert!((p - q).abs() <= 1e-3, "{name}: {x:?} vs {y:?}");
            }
            assert!((x.score - y.score).abs() <= 1e-5, "{name}: {x:?} vs {y:?}");
        }
        ids_seen.extend(a.iter().map(|d| d.class_id));
    }
    let valid: Vec<u32> = shipped.model().category_ids.clone();
    assert!(
        ids_seen.iter().all(|id| valid.contains(id)),
        "{ids_seen:?} not all in {valid:?}"
    );
    // Some detection is of a class whose index differs between the two models (else index + 1
    // would pass as well).
    let moved: Vec<u32> = perm
        .iter()
        .enumerate()
        .filter(|(j, i)| j != *i)
        .map(|(_, &i)| valid[i])
        .collect();
    assert!(
        ids_seen.iter().any(|id| moved.contains(id)),
        "no detection of a moved class {moved:?}: {ids_seen:?}"
    );
}

/// A class that is none of SeaDronesSee's (`kayak`) is category 0; the others keep theirs, and
/// loading says so at WARN.
#[test]
fn a_class_that_is_not_seadronessees_is_category_zero_with_a_warning() {
    let dir = TestDir::new();
    let shipped_names = names_of(&repo_file(FP32));
    assert!(
        shipped_names.iter().any(|n| n == "boat"),
        "{shipped_names:?}"
    );
    let model = make_model(
        "detect_ultralytics unknown class",
        &dir,
        "kayak.onnx",
        &["--rename", "boat=kayak"],
    );
    let names = names_of(&model);
    assert_eq!(names[..2], ["kayak", "swimmer"], "{names:?}");
    let info = load(&model);
    assert_eq!(info.category_ids[..2], [0, 1], "{names:?}");
    for (name, id) in names.iter().zip(&info.category_ids).skip(2) {
        assert_eq!(*id, seadronessee_id(name), "{name}");
    }
    // `mgmot detect` (the same load as `mgmot run`'s) warns, naming the class, and writes 0.
    let out = mgmot()
        .args(["detect", "--json", "--backend", "tract", "--model"])
        .arg(&model)
        .arg(fixtures())
        .output();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    let warning = stderr
        .lines()
        .find(|l| l.contains("WARN") && l.contains("kayak"))
        .unwrap_or_else(|| panic!("no warning naming kayak: {stderr}"));
    assert!(warning.contains("category 0"), "{warning}");
    let results: Vec<Value> = serde_json::from_slice(&out.stdout).unwrap();
    let mut kayaks = 0;
    for r in &results {
        let expected = match r["category_name"].as_str().unwrap() {
            "kayak" => {
                kayaks += 1;
                0
            }
            name => u64::from(seadronessee_id(name)),
        };
        assert_eq!(r["category_id"].as_u64(), Some(expected), "{r}");
    }
    assert!(
        kayaks > 0,
        "no kayak (the shipped boat) detected: {results:?}"
    );
}
