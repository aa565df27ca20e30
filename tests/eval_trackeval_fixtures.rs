//! `mgmot eval` against results TrackEval itself produced.
//!
//! Every `tests/fixtures/eval/case*/` holds a random case written by
//! `scripts/eval_trackeval_harness.py`: ground truth in MOTChallenge layout
//! (`gt/<seq>/gt/gt.txt` + `seqinfo.ini`), results (`pred/<seq>.txt`), and
//! TrackEval's numbers (`expected.json`, and `expected_per_class.json` for the
//! per-class cases) from the TrackEval configuration documented in
//! `mgmot::eval`.

use std::path::{Path, PathBuf};

use crate::common::mgmot;

use serde_json::Value;

const RATIO_KEYS: [&str; 15] = [
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
    "Recall",
    "Precision",
];
const COUNT_KEYS: [&str; 7] = ["IDSW", "Frag", "MT", "PT", "ML", "FP", "FN"];
/// Our sums run in a different order than numpy's; anything beyond rounding is a bug.
const TOLERANCE: f64 = 1e-9;

fn fixture_cases() -> Vec<PathBuf> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/eval");
    let mut cases: Vec<PathBuf> = std::fs::read_dir(&root)
        .unwrap_or_else(|e| panic!("{}: {e}", root.display()))
        .map(|e| e.unwrap().path())
        .filter(|p| p.join("expected.json").is_file())
        .collect();
    cases.sort();
    assert!(
        !cases.is_empty(),
        "no fixture cases under {}",
        root.display()
    );
    cases
}

fn mgmot_eval_json(case: &Path, per_class: bool) -> Value {
    let mut cmd = mgmot();
    cmd.arg("eval")
        .arg("--gt")
        .arg(case.join("gt"))
        .arg("--pred")
        .arg(case.join("pred"))
        .arg("--json");
    if per_class {
        cmd.arg("--per-class");
    }
    let out = cmd.ok();
    serde_json::from_slice(&out.stdout).unwrap()
}

/// Walks both trees; metric objects are compared key by key.
fn compare(expected: &Value, actual: &Value, at: &str, problems: &mut Vec<String>) {
    match expected {
        Value::Object(e) if e.contains_key("HOTA") => {
            for k in RATIO_KEYS {
                let (x, y) = (e[k].as_f64().unwrap(), actual[k].as_f64());
                match y {
                    Some(y) if (x - y).abs() <= TOLERANCE => {}
                    _ => problems.push(format!("{at}.{k}: TrackEval {x}, mgmot {:?}", actual[k])),
                }
            }
            for k in COUNT_KEYS {
                if e[k].as_u64() != actual[k].as_u64() || actual[k].as_u64().is_none() {
                    problems.push(format!("{at}.{k}: TrackEval {}, mgmot {}", e[k], actual[k]));
                }
            }
        }
        Value::Object(e) => {
            let mut ek: Vec<&String> = e.keys().collect();
            let mut ak: Vec<&String> = actual
                .as_object()
                .map(|a| a.keys().collect())
                .unwrap_or_default();
            ek.sort();
            ak.sort();
            if ek != ak {
                problems.push(format!("{at}: keys {ek:?} vs {ak:?}"));
                return;
            }
            for (k, v) in e {
                compare(v, &actual[k], &format!("{at}.{k}"), problems);
            }
        }
        other => {
            if other != actual {
                problems.push(format!("{at}: TrackEval {other}, mgmot {actual}"));
            }
        }
    }
}

#[test]
fn class_agnostic_results_match_trackeval() {
    let mut problems = Vec::new();
    for case in fixture_cases() {
        let expected: Value =
            serde_json::from_str(&std::fs::read_to_string(case.join("expected.json")).unwrap())
                .unwrap();
        let name = case.file_name().unwrap().to_string_lossy().into_owned();
        compare(
            &expected,
            &mgmot_eval_json(&case, false),
            &name,
            &mut problems,
        );
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

#[test]
fn per_class_results_match_trackeval() {
    let mut problems = Vec::new();
    let mut checked = 0;
    for case in fixture_cases() {
        let path = case.join("expected_per_class.json");
        if !path.is_file() {
            continue;
        }
        checked += 1;
        let expected: Value =
            serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
        let name = case.file_name().unwrap().to_string_lossy().into_owned();
        compare(
            &expected,
            &mgmot_eval_json(&case, true),
            &name,
            &mut problems,
        );
    }
    assert!(checked > 0, "no per-class fixtures");
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}
