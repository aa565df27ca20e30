//! The flight record's data: `flight.json` ([`FlightInfo`]) and the lines of `frames.ndjson`
//! ([`Record`]), one JSON object per line, tagged by `"type"`.
//!
//! Newline-delimited JSON because every tool reads it (`jq`, Python's `json`, pandas, a text
//! editor in the field), a line cut short by a crash is detectable and skipped without
//! losing the lines before it, and appending needs no index to patch up (MCAP would need its
//! summary section rewritten, CBOR needs a decoder nobody has on a field laptop). Floats are
//! written in their shortest exact form and read back bit for bit, which is what lets
//! `mgmot replay` reproduce a flight exactly.

use crate::frame::GeoFix;
use crate::geo::{FrameMetadata, GeoError, Geodetic};
use crate::track::{Detection, ExchangeEvent, MergeEvent, TrackOutput};
use nalgebra::{Quaternion, UnitQuaternion};
use serde::{Deserialize, Serialize};

/// `flight.json`'s `format`.
pub const FORMAT: &str = "mgmot-flight";
/// `flight.json`'s `version`: bumped when a field changes meaning or goes away.
pub const VERSION: u32 = 1;

/// `flight.json`: what produced the flight.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FlightInfo {
    /// Always [`FORMAT`].
    pub format: String,
    /// [`VERSION`] when written.
    pub version: u32,
    /// The mgmot that recorded it.
    pub mgmot_version: String,
    /// Start of the recording (UTC, RFC 3339).
    pub started_utc: String,
    /// Start of the recording (µs since the UNIX epoch).
    pub started_unix_us: u64,
    /// The vehicle's MAVLink system id.
    pub system_id: u8,
    /// mgmot's MAVLink component id (its messages in `flight.tlog` carry it).
    pub component_id: u8,
    /// What produced the detections.
    pub detector: DetectorIdentity,
    /// The `[detector] tile_model` configured beside it: it ran the frames that were tiled
    /// (the log says whether any were: `detector: tiling ...`). Absent without one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tile_detector: Option<DetectorIdentity>,
    /// The effective configuration beside it (`config.toml`).
    pub config_file: String,
}

/// The detector's identity: the model file (or the replayed detections file) and its hash.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DetectorIdentity {
    /// `onnx` or `replay`.
    pub kind: String,
    /// File name (no folder).
    pub file: String,
    /// SHA-256 of the file's bytes, lowercase hex.
    pub sha256: String,
    /// Size (bytes).
    pub bytes: u64,
}

/// One line of `frames.ndjson`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum Record {
    /// A frame the tracker took.
    Frame(Box<FrameRecord>),
    /// Recording stopped (disk full, size cap) and resumed: what was lost meanwhile.
    Gap(GapRecord),
    /// The run ended cleanly (absent after a crash or power loss).
    End(EndRecord),
}

/// A frame the tracker took: its times, pose, detections and every track output.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FrameRecord {
    /// The source's frame index.
    pub frame: u64,
    /// The tracker's clock (s): the exposure on the autopilot clock, made monotonic.
    pub time_s: f64,
    /// Exposure time on the autopilot's clock (µs since its boot), once the clocks are
    /// mapped.
    pub autopilot_time_us: Option<u64>,
    /// Exposure time, UTC (µs since the UNIX epoch), when it maps onto the companion clock.
    pub captured_unix_us: Option<u64>,
    /// When the frame had been processed, UTC (µs since the UNIX epoch).
    pub processed_unix_us: u64,
    /// Image width (px).
    pub width_px: u32,
    /// Image height (px).
    pub height_px: u32,
    /// The camera pose used; `None`: tracked in the image only (see `no_pose`).
    pub pose: Option<PoseRecord>,
    /// Why the frame had no pose.
    pub no_pose: Option<String>,
    /// The sea surface's altitude AMSL (m), when known.
    pub water_amsl_m: Option<f64>,
    /// The detections as the tracker got them (with their sea-surface observations).
    pub detections: Vec<Detection>,
    /// Every confirmed track of this frame, with its position on the map.
    pub tracks: Vec<TrackRecord>,
    /// Online ReID merges decided in this frame.
    pub merges: Vec<MergeEvent>,
    /// Contact repairs decided in this frame: two ids had exchanged the objects they follow
    /// since `since_frame_index` (those frames were sent swapped) and follow their own again
    /// from this frame on. Absent in recordings made before it was written.
    #[serde(default)]
    pub exchanges: Vec<ExchangeEvent>,
    /// Frames the camera delivered that inference never took, so far.
    pub frames_dropped: u64,
    /// The keyframe written for this frame (`keyframes/NAME`), if any.
    pub keyframe: Option<String>,
}

#[cfg(test)]
impl FrameRecord {
    /// A frame with nothing in it, for tests to fill in.
    pub(crate) fn empty(frame: u64, width_px: u32, height_px: u32) -> Self {
        Self {
            frame,
            time_s: 0.0,
            autopilot_time_us: None,
            captured_unix_us: None,
            processed_unix_us: 0,
            width_px,
            height_px,
            pose: None,
            no_pose: None,
            water_amsl_m: None,
            detections: Vec::new(),
            tracks: Vec::new(),
            merges: Vec::new(),
            exchanges: Vec::new(),
            frames_dropped: 0,
            keyframe: None,
        }
    }
}

/// The camera pose of a frame: position and optical-frame -> NED attitude, exactly as the
/// tracker's geolocation used it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PoseRecord {
    /// Latitude (deg).
    pub lat_deg: f64,
    /// Longitude (deg).
    pub lon_deg: f64,
    /// Altitude (m), in the datum of the flight's local frame.
    pub alt_m: f64,
    /// Height of the camera above the water (m).
    pub height_above_sea_m: f64,
    /// Camera attitude, optical frame -> local NED, as a quaternion (w, x, y, z).
    pub attitude_wxyz: [f64; 4],
    /// The GNSS receiver's horizontal accuracy at the frame (m, one sigma), when the autopilot
    /// reported it (GPS_RAW_INT `h_acc`); absent in flights recorded before it was kept.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub horizontal_accuracy_m: Option<f64>,
}

impl PoseRecord {
    /// The record of a pose.
    pub fn of(meta: &FrameMetadata) -> Self {
        let q = meta.camera_attitude.quaternion();
        Self {
            lat_deg: meta.position.lat_deg,
            lon_deg: meta.position.lon_deg,
            alt_m: meta.position.alt_m,
            height_above_sea_m: meta.height_above_sea_m,
            attitude_wxyz: [q.w, q.i, q.j, q.k],
            horizontal_accuracy_m: meta.horizontal_accuracy_m,
        }
    }

    /// The pose back, bit for bit.
    pub fn to_meta(&self) -> Result<FrameMetadata, GeoError> {
        let [w, x, y, z] = self.attitude_wxyz;
        Ok(FrameMetadata {
            position: Geodetic::new(self.lat_deg, self.lon_deg, self.alt_m)?,
            height_above_sea_m: self.height_above_sea_m,
            camera_attitude: UnitQuaternion::new_unchecked(Quaternion::new(w, x, y, z)),
            horizontal_accuracy_m: self.horizontal_accuracy_m,
        })
    }
}

/// A track in one frame, and where it is on the map.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TrackRecord {
    /// The tracker's output (id, box, class, state, world state with its covariance).
    pub track: TrackOutput,
    /// Its position on the map, when geolocated.
    pub geo: Option<GeoRecord>,
}

/// A track's position on the map.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GeoRecord {
    /// Latitude (deg).
    pub lat_deg: f64,
    /// Longitude (deg).
    pub lon_deg: f64,
    /// Altitude of the sea surface (m).
    pub alt_m: f64,
    /// Velocity north (m/s).
    pub vel_n_mps: f64,
    /// Velocity east (m/s).
    pub vel_e_mps: f64,
    /// Horizontal standard deviation (m, DRMS).
    pub h_std_m: f64,
}

impl From<GeoFix> for GeoRecord {
    fn from(f: GeoFix) -> Self {
        Self {
            lat_deg: f.position.lat_deg,
            lon_deg: f.position.lon_deg,
            alt_m: f.position.alt_m,
            vel_n_mps: f.vel_n_mps,
            vel_e_mps: f.vel_e_mps,
            h_std_m: f.h_std_m,
        }
    }
}

/// Recording stopped and resumed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GapRecord {
    /// When it stopped (µs since the UNIX epoch).
    pub stopped_unix_us: u64,
    /// When it resumed.
    pub resumed_unix_us: u64,
    /// Why it stopped.
    pub reason: String,
    /// Frame records lost.
    pub frames_lost: u64,
    /// MAVLink packets lost from `flight.tlog`.
    pub packets_lost: u64,
}

/// The run ended cleanly.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EndRecord {
    /// When (µs since the UNIX epoch).
    pub unix_us: u64,
    /// Frame records written.
    pub frames_written: u64,
    /// Frame records dropped because the disk was slower than the frames.
    pub frames_dropped_queue: u64,
    /// MAVLink packets dropped for the same reason.
    pub packets_dropped_queue: u64,
    /// Frame records lost while recording was stopped (disk full, size cap).
    pub frames_lost_stopped: u64,
    /// Keyframes written.
    pub keyframes: u64,
    /// The run's counters (`RunStats`), when the pipeline returned them.
    pub run_stats: Option<serde_json::Value>,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geo::attitude::camera_from_heading_pitch_deg;

    #[test]
    fn a_pose_survives_the_record_bit_for_bit() {
        let meta = FrameMetadata {
            position: Geodetic::new(47.672_956_123_456_78, 9.267_712_345_678_9, 431.123_456_789)
                .unwrap(),
            height_above_sea_m: 29.987_654_321,
            camera_attitude: camera_from_heading_pitch_deg(123.456_789, 61.234_567, 0.1),
            horizontal_accuracy_m: None,
        };
        let line = serde_json::to_string(&PoseRecord::of(&meta)).unwrap();
        // A flight recorded before the accuracy was kept reads back as "not reported".
        assert!(!line.contains("horizontal_accuracy_m"), "{line}");
        let back: PoseRecord = serde_json::from_str(&line).unwrap();
        assert_eq!(back.to_meta().unwrap(), meta);
        let meta = FrameMetadata {
            horizontal_accuracy_m: Some(0.734_567_891_234),
            ..meta
        };
        let line = serde_json::to_string(&PoseRecord::of(&meta)).unwrap();
        let back: PoseRecord = serde_json::from_str(&line).unwrap();
        assert_eq!(back.to_meta().unwrap(), meta);
    }
}
