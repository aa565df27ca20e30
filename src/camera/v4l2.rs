//! A V4L2 capture device through the `v4l` crate: format, size and frame rate from the
//! configuration (what the driver grants is logged and used), mmap streaming, kernel buffer
//! timestamps, decoding to RGB24 ([`super::decode`]).
//!
//! Timestamps: V4L2 stamps buffers on `CLOCK_MONOTONIC` when the buffer flags say
//! `V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC`; that is the companion clock of the whole runtime
//! ([`CompanionTimeUs::now`]), so frames and telemetry arrival times compare directly. A driver
//! that gives no monotonic timestamp gets the frame stamped at dequeue (later than the
//! exposure by the transfer time), said once in the log.
//!
//! After an error that is not a frame error the source must be dropped and opened again (the
//! capture loop does so): the stream's buffer bookkeeping is not resumable after a failed
//! dequeue.

use super::decode::{decode_to_rgb, FrameLayout, PixelFormat, YuvMatrix, YuvRange};
use super::{CameraError, CaptureTime, Frame, FrameSource};
use crate::telemetry::CompanionTimeUs;
use std::panic::AssertUnwindSafe;
use std::path::{Path, PathBuf};
use std::time::Duration;
use v4l::buffer::Type;
use v4l::capability::Flags as CapFlags;
use v4l::format::{Colorspace, Quantization};
use v4l::io::mmap::Stream as MmapStream;
use v4l::io::traits::CaptureStream;
use v4l::video::capture::Parameters;
use v4l::video::Capture;
use v4l::{Device, Format, FourCC};

/// `V4L2_BUF_FLAG_TIMESTAMP_MASK` and `V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC`.
const TIMESTAMP_MASK: u32 = 0x0000_e000;
const TIMESTAMP_MONOTONIC: u32 = 0x0000_2000;
/// `V4L2_BUF_FLAG_ERROR`: the driver says the buffer's data is corrupt (an incomplete USB
/// transfer, typically).
const BUF_FLAG_ERROR: u32 = 0x0000_0040;
/// `ENOTTY`: the ioctl is not for this kind of file (not a V4L2 node) or not supported.
const ENOTTY: i32 = 25;

/// What to ask of a V4L2 device.
#[derive(Debug, Clone, PartialEq)]
pub struct V4l2Settings {
    /// Device node, e.g. `/dev/video0`.
    pub device: PathBuf,
    /// Pixel format.
    pub pixel_format: PixelFormat,
    /// Width (px) asked for.
    pub width_px: u32,
    /// Height (px) asked for.
    pub height_px: u32,
    /// Frame rate asked for.
    pub fps: u32,
    /// Kernel buffers in the mmap ring: more absorb jitter, fewer keep latency and memory low.
    pub buffers: u32,
    /// No frame for this long means the camera is lost (stalled or unplugged).
    pub frame_timeout: Duration,
}

/// An open, configured V4L2 capture device.
pub struct V4l2Source {
    /// For errors and logs.
    device: PathBuf,
    /// The mmap ring; dropped before the device (field order), inside `catch_unwind`.
    stream: Option<MmapStream<'static>>,
    /// The open node (the stream shares its handle).
    _dev: Device,
    /// How the granted format lays out its buffers.
    layout: FrameLayout,
    /// Index of the first frame of this session (indices continue across reconnects).
    first_index: u64,
    /// Driver sequence number of the first frame of this session.
    first_sequence: Option<u32>,
    /// "No monotonic timestamps" has been logged for this session.
    dequeue_stamp_logged: bool,
}

impl std::fmt::Debug for V4l2Source {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("V4l2Source")
            .field("device", &self.device)
            .field("layout", &self.layout)
            .finish_non_exhaustive()
    }
}

impl V4l2Source {
    /// Opens and configures the device; its frames are numbered from `first_index`.
    pub fn open(settings: &V4l2Settings, first_index: u64) -> Result<Self, CameraError> {
        // The v4l crate panics on some driver answers it does not expect (an unknown
        // colorspace, a non-UTF-8 card name): a strange device must not kill the capture
        // thread.
        std::panic::catch_unwind(AssertUnwindSafe(|| open(settings, first_index))).unwrap_or_else(
            |_| {
                Err(CameraError::Unsupported {
                    device: settings.device.clone(),
                    problem: "the v4l crate panicked on the driver's answers".into(),
                })
            },
        )
    }

    /// The granted buffer layout.
    pub fn layout(&self) -> &FrameLayout {
        &self.layout
    }
}

fn open(settings: &V4l2Settings, first_index: u64) -> Result<V4l2Source, CameraError> {
    let device = settings.device.clone();
    let os = |action: &'static str| {
        let device = device.clone();
        move |source: std::io::Error| CameraError::Device {
            device,
            action,
            source,
        }
    };
    let unsupported = |problem: String| CameraError::Unsupported {
        device: device.clone(),
        problem,
    };
    let dev = Device::with_path(&device).map_err(os("open"))?;
    let caps = dev.query_caps().map_err(|e| {
        if e.raw_os_error() == Some(ENOTTY) {
            unsupported(format!("not a V4L2 device (VIDIOC_QUERYCAP: {e})"))
        } else {
            os("VIDIOC_QUERYCAP")(e)
        }
    })?;
    if !caps.capabilities.contains(CapFlags::VIDEO_CAPTURE) {
        return Err(unsupported(format!(
            "{} ({}) is not a single-planar video capture device",
            caps.card, caps.driver
        )));
    }
    if !caps.capabilities.contains(CapFlags::STREAMING) {
        return Err(unsupported(format!(
            "{} ({}) does not support streaming I/O",
            caps.card, caps.driver
        )));
    }
    let wanted = settings.pixel_format;
    let asked = Format::new(
        settings.width_px,
        settings.height_px,
        FourCC::new(&wanted.fourcc()),
    );
    let granted = dev.set_format(&asked).map_err(os("VIDIOC_S_FMT"))?;
    if granted.fourcc.repr != wanted.fourcc() {
        let offered = dev
            .enum_formats()
            .map(|fs| {
                fs.iter()
                    .map(|f| String::from_utf8_lossy(&f.fourcc.repr).into_owned())
                    .collect::<Vec<_>>()
                    .join(", ")
            })
            .unwrap_or_else(|e| format!("cannot list formats: {e}"));
        return Err(unsupported(format!(
            "the driver does not capture {wanted} (it offers: {offered})"
        )));
    }
    if (granted.width, granted.height) != (settings.width_px, settings.height_px) {
        tracing::warn!(
            device = %device.display(),
            asked = %format!("{}x{}", settings.width_px, settings.height_px),
            granted = %format!("{}x{}", granted.width, granted.height),
            "the driver chose another frame size; using it"
        );
    }
    match dev.set_params(&Parameters::with_fps(settings.fps)) {
        Ok(p) if p.interval.numerator > 0 => {
            let fps = f64::from(p.interval.denominator) / f64::from(p.interval.numerator);
            if (fps - f64::from(settings.fps)).abs() > 0.01 * f64::from(settings.fps) {
                tracing::warn!(
                    device = %device.display(),
                    asked = settings.fps,
                    granted = fps,
                    "the driver chose another frame rate"
                );
            }
        }
        Ok(_) => tracing::warn!(device = %device.display(), "the driver reports no frame interval"),
        Err(e) => tracing::warn!(
            device = %device.display(),
            error = %e,
            "the driver does not set the frame rate (VIDIOC_S_PARM)"
        ),
    }
    let layout = FrameLayout {
        format: wanted,
        width_px: granted.width,
        height_px: granted.height,
        stride_bytes: granted.stride,
        matrix: match granted.colorspace {
            Colorspace::Rec709 => YuvMatrix::Bt709,
            _ => YuvMatrix::Bt601,
        },
        range: match (granted.quantization, granted.colorspace) {
            (Quantization::FullRange, _) | (Quantization::Default, Colorspace::JPEG) => {
                YuvRange::Full
            }
            _ => YuvRange::Limited,
        },
    };
    let mut stream = MmapStream::with_buffers(&dev, Type::VideoCapture, settings.buffers)
        .map_err(os("VIDIOC_REQBUFS / mmap"))?;
    // (The v4l crate panics on a timeout beyond i32::MAX ms.)
    stream.set_timeout(settings.frame_timeout.min(Duration::from_secs(3600)));
    tracing::info!(
        device = %device.display(),
        card = %caps.card,
        driver = %caps.driver,
        format = %wanted,
        width_px = layout.width_px,
        height_px = layout.height_px,
        stride_bytes = layout.stride_bytes,
        matrix = ?layout.matrix,
        range = ?layout.range,
        "V4L2 device open"
    );
    Ok(V4l2Source {
        device,
        stream: Some(stream),
        _dev: dev,
        layout,
        first_index,
        first_sequence: None,
        dequeue_stamp_logged: false,
    })
}

impl FrameSource for V4l2Source {
    fn next_frame(&mut self) -> Result<Option<Frame>, CameraError> {
        let lost = |device: &Path, source| CameraError::Device {
            device: device.to_owned(),
            action: "capture",
            source,
        };
        let Some(stream) = self.stream.as_mut() else {
            return Err(lost(
                &self.device,
                std::io::Error::other("the stream is closed"),
            ));
        };
        let (buf, meta) = match stream.next() {
            Ok(x) => x,
            Err(e) => {
                // Not resumable (see the module doc): close now so a retry reopens.
                self.stream = None;
                return Err(lost(&self.device, e));
            }
        };
        let first = *self.first_sequence.get_or_insert(meta.sequence);
        let index = self.first_index + u64::from(meta.sequence.wrapping_sub(first));
        let flags = u32::from(meta.flags);
        let captured = if flags & TIMESTAMP_MASK == TIMESTAMP_MONOTONIC {
            #[allow(clippy::unnecessary_cast)] // time_t is 32-bit on some targets
            CompanionTimeUs::from_timespec(meta.timestamp.sec as i64, meta.timestamp.usec as i64)
        } else {
            if !self.dequeue_stamp_logged {
                tracing::warn!(
                    device = %self.device.display(),
                    flags = format!("{flags:#x}"),
                    "the driver gives no monotonic buffer timestamps; stamping frames at dequeue"
                );
                self.dequeue_stamp_logged = true;
            }
            crate::clock::now()
        };
        if flags & BUF_FLAG_ERROR != 0 {
            return Err(CameraError::Buffer {
                device: self.device.clone(),
                index,
                problem: "the driver flagged the buffer as corrupt".into(),
            });
        }
        let used = meta.bytesused as usize;
        let data = if used > 0 && used <= buf.len() {
            &buf[..used]
        } else {
            buf
        };
        let mut rgb = Vec::new();
        decode_to_rgb(&self.layout, data, &mut rgb).map_err(|source| CameraError::Decode {
            device: self.device.clone(),
            index,
            source,
        })?;
        Ok(Some(Frame {
            index,
            captured: CaptureTime::Companion(captured),
            width_px: self.layout.width_px,
            height_px: self.layout.height_px,
            rgb,
        }))
    }
}

impl Drop for V4l2Source {
    fn drop(&mut self) {
        if let Some(stream) = self.stream.take() {
            // The v4l crate's stream panics in its Drop when VIDIOC_STREAMOFF fails with
            // anything but ENODEV; an unplug can give other errors.
            if std::panic::catch_unwind(AssertUnwindSafe(move || drop(stream))).is_err() {
                tracing::warn!(device = %self.device.display(), "closing the V4L2 stream failed");
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn settings(device: &str) -> V4l2Settings {
        V4l2Settings {
            device: device.into(),
            pixel_format: PixelFormat::Mjpg,
            width_px: 1280,
            height_px: 720,
            fps: 30,
            buffers: 4,
            frame_timeout: Duration::from_secs(2),
        }
    }

    #[test]
    fn a_missing_node_is_named() {
        let e = V4l2Source::open(&settings("/dev/video-mgmot-missing"), 0).unwrap_err();
        let text = e.to_string();
        assert!(text.contains("/dev/video-mgmot-missing"), "{text}");
        assert!(text.contains("open"), "{text}");
        assert!(
            matches!(&e, CameraError::Device { source, .. } if source.kind() == std::io::ErrorKind::NotFound),
            "{e:?}"
        );
    }

    #[test]
    fn a_node_that_is_not_v4l2_is_named() {
        let e = V4l2Source::open(&settings("/dev/null"), 0).unwrap_err();
        let text = e.to_string();
        assert!(text.contains("/dev/null"), "{text}");
        assert!(text.contains("not a V4L2 device"), "{text}");
    }

    #[test]
    fn a_regular_file_is_not_a_device() {
        let f = tempfile::NamedTempFile::new().unwrap();
        let e = V4l2Source::open(&settings(f.path().to_str().unwrap()), 0).unwrap_err();
        assert!(e.to_string().contains("not a V4L2 device"), "{e}");
    }
}
