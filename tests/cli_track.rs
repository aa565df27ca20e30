//! `mgmot track` and `mgmot geolocate` run as real processes on the real SeaDronesSee subset.

use crate::common;

use common::{shared_data as data, TestDir};

/// `mgmot ARGS`, which must succeed.
fn mgmot(args: &[&str]) -> std::process::Output {
    common::mgmot().args(args).ok()
}

#[test]
fn tracks_real_detections_in_both_modes() {
    for mode in ["online", "offline"] {
        let dir = TestDir::new();
        let out_dir = dir.path().to_str().unwrap();
        let out = mgmot(&[
            "track",
            "--annotations",
            &data("val_subset_annotations.json"),
            "--detections",
            &data("val_subset_detections.json"),
            "--mode",
            mode,
            // SeaDronesSee's DJI metadata log lags the video by about 1 s.
            "--metadata-lag-s",
            "1.0",
            "--out",
            out_dir,
            "--json",
        ]);
        let summary: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        let videos = summary["videos"].as_array().unwrap();
        assert_eq!(videos.len(), 3);
        for v in videos {
            let name = v["video"].as_str().unwrap();
            assert_eq!(v["frames"], 60, "{name}");
            assert!(v["tracks"].as_u64().unwrap() > 0, "{name}: no tracks");
            // MOTChallenge results: one id at most once per frame, boxes finite.
            let text = std::fs::read_to_string(dir.path().join(format!("{name}.txt"))).unwrap();
            let mut seen = std::collections::HashSet::new();
            for line in text.lines() {
                let f: Vec<f64> = line.split(',').map(|x| x.parse().unwrap()).collect();
                assert_eq!(f.len(), 9, "{line}");
                assert!(
                    seen.insert((f[0] as u64, f[1] as i64)),
                    "{name}: duplicate id in a frame: {line}"
                );
                assert!(f[4] > 0.0 && f[5] > 0.0);
            }
            assert_eq!(seen.len() as u64, v["track_boxes"].as_u64().unwrap());
            // Geo tracks: every row near the drone (these videos stay within a few hundred m).
            let mut rdr =
                csv::Reader::from_path(dir.path().join(format!("{name}_tracks.csv"))).unwrap();
            let mut rows = 0;
            for rec in rdr.deserialize::<std::collections::HashMap<String, String>>() {
                let rec = rec.unwrap();
                let n: f64 = rec["north_m"].parse().unwrap();
                let e: f64 = rec["east_m"].parse().unwrap();
                let lat: f64 = rec["lat_deg"].parse().unwrap();
                assert!(n.hypot(e) < 2_000.0, "{name}: {n}, {e}");
                assert!((47.0..54.0).contains(&lat));
                rows += 1;
            }
            assert!(rows > 0, "{name}: no geolocated track rows");
        }
    }
}

#[test]
fn tracks_without_metadata() {
    let dir = TestDir::new();
    let out = mgmot(&[
        "track",
        "--annotations",
        &data("val_subset_annotations.json"),
        "--detections",
        &data("val_subset_detections.json"),
        "--no-metadata",
        "--out",
        dir.path().to_str().unwrap(),
        "--json",
    ]);
    let summary: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let videos = summary["videos"].as_array().unwrap();
    // The shared subset holds three validation videos: each must be tracked, none skipped.
    assert_eq!(videos.len(), 3, "{summary}");
    for v in videos {
        assert_eq!(v["detections_geolocated"], 0);
        assert!(v["tracks"].as_u64().unwrap() > 0);
    }
}

#[test]
fn geolocate_writes_the_documented_csv() {
    let dir = TestDir::new();
    let csv_path = dir.path().join("g.csv");
    let out = mgmot(&[
        "geolocate",
        "--annotations",
        &data("val_subset_annotations.json"),
        "--out",
        csv_path.to_str().unwrap(),
        "--json",
    ]);
    let summary: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let located = summary["located"].as_u64().unwrap();
    let skipped = summary["skipped"].as_array().unwrap().len() as u64;
    assert_eq!(
        located + skipped,
        1199,
        "every annotation is either located or reported"
    );
    let text = std::fs::read_to_string(&csv_path).unwrap();
    let mut lines = text.lines();
    assert_eq!(
        lines.next().unwrap(),
        "image_id,id,category_id,lat_deg,lon_deg,north_m,east_m,range_m,h_std_m"
    );
    assert_eq!(lines.count() as u64, located);
}

#[test]
fn bad_input_is_a_clear_error_not_a_panic() {
    let dir = TestDir::new();
    let bad = dir.path().join("bad.json");
    std::fs::write(
        &bad,
        r#"{"images": [{"id": 1, "width": 10, "height": 10, "meta": {"latitude": "north"}}]}"#,
    )
    .unwrap();
    let out = common::mgmot()
        .args([
            "geolocate",
            "--annotations",
            bad.to_str().unwrap(),
            "--out",
            "/tmp/x.csv",
        ])
        .output();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("bad.json") && err.contains("images[0].meta.latitude"),
        "{err}"
    );
    let det = dir.path().join("det.txt");
    std::fs::write(&det, "1,-1,10,10,5,5,0.9,1\n2,-1,10,10,oops,5,0.9,1\n").unwrap();
    let out = common::mgmot()
        .args([
            "track",
            "--annotations",
            &data("val_subset_annotations.json"),
            "--detections",
            det.to_str().unwrap(),
            "--video",
            "DJI_0032",
            "--out",
            dir.path().to_str().unwrap(),
        ])
        .output();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("det.txt:2") && err.contains("width"), "{err}");
}
