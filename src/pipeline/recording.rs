//! The pipeline's side of the flight record: starting the [`Recorder`] (its flight folder,
//! `flight.json` with the detector's identity, `config.toml`), the link's packet tap for
//! `flight.tlog`, and [`FrameRecording`], which turns each tracked frame into a
//! [`FrameRecord`] and decides when a keyframe is due.

use super::telemetry::FramePose;
use crate::camera::Frame;
use crate::config::{DetectorSettings, RecordingSettings, Settings};
use crate::frame::GeoFix;
use crate::health::{Level, Notice};
use crate::mavlink::{Outputs, PacketTap};
use crate::record::format::{
    DetectorIdentity, FlightInfo, FrameRecord, GeoRecord, PoseRecord, TrackRecord, FORMAT, VERSION,
};
use crate::record::{flight, unix_us_now, KeyframeImage, RecordSink, Recorder};
use crate::telemetry::CompanionTimeUs;
use crate::track::{FrameInput, FrameOutput, TrackOutput};
use std::collections::HashSet;
use std::path::Path;
use std::sync::{Arc, OnceLock};

/// Starts the recorder of this run, or logs why not and returns the notice for the operator
/// (the run goes on without a record; the link is not up yet, so the caller sends it once the
/// link has its peer). `outputs` is filled once the link is up; the recorder's announcements
/// wait for it.
pub(super) fn start(
    settings: &Settings,
    rec: &RecordingSettings,
    config_toml: &str,
    outputs: Arc<OnceLock<Outputs>>,
) -> Result<Recorder, Notice> {
    let started_unix_us = unix_us_now();
    let started_utc =
        chrono::DateTime::from_timestamp_micros(i64::try_from(started_unix_us).unwrap_or(i64::MAX))
            .map(|t| t.to_rfc3339_opts(chrono::SecondsFormat::Micros, true))
            .unwrap_or_default();
    let info = FlightInfo {
        format: FORMAT.to_owned(),
        version: VERSION,
        mgmot_version: env!("CARGO_PKG_VERSION").to_owned(),
        started_utc,
        started_unix_us,
        system_id: settings.mavlink.system_id,
        component_id: settings.mavlink.component_id,
        detector: detector_identity(&settings.detector),
        tile_detector: tile_detector_identity(&settings.detector),
        config_file: flight::CONFIG.to_owned(),
    };
    let announce_to = outputs.clone();
    let announce = Box::new(move |n: Notice| {
        if let Some(o) = announce_to.get() {
            o.notice(&n);
        }
    });
    match Recorder::start(rec, &info, config_toml, announce) {
        Ok(r) => {
            tracing::info!(dir = %r.dir().display(), "recording this flight");
            Ok(r)
        }
        Err(e) => {
            tracing::error!(error = %e, "cannot record this flight; tracking without a record");
            let why = match &e {
                crate::record::RecordError::Io { source, .. }
                    if source.kind() == std::io::ErrorKind::PermissionDenied
                        || source.raw_os_error() == Some(libc::EROFS) =>
                {
                    "read-only"
                }
                crate::record::RecordError::Io { source, .. }
                    if source.raw_os_error() == Some(libc::ENOSPC) =>
                {
                    "disk full"
                }
                _ => "cannot write",
            };
            Err(Notice::new(
                Level::Warning,
                format!("mgmot: recording off: {why}"),
            ))
        }
    }
}

/// The model's (or the replayed detections') file name and SHA-256.
fn detector_identity(d: &DetectorSettings) -> DetectorIdentity {
    let (kind, path): (&str, &Path) = match d {
        DetectorSettings::Onnx(o) => ("onnx", &o.detector.model_path),
        DetectorSettings::Replay { detections, .. } => ("replay", detections),
    };
    file_identity(kind, path)
}

/// The tile model's file name and SHA-256, when tiling is on with one.
fn tile_detector_identity(d: &DetectorSettings) -> Option<DetectorIdentity> {
    let DetectorSettings::Onnx(o) = d else {
        return None;
    };
    let path = o.detector.tile_model.as_ref()?;
    o.detector.tiling.map(|_| file_identity("onnx", path))
}

/// A detector file's identity: `kind`, its name, SHA-256 and size.
fn file_identity(kind: &str, path: &Path) -> DetectorIdentity {
    let (sha256, bytes) = flight::sha256_of(path).unwrap_or_else(|e| {
        tracing::warn!(path = %path.display(), error = %e, "detector file not hashed");
        (String::new(), 0)
    });
    DetectorIdentity {
        kind: kind.to_owned(),
        file: path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default(),
        sha256,
        bytes,
    }
}

/// The link's tap: every packet in and out into `flight.tlog`.
pub(super) fn packet_tap(sink: RecordSink) -> PacketTap {
    PacketTap(Arc::new(move |bytes: &[u8]| sink.packet(bytes)))
}

/// Turns each tracked frame into a record; decides keyframes.
pub(super) struct FrameRecording {
    sink: RecordSink,
    keyframe_every_us: Option<u64>,
    last_keyframe_us: Option<u64>,
    /// Track ids seen so far: a new one asks for a keyframe (the next frame's).
    seen: HashSet<u64>,
    new_track: bool,
    /// UNIX time minus companion (monotonic) time, µs, at the start.
    unix_minus_companion_us: i64,
}

impl FrameRecording {
    /// Records into `sink`, with keyframes every `keyframe_every` (if any) and at new tracks.
    pub fn new(sink: RecordSink, rec: &RecordingSettings) -> Self {
        let unix = i64::try_from(unix_us_now()).unwrap_or(i64::MAX);
        let companion = i64::try_from(crate::clock::now().0).unwrap_or(0);
        Self {
            sink,
            keyframe_every_us: rec
                .keyframe_every
                .map(|d| u64::try_from(d.as_micros()).unwrap_or(u64::MAX)),
            last_keyframe_us: None,
            seen: HashSet::new(),
            new_track: false,
            unix_minus_companion_us: unix - companion,
        }
    }

    /// The frame's pixels when a keyframe is due (copied before the detector takes them).
    pub fn keyframe(&mut self, frame: &Frame) -> Option<KeyframeImage> {
        let every = self.keyframe_every_us?;
        let now = crate::clock::now().0;
        let due = self.new_track
            || self
                .last_keyframe_us
                .is_none_or(|t| now.saturating_sub(t) >= every);
        if !due {
            return None;
        }
        self.new_track = false;
        self.last_keyframe_us = Some(now);
        Some(KeyframeImage {
            width_px: frame.width_px,
            height_px: frame.height_px,
            rgb: frame.rgb.clone(),
        })
    }

    /// Queues the record of a frame the tracker took.
    pub fn record(
        &mut self,
        input: &FrameInput,
        output: &FrameOutput,
        pose: &FramePose,
        fix: &dyn Fn(&TrackOutput) -> Option<GeoFix>,
        frames_dropped: u64,
        keyframe: Option<KeyframeImage>,
    ) {
        for t in &output.tracks {
            if self.seen.insert(t.id) && self.keyframe_every_us.is_some() {
                self.new_track = true;
            }
        }
        let to_unix = |c: CompanionTimeUs| {
            u64::try_from(i64::try_from(c.0).unwrap_or(0) + self.unix_minus_companion_us).ok()
        };
        let record = FrameRecord {
            frame: input.frame_index,
            time_s: input.time_s,
            autopilot_time_us: pose.frame_time.map(|t| t.0),
            captured_unix_us: pose.captured_at.and_then(to_unix),
            processed_unix_us: unix_us_now(),
            width_px: input.image_size_px.0,
            height_px: input.image_size_px.1,
            pose: pose.meta.as_ref().ok().map(PoseRecord::of),
            no_pose: pose.meta.as_ref().err().cloned(),
            water_amsl_m: pose.water_amsl_m,
            detections: input.detections.clone(),
            tracks: output
                .tracks
                .iter()
                .map(|t| TrackRecord {
                    track: *t,
                    geo: fix(t).map(GeoRecord::from),
                })
                .collect(),
            merges: output.merges.clone(),
            exchanges: output.exchanges.clone(),
            frames_dropped,
            keyframe: None,
        };
        self.sink.frame(record, keyframe);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::OnnxSettings;
    use crate::detect::{DetectorConfig, TilingConfig};

    fn repo(file: &str) -> std::path::PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join(file)
    }

    /// `flight.json` names the tile model beside the model, by hash, only when tiling is on
    /// with one.
    #[test]
    fn the_flight_names_its_tile_model() {
        let mut d = DetectorConfig::new(repo("models/mgmot-det-int8.onnx"));
        d.tile_model = Some(repo("models/mgmot-det-tiles-int8.onnx"));
        let without_tiling = DetectorSettings::Onnx(OnnxSettings::fixed(d.clone()));
        assert_eq!(tile_detector_identity(&without_tiling), None);
        d.tiling = Some(TilingConfig::default());
        let tiled = DetectorSettings::Onnx(OnnxSettings::fixed(d.clone()));
        let tiles = tile_detector_identity(&tiled).unwrap();
        let main = detector_identity(&tiled);
        assert_eq!(
            (tiles.kind.as_str(), tiles.file.as_str()),
            ("onnx", "mgmot-det-tiles-int8.onnx")
        );
        assert_eq!(tiles.sha256.len(), 64);
        assert_ne!(tiles.sha256, main.sha256);
        d.tile_model = None;
        let no_tile_model = DetectorSettings::Onnx(OnnxSettings::fixed(d));
        assert_eq!(tile_detector_identity(&no_tile_model), None);
    }
}
