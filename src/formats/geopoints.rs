//! Geolocated point tables as CSV or GeoJSON, chosen by the output file's extension.

use super::error::FormatError;
use serde::Serialize;
use std::io::Write;
use std::path::Path;

/// A row that has a WGS84 position.
pub trait GeoRow: Serialize {
    /// Latitude (deg).
    fn lat_deg(&self) -> f64;
    /// Longitude (deg).
    fn lon_deg(&self) -> f64;
}

/// The output layouts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GeoFormat {
    /// Comma-separated values with a header row (the row struct's field names).
    Csv,
    /// A GeoJSON FeatureCollection of Points; each row's fields become the properties.
    GeoJson,
}

impl GeoFormat {
    /// The layout an output path asks for: `.csv`, or `.geojson` / `.json`.
    pub fn from_path(path: &Path) -> Result<Self, FormatError> {
        match path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase)
            .as_deref()
        {
            Some("csv") => Ok(Self::Csv),
            Some("geojson") | Some("json") => Ok(Self::GeoJson),
            _ => Err(FormatError::invalid(
                path,
                "file name",
                "unknown output format: use a .csv or .geojson extension",
            )),
        }
    }
}

fn io_err(path: &Path) -> impl Fn(std::io::Error) -> FormatError + '_ {
    move |source| FormatError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// Writes `rows` to `path` in the layout its extension names. Nothing is written for an
/// unknown extension.
pub fn write_geo_rows<T: GeoRow>(path: &Path, rows: &[T]) -> Result<(), FormatError> {
    let format = GeoFormat::from_path(path)?;
    let file = std::fs::File::create(path).map_err(io_err(path))?;
    let mut out = std::io::BufWriter::new(file);
    match format {
        GeoFormat::Csv => {
            let mut w = csv::Writer::from_writer(&mut out);
            for row in rows {
                w.serialize(row)
                    .map_err(|e| FormatError::invalid(path, "row", e.to_string()))?;
            }
            w.flush().map_err(io_err(path))?;
        }
        GeoFormat::GeoJson => {
            let features: Vec<serde_json::Value> = rows
                .iter()
                .map(|row| {
                    serde_json::json!({
                        "type": "Feature",
                        "geometry": {"type": "Point", "coordinates": [row.lon_deg(), row.lat_deg()]},
                        "properties": row,
                    })
                })
                .collect();
            let doc = serde_json::json!({"type": "FeatureCollection", "features": features});
            serde_json::to_writer(&mut out, &doc)
                .map_err(|e| FormatError::invalid(path, "features", e.to_string()))?;
            out.write_all(b"\n").map_err(io_err(path))?;
        }
    }
    out.flush().map_err(io_err(path))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Serialize)]
    struct Row {
        id: u32,
        lat_deg: f64,
        lon_deg: f64,
    }
    impl GeoRow for Row {
        fn lat_deg(&self) -> f64 {
            self.lat_deg
        }
        fn lon_deg(&self) -> f64 {
            self.lon_deg
        }
    }

    #[test]
    fn writes_csv_and_geojson() {
        let dir = tempfile::tempdir().unwrap();
        let rows = [Row {
            id: 1,
            lat_deg: 47.5,
            lon_deg: 9.25,
        }];
        let csv_path = dir.path().join("p.csv");
        write_geo_rows(&csv_path, &rows).unwrap();
        assert_eq!(
            std::fs::read_to_string(&csv_path).unwrap(),
            "id,lat_deg,lon_deg\n1,47.5,9.25\n"
        );
        let gj = dir.path().join("p.geojson");
        write_geo_rows(&gj, &rows).unwrap();
        let v: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&gj).unwrap()).unwrap();
        assert_eq!(v["features"][0]["geometry"]["coordinates"][0], 9.25);
        assert_eq!(v["features"][0]["properties"]["id"], 1);
        assert!(write_geo_rows(&dir.path().join("p.txt"), &rows).is_err());
    }
}
