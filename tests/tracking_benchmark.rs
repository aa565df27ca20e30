//! Regression guard of the tracking benchmark (docs/benchmark.md, "Tracking benchmark"): every long search
//! mission at its own seed, the simulated detector's boxes tracked online (as flown, and with
//! provisional tracks withheld) and offline by the real binaries, scored by `mgmot eval`. A test fails when IDF1
//! drops more than [`TOLERANCE`] below the committed table (the default-seed rows of
//! `scripts/bench_tracking.sh`). The identity oracle (`mgmot oracle`) is printed beside.

use crate::common;

use std::path::Path;

use common::{mgmot, sim, TestDir};

/// How far IDF1 may fall below the committed table.
const TOLERANCE: f64 = 0.05;

/// IDF1 of one mission in `mgmot eval --json` output.
fn idf1(gt: &Path, pred: &Path) -> f64 {
    let out = mgmot()
        .arg("eval")
        .arg("--gt")
        .arg(gt)
        .arg("--pred")
        .arg(pred)
        .arg("--json")
        .ok();
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("eval --json output");
    v["IDF1"].as_f64().expect("IDF1 in eval --json")
}

/// Runs one mission and checks it against the committed IDF1 (online as flown, online with
/// provisional tracks withheld, offline).
fn mission(scenario: &str, committed: Committed) {
    let dir = TestDir::new();
    let det = dir.join("det.txt");
    let gt_dir = dir.join("gt");
    sim()
        .args([
            "detections",
            "--scenario",
            scenario,
            "--appearance",
            "--out",
        ])
        .arg(&det)
        .arg("--gt-dir")
        .arg(&gt_dir)
        .ok();
    let gt = gt_dir.join("gt/gt.txt");
    let ann = gt_dir.join("annotations.json");
    let oracle = dir.join("oracle.txt");
    mgmot()
        .arg("oracle")
        .arg("--gt")
        .arg(&gt)
        .arg("--detections")
        .arg(&det)
        .arg("--out")
        .arg(&oracle)
        .ok();
    let oracle_idf1 = idf1(&gt, &oracle);
    for (mode, committed, extra) in [
        ("online", committed.online, None),
        (
            "online",
            committed.online_withheld,
            Some("--withhold-provisional"),
        ),
        ("offline", committed.offline, None),
    ] {
        let label = if extra.is_some() {
            "online withheld"
        } else {
            mode
        };
        let out = dir.join(label.replace(' ', "_"));
        let mut cmd = mgmot();
        cmd.arg("track")
            .arg("--annotations")
            .arg(&ann)
            .arg("--detections")
            .arg(&det)
            .args(["--mode", mode])
            .args(extra)
            .arg("--json")
            .arg("--out")
            .arg(&out);
        cmd.ok();
        let pred = std::fs::read_dir(&out)
            .expect("track output folder")
            .filter_map(Result::ok)
            .map(|e| e.path())
            .find(|p| p.extension().is_some_and(|x| x == "txt"))
            .expect("a MOTChallenge results file");
        let got = idf1(&gt, &pred);
        eprintln!(
            "{scenario} {label}: IDF1 {got:.3} (committed {committed:.3}, oracle {oracle_idf1:.3})"
        );
        assert!(
            got >= committed - TOLERANCE,
            "{scenario} {label}: IDF1 {got:.3} fell more than {TOLERANCE} below the committed {committed:.3}"
        );
    }
}

#[test]
fn mixed_mission_soak_keeps_its_identities() {
    mission("mixed_mission_soak", MIXED);
}

#[test]
fn lawnmower_search_keeps_its_identities() {
    mission("lawnmower_search", LAWNMOWER);
}

#[test]
fn expanding_square_keeps_its_identities() {
    mission("expanding_square", SQUARE);
}

#[test]
fn sector_search_keeps_its_identities() {
    mission("sector_search", SECTOR);
}

/// Committed IDF1 of one mission.
struct Committed {
    /// Online, every confirmed track (the paper's convention).
    online: f64,
    /// Online, provisional tracks withheld.
    online_withheld: f64,
    /// Offline.
    offline: f64,
}

// The committed table (docs/benchmark.md, "Current results", 2026-12-07, seed "default"; the
// detections carry their colour signatures, `mgmot-sim detections --appearance`, as in the table).
const MIXED: Committed = Committed {
    online: 0.862,
    online_withheld: 0.848,
    offline: 0.917,
};
const LAWNMOWER: Committed = Committed {
    online: 0.945,
    online_withheld: 0.931,
    offline: 0.974,
};
const SQUARE: Committed = Committed {
    online: 0.933,
    online_withheld: 0.912,
    offline: 0.962,
};
/// Re-committed on 2026-12-06 after the renderer's realism (issue 41): the colour signatures
/// `mgmot-sim detections --appearance` computes from the new renders (shading, camera noise,
/// object variants) keep fewer wrong links from the swimmers' 0.6 appearance gate here (online
/// 0.906 -> 0.824, withheld 0.894 -> 0.812, offline 0.940 -> 0.874 with the same boxes; with
/// the gate off, 0.759 before and after). The gate was re-measured on the new renders on
/// 2026-12-07 over tuning and validation seeds and kept at 0.6 (docs/benchmark.md, "The
/// appearance gate re-measured on the new renders").
const SECTOR: Committed = Committed {
    online: 0.824,
    online_withheld: 0.812,
    offline: 0.874,
};
