//! Swimmer / boat detection with an ONNX model through `ort` (an IO edge).
//!
//! Any detector with the Ultralytics YOLOv8 / YOLO11 output layout loads here:
//! one float32 input `(1, 3, H, W)` (RGB in `[0, 1]`, letterboxed) and one
//! output `(1, 4 + nc, N)` (box centre x, centre y, width, height in input
//! pixels, then one score per class), or its transpose `(1, N, 4 + nc)`. The
//! project's own model (`models/`, trained by `train/`) has the same layout.
//!
//! The pipeline for one frame is
//! 1. [`preprocess`]: letterbox into the model's input size with
//!    `fast_image_resize` (optionally per tile of a large frame, see [`tiling`]);
//! 2. inference on the chosen [`backend`] (pure-Rust tract, or ONNX Runtime
//!    loaded at run time);
//! 3. [`postprocess`]: decode, class-aware NMS, then the MG-MOT paper's
//!    larger-box-priority suppression.
//!
//! The backend is process-global (ort keeps one API table per process): the
//! first [`Detector::load`] (or [`backend::init_backend`]) decides it, and a
//! later request for the other backend fails with
//! [`DetectError::BackendConflict`].

pub mod auto;
pub mod backend;
mod detector;
pub mod model;
pub mod postprocess;
pub mod preprocess;
pub mod tiling;

use std::path::PathBuf;

use serde::Serialize;

pub use auto::{BackendChoice, Measurement, Selection};
pub use backend::{BackendConfig, BackendKind, ORT_DYLIB_ENV};
pub use detector::{DetectTimings, Detector, DetectorConfig, DEFAULT_NMS_IOU};
pub use model::{ModelInfo, OutputLayout};
pub use tiling::TilingConfig;

/// An axis-aligned box in continuous image pixels; `(0, 0)` is the top-left
/// corner of the image, so the centre is `(x_px + w_px / 2, y_px + h_px / 2)`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PixelBox {
    /// Left edge.
    pub x_px: f32,
    /// Top edge.
    pub y_px: f32,
    /// Width.
    pub w_px: f32,
    /// Height.
    pub h_px: f32,
}

impl PixelBox {
    /// Box from its corners `(x1, y1)` (top-left) and `(x2, y2)` (bottom-right).
    pub fn from_corners(x1: f32, y1: f32, x2: f32, y2: f32) -> Self {
        Self {
            x_px: x1,
            y_px: y1,
            w_px: (x2 - x1).max(0.0),
            h_px: (y2 - y1).max(0.0),
        }
    }

    /// The same box as the tracker's [`crate::track::BBox`] (f64).
    pub fn to_bbox(&self) -> crate::track::BBox {
        crate::track::BBox::new(
            f64::from(self.x_px),
            f64::from(self.y_px),
            f64::from(self.w_px),
            f64::from(self.h_px),
        )
    }

    /// Area in square pixels.
    pub fn area(&self) -> f32 {
        self.w_px * self.h_px
    }

    /// Intersection over union with another box (0 when either is empty).
    pub fn iou(&self, other: &PixelBox) -> f32 {
        let ix1 = self.x_px.max(other.x_px);
        let iy1 = self.y_px.max(other.y_px);
        let ix2 = (self.x_px + self.w_px).min(other.x_px + other.w_px);
        let iy2 = (self.y_px + self.h_px).min(other.y_px + other.h_px);
        let inter = (ix2 - ix1).max(0.0) * (iy2 - iy1).max(0.0);
        let union = self.area() + other.area() - inter;
        if union > 0.0 {
            inter / union
        } else {
            0.0
        }
    }
}

/// One detected object in frame pixels.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Detection {
    /// Index into the model's class names ([`ModelInfo::class_names`]).
    pub class_id: usize,
    /// Class score in `[0, 1]` as the model reports it.
    pub score: f32,
    /// The box in the pixels of the frame given to the detector.
    pub bbox: PixelBox,
}

impl Detection {
    /// The box as the tracker takes it.
    pub fn track_bbox(&self) -> crate::track::BBox {
        crate::track::BBox {
            x: f64::from(self.bbox.x_px),
            y: f64::from(self.bbox.y_px),
            w: f64::from(self.bbox.w_px),
            h: f64::from(self.bbox.h_px),
        }
    }

    /// The colour signature of the box's pixels in `frame` (the frame given to the
    /// detector), for the tracker's long-gap ReID (`reid.appearance_gate`).
    pub fn appearance(&self, frame: &image::RgbImage) -> Option<crate::track::Appearance> {
        let pixels = crate::track::RgbImage {
            rgb: frame.as_raw(),
            width: frame.width() as usize,
            height: frame.height() as usize,
        };
        crate::track::Appearance::from_box(&pixels, &self.track_bbox())
    }
}

/// Everything that can go wrong while loading a model or detecting.
///
/// Every variant about a model names its file, so a user with several models
/// knows which one is at fault.
#[derive(Debug, thiserror::Error)]
pub enum DetectError {
    /// The model file could not be read (missing, permissions).
    #[error("model {path}: cannot read the file: {source}")]
    ModelRead {
        /// The model file.
        path: PathBuf,
        /// The IO error.
        source: std::io::Error,
    },
    /// The file is not a parsable ONNX model.
    #[error("model {path}: not a valid ONNX model: {message}")]
    ModelParse {
        /// The model file.
        path: PathBuf,
        /// The parser's or runtime's message.
        message: String,
    },
    /// The backend could not build a session from an otherwise parsable model.
    #[error("model {path}: the {backend} backend cannot load it: {message}")]
    SessionLoad {
        /// The model file.
        path: PathBuf,
        /// The backend that refused it.
        backend: BackendKind,
        /// The backend's message.
        message: String,
    },
    /// The model's input is not one float32 tensor of shape (1, 3, H, W).
    #[error("model {path}: input `{name}`: {problem}")]
    BadInput {
        /// The model file.
        path: PathBuf,
        /// The input's name.
        name: String,
        /// What is wrong with it.
        problem: String,
    },
    /// The model's output does not have a known detector layout.
    #[error("model {path}: output `{name}`: unknown output layout: {problem}")]
    UnknownOutputLayout {
        /// The model file.
        path: PathBuf,
        /// The output's name.
        name: String,
        /// What was found instead.
        problem: String,
    },
    /// A metadata entry (class names, input size) could not be understood.
    #[error("model {path}: metadata `{key}`: {problem}")]
    BadMetadata {
        /// The model file.
        path: PathBuf,
        /// The metadata key.
        key: String,
        /// What is wrong with it.
        problem: String,
    },
    /// Inference failed at run time.
    #[error("model {path}: inference on the {backend} backend failed: {message}")]
    Inference {
        /// The model file.
        path: PathBuf,
        /// The backend that ran it.
        backend: BackendKind,
        /// The backend's message.
        message: String,
    },
    /// No ONNX Runtime library was configured.
    #[error("the onnxruntime backend needs the ONNX Runtime library: configure its path or set ORT_DYLIB_PATH (scripts/detect_fetch_onnxruntime.sh prints one)")]
    OrtLibraryNotConfigured,
    /// The ONNX Runtime library could not be loaded or is too old.
    #[error("ONNX Runtime library {path}: {problem}")]
    OrtLibrary {
        /// The library file.
        path: PathBuf,
        /// What went wrong.
        problem: String,
    },
    /// The process already runs the other backend.
    #[error("this process already uses the {active} backend; {requested} cannot be selected as well (ort's API table is process-global: choose one backend per process)")]
    BackendConflict {
        /// The backend chosen first.
        active: BackendKind,
        /// The backend asked for now.
        requested: BackendKind,
    },
    /// A configuration value is out of range.
    #[error("detector configuration: {0}")]
    InvalidConfig(String),
}
