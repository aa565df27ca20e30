//! `mgmot review`: a recorded flight ([`Flight`]) turned into what a rescue coordinator and an
//! engineer look at afterwards. [`Review::build`] computes everything (per-track summaries,
//! the camera footprint per frame, telemetry health from `flight.tlog`, keyframes, and the
//! error against the simulator's truth when given); [`html`] writes it as one self-contained
//! HTML page and [`geo_export`] as GeoJSON and KML.
//!
//! Positions on the page are in a local north/east frame (metres) whose origin is the water
//! under the first pose; the page draws a lat/lon graticule over it.

mod build;
pub mod geo_export;
pub mod ground;
mod health;
pub mod html;
mod model;
mod text;
pub mod truth;

use crate::record::flight::KEYFRAMES as KEYFRAMES_DIR;
use crate::record::RecordError;
use std::path::{Path, PathBuf};

pub use build::{Merges, COASTING_MAX_S, FOOTPRINT_MAX_RANGE_M, MAX_KEYFRAMES, MAX_MAP_FRAMES};
pub use model::{
    Exchange, FlightSummary, KeyBox, Keyframe, MapFrame, Merge, Review, Segment, TrackPoint,
    TrackSummary,
};
pub use text::{class_name, dm, frame_unix_us, utc};

pub use health::Health;
pub use truth::{Truth, TruthReview};

/// Why a flight cannot be reviewed.
#[derive(Debug, thiserror::Error)]
pub enum ReviewError {
    /// The flight's folder cannot be read.
    #[error(transparent)]
    Record(#[from] RecordError),
    /// The simulator's truth folder cannot be read.
    #[error("truth {path}: {message}")]
    Truth {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// An output cannot be written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The IO error.
        source: std::io::Error,
    },
}

/// The GeoJSON written beside the report.
pub const GEOJSON_FILE: &str = "tracks.geojson";
/// The KML written beside the report.
pub const KML_FILE: &str = "tracks.kml";

/// What [`write`] wrote.
#[derive(Debug, Clone)]
pub struct Written {
    /// The HTML report.
    pub report: PathBuf,
    /// `tracks.geojson` beside it.
    pub geojson: PathBuf,
    /// `tracks.kml` beside it.
    pub kml: PathBuf,
}

fn write_file(path: &Path, bytes: &[u8]) -> Result<(), ReviewError> {
    std::fs::write(path, bytes).map_err(|source| ReviewError::Io {
        path: path.to_owned(),
        source,
    })
}

/// Writes the report to `out` (its keyframes read from `flight_dir`) and `tracks.geojson`
/// and `tracks.kml` into the same folder (created if missing).
pub fn write(review: &mut Review, flight_dir: &Path, out: &Path) -> Result<Written, ReviewError> {
    let folder = match out.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_owned(),
        _ => PathBuf::from("."),
    };
    std::fs::create_dir_all(&folder).map_err(|source| ReviewError::Io {
        path: folder.clone(),
        source,
    })?;
    let json_err = |path: &Path| {
        let path = path.to_owned();
        move |e: serde_json::Error| ReviewError::Io {
            path,
            source: std::io::Error::other(e),
        }
    };
    let geojson = folder.join(GEOJSON_FILE);
    let text =
        serde_json::to_string_pretty(&geo_export::geojson(review)).map_err(json_err(&geojson))?;
    write_file(&geojson, (text + "\n").as_bytes())?;
    let kml = folder.join(KML_FILE);
    write_file(&kml, geo_export::kml(review).as_bytes())?;
    html::embed_keyframes(review, flight_dir);
    let page = html::page(review).map_err(json_err(out))?;
    write_file(out, page.as_bytes())?;
    Ok(Written {
        report: out.to_owned(),
        geojson,
        kml,
    })
}

#[cfg(test)]
mod tests;
