//! `mgmot-sim follow`: frames only, for a real autopilot. Follow subscribes to the
//! autopilot's telemetry like a ground station, renders the scenario's world (placed around
//! the autopilot's home) from the camera pose the autopilot reports, streams the frames with
//! stamps on the autopilot clock, writes the truth of every frame, and checks mgmot's
//! MGMOT_TRACK messages (when a router forwards them to follow's link) against it.
//!
//! Threads: the link thread connects (retrying), reads every message and updates the shared
//! state; the control thread sends the HEARTBEAT and the stream requests; the main thread
//! renders at the scenario's frame rate. The pure parts are in [`mgmot_sim::follow`].

use super::frames::FrameSink;
use super::render::TruthWriter;
use super::ScenarioArgs;
use anyhow::Context;
use mavlink::{MavConnection, MavHeader, MavlinkVersion};
use mgmot_core::geo::Geodetic;
use mgmot_sim::follow::{
    gimbal_yaw_frame, horizontal_distance_m, place_world, quaternion_wxyz, vehicle_attitude,
    ClockSync, GimbalFix, GimbalReport, PoseBuffer, PositionFix,
};
use mgmot_sim::framing::FrameHeader;
use mgmot_sim::monitor::TrackMonitor;
use mgmot_sim::render::Renderer;
use mgmot_sim::truth::{frame_truth_posed, Optics};
use mgmot_sim::world::World;
use mgmot_wire::dialect::{
    MavAutopilot, MavCmd, MavMessage, MavModeFlag, MavResult, MavState, MavType, COMMAND_LONG_DATA,
    HEARTBEAT_DATA, MGMOT_TRACK_DATA,
};
use std::collections::VecDeque;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU8, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

/// Follow's MAVLink system id: not the vehicle's (1) and not a ground station's usual 255
/// (ArduPilot's SYSID_MYGCS), so that its heartbeat neither impersonates the vehicle nor
/// keeps a GCS failsafe from triggering.
pub const FOLLOW_SYSTEM_ID: u8 = 250;
/// Follow's component id: MAV_COMP_ID_MISSIONPLANNER (a ground-station-like component).
pub const FOLLOW_COMPONENT_ID: u8 = 190;

/// Wait between attempts to open the MAVLink address.
const RETRY: Duration = Duration::from_secs(1);
/// No ACK and no message this long after a request: ask again.
const REQUEST_RETRY: Duration = Duration::from_secs(2);
/// A stream that was flowing and sent nothing for this long has stopped: ask again.
const STREAM_STALE: Duration = Duration::from_secs(3);
/// A request the autopilot refused is repeated this rarely.
const REFUSED_RETRY: Duration = Duration::from_secs(10);
/// A COMMAND_ACK later than this after its request is not attributed to it.
const ACK_TIMEOUT: Duration = Duration::from_secs(2);
/// Window of the clock estimate (minimum transport delay over it).
const CLOCK_WINDOW_S: f64 = 20.0;
/// How often progress is logged.
const REPORT_EVERY: Duration = Duration::from_secs(5);

/// How to read GIMBAL_DEVICE_ATTITUDE_STATUS.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum GimbalReportArg {
    /// As its flags say (gimbal protocol v2).
    Flags,
    /// Relative to the vehicle body whatever the flags say (ArduPilot servo mounts).
    Body,
}

/// Arguments of `follow`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The autopilot: udpout:HOST:PORT, udpin:HOST:PORT, tcpin:HOST:PORT, tcpout:HOST:PORT
    /// or serial:DEVICE:BAUD. Unreachable peers are retried every second.
    #[arg(long)]
    mavlink: String,
    /// Frame output: unix:/path.sock (follow listens; framing in sim/README.md) or
    /// v4l2:/dev/videoN.
    #[arg(long)]
    frames: String,
    /// The world: a shipped scenario or a TOML file. Only its objects, sea and camera are
    /// used, placed around the autopilot's home; its flight, gimbal, faults and telemetry are
    /// ignored.
    #[arg(long, short = 's', default_value = "calm_baseline")]
    scenario: String,
    /// Seed of the objects and the sea (default: the scenario's).
    #[arg(long)]
    seed: Option<u64>,
    /// Stop after this many seconds of frames (default: the scenario's `duration_s`).
    #[arg(long)]
    duration_s: Option<f64>,
    /// Override the camera width (pixels); the FOV is kept.
    #[arg(long)]
    width: Option<u32>,
    /// Override the camera height (pixels).
    #[arg(long)]
    height: Option<u32>,
    /// Override the frame rate.
    #[arg(long)]
    fps: Option<f64>,
    /// How GIMBAL_DEVICE_ATTITUDE_STATUS's quaternion is referenced: `flags` as the message
    /// says, `body` relative to the vehicle (what ArduPilot sends for a servo mount,
    /// MNT1_TYPE=1, although its flags claim earth-frame roll and pitch).
    #[arg(long, value_enum, default_value = "flags")]
    gimbal_report: GimbalReportArg,
    /// Rate requested for GLOBAL_POSITION_INT, ATTITUDE and GIMBAL_DEVICE_ATTITUDE_STATUS.
    #[arg(long, default_value_t = 50.0)]
    rate_hz: f64,
    /// Wait this long for HOME_POSITION after the first position before taking home from
    /// the position itself (below it, at `alt - relative_alt`).
    #[arg(long, default_value_t = 5.0)]
    home_wait_s: f64,
    /// Write the ground truth of every frame into this folder (as `run --truth-out`).
    #[arg(long)]
    truth_out: Option<PathBuf>,
    /// Write the check of mgmot's MGMOT_TRACK messages against the truth to this JSON file
    /// at the end (as `run --track-report`).
    #[arg(long)]
    track_report: Option<PathBuf>,
}

/// The streams follow requests (message id, name); the pose messages first, in the order
/// of the indices [`Shared::stamp`] is called with.
const STREAMS: [(u32, &str); 4] = [
    (33, "GLOBAL_POSITION_INT"),
    (30, "ATTITUDE"),
    (285, "GIMBAL_DEVICE_ATTITUDE_STATUS"),
    (242, "HOME_POSITION"),
];
/// HOME_POSITION is asked for at this rate (it changes at arming).
const HOME_RATE_HZ: f64 = 1.0;

/// The request state of one stream.
#[derive(Debug, Clone, Default)]
struct StreamState {
    last_message: Option<Instant>,
    last_request: Option<Instant>,
    /// The last COMMAND_ACK result for it.
    result: Option<MavResult>,
    requests: u64,
    messages: u64,
}

/// What the link thread learns and the other threads read.
struct Shared {
    epoch: Instant,
    /// The autopilot: system and component id of its HEARTBEAT.
    target: Option<(u8, u8)>,
    last_heartbeat: Option<Instant>,
    poses: PoseBuffer,
    clock: ClockSync,
    home: Option<Geodetic>,
    first_fix: Option<(Instant, PositionFix)>,
    streams: [StreamState; STREAMS.len()],
    /// Requests awaiting their COMMAND_ACK: stream index and when.
    pending_acks: VecDeque<(usize, Instant)>,
    /// MGMOT_TRACK messages with the local time (µs since `epoch`) of their stamp.
    tracks: Vec<(MGMOT_TRACK_DATA, Option<i64>)>,
    reboots: u64,
    gimbal_report: GimbalReport,
}

impl Shared {
    fn local_us(&self, at: Instant) -> i64 {
        i64::try_from(at.saturating_duration_since(self.epoch).as_micros()).unwrap_or(i64::MAX)
    }

    /// A timestamped pose message from the autopilot: feeds the clock; a reboot resets the
    /// pose history and the stream requests.
    fn stamp(&mut self, time_boot_ms: u32, stream: usize, now: Instant) -> u64 {
        let ap_us = u64::from(time_boot_ms) * 1000;
        let local = self.local_us(now);
        if self.clock.observe(ap_us, local) {
            self.reboots += 1;
            tracing::warn!(
                time_boot_ms,
                "the autopilot clock went back (reboot?): pose history and stream requests reset"
            );
            self.poses.clear();
            for s in &mut self.streams {
                *s = StreamState::default();
            }
        }
        if let Some(s) = self.streams.get_mut(stream) {
            s.last_message = Some(now);
            s.messages += 1;
        }
        ap_us
    }
}

fn lock(shared: &Mutex<Shared>) -> anyhow::Result<MutexGuard<'_, Shared>> {
    shared
        .lock()
        .map_err(|_| anyhow::anyhow!("follow state poisoned"))
}

type Conn = Arc<dyn MavConnection<MavMessage> + Send + Sync>;

/// The connection currently open (none while connecting), shared with the control thread.
type ConnSlot = Arc<Mutex<Option<Conn>>>;

/// Runs follow until the duration is rendered or SIGINT/SIGTERM.
pub fn run(args: Args) -> anyhow::Result<()> {
    anyhow::ensure!(
        args.rate_hz.is_finite() && args.rate_hz > 0.0 && args.rate_hz <= 1000.0,
        "--rate-hz must be within (0, 1000]"
    );
    anyhow::ensure!(
        args.home_wait_s.is_finite() && args.home_wait_s >= 0.0,
        "--home-wait-s must be >= 0"
    );
    let proto = args.mavlink.split(':').next().unwrap_or("");
    anyhow::ensure!(
        matches!(proto, "udpout" | "udpin" | "tcpin" | "tcpout" | "serial")
            && args.mavlink.matches(':').count() >= 2,
        "invalid --mavlink address `{}`: expected udpout:HOST:PORT, udpin:HOST:PORT, \
         tcpin:HOST:PORT, tcpout:HOST:PORT or serial:DEVICE:BAUD",
        args.mavlink
    );
    let mut world = ScenarioArgs {
        scenario: args.scenario.clone(),
        seed: args.seed,
        duration_s: args.duration_s,
        width: args.width,
        height: args.height,
        fps: args.fps,
        // The real autopilot flies; the scenario's own drone is not used.
        vehicle: 0,
    }
    .world()?;
    let renderer = Renderer::new(&world.scenario, world.seed);
    let (w, h) = (
        world.scenario.camera.width_px,
        world.scenario.camera.height_px,
    );
    let mut sink = FrameSink::open(&args.frames, w, h)?;
    let gimbal_report = match args.gimbal_report {
        GimbalReportArg::Flags => GimbalReport::Flags,
        GimbalReportArg::Body => GimbalReport::Body,
    };
    let epoch = Instant::now();
    let shared = Arc::new(Mutex::new(Shared {
        epoch,
        target: None,
        last_heartbeat: None,
        poses: PoseBuffer::default(),
        clock: ClockSync::new(CLOCK_WINDOW_S),
        home: None,
        first_fix: None,
        streams: Default::default(),
        pending_acks: VecDeque::new(),
        tracks: Vec::new(),
        reboots: 0,
        gimbal_report,
    }));
    let interrupted = Arc::new(AtomicBool::new(false));
    for signal in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        signal_hook::flag::register(signal, interrupted.clone())
            .context("installing the signal handler")?;
    }
    let conn: ConnSlot = Arc::new(Mutex::new(None));
    let seq = Arc::new(AtomicU8::new(0));
    {
        let (address, shared, conn, seq) = (
            args.mavlink.clone(),
            shared.clone(),
            conn.clone(),
            seq.clone(),
        );
        std::thread::Builder::new()
            .name("follow-link".into())
            .spawn(move || link_thread(&address, &shared, &conn, &seq))?;
    }
    {
        let (shared, conn, seq, rate) = (shared.clone(), conn.clone(), seq.clone(), args.rate_hz);
        std::thread::Builder::new()
            .name("follow-control".into())
            .spawn(move || control_thread(&shared, &conn, &seq, rate))?;
    }
    tracing::info!(
        scenario = %world.scenario.name,
        seed = world.seed,
        mavlink = %args.mavlink,
        system_id = FOLLOW_SYSTEM_ID,
        component_id = FOLLOW_COMPONENT_ID,
        gimbal_report = ?gimbal_report,
        "follow started: waiting for the autopilot"
    );

    let fps = world.scenario.camera.fps;
    let period = Duration::from_secs_f64(1.0 / fps);
    let latency = Duration::from_secs_f64(world.scenario.camera.capture_latency_ms / 1000.0);
    let duration_s = world.scenario.duration_s;
    let mut rgb = vec![0u8; renderer.frame_bytes()];
    // Set once home is known.
    let mut placed: Option<(Optics, TrackMonitor)> = None;
    let mut truth: Option<TruthWriter> = None;
    // Local time (µs since epoch) of scenario time 0, and the last frame index.
    let mut render_start: Option<i64> = None;
    let mut last_index: Option<u64> = None;
    let (mut frames_sent, mut frames_unsent, mut frames_late) = (0u64, 0u64, 0u64);
    let mut no_pose_ticks = 0u64;
    let mut last_log = Instant::now() - REPORT_EVERY;
    let mut last_waiting: Option<String> = None;
    let mut next = Instant::now();
    loop {
        if interrupted.load(Ordering::Relaxed) {
            tracing::warn!("interrupted: stopping");
            break;
        }
        let now = Instant::now();
        if next > now {
            std::thread::sleep(next - now);
        }
        next += period;
        if Instant::now() > next {
            // Rendering fell behind by a whole frame: skip ahead rather than burst.
            frames_late += 1;
            next = Instant::now() + period;
        }

        if placed.is_none() {
            if let Some(home) = decide_home(&shared, args.home_wait_s)? {
                place_world(&mut world, &home);
                let optics =
                    Optics::new(&world.scenario).context("home is not a valid position")?;
                let monitor = TrackMonitor::new(&world).context("home is not a valid position")?;
                tracing::info!(
                    lat_deg = home.lat_deg,
                    lon_deg = home.lon_deg,
                    sea_level_amsl_m = home.alt_m,
                    "world placed around home"
                );
                placed = Some((optics, monitor));
            }
        }
        let capture = Instant::now().checked_sub(latency).unwrap_or(epoch);
        let (pose, ap_us, capture_local) = {
            let st = lock(&shared)?;
            let capture_local = st.local_us(capture);
            let ap_us = st.clock.autopilot_us(capture_local);
            let pose = match (&placed, ap_us) {
                (None, _) => Err(if st.target.is_none() {
                    "no autopilot HEARTBEAT yet".to_string()
                } else {
                    "home not known yet".to_string()
                }),
                (_, None) => Err("no timestamped telemetry yet".to_string()),
                (Some((optics, _)), Some(t)) => st
                    .poses
                    .pose_at(t, &optics.frame)
                    .map_err(|m| format!("no {m} around the capture time")),
            };
            (pose, ap_us.unwrap_or(0), capture_local)
        };
        let pose = match pose {
            Ok(p) => p,
            Err(why) => {
                no_pose_ticks += 1;
                if last_waiting.as_deref() != Some(why.as_str()) {
                    tracing::info!(reason = %why, "no pose: no frames");
                    last_waiting = Some(why);
                }
                continue;
            }
        };
        if last_waiting.take().is_some() {
            tracing::info!("pose available: rendering");
        }
        let Some((optics, monitor)) = placed.as_mut() else {
            continue;
        };
        let start = *render_start.get_or_insert_with(|| {
            let unix_now = SystemTime::now()
                .duration_since(UNIX_EPOCH)
                .map_or(0.0, |d| d.as_secs_f64());
            world.scenario.origin.start_unix_s = unix_now - latency.as_secs_f64();
            tracing::info!(autopilot_time_us = ap_us, "scenario time 0: first frame");
            capture_local
        });
        if truth.is_none() {
            if let Some(dir) = &args.truth_out {
                truth = Some(TruthWriter::create(dir, &world)?);
            }
        }
        let t_s = (capture_local - start) as f64 / 1e6;
        if t_s > duration_s {
            tracing::info!(duration_s, "scenario duration reached");
            break;
        }
        let index = (t_s * fps).round().max(0.0) as u64;
        if last_index.is_some_and(|l| index <= l) {
            continue;
        }
        last_index = Some(index);
        let mut ft = frame_truth_posed(&world, optics, index, t_s, pose.drone_state(), pose.camera);
        ft.stamp_us = ap_us;
        if sink.ready()? {
            renderer.render_pose(&world, optics, &pose.camera, t_s, &mut rgb, true);
            let hdr = FrameHeader::rgb24(index, ap_us, w, h);
            if sink.send(&hdr, &rgb, false, Duration::ZERO)? {
                frames_sent += 1;
            } else {
                frames_unsent += 1;
            }
        } else {
            frames_unsent += 1;
        }
        if let Some(tw) = truth.as_mut() {
            tw.add(&world, optics, &ft, &format!("img1/{:06}.jpg", index + 1))?;
        }
        check_tracks(&shared, &world, monitor, start)?;
        if last_log.elapsed() >= REPORT_EVERY {
            last_log = Instant::now();
            let st = lock(&shared)?;
            let newest = st.poses.newest_us();
            tracing::info!(
                t_s = format!("{t_s:.1}"),
                frames_sent,
                frames_unsent,
                frames_late,
                clock_offset_us = st.clock.offset_us(),
                pose_age_ms = ?newest.map(|n| n.map(|n| (n as i64 - ap_us as i64) / 1000)),
                "following"
            );
            if monitor.messages() > 0 {
                monitor.summary().log("mgmot tracks so far");
            }
        }
    }
    sink.finish();
    if let Some(tw) = truth {
        tw.finish(&world, "jpg")?;
    }
    {
        let st = lock(&shared)?;
        for ((_, name), s) in STREAMS.iter().zip(&st.streams) {
            tracing::info!(
                stream = %name,
                requests = s.requests,
                ack = ?s.result,
                received = s.messages,
                "stream"
            );
        }
        tracing::info!(
            frames_sent,
            frames_unsent,
            frames_late,
            no_pose_ticks,
            autopilot_reboots = st.reboots,
            "follow finished"
        );
    }
    if let (Some((_, monitor)), Some(start)) = (placed.as_mut(), render_start) {
        check_tracks(&shared, &world, monitor, start)?;
        let summary = monitor.summary();
        summary.log("mgmot tracks");
        if let Some(path) = &args.track_report {
            let json = serde_json::to_string_pretty(&summary)?;
            std::fs::write(path, json + "\n")
                .with_context(|| format!("writing {}", path.display()))?;
        }
    } else if let Some(path) = &args.track_report {
        tracing::warn!(path = %path.display(), "no frame was rendered: no track report written");
    }
    Ok(())
}

/// Home once known: HOME_POSITION, or after `wait_s` without one the home implied by the
/// first position.
fn decide_home(shared: &Mutex<Shared>, wait_s: f64) -> anyhow::Result<Option<Geodetic>> {
    let st = lock(shared)?;
    if let Some(h) = st.home {
        return Ok(Some(h));
    }
    Ok(match st.first_fix {
        Some((at, fix)) if at.elapsed().as_secs_f64() >= wait_s => {
            let home = fix.implied_home();
            if home.is_some() {
                tracing::warn!(
                    wait_s,
                    "no HOME_POSITION: home taken from the first GLOBAL_POSITION_INT"
                );
            }
            home
        }
        _ => None,
    })
}

/// Checks the MGMOT_TRACK messages received since the last call.
fn check_tracks(
    shared: &Mutex<Shared>,
    world: &World,
    monitor: &mut TrackMonitor,
    start_local_us: i64,
) -> anyhow::Result<()> {
    let tracks = std::mem::take(&mut lock(shared)?.tracks);
    for (m, local) in tracks {
        // Unknown clock: a time no scenario contains, counted as out of scenario.
        let t_s = local.map_or(f64::NAN, |l| (l - start_local_us) as f64 / 1e6);
        let check = monitor.observe_at(world, &m, t_s);
        tracing::debug!(track = m.track_id, t_s, check = ?check, "mgmot track");
    }
    Ok(())
}

fn header(seq: &AtomicU8) -> MavHeader {
    MavHeader {
        system_id: u32::from(FOLLOW_SYSTEM_ID),
        component_id: FOLLOW_COMPONENT_ID,
        sequence: seq.fetch_add(1, Ordering::Relaxed),
    }
}

fn current(conn: &ConnSlot) -> Option<Conn> {
    conn.lock().ok().and_then(|c| c.clone())
}

/// Connects (retrying), then reads until the link breaks, forever.
fn link_thread(address: &str, shared: &Mutex<Shared>, slot: &ConnSlot, seq: &AtomicU8) {
    let stream_oriented = address.starts_with("tcp") || address.starts_with("serial");
    loop {
        let conn: Conn = match mavlink::connect::<MavMessage>(address) {
            Ok(mut c) => {
                c.set_protocol_version(MavlinkVersion::V2);
                tracing::info!(%address, "MAVLink link open");
                Arc::new(c)
            }
            Err(e) => {
                tracing::warn!(%address, error = %e, "cannot open MAVLink link; retrying in 1 s");
                std::thread::sleep(RETRY);
                continue;
            }
        };
        if let Ok(mut s) = slot.lock() {
            *s = Some(conn.clone());
        }
        // Say hello at once: on udpout the autopilot only answers a link it has heard from.
        if let Err(e) = conn.send(&header(seq), &heartbeat()) {
            tracing::debug!(error = %e, "heartbeat not sent");
        }
        loop {
            match conn.recv() {
                Ok((from, msg)) => {
                    if handle(shared, &from, msg).is_err() {
                        return;
                    }
                }
                Err(e) => {
                    if stream_oriented {
                        tracing::warn!(%address, error = %e, "MAVLink receive failed; reconnecting");
                        break;
                    }
                    tracing::debug!(error = %e, "MAVLink receive error");
                    std::thread::sleep(Duration::from_millis(10));
                }
            }
        }
        if let Ok(mut s) = slot.lock() {
            *s = None;
        }
        std::thread::sleep(RETRY);
    }
}

/// Updates the shared state with one message.
fn handle(shared: &Mutex<Shared>, from: &MavHeader, msg: MavMessage) -> anyhow::Result<()> {
    let now = Instant::now();
    let mut st = lock(shared)?;
    let sender = (u8::try_from(from.system_id).unwrap_or(0), from.component_id);
    if let MavMessage::MGMOT_TRACK(t) = msg {
        let local = st.clock.local_us(t.time_usec);
        st.tracks.push((t, local));
        return Ok(());
    }
    if let MavMessage::HEARTBEAT(hb) = &msg {
        let is_autopilot = hb.autopilot != MavAutopilot::MAV_AUTOPILOT_INVALID
            && hb.mavtype != MavType::MAV_TYPE_GCS
            && hb.mavtype != MavType::MAV_TYPE_GIMBAL;
        if st.target.is_none() && is_autopilot {
            tracing::info!(
                system_id = sender.0,
                component_id = sender.1,
                mavtype = ?hb.mavtype,
                "autopilot heartbeat"
            );
            st.target = Some(sender);
        }
        if st.target == Some(sender) {
            st.last_heartbeat = Some(now);
        }
        return Ok(());
    }
    let Some(target) = st.target else {
        return Ok(());
    };
    if sender.0 != target.0 {
        return Ok(());
    }
    match msg {
        MavMessage::GLOBAL_POSITION_INT(p) => {
            let t = st.stamp(p.time_boot_ms, 0, now);
            if let Some(fix) =
                PositionFix::from_mavlink(p.lat, p.lon, p.alt, p.relative_alt, [p.vx, p.vy, p.vz])
            {
                st.poses.push_position(t, fix);
                if st.first_fix.is_none() {
                    st.first_fix = Some((now, fix));
                }
            }
        }
        MavMessage::ATTITUDE(a) => {
            let t = st.stamp(a.time_boot_ms, 1, now);
            if let Some(q) = vehicle_attitude(a.roll, a.pitch, a.yaw) {
                st.poses.push_attitude(t, q);
            }
        }
        MavMessage::GIMBAL_DEVICE_ATTITUDE_STATUS(g) => {
            let t = st.stamp(g.time_boot_ms, 2, now);
            if let Some(q) = quaternion_wxyz(g.q) {
                let frame = gimbal_yaw_frame(g.flags, st.gimbal_report);
                st.poses.push_gimbal(t, GimbalFix { q, frame });
            }
        }
        MavMessage::HOME_POSITION(hp) => {
            if let Some(s) = st.streams.get_mut(3) {
                s.last_message = Some(now);
                s.messages += 1;
            }
            let Ok(home) = Geodetic::new(
                f64::from(hp.latitude) * 1e-7,
                f64::from(hp.longitude) * 1e-7,
                f64::from(hp.altitude) * 1e-3,
            ) else {
                return Ok(());
            };
            if hp.latitude == 0 && hp.longitude == 0 {
                return Ok(());
            }
            match st.home {
                None => {
                    tracing::info!(
                        lat_deg = home.lat_deg,
                        lon_deg = home.lon_deg,
                        alt_amsl_m = home.alt_m,
                        "HOME_POSITION"
                    );
                    st.home = Some(home);
                }
                Some(h) => {
                    let moved = horizontal_distance_m(&h, &home);
                    if moved > 1.0 || (h.alt_m - home.alt_m).abs() > 1.0 {
                        tracing::warn!(
                            moved_m = moved,
                            alt_change_m = home.alt_m - h.alt_m,
                            "home moved; the world stays where it was placed"
                        );
                        st.home = Some(home);
                    }
                }
            }
        }
        MavMessage::COMMAND_ACK(ack)
            if ack.command == MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL
                && (ack.target_system == 0 || ack.target_system == FOLLOW_SYSTEM_ID) =>
        {
            while st
                .pending_acks
                .front()
                .is_some_and(|p| now.duration_since(p.1) > ACK_TIMEOUT)
            {
                st.pending_acks.pop_front();
            }
            if let Some((i, _)) = st.pending_acks.pop_front() {
                let name = STREAMS.get(i).map_or("?", |s| s.1);
                if let Some(s) = st.streams.get_mut(i) {
                    if s.result != Some(ack.result) {
                        tracing::info!(
                            stream = %name,
                            result = ?ack.result,
                            "SET_MESSAGE_INTERVAL acknowledged"
                        );
                    }
                    s.result = Some(ack.result);
                }
            }
        }
        _ => {}
    }
    Ok(())
}

fn heartbeat() -> MavMessage {
    MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        custom_mode: 0,
        mavtype: MavType::MAV_TYPE_GCS,
        autopilot: MavAutopilot::MAV_AUTOPILOT_INVALID,
        base_mode: MavModeFlag::empty(),
        system_status: MavState::MAV_STATE_ACTIVE,
        mavlink_version: 3,
    })
}

fn interval_request(target: (u8, u8), message_id: u32, rate_hz: f64) -> MavMessage {
    MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
        target_system: target.0,
        target_component: target.1,
        command: MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL,
        confirmation: 0,
        param1: message_id as f32,
        param2: (1e6 / rate_hz) as f32,
        ..Default::default()
    })
}

/// Whether stream `s` needs a (new) request now.
fn needs_request(s: &StreamState, now: Instant) -> bool {
    let since = |t: Option<Instant>| t.map(|t| now.saturating_duration_since(t));
    let Some(asked) = since(s.last_request) else {
        return true;
    };
    match s.result {
        Some(MavResult::MAV_RESULT_ACCEPTED) => {
            // Flowing, or stopped (a reboot the clock did not catch, a reset link).
            let quiet = since(s.last_message).is_none_or(|d| d > STREAM_STALE);
            quiet && asked > STREAM_STALE
        }
        Some(_) => asked > REFUSED_RETRY,
        None => {
            // No answer: ArduPilot drops requests on a link it has not heard from yet.
            let quiet = since(s.last_message).is_none_or(|d| d > STREAM_STALE);
            quiet && asked > REQUEST_RETRY
        }
    }
}

/// HEARTBEAT at 1 Hz; stream requests after first contact and whenever a stream stops.
fn control_thread(shared: &Mutex<Shared>, slot: &ConnSlot, seq: &AtomicU8, rate_hz: f64) {
    let mut last_heartbeat: Option<Instant> = None;
    loop {
        std::thread::sleep(Duration::from_millis(100));
        let Some(conn) = current(slot) else {
            continue;
        };
        let now = Instant::now();
        if last_heartbeat.is_none_or(|t| now.duration_since(t) >= Duration::from_secs(1)) {
            last_heartbeat = Some(now);
            if let Err(e) = conn.send(&header(seq), &heartbeat()) {
                tracing::debug!(error = %e, "heartbeat not sent");
            }
        }
        let mut requests = Vec::new();
        {
            let Ok(mut st) = shared.lock() else {
                return;
            };
            let Some(target) = st.target else {
                continue;
            };
            for (i, (id, name)) in STREAMS.iter().enumerate() {
                let Some(s) = st.streams.get_mut(i) else {
                    continue;
                };
                if !needs_request(s, now) {
                    continue;
                }
                if s.requests > 0 {
                    tracing::info!(stream = %name, "stream not flowing: asking again");
                }
                s.last_request = Some(now);
                s.requests += 1;
                let rate = if *id == 242 { HOME_RATE_HZ } else { rate_hz };
                requests.push((i, interval_request(target, *id, rate)));
            }
            for (i, _) in &requests {
                st.pending_acks.push_back((*i, now));
            }
        }
        for (i, r) in requests {
            tracing::debug!(
                stream = %STREAMS.get(i).map_or("?", |s| s.1),
                "SET_MESSAGE_INTERVAL"
            );
            if let Err(e) = conn.send(&header(seq), &r) {
                tracing::debug!(error = %e, "request not sent");
            }
        }
    }
}
