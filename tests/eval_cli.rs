//! `mgmot eval` end to end: output shapes, folder layouts and error messages.

use std::path::Path;
use std::process::Output;

use crate::common::{mgmot, TestDir};

use serde_json::Value;

const KEYS: [&str; 22] = [
    "HOTA",
    "DetA",
    "AssA",
    "DetRe",
    "DetPr",
    "AssRe",
    "AssPr",
    "LocA",
    "MOTA",
    "MOTP",
    "IDF1",
    "IDR",
    "IDP",
    "IDSW",
    "Frag",
    "MT",
    "PT",
    "ML",
    "FP",
    "FN",
    "Recall",
    "Precision",
];

fn eval(gt: &Path, pred: &Path, extra: &[&str]) -> Output {
    mgmot()
        .arg("eval")
        .arg("--gt")
        .arg(gt)
        .arg("--pred")
        .arg(pred)
        .args(extra)
        .output()
}

fn write(path: &Path, text: &str) {
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    std::fs::write(path, text).unwrap();
}

const GT: &str =
    "1,1,0,0,10,10,1,1,1\n2,1,0,0,10,10,1,1,1\n3,1,0,0,10,10,1,1,1\n4,1,0,0,10,10,1,1,1\n";
/// Perfect boxes, but the id changes after frame 2: one IDSW, IDF1 0.5.
const PRED: &str = "1,5,0,0,10,10,0.9,-1,-1,-1\n2,5,0,0,10,10,0.9,-1,-1,-1\n3,6,0,0,10,10,0.9,-1,-1,-1\n4,6,0,0,10,10,0.9,-1,-1,-1\n";

#[test]
fn two_files_give_one_flat_object_with_exactly_the_documented_keys() {
    let dir = TestDir::new();
    let (gt, pred) = (dir.path().join("gt.txt"), dir.path().join("pred.txt"));
    write(&gt, GT);
    write(&pred, PRED);
    let out = eval(&gt, &pred, &["--json"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: Value = serde_json::from_slice(&out.stdout).unwrap();
    let mut keys: Vec<&str> = v.as_object().unwrap().keys().map(String::as_str).collect();
    keys.sort_unstable();
    let mut want = KEYS.to_vec();
    want.sort_unstable();
    assert_eq!(keys, want);
    assert_eq!(v["IDSW"], 1);
    assert!(v["IDSW"].is_u64() && v["FP"].is_u64());
    assert!((v["MOTA"].as_f64().unwrap() - 0.75).abs() < 1e-12);
    assert!((v["IDF1"].as_f64().unwrap() - 0.5).abs() < 1e-12);
}

#[test]
fn table_output_names_the_metrics() {
    let dir = TestDir::new();
    let (gt, pred) = (dir.path().join("gt.txt"), dir.path().join("pred.txt"));
    write(&gt, GT);
    write(&pred, PRED);
    let out = eval(&gt, &pred, &[]);
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    for k in ["HOTA", "MOTA", "IDF1", "COMBINED"] {
        assert!(text.contains(k), "{text}");
    }
}

#[test]
fn folders_in_both_layouts_give_sequences_and_combined() {
    let dir = TestDir::new();
    let gt = dir.path().join("gt");
    let pred = dir.path().join("pred");
    write(&gt.join("a/gt/gt.txt"), GT);
    write(
        &gt.join("a/seqinfo.ini"),
        "[Sequence]\nname=a\nseqLength=4\n",
    );
    write(&gt.join("b.txt"), GT);
    write(&pred.join("a.txt"), PRED);
    write(&pred.join("b.txt"), GT);
    write(&pred.join("unrelated.txt"), GT);
    let out = eval(&gt, &pred, &["--json"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["sequences"]["a"]["IDSW"], 1);
    assert_eq!(v["sequences"]["b"]["IDF1"], 1.0);
    assert_eq!(v["combined"]["IDSW"], 1);
    // (8 TP - 1 IDSW) / 8 GT.
    assert!((v["combined"]["MOTA"].as_f64().unwrap() - 7.0 / 8.0).abs() < 1e-12);
}

#[test]
fn per_class_reports_each_class_and_the_class_combinations() {
    let dir = TestDir::new();
    let (gt, pred) = (dir.path().join("gt.txt"), dir.path().join("pred.txt"));
    write(&gt, "1,1,0,0,10,10,1,1,1\n1,2,50,0,10,10,1,2,1\n");
    write(&pred, "1,1,0,0,10,10,1,1\n1,2,50,0,10,10,1,1\n");
    let out = eval(&gt, &pred, &["--json", "--per-class"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["classes"]["1"]["FP"], 1);
    assert_eq!(v["classes"]["2"]["FN"], 1);
    assert_eq!(v["detection_averaged"]["FP"], 1);
    assert!(v["class_averaged"]["HOTA"].is_number());
}

#[test]
fn malformed_line_is_reported_with_file_and_line() {
    let dir = TestDir::new();
    let (gt, pred) = (dir.path().join("gt.txt"), dir.path().join("pred.txt"));
    write(&gt, GT);
    write(&pred, "1,5,0,0,10,10\n2,5,0,0,ten,10\n");
    let out = eval(&gt, &pred, &["--json"]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("pred.txt:2:") && err.contains("\"ten\" is not a number"),
        "{err}"
    );
}

#[test]
fn duplicate_id_and_frame_beyond_seq_length_are_errors() {
    let dir = TestDir::new();
    let (gt, pred) = (dir.path().join("gt.txt"), dir.path().join("pred.txt"));
    write(&gt, GT);
    write(&pred, "1,5,0,0,10,10\n1,5,3,0,10,10\n");
    let err = String::from_utf8(eval(&gt, &pred, &[]).stderr).unwrap();
    assert!(
        err.contains("pred.txt:2: id 5 occurs twice in frame 1"),
        "{err}"
    );

    let gt_dir = dir.path().join("g");
    let pred_dir = dir.path().join("p");
    write(&gt_dir.join("s/gt/gt.txt"), GT);
    write(&gt_dir.join("s/seqinfo.ini"), "[Sequence]\nseqLength=3\n");
    write(&pred_dir.join("s.txt"), PRED);
    let err = String::from_utf8(eval(&gt_dir, &pred_dir, &[]).stderr).unwrap();
    assert!(
        err.contains("gt.txt:4: frame 4 is beyond the sequence length 3"),
        "{err}"
    );
}

#[test]
fn missing_prediction_sequence_is_named() {
    let dir = TestDir::new();
    let gt = dir.path().join("gt");
    let pred = dir.path().join("pred");
    write(&gt.join("MOT-02/gt/gt.txt"), GT);
    write(&pred.join("other.txt"), PRED);
    let out = eval(&gt, &pred, &[]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("sequence MOT-02: no results file"), "{err}");
}

#[test]
fn file_and_folder_cannot_be_mixed() {
    let dir = TestDir::new();
    let gt = dir.path().join("gt.txt");
    write(&gt, GT);
    let out = eval(&gt, dir.path(), &[]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("both be files or both be folders"));
}

#[test]
fn empty_files_evaluate_without_error() {
    let dir = TestDir::new();
    let (gt, pred) = (dir.path().join("gt.txt"), dir.path().join("pred.txt"));
    write(&gt, "");
    write(&pred, "");
    let out = eval(&gt, &pred, &["--json"]);
    assert!(out.status.success());
    let v: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(
        (v["HOTA"].as_f64(), v["LocA"].as_f64()),
        (Some(0.0), Some(1.0))
    );
}
