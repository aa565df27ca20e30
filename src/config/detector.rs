//! `[detector]`: what finds objects in frames (the ONNX detector, or replayed detections).

use super::problems::Problems;
use crate::detect::{BackendConfig, BackendKind, TilingConfig};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Detectors.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum DetectorConfig {
    /// The ONNX detector (`mgmot::detect`) on every frame: what flies.
    Onnx(OnnxDetectorConfig),
    /// Replays detections from a COCO results file keyed by frame (the simulator's
    /// `mgmot-sim detections` output), not looking at the pixels: for bench runs that
    /// measure the rest of the pipeline, or feed the tracker the simulator's detector model.
    Replay {
        /// COCO results JSON (`[{image_id, category_id, bbox, score}]`).
        detections: PathBuf,
        /// The image id of frame index 0 (ids count up by frame index).
        #[serde(default = "one_u64")]
        first_image_id: u64,
    },
}

/// The ONNX detector's settings (`[detector]` with `kind = "onnx"`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OnnxDetectorConfig {
    /// The model file: `models/mgmot-det-int8.onnx` (fastest on onnxruntime),
    /// `models/mgmot-det-fp32.onnx` (fastest on tract), or a YOLOv8 / YOLO11 export.
    pub model: PathBuf,
    /// Inference engine: `tract` (pure Rust, nothing to install) or `onnxruntime`.
    #[serde(default = "default_backend")]
    pub backend: BackendKind,
    /// `libonnxruntime.so` for the onnxruntime backend; absent: `$ORT_DYLIB_PATH`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ort_library: Option<PathBuf>,
    /// Intra-op threads of the model run (onnxruntime; tract runs on one).
    #[serde(default = "default_detector_threads")]
    pub threads: usize,
    /// Candidates scoring below this are dropped.
    #[serde(default = "default_score_threshold")]
    pub score_threshold: f32,
    /// IoU above which the class-aware NMS drops the lower-scoring box.
    #[serde(default = "default_nms_iou")]
    pub nms_iou: f32,
    /// IoU above which the paper's larger-box-priority suppression drops the smaller box
    /// (class-agnostic); 1 turns it off.
    #[serde(default = "default_larger_box_iou")]
    pub larger_box_iou: f32,
    /// At most this many detections per frame.
    #[serde(default = "default_max_detections")]
    pub max_detections: usize,
    /// Class names overriding the model's metadata, in the model's class order. The names,
    /// not the indices, decide the track class ids: each is mapped to its SeaDronesSee
    /// category (1 swimmer, 2 boat, 3 jetski, 4 life-saving appliance, 5 buoy, with common
    /// synonyms; 0 for a name that is none of them), see
    /// [`crate::detect::model::category_ids_for`].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub class_names: Option<Vec<String>>,
    /// Run the model on overlapping tiles at native resolution (plus the whole frame, for
    /// objects larger than a tile), merged by NMS: for frames much larger than the model's
    /// input (a 4K frame letterboxed into the shipped 800x448 input shrinks a 20 px swimmer to
    /// 4 px). Costs one model run per tile (1280x720 in 800x448 tiles: 4 tiles + 1).
    #[serde(default)]
    pub tile: bool,
    /// Side of square tiles (px of the frame); absent: tiles of the model's input size (native
    /// resolution, no letterbox padding).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tile_size_px: Option<u32>,
    /// Overlap between neighbouring tiles (px); at least the largest object to keep whole.
    #[serde(default = "default_tile_overlap_px")]
    pub tile_overlap_px: u32,
}

fn one_u64() -> u64 {
    1
}
fn default_backend() -> BackendKind {
    BackendKind::Tract
}
fn default_detector_threads() -> usize {
    2
}
fn default_score_threshold() -> f32 {
    0.25
}
fn default_nms_iou() -> f32 {
    crate::detect::DEFAULT_NMS_IOU
}
fn default_larger_box_iou() -> f32 {
    0.7
}
fn default_max_detections() -> usize {
    300
}
fn default_tile_overlap_px() -> u32 {
    64
}

/// The validated detector.
#[derive(Debug, Clone, PartialEq)]
pub enum DetectorSettings {
    /// The ONNX detector, with the settings of `mgmot::detect`.
    Onnx(crate::detect::DetectorConfig),
    /// Replayed detections.
    Replay {
        /// COCO results JSON.
        detections: PathBuf,
        /// The image id of frame index 0.
        first_image_id: u64,
    },
}

impl DetectorSettings {
    /// The files the detector needs at start, looked at on this machine (what
    /// `mgmot check-config` adds to [`DetectorConfig::validate`], which looks at values only):
    /// the ONNX model must be a readable file and, on the onnxruntime backend, the ONNX
    /// Runtime library (`detector.ort_library`, else `ORT_DYLIB_PATH`) must exist. Nothing is
    /// loaded. Problems are pushed onto `p` under the keys that name the files.
    pub fn check_files(&self, p: &mut Problems) {
        let DetectorSettings::Onnx(onnx) = self else {
            return;
        };
        if let Err(why) = readable_file(&onnx.model_path) {
            p.push(
                "detector.model",
                format!("{}: {why}", onnx.model_path.display()),
            );
        }
        if onnx.backend.kind != BackendKind::OnnxRuntime {
            return;
        }
        match (
            &onnx.backend.ort_dylib_path,
            onnx.backend.resolved_ort_dylib_path(),
        ) {
            (_, None) => p.push(
                "detector.ort_library",
                format!(
                    "the onnxruntime backend needs the ONNX Runtime library: set this key or {}",
                    crate::detect::ORT_DYLIB_ENV
                ),
            ),
            (configured, Some(lib)) => {
                if let Err(why) = readable_file(&lib) {
                    let from = if configured.is_some() {
                        String::new()
                    } else {
                        format!(" (from {})", crate::detect::ORT_DYLIB_ENV)
                    };
                    p.push(
                        "detector.ort_library",
                        format!("{}{from}: {why}", lib.display()),
                    );
                }
            }
        }
    }
}

/// `Ok` when `path` is a file this process can open for reading; otherwise why not.
fn readable_file(path: &Path) -> Result<(), String> {
    match std::fs::metadata(path) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Err("no such file".into()),
        Err(e) => Err(e.to_string()),
        Ok(m) if !m.is_file() => Err("not a regular file".into()),
        Ok(_) => std::fs::File::open(path)
            .map(drop)
            .map_err(|e| format!("cannot be read: {e}")),
    }
}

impl DetectorConfig {
    /// The detector's settings, or the section's problems pushed onto `p`.
    pub fn validate(&self, p: &mut Problems) -> Option<DetectorSettings> {
        match self {
            DetectorConfig::Onnx(onnx) => onnx.validate(p).map(DetectorSettings::Onnx),
            DetectorConfig::Replay {
                detections,
                first_image_id,
            } => Some(DetectorSettings::Replay {
                detections: detections.clone(),
                first_image_id: *first_image_id,
            }),
        }
    }
}

impl OnnxDetectorConfig {
    /// The settings of `mgmot::detect`, as written (unchecked: see
    /// [`OnnxDetectorConfig::validate`]).
    pub fn settings(&self) -> crate::detect::DetectorConfig {
        let mut c = crate::detect::DetectorConfig::new(&self.model);
        c.backend = BackendConfig {
            kind: self.backend,
            ort_dylib_path: self.ort_library.clone(),
        };
        c.threads = self.threads;
        c.score_threshold = self.score_threshold;
        c.nms_iou = self.nms_iou;
        c.larger_box_iou = (self.larger_box_iou < 1.0).then_some(self.larger_box_iou);
        c.max_detections = self.max_detections;
        c.class_names = self.class_names.clone();
        c.tiling = self.tile.then_some(TilingConfig {
            tile_px: self.tile_size_px,
            overlap_px: self.tile_overlap_px,
            include_full_frame: true,
        });
        c
    }

    /// The settings of `mgmot::detect`, or every problem pushed onto `p`.
    pub fn validate(&self, p: &mut Problems) -> Option<crate::detect::DetectorConfig> {
        let before = p.len();
        self.check_tiles(p);
        if self.model.as_os_str().is_empty() {
            p.push("detector.model", "must name the ONNX model file");
        }
        if self.threads == 0 {
            p.push("detector.threads", "must be >= 1");
        }
        for (key, v) in [
            ("detector.score_threshold", self.score_threshold),
            ("detector.nms_iou", self.nms_iou),
        ] {
            if !(0.0..=1.0).contains(&v) {
                p.push(key, format!("must be in [0, 1], got {v}"));
            }
        }
        let larger = self.larger_box_iou;
        if !(larger > 0.0 && larger <= 1.0) {
            p.push(
                "detector.larger_box_iou",
                format!("must be in (0, 1] (1 turns it off), got {larger}"),
            );
        }
        if self.max_detections == 0 {
            p.push("detector.max_detections", "must be >= 1");
        }
        if let Some(names) = &self.class_names {
            if names.is_empty() || names.iter().any(|n| n.trim().is_empty()) {
                p.push(
                    "detector.class_names",
                    "must list one non-empty name per model class",
                );
            }
        }
        (p.len() == before).then(|| self.settings())
    }

    fn check_tiles(&self, p: &mut Problems) {
        let (Some(t), overlap) = (self.tile_size_px, self.tile_overlap_px) else {
            return;
        };
        if t < 32 {
            p.push("detector.tile_size_px", format!("must be >= 32, got {t}"));
        } else if overlap >= t {
            p.push(
                "detector.tile_overlap_px",
                format!("must be smaller than tile_size_px ({t}), got {overlap}"),
            );
        }
    }
}
