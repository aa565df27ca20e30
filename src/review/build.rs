//! Building the review from a flight's record: tracks and their segments, footprints, merges,
//! keyframes' boxes.

use super::health::Health;
use super::model::{
    Exchange, FlightSummary, KeyBox, Keyframe, MapFrame, Merge, Review, Segment, TrackPoint,
    TrackSummary,
};
use super::text::{class_name, dm, frame_unix_us, utc};
use super::truth::Truth;
use crate::config::Config;
use crate::geo::{CameraModel, Geodetic, Geolocator, LocalTangentFrame, Pixel, PoseNoise};
use crate::record::format::FrameRecord;
use crate::record::tlog::TlogEntry;
use crate::record::Flight;
use std::collections::BTreeMap;

/// A track absent for at most this long (s) between two frames where it is reported is
/// drawn as coasting (the tracker predicts it); longer, as lost.
pub const COASTING_MAX_S: f64 = 2.0;
/// Footprint points farther than this from the camera (m) are left out: near the horizon the
/// flat-sea projection runs off to kilometres and would squash the map.
pub const FOOTPRINT_MAX_RANGE_M: f64 = 1500.0;
/// At most this many frames are kept for the map's drone path and footprints (evenly
/// thinned beyond it; a one-hour flight has tens of thousands of frames).
pub const MAX_MAP_FRAMES: usize = 2000;
/// At most this many keyframes are embedded in the page (evenly thinned beyond it).
pub const MAX_KEYFRAMES: usize = 48;
/// Samples along each image edge for the footprint (corners included).
pub(super) const EDGE_SAMPLES: usize = 6;
/// The camera's horizontal field of view when `config.toml` has none (deg).
const DEFAULT_HFOV_DEG: f64 = 70.0;

/// Follows ReID merges to the id a track ended up with.
#[derive(Debug, Default)]
pub struct Merges {
    into: BTreeMap<u64, u64>,
}

impl Merges {
    /// From every merge of a flight.
    pub fn of(frames: &[FrameRecord]) -> Self {
        let mut into = BTreeMap::new();
        for m in frames.iter().flat_map(|f| &f.merges) {
            if m.new_id != m.merged_into_id {
                into.insert(m.new_id, m.merged_into_id);
            }
        }
        Self { into }
    }

    /// The final id of `id` (a cycle stops where it closes).
    pub fn final_id(&self, id: u64) -> u64 {
        let mut f = id;
        for _ in 0..=self.into.len() {
            match self.into.get(&f) {
                Some(&next) if next != id => f = next,
                _ => break,
            }
        }
        f
    }
}

/// Evenly spaced indices, at most `max` of `n` (first and last kept).
pub(super) fn thin(n: usize, max: usize) -> Vec<usize> {
    if n <= max {
        return (0..n).collect();
    }
    if max < 2 {
        return (0..max).collect();
    }
    let mut v: Vec<usize> = (0..max).map(|i| i * (n - 1) / (max - 1)).collect();
    v.dedup();
    v
}

/// The camera's horizontal field of view from `config.toml` (70° when absent or invalid).
fn hfov_of(config_toml: &str) -> f64 {
    match Config::parse(config_toml) {
        Ok(c) if c.camera.hfov_deg.is_finite() && c.camera.hfov_deg > 0.0 => c.camera.hfov_deg,
        Ok(_) => DEFAULT_HFOV_DEG,
        Err(e) => {
            tracing::warn!(error = %e, "config.toml does not parse; footprints use a 70 deg field of view");
            DEFAULT_HFOV_DEG
        }
    }
}

/// The points of the image border (clockwise from the top-left corner).
fn border(width: f64, height: f64) -> Vec<Pixel> {
    let mut px = Vec::with_capacity(4 * EDGE_SAMPLES);
    let step = |i: usize| i as f64 / EDGE_SAMPLES as f64;
    for i in 0..EDGE_SAMPLES {
        px.push(Pixel::new(width * step(i), 0.0));
    }
    for i in 0..EDGE_SAMPLES {
        px.push(Pixel::new(width, height * step(i)));
    }
    for i in 0..EDGE_SAMPLES {
        px.push(Pixel::new(width * (1.0 - step(i)), height));
    }
    for i in 0..EDGE_SAMPLES {
        px.push(Pixel::new(0.0, height * (1.0 - step(i))));
    }
    px
}

/// The footprint of one frame in the reference frame (north, east).
pub(super) fn footprint(f: &FrameRecord, origin: Geodetic, hfov_deg: f64) -> Vec<[f64; 2]> {
    let Some(pose) = &f.pose else {
        return Vec::new();
    };
    let (Ok(meta), Ok(camera)) = (
        pose.to_meta(),
        CameraModel::from_hfov(f.width_px, f.height_px, hfov_deg),
    ) else {
        return Vec::new();
    };
    let geolocator = Geolocator::new(origin, camera, PoseNoise::default())
        .with_max_range_m(FOOTPRINT_MAX_RANGE_M);
    let Ok(geometry) = geolocator.frame(&meta) else {
        return Vec::new();
    };
    border(f64::from(f.width_px), f64::from(f.height_px))
        .into_iter()
        .filter_map(|px| geometry.locate(px).ok())
        .map(|g| [g.ned_m.x, g.ned_m.y])
        .collect()
}

/// The detected / coasting / lost stretches of one reported id from the times it was
/// reported at (ascending).
pub(super) fn segments_of(
    id: u64,
    times: impl Iterator<Item = f64>,
    frame_dt: f64,
) -> Vec<Segment> {
    let mut segments: Vec<Segment> = Vec::new();
    for t in times {
        match segments.last_mut() {
            Some(s) if t - s.t1 <= 1.5 * frame_dt => s.t1 = t,
            Some(s) => {
                let t1 = s.t1;
                let state = if t - t1 <= COASTING_MAX_S {
                    "coasting"
                } else {
                    "lost"
                };
                segments.push(Segment {
                    id,
                    t0: t1,
                    t1: t,
                    state,
                });
                segments.push(Segment {
                    id,
                    t0: t,
                    t1: t,
                    state: "detected",
                });
            }
            None => segments.push(Segment {
                id,
                t0: t,
                t1: t,
                state: "detected",
            }),
        }
    }
    segments
}

/// The tracks of a flight under their final ids.
fn tracks(
    frames: &[FrameRecord],
    merges: &Merges,
    frame_local: Option<&LocalTangentFrame>,
    t_of: &dyn Fn(&FrameRecord) -> f64,
) -> Vec<TrackSummary> {
    let mut by_id: BTreeMap<u64, (Vec<TrackPoint>, Vec<u64>, u32)> = BTreeMap::new();
    for f in frames {
        for r in &f.tracks {
            let id = merges.final_id(r.track.id);
            let entry = by_id
                .entry(id)
                .or_insert_with(|| (Vec::new(), Vec::new(), 0));
            if !entry.1.contains(&r.track.id) {
                entry.1.push(r.track.id);
            }
            entry.2 = r.track.class_id;
            let ne = match (frame_local, &r.geo) {
                (Some(local), Some(g)) => {
                    Geodetic::new(g.lat_deg, g.lon_deg, g.alt_m).ok().map(|p| {
                        let v = local.to_ned(&p);
                        [v.x, v.y]
                    })
                }
                _ => None,
            };
            entry.0.push(TrackPoint {
                t: t_of(f),
                unix_us: frame_unix_us(f),
                reported_id: r.track.id,
                ne,
                lat_lon: r.geo.map(|g| [g.lat_deg, g.lon_deg]),
                h_std_m: r.geo.map(|g| g.h_std_m),
                vel_ne: r.geo.map(|g| [g.vel_n_mps, g.vel_e_mps]),
            });
        }
    }
    // The typical frame interval: a track missing from one frame more than that is absent.
    let mut dts: Vec<f64> = frames
        .windows(2)
        .map(|w| t_of(&w[1]) - t_of(&w[0]))
        .filter(|d| d.is_finite() && *d > 0.0)
        .collect();
    dts.sort_by(f64::total_cmp);
    let frame_dt = dts.get(dts.len() / 2).copied().unwrap_or(0.1);
    by_id
        .into_iter()
        .filter_map(|(id, (points, mut ids, class_id))| {
            let first = points.first()?;
            let last = points.last()?;
            ids.sort_unstable();
            let mut segments: Vec<Segment> = Vec::new();
            for reported in &ids {
                segments.extend(segments_of(
                    *reported,
                    points
                        .iter()
                        .filter(|p| p.reported_id == *reported)
                        .map(|p| p.t),
                    frame_dt,
                ));
            }
            let geo: Vec<&TrackPoint> = points.iter().filter(|p| p.ne.is_some()).collect();
            let distance_m = geo
                .windows(2)
                .filter_map(|w| {
                    let (a, b) = (w[0].ne?, w[1].ne?);
                    Some((a[0] - b[0]).hypot(a[1] - b[1]))
                })
                .sum();
            let last_fix = geo.last();
            let last_lat_lon = last_fix.and_then(|p| p.lat_lon);
            let drift = last_fix.and_then(|p| p.vel_ne);
            Some(TrackSummary {
                id,
                ids,
                class_id,
                class: class_name(class_id),
                first_utc: utc(first.unix_us),
                last_utc: utc(last.unix_us),
                first_t: first.t,
                last_t: last.t,
                frames: points.len(),
                last_lat_lon,
                last_dm: last_lat_lon
                    .map(|[la, lo]| format!("{} {}", dm(la, 'N', 'S'), dm(lo, 'E', 'W'))),
                last_h_std_m: last_fix.and_then(|p| p.h_std_m),
                last_fix_utc: last_fix.map(|p| utc(p.unix_us)),
                distance_m,
                drift_mps: drift.map(|[n, e]| n.hypot(e)),
                drift_course_deg: drift.map(|[n, e]| e.atan2(n).to_degrees().rem_euclid(360.0)),
                points,
                segments,
            })
        })
        .collect()
}

/// The boxes of a keyframe: tracks under their final ids, then detections no track took.
fn key_boxes(f: &FrameRecord, merges: &Merges) -> Vec<KeyBox> {
    let mut boxes: Vec<KeyBox> = f
        .tracks
        .iter()
        .map(|r| {
            let b = &r.track.bbox;
            KeyBox {
                xywh: [b.x, b.y, b.w, b.h],
                track_id: Some(merges.final_id(r.track.id)),
                class: class_name(r.track.class_id),
                score: r.track.score,
            }
        })
        .collect();
    let taken: Vec<usize> = f
        .tracks
        .iter()
        .filter_map(|r| r.track.detection_index)
        .collect();
    for (i, d) in f.detections.iter().enumerate() {
        if taken.contains(&i) {
            continue;
        }
        let b = &d.bbox;
        boxes.push(KeyBox {
            xywh: [b.x, b.y, b.w, b.h],
            track_id: None,
            class: class_name(d.class_id),
            score: d.score,
        });
    }
    boxes
}

impl Review {
    /// Computes the review of a flight from its record, its tlog's packets (whether the tlog
    /// ended cleanly) and, for a simulated flight, the simulator's truth.
    pub fn build(
        flight: &Flight,
        tlog: &[TlogEntry],
        tlog_clean: bool,
        truth: Option<&Truth>,
    ) -> Self {
        let frames = &flight.frames;
        let hfov_deg = hfov_of(&flight.config_toml);
        let t0_us = frames
            .first()
            .map(frame_unix_us)
            .unwrap_or(flight.info.started_unix_us);
        let t_of = |f: &FrameRecord| (frame_unix_us(f) as f64 - t0_us as f64) / 1e6;
        let origin = frames
            .iter()
            .filter_map(|f| f.pose.as_ref()?.to_meta().ok())
            .map(|m| m.nadir_on_water())
            .next();
        let local = origin.map(LocalTangentFrame::new);
        let merges = Merges::of(frames);

        let map = thin(frames.len(), MAX_MAP_FRAMES)
            .into_iter()
            .filter_map(|i| frames.get(i))
            .map(|f| MapFrame {
                t: t_of(f),
                drone: match (&local, &f.pose) {
                    (Some(l), Some(p)) => {
                        Geodetic::new(p.lat_deg, p.lon_deg, p.alt_m).ok().map(|g| {
                            let v = l.to_ned(&g);
                            [v.x, v.y]
                        })
                    }
                    _ => None,
                },
                footprint: origin.map_or_else(Vec::new, |o| footprint(f, o, hfov_deg)),
            })
            .collect();

        let tracks = tracks(frames, &merges, local.as_ref(), &t_of);
        let merge_list = frames
            .iter()
            .flat_map(|f| f.merges.iter().map(move |m| (f, m)))
            .map(|(f, m)| Merge {
                t: t_of(f),
                new_id: m.new_id,
                merged_into_id: m.merged_into_id,
                final_id: merges.final_id(m.merged_into_id),
            })
            .collect();
        let exchanges = frames
            .iter()
            .flat_map(|f| f.exchanges.iter().map(move |e| (f, e)))
            .map(|(f, e)| {
                let t = t_of(f);
                // Frames are recorded in order: the swap's frame by binary search.
                let since = frames.partition_point(|g| g.frame < e.since_frame_index);
                Exchange {
                    t,
                    since_t: frames
                        .get(since)
                        .filter(|g| g.frame == e.since_frame_index)
                        .map_or(t, t_of),
                    ids: (merges.final_id(e.id), merges.final_id(e.other_id)),
                }
            })
            .collect();

        let with_keyframe: Vec<&FrameRecord> =
            frames.iter().filter(|f| f.keyframe.is_some()).collect();
        let keyframes = thin(with_keyframe.len(), MAX_KEYFRAMES)
            .into_iter()
            .filter_map(|i| with_keyframe.get(i).copied())
            .filter_map(|f| {
                Some(Keyframe {
                    t: t_of(f),
                    utc: utc(frame_unix_us(f)),
                    file: f.keyframe.clone()?,
                    width_px: f.width_px,
                    height_px: f.height_px,
                    boxes: key_boxes(f, &merges),
                    data_uri: None,
                })
            })
            .collect();

        let autopilot_component = Config::parse(&flight.config_toml)
            .map(|c| c.mavlink.autopilot_component_id)
            .unwrap_or(1);
        let health = Health::of(
            frames,
            tlog,
            tlog_clean,
            flight.info.system_id,
            autopilot_component,
            flight.info.component_id,
            t0_us,
        );
        let truth = match (truth, &local) {
            (Some(t), Some(l)) => Some(t.review(frames, &merges, l, &t_of)),
            _ => None,
        };

        let d = &flight.info.detector;
        let flight_summary = FlightSummary {
            dir: flight.dir.display().to_string(),
            started_utc: flight.info.started_utc.clone(),
            system_id: flight.info.system_id,
            mgmot_version: flight.info.mgmot_version.clone(),
            detector: match &flight.info.tile_detector {
                None => format!("{} {} (sha256 {})", d.kind, d.file, d.sha256),
                Some(t) => format!(
                    "{} {} (sha256 {}); tiled frames: {} (sha256 {})",
                    d.kind, d.file, d.sha256, t.file, t.sha256
                ),
            },
            clean_end: flight.end.is_some(),
            frames: frames.len(),
            bad_lines: flight.bad_lines.len(),
            gaps: flight
                .gaps
                .iter()
                .map(|g| {
                    (
                        utc(g.stopped_unix_us),
                        utc(g.resumed_unix_us),
                        g.reason.clone(),
                        g.frames_lost,
                    )
                })
                .collect(),
            span_utc: match (frames.first(), frames.last()) {
                (Some(a), Some(b)) => Some((utc(frame_unix_us(a)), utc(frame_unix_us(b)))),
                _ => None,
            },
            duration_s: frames.last().map_or(0.0, t_of),
            origin: origin.map(|o| (o.lat_deg, o.lon_deg)),
            hfov_deg,
        };
        Self {
            flight: flight_summary,
            map,
            tracks,
            merges: merge_list,
            exchanges,
            health,
            keyframes_recorded: with_keyframe.len(),
            keyframes,
            truth,
        }
    }
}
