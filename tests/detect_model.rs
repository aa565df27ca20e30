//! The detector on the shipped model and on broken models, through the
//! pure-Rust tract backend (no system library needed, so this always runs).

use std::path::{Path, PathBuf};

use mgmot::detect::{
    BackendConfig, BackendKind, DetectError, Detector, DetectorConfig, OutputLayout, PixelBox,
    TilingConfig,
};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn fixture(name: &str) -> PathBuf {
    root().join("tests/fixtures/detect").join(name)
}

const INT8: &str = "models/mgmot-det-int8.onnx";
const FP32: &str = "models/mgmot-det-fp32.onnx";

fn load(path: &Path) -> Result<Detector, DetectError> {
    Detector::load(DetectorConfig::new(path))
}

/// Ground-truth boxes of one fixture image: (class id, box).
fn ground_truth(file_name: &str) -> Vec<(usize, PixelBox)> {
    let text = std::fs::read_to_string(fixture("gt.json")).unwrap();
    let doc: serde_json::Value = serde_json::from_str(&text).unwrap();
    let id = doc["images"]
        .as_array()
        .unwrap()
        .iter()
        .find(|im| im["file_name"] == file_name)
        .unwrap()["id"]
        .as_u64()
        .unwrap();
    doc["annotations"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|a| a["image_id"].as_u64() == Some(id))
        .map(|a| {
            let b: Vec<f32> = a["bbox"]
                .as_array()
                .unwrap()
                .iter()
                .map(|v| v.as_f64().unwrap() as f32)
                .collect();
            (
                a["category_id"].as_u64().unwrap() as usize - 1,
                PixelBox {
                    x_px: b[0],
                    y_px: b[1],
                    w_px: b[2],
                    h_px: b[3],
                },
            )
        })
        .collect()
}

#[test]
fn shipped_models_load_with_their_metadata() {
    for model in [INT8, FP32] {
        let d = load(&root().join(model)).unwrap();
        let info = d.model();
        assert_eq!(info.class_names, vec!["swimmer", "boat"], "{model}");
        assert_eq!((info.input_width_px, info.input_height_px), (320, 320));
        assert_eq!(info.layout, OutputLayout::ChannelsFirst);
        // (320/8)^2 + (320/16)^2 + (320/32)^2 candidates.
        assert_eq!(info.num_candidates, 1600 + 400 + 100);
        assert_eq!(d.backend(), BackendKind::Tract);
    }
}

#[test]
fn shipped_model_finds_the_objects_in_held_out_frames() {
    let mut d = load(&root().join(INT8)).unwrap();
    let mut matched = 0;
    let mut total = 0;
    let mut false_positives = 0;
    for name in ["sea_2000003.jpg", "sea_2000011.jpg"] {
        let frame = image::open(fixture(name)).unwrap().to_rgb8();
        let dets = d.detect(&frame).unwrap();
        let gt = ground_truth(name);
        total += gt.len();
        for (class, g) in &gt {
            if dets
                .iter()
                .any(|x| x.class_id == *class && x.bbox.iou(g) >= 0.5)
            {
                matched += 1;
            }
        }
        false_positives += dets
            .iter()
            .filter(|x| {
                !gt.iter()
                    .any(|(c, g)| *c == x.class_id && x.bbox.iou(g) >= 0.5)
            })
            .count();
        for x in &dets {
            assert!(x.bbox.x_px >= 0.0 && x.bbox.x_px + x.bbox.w_px <= frame.width() as f32 + 1e-3);
            assert!(x.score >= 0.25 && x.score <= 1.0);
        }
    }
    assert!(total > 0);
    // The provisional model (models/README.md) is weak; these bounds record
    // what it does reach on these frames rather than an aspiration.
    assert!(matched * 2 >= total, "matched {matched} of {total} objects");
    assert!(
        false_positives <= total,
        "{false_positives} false positives for {total} objects"
    );
}

#[test]
fn tiling_keeps_full_frame_detections_and_maps_tiles_back() {
    let path = root().join(INT8);
    let frame = image::open(fixture("sea_2000003.jpg")).unwrap().to_rgb8();
    // Upscale 2x so the 480x320 frame needs several 320 px tiles.
    let big = image::imageops::resize(
        &frame,
        frame.width() * 2,
        frame.height() * 2,
        image::imageops::FilterType::Triangle,
    );
    let mut cfg = DetectorConfig::new(&path);
    cfg.tiling = Some(TilingConfig::default());
    let mut tiled = Detector::load(cfg).unwrap();
    let dets = tiled.detect(&big).unwrap();
    let gt = ground_truth("sea_2000003.jpg");
    let found = gt
        .iter()
        .filter(|(class, g)| {
            let g2 = PixelBox {
                x_px: g.x_px * 2.0,
                y_px: g.y_px * 2.0,
                w_px: g.w_px * 2.0,
                h_px: g.h_px * 2.0,
            };
            dets.iter()
                .any(|d| d.class_id == *class && d.bbox.iou(&g2) >= 0.5)
        })
        .count();
    assert!(
        found * 2 >= gt.len(),
        "found {found} of {} objects in {dets:?}",
        gt.len()
    );
    for d in &dets {
        assert!(d.bbox.x_px >= 0.0 && d.bbox.x_px + d.bbox.w_px <= big.width() as f32 + 1e-3);
        assert!(d.bbox.y_px >= 0.0 && d.bbox.y_px + d.bbox.h_px <= big.height() as f32 + 1e-3);
    }
}

#[test]
fn missing_model_names_the_file() {
    let p = root().join("models/does-not-exist.onnx");
    let e = load(&p).unwrap_err();
    assert!(matches!(e, DetectError::ModelRead { .. }), "{e:?}");
    let msg = e.to_string();
    assert!(
        msg.contains("does-not-exist.onnx") && msg.contains("cannot read"),
        "{msg}"
    );
}

#[test]
fn corrupt_model_names_the_file() {
    let e = load(&fixture("corrupt.onnx")).unwrap_err();
    assert!(matches!(e, DetectError::ModelParse { .. }), "{e:?}");
    assert!(e.to_string().contains("corrupt.onnx"), "{e}");
}

#[test]
fn wrong_input_rank_is_rejected() {
    let e = load(&fixture("bad_rank.onnx")).unwrap_err();
    let msg = e.to_string();
    assert!(matches!(e, DetectError::BadInput { .. }), "{e:?}");
    assert!(
        msg.contains("bad_rank.onnx") && msg.contains("rank 3"),
        "{msg}"
    );
}

#[test]
fn unknown_output_layout_is_rejected() {
    let e = load(&fixture("bad_layout.onnx")).unwrap_err();
    let msg = e.to_string();
    assert!(
        matches!(e, DetectError::UnknownOutputLayout { .. }),
        "{e:?}"
    );
    assert!(
        msg.contains("bad_layout.onnx") && msg.contains("rank 3"),
        "{msg}"
    );
}

#[test]
fn wrong_class_count_in_config_is_rejected() {
    let mut cfg = DetectorConfig::new(root().join(INT8));
    cfg.class_names = Some(vec!["a".into(), "b".into(), "c".into()]);
    let e = Detector::load(cfg).unwrap_err();
    assert!(
        matches!(e, DetectError::UnknownOutputLayout { .. }),
        "{e:?}"
    );
    assert!(e.to_string().contains("4 + 3"), "{e}");
}

#[test]
fn the_other_backend_cannot_join_this_process() {
    // Make sure tract is this process's backend, then ask for ONNX Runtime.
    load(&root().join(INT8)).unwrap();
    let mut cfg = DetectorConfig::new(root().join(INT8));
    cfg.backend = BackendConfig {
        kind: BackendKind::OnnxRuntime,
        ort_dylib_path: Some(PathBuf::from("/nonexistent/libonnxruntime.so")),
    };
    let e = Detector::load(cfg).unwrap_err();
    assert!(matches!(e, DetectError::BackendConflict { .. }), "{e:?}");
}
