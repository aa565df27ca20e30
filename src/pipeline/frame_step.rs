//! One frame's journey, top to bottom: [`FrameStep::process`] takes a frame from the
//! newest-frame slot, runs the detector, asks telemetry for the camera pose at exposure,
//! geolocates the boxes and builds the tracker's input (`mgmot_core::frame`), steps the
//! tracker, publishes the due track reports and the operator-selected track's status, and
//! records each stage's latency.

use super::camera_fov::CameraFovStep;
use super::capture::Delivered;
use super::cot_step::CotStep;
use super::detect_stage::DetectStage;
use super::heartbeat::announce;
use super::latency::{Latency, LatencyReport, Stage, LOG_INTERVAL};
use super::operator_link::OperatorLink;
use super::recording::FrameRecording;
use super::service::ServiceNotifier;
use super::shutdown::Shutdown;
use super::slot::{SlotReader, Taken};
use super::stats::RunStats;
use super::telemetry::{FramePose, TelemetryState};
use crate::camera::Frame;
use crate::config::Settings;
use crate::digest::{Digest, DigestSettings};
use crate::frame::{geo_fix, ClockJump, FrameClock, GeoFix, GeoSettings, InputBuilder};
use crate::geo::Geolocator;
use crate::health::{Condition, ConditionReport, Level, Notice};
use crate::logging::LogThrottle;
use crate::mavlink::Outputs;
use crate::report::TrackReport;
use crate::telemetry::{AutopilotTimeUs, CompanionTimeUs};
use crate::track::{Detection, FrameInput, FrameOutput, TrackOutput, Tracker};
use nalgebra::Vector3;
use std::collections::HashMap;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// How long the frame step waits for a frame before answering operator requests anyway.
const TAKE_TIMEOUT: Duration = Duration::from_millis(100);

/// Everything one frame's processing needs, and what it remembers from frame to frame.
pub(super) struct FrameStep {
    detector: Box<dyn DetectStage>,
    detector_health: ConditionReport,
    tracker: Tracker,
    telemetry: Arc<Mutex<TelemetryState>>,
    /// The tracker's inputs: the local frame (set at the first pose), the previous frame's
    /// pose and the tracker's clock.
    inputs: InputBuilder,
    /// "No pose" is logged once per spell, and spells at most every [`LOG_EVERY`].
    no_pose_reported: bool,
    no_pose_log: LogThrottle,
    /// Jumps of the frame source's clock are logged at most every [`LOG_EVERY`].
    clock_jump_log: LogThrottle,
    publisher: TrackPublisher,
    /// Cursor-on-Target events, when `[outputs.cot]` is on.
    cot: Option<CotStep>,
    /// CAMERA_FOV_STATUS, unless `outputs.camera_fov_hz` is 0.
    camera_fov: Option<CameraFovStep>,
    operator: OperatorLink,
    outputs: Outputs,
    latency: Arc<Mutex<Latency>>,
    stats: RunStats,
    first_taken: Option<Instant>,
    /// systemd's READY / WATCHDOG / STATUS notifications (a no-op outside systemd).
    service: ServiceNotifier,
    /// The flight record, when `[recording]` is on.
    recording: Option<FrameRecording>,
    /// Frames the slot dropped so far (for the record).
    frames_dropped: u64,
}

/// The stage boundaries of one frame, for the latency histograms.
struct Marks {
    started: Instant,
    taken_at: CompanionTimeUs,
    delivered: CompanionTimeUs,
    detected: Instant,
    geolocated: Instant,
    tracked: Instant,
}

impl FrameStep {
    /// A step with its detector, tracker, the shared telemetry, the outputs and the flight
    /// record (if on).
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        settings: &Settings,
        detector: Box<dyn DetectStage>,
        tracker: Tracker,
        telemetry: Arc<Mutex<TelemetryState>>,
        operator: OperatorLink,
        outputs: Outputs,
        latency: Arc<Mutex<Latency>>,
        recording: Option<FrameRecording>,
    ) -> Self {
        Self {
            detector,
            detector_health: ConditionReport::new(Condition::Detector),
            tracker,
            telemetry,
            inputs: InputBuilder::new(geo_settings(settings)),
            no_pose_reported: false,
            no_pose_log: LogThrottle::default(),
            clock_jump_log: LogThrottle::default(),
            publisher: TrackPublisher::new(
                settings.outputs.track_every,
                settings.outputs.radio_digest,
                outputs.clone(),
            ),
            cot: CotStep::start(settings),
            camera_fov: CameraFovStep::new(settings.outputs.camera_fov_every),
            operator,
            outputs,
            latency,
            stats: RunStats::default(),
            first_taken: None,
            service: ServiceNotifier::from_env(settings.telemetry.lost_after),
            recording,
            frames_dropped: 0,
        }
    }

    /// Processes frames until `shutdown` fires or the source ends; returns the counters.
    pub fn run(mut self, reader: &SlotReader<Delivered>, shutdown: &Shutdown) -> RunStats {
        let mut window = Window::new();
        while !shutdown.is_shutdown() {
            window.log_if_due(&self.latency, &self.stats, reader.dropped());
            match reader.take(TAKE_TIMEOUT) {
                Taken::Value(d) => {
                    self.frames_dropped = reader.dropped();
                    self.process(d);
                }
                // No frame: requests are still answered, against the last frame's tracks.
                Taken::Timeout => self.operator.answer_requests(),
                Taken::Closed => break,
            }
            self.service.tick(&self.telemetry);
        }
        self.service.stopping();
        self.stats.frames_dropped = reader.dropped();
        self.stats.cot = self.cot.take().map(CotStep::finish);
        if let Ok(t) = self.telemetry.lock() {
            self.stats.telemetry = t.counters();
        }
        self.stats
    }

    /// One frame, from the slot to the outputs.
    fn process(&mut self, Delivered { frame, at }: Delivered) {
        let started = Instant::now();
        let taken_at = crate::clock::now();
        self.first_taken.get_or_insert(started);
        let (index, captured, size) = (
            frame.index,
            frame.captured,
            (frame.width_px, frame.height_px),
        );
        let keyframe = self.recording.as_mut().and_then(|r| r.keyframe(&frame));
        let Some(detections) = self.detect(frame) else {
            return;
        };
        let detected = Instant::now();
        let Ok(pose) = self.telemetry.lock().map(|t| t.at_capture(captured)) else {
            return;
        };
        self.report_missing_pose(index, &pose);
        let (input, camera_ned) = self.tracker_input(index, size, detections, &pose, at);
        let geolocated = Instant::now();
        let output = match self.tracker.step(&input) {
            Ok(o) => o,
            Err(e) => {
                self.stats.tracker_errors += 1;
                tracing::warn!(error = %e, frame = index, "tracker rejected a frame");
                return;
            }
        };
        let tracked = Instant::now();
        self.stats.frames_processed += 1;
        self.service.frame_processed(output.tracks.len());
        // The next frame's motion compensation starts from the frame the tracker just took.
        self.inputs.taken(index);
        self.publish(&output, input.time_s, size, &pose, at, camera_ned);
        if let Some(r) = &mut self.recording {
            let geolocator = self.inputs.geolocator();
            let fix = |t: &TrackOutput| fix_of(geolocator, &pose, t);
            r.record(&input, &output, &pose, &fix, self.frames_dropped, keyframe);
        }
        self.record_latency(
            &pose,
            Marks {
                started,
                taken_at,
                delivered: at,
                detected,
                geolocated,
                tracked,
            },
        );
        tracing::debug!(
            frame = index,
            tracks = output.tracks.len(),
            elapsed_us = started.elapsed().as_micros() as u64,
            "frame processed"
        );
    }

    /// The detector on one frame; its failures and recoveries are announced on change.
    fn detect(&mut self, frame: Frame) -> Option<Vec<Detection>> {
        match self.detector.detect(frame) {
            Ok(d) => {
                if let Some(n) = self.detector_health.observe(true, None) {
                    tracing::info!(
                        failed_frames = self.stats.detector_errors,
                        "detector ok again"
                    );
                    self.outputs.notice(&n);
                }
                Some(d)
            }
            Err(e) => {
                self.stats.detector_errors += 1;
                match self.detector_health.observe(false, Some(&e.to_string())) {
                    Some(n) => announce(&self.outputs, &n),
                    None => tracing::debug!(error = %e, "detector"),
                }
                None
            }
        }
    }

    /// Counts frames without a pose and logs the first of each spell.
    fn report_missing_pose(&mut self, index: u64, pose: &FramePose) {
        match &pose.meta {
            Ok(_) => self.no_pose_reported = false,
            Err(why) => {
                self.stats.frames_without_pose += 1;
                if !self.no_pose_reported {
                    self.no_pose_reported = true;
                    if let Some(suppressed) = self.no_pose_log.allow() {
                        tracing::warn!(
                            frame = index,
                            %why,
                            suppressed,
                            "no pose: tracking in the image only"
                        );
                    }
                }
            }
        }
    }

    /// Geolocates the detections (when the frame has a pose) and builds the tracker's input;
    /// also returns the camera's position in the local frame (for the operator's range). The
    /// tracker's clock follows the exposure times and bridges their jumps (an autopilot reboot,
    /// a restarted frame source) with the companion's monotonic clock at delivery.
    fn tracker_input(
        &mut self,
        index: u64,
        size: (u32, u32),
        detections: Vec<Detection>,
        pose: &FramePose,
        delivered: CompanionTimeUs,
    ) -> (FrameInput, Option<Vector3<f64>>) {
        let time = FrameClock {
            source_s: frame_time_s(index, pose.frame_time),
            reference_s: Some(delivered.0 as f64 / 1e6),
        };
        let (input, camera_ned, jump) =
            self.inputs
                .build(index, time, size, detections, pose.meta.as_ref().ok());
        if let Some(jump) = jump {
            self.report_clock_jump(index, &jump);
        }
        (input, camera_ned)
    }

    /// Counts a bridged jump of the frame source's clock and logs it (throttled).
    fn report_clock_jump(&mut self, index: u64, jump: &ClockJump) {
        self.stats.clock_jumps += 1;
        if let Some(suppressed) = self.clock_jump_log.allow() {
            tracing::warn!(
                frame = index,
                from_s = format_args!("{:.3}", jump.previous_source_s),
                to_s = format_args!("{:.3}", jump.source_s),
                tracker_s = format_args!("{:.3}", jump.tracker_s),
                suppressed,
                "the frame clock jumped (autopilot reboot, restarted camera or clock mapping found); the tracker's clock continues"
            );
        }
    }

    /// The due track reports and the operator's selected track.
    fn publish(
        &mut self,
        output: &FrameOutput,
        time_s: f64,
        size: (u32, u32),
        pose: &FramePose,
        delivered: CompanionTimeUs,
        camera_ned: Option<Vector3<f64>>,
    ) {
        let geolocator = self.inputs.geolocator();
        let fix = |t: &TrackOutput| fix_of(geolocator, pose, t);
        let timing = FrameTiming {
            captured: pose.captured_at,
            delivered,
            latency: self.latency.clone(),
        };
        self.stats.track_messages += self.publisher.publish(
            output,
            size,
            pose.frame_time.unwrap_or(AutopilotTimeUs(0)),
            tracker_time_us(time_s),
            &fix,
            &timing,
        );
        if let Some(fov) = &mut self.camera_fov {
            fov.frame(
                &self.outputs,
                tracker_time_us(time_s),
                pose,
                geolocator,
                size,
            );
        }
        if let Some(cot) = &mut self.cot {
            cot.frame(
                output,
                size,
                tracker_time_us(time_s),
                pose,
                delivered,
                geolocator,
                &fix,
            );
        }
        self.operator
            .after_step(output, &self.tracker, size, |t: &TrackOutput| {
                let f = fix(t);
                let range_m = match (camera_ned, f, t.world) {
                    (Some(camera), Some(_), Some(ws)) => {
                        Some((Vector3::new(ws.pos_ne_m.x, ws.pos_ne_m.y, 0.0) - camera).norm())
                    }
                    _ => None,
                };
                (f, range_m)
            });
    }

    fn record_latency(&mut self, pose: &FramePose, m: Marks) {
        let done = Instant::now();
        if let Ok(mut l) = self.latency.lock() {
            if let Some(c) = pose.captured_at {
                l.record_between_us(Stage::FrameAge, c.0, m.taken_at.0);
            }
            l.record_between_us(Stage::SlotWait, m.delivered.0, m.taken_at.0);
            l.record(Stage::Detect, m.detected - m.started);
            if let Some(t) = self.detector.last_timings() {
                l.record(Stage::DetectInference, t.inference);
            }
            l.record(Stage::PoseGeolocate, m.geolocated - m.detected);
            l.record(Stage::Track, m.tracked - m.geolocated);
            l.record(Stage::Encode, done - m.tracked);
            l.record(Stage::Processing, done - m.started);
        }
        self.stats.active_us = self
            .first_taken
            .map_or(0, |f| (done - f).as_micros() as u64);
    }
}

/// Where a track is on the map, as reported: without a pose this frame, the outputs say
/// "geolocation invalid" rather than repeat an old position.
fn fix_of(geolocator: Option<&Geolocator>, pose: &FramePose, t: &TrackOutput) -> Option<GeoFix> {
    let g = geolocator.filter(|_| pose.meta.is_ok())?;
    Some(geo_fix(g.reference(), t.world.as_ref()?, pose.water_amsl_m))
}

/// The geolocation settings of the tracker's inputs, from the configuration.
pub(crate) fn geo_settings(settings: &Settings) -> GeoSettings {
    GeoSettings {
        hfov_deg: settings.camera.hfov_deg,
        noise: settings.geolocation.noise,
        max_range_m: settings.geolocation.max_range_m,
        motion_smoothing: settings.tracker.baseline.cmc_smoothing,
    }
}

/// A time on the tracker's clock (s) in µs: what report rates and the digest's ages are
/// measured on, as it never goes back or restarts (not even when the autopilot reboots).
fn tracker_time_us(time_s: f64) -> u64 {
    (time_s.max(0.0) * 1e6) as u64
}

/// A frame's source time (s): its exposure on the autopilot clock, or, before the clock
/// mapping is known, its index at 30 fps. The tracker's clock is made from it.
fn frame_time_s(index: u64, frame_time: Option<AutopilotTimeUs>) -> f64 {
    frame_time.map_or(index as f64 / 30.0, |t| t.0 as f64 / 1e6)
}

/// Companion times of a frame, for the latency histograms of its track messages.
struct FrameTiming {
    /// The capture (exposure) time, when it maps onto the companion clock.
    captured: Option<CompanionTimeUs>,
    /// When the frame source delivered the frame to the capture thread.
    delivered: CompanionTimeUs,
    latency: Arc<Mutex<Latency>>,
}

/// Rate-limits track reports per track (`outputs.track_rate_hz`); a track that was just
/// re-identified is reported at once, with the id it had. The reports also feed the
/// STATUSTEXT digest for a ground station behind the autopilot's radio
/// (`outputs.radio_digest_every_s`).
struct TrackPublisher {
    period_us: u64,
    last_sent: HashMap<u64, u64>,
    digest: Option<Digest>,
    outputs: Outputs,
}

impl TrackPublisher {
    fn new(period: Duration, digest: Option<DigestSettings>, outputs: Outputs) -> Self {
        Self {
            period_us: u64::try_from(period.as_micros()).unwrap_or(u64::MAX),
            last_sent: HashMap::new(),
            digest: digest.map(Digest::new),
            outputs,
        }
    }

    /// Queues the due reports of one frame; returns how many. `stamp` is the exposure on the
    /// autopilot clock (the messages' time), `now_us` the tracker's clock (the rates').
    #[allow(clippy::too_many_arguments)]
    fn publish(
        &mut self,
        output: &FrameOutput,
        size: (u32, u32),
        stamp: AutopilotTimeUs,
        now_us: u64,
        fix: &dyn Fn(&TrackOutput) -> Option<GeoFix>,
        timing: &FrameTiming,
    ) -> u64 {
        // Forget the send times of tracks the tracker no longer reports (a flight sees
        // thousands of ids; a track that comes back is simply due at once).
        if self.last_sent.len() > 2 * output.tracks.len() + 64 {
            self.last_sent
                .retain(|id, _| output.tracks.iter().any(|t| t.id == *id));
        }
        let merged_from: HashMap<u64, u64> = output
            .merges
            .iter()
            .map(|m| (m.merged_into_id, m.new_id))
            .collect();
        let mut sent = 0;
        for t in &output.tracks {
            let due = self
                .last_sent
                .get(&t.id)
                .is_none_or(|&at| now_us.saturating_sub(at) >= self.period_us)
                || merged_from.contains_key(&t.id);
            if !due {
                continue;
            }
            self.last_sent.insert(t.id, now_us);
            let report = TrackReport::new(stamp, t, size, merged_from.get(&t.id).copied(), fix(t));
            self.outputs.track(&report, latency_on_sent(timing));
            sent += 1;
            if let Some(found) = self
                .digest
                .as_mut()
                .and_then(|d| d.observe(&report, now_us))
            {
                self.outputs.notice(&Notice::new(Level::Notice, found));
            }
        }
        if let Some(d) = self.digest.as_mut() {
            for text in d.due(now_us) {
                self.outputs.notice(&Notice::new(Level::Info, text));
            }
        }
        sent
    }
}

/// When a track message reaches the socket: capture -> socket (end to end), delivery -> socket
/// and queued -> socket are recorded.
fn latency_on_sent(t: &FrameTiming) -> crate::mavlink::link::OnSent {
    let (captured, delivered, queued) = (t.captured, t.delivered, crate::clock::now());
    let latency = t.latency.clone();
    Box::new(move |now: CompanionTimeUs| {
        if let Ok(mut l) = latency.lock() {
            l.record_between_us(Stage::Send, queued.0, now.0);
            l.record_between_us(Stage::DeliveredToSocket, delivered.0, now.0);
            if let Some(c) = captured {
                l.record_between_us(Stage::EndToEnd, c.0, now.0);
            }
        }
    })
}

/// The periodic log line: frame rate, drops and latency over the last [`LOG_INTERVAL`].
struct Window {
    started: Instant,
    processed: u64,
    dropped: u64,
}

impl Window {
    fn new() -> Self {
        Self {
            started: Instant::now(),
            processed: 0,
            dropped: 0,
        }
    }

    fn log_if_due(&mut self, latency: &Mutex<Latency>, stats: &RunStats, dropped: u64) {
        let elapsed = self.started.elapsed();
        if elapsed < LOG_INTERVAL {
            return;
        }
        let Ok(mut l) = latency.lock() else { return };
        let report: LatencyReport = l.take_window();
        drop(l);
        let fps = (stats.frames_processed - self.processed) as f64 / elapsed.as_secs_f64();
        tracing::info!(
            fps = format_args!("{fps:.1}"),
            frames_dropped = dropped - self.dropped,
            detector_errors = stats.detector_errors,
            latency = %report.to_log_line(),
            "pipeline latency, last {:.0} s (p50/p95/p99/max)",
            elapsed.as_secs_f64()
        );
        *self = Self {
            started: Instant::now(),
            processed: stats.frames_processed,
            dropped,
        };
    }
}
