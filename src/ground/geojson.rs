//! The picture as GeoJSON (RFC 7946): the fused tracks, the drones and their cameras'
//! footprints; what the live map draws, the file a GIS opens, and each line of the recording.

use super::ingest::Drone;
use mgmot_core::digest::class_name;
use mgmot_core::fuse::{FusedTrack, FusedTrackState};
use serde_json::{json, Value};

/// A time in s as integer ms (GeoJSON consumers like integers; NaN becomes null).
fn ms(t_s: f64) -> Value {
    if t_s.is_finite() {
        json!((t_s * 1000.0).round() as i64)
    } else {
        Value::Null
    }
}

/// A number, or null when not finite (JSON has no NaN).
fn num(v: f64) -> Value {
    if v.is_finite() {
        json!(v)
    } else {
        Value::Null
    }
}

/// One fused track as a Point feature.
pub fn track_feature(t: &FusedTrack) -> Value {
    let members: Vec<Value> = t
        .members
        .iter()
        .map(|m| {
            json!({
                "system_id": m.system_id,
                "track_id": m.track_id,
                "state": if !m.live { "ended" } else if m.tracked { "tracked" } else { "lost" },
            })
        })
        .collect();
    json!({
        "type": "Feature",
        "id": format!("track-{}", t.id),
        "geometry": {"type": "Point", "coordinates": [t.lon_deg, t.lat_deg]},
        "properties": {
            "kind": "track",
            "fused_id": t.id,
            "class": class_name(t.class_id),
            "class_id": t.class_id,
            "state": match t.state { FusedTrackState::Tracked => "tracked", FusedTrackState::Lost => "lost" },
            "ce95_m": num(t.ce95_m),
            "last_seen_unix_ms": t.last_seen_s.map_or(Value::Null, ms),
            "vel_n_m_s": num(t.vel_ne_m_s.x),
            "vel_e_m_s": num(t.vel_ne_m_s.y),
            "members": members,
            "merged_from": t.merged_from,
        }
    })
}

/// One drone as a Point feature (`None` before its first position).
pub fn drone_feature(d: &Drone) -> Option<Value> {
    let (lat, lon) = d.position?;
    Some(json!({
        "type": "Feature",
        "id": format!("drone-{}", d.system_id),
        "geometry": {"type": "Point", "coordinates": [lon, lat]},
        "properties": {
            "kind": "drone",
            "system_id": d.system_id,
            "alt_m": num(d.alt_m),
            "heading_deg": d.heading_deg.map_or(Value::Null, num),
            "last_unix_ms": ms(d.last_heard_s),
            "track_messages": d.track_messages,
            "digest_positions": d.digest_positions,
        }
    }))
}

/// A footprint older than this (s) is no longer drawn: the camera has moved on, or stopped
/// telling where it looks.
pub const FOOTPRINT_STALE_S: f64 = 10.0;

/// One drone's camera footprint as a Polygon feature (`None` without a fresh one). Its
/// arrival is on the ground's clock, `ground_s` now; `now_s` is the picture's time, which its
/// `time_unix_ms` is given on.
pub fn footprint_feature(d: &Drone, now_s: f64, ground_s: f64) -> Option<Value> {
    let at = d.footprint_s?;
    if d.footprint.len() < 3 || (ground_s - at).abs() > FOOTPRINT_STALE_S {
        return None;
    }
    let mut ring: Vec<[f64; 2]> = d.footprint.iter().map(|&(lat, lon)| [lon, lat]).collect();
    // RFC 7946: an exterior ring runs counterclockwise (positive shoelace area in lon, lat).
    let twice_area: f64 = ring
        .iter()
        .zip(ring.iter().cycle().skip(1))
        .map(|(a, b)| a[0] * b[1] - b[0] * a[1])
        .sum();
    if twice_area < 0.0 {
        ring.reverse();
    }
    ring.push(ring[0]);
    Some(json!({
        "type": "Feature",
        "id": format!("footprint-{}", d.system_id),
        "geometry": {"type": "Polygon", "coordinates": [ring]},
        "properties": {
            "kind": "footprint",
            "system_id": d.system_id,
            "time_unix_ms": ms(at - ground_s + now_s),
        }
    }))
}

/// The whole picture at fuser time `now_s` (the time the tracks were predicted to), made at
/// `ground_s` on the ground's clock.
pub fn collection<'a>(
    now_s: f64,
    ground_s: f64,
    tracks: &[FusedTrack],
    drones: impl Iterator<Item = &'a Drone>,
) -> Value {
    let mut features: Vec<Value> = tracks.iter().map(track_feature).collect();
    for d in drones {
        features.extend(footprint_feature(d, now_s, ground_s));
        features.extend(drone_feature(d));
    }
    json!({
        "type": "FeatureCollection",
        "properties": {
            "source": "mgmot ground",
            "time_unix_ms": ms(now_s),
            "generated_utc": crate::cot::event::format_time((now_s * 1e6) as i64),
        },
        "features": features,
    })
}
