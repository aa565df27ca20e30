//! `pipeline::run`: the wiring. It starts the MAVLink link (its domain ends: [`Inbox`] and
//! [`Outputs`]), two tasks in a [`JoinSet`] (link events -> telemetry and operator requests;
//! heartbeat and telemetry watch), the capture thread and the frame-step thread
//! ([`FrameStep`]), and stops them all with one [`Shutdown`], draining the tasks and closing
//! the link last so that what is queued goes out.

use super::capture::Delivered;
use super::detect_stage::{DetectStage, DetectStageError, OnnxStage, ReplayStage};
use super::error::PipelineError;
use super::frame_step::FrameStep;
use super::heartbeat::{announce, heartbeat_and_telemetry_watch};
use super::latency::Latency;
use super::operator_link::OperatorLink;
use super::recording::{self, FrameRecording};
use super::shutdown::{shutdown_signal, Shutdown, Trigger};
use super::slot::newest_slot;
use super::stats::RunStats;
use super::telemetry::TelemetryState;
use crate::camera::CameraStatus;
use crate::config::{DetectorSettings, MavlinkSettings, OnnxSettings, Settings};
use crate::health::{Condition, ConditionReport, Level, Notice};
use crate::mavlink::{self as mavlink_edge, Inbox, LinkInput, LinkSettings, OperatorRequest};
use crate::mavlink::{Outputs, SigningSettings};
use crate::track::Tracker;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, OnceLock};
use std::time::{Duration, Instant};
use tokio::task::JoinSet;

/// Operator requests waiting for the frame step: a GCS sends one at a time and retries
/// unanswered ones, so a few are plenty; beyond that the request is answered "try again"
/// (TEMPORARILY_REJECTED).
const REQUEST_QUEUE: usize = 8;

/// How long shutdown waits for the capture thread.
const CAPTURE_JOIN_TIMEOUT: Duration = Duration::from_secs(1);

/// Runs until `shutdown` fires or the frame source ends; returns the counters.
/// `effective_config` is the configuration as TOML, for the flight record (`[recording]`).
pub async fn run(
    mut settings: Settings,
    effective_config: &str,
    shutdown: Shutdown,
) -> Result<RunStats, PipelineError> {
    // The detector and the tracker are set up first: they fail before any thread or socket
    // exists. What can still fail later (the link, the frame source) is set up after the
    // recorder and the link; each of those failures stops what was already started (the
    // recorder is finished, the link's tasks and the capture thread are stopped) before the
    // error is returned.
    // The ONNX detector's (backend, model) pair is chosen first (timed, under `auto`); the
    // settings then name the chosen model, for the flight record.
    let mut selection = None;
    let detector: Box<dyn DetectStage> = match &settings.detector {
        DetectorSettings::Replay {
            detections,
            first_image_id,
        } => Box::new(ReplayStage::load(detections, *first_image_id)?),
        DetectorSettings::Onnx(onnx) => {
            let (chosen, how) = onnx.select().map_err(DetectStageError::Model)?;
            let stage = OnnxStage::load(chosen.clone())?;
            settings.detector = DetectorSettings::Onnx(OnnxSettings::fixed(chosen));
            selection = Some(how);
            Box::new(stage)
        }
    };
    let tracker = Tracker::new(settings.tracker.clone())
        .map_err(|e| PipelineError::Tracker(e.to_string()))?;
    let announce_to = Arc::new(OnceLock::new());
    let (recorder, recording_off) = match settings
        .recording
        .as_ref()
        .map(|r| recording::start(&settings, r, effective_config, announce_to.clone()))
    {
        Some(Ok(r)) => (Some(r), None),
        Some(Err(notice)) => (None, Some(notice)),
        None => (None, None),
    };
    let mut link_settings = link_settings(&settings.mavlink);
    link_settings.tap = recorder.as_ref().map(|r| recording::packet_tap(r.sink()));
    let (link, inbox, outputs) =
        match mavlink_edge::bridge::start(link_settings, settings.outputs.target_absolute) {
            Ok(l) => l,
            Err(e) => {
                if let Some(r) = recorder {
                    r.finish(None);
                }
                return Err(e.into());
            }
        };
    let _ = announce_to.set(outputs.clone());
    // The tasks and threads below stop on `stop`: the caller's shutdown, or the source's end.
    let (stop_trigger, stop) = shutdown_signal();
    let stop_trigger = Arc::new(stop_trigger);
    let forward = forward_shutdown(shutdown, stop_trigger.clone());

    let telemetry = Arc::new(Mutex::new(TelemetryState::new(&settings.telemetry)));
    let (request_tx, request_rx) = std::sync::mpsc::sync_channel(REQUEST_QUEUE);
    let mut tasks = JoinSet::new();
    tasks.spawn(receive(
        inbox,
        telemetry.clone(),
        request_tx,
        outputs.clone(),
        stop.clone(),
        recording_off,
    ));
    tasks.spawn(heartbeat_and_telemetry_watch(
        outputs.clone(),
        telemetry.clone(),
        stop.clone(),
        settings.outputs.heartbeat_every,
        settings.telemetry.lost_after,
    ));

    let (writer, reader) = newest_slot::<Delivered>();
    let captured = Arc::new(AtomicU64::new(0));
    let mut camera = ConditionReport::new(Condition::Camera);
    let camera_outputs = outputs.clone();
    let capture = super::capture::start(
        &settings.frames,
        writer,
        stop.clone(),
        captured.clone(),
        move |status| match status {
            CameraStatus::Denied => announce(
                &camera_outputs,
                &Notice::new(Level::Warning, "mgmot: camera: permission denied"),
            ),
            CameraStatus::Lost | CameraStatus::Back => {
                let ok = matches!(status, CameraStatus::Back);
                if let Some(n) = camera.observe(ok, None) {
                    announce(&camera_outputs, &n);
                }
            }
        },
    );
    let started = capture.and_then(|capture| {
        let latency = Arc::new(Mutex::new(Latency::new()));
        let operator = OperatorLink::new(
            request_rx,
            settings.outputs.track_point_radius,
            settings.outputs.camera_tracking_every,
            outputs.clone(),
        );
        let frame_recording = recorder
            .as_ref()
            .zip(settings.recording.as_ref())
            .map(|(r, s)| FrameRecording::new(r.sink(), s));
        let step = FrameStep::new(
            &settings,
            detector,
            tracker,
            telemetry,
            operator,
            outputs.clone(),
            latency.clone(),
            frame_recording,
        );
        let stop = stop.clone();
        std::thread::Builder::new()
            .name("frame-step".into())
            .spawn(move || step.run(&reader, &stop))
            .map(|t| (capture, t, latency))
            .map_err(|_| PipelineError::Panicked("frame-step"))
    });
    let result = match started {
        Ok((capture, frame_step, latency)) => {
            let stats = tokio::task::spawn_blocking(move || frame_step.join()).await;
            stop_trigger.fire();
            join_capture(capture).await;
            // A panicked frame step is an error, but the link and the recorder below are
            // still closed.
            stats
                .ok()
                .and_then(Result::ok)
                .ok_or(PipelineError::Panicked("frame-step"))
                .map(|mut stats| {
                    stats.detector = selection;
                    stats.frames_captured = captured.load(Ordering::Relaxed);
                    if let Ok(l) = latency.lock() {
                        stats.latency = l.total();
                    }
                    stats
                })
        }
        Err(e) => {
            stop_trigger.fire();
            Err(e)
        }
    };
    // Drain the tasks (they end on `stop`), then close the link, which sends what is queued.
    while tasks.join_next().await.is_some() {}
    forward.abort();
    let dropped = outputs.dropped();
    drop(outputs);
    drop(announce_to);
    let link_stats = link.close().await;
    tracing::info!(?link_stats, "MAVLink link closed");
    let result = result.map(|mut stats| {
        stats.messages_dropped = dropped;
        stats.link = link_stats;
        stats
    });
    // The record closes last, with what the link sent while closing and the run's counters.
    if let Some(r) = recorder {
        let counters = result
            .as_ref()
            .ok()
            .and_then(|s| serde_json::to_value(s).ok());
        let dir = r.dir().to_owned();
        let closed = tokio::task::spawn_blocking(move || r.finish(counters))
            .await
            .ok()
            .flatten();
        match closed {
            Some(c) if c.deleted.is_empty() && c.stopped.is_none() => tracing::info!(
                dir = %c.dir.display(), frames = c.end.frames_written,
                lost_while_stopped = c.end.frames_lost_stopped, "flight recorded"
            ),
            Some(c) => tracing::warn!(
                dir = %c.dir.display(), frames = c.end.frames_written,
                frames_in_deleted_folders = c.frames_written_total - c.end.frames_written,
                deleted = ?c.deleted, stopped = ?c.stopped,
                lost_while_stopped = c.end.frames_lost_stopped,
                "flight recorded in part"
            ),
            None => tracing::warn!(dir = %dir.display(), "flight record not closed"),
        }
    }
    let stats = result?;
    tracing::info!(
        latency = %stats.latency.to_log_line(),
        "latency over the whole run (p50/p95/p99/max)"
    );
    tracing::info!(?stats, "pipeline stopped");
    Ok(stats)
}

/// Fires `stop` when `shutdown` does (the caller's signal); abort the returned handle once
/// `stop` has fired anyway.
fn forward_shutdown(mut shutdown: Shutdown, stop: Arc<Trigger>) -> tokio::task::AbortHandle {
    tokio::spawn(async move {
        shutdown.recv().await;
        stop.fire();
    })
    .abort_handle()
}

/// The link's receive task: telemetry updates into the shared state, operator requests onto
/// the frame step's queue (answered "try again" when it is full). `pending` is said to the
/// operator at the first input, when the link has its peer (sent earlier, on `udpin`, it would
/// go nowhere).
async fn receive(
    mut inbox: Inbox,
    telemetry: Arc<Mutex<TelemetryState>>,
    requests: std::sync::mpsc::SyncSender<OperatorRequest>,
    outputs: Outputs,
    mut stop: Shutdown,
    mut pending: Option<Notice>,
) {
    loop {
        let input = tokio::select! {
            _ = stop.recv() => break,
            i = inbox.recv() => i,
        };
        if input.is_some() {
            if let Some(n) = pending.take() {
                outputs.notice(&n);
            }
        }
        match input {
            None => break,
            Some(LinkInput::Telemetry(u)) => match telemetry.lock() {
                Ok(mut t) => t.apply(u),
                Err(_) => break,
            },
            Some(LinkInput::Operator(r)) => {
                if requests.try_send(r).is_err() {
                    outputs.command_busy(r.reply);
                }
            }
        }
    }
}

/// Waits for the capture thread. It notices shutdown between frames; one blocked in a read of
/// a frozen source gives up at its read timeout. Shutdown never waits on it for longer than
/// [`CAPTURE_JOIN_TIMEOUT`]: the thread is left to end with the process. (Polled, not joined
/// on a blocking task: the runtime waits for its blocking tasks when it is dropped, which
/// would bring the wait back.)
async fn join_capture(capture: std::thread::JoinHandle<()>) {
    let deadline = Instant::now() + CAPTURE_JOIN_TIMEOUT;
    while !capture.is_finished() && Instant::now() < deadline {
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    if capture.is_finished() {
        let _ = capture.join();
    } else {
        tracing::warn!("the capture thread is blocked in a read; not waiting for it");
    }
}

/// The link's settings from the configuration.
fn link_settings(m: &MavlinkSettings) -> LinkSettings {
    let streams = if m.stream_rate_hz > 0.0 {
        mavlink_edge::STREAMS
            .iter()
            .map(|&(id, rate)| (id, rate.unwrap_or(m.stream_rate_hz)))
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
        signing: m.signing.as_ref().map(|s| SigningSettings {
            key: s.key,
            link_id: s.link_id,
            state_file: Some(s.state_file.clone()),
        }),
        streams,
        timesync_hz: m.timesync_every.map_or(0.0, |d| 1.0 / d.as_secs_f64()),
        accept_unsigned_telemetry: m
            .signing
            .as_ref()
            .is_none_or(|s| s.accept_unsigned_telemetry),
        tap: None,
    }
}
