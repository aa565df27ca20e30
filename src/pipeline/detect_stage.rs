//! The pipeline's detect stage: the [`DetectStage`] trait, the ONNX model
//! ([`OnnxStage`], through `mgmot::detect`) that flies, and [`ReplayStage`], which replays
//! the simulator's detection output for bench runs that should not spend CPU on inference.

use crate::camera::Frame;
use crate::detect::{self, DetectError, DetectTimings};
use crate::formats::coco;
use crate::track::{BBox, Detection};
use image::RgbImage;
use std::collections::HashMap;
use std::path::Path;

/// Why a frame could not be run through the detector.
#[derive(Debug, thiserror::Error)]
pub enum DetectStageError {
    /// The detector could not be set up (model or file missing or invalid).
    #[error("detector set-up: {0}")]
    Setup(String),
    /// The ONNX model could not be loaded (the message names the model file).
    #[error("detector set-up: {0}")]
    Model(#[source] DetectError),
    /// One frame failed; the next may work.
    #[error("detection failed on frame {frame}: {message}")]
    Frame {
        /// Frame index.
        frame: u64,
        /// What went wrong.
        message: String,
    },
}

/// Finds objects in a frame. Runs on the inference thread (synchronous, may block).
pub trait DetectStage: Send {
    /// Detections of one frame, in its pixel coordinates, without world positions. The frame
    /// is taken by value: the pixels are handed to the model without a copy.
    fn detect(&mut self, frame: Frame) -> Result<Vec<Detection>, DetectStageError>;

    /// Where the time of the last successful [`DetectStage::detect`] went, for detectors that
    /// measure it (the latency histograms split the model run from the rest).
    fn last_timings(&self) -> Option<DetectTimings> {
        None
    }
}

/// The ONNX detector of `mgmot::detect` on the pipeline's frames. A class's track class id is
/// the SeaDronesSee category of its NAME ([`detect::ModelInfo::category_id`]), as in
/// `mgmot detect`'s COCO output: 1 swimmer, 2 boat, 3 jetski, 4 life-saving appliance, 5 buoy
/// (0 for a name that is none of them), whatever the class's index in the model; the ids the
/// tracker's per-class thresholds are keyed by.
#[derive(Debug)]
pub struct OnnxStage {
    inner: detect::Detector,
    last: Option<DetectTimings>,
}

impl OnnxStage {
    /// Loads the model (and the backend, once per process) and runs one warm-up inference.
    pub fn load(config: detect::DetectorConfig) -> Result<Self, DetectStageError> {
        let inner = detect::Detector::load(config).map_err(DetectStageError::Model)?;
        Ok(Self { inner, last: None })
    }

    /// The loaded model's interface (input size, class names).
    pub fn model(&self) -> &detect::ModelInfo {
        self.inner.model()
    }
}

impl DetectStage for OnnxStage {
    fn detect(&mut self, frame: Frame) -> Result<Vec<Detection>, DetectStageError> {
        let index = frame.index;
        let failed = |message: String| DetectStageError::Frame {
            frame: index,
            message,
        };
        let (w, h, len) = (frame.width_px, frame.height_px, frame.rgb.len());
        let image = RgbImage::from_raw(w, h, frame.rgb).ok_or_else(|| {
            failed(format!(
                "{len} bytes of pixels do not make a {w}x{h} RGB24 image"
            ))
        })?;
        self.last = None;
        let (found, timings) = self
            .inner
            .detect_timed(&image)
            .map_err(|e| failed(e.to_string()))?;
        self.last = Some(timings);
        let model = self.inner.model();
        Ok(found
            .into_iter()
            .map(|d| Detection {
                bbox: d.track_bbox(),
                score: d.score,
                class_id: model.category_id(d.class_id),
                world: None,
                appearance: d.appearance(&image),
            })
            .collect())
    }

    fn last_timings(&self) -> Option<DetectTimings> {
        self.last
    }
}

/// Replays a COCO results file (`mgmot-sim detections --out X.json`) by frame index: frame `k`
/// gets the detections of image id `first_image_id + k`; the pixels are not looked at. For the
/// bench: it measures the rest of the pipeline without the cost of inference, and gives the
/// tracker the simulator's detector model (known miss and false-positive rates).
#[derive(Debug, Clone)]
pub struct ReplayStage {
    by_image: HashMap<u64, Vec<Detection>>,
    first_image_id: u64,
}

impl ReplayStage {
    /// Loads the file.
    pub fn load(path: &Path, first_image_id: u64) -> Result<Self, DetectStageError> {
        let dets =
            coco::read_detections(path).map_err(|e| DetectStageError::Setup(e.to_string()))?;
        let mut by_image: HashMap<u64, Vec<Detection>> = HashMap::new();
        for d in dets {
            by_image.entry(d.image_id).or_default().push(Detection {
                bbox: BBox {
                    x: d.bbox[0],
                    y: d.bbox[1],
                    w: d.bbox[2],
                    h: d.bbox[3],
                },
                score: d.score as f32,
                class_id: d.category_id,
                world: None,
                appearance: d.signature(),
            });
        }
        Ok(Self {
            by_image,
            first_image_id,
        })
    }
}

impl DetectStage for ReplayStage {
    fn detect(&mut self, frame: Frame) -> Result<Vec<Detection>, DetectStageError> {
        let id = self
            .first_image_id
            .checked_add(frame.index)
            .ok_or_else(|| DetectStageError::Frame {
                frame: frame.index,
                message: "image id overflows".into(),
            })?;
        Ok(self.by_image.get(&id).cloned().unwrap_or_default())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::CaptureTime;
    use crate::telemetry::AutopilotTimeUs;

    fn frame(index: u64) -> Frame {
        Frame {
            index,
            captured: CaptureTime::Autopilot(AutopilotTimeUs(0)),
            width_px: 1,
            height_px: 1,
            rgb: vec![0; 3],
        }
    }

    #[test]
    fn replays_by_frame_index() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("d.json");
        std::fs::write(
            &path,
            r#"[{"image_id": 1, "category_id": 1, "bbox": [10, 20, 5, 6], "score": 0.9},
                {"image_id": 3, "category_id": 2, "bbox": [1, 2, 3, 4], "score": 0.5},
                {"image_id": 3, "category_id": 1, "bbox": [5, 6, 7, 8], "score": 0.4}]"#,
        )
        .unwrap();
        let mut d = ReplayStage::load(&path, 1).unwrap();
        let f0 = d.detect(frame(0)).unwrap();
        assert_eq!(f0.len(), 1);
        assert_eq!(
            f0[0].bbox,
            BBox {
                x: 10.0,
                y: 20.0,
                w: 5.0,
                h: 6.0
            }
        );
        assert!(d.detect(frame(1)).unwrap().is_empty());
        assert_eq!(d.detect(frame(2)).unwrap().len(), 2);
    }

    fn shipped_model() -> detect::DetectorConfig {
        detect::DetectorConfig::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/models/mgmot-det-fp32.onnx"
        ))
    }

    #[test]
    fn onnx_detector_runs_on_a_frame_and_reports_its_timings() {
        let mut d = OnnxStage::load(shipped_model()).unwrap();
        assert_eq!(
            d.model().class_names,
            [
                "swimmer",
                "boat",
                "jetski",
                "life_saving_appliances",
                "buoy"
            ]
        );
        let mut f = frame(5);
        (f.width_px, f.height_px) = (160, 90);
        f.rgb = vec![90; 160 * 90 * 3];
        let found = d.detect(f).unwrap();
        for det in &found {
            assert!((1..=5).contains(&det.class_id), "{det:?}");
            assert!(det.world.is_none());
        }
        let t = d.last_timings().unwrap();
        assert!(t.inference > std::time::Duration::ZERO);
    }

    #[test]
    fn onnx_detector_names_the_frame_with_a_bad_buffer() {
        let mut d = OnnxStage::load(shipped_model()).unwrap();
        let mut f = frame(7);
        (f.width_px, f.height_px) = (10, 10);
        let e = d.detect(f).unwrap_err().to_string();
        assert!(e.contains("frame 7") && e.contains("10x10"), "{e}");
        assert!(d.last_timings().is_none());
    }

    #[test]
    fn missing_model_names_the_file() {
        let e = OnnxStage::load(detect::DetectorConfig::new("/nonexistent/m.onnx")).unwrap_err();
        assert!(e.to_string().contains("/nonexistent/m.onnx"), "{e}");
    }

    #[test]
    fn bad_file_is_a_setup_error_naming_it() {
        let e = ReplayStage::load(Path::new("/nonexistent/d.json"), 1).unwrap_err();
        assert!(e.to_string().contains("/nonexistent/d.json"));
    }
}
