//! Image files of a directory as a camera: `.jpg`, `.jpeg` and `.png` files (extension case
//! ignored, other files skipped) in byte order of their names, paced at a nominal frame rate.
//!
//! Timing: frame `k` is due at `t0 + k / fps` on the companion's monotonic clock, where `t0` is
//! when the first frame was asked for; the source sleeps until a frame is due and stamps it
//! with that nominal time ([`CaptureTime::Companion`]). So a directory plays like a live
//! camera: the runtime looks up the pose at the moment the frame is shown, from live
//! telemetry (bench tests with the simulator's MAVLink stream). A slow consumer does not slow
//! the clock; it drops frames in the newest-frame slot as with a real camera.
//!
//! Frame indices count images shown, across loops (`k`): index `k` is the `k mod n`-th file,
//! so the replay detector's image ids follow the file order on the first pass.
//!
//! A file that cannot be read or decoded spoils its frame only: `next_frame` returns a
//! [`CameraError::Image`] naming it (the capture loop logs it and goes on), its index is
//! skipped (a gap, as for a dropped frame) and the next file keeps its time slot.

use super::{CameraError, CaptureTime, Frame, FrameSource};
use crate::telemetry::CompanionTimeUs;
use std::path::{Path, PathBuf};

/// The clock that paces a directory: now, and waiting until a time.
pub trait FrameClock: Send {
    /// Now on the companion's monotonic clock.
    fn now(&self) -> CompanionTimeUs;
    /// Blocks until `t` (returns at once if it has passed).
    fn sleep_until(&mut self, t: CompanionTimeUs);
}

/// `CLOCK_MONOTONIC` and `std::thread::sleep`.
#[derive(Debug, Clone, Copy, Default)]
pub struct MonotonicClock;

impl FrameClock for MonotonicClock {
    fn now(&self) -> CompanionTimeUs {
        crate::clock::now()
    }

    fn sleep_until(&mut self, t: CompanionTimeUs) {
        let now = crate::clock::now();
        if t > now {
            std::thread::sleep(std::time::Duration::from_micros(t.0 - now.0));
        }
    }
}

/// A directory of images played as a camera.
#[derive(Debug)]
pub struct ImageDirectory<C: FrameClock = MonotonicClock> {
    /// For errors.
    directory: PathBuf,
    /// The images, in name order.
    files: Vec<PathBuf>,
    /// Nominal frame period (µs).
    period_us: f64,
    /// Start again after the last image instead of ending.
    looping: bool,
    /// Paces the frames (injected in tests).
    clock: C,
    /// When frame 0 was due; set by the first `next_frame`.
    start: Option<CompanionTimeUs>,
    /// Index of the next frame.
    next: u64,
}

impl ImageDirectory<MonotonicClock> {
    /// Lists `directory`, paced at `fps` on the monotonic clock.
    pub fn open(directory: &Path, fps: f64, looping: bool) -> Result<Self, CameraError> {
        Self::with_clock(directory, fps, looping, MonotonicClock)
    }
}

impl<C: FrameClock> ImageDirectory<C> {
    /// Lists `directory`, paced by `clock`. Errors when it cannot be read, has no images, or
    /// `fps` is not a positive number.
    pub fn with_clock(
        directory: &Path,
        fps: f64,
        looping: bool,
        clock: C,
    ) -> Result<Self, CameraError> {
        let bad = |problem: String| CameraError::Directory {
            directory: directory.to_owned(),
            problem,
        };
        if !(fps.is_finite() && fps > 0.0) {
            return Err(bad(format!("frame rate {fps} must be > 0")));
        }
        let entries = std::fs::read_dir(directory).map_err(|e| bad(e.to_string()))?;
        let mut files = Vec::new();
        for entry in entries {
            let path = entry.map_err(|e| bad(e.to_string()))?.path();
            let is_image = path.extension().and_then(|e| e.to_str()).is_some_and(|e| {
                ["jpg", "jpeg", "png"]
                    .iter()
                    .any(|x| e.eq_ignore_ascii_case(x))
            });
            if is_image && path.is_file() {
                files.push(path);
            }
        }
        if files.is_empty() {
            return Err(bad("no .jpg, .jpeg or .png files".into()));
        }
        files.sort_by(|a, b| a.file_name().cmp(&b.file_name()));
        Ok(Self {
            directory: directory.to_owned(),
            files,
            period_us: 1e6 / fps,
            looping,
            clock,
            start: None,
            next: 0,
        })
    }

    /// The images, in the order they are shown.
    pub fn files(&self) -> &[PathBuf] {
        &self.files
    }

    /// The directory.
    pub fn directory(&self) -> &Path {
        &self.directory
    }
}

impl<C: FrameClock> FrameSource for ImageDirectory<C> {
    fn next_frame(&mut self) -> Result<Option<Frame>, CameraError> {
        let n = self.files.len() as u64;
        if self.next >= n && !self.looping {
            return Ok(None);
        }
        let index = self.next;
        self.next += 1;
        let start = *self.start.get_or_insert_with(|| self.clock.now());
        let due = CompanionTimeUs(start.0 + (index as f64 * self.period_us).round() as u64);
        self.clock.sleep_until(due);
        let path = &self.files[(index % n) as usize];
        let image = image::ImageReader::open(path)
            .map_err(|e| e.to_string())
            .and_then(|r| r.with_guessed_format().map_err(|e| e.to_string()))
            .and_then(|r| r.decode().map_err(|e| e.to_string()))
            .map_err(|problem| CameraError::Image {
                path: path.clone(),
                problem,
            })?
            .into_rgb8();
        Ok(Some(Frame {
            index,
            captured: CaptureTime::Companion(due),
            width_px: image.width(),
            height_px: image.height(),
            rgb: image.into_raw(),
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A clock that only moves when slept on, recording every wait.
    #[derive(Debug, Default)]
    struct FakeClock {
        now_us: u64,
        slept_until: Vec<u64>,
    }

    impl FrameClock for &mut FakeClock {
        fn now(&self) -> CompanionTimeUs {
            CompanionTimeUs(self.now_us)
        }
        fn sleep_until(&mut self, t: CompanionTimeUs) {
            self.slept_until.push(t.0);
            self.now_us = self.now_us.max(t.0);
        }
    }

    // `&mut FakeClock` must be Send for FrameSource: it is, FakeClock being Send.

    fn write_png(path: &Path, rgb: [u8; 3]) {
        image::RgbImage::from_pixel(4, 3, image::Rgb(rgb))
            .save(path)
            .unwrap();
    }

    #[test]
    fn plays_in_name_order_at_the_nominal_rate_then_ends() {
        let dir = tempfile::tempdir().unwrap();
        write_png(&dir.path().join("000002.png"), [2, 0, 0]);
        write_png(&dir.path().join("000010.PNG"), [10, 0, 0]);
        write_png(&dir.path().join("000001.png"), [1, 0, 0]);
        image::RgbImage::from_pixel(4, 3, image::Rgb([3, 0, 0]))
            .save(dir.path().join("000003.jpg"))
            .unwrap();
        std::fs::write(dir.path().join("notes.txt"), "not an image").unwrap();
        let mut clock = FakeClock {
            now_us: 5_000_000,
            ..FakeClock::default()
        };
        let mut src = ImageDirectory::with_clock(dir.path(), 30.0, false, &mut clock).unwrap();
        let names: Vec<_> = src
            .files()
            .iter()
            .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
            .collect();
        assert_eq!(
            names,
            ["000001.png", "000002.png", "000003.jpg", "000010.PNG"]
        );
        let mut frames = Vec::new();
        while let Some(f) = src.next_frame().unwrap() {
            frames.push(f);
        }
        assert!(src.next_frame().unwrap().is_none());
        drop(src);
        let times: Vec<_> = frames.iter().map(|f| f.captured).collect();
        let expected: Vec<_> = [0u64, 33_333, 66_667, 100_000]
            .iter()
            .map(|d| CaptureTime::Companion(CompanionTimeUs(5_000_000 + d)))
            .collect();
        assert_eq!(times, expected);
        assert_eq!(
            clock.slept_until,
            [5_000_000, 5_033_333, 5_066_667, 5_100_000]
        );
        let firsts: Vec<_> = frames.iter().map(|f| (f.index, f.rgb[0])).collect();
        assert_eq!(firsts[0], (0, 1));
        assert_eq!(firsts[1], (1, 2));
        assert!(firsts[2].0 == 2 && firsts[2].1.abs_diff(3) <= 2, "JPEG");
        assert_eq!(firsts[3], (3, 10));
        assert!(frames
            .iter()
            .all(|f| (f.width_px, f.height_px, f.rgb.len()) == (4, 3, 36)));
    }

    #[test]
    fn a_corrupt_file_is_named_and_skipped_looping_goes_on() {
        let dir = tempfile::tempdir().unwrap();
        write_png(&dir.path().join("a.png"), [1, 0, 0]);
        std::fs::write(dir.path().join("b.png"), b"\x89PNG broken").unwrap();
        write_png(&dir.path().join("c.png"), [3, 0, 0]);
        let mut clock = FakeClock::default();
        let mut src = ImageDirectory::with_clock(dir.path(), 10.0, true, &mut clock).unwrap();
        assert_eq!(src.next_frame().unwrap().unwrap().index, 0);
        let e = src.next_frame().unwrap_err();
        assert!(e.is_frame_error());
        assert!(e.to_string().contains("b.png"), "{e}");
        let c = src.next_frame().unwrap().unwrap();
        assert_eq!((c.index, c.rgb[0]), (2, 3));
        assert_eq!(c.captured, CaptureTime::Companion(CompanionTimeUs(200_000)));
        // Looping: the first file again, with the next index and time.
        let again = src.next_frame().unwrap().unwrap();
        assert_eq!((again.index, again.rgb[0]), (3, 1));
        assert_eq!(
            again.captured,
            CaptureTime::Companion(CompanionTimeUs(300_000))
        );
    }

    #[test]
    fn missing_empty_directory_and_bad_rate_are_named() {
        let e = ImageDirectory::open(Path::new("/nonexistent/frames"), 30.0, false).unwrap_err();
        assert!(e.to_string().contains("/nonexistent/frames"), "{e}");
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("readme.txt"), "x").unwrap();
        let e = ImageDirectory::open(dir.path(), 30.0, false).unwrap_err();
        assert!(e.to_string().contains("no .jpg"), "{e}");
        write_png(&dir.path().join("a.png"), [0, 0, 0]);
        assert!(ImageDirectory::open(dir.path(), 0.0, false).is_err());
        assert!(ImageDirectory::open(dir.path(), f64::NAN, false).is_err());
    }
}
