//! The detector seen by the pipeline: a trait the ONNX detector (`mgmot::detect`, not merged
//! yet) will implement, and a stand-in that replays the simulator's detection output.

use crate::camera::Frame;
use crate::formats::coco;
use crate::track::{BBox, Detection};
use std::collections::HashMap;
use std::path::Path;

/// Why a frame could not be run through the detector.
#[derive(Debug, thiserror::Error)]
pub enum DetectorError {
    /// The detector could not be set up (model or file missing or invalid).
    #[error("detector set-up: {0}")]
    Setup(String),
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
pub trait Detector: Send {
    /// Detections of one frame, in its pixel coordinates, without world positions.
    fn detect(&mut self, frame: &Frame) -> Result<Vec<Detection>, DetectorError>;
}

/// Replays a COCO results file (`mgmot-sim detections --out X.json`) by frame index: frame `k`
/// gets the detections of image id `first_image_id + k`. Stands in for the ONNX detector on
/// the bench until it lands; the pixels are not looked at.
#[derive(Debug, Clone)]
pub struct ReplayDetector {
    by_image: HashMap<u64, Vec<Detection>>,
    first_image_id: u64,
}

impl ReplayDetector {
    /// Loads the file.
    pub fn load(path: &Path, first_image_id: u64) -> Result<Self, DetectorError> {
        let dets = coco::read_detections(path).map_err(|e| DetectorError::Setup(e.to_string()))?;
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
            });
        }
        Ok(Self {
            by_image,
            first_image_id,
        })
    }
}

impl Detector for ReplayDetector {
    fn detect(&mut self, frame: &Frame) -> Result<Vec<Detection>, DetectorError> {
        let id = self
            .first_image_id
            .checked_add(frame.index)
            .ok_or_else(|| DetectorError::Frame {
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
        let mut d = ReplayDetector::load(&path, 1).unwrap();
        let f0 = d.detect(&frame(0)).unwrap();
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
        assert!(d.detect(&frame(1)).unwrap().is_empty());
        assert_eq!(d.detect(&frame(2)).unwrap().len(), 2);
    }

    #[test]
    fn bad_file_is_a_setup_error_naming_it() {
        let e = ReplayDetector::load(Path::new("/nonexistent/d.json"), 1).unwrap_err();
        assert!(e.to_string().contains("/nonexistent/d.json"));
    }
}
