//! `mgmot review`: a recorded flight ([`Flight`]) turned into what a rescue coordinator and an
//! engineer look at afterwards. [`Review::build`] computes everything (per-track summaries,
//! the camera footprint per frame, telemetry health from `flight.tlog`, keyframes, and the
//! error against the simulator's truth when given); [`html`] writes it as one self-contained
//! HTML page and [`geo_export`] as GeoJSON and KML.
//!
//! Positions on the page are in a local north/east frame (metres) whose origin is the water
//! under the first pose; the page draws a lat/lon graticule over it.

pub mod geo_export;
mod health;
pub mod html;
pub mod truth;

use crate::config::Config;
use crate::geo::{CameraModel, Geodetic, Geolocator, LocalTangentFrame, Pixel, PoseNoise};
use crate::record::flight::KEYFRAMES as KEYFRAMES_DIR;
use crate::record::format::FrameRecord;
use crate::record::tlog::TlogEntry;
use crate::record::{Flight, RecordError};
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

pub use health::Health;
pub use truth::{Truth, TruthReview};

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
const EDGE_SAMPLES: usize = 6;
/// The camera's horizontal field of view when `config.toml` has none (deg).
const DEFAULT_HFOV_DEG: f64 = 70.0;

/// Class names by the tracker's class id (the ids of `MGMOT_OBJECT_CLASS`).
const CLASS_NAMES: [&str; 6] = [
    "unknown",
    "swimmer",
    "boat",
    "jetski",
    "life-saving appliance",
    "buoy",
];

/// The name of a tracker class id.
pub fn class_name(id: u32) -> &'static str {
    CLASS_NAMES.get(id as usize).copied().unwrap_or("unknown")
}

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

/// UTC (RFC 3339, milliseconds) of a time in µs since the UNIX epoch.
pub fn utc(unix_us: u64) -> String {
    let us = i64::try_from(unix_us).unwrap_or(i64::MAX);
    chrono::DateTime::from_timestamp_micros(us)
        .unwrap_or_default()
        .to_rfc3339_opts(chrono::SecondsFormat::Millis, true)
}

/// A frame's time (µs since the UNIX epoch): its exposure when mapped, else when processed.
pub fn frame_unix_us(f: &FrameRecord) -> u64 {
    f.captured_unix_us.unwrap_or(f.processed_unix_us)
}

/// Degrees as D°M.mmm' with a hemisphere letter (`pos`/`neg`: "N"/"S" or "E"/"W").
pub fn dm(deg: f64, pos: char, neg: char) -> String {
    let h = if deg < 0.0 { neg } else { pos };
    let a = deg.abs();
    let mut d = a.trunc();
    let mut m = (a - d) * 60.0;
    // 59.9996' rounds to 60.000': carry it into the degrees.
    if (m * 1000.0).round() >= 60_000.0 {
        d += 1.0;
        m = 0.0;
    }
    format!("{d:.0}°{m:06.3}'{h}")
}

/// The flight's identity and how it ended.
#[derive(Debug, Clone, Serialize)]
pub struct FlightSummary {
    /// The folder.
    pub dir: String,
    /// Start of the recording (UTC).
    pub started_utc: String,
    /// The vehicle's system id.
    pub system_id: u8,
    /// The mgmot that recorded it.
    pub mgmot_version: String,
    /// The detector (`kind file sha256`).
    pub detector: String,
    /// Whether `frames.ndjson` has an end record.
    pub clean_end: bool,
    /// Frame records.
    pub frames: usize,
    /// Lines of `frames.ndjson` that could not be read.
    pub bad_lines: usize,
    /// Recording gaps: (stopped UTC, resumed UTC, reason, frames lost).
    pub gaps: Vec<(String, String, String, u64)>,
    /// First and last frame time (UTC), when there are frames.
    pub span_utc: Option<(String, String)>,
    /// Duration of the frames (s).
    pub duration_s: f64,
    /// Reference of the local frame (lat, lon in degrees), when any frame had a pose.
    pub origin: Option<(f64, f64)>,
    /// The camera's horizontal field of view used for the footprints (deg).
    pub hfov_deg: f64,
}

/// One frame on the map.
#[derive(Debug, Clone, Serialize)]
pub struct MapFrame {
    /// Time since the first frame (s).
    pub t: f64,
    /// Drone position north, east (m), when posed.
    pub drone: Option<[f64; 2]>,
    /// Camera footprint on the sea (north, east in m), clipped to what projects below the
    /// horizon and within [`FOOTPRINT_MAX_RANGE_M`]; empty when there is none.
    pub footprint: Vec<[f64; 2]>,
}

/// A track's position in one frame.
#[derive(Debug, Clone, Serialize)]
pub struct TrackPoint {
    /// Time since the first frame (s).
    pub t: f64,
    /// UTC (µs since the UNIX epoch).
    pub unix_us: u64,
    /// The id it was reported under in this frame.
    pub reported_id: u64,
    /// Local north, east (m), when geolocated.
    pub ne: Option<[f64; 2]>,
    /// Latitude, longitude (deg), when geolocated.
    pub lat_lon: Option<[f64; 2]>,
    /// Horizontal standard deviation (m), when geolocated.
    pub h_std_m: Option<f64>,
    /// Velocity north, east (m/s), when geolocated.
    pub vel_ne: Option<[f64; 2]>,
}

/// A stretch of a track's timeline under one reported id.
#[derive(Debug, Clone, Serialize)]
pub struct Segment {
    /// The id reported in this stretch (before any merge it takes part in).
    pub id: u64,
    /// Start (s since the first frame).
    pub t0: f64,
    /// End (s).
    pub t1: f64,
    /// `detected`, `coasting` or `lost`.
    pub state: &'static str,
}

/// A track under its final id (after ReID merges), with what a coordinator radios out.
#[derive(Debug, Clone, Serialize)]
pub struct TrackSummary {
    /// The final id.
    pub id: u64,
    /// Every id it was reported under (the final one included), ascending.
    pub ids: Vec<u64>,
    /// Class id of its last report (the tracker's majority vote).
    pub class_id: u32,
    /// Its name.
    pub class: &'static str,
    /// First seen (UTC).
    pub first_utc: String,
    /// Last seen (UTC).
    pub last_utc: String,
    /// First seen (s since the first frame).
    pub first_t: f64,
    /// Last seen (s).
    pub last_t: f64,
    /// Frames it was reported in.
    pub frames: usize,
    /// The last geolocated position: latitude, longitude (deg).
    pub last_lat_lon: Option<[f64; 2]>,
    /// The same as D°M.mmm' text.
    pub last_dm: Option<String>,
    /// Its horizontal standard deviation (m).
    pub last_h_std_m: Option<f64>,
    /// When it was (UTC).
    pub last_fix_utc: Option<String>,
    /// Path length over the geolocated positions (m).
    pub distance_m: f64,
    /// Drift speed: the tracker's velocity at the last fix (m/s).
    pub drift_mps: Option<f64>,
    /// Its direction (deg, true north, towards which it drifts).
    pub drift_course_deg: Option<f64>,
    /// Positions per frame.
    pub points: Vec<TrackPoint>,
    /// Detected / coasting / lost stretches.
    pub segments: Vec<Segment>,
}

/// A ReID merge.
#[derive(Debug, Clone, Serialize)]
pub struct Merge {
    /// When (s since the first frame).
    pub t: f64,
    /// The new id.
    pub new_id: u64,
    /// The old id it became.
    pub merged_into_id: u64,
    /// The final id of both.
    pub final_id: u64,
}

/// A contact repair as the report shows it: two tracks had exchanged the objects they follow
/// (while their boxes overlapped) and exchanged them back.
#[derive(Debug, Clone, Serialize)]
pub struct Exchange {
    /// When it was decided (s since the first frame).
    pub t: f64,
    /// Since when the two were swapped (s since the first frame; the decision's own time when
    /// that frame is not in the record).
    pub since_t: f64,
    /// The final ids of the two tracks.
    pub ids: (u64, u64),
}

/// A detection box (full-frame pixels) on a keyframe.
#[derive(Debug, Clone, Serialize)]
pub struct KeyBox {
    /// Left, top, width, height (px of the full frame).
    pub xywh: [f64; 4],
    /// Final track id, or `None` for a detection that no track reported.
    pub track_id: Option<u64>,
    /// Class name.
    pub class: &'static str,
    /// Score.
    pub score: f32,
}

/// A recorded keyframe.
#[derive(Debug, Clone, Serialize)]
pub struct Keyframe {
    /// Time (s since the first frame).
    pub t: f64,
    /// UTC.
    pub utc: String,
    /// File name under `keyframes/`.
    pub file: String,
    /// The full frame's size (px): the boxes' coordinate space.
    pub width_px: u32,
    /// Height (px).
    pub height_px: u32,
    /// Tracks (with their final ids) and untracked detections.
    pub boxes: Vec<KeyBox>,
    /// `data:image/jpeg;base64,...`, filled by the page writer (`None`: unreadable).
    pub data_uri: Option<String>,
}

/// Everything the report shows.
#[derive(Debug, Clone, Serialize)]
pub struct Review {
    /// The flight.
    pub flight: FlightSummary,
    /// The map's frames (thinned to [`MAX_MAP_FRAMES`]).
    pub map: Vec<MapFrame>,
    /// Tracks by final id.
    pub tracks: Vec<TrackSummary>,
    /// ReID merges.
    pub merges: Vec<Merge>,
    /// Contact repairs.
    pub exchanges: Vec<Exchange>,
    /// Telemetry health.
    pub health: Health,
    /// Keyframes (thinned to [`MAX_KEYFRAMES`]), images not yet read.
    pub keyframes: Vec<Keyframe>,
    /// Keyframes recorded in all.
    pub keyframes_recorded: usize,
    /// The error against the simulator's truth.
    pub truth: Option<TruthReview>,
}

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
fn thin(n: usize, max: usize) -> Vec<usize> {
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
fn footprint(f: &FrameRecord, origin: Geodetic, hfov_deg: f64) -> Vec<[f64; 2]> {
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
fn segments_of(id: u64, times: impl Iterator<Item = f64>, frame_dt: f64) -> Vec<Segment> {
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
            detector: format!("{} {} (sha256 {})", d.kind, d.file, d.sha256),
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
