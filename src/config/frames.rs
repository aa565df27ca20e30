//! `[frames]`: where frames come from (a V4L2 camera, the simulator's socket, or images).

use super::problems::{Problem, Problems};
use crate::camera::{PixelFormat, V4l2Settings};
use serde::{Deserialize, Serialize};
use std::fmt;
use std::path::PathBuf;
use std::time::Duration;

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

/// The validated frame source.
#[derive(Debug, Clone, PartialEq)]
pub enum FrameSettings {
    /// A V4L2 capture device.
    V4l2 {
        /// What to ask of the device (pixel format parsed, frame timeout as a duration).
        camera: V4l2Settings,
        /// Backoff after the camera is lost.
        reconnect: ReconnectDelays,
    },
    /// The simulator's Unix-socket frame stream.
    Sim {
        /// The socket path.
        socket: PathBuf,
        /// A longer wait for the next frame means the simulator froze.
        frame_timeout: Duration,
        /// Backoff when the socket is absent or the stream breaks.
        reconnect: ReconnectDelays,
        /// Hold each frame until the detector took the previous one (bench runs only).
        wait_for_detector: bool,
    },
    /// Image files of a directory, in name order.
    Images {
        /// The directory.
        directory: PathBuf,
        /// Frame rate used to time the images (in (0, 1000]).
        fps: f64,
        /// Start again after the last image.
        looping: bool,
    },
}

/// The source in one line, as `mgmot check-config` prints it: `v4l2 /dev/video0 MJPG 1280x720
/// @ 30 fps`, `simulator socket PATH`, `images in DIR @ FPS fps`.
impl fmt::Display for FrameSettings {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            FrameSettings::V4l2 { camera: c, .. } => write!(
                f,
                "v4l2 {} {} {}x{} @ {} fps",
                c.device.display(),
                c.pixel_format,
                c.width_px,
                c.height_px,
                c.fps
            ),
            FrameSettings::Sim { socket, .. } => {
                write!(f, "simulator socket {}", socket.display())
            }
            FrameSettings::Images { directory, fps, .. } => {
                write!(f, "images in {} @ {fps} fps", directory.display())
            }
        }
    }
}

/// The reconnect backoff of a frame source: `initial`, doubling up to `max`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ReconnectDelays {
    /// First delay (> 0).
    pub initial: Duration,
    /// Cap (>= `initial`).
    pub max: Duration,
}

/// The frame timeout, if within 1..=60000 ms.
fn frame_timeout(p: &mut Problems, ms: u64) -> Option<Duration> {
    p.check(
        (1..=60_000).contains(&ms),
        "frames.frame_timeout_ms",
        "must be within 1..=60000",
        Duration::from_millis(ms),
    )
}

/// The reconnect backoff, if the first delay is > 0 and the cap no smaller.
fn reconnect(p: &mut Problems, initial_ms: u64, max_ms: u64) -> Option<ReconnectDelays> {
    let initial = p.check(
        initial_ms > 0,
        "frames.reconnect_initial_ms",
        "must be > 0",
        initial_ms,
    );
    let max = p.check(
        max_ms >= initial_ms,
        "frames.reconnect_max_ms",
        format!("must be >= reconnect_initial_ms ({initial_ms})"),
        max_ms,
    );
    Some(ReconnectDelays {
        initial: Duration::from_millis(initial?),
        max: Duration::from_millis(max?),
    })
}

impl FramesConfig {
    /// The frame source's settings, or the section's problems pushed onto `p`.
    pub fn validate(&self, p: &mut Problems) -> Option<FrameSettings> {
        match self {
            FramesConfig::V4l2 { .. } => self.validate_v4l2(p),
            FramesConfig::Sim {
                socket,
                frame_timeout_ms,
                reconnect_initial_ms,
                reconnect_max_ms,
                wait_for_detector,
            } => {
                let frame_timeout = frame_timeout(p, *frame_timeout_ms);
                let reconnect = reconnect(p, *reconnect_initial_ms, *reconnect_max_ms);
                Some(FrameSettings::Sim {
                    socket: socket.clone(),
                    frame_timeout: frame_timeout?,
                    reconnect: reconnect?,
                    wait_for_detector: *wait_for_detector,
                })
            }
            FramesConfig::Images {
                directory,
                fps,
                looping,
            } => p.check(
                fps.is_finite() && *fps > 0.0 && *fps <= 1000.0,
                "frames.fps",
                "must be within (0, 1000]",
                FrameSettings::Images {
                    directory: directory.clone(),
                    fps: *fps,
                    looping: *looping,
                },
            ),
        }
    }

    /// [`FramesConfig::validate`] on its own, for a caller that holds a configuration and not
    /// its settings: every problem of the section, or its settings.
    pub fn settings(&self) -> Result<FrameSettings, Vec<Problem>> {
        let mut p = Problems::default();
        match self.validate(&mut p) {
            Some(settings) if p.is_empty() => Ok(settings),
            _ => Err(p.into_vec()),
        }
    }

    /// The `V4l2` arm of [`FramesConfig::validate`] (`None` for another source).
    fn validate_v4l2(&self, p: &mut Problems) -> Option<FrameSettings> {
        let FramesConfig::V4l2 {
            device,
            pixel_format,
            width_px,
            height_px,
            fps,
            buffers,
            frame_timeout_ms,
            reconnect_initial_ms,
            reconnect_max_ms,
        } = self
        else {
            return None;
        };
        let pixel_format = pixel_format
            .parse::<PixelFormat>()
            .map_err(|e| p.push("frames.pixel_format", e))
            .ok();
        let size_ok = *width_px > 0 && *height_px > 0;
        let size = p.check(
            size_ok,
            "frames.width_px",
            "width and height must be > 0",
            (),
        );
        let fps = p.check(*fps > 0, "frames.fps", "must be > 0", *fps);
        let buffers_ok = (2..=32).contains(buffers);
        let buffers = p.check(
            buffers_ok,
            "frames.buffers",
            "must be within 2..=32",
            *buffers,
        );
        let frame_timeout = frame_timeout(p, *frame_timeout_ms);
        let reconnect = reconnect(p, *reconnect_initial_ms, *reconnect_max_ms);
        size?;
        Some(FrameSettings::V4l2 {
            camera: V4l2Settings {
                device: device.clone(),
                pixel_format: pixel_format?,
                width_px: *width_px,
                height_px: *height_px,
                fps: fps?,
                buffers: buffers?,
                frame_timeout: frame_timeout?,
            },
            reconnect: reconnect?,
        })
    }
}
