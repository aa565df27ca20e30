//! Frame output to a v4l2loopback device (cargo feature `v4l2`), so that `mgmot`'s real
//! V4L2 capture path can read the simulated camera.

use anyhow::Context;
use std::io::Write;
use v4l::video::Output;

/// An opened V4L2 output device configured for packed RGB24 at the scenario's size.
pub struct V4l2Sink {
    device: v4l::Device,
    path: String,
}

impl V4l2Sink {
    /// Opens `path`, checks that it is a video output device and sets the format.
    pub fn open(path: &str, width: u32, height: u32) -> anyhow::Result<V4l2Sink> {
        if !std::path::Path::new(path).exists() {
            anyhow::bail!(
                "no V4L2 device {path}: load v4l2loopback first (e.g. `modprobe v4l2loopback video_nr=10`)"
            );
        }
        let device = v4l::Device::with_path(path).with_context(|| format!("cannot open {path}"))?;
        let caps = device
            .query_caps()
            .with_context(|| format!("{path} is not a V4L2 device"))?;
        anyhow::ensure!(
            caps.capabilities
                .contains(v4l::capability::Flags::VIDEO_OUTPUT),
            "{path} ({}, driver {}) is not a video output device; use a v4l2loopback device",
            caps.card,
            caps.driver
        );
        let mut fmt =
            Output::format(&device).with_context(|| format!("cannot read the format of {path}"))?;
        fmt.width = width;
        fmt.height = height;
        fmt.fourcc = v4l::FourCC::new(b"RGB3");
        fmt.stride = width * 3;
        fmt.size = width * height * 3;
        let got = Output::set_format(&device, &fmt)
            .with_context(|| format!("cannot set RGB24 {width}x{height} on {path}"))?;
        anyhow::ensure!(
            got.width == width && got.height == height && got.fourcc == v4l::FourCC::new(b"RGB3"),
            "{path} refused RGB24 {width}x{height} (got {}x{} {})",
            got.width,
            got.height,
            got.fourcc
        );
        tracing::info!(%path, card = %caps.card, "writing frames to V4L2 output");
        Ok(V4l2Sink {
            device,
            path: path.to_string(),
        })
    }

    /// Writes one frame (v4l2loopback accepts write() I/O).
    pub fn send(&mut self, rgb: &[u8]) -> anyhow::Result<()> {
        self.device
            .write_all(rgb)
            .with_context(|| format!("writing a frame to {}", self.path))
    }
}
