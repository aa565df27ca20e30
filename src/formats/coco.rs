//! COCO results JSON: a list of `{image_id, category_id, bbox: [x, y, w, h], score}`.

use super::error::{read_json, FormatError};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// One detection in COCO results layout.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CocoDetection {
    /// The image it belongs to.
    pub image_id: u64,
    /// Category id (SeaDronesSee: 1 swimmer, 2 boat, 3 jetski, 4 life-saving appliance, 5 buoy).
    pub category_id: u32,
    /// Box `[x, y, w, h]` in pixels, top-left origin.
    pub bbox: [f64; 4],
    /// Detector confidence in [0, 1].
    pub score: f64,
    /// The box's colour signature in hex ([`crate::track::Appearance::to_hex`]), an extra
    /// field `mgmot detect` writes; other tools leave it out.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub appearance: Option<String>,
}

impl CocoDetection {
    /// The colour signature, when the entry carries a valid one.
    pub fn signature(&self) -> Option<crate::track::Appearance> {
        self.appearance
            .as_deref()
            .and_then(crate::track::Appearance::from_hex)
    }
}

/// Reads and validates a COCO results file (finite boxes with non-negative size, scores in
/// [0, 1]).
pub fn read_detections(path: &Path) -> Result<Vec<CocoDetection>, FormatError> {
    let dets: Vec<CocoDetection> = read_json(path)?;
    for (i, d) in dets.iter().enumerate() {
        if !d.bbox.iter().all(|v| v.is_finite()) || d.bbox[2] < 0.0 || d.bbox[3] < 0.0 {
            return Err(FormatError::invalid(
                path,
                format!("[{i}].bbox"),
                format!(
                    "box must be finite with non-negative size, got {:?}",
                    d.bbox
                ),
            ));
        }
        if !(0.0..=1.0).contains(&d.score) {
            return Err(FormatError::invalid(
                path,
                format!("[{i}].score"),
                format!("score must be in [0, 1], got {}", d.score),
            ));
        }
    }
    Ok(dets)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;

    fn write(content: &str) -> tempfile::NamedTempFile {
        let mut f = tempfile::NamedTempFile::new().unwrap();
        f.write_all(content.as_bytes()).unwrap();
        f
    }

    #[test]
    fn reads_valid_file() {
        let f = write(r#"[{"image_id": 3, "category_id": 1, "bbox": [1, 2, 3, 4], "score": 0.5}]"#);
        let d = read_detections(f.path()).unwrap();
        assert_eq!(d.len(), 1);
        assert_eq!(d[0].bbox, [1.0, 2.0, 3.0, 4.0]);
    }

    #[test]
    fn errors_name_the_json_path() {
        let f = write(
            r#"[{"image_id": 3, "category_id": 1, "bbox": [1, 2, 3, 4], "score": 0.5},
                          {"image_id": "x", "category_id": 1, "bbox": [1, 2, 3, 4], "score": 0.5}]"#,
        );
        let e = read_detections(f.path()).unwrap_err().to_string();
        assert!(e.contains("[1].image_id"), "{e}");
        let f =
            write(r#"[{"image_id": 3, "category_id": 1, "bbox": [1, 2, -3, 4], "score": 0.5}]"#);
        let e = read_detections(f.path()).unwrap_err().to_string();
        assert!(e.contains("[0].bbox"), "{e}");
        let f = write("[{");
        assert!(read_detections(f.path())
            .unwrap_err()
            .to_string()
            .contains("line 1"));
        let e = read_detections(Path::new("/nonexistent/x.json"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("/nonexistent/x.json"), "{e}");
    }
}
