//! The review's data model: what the page, the GeoJSON and the KML are made from.

use super::health::Health;
use super::truth::TruthReview;
use serde::Serialize;

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
