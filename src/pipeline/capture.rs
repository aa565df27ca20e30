//! The capture thread: opens the configured frame source, puts its frames into the
//! newest-frame slot, and gets the source back when it is lost (V4L2 unplug, simulator
//! restart) with the backoff of [`Reconnect`], telling the operator "camera lost" once and
//! "camera back" when frames flow again. The MAVLink link and heartbeat live elsewhere and are
//! untouched by a lost camera.

use super::error::PipelineError;
use super::shutdown::Shutdown;
use super::slot::SlotWriter;
use crate::camera::{
    Backoff, CameraError, CameraStatus, Frame, FrameSource, ImageDirectory, Reconnect,
    SimSocketSource, V4l2Source,
};
use crate::config::{FrameSettings, ReconnectDelays};
use crate::telemetry::CompanionTimeUs;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// Longest single sleep of a reconnect wait, so a shutdown is noticed within this.
const WAIT_SLICE: Duration = Duration::from_millis(50);

/// A frame as the capture thread hands it over, stamped when its source delivered it (read
/// and decoded), so the pipeline's own latency can be told from the source's.
#[derive(Debug)]
pub(super) struct Delivered {
    /// The frame.
    pub frame: Frame,
    /// When the source delivered it (companion clock).
    pub at: CompanionTimeUs,
}

/// With `frames.wait_for_detector`, the longest a frame waits for the detector to take the
/// previous one (then it replaces it, counted as dropped): shutdown never waits longer.
const WAIT_FOR_DETECTOR: Duration = Duration::from_secs(1);

/// Why a capture loop returned.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum CaptureEnd {
    /// The source ended (the simulator finished, the last image was shown).
    SourceEnded,
    /// Shutdown fired.
    Shutdown,
    /// The inference side dropped its end of the slot.
    ConsumerGone,
}

/// Starts the capture thread for `frames`. An image directory is listed here, so a missing
/// or empty one stops the start-up with an error; a missing camera or simulator does not (the
/// runtime keeps its link up and retries).
pub(super) fn start(
    frames: &FrameSettings,
    writer: SlotWriter<Delivered>,
    shutdown: Shutdown,
    captured: Arc<AtomicU64>,
    mut report: impl FnMut(CameraStatus) + Send + 'static,
) -> Result<JoinHandle<()>, PipelineError> {
    check_access(frames)?;
    let stop = shutdown.clone();
    let mut wait = move |d: Duration| wait_unless(&stop, d);
    let wait_for_detector = matches!(
        frames,
        FrameSettings::Sim {
            wait_for_detector: true,
            ..
        }
    );
    let deliver = move |frame: Frame| {
        let delivered = Delivered {
            frame,
            at: crate::clock::now(),
        };
        if wait_for_detector {
            writer.put_waiting(delivered, WAIT_FOR_DETECTOR)
        } else {
            writer.put(delivered)
        }
    };
    let stop = move || shutdown.is_shutdown();
    let (open, reconnect) = opener(frames.clone())?;
    std::thread::Builder::new()
        .name("capture".into())
        .spawn(move || {
            let end = capture_loop(
                open,
                deliver,
                reconnect,
                &stop,
                &mut wait,
                &mut report,
                &captured,
            );
            tracing::info!(?end, "capture stopped");
        })
        .map_err(|_| PipelineError::Panicked("capture"))
}

/// The opener of the configured source and its reconnect backoff.
fn opener(frames: FrameSettings) -> Result<(Opener, Reconnect), PipelineError> {
    let backoff = |d: ReconnectDelays| Reconnect::new(Backoff::new(d.initial, d.max));
    Ok(match frames {
        FrameSettings::Sim {
            socket,
            frame_timeout,
            reconnect,
            wait_for_detector: _,
        } => (
            Box::new(move |_| {
                SimSocketSource::connect(&socket, frame_timeout)
                    .map(boxed)
                    .map_err(CameraError::from)
            }),
            backoff(reconnect),
        ),
        FrameSettings::V4l2 { camera, reconnect } => (
            Box::new(move |first_index| V4l2Source::open(&camera, first_index).map(boxed)),
            backoff(reconnect),
        ),
        FrameSettings::Images {
            directory,
            fps,
            looping,
        } => {
            let mut first = Some(ImageDirectory::open(&directory, fps, looping)?);
            tracing::info!(
                directory = %directory.display(),
                images = first.as_ref().map_or(0, |d| d.files().len()),
                fps,
                looping,
                "playing an image directory"
            );
            // Images never lose their source (a bad file spoils one frame); the reconnect
            // path is only there for the shape of the loop.
            (
                Box::new(move |_| {
                    match first.take() {
                        Some(d) => Ok(d),
                        None => ImageDirectory::open(&directory, fps, looping),
                    }
                    .map(boxed)
                }),
                backoff(ReconnectDelays {
                    initial: Duration::from_secs(1),
                    max: Duration::from_secs(5),
                }),
            )
        }
    })
}

/// Maps a source's frame indices onto the pipeline's: the first frame of a session gets
/// `base`, later ones keep their distance from it; an index that goes back within the session
/// (the source restarted without a reconnect) starts a new base right after the last one.
#[derive(Debug, Clone, Copy)]
struct IndexRebase {
    /// `None`: the source's own first index (the first session keeps the source's numbering).
    base: Option<u64>,
    first_source: Option<u64>,
    last: Option<u64>,
}

impl IndexRebase {
    fn new(base: u64) -> Self {
        Self {
            base: Some(base),
            first_source: None,
            last: None,
        }
    }

    /// The first session: frames keep the source's own indices, so that a frame the source
    /// numbered `k` is frame `k` (the simulator's frame numbers, which its replayed detections
    /// are keyed by, even when mgmot connects after the first frames went by).
    fn keeping_source() -> Self {
        Self {
            base: None,
            first_source: None,
            last: None,
        }
    }

    fn index(&mut self, source: u64) -> u64 {
        let first = *self.first_source.get_or_insert(source);
        let base = *self.base.get_or_insert(first);
        let mapped = source.checked_sub(first).map(|d| base.saturating_add(d));
        let mapped = match (mapped, self.last) {
            (Some(m), Some(last)) if m > last => m,
            (Some(m), None) => m,
            // Went back or repeated: a new base right after the last index given.
            (_, last) => {
                let next = last.map_or(base, |l| l.saturating_add(1));
                self.base = Some(next);
                self.first_source = Some(source);
                next
            }
        };
        self.last = Some(mapped);
        mapped
    }
}

/// A frame source that exists but that this user may not open is named at start-up, with the
/// reason, instead of being retried for ever as "camera lost". One that does not exist yet (a
/// camera not plugged in, a simulator not started) is left to the reconnect loop.
fn check_access(frames: &FrameSettings) -> Result<(), PipelineError> {
    let (path, key, hint) = match frames {
        FrameSettings::Sim { socket, .. } => (
            socket,
            "frames.socket",
            "the user running mgmot needs write access to the socket",
        ),
        FrameSettings::V4l2 { camera, .. } => (
            &camera.device,
            "frames.device",
            "the user running mgmot needs read and write access (usually the `video` group)",
        ),
        FrameSettings::Images { .. } => return Ok(()),
    };
    if !path.exists() {
        return Ok(());
    }
    use rustix::fs::{access, Access};
    access(path.as_path(), Access::READ_OK | Access::WRITE_OK).map_err(|e| {
        PipelineError::Frames(CameraError::Unsupported {
            device: path.clone(),
            problem: format!("{key}: cannot be opened: {e} ({hint})"),
        })
    })
}

/// (Re)opens the configured frame source; the argument is the index its first frame gets.
type Opener = Box<dyn FnMut(u64) -> Result<Box<dyn FrameSource>, CameraError> + Send>;

fn boxed(source: impl FrameSource + 'static) -> Box<dyn FrameSource> {
    Box::new(source)
}

/// Sleeps `d`, in slices, returning early when shutdown fires.
fn wait_unless(shutdown: &Shutdown, d: Duration) {
    let until = Instant::now() + d;
    while !shutdown.is_shutdown() {
        let left = until.saturating_duration_since(Instant::now());
        if left.is_zero() {
            break;
        }
        std::thread::sleep(left.min(WAIT_SLICE));
    }
}

/// The capture loop, whatever the source: `open(next_index)` (re)opens it, each frame goes
/// to `deliver` (false: the consumer is gone), losses are answered by `reconnect` with a
/// `wait` and a `report`. Clock-free, so tests drive it with a fake source and a recording
/// `wait`.
pub(super) fn capture_loop<S: FrameSource>(
    mut open: impl FnMut(u64) -> Result<S, CameraError>,
    mut deliver: impl FnMut(Frame) -> bool,
    mut reconnect: Reconnect,
    stop: &dyn Fn() -> bool,
    wait: &mut dyn FnMut(Duration),
    report: &mut dyn FnMut(CameraStatus),
    captured: &AtomicU64,
) -> CaptureEnd {
    let mut next_index = 0u64;
    let mut bad_frames = 0u64;
    loop {
        if stop() {
            return CaptureEnd::Shutdown;
        }
        // Frame indices are the pipeline's, increasing across sessions: a restarted source
        // (a simulator or camera starting again at 0) must not look like frames from the past
        // to the tracker. Within a session the source's own gaps (dropped frames) are kept;
        // until a first frame arrived, the source's own numbering is.
        let mut rebase = if next_index == 0 {
            IndexRebase::keeping_source()
        } else {
            IndexRebase::new(next_index)
        };
        let mut source = match open(next_index) {
            Ok(s) => {
                reconnect.refused(false);
                s
            }
            Err(e) => {
                let (status, delay) = reconnect.open_failed();
                if let Some(status) = status {
                    tracing::warn!(error = %e, "camera lost: cannot open the frame source; retrying");
                    report(status);
                } else {
                    tracing::debug!(error = %e, retry_in_ms = delay.as_millis() as u64, "camera still lost");
                }
                if reconnect.refused(e.is_permission_denied()) {
                    tracing::warn!(error = %e, "the frame source refuses mgmot (permission denied); retrying");
                    report(CameraStatus::Denied);
                }
                wait(delay);
                continue;
            }
        };
        loop {
            if stop() {
                return CaptureEnd::Shutdown;
            }
            match source.next_frame() {
                Ok(Some(frame)) => {
                    if let Some(status) = reconnect.frame() {
                        tracing::info!("camera back");
                        report(status);
                    }
                    if bad_frames > 0 {
                        tracing::info!(bad_frames, "frames flow again after bad ones");
                        bad_frames = 0;
                    }
                    let mut frame = frame;
                    frame.index = rebase.index(frame.index);
                    next_index = frame.index + 1;
                    captured.fetch_add(1, Ordering::Relaxed);
                    if !deliver(frame) {
                        return CaptureEnd::ConsumerGone;
                    }
                }
                Ok(None) => {
                    tracing::info!("frame source ended");
                    return CaptureEnd::SourceEnded;
                }
                Err(e) if e.is_frame_error() => {
                    bad_frames += 1;
                    // The first of a run, then ever more sparsely.
                    if bad_frames.is_power_of_two() {
                        tracing::warn!(error = %e, bad_frames, "frame skipped");
                    }
                }
                Err(e) => {
                    drop(source);
                    let (status, delay) = reconnect.read_failed();
                    if let Some(status) = status {
                        tracing::warn!(error = %e, "camera lost; reconnecting");
                        report(status);
                    } else {
                        tracing::debug!(error = %e, "camera failed again");
                    }
                    wait(delay);
                    break;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::{CaptureTime, SimFramingError};
    use std::collections::VecDeque;
    use std::path::PathBuf;

    /// What one open of the fake device does.
    enum Session {
        /// The node is missing.
        Missing,
        /// Opens, gives this many frames (the `bad`-th of them spoiled, if any), then fails
        /// like an unplug (ENODEV) or ends.
        Frames {
            count: u64,
            bad: Option<u64>,
            then_end: bool,
        },
    }

    struct Fake {
        /// The index of the session's first frame (the opener's argument, or 0 for a source
        /// that restarts its numbering like the simulator).
        first_index: u64,
        k: u64,
        count: u64,
        bad: Option<u64>,
        then_end: bool,
    }

    fn device() -> PathBuf {
        "/dev/video9".into()
    }

    impl FrameSource for Fake {
        fn next_frame(&mut self) -> Result<Option<Frame>, CameraError> {
            if self.k == self.count {
                if self.then_end {
                    return Ok(None);
                }
                return Err(CameraError::Device {
                    device: device(),
                    action: "VIDIOC_DQBUF",
                    source: std::io::Error::from_raw_os_error(19),
                });
            }
            let index = self.first_index + self.k;
            self.k += 1;
            if self.bad == Some(self.k - 1) {
                return Err(CameraError::Buffer {
                    device: device(),
                    index,
                    problem: "corrupt".into(),
                });
            }
            Ok(Some(Frame {
                index,
                captured: CaptureTime::Companion(CompanionTimeUs(index)),
                width_px: 1,
                height_px: 1,
                rgb: vec![0; 3],
            }))
        }
    }

    fn run(script: Vec<Session>) -> (CaptureEnd, Vec<u64>, Vec<Duration>, Vec<CameraStatus>) {
        let mut script: VecDeque<Session> = script.into();
        let mut frames = Vec::new();
        let mut waits = Vec::new();
        let mut reports = Vec::new();
        let captured = AtomicU64::new(0);
        let open = |first_index| match script.pop_front() {
            Some(Session::Frames {
                count,
                bad,
                then_end,
            }) => Ok(Fake {
                first_index,
                k: 0,
                count,
                bad,
                then_end,
            }),
            Some(Session::Missing) | None => Err(CameraError::Device {
                device: device(),
                action: "open",
                source: std::io::Error::from_raw_os_error(2),
            }),
        };
        let end = capture_loop(
            open,
            |f: Frame| {
                frames.push(f.index);
                true
            },
            Reconnect::new(Backoff::new(Duration::from_secs(1), Duration::from_secs(5))),
            &|| false,
            &mut |d| waits.push(d),
            &mut |s| reports.push(s),
            &captured,
        );
        assert_eq!(captured.load(Ordering::Relaxed), frames.len() as u64);
        (end, frames, waits, reports)
    }

    /// Missing at start, streams, unplugged, away for three tries, back, unplugged, back,
    /// ends: "lost" and "back" once per loss, backoff 1 s doubling to 5 s, reset by frames,
    /// indices continuing across sessions, a spoiled frame skipped without a reconnect.
    #[test]
    fn fails_comes_back_fails_and_comes_back() {
        use CameraStatus::{Back, Lost};
        use Session::{Frames, Missing};
        let s = Duration::from_secs;
        let (end, frames, waits, reports) = run(vec![
            Missing,
            Missing,
            Frames {
                count: 3,
                bad: Some(1),
                then_end: false,
            },
            Missing,
            Missing,
            Missing,
            Missing,
            Frames {
                count: 2,
                bad: None,
                then_end: false,
            },
            Frames {
                count: 0,
                bad: None,
                then_end: false,
            },
            Frames {
                count: 2,
                bad: None,
                then_end: true,
            },
        ]);
        assert_eq!(end, CaptureEnd::SourceEnded);
        assert_eq!(reports, [Lost, Back, Lost, Back, Lost, Back]);
        assert_eq!(
            waits,
            [s(1), s(2), s(1), s(2), s(4), s(5), s(5), s(1), s(2)]
        );
        assert_eq!(frames, [0, 2, 3, 4, 5, 6]);
    }

    /// A source that numbers every session from 0 again (the simulator restarted, a camera
    /// driver reset): the pipeline's indices still only go forward, and gaps within a
    /// session (dropped frames) are kept.
    #[test]
    fn a_source_restarting_its_numbering_never_goes_back() {
        let captured = AtomicU64::new(0);
        let mut sessions = 0;
        let mut frames = Vec::new();
        capture_loop(
            |_| {
                sessions += 1;
                if sessions > 3 {
                    return Ok(Fake {
                        first_index: 0,
                        k: 0,
                        count: 0,
                        bad: None,
                        then_end: true,
                    });
                }
                Ok(Fake {
                    first_index: 0,
                    k: 0,
                    count: 3,
                    bad: None,
                    then_end: false,
                })
            },
            |f: Frame| {
                frames.push(f.index);
                true
            },
            Reconnect::new(Backoff::new(Duration::from_secs(1), Duration::from_secs(5))),
            &|| false,
            &mut |_| {},
            &mut |_| {},
            &captured,
        );
        assert_eq!(frames, [0, 1, 2, 3, 4, 5, 6, 7, 8]);

        let mut r = IndexRebase::new(100);
        let got: Vec<u64> = [7, 8, 10, 3, 4, 4, 20]
            .iter()
            .map(|&i| r.index(i))
            .collect();
        assert_eq!(got, [100, 101, 103, 104, 105, 106, 122]);

        // The first session keeps the source's numbering (connected after frame 27 went by).
        let mut r = IndexRebase::keeping_source();
        let got: Vec<u64> = [27, 28, 30, 2].iter().map(|&i| r.index(i)).collect();
        assert_eq!(got, [27, 28, 30, 31]);
    }

    #[test]
    fn stops_on_shutdown_and_when_the_consumer_is_gone() {
        let captured = AtomicU64::new(0);
        let opens = std::cell::Cell::new(0);
        let end = capture_loop(
            |_| -> Result<Fake, CameraError> {
                opens.set(opens.get() + 1);
                Err(CameraError::Sim(SimFramingError::Io {
                    path: "/tmp/x.sock".into(),
                    source: std::io::ErrorKind::NotFound.into(),
                }))
            },
            |_| true,
            Reconnect::new(Backoff::new(Duration::from_secs(1), Duration::from_secs(5))),
            &|| opens.get() >= 3,
            &mut |_| {},
            &mut |_| {},
            &captured,
        );
        assert_eq!((end, opens.get()), (CaptureEnd::Shutdown, 3));
        let end = capture_loop(
            |first_index| {
                Ok(Fake {
                    first_index,
                    k: 0,
                    count: 10,
                    bad: None,
                    then_end: true,
                })
            },
            |f| f.index < 4,
            Reconnect::new(Backoff::new(Duration::from_secs(1), Duration::from_secs(5))),
            &|| false,
            &mut |_| {},
            &mut |_| {},
            &captured,
        );
        assert_eq!(end, CaptureEnd::ConsumerGone);
        assert_eq!(captured.load(Ordering::Relaxed), 5);
    }
}
