//! The tracks of a review as GeoJSON (RFC 7946) and KML 2.2, for QGIS and Google Earth: per
//! track a LineString of its geolocated positions with their times, and its last position as
//! a Point with id, class, uncertainty and last-seen time.

use super::{utc, Review, TrackSummary};
use serde_json::{json, Value};
use std::fmt::Write as _;

/// The geolocated positions of a track: (lon, lat, UTC).
fn fixes(t: &TrackSummary) -> Vec<(f64, f64, String)> {
    t.points
        .iter()
        .filter_map(|p| {
            let [lat, lon] = p.lat_lon?;
            Some((lon, lat, utc(p.unix_us)))
        })
        .collect()
}

/// Rounds to 1e-8 degrees (about a millimetre) for a readable file.
fn r8(x: f64) -> f64 {
    (x * 1e8).round() / 1e8
}

/// The GeoJSON FeatureCollection: per track a `LineString` (when it has two fixes or more)
/// with `properties.times` (RFC 3339, one per vertex) and a `Point` at its last fix.
pub fn geojson(review: &Review) -> Value {
    let mut features = Vec::new();
    for t in &review.tracks {
        let f = fixes(t);
        if f.len() >= 2 {
            features.push(json!({
                "type": "Feature",
                "id": format!("track-{}", t.id),
                "geometry": {
                    "type": "LineString",
                    "coordinates": f.iter().map(|(lo, la, _)| [r8(*lo), r8(*la)]).collect::<Vec<_>>(),
                },
                "properties": {
                    "kind": "track",
                    "track_id": t.id,
                    "ids": t.ids,
                    "class": t.class,
                    "first_seen": t.first_utc,
                    "last_seen": t.last_utc,
                    "times": f.iter().map(|(_, _, u)| u.as_str()).collect::<Vec<_>>(),
                },
            }));
        }
        if let (Some([lat, lon]), Some(h), Some(at)) =
            (t.last_lat_lon, t.last_h_std_m, &t.last_fix_utc)
        {
            features.push(json!({
                "type": "Feature",
                "id": format!("last-{}", t.id),
                "geometry": { "type": "Point", "coordinates": [r8(lon), r8(lat)] },
                "properties": {
                    "kind": "last_position",
                    "track_id": t.id,
                    "class": t.class,
                    "h_std_m": (h * 10.0).round() / 10.0,
                    "last_seen": at,
                    "position_dm": t.last_dm,
                    "drift_mps": t.drift_mps.map(|v| (v * 100.0).round() / 100.0),
                    "drift_course_deg": t.drift_course_deg.map(f64::round),
                },
            }));
        }
    }
    json!({ "type": "FeatureCollection", "features": features })
}

/// Escapes text for XML.
fn xml(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// The KML document: per track a LineString placemark with its `TimeSpan` and a Point
/// placemark at its last fix with its `TimeStamp`.
pub fn kml(review: &Review) -> String {
    let mut s = String::new();
    let name = xml(&format!(
        "mgmot flight {} (system {})",
        review.flight.started_utc, review.flight.system_id
    ));
    let _ = write!(
        s,
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n\
         <kml xmlns=\"http://www.opengis.net/kml/2.2\">\n<Document>\n<name>{name}</name>\n\
         <Style id=\"track\"><LineStyle><color>ff00aaff</color><width>3</width></LineStyle></Style>\n\
         <Style id=\"last\"><IconStyle><scale>1.1</scale></IconStyle></Style>\n"
    );
    for t in &review.tracks {
        let f = fixes(t);
        if f.len() >= 2 {
            let coords: Vec<String> = f
                .iter()
                .map(|(lo, la, _)| format!("{:.8},{:.8},0", lo, la))
                .collect();
            let _ = write!(
                s,
                "<Placemark id=\"track-{id}\">\n<name>Track {id} ({class})</name>\n\
                 <styleUrl>#track</styleUrl>\n\
                 <TimeSpan><begin>{b}</begin><end>{e}</end></TimeSpan>\n\
                 <LineString><tessellate>1</tessellate><coordinates>{c}</coordinates></LineString>\n\
                 </Placemark>\n",
                id = t.id,
                class = xml(t.class),
                b = xml(&f[0].2),
                e = xml(&f[f.len() - 1].2),
                c = coords.join(" ")
            );
        }
        if let (Some([lat, lon]), Some(h), Some(at)) =
            (t.last_lat_lon, t.last_h_std_m, &t.last_fix_utc)
        {
            let _ = write!(
                s,
                "<Placemark id=\"last-{id}\">\n<name>{id} {class} last</name>\n\
                 <description>Track {id} ({class}), last seen {at}: {lat:.6}, {lon:.6} ({dm}) \
                 ±{h:.1} m</description>\n<styleUrl>#last</styleUrl>\n\
                 <TimeStamp><when>{at}</when></TimeStamp>\n\
                 <ExtendedData><Data name=\"track_id\"><value>{id}</value></Data>\
                 <Data name=\"class\"><value>{class}</value></Data>\
                 <Data name=\"h_std_m\"><value>{h:.1}</value></Data>\
                 <Data name=\"last_seen\"><value>{at}</value></Data></ExtendedData>\n\
                 <Point><coordinates>{lon:.8},{lat:.8},0</coordinates></Point>\n</Placemark>\n",
                id = t.id,
                class = xml(t.class),
                at = xml(at),
                dm = xml(t.last_dm.as_deref().unwrap_or("")),
            );
        }
    }
    s.push_str("</Document>\n</kml>\n");
    s
}
