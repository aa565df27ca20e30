//! The recording of the fused picture: JSON lines, the first a header (what made it), then
//! one GeoJSON FeatureCollection per update. `mgmot review` opens it; any JSON tool reads it.

use serde_json::{json, Value};
use std::io::Write;
use std::path::{Path, PathBuf};

/// The header line's `format`.
pub const FORMAT: &str = "mgmot-ground-recording";
/// The header line's `version`.
pub const VERSION: u32 = 1;

/// Why the recording failed.
#[derive(Debug, thiserror::Error)]
#[error("recording {path}: {source}")]
pub struct RecordError {
    /// The file.
    pub path: PathBuf,
    /// Why.
    pub source: std::io::Error,
}

/// An open recording.
#[derive(Debug)]
pub struct GroundRecorder {
    path: PathBuf,
    out: std::io::BufWriter<std::fs::File>,
    /// Updates written.
    pub updates: u64,
}

impl GroundRecorder {
    /// Creates (or empties) the file and writes the header.
    pub fn create(path: &Path, config: &Value) -> Result<Self, RecordError> {
        let err = |source| RecordError {
            path: path.to_owned(),
            source,
        };
        let file = std::fs::File::create(path).map_err(err)?;
        let mut r = Self {
            path: path.to_owned(),
            out: std::io::BufWriter::new(file),
            updates: 0,
        };
        let header = json!({
            "format": FORMAT,
            "version": VERSION,
            "mgmot_version": env!("CARGO_PKG_VERSION"),
            "config": config,
        });
        r.line(&header)?;
        r.flush()?;
        Ok(r)
    }

    fn line(&mut self, v: &Value) -> Result<(), RecordError> {
        serde_json::to_writer(&mut self.out, v)
            .map_err(std::io::Error::from)
            .and_then(|()| self.out.write_all(b"\n"))
            .map_err(|source| RecordError {
                path: self.path.clone(),
                source,
            })
    }

    /// Appends one picture (flushed: a crash loses at most the update being written).
    pub fn update(&mut self, picture: &Value) -> Result<(), RecordError> {
        self.line(picture)?;
        self.updates += 1;
        self.flush()
    }

    fn flush(&mut self) -> Result<(), RecordError> {
        self.out.flush().map_err(|source| RecordError {
            path: self.path.clone(),
            source,
        })
    }
}

/// Reads a recording: the header and the pictures.
pub fn read(path: &Path) -> Result<(Value, Vec<Value>), String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let mut lines = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty());
    let (_, first) = lines
        .next()
        .ok_or_else(|| format!("{}: empty, not a ground recording", path.display()))?;
    let header: Value =
        serde_json::from_str(first).map_err(|e| format!("{}:1: not JSON: {e}", path.display()))?;
    if header.get("format").and_then(Value::as_str) != Some(FORMAT) {
        return Err(format!(
            "{}: not a ground recording (its first line has no \"format\": \"{FORMAT}\")",
            path.display()
        ));
    }
    let mut pictures = Vec::new();
    for (i, line) in lines {
        match serde_json::from_str::<Value>(line) {
            Ok(v) => pictures.push(v),
            // A recording cut by a crash ends in half a line: keep what is whole.
            Err(e) => {
                tracing::warn!(line = i + 1, error = %e, "ground recording: skipping a broken line")
            }
        }
    }
    Ok((header, pictures))
}
