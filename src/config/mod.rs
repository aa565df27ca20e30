//! The runtime configuration: one TOML file (`systemd/mgmot.example.toml` documents every key).
//!
//! Loading is two steps: TOML parsing with unknown keys rejected (the parser's error names the
//! line and the key), then [`Config::validate`], whose errors name the dotted key and the
//! problem.

use crate::detect::BackendKind;
use crate::geo::PoseNoise;
use crate::track::TrackerParams;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Default limit on the camera-to-sea distance (m), the geolocator's own default: beyond about
/// 10 km the flat-sea model and realistic attitude accuracy give no usable position.
pub const DEFAULT_MAX_RANGE_M: f64 = 10_000.0;

/// Why a configuration cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    /// The file cannot be read.
    #[error("{path}: {source}")]
    Read {
        /// The file.
        path: PathBuf,
        /// The IO error.
        source: std::io::Error,
    },
    /// Not valid TOML, an unknown key, or a value of the wrong type.
    #[error("{path}: {message}")]
    Parse {
        /// The file.
        path: PathBuf,
        /// The parser's message (with line, column and key).
        message: String,
    },
    /// Values that parse but cannot work.
    #[error("{path}: {}", .problems.iter().map(ToString::to_string).collect::<Vec<_>>().join("; "))]
    Invalid {
        /// The file.
        path: PathBuf,
        /// Every problem found.
        problems: Vec<Problem>,
    },
}

/// One invalid value.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("`{key}`: {problem}")]
pub struct Problem {
    /// Dotted key, e.g. `mavlink.connection`.
    pub key: String,
    /// What is wrong with it.
    pub problem: String,
}

/// The whole configuration.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Config {
    /// The MAVLink link to the autopilot (or mavlink-router).
    pub mavlink: MavlinkConfig,
    /// How telemetry is turned into a camera pose per frame.
    #[serde(default)]
    pub telemetry: TelemetryConfig,
    /// Where frames come from.
    pub frames: FramesConfig,
    /// The camera's optics.
    #[serde(default)]
    pub camera: CameraConfig,
    /// What finds objects in frames.
    pub detector: DetectorConfig,
    /// Geolocation noise model and limits.
    #[serde(default)]
    pub geolocation: GeolocationConfig,
    /// What is sent, and how often.
    #[serde(default)]
    pub outputs: OutputsConfig,
    /// Tracker parameters (the paper's values by default).
    #[serde(default)]
    pub tracker: TrackerParams,
}

/// The MAVLink link.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MavlinkConfig {
    /// `serial:/dev/ttyS0:921600`, `udpin:0.0.0.0:14550`, `udpout:HOST:PORT`, `tcpin:…`,
    /// `tcpout:…`.
    pub connection: String,
    /// Our system id: the vehicle's, since mgmot is one of its components.
    #[serde(default = "one")]
    pub system_id: u8,
    /// Our component id (191 = MAV_COMP_ID_ONBOARD_COMPUTER).
    #[serde(default = "onboard_computer")]
    pub component_id: u8,
    /// The autopilot's component id (1 = MAV_COMP_ID_AUTOPILOT1), target of the stream
    /// requests.
    #[serde(default = "one")]
    pub autopilot_component_id: u8,
    /// Rate asked for position, attitude and gimbal messages (Hz); 0 leaves the autopilot's
    /// own stream rates alone.
    #[serde(default = "default_stream_rate_hz")]
    pub stream_rate_hz: f32,
    /// TIMESYNC requests per second (0 = never; the arrival-time estimate is used instead).
    #[serde(default = "one_f64")]
    pub timesync_hz: f64,
    /// MAVLink 2 signing; absent = no signing.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub signing: Option<SigningConfig>,
    /// `udpin` only: the one peer (`IP:PORT`, the autopilot or router) mgmot answers. Absent:
    /// the first peer that sends a valid frame from the vehicle's system (signed, with signing
    /// on); another peer takes over only after that one has been silent for 5 s.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub udp_peer: Option<std::net::SocketAddr>,
}

/// MAVLink 2 signing.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SigningConfig {
    /// The 32-byte secret key as 64 hex digits (the same key as the autopilot and GCS).
    pub key_hex: String,
    /// Link id put in our signatures.
    #[serde(default)]
    pub link_id: u8,
    /// Where the signing timestamps are kept across restarts, so that a signed command
    /// captured before a restart cannot be replayed after it (the signing spec's advice). The
    /// file is written at start-up, every second and at exit; its directory must be writable.
    #[serde(default = "default_signing_state_file")]
    pub state_file: PathBuf,
    /// Use unsigned position, attitude, home, clock and gimbal messages from the autopilot
    /// (an autopilot or router that does not sign). Set false when the autopilot signs its
    /// link (ArduPilot with signing on signs everything): unsigned telemetry is then refused
    /// too. Commands must be signed either way.
    #[serde(default = "yes")]
    pub accept_unsigned_telemetry: bool,
}

fn default_signing_state_file() -> PathBuf {
    PathBuf::from("/var/lib/mgmot/signing-state.json")
}

fn yes() -> bool {
    true
}

impl SigningConfig {
    /// The key bytes, if `key_hex` is 64 hex digits.
    pub fn key(&self) -> Option<[u8; 32]> {
        let s = self.key_hex.trim();
        if s.len() != 64 || !s.is_ascii() {
            return None;
        }
        let mut key = [0u8; 32];
        for (i, b) in key.iter_mut().enumerate() {
            *b = u8::from_str_radix(&s[2 * i..2 * i + 2], 16).ok()?;
        }
        Some(key)
    }
}

/// Telemetry -> camera pose.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TelemetryConfig {
    /// A frame whose nearest sample of any needed stream is further than this from its
    /// capture time gets no pose (no geolocation) rather than a stale one (ms).
    pub max_pose_age_ms: f64,
    /// Delay from the real exposure to the frame's timestamp (ms); the pose is taken at
    /// `timestamp - camera_latency_ms`.
    pub camera_latency_ms: f64,
    /// Water surface altitude AMSL (m); absent: the home position is at the waterline.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub water_level_amsl_m: Option<f64>,
    /// Telemetry is reported lost (STATUSTEXT) when no position arrives for this long (ms).
    pub lost_after_ms: f64,
    /// Camera hard-mounted to the body instead of on a gimbal: its pitch (deg, negative =
    /// down) relative to the body; absent: the gimbal's telemetry is used.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fixed_mount_pitch_deg: Option<f64>,
}

impl Default for TelemetryConfig {
    fn default() -> Self {
        Self {
            max_pose_age_ms: 200.0,
            camera_latency_ms: 0.0,
            water_level_amsl_m: None,
            lost_after_ms: 2000.0,
            fixed_mount_pitch_deg: None,
        }
    }
}

/// Frame sources.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "source", rename_all = "lowercase", deny_unknown_fields)]
pub enum FramesConfig {
    /// A V4L2 capture device.
    V4l2 {
        /// Device node, e.g. `/dev/video0`.
        device: PathBuf,
        /// `MJPG`, `YUYV` or `NV12`.
        pixel_format: String,
        /// Capture width (px).
        width_px: u32,
        /// Capture height (px).
        height_px: u32,
        /// Frames per second asked of the device.
        fps: u32,
        /// Kernel buffers in the mmap ring (2..=32): more absorb jitter, fewer keep latency
        /// and memory low.
        #[serde(default = "default_v4l2_buffers")]
        buffers: u32,
        /// No frame for this long (ms, 1..=60000) means the camera is lost: close it and
        /// reconnect.
        #[serde(default = "default_frame_timeout_ms")]
        frame_timeout_ms: u64,
        /// First reconnect delay after the camera is lost (ms); doubles per failed attempt.
        #[serde(default = "default_reconnect_initial_ms")]
        reconnect_initial_ms: u64,
        /// Cap of the reconnect delay (ms).
        #[serde(default = "default_reconnect_max_ms")]
        reconnect_max_ms: u64,
    },
    /// The simulator's Unix-socket frame stream (`mgmot-sim run --frames unix:PATH`).
    Sim {
        /// The socket path.
        socket: PathBuf,
        /// A read that waits longer than this for the next frame means the simulator froze:
        /// camera lost, reconnect (ms).
        #[serde(default = "default_sim_frame_timeout_ms")]
        frame_timeout_ms: u64,
        /// First reconnect delay when the socket is absent or the stream breaks (ms).
        #[serde(default = "default_reconnect_initial_ms")]
        reconnect_initial_ms: u64,
        /// Cap of the reconnect delay (ms).
        #[serde(default = "default_reconnect_max_ms")]
        reconnect_max_ms: u64,
        /// Bench runs only: hold each frame until the detector took the previous one (at most
        /// 1 s), instead of replacing it, so that with `mgmot-sim run --lockstep` every frame
        /// is processed whatever the machine's speed. Never in the air, where a stale frame
        /// is worth nothing.
        #[serde(default)]
        wait_for_detector: bool,
    },
    /// Image files (`.jpg`, `.jpeg`, `.png`) of a directory, in name order.
    Images {
        /// The directory.
        directory: PathBuf,
        /// Frame rate used to time the images (frame k is shown k / fps after the first).
        fps: f64,
        /// Start again after the last image instead of ending the run.
        #[serde(rename = "loop", default)]
        looping: bool,
    },
}

fn default_v4l2_buffers() -> u32 {
    4
}

fn default_frame_timeout_ms() -> u64 {
    2000
}

fn default_sim_frame_timeout_ms() -> u64 {
    5000
}

fn default_reconnect_initial_ms() -> u64 {
    1000
}

fn default_reconnect_max_ms() -> u64 {
    5000
}

/// The camera's optics.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CameraConfig {
    /// Horizontal field of view (deg), for an ideal pinhole with the principal point at the
    /// centre.
    pub hfov_deg: f64,
}

impl Default for CameraConfig {
    fn default() -> Self {
        Self { hfov_deg: 70.0 }
    }
}

/// Detectors.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum DetectorConfig {
    /// The ONNX detector (`mgmot::detect`) on every frame: what flies.
    Onnx(OnnxDetectorConfig),
    /// Replays detections from a COCO results file keyed by frame (the simulator's
    /// `mgmot-sim detections` output), not looking at the pixels: for bench runs that
    /// measure the rest of the pipeline, or feed the tracker the simulator's detector model.
    Replay {
        /// COCO results JSON (`[{image_id, category_id, bbox, score}]`).
        detections: PathBuf,
        /// The image id of frame index 0 (ids count up by frame index).
        #[serde(default = "one_u64")]
        first_image_id: u64,
    },
}

/// The ONNX detector's settings (`[detector]` with `kind = "onnx"`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OnnxDetectorConfig {
    /// The model file: `models/mgmot-det-int8.onnx` (fastest on onnxruntime),
    /// `models/mgmot-det-fp32.onnx` (fastest on tract), or a YOLOv8 / YOLO11 export.
    pub model: PathBuf,
    /// Inference engine: `tract` (pure Rust, nothing to install) or `onnxruntime`.
    #[serde(default = "default_backend")]
    pub backend: BackendKind,
    /// `libonnxruntime.so` for the onnxruntime backend; absent: `$ORT_DYLIB_PATH`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ort_library: Option<PathBuf>,
    /// Intra-op threads of the model run (onnxruntime; tract runs on one).
    #[serde(default = "default_detector_threads")]
    pub threads: usize,
    /// Candidates scoring below this are dropped.
    #[serde(default = "default_score_threshold")]
    pub score_threshold: f32,
    /// IoU above which the class-aware NMS drops the lower-scoring box.
    #[serde(default = "default_nms_iou")]
    pub nms_iou: f32,
    /// IoU above which the paper's larger-box-priority suppression drops the smaller box
    /// (class-agnostic); 1 turns it off.
    #[serde(default = "default_larger_box_iou")]
    pub larger_box_iou: f32,
    /// At most this many detections per frame.
    #[serde(default = "default_max_detections")]
    pub max_detections: usize,
    /// Class names overriding the model's metadata, in the model's class order (class
    /// index `i` becomes track class id `i + 1`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub class_names: Option<Vec<String>>,
    /// Run the model on overlapping tiles at native resolution (plus the whole frame, for
    /// objects larger than a tile), merged by NMS: for frames much larger than the model's
    /// input (a 4K frame letterboxed into the shipped 800x448 input shrinks a 20 px swimmer to
    /// 4 px). Costs one model run per tile (1280x720 in 800x448 tiles: 4 tiles + 1).
    #[serde(default)]
    pub tile: bool,
    /// Side of square tiles (px of the frame); absent: tiles of the model's input size (native
    /// resolution, no letterbox padding).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tile_size_px: Option<u32>,
    /// Overlap between neighbouring tiles (px); at least the largest object to keep whole.
    #[serde(default = "default_tile_overlap_px")]
    pub tile_overlap_px: u32,
}

fn default_tile_overlap_px() -> u32 {
    64
}

impl OnnxDetectorConfig {
    /// The settings of `mgmot::detect`.
    pub fn settings(&self) -> crate::detect::DetectorConfig {
        let mut c = crate::detect::DetectorConfig::new(&self.model);
        c.backend = crate::detect::BackendConfig {
            kind: self.backend,
            ort_dylib_path: self.ort_library.clone(),
        };
        c.threads = self.threads;
        c.score_threshold = self.score_threshold;
        c.nms_iou = self.nms_iou;
        c.larger_box_iou = (self.larger_box_iou < 1.0).then_some(self.larger_box_iou);
        c.max_detections = self.max_detections;
        c.class_names = self.class_names.clone();
        c.tiling = self.tile.then_some(crate::detect::TilingConfig {
            tile_px: self.tile_size_px,
            overlap_px: self.tile_overlap_px,
            include_full_frame: true,
        });
        c
    }
}

/// Geolocation.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct GeolocationConfig {
    /// Noise of the pose and the boxes, for the position uncertainty.
    pub noise: PoseNoise,
    /// Points further than this from the camera are not geolocated (m).
    pub max_range_m: f64,
}

impl Default for GeolocationConfig {
    fn default() -> Self {
        Self {
            noise: PoseNoise::default(),
            max_range_m: DEFAULT_MAX_RANGE_M,
        }
    }
}

/// Outputs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct OutputsConfig {
    /// MGMOT_TRACK messages per confirmed track per second.
    pub track_rate_hz: f64,
    /// Also send TARGET_ABSOLUTE for each geolocated track.
    pub target_absolute: bool,
    /// HEARTBEATs per second.
    pub heartbeat_hz: f64,
    /// CAMERA_TRACKING_IMAGE_STATUS + CAMERA_TRACKING_GEO_STATUS per second while an operator
    /// has selected a track (MAV_CMD_CAMERA_TRACK_POINT / _RECTANGLE).
    pub camera_tracking_hz: f64,
    /// How far from a track's box a MAV_CMD_CAMERA_TRACK_POINT may land and still select it,
    /// as a fraction of the image width, when the command's own radius (param 3) is 0.
    pub track_point_radius: f64,
}

impl Default for OutputsConfig {
    fn default() -> Self {
        Self {
            track_rate_hz: 2.0,
            target_absolute: true,
            heartbeat_hz: 1.0,
            camera_tracking_hz: 5.0,
            track_point_radius: crate::operator::DEFAULT_POINT_RADIUS,
        }
    }
}

fn one() -> u8 {
    1
}
fn one_u64() -> u64 {
    1
}
fn one_f64() -> f64 {
    1.0
}
fn onboard_computer() -> u8 {
    crate::mavlink::COMPONENT_ID
}
fn default_stream_rate_hz() -> f32 {
    50.0
}
fn default_backend() -> BackendKind {
    BackendKind::Tract
}
fn default_detector_threads() -> usize {
    2
}
fn default_score_threshold() -> f32 {
    0.25
}
fn default_nms_iou() -> f32 {
    crate::detect::DEFAULT_NMS_IOU
}
fn default_larger_box_iou() -> f32 {
    0.7
}
fn default_max_detections() -> usize {
    300
}

impl Config {
    /// Reads, parses and validates a file.
    pub fn load(path: &Path) -> Result<Config, ConfigError> {
        let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Read {
            path: path.to_owned(),
            source,
        })?;
        let config = Config::parse(&text).map_err(|message| ConfigError::Parse {
            path: path.to_owned(),
            message,
        })?;
        config.validate().map_err(|problems| ConfigError::Invalid {
            path: path.to_owned(),
            problems,
        })?;
        Ok(config)
    }

    /// Parses TOML text (no validation).
    pub fn parse(text: &str) -> Result<Config, String> {
        toml::from_str(text).map_err(|e| e.to_string())
    }

    /// Every problem with the values, each naming its key.
    pub fn validate(&self) -> Result<(), Vec<Problem>> {
        let mut problems = Vec::new();
        let mut bad = |key: &str, problem: String| {
            problems.push(Problem {
                key: key.to_owned(),
                problem,
            })
        };
        let positive = |v: f64| v.is_finite() && v > 0.0;
        // Every rate, duration and noise figure also has an upper bound: beyond it a value is
        // a typo (1e300 Hz, a 30-year timeout) that would overflow a timer or a covariance.
        let within = |bad: &mut dyn FnMut(&str, String),
                      key: &str,
                      v: f64,
                      lo: f64,
                      hi: f64,
                      lo_open: bool| {
            let above_lo = if lo_open { v > lo } else { v >= lo };
            if !(v.is_finite() && above_lo && v <= hi) {
                let open = if lo_open { "(" } else { "[" };
                bad(
                    key,
                    format!("must be a number in {open}{lo}, {hi}], got {v}"),
                );
            }
        };

        if let Err(e) = crate::mavlink::parse_connection(&self.mavlink.connection) {
            bad("mavlink.connection", e.to_string());
        }
        if self.mavlink.system_id == 0 {
            bad("mavlink.system_id", "must be 1..=255".into());
        }
        if self.mavlink.component_id == 0 {
            bad("mavlink.component_id", "must be 1..=255".into());
        }
        within(
            &mut bad,
            "mavlink.stream_rate_hz",
            f64::from(self.mavlink.stream_rate_hz),
            0.0,
            400.0,
            false,
        );
        within(
            &mut bad,
            "mavlink.timesync_hz",
            self.mavlink.timesync_hz,
            0.0,
            50.0,
            false,
        );
        if let Some(s) = &self.mavlink.signing {
            if s.key().is_none() {
                bad(
                    "mavlink.signing.key_hex",
                    format!(
                        "must be 64 hex digits (32 bytes), got {} characters",
                        s.key_hex.trim().len()
                    ),
                );
            }
        }
        let t = &self.telemetry;
        within(
            &mut bad,
            "telemetry.max_pose_age_ms",
            t.max_pose_age_ms,
            0.0,
            60_000.0,
            true,
        );
        within(
            &mut bad,
            "telemetry.camera_latency_ms",
            t.camera_latency_ms,
            0.0,
            10_000.0,
            false,
        );
        within(
            &mut bad,
            "telemetry.lost_after_ms",
            t.lost_after_ms,
            0.0,
            3_600_000.0,
            true,
        );
        if let Some(v) = t.water_level_amsl_m {
            // The Dead Sea shore to far above any sea.
            within(
                &mut bad,
                "telemetry.water_level_amsl_m",
                v,
                -500.0,
                9000.0,
                false,
            );
        }
        if t.fixed_mount_pitch_deg
            .is_some_and(|v| !(v.is_finite() && (-90.0..=90.0).contains(&v)))
        {
            bad(
                "telemetry.fixed_mount_pitch_deg",
                "must be in -90..=90".into(),
            );
        }
        let reconnect = |bad: &mut dyn FnMut(&str, String), initial_ms: u64, max_ms: u64| {
            if initial_ms == 0 {
                bad("frames.reconnect_initial_ms", "must be > 0".into());
            }
            if max_ms < initial_ms {
                bad(
                    "frames.reconnect_max_ms",
                    format!("must be >= reconnect_initial_ms ({initial_ms})"),
                );
            }
        };
        match &self.frames {
            FramesConfig::V4l2 {
                pixel_format,
                width_px,
                height_px,
                fps,
                buffers,
                frame_timeout_ms,
                reconnect_initial_ms,
                reconnect_max_ms,
                ..
            } => {
                if let Err(e) = pixel_format.parse::<crate::camera::PixelFormat>() {
                    bad("frames.pixel_format", e);
                }
                if *width_px == 0 || *height_px == 0 {
                    bad("frames.width_px", "width and height must be > 0".into());
                }
                if *fps == 0 {
                    bad("frames.fps", "must be > 0".into());
                }
                if !(2..=32).contains(buffers) {
                    bad("frames.buffers", "must be within 2..=32".into());
                }
                if !(1..=60_000).contains(frame_timeout_ms) {
                    bad("frames.frame_timeout_ms", "must be within 1..=60000".into());
                }
                reconnect(&mut bad, *reconnect_initial_ms, *reconnect_max_ms);
            }
            FramesConfig::Sim {
                frame_timeout_ms,
                reconnect_initial_ms,
                reconnect_max_ms,
                ..
            } => {
                if !(1..=60_000).contains(frame_timeout_ms) {
                    bad("frames.frame_timeout_ms", "must be within 1..=60000".into());
                }
                reconnect(&mut bad, *reconnect_initial_ms, *reconnect_max_ms)
            }
            FramesConfig::Images { fps, .. } => {
                if !(positive(*fps) && *fps <= 1000.0) {
                    bad("frames.fps", "must be within (0, 1000]".into());
                }
            }
        }
        if let DetectorConfig::Onnx(OnnxDetectorConfig {
            model,
            threads,
            score_threshold,
            nms_iou,
            larger_box_iou,
            max_detections,
            class_names,
            tile_size_px,
            tile_overlap_px,
            ..
        }) = &self.detector
        {
            if let Some(t) = tile_size_px {
                if *t < 32 {
                    bad("detector.tile_size_px", format!("must be >= 32, got {t}"));
                } else if tile_overlap_px >= t {
                    bad(
                        "detector.tile_overlap_px",
                        format!("must be smaller than tile_size_px ({t}), got {tile_overlap_px}"),
                    );
                }
            }
            if model.as_os_str().is_empty() {
                bad("detector.model", "must name the ONNX model file".into());
            }
            if *threads == 0 {
                bad("detector.threads", "must be >= 1".into());
            }
            for (key, v) in [
                ("detector.score_threshold", *score_threshold),
                ("detector.nms_iou", *nms_iou),
            ] {
                if !(0.0..=1.0).contains(&v) {
                    bad(key, format!("must be in [0, 1], got {v}"));
                }
            }
            if !(*larger_box_iou > 0.0 && *larger_box_iou <= 1.0) {
                bad(
                    "detector.larger_box_iou",
                    format!("must be in (0, 1] (1 turns it off), got {larger_box_iou}"),
                );
            }
            if *max_detections == 0 {
                bad("detector.max_detections", "must be >= 1".into());
            }
            if let Some(names) = class_names {
                if names.is_empty() || names.iter().any(|n| n.trim().is_empty()) {
                    bad(
                        "detector.class_names",
                        "must list one non-empty name per model class".into(),
                    );
                }
            }
        }
        if !(self.camera.hfov_deg.is_finite()
            && self.camera.hfov_deg > 0.0
            && self.camera.hfov_deg < 180.0)
        {
            bad("camera.hfov_deg", "must be in (0, 180)".into());
        }
        within(
            &mut bad,
            "geolocation.max_range_m",
            self.geolocation.max_range_m,
            0.0,
            100_000.0,
            true,
        );
        let n = &self.geolocation.noise;
        for (key, v) in [
            ("geolocation.noise.attitude_std_deg", n.attitude_std_deg),
            ("geolocation.noise.altitude_std_m", n.altitude_std_m),
            ("geolocation.noise.pixel_std_px", n.pixel_std_px),
            (
                "geolocation.noise.horizontal_position_std_m",
                n.horizontal_position_std_m,
            ),
        ] {
            let hi = if key.ends_with("attitude_std_deg") {
                90.0
            } else {
                1000.0
            };
            within(&mut bad, key, v, 0.0, hi, false);
        }
        within(
            &mut bad,
            "outputs.track_rate_hz",
            self.outputs.track_rate_hz,
            0.0,
            100.0,
            true,
        );
        // MAVLink components send HEARTBEAT at about 1 Hz; a GCS counts one silent for 3-5 s
        // as gone.
        within(
            &mut bad,
            "outputs.heartbeat_hz",
            self.outputs.heartbeat_hz,
            0.2,
            10.0,
            false,
        );
        within(
            &mut bad,
            "outputs.camera_tracking_hz",
            self.outputs.camera_tracking_hz,
            0.0,
            100.0,
            true,
        );
        if !(self.outputs.track_point_radius.is_finite()
            && (0.0..=1.0).contains(&self.outputs.track_point_radius))
        {
            bad(
                "outputs.track_point_radius",
                "must be in 0..=1 (a fraction of the image width)".into(),
            );
        }
        if let Err(e) = self.tracker.validate() {
            bad("tracker", e.to_string());
        }
        if problems.is_empty() {
            Ok(())
        } else {
            Err(problems)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const EXAMPLE: &str = include_str!("../../systemd/mgmot.example.toml");

    const MINIMAL: &str = r#"
[mavlink]
connection = "udpin:0.0.0.0:14550"
[frames]
source = "sim"
socket = "/tmp/mgmot-sim.sock"
[detector]
kind = "replay"
detections = "dets.json"
"#;

    const ONNX: &str = r#"
[mavlink]
connection = "udpin:0.0.0.0:14550"
[frames]
source = "sim"
socket = "/tmp/mgmot-sim.sock"
[detector]
kind = "onnx"
model = "models/mgmot-det-int8.onnx"
ort_library = "/opt/onnxruntime/libonnxruntime.so"
class_names = ["swimmer", "boat"]
"#;

    #[test]
    fn example_is_valid() {
        let c = Config::parse(EXAMPLE).unwrap();
        c.validate().unwrap();
    }

    /// Every key the configuration has (defaults included) is written in the example, so the
    /// example documents all of them.
    #[test]
    fn example_documents_every_key() {
        example_documents_every_key_of(MINIMAL);
        example_documents_every_key_of(ONNX);
    }

    fn example_documents_every_key_of(config: &str) {
        let mut c = Config::parse(config).unwrap();
        c.mavlink.signing = Some(SigningConfig {
            key_hex: "00".repeat(32),
            link_id: 0,
            state_file: default_signing_state_file(),
            accept_unsigned_telemetry: true,
        });
        c.mavlink.udp_peer = Some(([127, 0, 0, 1], 14555).into());
        c.telemetry.water_level_amsl_m = Some(0.0);
        c.telemetry.fixed_mount_pitch_deg = Some(0.0);
        // Through text: the tracker's per-class table has integer keys, which toml::Value lacks.
        let value: toml::Value = toml::from_str(&toml::to_string(&c).unwrap()).unwrap();
        let mut missing = Vec::new();
        fn walk(v: &toml::Value, prefix: &str, example: &str, missing: &mut Vec<String>) {
            if let toml::Value::Table(t) = v {
                for (k, v) in t {
                    let key = if prefix.is_empty() {
                        k.clone()
                    } else {
                        format!("{prefix}.{k}")
                    };
                    let as_key = format!("{k} =");
                    let as_table = format!("[{key}]");
                    let as_parent = format!("[{key}.");
                    if !example.contains(&as_key)
                        && !example.contains(&as_table)
                        && !example.contains(&as_parent)
                    {
                        missing.push(key.clone());
                    }
                    walk(v, &key, example, missing);
                }
            }
        }
        walk(&value, "", EXAMPLE, &mut missing);
        assert!(
            missing.is_empty(),
            "keys not in the example config: {missing:?}"
        );
    }

    #[test]
    fn minimal_takes_defaults() {
        let c = Config::parse(MINIMAL).unwrap();
        c.validate().unwrap();
        assert_eq!(c.mavlink.component_id, 191);
        assert_eq!(c.telemetry.max_pose_age_ms, 200.0);
    }

    #[test]
    fn unknown_key_is_named_with_its_line() {
        let text = MINIMAL.replace("[mavlink]", "[mavlink]\nconection = \"x\"");
        let e = Config::parse(&text).unwrap_err();
        assert!(e.contains("conection"), "{e}");
        assert!(e.contains("line 3") || e.contains("3 |"), "{e}");
    }

    #[test]
    fn invalid_values_name_their_keys() {
        let text = MINIMAL
            .replace("udpin:0.0.0.0:14550", "udp:nowhere")
            .replace(
                "[frames]",
                "[outputs]\ntrack_rate_hz = 0\ncamera_tracking_hz = -1\ntrack_point_radius = 2\n\
                 [mavlink.signing]\nkey_hex = \"abc\"\n[frames]",
            );
        let c = Config::parse(&text).unwrap();
        let keys: Vec<String> = c
            .validate()
            .unwrap_err()
            .into_iter()
            .map(|p| p.key)
            .collect();
        assert_eq!(
            keys,
            [
                "mavlink.connection",
                "mavlink.signing.key_hex",
                "outputs.track_rate_hz",
                "outputs.camera_tracking_hz",
                "outputs.track_point_radius"
            ]
        );
    }

    #[test]
    fn frame_sources_parse_with_defaults_and_name_bad_keys() {
        let images = MINIMAL.replace(
            "source = \"sim\"\nsocket = \"/tmp/mgmot-sim.sock\"",
            "source = \"images\"\ndirectory = \"/data/img1\"\nfps = 10.0\nloop = true",
        );
        let c = Config::parse(&images).unwrap();
        c.validate().unwrap();
        assert_eq!(
            c.frames,
            FramesConfig::Images {
                directory: "/data/img1".into(),
                fps: 10.0,
                looping: true
            }
        );
        let v4l2 = MINIMAL.replace(
            "source = \"sim\"\nsocket = \"/tmp/mgmot-sim.sock\"",
            "source = \"v4l2\"\ndevice = \"/dev/video0\"\npixel_format = \"NV12\"\n\
             width_px = 1280\nheight_px = 720\nfps = 30",
        );
        let c = Config::parse(&v4l2).unwrap();
        c.validate().unwrap();
        let FramesConfig::V4l2 {
            buffers,
            frame_timeout_ms,
            reconnect_initial_ms,
            reconnect_max_ms,
            ..
        } = c.frames
        else {
            panic!("{:?}", c.frames)
        };
        assert_eq!(
            (
                buffers,
                frame_timeout_ms,
                reconnect_initial_ms,
                reconnect_max_ms
            ),
            (4, 2000, 1000, 5000)
        );
        let bad = v4l2
            .replace("NV12", "RGB3")
            .replace("fps = 30", "fps = 30\nbuffers = 1\nreconnect_max_ms = 10");
        let keys: Vec<String> = Config::parse(&bad)
            .unwrap()
            .validate()
            .unwrap_err()
            .into_iter()
            .map(|p| p.key)
            .collect();
        assert_eq!(
            keys,
            [
                "frames.pixel_format",
                "frames.buffers",
                "frames.reconnect_max_ms"
            ]
        );
        let e = Config::parse(&images.replace("loop = true", "looping = true")).unwrap_err();
        assert!(e.contains("looping"), "{e}");
    }

    #[test]
    fn onnx_detector_defaults_and_settings() {
        let c = Config::parse(ONNX).unwrap();
        c.validate().unwrap();
        let d = onnx_settings(&c);
        assert_eq!(d.model_path, Path::new("models/mgmot-det-int8.onnx"));
        assert_eq!(d.backend.kind, BackendKind::Tract);
        assert_eq!(
            d.backend.ort_dylib_path.as_deref(),
            Some(Path::new("/opt/onnxruntime/libonnxruntime.so"))
        );
        assert_eq!(d.threads, 2);
        assert_eq!(d.score_threshold, 0.25);
        assert_eq!(d.larger_box_iou, Some(0.7));
        assert_eq!(d.class_names.as_deref().map(<[String]>::len), Some(2));
        let off = Config::parse(&ONNX.replace(
            "kind = \"onnx\"",
            "kind = \"onnx\"\nbackend = \"onnxruntime\"\nlarger_box_iou = 1.0",
        ))
        .unwrap();
        let d = onnx_settings(&off);
        assert_eq!(d.backend.kind, BackendKind::OnnxRuntime);
        assert_eq!(d.larger_box_iou, None);
    }

    fn onnx_settings(c: &Config) -> crate::detect::DetectorConfig {
        match &c.detector {
            DetectorConfig::Onnx(o) => o.settings(),
            other => panic!("not the ONNX detector: {other:?}"),
        }
    }

    #[test]
    fn onnx_detector_tiling_keys() {
        let c = Config::parse(&ONNX.replace(
            "kind = \"onnx\"",
            "kind = \"onnx\"\ntile = true\ntile_size_px = 640\ntile_overlap_px = 96",
        ))
        .unwrap();
        c.validate().unwrap();
        let t = onnx_settings(&c).tiling.unwrap();
        assert_eq!(
            (t.tile_px, t.overlap_px, t.include_full_frame),
            (Some(640), 96, true)
        );
        assert_eq!(onnx_settings(&Config::parse(ONNX).unwrap()).tiling, None);
        let keys: Vec<String> = Config::parse(&ONNX.replace(
            "kind = \"onnx\"",
            "kind = \"onnx\"\ntile = true\ntile_size_px = 100\ntile_overlap_px = 100",
        ))
        .unwrap()
        .validate()
        .unwrap_err()
        .into_iter()
        .map(|p| p.key)
        .collect();
        assert_eq!(keys, ["detector.tile_overlap_px"]);
    }

    #[test]
    fn onnx_detector_problems_name_their_keys() {
        let text = ONNX
            .replace(
                "kind = \"onnx\"",
                "kind = \"onnx\"\nthreads = 0\nscore_threshold = 1.5\nnms_iou = -0.1\n\
             larger_box_iou = 0.0\nmax_detections = 0",
            )
            .replace("[\"swimmer\", \"boat\"]", "[\"swimmer\", \" \"]");
        let keys: Vec<String> = Config::parse(&text)
            .unwrap()
            .validate()
            .unwrap_err()
            .into_iter()
            .map(|p| p.key)
            .collect();
        assert_eq!(
            keys,
            [
                "detector.threads",
                "detector.score_threshold",
                "detector.nms_iou",
                "detector.larger_box_iou",
                "detector.max_detections",
                "detector.class_names"
            ]
        );
        let e =
            Config::parse(&ONNX.replace("kind = \"onnx\"", "kind = \"onnx\"\nbackend = \"cuda\""))
                .unwrap_err();
        // The detector table is parsed as a whole (internally tagged): the error points at the
        // `[detector]` line and names the bad value and the accepted ones.
        assert!(
            e.contains("cuda") && e.contains("[detector]") && e.contains("onnxruntime"),
            "{e}"
        );
    }

    /// Issue "Hardening" item 10: numbers that validated before and then broke `mgmot run`
    /// (a panic at start, a panicking task, 110,000 heartbeats in 20 s) are refused with their
    /// key named.
    #[test]
    fn out_of_range_numbers_are_refused_with_their_key() {
        for (key, section, value) in [
            ("heartbeat_hz", "outputs", "1e-300"),
            ("heartbeat_hz", "outputs", "1e300"),
            ("heartbeat_hz", "outputs", "2e9"),
            ("heartbeat_hz", "outputs", "nan"),
            ("track_rate_hz", "outputs", "inf"),
            ("camera_tracking_hz", "outputs", "1e9"),
            ("timesync_hz", "mavlink", "1e12"),
            ("max_range_m", "geolocation", "1e308"),
            ("lost_after_ms", "telemetry", "1e300"),
            ("max_pose_age_ms", "telemetry", "-1"),
        ] {
            let text = if section == "mavlink" {
                MINIMAL.replace("[mavlink]\n", &format!("[mavlink]\n{key} = {value}\n"))
            } else {
                format!("{MINIMAL}\n[{section}]\n{key} = {value}\n")
            };
            let c = Config::parse(&text).unwrap();
            let problems = c.validate().unwrap_err();
            assert!(
                problems.iter().any(|p| p.key == format!("{section}.{key}")),
                "{section}.{key} = {value}: {problems:?}"
            );
        }
        let mut c = Config::parse(MINIMAL).unwrap();
        c.outputs.heartbeat_hz = 1.0;
        c.validate().unwrap();
    }

    #[test]
    fn signing_key_hex() {
        let s = SigningConfig {
            key_hex: "0f".repeat(32),
            link_id: 1,
            state_file: default_signing_state_file(),
            accept_unsigned_telemetry: true,
        };
        assert_eq!(s.key(), Some([0x0f; 32]));
        let bad = SigningConfig {
            key_hex: "zz".repeat(32),
            link_id: 1,
            state_file: default_signing_state_file(),
            accept_unsigned_telemetry: true,
        };
        assert_eq!(bad.key(), None);
    }
}
