//! `[detector]`: what finds objects in frames (the ONNX detector, or replayed detections).

use super::problems::Problems;
use crate::detect::{BackendChoice, BackendConfig, BackendKind, TilingConfig};
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
    /// Other model files with the same classes and input size (e.g. the fp32 twin of an int8
    /// model), timed against `model` at start; the fastest (backend, model) pair runs.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub alternatives: Vec<PathBuf>,
    /// Inference engine: `auto` (the default: tract, and onnxruntime where its library is
    /// found, each timed at start with `model` and the `alternatives`; the fastest runs),
    /// `tract` (pure Rust, nothing to install) or `onnxruntime`.
    #[serde(default = "default_backend")]
    pub backend: BackendChoice,
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
    /// objects larger than a tile), merged by NMS: `false` (the default), `true`, or `"auto"`
    /// (tile when the model runs a frame needs fit in the frame period of `tile_min_fps` at
    /// the model run time measured at start; decided per frame size and logged). Costs one
    /// model run per tile (1280x720 in 800x448 tiles: 4 tiles + 1); finds more of the small
    /// objects (models/README.md, "Tiling").
    #[serde(default)]
    pub tile: TileChoice,
    /// With `tile = "auto"`: the frame rate the detector must keep to tile (frames/s).
    #[serde(default = "default_tile_min_fps")]
    pub tile_min_fps: f64,
    /// Side of square tiles (px of the frame); absent: tiles of the model's input size (native
    /// resolution, no letterbox padding).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tile_size_px: Option<u32>,
    /// Overlap between neighbouring tiles (px); at least the largest object to keep whole.
    #[serde(default = "default_tile_overlap_px")]
    pub tile_overlap_px: u32,
    /// With `tile` on or `"auto"`: the model that runs the frames that are tiled (their tiles
    /// and their whole-frame pass), on the backend chosen for `model`; it must have `model`'s
    /// classes and input size. Frames that are not tiled run `model`. Absent: `model` runs
    /// every frame. The shipped `mgmot-det-tiles-int8.onnx` learned on uncompressed frames
    /// too, which the shipped model's tiles misread (models/README.md, "The tile model").
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tile_model: Option<PathBuf>,
}

fn one_u64() -> u64 {
    1
}
fn default_backend() -> BackendChoice {
    BackendChoice::Auto
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
fn default_tile_min_fps() -> f64 {
    15.0
}

/// `[detector] tile`: `false`, `true` or `"auto"`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum TileChoice {
    /// Whole frames only.
    #[default]
    Off,
    /// Tiles plus the whole frame, on every frame.
    On,
    /// Tiles when they fit in the frame period of `tile_min_fps` (measured at start).
    Auto,
}

impl Serialize for TileChoice {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match self {
            TileChoice::Off => s.serialize_bool(false),
            TileChoice::On => s.serialize_bool(true),
            TileChoice::Auto => s.serialize_str("auto"),
        }
    }
}

impl<'de> Deserialize<'de> for TileChoice {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct Visitor;
        impl serde::de::Visitor<'_> for Visitor {
            type Value = TileChoice;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("true, false or \"auto\"")
            }
            fn visit_bool<E: serde::de::Error>(self, v: bool) -> Result<TileChoice, E> {
                Ok(if v { TileChoice::On } else { TileChoice::Off })
            }
            fn visit_str<E: serde::de::Error>(self, v: &str) -> Result<TileChoice, E> {
                match v {
                    "auto" => Ok(TileChoice::Auto),
                    other => Err(E::invalid_value(serde::de::Unexpected::Str(other), &self)),
                }
            }
        }
        d.deserialize_any(Visitor)
    }
}

/// The validated detector.
#[derive(Debug, Clone, PartialEq)]
pub enum DetectorSettings {
    /// The ONNX detector.
    Onnx(OnnxSettings),
    /// Replayed detections.
    Replay {
        /// COCO results JSON.
        detections: PathBuf,
        /// The image id of frame index 0.
        first_image_id: u64,
    },
}

/// The validated ONNX detector: the settings of `mgmot::detect` for the main model, and how
/// the (backend, model) pair that runs is chosen.
#[derive(Debug, Clone, PartialEq)]
pub struct OnnxSettings {
    /// The settings of `mgmot::detect` with `[detector] model`; their backend is the configured
    /// one (tract, a placeholder, under `auto` until [`OnnxSettings::select`] has chosen).
    pub detector: crate::detect::DetectorConfig,
    /// `[detector] backend`.
    pub backend: BackendChoice,
    /// `[detector] alternatives`: other models to time against the main one.
    pub alternatives: Vec<PathBuf>,
}

impl OnnxSettings {
    /// Settings that run `detector` as they are: its backend, no alternatives.
    pub fn fixed(detector: crate::detect::DetectorConfig) -> Self {
        Self {
            backend: detector.backend.kind.into(),
            detector,
            alternatives: Vec::new(),
        }
    }

    /// Chooses the (backend, model) pair to run ([`crate::detect::auto::select`]: with one
    /// candidate it is taken as is, several are timed) and returns the settings of
    /// `mgmot::detect` for it, with the selection (what was measured, for the log and the
    /// run's stats).
    pub fn select(
        &self,
    ) -> Result<(crate::detect::DetectorConfig, crate::detect::Selection), crate::detect::DetectError>
    {
        let selection =
            crate::detect::auto::select(&self.detector, self.backend, &self.alternatives)?;
        Ok((selection.apply(&self.detector), selection))
    }
}

impl DetectorSettings {
    /// The files the detector needs at start, looked at on this machine (what
    /// `mgmot check-config` adds to [`DetectorConfig::validate`], which looks at values only):
    /// the ONNX model and every alternative must be readable files, and each alternative must
    /// have the model's class names and input size (their graphs and metadata are read, not
    /// loaded); the ONNX Runtime library (`detector.ort_library`, else `ORT_DYLIB_PATH`) must
    /// exist on the onnxruntime backend, and under `auto` when `ort_library` names one (a
    /// library from `ORT_DYLIB_PATH` that is not there only leaves onnxruntime out of the
    /// choice). Problems are pushed onto `p` under the keys that name the files.
    pub fn check_files(&self, p: &mut Problems) {
        let DetectorSettings::Onnx(settings) = self else {
            return;
        };
        let onnx = &settings.detector;
        let model_ok = match readable_file(&onnx.model_path) {
            Ok(()) => true,
            Err(why) => {
                p.push(
                    "detector.model",
                    format!("{}: {why}", onnx.model_path.display()),
                );
                false
            }
        };
        check_alternatives(settings, model_ok, p);
        check_tile_model(settings, model_ok, p);
        match settings.backend {
            BackendChoice::Tract => return,
            BackendChoice::Auto if onnx.backend.ort_dylib_path.is_none() => return,
            BackendChoice::Auto | BackendChoice::OnnxRuntime => {}
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

/// `detector.alternatives`: each a readable file with the main model's class names and input
/// size (compared only when the main model, `model_ok`, is readable).
fn check_alternatives(settings: &OnnxSettings, model_ok: bool, p: &mut Problems) {
    use crate::detect::auto::ModelInterface;
    if settings.alternatives.is_empty() {
        return;
    }
    let main = if model_ok {
        match ModelInterface::read(&settings.detector.model_path) {
            Ok(m) => Some(m),
            Err(e) => {
                p.push("detector.model", e.to_string());
                None
            }
        }
    } else {
        None
    };
    for alt in &settings.alternatives {
        if let Err(why) = readable_file(alt) {
            p.push("detector.alternatives", format!("{}: {why}", alt.display()));
            continue;
        }
        let Some(main) = &main else { continue };
        match ModelInterface::read(alt) {
            Err(e) => p.push("detector.alternatives", e.to_string()),
            Ok(interface) => {
                if let Some(why) = interface.mismatch(main) {
                    p.push(
                        "detector.alternatives",
                        format!(
                            "{} cannot stand in for {}: {why}",
                            alt.display(),
                            settings.detector.model_path.display()
                        ),
                    );
                }
            }
        }
    }
}

/// `detector.tile_model`: a readable file with the main model's class names and input size
/// (compared only when the main model, `model_ok`, is readable). Checked with tiling off too:
/// a file named in the configuration that is not there is a mistake either way.
fn check_tile_model(settings: &OnnxSettings, model_ok: bool, p: &mut Problems) {
    use crate::detect::auto::ModelInterface;
    let detector = &settings.detector;
    let Some(tile_model) = &detector.tile_model else {
        return;
    };
    if let Err(why) = readable_file(tile_model) {
        p.push(
            "detector.tile_model",
            format!("{}: {why}", tile_model.display()),
        );
        return;
    }
    if !model_ok {
        return;
    }
    let (main, tiles) = match (
        ModelInterface::read(&detector.model_path),
        ModelInterface::read(tile_model),
    ) {
        (Ok(main), Ok(tiles)) => (main, tiles),
        // With alternatives, `check_alternatives` has reported the main model's problem.
        (Err(e), _) => {
            if settings.alternatives.is_empty() {
                p.push("detector.model", e.to_string());
            }
            return;
        }
        (_, Err(e)) => return p.push("detector.tile_model", e.to_string()),
    };
    if let Some(why) = tiles.mismatch(&main) {
        p.push(
            "detector.tile_model",
            format!(
                "{} cannot run the tiles of {}: {why}",
                tile_model.display(),
                detector.model_path.display()
            ),
        );
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
            DetectorConfig::Onnx(onnx) => onnx.validate(p).map(|detector| {
                DetectorSettings::Onnx(OnnxSettings {
                    detector,
                    backend: onnx.backend,
                    alternatives: onnx.alternatives.clone(),
                })
            }),
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
    /// The settings of `mgmot::detect` for `model`, as written (unchecked: see
    /// [`OnnxDetectorConfig::validate`]); under `backend = "auto"` their backend is tract
    /// until [`OnnxSettings::select`] chooses.
    pub fn settings(&self) -> crate::detect::DetectorConfig {
        let mut c = crate::detect::DetectorConfig::new(&self.model);
        c.backend = BackendConfig {
            kind: self.backend.fixed().unwrap_or(BackendKind::Tract),
            ort_dylib_path: self.ort_library.clone(),
        };
        c.threads = self.threads;
        c.score_threshold = self.score_threshold;
        c.nms_iou = self.nms_iou;
        c.larger_box_iou = (self.larger_box_iou < 1.0).then_some(self.larger_box_iou);
        c.max_detections = self.max_detections;
        c.class_names = self.class_names.clone();
        c.tile_model = self.tile_model.clone();
        let tiling = TilingConfig {
            tile_px: self.tile_size_px,
            overlap_px: self.tile_overlap_px,
            include_full_frame: true,
            frame_budget_us: None,
        };
        c.tiling = match self.tile {
            TileChoice::Off => None,
            TileChoice::On => Some(tiling),
            TileChoice::Auto => Some(TilingConfig {
                frame_budget_us: (self.tile_min_fps > 0.0)
                    .then(|| (1e6 / self.tile_min_fps).round() as u64),
                ..tiling
            }),
        };
        c
    }

    /// The settings of `mgmot::detect`, or every problem pushed onto `p`.
    pub fn validate(&self, p: &mut Problems) -> Option<crate::detect::DetectorConfig> {
        let before = p.len();
        self.check_tiles(p);
        if self.model.as_os_str().is_empty() {
            p.push("detector.model", "must name the ONNX model file");
        }
        if self.alternatives.iter().any(|a| a.as_os_str().is_empty()) {
            p.push("detector.alternatives", "must name ONNX model files");
        }
        if self
            .tile_model
            .as_ref()
            .is_some_and(|m| m.as_os_str().is_empty())
        {
            p.push("detector.tile_model", "must name an ONNX model file");
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
        let fps = self.tile_min_fps;
        if !(fps.is_finite() && fps > 0.0 && fps <= 1000.0) {
            p.push(
                "detector.tile_min_fps",
                format!("must be in (0, 1000] frames/s, got {fps}"),
            );
        }
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
