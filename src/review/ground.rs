//! Review of a `mgmot ground` recording: each fused id's life (class, first and last time
//! seen, the drones' tracks it held, its path) as one self-contained HTML table, and the paths
//! as GeoJSON LineStrings beside it.

use super::text::utc;
use serde_json::{json, Value};
use std::collections::{BTreeMap, BTreeSet};
use std::fmt::Write as _;

/// One fused id over the recording.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct FusedLife {
    /// The fused id.
    pub fused_id: u64,
    /// Class name.
    pub class: String,
    /// First and last update that held it (UTC ms).
    pub first_ms: i64,
    /// Last update that held it (UTC ms).
    pub last_ms: i64,
    /// Updates in which a drone saw it.
    pub tracked_updates: u64,
    /// The drones' tracks it held (`system id:track id`).
    pub members: BTreeSet<String>,
    /// Fused ids merged into it.
    pub merged_from: BTreeSet<u64>,
    /// Its position at each update while tracked (lon, lat).
    pub path: Vec<(f64, f64)>,
}

/// Every fused id of the recording's pictures, by id.
pub fn lives(pictures: &[Value]) -> Vec<FusedLife> {
    let mut by: BTreeMap<u64, FusedLife> = BTreeMap::new();
    for p in pictures {
        let Some(t) = p["properties"]["time_unix_ms"].as_i64() else {
            continue;
        };
        let Some(features) = p["features"].as_array() else {
            continue;
        };
        for f in features {
            let props = &f["properties"];
            let Some(id) = props["fused_id"]
                .as_u64()
                .filter(|_| props["kind"] == "track")
            else {
                continue;
            };
            let life = by.entry(id).or_insert_with(|| FusedLife {
                fused_id: id,
                first_ms: t,
                ..FusedLife::default()
            });
            life.class = props["class"].as_str().unwrap_or("object").to_owned();
            life.last_ms = t;
            for m in props["members"].as_array().into_iter().flatten() {
                if let (Some(s), Some(k)) = (m["system_id"].as_u64(), m["track_id"].as_u64()) {
                    life.members.insert(format!("{s}:{k}"));
                }
            }
            for m in props["merged_from"].as_array().into_iter().flatten() {
                life.merged_from.extend(m.as_u64());
            }
            if props["state"] == "tracked" {
                life.tracked_updates += 1;
                let c = &f["geometry"]["coordinates"];
                if let (Some(lon), Some(lat)) = (c[0].as_f64(), c[1].as_f64()) {
                    life.path.push((lon, lat));
                }
            }
        }
    }
    by.into_values().collect()
}

/// The paths as a GeoJSON FeatureCollection (one LineString, or Point, per fused id).
pub fn paths_geojson(lives: &[FusedLife]) -> Value {
    let features: Vec<Value> = lives
        .iter()
        .filter(|l| !l.path.is_empty())
        .map(|l| {
            let coords: Vec<[f64; 2]> = l.path.iter().map(|(lo, la)| [*lo, *la]).collect();
            let geometry = if coords.len() == 1 {
                json!({"type": "Point", "coordinates": coords[0]})
            } else {
                json!({"type": "LineString", "coordinates": coords})
            };
            json!({
                "type": "Feature",
                "id": format!("track-{}", l.fused_id),
                "geometry": geometry,
                "properties": {
                    "fused_id": l.fused_id,
                    "class": l.class,
                    "first_unix_ms": l.first_ms,
                    "last_unix_ms": l.last_ms,
                    "members": l.members.iter().cloned().collect::<Vec<_>>(),
                    "merged_from": l.merged_from.iter().copied().collect::<Vec<_>>(),
                },
            })
        })
        .collect();
    json!({"type": "FeatureCollection", "features": features})
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// The HTML report: a summary and one table row per fused id.
pub fn html(lives: &[FusedLife], updates: usize, source: &str) -> String {
    let drones: BTreeSet<&str> = lives
        .iter()
        .flat_map(|l| l.members.iter())
        .filter_map(|m| m.split(':').next())
        .collect();
    let both = lives
        .iter()
        .filter(|l| {
            l.members
                .iter()
                .filter_map(|m| m.split(':').next())
                .collect::<BTreeSet<_>>()
                .len()
                > 1
        })
        .count();
    let mut rows = String::new();
    for l in lives {
        let _ = write!(
            rows,
            "<tr><td>#{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            l.fused_id,
            escape(&l.class),
            escape(&utc(l.first_ms.max(0) as u64 * 1000)),
            escape(&utc(l.last_ms.max(0) as u64 * 1000)),
            l.tracked_updates,
            escape(&l.members.iter().cloned().collect::<Vec<_>>().join(" ")),
            escape(
                &l.merged_from
                    .iter()
                    .map(|m| format!("#{m}"))
                    .collect::<Vec<_>>()
                    .join(" ")
            ),
        );
    }
    format!(
        "<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\"><title>mgmot ground review</title>\
         <style>body{{font-family:sans-serif;margin:1.5em}}table{{border-collapse:collapse}}\
         td,th{{border:1px solid #ccc;padding:2px 8px;text-align:left}}th{{background:#eee}}</style></head><body>\
         <h1>Ground picture review</h1><p>{} &middot; {updates} updates &middot; {} drones &middot; \
         {} fused ids, {both} held tracks of more than one drone</p>\
         <p>The paths are in <code>ground_tracks.geojson</code> beside this file.</p>\
         <table><tr><th>fused id</th><th>class</th><th>first</th><th>last</th><th>updates seen</th>\
         <th>drone:track</th><th>merged from</th></tr>{rows}</table></body></html>\n",
        escape(source),
        drones.len(),
        lives.len()
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fused track as the test writes it: id, class, state, members (system id, track id).
    type Track<'a> = (u64, &'a str, &'a str, &'a [(u8, u64)]);

    fn picture(t: i64, tracks: &[Track<'_>]) -> Value {
        let features: Vec<Value> = tracks
            .iter()
            .map(|(id, class, state, members)| {
                json!({
                    "type": "Feature",
                    "geometry": {"type": "Point", "coordinates": [9.0 + *id as f64 * 1e-4, 47.0]},
                    "properties": {
                        "kind": "track", "fused_id": id, "class": class, "state": state,
                        "members": members.iter().map(|(s, k)| json!({"system_id": s, "track_id": k})).collect::<Vec<_>>(),
                        "merged_from": [],
                    }
                })
            })
            .collect();
        json!({"type": "FeatureCollection", "properties": {"time_unix_ms": t}, "features": features})
    }

    #[test]
    fn lives_follow_each_fused_id_over_the_updates() {
        let pictures = vec![
            picture(1000, &[(1, "swimmer", "tracked", &[(1, 12)])]),
            picture(
                2000,
                &[
                    (1, "swimmer", "tracked", &[(1, 12), (2, 7)]),
                    (2, "boat", "lost", &[(2, 3)]),
                ],
            ),
            picture(3000, &[(1, "swimmer", "lost", &[(1, 12), (2, 7)])]),
        ];
        let l = lives(&pictures);
        assert_eq!(l.len(), 2);
        assert_eq!(
            (l[0].first_ms, l[0].last_ms, l[0].tracked_updates),
            (1000, 3000, 2)
        );
        assert_eq!(
            l[0].members.iter().cloned().collect::<Vec<_>>(),
            ["1:12", "2:7"]
        );
        assert_eq!(l[0].path.len(), 2);
        assert!(l[1].path.is_empty());
        let g = paths_geojson(&l);
        assert_eq!(g["features"].as_array().unwrap().len(), 1);
        assert_eq!(g["features"][0]["geometry"]["type"], "LineString");
        let page = html(&l, 3, "<x>");
        assert!(
            page.contains("2 fused ids, 1 held tracks of more than one drone"),
            "{page}"
        );
        assert!(page.contains("&lt;x&gt;"));
    }
}
