//! The recorder: a thread that owns the flight's files, fed through a bounded queue so that
//! the frame step and the MAVLink link never wait for the disk.
//!
//! - Frame records are appended to `frames.ndjson` one `write` per line, and the files are
//!   flushed and `fdatasync`ed whenever the queue runs empty (group commit): a SIGKILL or a
//!   power cut loses at most the records still in flight, and a line cut short is skipped by
//!   the reader.
//! - When the queue is full (the disk is slower than the frames), records are dropped and
//!   counted.
//! - A write that fails (disk full, read-only, removed) stops recording: the files are cut
//!   back to their last whole record, the failure is announced once (log and STATUSTEXT),
//!   and every [`RETRY_EVERY`] a write is tried again once [`RESUME_FREE_BYTES`] are free;
//!   when it succeeds recording resumes, with a [`GapRecord`] saying what was lost.
//! - `recording.max_total_mb`: the oldest other flights are deleted to stay under the cap;
//!   a flight that alone outgrows it stops recording, as above.
//! - The flight's folder deleted mid-flight (its files' link count drops to 0) is announced
//!   once (log and STATUSTEXT) and recording goes on in a fresh folder, which starts with a
//!   [`GapRecord`] saying so; nothing is written into a recreated half-folder, and
//!   [`Recorder::finish`] names the folders lost.

use super::flight::{self, FlightFiles};
use super::format::{EndRecord, FrameRecord, GapRecord, Record};
use super::keyframe::KeyframeImage;
use super::tlog;
use super::RecordError;
use crate::config::RecordingSettings;
use crate::health::{Level, Notice};
use std::fs::File;
use std::io::{self, BufWriter, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{self, RecvTimeoutError, SyncSender, TrySendError};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

/// How often a stopped recording tries to write again.
pub const RETRY_EVERY: Duration = Duration::from_secs(5);
/// A recording stopped by a full disk resumes only with this much free (so that it does not
/// stop and resume, announcing both, every few seconds on a disk that is still nearly full).
pub const RESUME_FREE_BYTES: u64 = 4 << 20;
/// How often the size cap is checked.
const CAP_CHECK_EVERY: Duration = Duration::from_secs(10);
/// The gap's reason when the flight's folder was deleted.
const FOLDER_DELETED: &str = "flight folder deleted";
/// Longest wait for the queue before the files are synced anyway.
const IDLE_SYNC: Duration = Duration::from_millis(200);

/// Says something to the operator (STATUSTEXT) and the log.
pub type Announce = Box<dyn Fn(Notice) + Send>;

/// What [`Recorder::finish`] tells: the end record of the folder recording ended in.
#[derive(Debug, Clone)]
pub struct Closed {
    /// The end record (of `dir`'s `frames.ndjson`).
    pub end: EndRecord,
    /// The folder recording ended in.
    pub dir: PathBuf,
    /// Earlier folders of this flight that were deleted while it was recorded.
    pub deleted: Vec<PathBuf>,
    /// Frames written over the whole run, deleted folders included.
    pub frames_written_total: u64,
    /// Why recording was stopped at the end, if it was (what came after is not recorded).
    pub stopped: Option<String>,
}

enum Item {
    Frame(Box<FrameRecord>, Option<KeyframeImage>),
    Packet(u64, Vec<u8>),
    Finish(Option<serde_json::Value>),
}

#[derive(Debug, Default)]
struct QueueCounters {
    frames_dropped: AtomicU64,
    packets_dropped: AtomicU64,
}

/// Feeds the recorder (cheap to clone; never blocks).
#[derive(Clone)]
pub struct RecordSink {
    tx: SyncSender<Item>,
    counters: Arc<QueueCounters>,
}

impl std::fmt::Debug for RecordSink {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RecordSink")
            .field("counters", &self.counters)
            .finish_non_exhaustive()
    }
}

impl RecordSink {
    /// Queues a frame record (and its keyframe's pixels); dropped and counted when the queue
    /// is full.
    pub fn frame(&self, record: FrameRecord, keyframe: Option<KeyframeImage>) {
        if let Err(TrySendError::Full(_) | TrySendError::Disconnected(_)) =
            self.tx.try_send(Item::Frame(Box::new(record), keyframe))
        {
            self.counters.frames_dropped.fetch_add(1, Ordering::Relaxed);
        }
    }

    /// Queues a MAVLink packet for `flight.tlog`, stamped now.
    pub fn packet(&self, bytes: &[u8]) {
        if let Err(TrySendError::Full(_) | TrySendError::Disconnected(_)) = self
            .tx
            .try_send(Item::Packet(unix_us_now(), bytes.to_vec()))
        {
            self.counters
                .packets_dropped
                .fetch_add(1, Ordering::Relaxed);
        }
    }
}

/// µs since the UNIX epoch, now.
pub fn unix_us_now() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| u64::try_from(d.as_micros()).unwrap_or(u64::MAX))
}

/// The running recorder of one flight.
pub struct Recorder {
    sink: RecordSink,
    thread: Option<JoinHandle<Closed>>,
    dir: PathBuf,
}

impl std::fmt::Debug for Recorder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Recorder")
            .field("dir", &self.dir)
            .finish_non_exhaustive()
    }
}

impl Recorder {
    /// Creates the flight's folder (its `flight.json` and `config.toml` written) and starts
    /// the writer thread.
    pub fn start(
        settings: &RecordingSettings,
        info: &super::format::FlightInfo,
        config_toml: &str,
        announce: Announce,
    ) -> Result<Self, RecordError> {
        let files = flight::create(&settings.dir, info, config_toml)?;
        let dir = files.dir.clone();
        let (tx, rx) = mpsc::sync_channel(settings.queue);
        let counters = Arc::new(QueueCounters::default());
        let mut writer = Writer {
            files,
            info: info.clone(),
            config_toml: config_toml.to_owned(),
            deleted: Vec::new(),
            frames_written_total: 0,
            settings: settings.clone(),
            counters: counters.clone(),
            announce,
            stopped: None,
            frames_written: 0,
            frames_lost_stopped: 0,
            keyframes: 0,
            dirty: false,
            last_cap_check: None,
        };
        writer.enforce_cap();
        let thread = std::thread::Builder::new()
            .name("recorder".into())
            .spawn(move || writer.run(&rx))
            .map_err(|e| RecordError::Io {
                path: dir.clone(),
                source: e,
            })?;
        Ok(Self {
            sink: RecordSink { tx, counters },
            thread: Some(thread),
            dir,
        })
    }

    /// The flight's folder.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// A handle that feeds the recorder.
    pub fn sink(&self) -> RecordSink {
        self.sink.clone()
    }

    /// Writes what is queued and the end record (with the run's counters), closes the files.
    pub fn finish(mut self, run_stats: Option<serde_json::Value>) -> Option<Closed> {
        // Blocking send: the queue drains on its own; the end record must not be dropped.
        let _ = self.sink.tx.send(Item::Finish(run_stats));
        self.thread.take().and_then(|t| t.join().ok())
    }
}

/// Recording stopped: since when and why, and what was lost meanwhile.
struct Stopped {
    since_unix_us: u64,
    reason: String,
    last_try: Instant,
    frames_lost: u64,
    packets_lost: u64,
    /// Stopped by the size cap (only space freed elsewhere resumes it).
    by_cap: bool,
    /// The folder was deleted: recording resumes in a fresh one.
    folder_deleted: bool,
}

struct Writer {
    files: FlightFiles,
    /// The flight's `flight.json` and `config.toml`, for a fresh folder.
    info: super::format::FlightInfo,
    config_toml: String,
    /// Folders of this flight deleted while it was recorded.
    deleted: Vec<PathBuf>,
    frames_written_total: u64,
    settings: RecordingSettings,
    counters: Arc<QueueCounters>,
    announce: Announce,
    stopped: Option<Stopped>,
    frames_written: u64,
    frames_lost_stopped: u64,
    keyframes: u64,
    dirty: bool,
    last_cap_check: Option<Instant>,
}

impl Writer {
    fn run(mut self, rx: &mpsc::Receiver<Item>) -> Closed {
        let mut run_stats = None;
        loop {
            let item = match rx.try_recv() {
                Ok(i) => Some(i),
                Err(mpsc::TryRecvError::Empty) => {
                    // The queue ran empty: commit what was written.
                    self.sync();
                    match rx.recv_timeout(IDLE_SYNC) {
                        Ok(i) => Some(i),
                        Err(RecvTimeoutError::Timeout) => None,
                        Err(RecvTimeoutError::Disconnected) => break,
                    }
                }
                Err(mpsc::TryRecvError::Disconnected) => break,
            };
            match item {
                Some(Item::Finish(stats)) => {
                    run_stats = stats;
                    break;
                }
                Some(item) => self.write(item),
                None => {}
            }
            if self
                .last_cap_check
                .is_none_or(|t| t.elapsed() >= CAP_CHECK_EVERY)
            {
                self.enforce_cap();
            }
        }
        let end = EndRecord {
            unix_us: unix_us_now(),
            frames_written: self.frames_written,
            frames_dropped_queue: self.counters.frames_dropped.load(Ordering::Relaxed),
            packets_dropped_queue: self.counters.packets_dropped.load(Ordering::Relaxed),
            frames_lost_stopped: self.frames_lost_stopped,
            keyframes: self.keyframes,
            run_stats,
        };
        if self.stopped.is_none() && !self.folder_gone() {
            let line = record_line(&Record::End(end.clone()));
            if let Err(e) = line.and_then(|l| self.append_frames(&l)) {
                tracing::warn!(error = %e, "flight record: end record not written");
            }
        }
        self.sync();
        tracing::info!(
            dir = %self.files.dir.display(),
            frames = end.frames_written,
            dropped = end.frames_dropped_queue,
            lost_while_stopped = end.frames_lost_stopped,
            "flight record closed"
        );
        Closed {
            end,
            dir: self.files.dir.clone(),
            deleted: std::mem::take(&mut self.deleted),
            frames_written_total: self.frames_written_total,
            stopped: self.stopped.as_ref().map(|s| s.reason.clone()),
        }
    }

    /// The flight's files were unlinked (their folder deleted): their link count is 0.
    fn folder_gone(&self) -> bool {
        use std::os::unix::fs::MetadataExt;
        let unlinked = |f: &File| f.metadata().is_ok_and(|m| m.nlink() == 0);
        unlinked(&self.files.frames) || unlinked(self.files.tlog.get_ref())
    }

    /// The folder was deleted: said once, and recording stops until a fresh folder is open
    /// (tried at once, then every [`RETRY_EVERY`]).
    fn folder_deleted(&mut self) {
        tracing::error!(
            dir = %self.files.dir.display(),
            "flight recording folder deleted mid-flight; recording goes on in a fresh folder"
        );
        (self.announce)(Notice::new(
            Level::Warning,
            "mgmot: recording folder deleted; new folder",
        ));
        let now = Instant::now();
        self.stopped = Some(Stopped {
            since_unix_us: unix_us_now(),
            reason: FOLDER_DELETED.to_owned(),
            last_try: now.checked_sub(RETRY_EVERY).unwrap_or(now),
            frames_lost: 0,
            packets_lost: 0,
            by_cap: false,
            folder_deleted: true,
        });
    }

    /// Opens a fresh folder for the rest of the flight (named by now), its counters from 0
    /// but the frames lost in the current gap.
    fn fresh_folder(&mut self) -> Result<(), RecordError> {
        let mut info = self.info.clone();
        info.started_unix_us = unix_us_now();
        info.started_utc = chrono::DateTime::from_timestamp_micros(
            i64::try_from(info.started_unix_us).unwrap_or(i64::MAX),
        )
        .map(|t| t.to_rfc3339_opts(chrono::SecondsFormat::Micros, true))
        .unwrap_or_default();
        let mut avoid = self.deleted.clone();
        avoid.push(self.files.dir.clone());
        let files = flight::create_avoiding(&self.settings.dir, &info, &self.config_toml, &avoid)?;
        tracing::info!(dir = %files.dir.display(), "flight recording continues in a fresh folder");
        let old = std::mem::replace(&mut self.files, files);
        self.deleted.push(old.dir);
        self.frames_written = 0;
        self.keyframes = 0;
        self.frames_lost_stopped = self.stopped.as_ref().map_or(0, |s| s.frames_lost);
        if let Some(s) = &mut self.stopped {
            s.folder_deleted = false;
        }
        Ok(())
    }

    fn write(&mut self, item: Item) {
        let frame = matches!(item, Item::Frame(..));
        if frame && self.stopped.is_none() && self.folder_gone() {
            self.folder_deleted();
        }
        let retrying = self.stopped.is_some();
        if let Some(s) = &mut self.stopped {
            if s.by_cap || s.last_try.elapsed() < RETRY_EVERY {
                self.lost(frame);
                return;
            }
            s.last_try = Instant::now();
            let fresh = s.folder_deleted;
            if fresh || self.folder_gone() {
                if let Err(e) = self.fresh_folder() {
                    tracing::debug!(error = %e, "no fresh flight folder yet");
                    self.lost(frame);
                    return;
                }
            } else if free_bytes(&self.files.dir).is_some_and(|free| free < RESUME_FREE_BYTES) {
                self.lost(frame);
                return;
            }
        }
        let result = match item {
            Item::Frame(record, keyframe) => self.write_frame(*record, keyframe),
            Item::Packet(at, bytes) => self.write_packet(at, &bytes),
            Item::Finish(_) => Ok(()),
        };
        // A retry counts only once its bytes are in the file, not in a buffer.
        let result = if retrying {
            result.and_then(|()| self.flush_tlog())
        } else {
            result
        };
        match result {
            Ok(()) => {
                self.dirty = true;
                if frame {
                    self.frames_written += 1;
                    self.frames_written_total += 1;
                }
                if self.stopped.is_some() {
                    self.resumed();
                }
            }
            Err(e) => {
                self.failed(&e, false);
                self.lost(frame);
            }
        }
    }

    /// A record lost while recording is stopped.
    fn lost(&mut self, frame: bool) {
        if let Some(s) = &mut self.stopped {
            if frame {
                s.frames_lost += 1;
                self.frames_lost_stopped += 1;
            } else {
                s.packets_lost += 1;
            }
        }
    }

    fn write_frame(
        &mut self,
        mut record: FrameRecord,
        keyframe: Option<KeyframeImage>,
    ) -> io::Result<()> {
        if let Some(k) = keyframe {
            let name = format!("{:08}.jpg", record.frame);
            match super::keyframe::write(
                &self.files.dir.join(flight::KEYFRAMES).join(&name),
                k,
                self.settings.keyframe_width_px,
            ) {
                Ok(()) => {
                    record.keyframe = Some(name);
                    self.keyframes += 1;
                }
                Err(e) => tracing::debug!(error = %e, "keyframe not written"),
            }
        }
        let line = record_line(&Record::Frame(Box::new(record)))?;
        // The tlog first: the packets before this frame are on disk when the frame is.
        self.flush_tlog()?;
        self.append_frames(&line)
    }

    fn write_packet(&mut self, unix_us: u64, bytes: &[u8]) -> io::Result<()> {
        tlog::write_entry(&mut self.files.tlog, unix_us, bytes)?;
        self.files.tlog_len_buffered += 8 + bytes.len() as u64;
        Ok(())
    }

    fn flush_tlog(&mut self) -> io::Result<()> {
        self.files.tlog.flush()?;
        self.files.tlog_len = self.files.tlog_len_buffered;
        Ok(())
    }

    fn append_frames(&mut self, line: &[u8]) -> io::Result<()> {
        self.files.frames.write_all(line)?;
        self.files.frames_len += line.len() as u64;
        Ok(())
    }

    fn sync(&mut self) {
        if !self.dirty || self.stopped.is_some() {
            return;
        }
        let r = self
            .flush_tlog()
            .and_then(|()| self.files.frames.sync_data())
            .and_then(|()| self.files.tlog.get_ref().sync_data());
        match r {
            Ok(()) => self.dirty = false,
            Err(e) => self.failed(&e, false),
        }
    }

    /// A write failed: cut the files back to their last whole record and stop.
    fn failed(&mut self, e: &io::Error, by_cap: bool) {
        let _ = self.truncate_to_good();
        if self.stopped.is_some() {
            return;
        }
        let reason = if e.raw_os_error() == Some(libc::ENOSPC) {
            "disk full".to_owned()
        } else {
            e.to_string()
        };
        tracing::error!(
            dir = %self.files.dir.display(), error = %e,
            "flight recording stopped; tracking and MAVLink go on"
        );
        (self.announce)(Notice::new(
            Level::Warning,
            format!("mgmot: recording stopped: {reason}"),
        ));
        self.stopped = Some(Stopped {
            since_unix_us: unix_us_now(),
            reason,
            last_try: Instant::now(),
            frames_lost: 0,
            packets_lost: 0,
            by_cap,
            folder_deleted: false,
        });
    }

    /// Back to the lengths of the last whole records (a failed write may have left a part of
    /// one); a fresh tlog buffer.
    fn truncate_to_good(&mut self) -> io::Result<()> {
        let f = &mut self.files;
        f.frames.set_len(f.frames_len)?;
        f.frames.seek(SeekFrom::Start(f.frames_len))?;
        let tlog_file = f.tlog.get_ref().try_clone()?;
        tlog_file.set_len(f.tlog_len)?;
        let mut file = tlog_file;
        file.seek(SeekFrom::Start(f.tlog_len))?;
        // The old buffer holds bytes that may never have made it: dropped, not written.
        let old = std::mem::replace(&mut f.tlog, BufWriter::new(file));
        let (_file, _unwritten) = old.into_parts();
        f.tlog_len_buffered = f.tlog_len;
        Ok(())
    }

    fn resumed(&mut self) {
        let Some(s) = self.stopped.take() else { return };
        let gap = GapRecord {
            stopped_unix_us: s.since_unix_us,
            resumed_unix_us: unix_us_now(),
            reason: s.reason.clone(),
            frames_lost: s.frames_lost,
            packets_lost: s.packets_lost,
        };
        if let Ok(line) = record_line(&Record::Gap(gap)) {
            let _ = self.append_frames(&line);
        }
        // A warning, as the stop was: the record has a hole.
        tracing::warn!(
            frames_lost = s.frames_lost,
            packets_lost = s.packets_lost,
            "flight recording resumed"
        );
        if s.reason == FOLDER_DELETED {
            // The operator was told when it happened, new folder included.
            return;
        }
        (self.announce)(Notice::new(
            Level::Notice,
            format!("mgmot: recording resumed, {} frames lost", s.frames_lost),
        ));
    }

    /// Deletes the oldest other flights to stay under the cap; stops recording when this
    /// flight alone is over it.
    fn enforce_cap(&mut self) {
        self.last_cap_check = Some(Instant::now());
        let Some(cap) = self.settings.max_total_bytes else {
            return;
        };
        let own = self.files.frames_len + self.files.tlog_len + self.keyframes * 50_000;
        match flight::enforce_cap(&self.settings.dir, &self.files.dir, own, cap) {
            Ok(deleted) => {
                for d in deleted {
                    tracing::info!(flight = %d.display(), "old flight deleted (recording.max_total_mb)");
                }
            }
            Err(e) => tracing::warn!(error = %e, "recording.max_total_mb: old flights not deleted"),
        }
        if own > cap && self.stopped.is_none() {
            let e = io::Error::other(format!(
                "this flight reached recording.max_total_mb ({} MB)",
                cap >> 20
            ));
            self.failed(&e, true);
        }
    }
}

/// Free bytes for an unprivileged writer on the file system of `dir` (`None`: unknown).
fn free_bytes(dir: &Path) -> Option<u64> {
    use std::os::unix::ffi::OsStrExt;
    let path = std::ffi::CString::new(dir.as_os_str().as_bytes()).ok()?;
    // SAFETY: an all-zero statvfs is a valid value for the call to overwrite.
    let mut st: libc::statvfs = unsafe { std::mem::zeroed() };
    // SAFETY: `path` is a NUL-terminated string and `st` a valid, writable statvfs.
    let rc = unsafe { libc::statvfs(path.as_ptr(), &mut st) };
    // The field types differ between targets.
    #[allow(clippy::unnecessary_cast, clippy::useless_conversion)]
    (rc == 0).then(|| u64::from(st.f_bavail as u64).saturating_mul(st.f_frsize as u64))
}

/// One record as a line (JSON and a newline).
fn record_line(r: &Record) -> io::Result<Vec<u8>> {
    let mut line = serde_json::to_vec(r).map_err(io::Error::other)?;
    line.push(b'\n');
    Ok(line)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::record::format::{DetectorIdentity, FlightInfo, FORMAT, VERSION};
    use crate::record::Flight;
    use std::sync::Mutex;

    fn settings(dir: &Path, queue: usize) -> RecordingSettings {
        RecordingSettings {
            dir: dir.to_owned(),
            max_total_bytes: None,
            keyframe_every: None,
            keyframe_width_px: 64,
            queue,
        }
    }

    fn info() -> FlightInfo {
        FlightInfo {
            format: FORMAT.into(),
            version: VERSION,
            mgmot_version: "test".into(),
            started_utc: String::new(),
            started_unix_us: unix_us_now(),
            system_id: 1,
            component_id: 191,
            detector: DetectorIdentity {
                kind: "replay".into(),
                file: "dets.json".into(),
                sha256: String::new(),
                bytes: 0,
            },
            tile_detector: None,
            config_file: "config.toml".into(),
        }
    }

    fn frame(n: u64) -> FrameRecord {
        FrameRecord {
            time_s: n as f64 / 30.0,
            processed_unix_us: unix_us_now(),
            no_pose: Some("test".into()),
            ..FrameRecord::empty(n, 64, 48)
        }
    }

    #[test]
    fn a_queue_faster_than_the_disk_drops_and_counts_records_and_never_blocks() {
        let root = tempfile::tempdir().unwrap();
        let said = Arc::new(Mutex::new(Vec::new()));
        let s = said.clone();
        let rec = Recorder::start(
            &settings(root.path(), 16),
            &info(),
            "",
            Box::new(move |n| s.lock().unwrap().push(n.text)),
        )
        .unwrap();
        let sink = rec.sink();
        let started = Instant::now();
        let heartbeat = [
            0xFD, 9, 0, 0, 0, 1, 191, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1, 2,
        ];
        for n in 0..20_000 {
            sink.packet(&heartbeat);
            if n % 10 == 0 {
                sink.frame(frame(n / 10), None);
            }
        }
        // 22,000 records queued in far less than the disk could take one by one.
        assert!(started.elapsed() < Duration::from_secs(2));
        let dir = rec.dir().to_owned();
        let end = rec.finish(None).unwrap().end;
        assert_eq!(end.frames_written + end.frames_dropped_queue, 2_000);
        assert!(end.packets_dropped_queue > 0, "{end:?}");
        let flight = Flight::load(&dir).unwrap();
        assert_eq!(flight.frames.len() as u64, end.frames_written);
        assert_eq!(flight.end, Some(end.clone()));
        let (packets, clean) = flight.tlog().unwrap();
        assert!(clean);
        assert_eq!(packets.len() as u64 + end.packets_dropped_queue, 20_000);
        assert!(said.lock().unwrap().is_empty(), "nothing to announce");
    }

    #[test]
    fn a_flight_over_the_cap_stops_recording_and_says_so_once() {
        let root = tempfile::tempdir().unwrap();
        let said = Arc::new(Mutex::new(Vec::new()));
        let s = said.clone();
        let mut settings = settings(root.path(), 100_000);
        settings.max_total_bytes = Some(200_000);
        let rec = Recorder::start(
            &settings,
            &info(),
            "",
            Box::new(move |n| s.lock().unwrap().push(n.text)),
        )
        .unwrap();
        let sink = rec.sink();
        let big = vec![0xFDu8; 280];
        // About 1.5 MB of packets over the 10 s cap check: the flight outgrows the cap.
        for _ in 0..110 {
            for _ in 0..50 {
                let mut p = big.clone();
                p[1] = 255;
                p[2] = 0;
                sink.packet(&p[..267]);
            }
            std::thread::sleep(Duration::from_millis(100));
        }
        let dir = rec.dir().to_owned();
        rec.finish(None).unwrap();
        let said = said.lock().unwrap().clone();
        assert_eq!(said.len(), 1, "{said:?}");
        assert!(said[0].contains("recording.max_total_mb"), "{said:?}");
        let (packets, clean) = Flight::load(&dir).unwrap().tlog().unwrap();
        assert!(clean);
        // 5,500 sent over 11 s; the cap is checked every 10 s.
        assert!(
            packets.len() < 5_400,
            "{} packets: recording went on",
            packets.len()
        );
    }

    /// Issue 39 item 10: the flight's folder deleted mid-flight is said once (log and
    /// STATUSTEXT); no keyframe recreates the deleted folder, and recording goes on in a fresh
    /// folder that starts with a gap record saying why.
    #[test]
    fn a_folder_deleted_mid_flight_is_said_once_and_recording_goes_on_in_a_fresh_one() {
        let root = tempfile::tempdir().unwrap();
        let said = Arc::new(Mutex::new(Vec::new()));
        let s = said.clone();
        let rec = Recorder::start(
            &settings(root.path(), 1_000),
            &info(),
            "",
            Box::new(move |n| s.lock().unwrap().push(n.text)),
        )
        .unwrap();
        let sink = rec.sink();
        let image = || KeyframeImage {
            width_px: 16,
            height_px: 8,
            rgb: vec![128; 16 * 8 * 3],
        };
        for n in 0..20 {
            sink.frame(frame(n), (n % 5 == 0).then(image));
            std::thread::sleep(Duration::from_millis(10));
        }
        std::thread::sleep(Duration::from_millis(300));
        let first = rec.dir().to_owned();
        std::fs::remove_dir_all(&first).unwrap();
        for n in 20..60 {
            sink.frame(frame(n), (n % 5 == 0).then(image));
            std::thread::sleep(Duration::from_millis(10));
        }
        let closed = rec.finish(None).unwrap();
        assert_eq!(closed.deleted, std::slice::from_ref(&first));
        assert_eq!(closed.stopped, None);
        assert!(!first.exists(), "the deleted folder was recreated");
        let said = said.lock().unwrap().clone();
        assert_eq!(said.len(), 1, "{said:?}");
        assert!(said[0].contains("folder deleted"), "{said:?}");
        let flights = flight::list(root.path());
        assert_eq!(flights.len(), 1, "{flights:?}");
        let flight = Flight::load(&flights[0]).unwrap();
        assert_eq!(flight.gaps.len(), 1, "{:?}", flight.gaps);
        assert!(
            flight.gaps[0].reason.contains("deleted"),
            "{:?}",
            flight.gaps
        );
        assert!(!flight.frames.is_empty());
        assert!(flight.frames.iter().all(|f| f.frame >= 20));
        let end = flight.end.as_ref().expect("end record");
        assert_eq!(end.frames_written, flight.frames.len() as u64);
        assert!(end.keyframes > 0);
        let (_, clean) = flight.tlog().unwrap();
        assert!(clean);
    }
}
