//! `pipeline::run`: the MAVLink link (tokio tasks), the capture thread, the inference thread
//! (detector -> pose -> geolocation -> tracker) and the track outputs, stopped by one
//! [`Shutdown`].

use super::capture::Delivered;
use super::latency::{Latency, LatencyReport, Stage, LOG_INTERVAL};
use super::operator::{self, Candidate, CommandResult, Outcome, Selection};
use super::{newest_slot, Detector, OnnxDetector, ReplayDetector, Shutdown, SlotReader, Taken};
use crate::camera::{CameraStatus, CaptureTime};
use crate::config::{Config, DetectorConfig};
use crate::geo::{CameraModel, FrameGeometry, FrameMetadata, Geodetic, Geolocator};
use crate::mavlink::{
    self as link,
    dialect::{MavCmd, MavMessage},
    AckResult, CameraCommand, Condition, ConditionReport, Incoming, Link, LinkEvent, LinkSender,
    LinkSettings, LinkStats, Received, Severity, SigningSettings, TrackGeo, TrackReport,
    TrackingMode, TrackingStatus,
};
use crate::telemetry::{AutopilotTimeUs, ClockSync, CompanionTimeUs, PoseBuffer};
use crate::track::{Detection, FrameInput, TrackOutput, TrackState, Tracker, WorldObservation};
use nalgebra::{UnitQuaternion, Vector3};
use std::collections::HashMap;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// Operator commands waiting for the inference thread: a GCS sends one at a time and retries
/// unanswered ones, so a few are plenty; beyond that the command is answered
/// TEMPORARILY_REJECTED.
const COMMAND_QUEUE: usize = 8;

/// How long shutdown waits for the capture thread.
const CAPTURE_JOIN_TIMEOUT: Duration = Duration::from_secs(1);

/// Why the runtime stopped with an error.
#[derive(Debug, thiserror::Error)]
pub enum PipelineError {
    /// The MAVLink link could not be set up (bad connection string, unusable signing state).
    #[error("MAVLink link: {0}")]
    Link(#[from] link::link::LinkError),
    /// The frame source cannot be used (an image directory that is missing or empty).
    #[error(transparent)]
    Frames(#[from] crate::camera::CameraError),
    /// The detector could not be set up.
    #[error(transparent)]
    Detector(#[from] super::DetectorError),
    /// The tracker parameters are invalid.
    #[error("tracker: {0}")]
    Tracker(String),
    /// A configuration this version cannot run yet.
    #[error("{0} is not implemented in this version")]
    Unsupported(&'static str),
    /// A thread of the pipeline panicked.
    #[error("the {0} thread panicked")]
    Panicked(&'static str),
}

/// Counters and latency percentiles of one run, logged and returned at the end (`mgmot run
/// --stats-json` writes them).
#[derive(Debug, Default, Clone, PartialEq, Eq, serde::Serialize)]
pub struct RunStats {
    /// Frames the source delivered.
    pub frames_captured: u64,
    /// Frames overwritten in the newest-frame slot before inference took them.
    pub frames_dropped: u64,
    /// Frames through detector and tracker.
    pub frames_processed: u64,
    /// Frames processed without a usable pose (tracked in the image only).
    pub frames_without_pose: u64,
    /// MGMOT_TRACK messages queued.
    pub track_messages: u64,
    /// Outgoing messages dropped because the link queue was full.
    pub messages_dropped: u64,
    /// Frames the detector failed on (reported by STATUSTEXT when it starts and stops failing).
    pub detector_errors: u64,
    /// Frames the tracker rejected.
    pub tracker_errors: u64,
    /// From the first frame taken by inference to the end of the last one processed (µs):
    /// `frames_processed / active_us` is the sustained rate.
    pub active_us: u64,
    /// Per-stage latency percentiles over the whole run (see [`super::latency`]).
    pub latency: LatencyReport,
    /// The MAVLink link's counters (frames, refusals, reconnects, stream requests).
    pub link: LinkStats,
}

/// Telemetry shared between the link's receive task and the inference thread.
#[derive(Debug)]
struct Telemetry {
    poses: PoseBuffer,
    clock: ClockSync,
    home: Option<Geodetic>,
    /// Companion time of the latest position fix (for "telemetry lost").
    last_position_at: Option<CompanionTimeUs>,
}

/// The companion's monotonic clock: `CLOCK_MONOTONIC`, the clock of V4L2 buffer timestamps,
/// so frames and telemetry arrival times compare directly.
#[derive(Debug, Clone, Copy)]
struct Monotonic;

impl Monotonic {
    fn now(&self) -> CompanionTimeUs {
        CompanionTimeUs::now()
    }
}

/// Companion times of a track message's frame, for the latency histograms.
#[derive(Debug, Clone, Copy)]
struct FrameTiming {
    /// The capture (exposure) time, when it maps onto the companion clock.
    captured: Option<CompanionTimeUs>,
    /// When the frame source delivered the frame to the capture thread.
    delivered: CompanionTimeUs,
    /// When the message was queued for the link.
    queued: CompanionTimeUs,
}

/// Queues messages for the link; track messages record their latency when they are sent.
#[derive(Debug, Clone)]
struct Outbox {
    link: LinkSender,
    latency: Arc<Mutex<Latency>>,
}

impl Outbox {
    fn send(&self, m: MavMessage) {
        self.link.send(m);
    }

    /// Queues a track message with its frame's times: when it reaches the socket, capture ->
    /// socket (end to end), delivery -> socket and queued -> socket are recorded.
    fn send_track(&self, m: MavMessage, t: FrameTiming) {
        let latency = self.latency.clone();
        self.link.send_then(
            m,
            Box::new(move |now: CompanionTimeUs| {
                if let Ok(mut l) = latency.lock() {
                    l.record_between_us(Stage::Send, t.queued.0, now.0);
                    l.record_between_us(Stage::DeliveredToSocket, t.delivered.0, now.0);
                    if let Some(c) = t.captured {
                        l.record_between_us(Stage::EndToEnd, c.0, now.0);
                    }
                }
            }),
        );
    }
}

/// The link's settings from the configuration.
fn link_settings(config: &Config) -> LinkSettings {
    let m = &config.mavlink;
    let streams = if m.stream_rate_hz > 0.0 {
        link::STREAMS
            .iter()
            .map(|&(id, rate)| (id, if rate >= 1.0 { m.stream_rate_hz } else { rate }))
            .collect()
    } else {
        Vec::new()
    };
    LinkSettings {
        connection: m.connection.clone(),
        system_id: m.system_id,
        component_id: m.component_id,
        autopilot_component_id: m.autopilot_component_id,
        udp_peer: m.udp_peer,
        signing: m.signing.as_ref().and_then(|s| {
            s.key().map(|key| SigningSettings {
                key,
                link_id: s.link_id,
                state_file: Some(s.state_file.clone()),
            })
        }),
        streams,
        timesync_hz: m.timesync_hz,
        accept_unsigned_telemetry: m
            .signing
            .as_ref()
            .is_none_or(|s| s.accept_unsigned_telemetry),
    }
}

/// Runs until `shutdown` fires or the frame source ends; returns the counters.
pub async fn run(config: Config, shutdown: Shutdown) -> Result<RunStats, PipelineError> {
    let clock = Monotonic;
    let commands_need_signature = config.mavlink.signing.is_some();
    let max_age_us = (config.telemetry.max_pose_age_ms * 1000.0) as u64;
    let mut poses = PoseBuffer::new(max_age_us);
    if let Some(pitch) = config.telemetry.fixed_mount_pitch_deg {
        poses = poses.with_fixed_mount(UnitQuaternion::from_euler_angles(
            0.0,
            pitch.to_radians(),
            0.0,
        ));
    }
    let telemetry = Arc::new(Mutex::new(Telemetry {
        poses,
        clock: ClockSync::new(),
        home: None,
        last_position_at: None,
    }));
    let latency = Arc::new(Mutex::new(Latency::new()));
    let (link_handle, link_sender, mut events) = Link::start(link_settings(&config))?;
    let outbox = Outbox {
        link: link_sender,
        latency: latency.clone(),
    };

    let (command_tx, command_rx) = std::sync::mpsc::sync_channel::<OperatorCommand>(COMMAND_QUEUE);
    // The latest frame's size, for CAMERA_INFORMATION (0: no frame yet).
    let frame_size = Arc::new(FrameSize::default());
    // Receive task: the link's events -> telemetry, clock, operator commands.
    let receiver = {
        let frame_size = frame_size.clone();
        let telemetry = telemetry.clone();
        let outbox = outbox.clone();
        let mut shutdown = shutdown.clone();
        let (our_system, our_component) = (config.mavlink.system_id, config.mavlink.component_id);
        tokio::spawn(async move {
            loop {
                let event = tokio::select! {
                    _ = shutdown.recv() => break,
                    e = events.recv() => e,
                };
                let Some(event) = event else { break };
                let Ok(mut t) = telemetry.lock() else { break };
                let Received {
                    message: msg,
                    system_id: from_system,
                    component_id: from_component,
                    signed,
                    at: now,
                } = match event {
                    LinkEvent::TimeSync {
                        sent,
                        autopilot,
                        at,
                    } => {
                        t.clock.observe_timesync(sent, autopilot, at);
                        continue;
                    }
                    LinkEvent::Message(r) => *r,
                };
                if let MavMessage::MOUNT_STATUS(_) = &msg {
                    if let Some(ap) = t.clock.to_autopilot(now) {
                        if let Some(g) = link::decode_mount_status(&msg, ap) {
                            t.poses.push_gimbal(g);
                        }
                    }
                    continue;
                }
                match link::decode(&msg, from_component, our_system, our_component) {
                    Some(Incoming::Position(p)) => {
                        t.clock.observe_arrival(p.time, now);
                        t.poses.push_position(p);
                        t.last_position_at = Some(now);
                    }
                    Some(Incoming::Attitude(a)) => {
                        t.clock.observe_arrival(a.time, now);
                        t.poses.push_attitude(a);
                    }
                    Some(Incoming::Gimbal(g)) => t.poses.push_gimbal(g),
                    Some(Incoming::Home(h)) => t.home = Some(h),
                    Some(c) if c.is_command() => {
                        let ack = |mav_cmd, result| {
                            link::command_ack(mav_cmd, result, from_system, from_component)
                        };
                        match c {
                            _ if commands_need_signature && !signed => {
                                tracing::warn!(
                                    from_system,
                                    from_component,
                                    "unsigned command refused (signing is on)"
                                );
                                if let Some(mav_cmd) = c.mav_cmd() {
                                    outbox.send(ack(mav_cmd, AckResult::Denied));
                                }
                            }
                            Incoming::Command { command, mav_cmd } => {
                                let queued = command_tx.try_send(OperatorCommand {
                                    request: operator_request(command),
                                    mav_cmd,
                                    from: (from_system, from_component),
                                });
                                if queued.is_err() {
                                    outbox.send(ack(mav_cmd, AckResult::TemporarilyRejected));
                                }
                            }
                            Incoming::CameraInformationRequest => {
                                outbox.send(ack(
                                    MavCmd::MAV_CMD_REQUEST_MESSAGE,
                                    AckResult::Accepted,
                                ));
                                let boot_ms = u32::try_from(now.0 / 1000).unwrap_or(u32::MAX);
                                outbox.send(link::camera_information(boot_ms, frame_size.get()));
                            }
                            Incoming::UnsupportedCommand { mav_cmd } => {
                                outbox.send(ack(mav_cmd, AckResult::Unsupported));
                            }
                            _ => {}
                        }
                    }
                    Some(_) | None => {}
                }
            }
        })
    };

    // Heartbeat and telemetry-health task. The heartbeat has an interval of its own (the
    // configured rate, validated to a sane range), the telemetry check runs twice a second.
    let health = {
        let outbox = outbox.clone();
        let telemetry = telemetry.clone();
        let mut shutdown = shutdown.clone();
        let heartbeat_every = Duration::from_secs_f64(1.0 / config.outputs.heartbeat_hz);
        let lost_after_us = (config.telemetry.lost_after_ms * 1000.0) as u64;
        tokio::spawn(async move {
            let mut heartbeat = tokio::time::interval(heartbeat_every);
            heartbeat.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
            let mut check = tokio::time::interval(Duration::from_millis(500));
            let mut telemetry_ok: Option<bool> = None;
            // The companion clock is CLOCK_MONOTONIC (time since boot): start-up is now, not 0.
            let started = clock.now();
            loop {
                tokio::select! {
                    _ = shutdown.recv() => break,
                    _ = heartbeat.tick() => {
                        outbox.send(link::heartbeat());
                        continue;
                    }
                    _ = check.tick() => {}
                }
                let now = clock.now();
                // Before the first fix, telemetry has had since start-up to arrive: it is not
                // "lost" (and not announced) until `lost_after_ms` have passed without it.
                let ok = telemetry
                    .lock()
                    .ok()
                    .map(|t| t.last_position_at.unwrap_or(started))
                    .is_some_and(|at| now.0.saturating_sub(at.0) <= lost_after_us);
                if telemetry_ok != Some(ok) {
                    let (severity, text) = if ok {
                        (Severity::Info, "mgmot: telemetry ok")
                    } else {
                        (
                            Severity::Warning,
                            "mgmot: no telemetry, geolocation invalid",
                        )
                    };
                    // The first "ok" is not news; every change after it is.
                    if telemetry_ok.is_some() || !ok {
                        tracing::warn!(telemetry_ok = ok, "{text}");
                        outbox.send(link::statustext(severity, text));
                    }
                    telemetry_ok = Some(ok);
                }
            }
        })
    };

    // Capture and inference threads.
    let detector: Box<dyn Detector> = match &config.detector {
        DetectorConfig::Replay {
            detections,
            first_image_id,
        } => Box::new(ReplayDetector::load(detections, *first_image_id)?),
        DetectorConfig::Onnx(onnx) => Box::new(OnnxDetector::load(onnx.settings())?),
    };
    let tracker =
        Tracker::new(config.tracker.clone()).map_err(|e| PipelineError::Tracker(e.to_string()))?;
    let (writer, reader) = newest_slot::<Delivered>();
    let captured = Arc::new(AtomicU64::new(0));
    let capture = {
        let outbox = outbox.clone();
        super::capture::start(
            &super::capture::frame_settings(&config.frames)?,
            writer,
            shutdown.clone(),
            captured.clone(),
            move |status| {
                outbox.send(match status {
                    CameraStatus::Lost => link::statustext(Severity::Warning, "mgmot: camera lost"),
                    CameraStatus::Back => link::statustext(Severity::Info, "mgmot: camera back"),
                })
            },
        )?
    };
    let inference = {
        let shutdown = shutdown.clone();
        let telemetry = telemetry.clone();
        let outbox = outbox.clone();
        let cfg = config.clone();
        let latency = latency.clone();
        let operator = OperatorLink::new(&config, command_rx, frame_size);
        std::thread::Builder::new()
            .name("inference".into())
            .spawn(move || {
                infer(
                    &cfg, clock, reader, detector, tracker, &telemetry, &outbox, &latency,
                    &shutdown, operator,
                )
            })
            .map_err(|_| PipelineError::Panicked("inference"))?
    };

    // Wait for the inference thread (it ends when shutdown fires or the source ends).
    let mut stats = tokio::task::spawn_blocking(move || inference.join())
        .await
        .map_err(|_| PipelineError::Panicked("inference"))?
        .map_err(|_| PipelineError::Panicked("inference"))?;
    // The capture thread notices shutdown between frames; one blocked in a read of a frozen
    // source gives up at its read timeout. Shutdown never waits on it for longer than this:
    // the thread is left to end with the process.
    // (Polled, not joined on a blocking task: the runtime waits for its blocking tasks when
    // it is dropped, which would bring the wait back.)
    let deadline = Instant::now() + CAPTURE_JOIN_TIMEOUT;
    while !capture.is_finished() && Instant::now() < deadline {
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    if capture.is_finished() {
        let _ = capture.join();
    } else {
        tracing::warn!("the capture thread is blocked in a read; not waiting for it");
    }
    stats.frames_captured = captured.load(Ordering::Relaxed);
    // Stop the tasks (they watch the shutdown signal; the source ending also ends them), then
    // close the link, which sends what is queued.
    health.abort();
    receiver.abort();
    let _ = health.await;
    let _ = receiver.await;
    stats.messages_dropped = outbox.link.dropped();
    drop(outbox);
    let link_stats = link_handle.close().await;
    tracing::info!(?link_stats, "MAVLink link closed");
    stats.link = link_stats;
    if let Ok(l) = latency.lock() {
        stats.latency = l.total();
    }
    tracing::info!(
        latency = %stats.latency.to_log_line(),
        "latency over the whole run (p50/p95/p99/max)"
    );
    tracing::info!(?stats, "pipeline stopped");
    Ok(stats)
}

/// The inference loop: newest frame -> detections -> pose -> world observations -> tracker ->
/// rate-limited track messages and the operator-selected track's status, timing each stage
/// (logged every [`LOG_INTERVAL`]).
#[allow(clippy::too_many_arguments)]
fn infer(
    config: &Config,
    clock: Monotonic,
    reader: SlotReader<Delivered>,
    mut detector: Box<dyn Detector>,
    mut tracker: Tracker,
    telemetry: &Mutex<Telemetry>,
    outbox: &Outbox,
    latency: &Mutex<Latency>,
    shutdown: &Shutdown,
    mut operator: OperatorLink,
) -> RunStats {
    let mut stats = RunStats::default();
    let mut first_taken: Option<Instant> = None;
    let mut last_log = Instant::now();
    let mut window_start = (0u64, 0u64);
    let latency_us = (config.telemetry.camera_latency_ms * 1000.0) as u64;
    let track_period_us = (1e6 / config.outputs.track_rate_hz) as u64;
    let mut last_sent: HashMap<u64, u64> = HashMap::new();
    let mut geolocator: Option<Geolocator> = None;
    let mut previous_meta: Option<FrameMetadata> = None;
    let mut last_frame_index: Option<u64> = None;
    let mut last_time_s: Option<f64> = None;
    let mut no_pose_reported = false;
    let mut detector_health = ConditionReport::new(Condition::Detector);
    loop {
        if shutdown.is_shutdown() {
            break;
        }
        if last_log.elapsed() >= LOG_INTERVAL {
            log_window(
                latency,
                &stats,
                &mut window_start,
                &reader,
                last_log.elapsed(),
            );
            last_log = Instant::now();
        }
        let Delivered {
            frame,
            at: delivered,
        } = match reader.take(Duration::from_millis(100)) {
            Taken::Value(d) => d,
            Taken::Timeout => {
                // No frame: commands are still answered, against the last frame's tracks.
                operator.answer_commands(outbox);
                continue;
            }
            Taken::Closed => break,
        };
        let started = Instant::now();
        let taken_at = clock.now();
        first_taken.get_or_insert(started);
        let (index, captured, width_px, height_px) =
            (frame.index, frame.captured, frame.width_px, frame.height_px);
        let detections = match detector.detect(frame) {
            Ok(d) => {
                if let Some(m) = detector_health.observe(true, None) {
                    tracing::info!(failed_frames = stats.detector_errors, "detector ok again");
                    outbox.send(m);
                }
                d
            }
            Err(e) => {
                stats.detector_errors += 1;
                if let Some(m) = detector_health.observe(false, Some(&e.to_string())) {
                    tracing::warn!(error = %e, "detector failing");
                    outbox.send(m);
                } else {
                    tracing::debug!(error = %e, "detector");
                }
                continue;
            }
        };
        let detected = Instant::now();
        // The pose at the exposure time, on the autopilot clock.
        let (frame_time, captured_at, pose, water_amsl_m) = {
            let Ok(t) = telemetry.lock() else { break };
            let captured_at = match captured {
                CaptureTime::Autopilot(a) => t.clock.to_companion(a),
                CaptureTime::Companion(c) => Some(c),
            };
            let frame_time = match captured {
                CaptureTime::Autopilot(a) => Some(a),
                CaptureTime::Companion(c) => t.clock.to_autopilot(c),
            }
            .map(|a| a.saturating_sub_us(latency_us));
            let pose = frame_time.map(|ft| t.poses.pose_at(ft));
            let water = config
                .telemetry
                .water_level_amsl_m
                .or(t.home.map(|h| h.alt_m));
            (frame_time, captured_at, pose, water)
        };
        let meta = match (&pose, water_amsl_m) {
            (Some(Ok(p)), Some(water)) => Some(FrameMetadata {
                position: p.position,
                height_above_sea_m: p.position.alt_m - water,
                camera_attitude: p.camera_attitude,
            }),
            _ => None,
        };
        if meta.is_none() {
            stats.frames_without_pose += 1;
            if !no_pose_reported {
                let why = match &pose {
                    Some(Err(e)) => e.to_string(),
                    Some(Ok(_)) => "water level unknown (no HOME_POSITION)".into(),
                    None => "autopilot clock not known yet".into(),
                };
                tracing::warn!(frame = index, %why, "no pose: tracking in the image only");
                no_pose_reported = true;
            }
        } else {
            no_pose_reported = false;
        }
        if geolocator.is_none() {
            if let Some(m) = &meta {
                match CameraModel::from_hfov(width_px, height_px, config.camera.hfov_deg) {
                    Ok(camera) => {
                        geolocator = Some(
                            Geolocator::new(m.nadir_on_water(), camera, config.geolocation.noise)
                                .with_max_range_m(config.geolocation.max_range_m),
                        )
                    }
                    Err(e) => tracing::warn!(error = %e, "camera model"),
                }
            }
        }
        let geometry: Option<FrameGeometry<'_>> = match (&geolocator, &meta) {
            (Some(g), Some(m)) => g.frame(m).ok(),
            _ => None,
        };
        let previous_geometry = match (&geolocator, &previous_meta, last_frame_index) {
            (Some(g), Some(m), Some(prev)) if prev + 1 == index => g.frame(m).ok(),
            _ => None,
        };
        let detections: Vec<Detection> = detections
            .into_iter()
            .map(|d| Detection {
                world: geometry
                    .as_ref()
                    .and_then(|g| WorldObservation::of_box(g, &d.bbox)),
                ..d
            })
            .collect();
        let image_motion = match (&previous_geometry, &geometry) {
            (Some(p), Some(c)) => p.image_motion_to(c).ok(),
            _ => None,
        };
        // The tracker's clock only goes forward: a source that restarted (its clock from 0
        // again, a new session) continues just after the last frame's time.
        let raw_time_s = frame_time.map_or(index as f64 / 30.0, |t| t.0 as f64 / 1e6);
        let time_s = match last_time_s {
            Some(last) if raw_time_s < last => last + 1e-3,
            _ => raw_time_s,
        };
        last_time_s = Some(time_s);
        let input = FrameInput {
            frame_index: index,
            time_s,
            image_size_px: (width_px, height_px),
            detections,
            image_motion,
        };
        let geolocated = Instant::now();
        let output = match tracker.step(&input) {
            Ok(o) => o,
            Err(e) => {
                stats.tracker_errors += 1;
                tracing::warn!(error = %e, frame = index, "tracker rejected a frame");
                continue;
            }
        };
        let tracked = Instant::now();
        stats.frames_processed += 1;
        // Forget the send times of tracks the tracker no longer reports (a flight sees
        // thousands of ids; a track that comes back is simply due at once).
        if last_sent.len() > 2 * output.tracks.len() + 64 {
            last_sent.retain(|id, _| output.tracks.iter().any(|t| t.id == *id));
        }
        let merged_from: HashMap<u64, u64> = output
            .merges
            .iter()
            .map(|m| (m.merged_into_id, m.new_id))
            .collect();
        let stamp = frame_time.unwrap_or(AutopilotTimeUs(0));
        let (w, h) = (f64::from(width_px), f64::from(height_px));
        for t in &output.tracks {
            let due = last_sent
                .get(&t.id)
                .is_none_or(|&at| stamp.0.saturating_sub(at) >= track_period_us)
                || merged_from.contains_key(&t.id);
            if !due {
                continue;
            }
            last_sent.insert(t.id, stamp.0);
            let geo = track_geo(t, geolocator.as_ref(), meta.is_some(), water_amsl_m);
            let report = TrackReport {
                time: stamp,
                track_id: t.id,
                merged_from_id: merged_from.get(&t.id).copied(),
                class_id: t.class_id,
                confidence: t.score,
                bbox_norm: [
                    (t.bbox.x / w) as f32,
                    (t.bbox.y / h) as f32,
                    (t.bbox.w / w) as f32,
                    (t.bbox.h / h) as f32,
                ],
                tracked: t.detection_index.is_some(),
                geo,
            };
            outbox.send_track(
                link::mgmot_track(&report),
                FrameTiming {
                    captured: captured_at,
                    delivered,
                    queued: clock.now(),
                },
            );
            stats.track_messages += 1;
            if config.outputs.target_absolute {
                if let Some(m) = link::target_absolute(&report) {
                    outbox.send(m);
                }
            }
        }
        let has_pose = meta.is_some();
        operator.after_step(
            &output,
            &tracker,
            (width_px, height_px),
            |t: &TrackOutput| {
                let geo = track_geo(t, geolocator.as_ref(), has_pose, water_amsl_m);
                let range_m = match (&geometry, &geo) {
                    (Some(g), Some(_)) => t.world.map(|ws| {
                        let camera = g.pose_in_reference().position_ned;
                        (Vector3::new(ws.pos_ne_m.x, ws.pos_ne_m.y, 0.0) - camera).norm()
                    }),
                    _ => None,
                };
                (geo, range_m)
            },
            outbox,
        );
        let done = Instant::now();
        if let Ok(mut l) = latency.lock() {
            if let Some(c) = captured_at {
                l.record_between_us(Stage::FrameAge, c.0, taken_at.0);
            }
            l.record_between_us(Stage::SlotWait, delivered.0, taken_at.0);
            l.record(Stage::Detect, detected - started);
            if let Some(t) = detector.last_timings() {
                l.record(Stage::DetectInference, t.inference);
            }
            l.record(Stage::PoseGeolocate, geolocated - detected);
            l.record(Stage::Track, tracked - geolocated);
            l.record(Stage::Encode, done - tracked);
            l.record(Stage::Processing, done - started);
        }
        stats.active_us = first_taken.map_or(0, |f| (done - f).as_micros() as u64);
        tracing::debug!(
            frame = index,
            tracks = output.tracks.len(),
            elapsed_us = (done - started).as_micros() as u64,
            "frame processed"
        );
        previous_meta = meta;
        last_frame_index = Some(index);
    }
    stats.frames_dropped = reader.dropped();
    stats
}

/// Logs the latency histograms of the interval just ended with the frame rate over it.
fn log_window(
    latency: &Mutex<Latency>,
    stats: &RunStats,
    window_start: &mut (u64, u64),
    reader: &SlotReader<Delivered>,
    elapsed: Duration,
) {
    let Ok(mut l) = latency.lock() else { return };
    let report = l.take_window();
    drop(l);
    let (processed, dropped) = (stats.frames_processed, reader.dropped());
    let fps = (processed - window_start.0) as f64 / elapsed.as_secs_f64().max(1e-3);
    tracing::info!(
        fps = format_args!("{fps:.1}"),
        frames_dropped = dropped - window_start.1,
        detector_errors = stats.detector_errors,
        latency = %report.to_log_line(),
        "pipeline latency, last {:.0} s (p50/p95/p99/max)",
        elapsed.as_secs_f64()
    );
    *window_start = (processed, dropped);
}

/// The geolocation of a track for the outputs: its world state on the sea surface (altitude =
/// the water level), only when this frame had a usable pose (`geolocated`); without one the
/// outputs say "geolocation invalid" rather than repeat an old position.
fn track_geo(
    t: &TrackOutput,
    geolocator: Option<&Geolocator>,
    geolocated: bool,
    water_amsl_m: Option<f64>,
) -> Option<TrackGeo> {
    let (g, ws) = (geolocator?, t.world.as_ref()?);
    if !geolocated {
        return None;
    }
    let mut p = g
        .reference()
        .to_geodetic(&Vector3::new(ws.pos_ne_m.x, ws.pos_ne_m.y, 0.0));
    if let Some(water) = water_amsl_m {
        p.alt_m = water;
    }
    Some(TrackGeo {
        position: p,
        vel_n_mps: ws.vel_ne_m_s.x,
        vel_e_mps: ws.vel_ne_m_s.y,
        // DRMS, as geo::Geolocation::h_std_m.
        h_std_m: ws.pos_cov_m2().trace().max(0.0).sqrt(),
    })
}

/// An operator's camera-tracking command on its way from the link to the inference thread.
#[derive(Debug, Clone, Copy)]
struct OperatorCommand {
    /// What is asked.
    request: operator::Request,
    /// The command number, for the COMMAND_ACK.
    mav_cmd: MavCmd,
    /// Sender (system, component): the COMMAND_ACK goes back to it.
    from: (u8, u8),
}

fn operator_request(c: CameraCommand) -> operator::Request {
    match c {
        CameraCommand::TrackPoint { x, y, radius } => operator::Request::Point {
            x: f64::from(x),
            y: f64::from(y),
            radius: Some(f64::from(radius)),
        },
        CameraCommand::TrackRectangle { x0, y0, x1, y1 } => operator::Request::Rectangle {
            x0: f64::from(x0),
            y0: f64::from(y0),
            x1: f64::from(x1),
            y1: f64::from(y1),
        },
        CameraCommand::Stop => operator::Request::Stop,
    }
}

/// The inference thread's side of operator tracking: the command queue, the selection, and
/// the timing of the CAMERA_TRACKING_* status messages.
/// A frame size shared between threads, `(width << 32) | height` (0: none yet).
#[derive(Debug, Default)]
struct FrameSize(AtomicU64);

impl FrameSize {
    fn set(&self, (w, h): (u32, u32)) {
        self.0
            .store((u64::from(w) << 32) | u64::from(h), Ordering::Relaxed);
    }

    fn get(&self) -> Option<(u32, u32)> {
        let v = self.0.load(Ordering::Relaxed);
        (v != 0).then_some(((v >> 32) as u32, v as u32))
    }
}

struct OperatorLink {
    /// Commands from the link's receive task.
    commands: std::sync::mpsc::Receiver<OperatorCommand>,
    /// Which track is selected.
    selection: Selection,
    /// The confirmed tracks of the latest frame: what a command can select.
    candidates: Vec<Candidate>,
    /// The latest frame's size (px); `None` before the first frame.
    image_size_px: Option<(u32, u32)>,
    /// The same, for the receive task's CAMERA_INFORMATION.
    frame_size: Arc<FrameSize>,
    /// Time between status messages of the selected track.
    status_every: Duration,
    /// When status was last sent (`None`: send at the next frame).
    last_status: Option<Instant>,
}

impl OperatorLink {
    fn new(
        config: &Config,
        commands: std::sync::mpsc::Receiver<OperatorCommand>,
        frame_size: Arc<FrameSize>,
    ) -> Self {
        Self {
            commands,
            selection: Selection::new(config.outputs.track_point_radius),
            candidates: Vec::new(),
            image_size_px: None,
            frame_size,
            // Validated > 0; the fallback only keeps an unchecked config from panicking.
            status_every: Duration::try_from_secs_f64(1.0 / config.outputs.camera_tracking_hz)
                .unwrap_or(Duration::from_millis(200)),
            last_status: None,
        }
    }

    /// Answers every queued command against the latest tracks.
    fn answer_commands(&mut self, outbox: &Outbox) {
        while let Ok(c) = self.commands.try_recv() {
            let outcome = self
                .selection
                .command(&c.request, &self.candidates, self.image_size_px);
            let result = match outcome.result() {
                CommandResult::Accepted => AckResult::Accepted,
                CommandResult::Denied => AckResult::Denied,
                CommandResult::Failed => AckResult::Failed,
            };
            tracing::info!(request = ?c.request, ?outcome, "operator command");
            outbox.send(link::command_ack(c.mav_cmd, result, c.from.0, c.from.1));
            match outcome {
                Outcome::Selected { .. } => self.last_status = None,
                Outcome::Stopped { .. } => send_idle_status(outbox),
                Outcome::Refused(_) => {}
            }
        }
    }

    /// After a tracker step: keep the selection on its track (merges, removal), answer the
    /// queued commands against this frame's tracks, and send the selected track's status
    /// when due. `geo` gives a track's geolocation and camera distance.
    fn after_step(
        &mut self,
        output: &crate::track::FrameOutput,
        tracker: &Tracker,
        image_size_px: (u32, u32),
        geo: impl Fn(&TrackOutput) -> (Option<TrackGeo>, Option<f64>),
        outbox: &Outbox,
    ) {
        if self.image_size_px != Some(image_size_px) {
            self.frame_size.set(image_size_px);
        }
        self.image_size_px = Some(image_size_px);
        self.candidates.clear();
        self.candidates
            .extend(output.tracks.iter().map(|t| Candidate {
                id: t.id,
                bbox: t.bbox,
            }));
        if let Some(gone) = self.selection.follow(&output.merges, |id| {
            tracker.live_tracks().any(|t| t.id == id)
        }) {
            tracing::warn!(track = gone, "selected track removed: tracking stopped");
            outbox.send(link::statustext(
                Severity::Warning,
                &format!("mgmot: track {gone} gone, tracking stopped"),
            ));
            send_idle_status(outbox);
        }
        self.answer_commands(outbox);
        let Some(selected) = self.selection.selected() else {
            return;
        };
        if self
            .last_status
            .is_some_and(|at| at.elapsed() < self.status_every)
        {
            return;
        }
        // A confirmed track of this frame, or (lost for now) the tracker's prediction.
        let track = output
            .tracks
            .iter()
            .find(|t| t.id == selected.track_id)
            .copied()
            .or_else(|| tracker.live_tracks().find(|t| t.id == selected.track_id));
        let Some(t) = track else {
            return;
        };
        let (w, h) = (f64::from(image_size_px.0), f64::from(image_size_px.1));
        let (geo_now, range_m) = geo(&t);
        let status = TrackingStatus {
            mode: match selected.mode {
                operator::Mode::Point => TrackingMode::Point,
                operator::Mode::Rectangle => TrackingMode::Rectangle,
            },
            bbox_norm: [
                (t.bbox.x / w) as f32,
                (t.bbox.y / h) as f32,
                (t.bbox.w / w) as f32,
                (t.bbox.h / h) as f32,
            ],
            aspect: (w / h) as f32,
            coasting: t.state != TrackState::Confirmed || t.detection_index.is_none(),
            vel_std_mps: geo_now.and(t.world).map(|ws| {
                let (vn, ve) = (ws.cov[(2, 2)], ws.cov[(3, 3)]);
                ((vn + ve) / 2.0).max(0.0).sqrt()
            }),
            geo: geo_now,
            range_m,
        };
        outbox.send(link::camera_tracking_image_status(Some(&status)));
        outbox.send(link::camera_tracking_geo_status(Some(&status)));
        self.last_status = Some(Instant::now());
    }
}

/// "Not tracking" in both status messages, once, when a selection ends.
fn send_idle_status(outbox: &Outbox) {
    outbox.send(link::camera_tracking_image_status(None));
    outbox.send(link::camera_tracking_geo_status(None));
}
