//! `mgmot-sim run`: the simulated autopilot and camera, in real time or in lockstep with the
//! frame consumer.

use super::frames::FrameSink;
use super::link::{Link, SimClock};
use super::render::TruthWriter;
use super::ScenarioArgs;
use anyhow::Context;
use mgmot_sim::framing::FrameHeader;
use mgmot_sim::monitor::TrackMonitor;
use mgmot_sim::render::Renderer;
use mgmot_sim::telemetry::{Autopilot, Scheduler};
use mgmot_sim::truth::{frame_truth, Optics};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// Arguments of `run`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    scenario: ScenarioArgs,
    /// MAVLink 2 output: udpout:HOST:PORT, udpin:HOST:PORT, tcpin:HOST:PORT,
    /// tcpout:HOST:PORT or serial:DEVICE:BAUD. Unreachable peers are retried every second.
    #[arg(long)]
    mavlink: Option<String>,
    /// Frame output: unix:/path.sock (the sim listens; framing in sim/README.md) or
    /// v4l2:/dev/videoN (a v4l2loopback device; needs the `v4l2` feature).
    #[arg(long)]
    frames: Option<String>,
    /// Run as fast as the frame consumer reads (blocking on it) instead of in real time.
    #[arg(long, conflicts_with = "realtime")]
    lockstep: bool,
    /// Run in real time (the default).
    #[arg(long)]
    realtime: bool,
    /// Lockstep: how long to wait for a frame consumer to (re)connect before giving up.
    #[arg(long, default_value_t = 30.0)]
    wait_consumer_s: f64,
    /// Also write the ground truth of every frame into this folder (as `render` does).
    #[arg(long)]
    truth_out: Option<PathBuf>,
    /// Write the check of mgmot's MGMOT_TRACK messages against the ground truth (geolocation
    /// error, ids per object) to this JSON file at the end. The check itself always runs when
    /// --mavlink is given and is logged every few seconds.
    #[arg(long)]
    track_report: Option<PathBuf>,
}

/// How often the check of mgmot's tracks is logged while messages arrive.
const REPORT_EVERY: Duration = Duration::from_secs(5);

/// Runs the scenario.
pub fn run(args: Args) -> anyhow::Result<()> {
    anyhow::ensure!(
        args.wait_consumer_s.is_finite() && args.wait_consumer_s >= 0.0,
        "--wait-consumer-s must be >= 0"
    );
    let world = Arc::new(args.scenario.world()?);
    let optics = Optics::new(&world.scenario).context("camera or origin invalid")?;
    let renderer = Renderer::new(&world.scenario, world.seed);
    let autopilot = Autopilot::new(&world).context("origin invalid")?;
    let scheduler = Arc::new(Mutex::new(Scheduler::new(&world)));
    let clock = Arc::new(SimClock::default());
    let monitor = Arc::new(Mutex::new(
        TrackMonitor::new(&world).context("origin invalid")?,
    ));
    let link = match &args.mavlink {
        Some(addr) => Some(Link::start(
            addr.clone(),
            world.clone(),
            scheduler.clone(),
            clock.clone(),
            args.lockstep,
            Some(monitor.clone()),
        )?),
        None => None,
    };
    let mut last_report = (Instant::now(), 0u64);
    let (w, h) = (
        world.scenario.camera.width_px,
        world.scenario.camera.height_px,
    );
    let mut sink = match &args.frames {
        Some(spec) => Some(FrameSink::open(spec, w, h)?),
        None => None,
    };
    let mut truth = match &args.truth_out {
        Some(dir) => Some(TruthWriter::create(dir, &world)?),
        None => None,
    };
    // Ctrl-C or SIGTERM ends the run like its end: the truth and the track report are
    // written for what ran.
    let interrupted = Arc::new(AtomicBool::new(false));
    for signal in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        signal_hook::flag::register(signal, interrupted.clone())
            .context("installing the signal handler")?;
    }
    let lockstep = args.lockstep;
    let wait_for = Duration::from_secs_f64(args.wait_consumer_s);
    let n_frames = world.scenario.frame_count();
    let latency_s = world.scenario.camera.capture_latency_ms / 1000.0;
    let end_s = world.scenario.duration_s;
    let mut rgb = vec![0u8; renderer.frame_bytes()];
    let (mut frames_sent, mut frames_dropped) = (0u64, 0u64);
    let mut k = 0u64;
    let start = Instant::now();
    if !lockstep {
        clock.start_realtime(start);
    }
    tracing::info!(
        scenario = %world.scenario.name,
        seed = world.seed,
        frames = n_frames,
        mode = if lockstep { "lockstep" } else { "realtime" },
        "simulation started"
    );
    loop {
        if interrupted.load(Ordering::Relaxed) {
            tracing::warn!(frames = k, "interrupted: stopping early");
            break;
        }
        let next_frame = (k < n_frames).then(|| world.frame_time_s(k) + latency_s);
        let next_tel = scheduler
            .lock()
            .ok()
            .and_then(|s| s.next_due_s())
            .filter(|t| *t <= end_s);
        let t = match (next_frame, next_tel) {
            (Some(a), Some(b)) => a.min(b),
            (Some(a), None) => a,
            (None, Some(b)) => b,
            (None, None) => break,
        };
        if !lockstep {
            let due = start + Duration::from_secs_f64(t.max(0.0));
            let now = Instant::now();
            if due > now {
                std::thread::sleep(due - now);
            }
        }
        clock.set(t);
        let due = scheduler.lock().map(|mut s| s.due(t)).unwrap_or_default();
        if let Some(link) = &link {
            for (ts, stream) in due {
                if !world.in_dropout(ts) {
                    link.send(autopilot.message(stream, ts));
                }
            }
        }
        if next_frame.is_some_and(|f| f <= t) {
            let t_cap = world.frame_time_s(k);
            if let Some(sink) = sink.as_mut() {
                // In real time nobody waits for a late consumer: render only when one listens.
                if lockstep || sink.ready()? {
                    renderer.render(&world, &optics, t_cap, &mut rgb, true);
                    let hdr = FrameHeader::rgb24(k, world.frame_stamp_us(t_cap), w, h);
                    if sink.send(&hdr, &rgb, lockstep, wait_for)? {
                        frames_sent += 1;
                    } else {
                        frames_dropped += 1;
                    }
                } else {
                    frames_dropped += 1;
                }
            }
            if let Some(tw) = truth.as_mut() {
                let ft = frame_truth(&world, &optics, k);
                tw.add(&world, &optics, &ft, &format!("img1/{:06}.jpg", k + 1))?;
            }
            k += 1;
        }
        if last_report.0.elapsed() >= REPORT_EVERY {
            if let Ok(mon) = monitor.lock() {
                if mon.messages() > last_report.1 {
                    mon.summary().log("mgmot tracks so far");
                }
                last_report = (Instant::now(), mon.messages());
            }
        }
    }
    if let Some(sink) = sink.as_mut() {
        sink.finish();
    }
    if let Some(tw) = truth {
        tw.finish(&world, "jpg")?;
    }
    if let Some(link) = &link {
        // Let the link thread flush its queue.
        std::thread::sleep(Duration::from_millis(200));
        tracing::info!(
            sent = link.sent.load(Ordering::Relaxed),
            dropped = link.dropped.load(Ordering::Relaxed),
            "telemetry"
        );
    }
    tracing::info!(
        frames_sent,
        frames_dropped,
        elapsed_s = start.elapsed().as_secs_f64(),
        "simulation finished"
    );
    if link.is_some() {
        let summary = monitor
            .lock()
            .map_err(|_| anyhow::anyhow!("track monitor poisoned"))?
            .summary();
        summary.log("mgmot tracks");
        for o in &summary.objects {
            tracing::info!(
                object = o.object_id,
                track_ids = ?o.track_ids,
                latest = o.latest_track_id,
                after_reid = ?o.final_track_ids,
                "object reported as"
            );
        }
        if let Some(path) = &args.track_report {
            let json = serde_json::to_string_pretty(&summary)?;
            std::fs::write(path, json + "\n")
                .with_context(|| format!("writing {}", path.display()))?;
        }
    }
    Ok(())
}
