//! The MAVLink link of `run`: opens the address (retrying while it cannot), sends what the
//! run loop queues, answers TIMESYNC and commands, and reconnects when a TCP or serial peer
//! goes away. Never panics on network errors; they are logged.

use mavlink::{MavConnection, MavHeader, MavlinkVersion};
use mgmot_sim::monitor::{TrackCheck, TrackMonitor};
use mgmot_sim::scenario::AutopilotKind;
use mgmot_sim::telemetry::{Autopilot, Reply, Scheduler, Sender};
use mgmot_sim::world::World;
use mgmot_wire::dialect::MavMessage;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicU8, Ordering};
use std::sync::mpsc::{sync_channel, Receiver, RecvTimeoutError, SyncSender, TrySendError};
use std::sync::{Arc, Mutex, OnceLock};
use std::time::{Duration, Instant};

/// Queue between the run loop and the link: about 2 s of telemetry at default rates. When
/// the link stalls, newer messages are dropped (and counted) rather than blocking the sim.
const QUEUE: usize = 128;

/// Wait between attempts to open an address that fails.
const RETRY: Duration = Duration::from_secs(1);

/// MAV_COMP_ID_AUTOPILOT1.
const COMP_AUTOPILOT: u8 = 1;
/// MAV_COMP_ID_GIMBAL: gimbal device messages come from the gimbal's own component.
const COMP_GIMBAL: u8 = 154;
/// A ground station's system id (`faults.gcs_timesync_answers`).
const GCS_SYSTEM: u8 = 255;
/// MAV_COMP_ID_MISSIONPLANNER.
const GCS_COMPONENT: u8 = 190;

/// Sim time shared with the receive thread (f64 bits), so replies carry the current time.
///
/// In real time the autopilot's clock keeps running between the run loop's events (and when
/// the loop falls behind), so a TIMESYNC answer gives the wall-clock sim time, as a real
/// autopilot would; in lockstep it gives the time of the last event.
#[derive(Debug, Default)]
pub struct SimClock {
    last_event_s: AtomicU64,
    realtime_start: OnceLock<Instant>,
}

impl SimClock {
    /// Sets the time of the event being handled.
    pub fn set(&self, t_s: f64) {
        self.last_event_s.store(t_s.to_bits(), Ordering::Relaxed);
    }
    /// Marks sim time 0 as `start` on the wall clock (real-time runs).
    pub fn start_realtime(&self, start: Instant) {
        let _ = self.realtime_start.set(start);
    }
    /// The current sim time.
    pub fn get(&self) -> f64 {
        let event = f64::from_bits(self.last_event_s.load(Ordering::Relaxed));
        match self.realtime_start.get() {
            Some(start) => event.max(start.elapsed().as_secs_f64()),
            None => event,
        }
    }
}

/// The run loop's end of the link.
pub struct Link {
    tx: SyncSender<MavMessage>,
    /// Lockstep: wait for the link instead of dropping when it falls behind.
    blocking: bool,
    /// Messages dropped because the link was not keeping up or not connected.
    pub dropped: Arc<AtomicU64>,
    /// Messages handed to the transport.
    pub sent: Arc<AtomicU64>,
}

impl Link {
    /// Starts the link thread for `address` (mavlink crate syntax: `udpout:host:port`,
    /// `udpin:host:port`, `tcpin:host:port`, `tcpout:host:port`, `serial:/dev/tty:baud`).
    pub fn start(
        address: String,
        world: Arc<World>,
        scheduler: Arc<Mutex<Scheduler>>,
        clock: Arc<SimClock>,
        blocking: bool,
        monitor: Option<Arc<Mutex<TrackMonitor>>>,
    ) -> anyhow::Result<Link> {
        // Reject malformed addresses at once instead of retrying forever.
        let proto = address.split(':').next().unwrap_or("");
        anyhow::ensure!(
            matches!(
                proto,
                "udpout" | "udpin" | "udpbcast" | "tcpin" | "tcpout" | "serial"
            ) && address.matches(':').count() >= 2,
            "invalid --mavlink address `{address}`: expected udpout:HOST:PORT, udpin:HOST:PORT, \
             tcpin:HOST:PORT, tcpout:HOST:PORT or serial:DEVICE:BAUD"
        );
        let (tx, rx) = sync_channel(QUEUE);
        let dropped = Arc::new(AtomicU64::new(0));
        let sent = Arc::new(AtomicU64::new(0));
        let sent2 = sent.clone();
        std::thread::Builder::new()
            .name("mavlink-link".into())
            .spawn(move || link_thread(address, world, scheduler, clock, rx, sent2, monitor))?;
        Ok(Link {
            tx,
            blocking,
            dropped,
            sent,
        })
    }

    /// Queues a message. In real time a full queue drops it (counted); in lockstep it
    /// waits for the link (a link that cannot open discards while it retries, so this never
    /// waits for more than about a second).
    pub fn send(&self, msg: MavMessage) {
        if self.blocking {
            if self.tx.send(msg).is_err() {
                self.dropped.fetch_add(1, Ordering::Relaxed);
            }
            return;
        }
        match self.tx.try_send(msg) {
            Ok(()) => {}
            Err(TrySendError::Full(_)) | Err(TrySendError::Disconnected(_)) => {
                self.dropped.fetch_add(1, Ordering::Relaxed);
            }
        }
    }
}

type Conn = Arc<dyn MavConnection<MavMessage> + Send + Sync>;

fn header(world: &World, seq: &AtomicU8, msg: &MavMessage, sender: Sender) -> MavHeader {
    let (system_id, component_id) = match (sender, msg) {
        (Sender::GroundStation, _) => (GCS_SYSTEM, GCS_COMPONENT),
        // ArduPilot sends its mounts' status as the autopilot.
        (Sender::Vehicle, MavMessage::GIMBAL_DEVICE_ATTITUDE_STATUS(_))
            if world.scenario.telemetry.autopilot == AutopilotKind::Generic =>
        {
            (world.scenario.telemetry.system_id, COMP_GIMBAL)
        }
        (Sender::Vehicle, _) => (world.scenario.telemetry.system_id, COMP_AUTOPILOT),
    };
    MavHeader {
        system_id: u32::from(system_id),
        component_id,
        sequence: seq.fetch_add(1, Ordering::Relaxed),
    }
}

fn link_thread(
    address: String,
    world: Arc<World>,
    scheduler: Arc<Mutex<Scheduler>>,
    clock: Arc<SimClock>,
    rx: Receiver<MavMessage>,
    sent: Arc<AtomicU64>,
    monitor: Option<Arc<Mutex<TrackMonitor>>>,
) {
    let seq = Arc::new(AtomicU8::new(0));
    let stream_oriented = address.starts_with("tcp") || address.starts_with("serial");
    loop {
        let conn: Conn = match mavlink::connect::<MavMessage>(&address) {
            Ok(mut c) => {
                c.set_protocol_version(MavlinkVersion::V2);
                tracing::info!(%address, "MAVLink link open");
                Arc::new(c)
            }
            Err(e) => {
                tracing::warn!(%address, error = %e, "cannot open MAVLink link; retrying in 1 s");
                // Keep draining so the run loop never blocks on a dead link.
                let deadline = Instant::now() + RETRY;
                while Instant::now() < deadline {
                    match rx.recv_timeout(Duration::from_millis(100)) {
                        Err(RecvTimeoutError::Disconnected) => return,
                        _ => continue,
                    }
                }
                continue;
            }
        };
        let broken = Arc::new(AtomicBool::new(false));
        {
            let (conn, world, scheduler, clock, broken, seq, monitor) = (
                conn.clone(),
                world.clone(),
                scheduler.clone(),
                clock.clone(),
                broken.clone(),
                seq.clone(),
                monitor.clone(),
            );
            let spawned = std::thread::Builder::new()
                .name("mavlink-recv".into())
                .spawn(move || {
                    receive_loop(
                        conn,
                        &Receiving {
                            world: &world,
                            scheduler: &scheduler,
                            clock: &clock,
                            seq: &seq,
                            monitor: monitor.as_deref(),
                        },
                        &broken,
                        stream_oriented,
                    )
                });
            if let Err(e) = spawned {
                tracing::error!(error = %e, "cannot start the MAVLink receive thread");
            }
        }
        loop {
            if broken.load(Ordering::Relaxed) {
                break;
            }
            let msg = match rx.recv_timeout(Duration::from_millis(200)) {
                Ok(m) => m,
                Err(RecvTimeoutError::Timeout) => continue,
                Err(RecvTimeoutError::Disconnected) => return,
            };
            match conn.send(&header(&world, &seq, &msg, Sender::Vehicle), &msg) {
                Ok(_) => {
                    sent.fetch_add(1, Ordering::Relaxed);
                }
                Err(e) if stream_oriented => {
                    tracing::warn!(%address, error = %e, "MAVLink peer gone; reconnecting");
                    broken.store(true, Ordering::Relaxed);
                    break;
                }
                Err(e) => tracing::debug!(%address, error = %e, "MAVLink send failed"),
            }
        }
    }
}

/// What the receive thread reads and updates besides the connection.
struct Receiving<'a> {
    world: &'a World,
    scheduler: &'a Mutex<Scheduler>,
    clock: &'a SimClock,
    seq: &'a AtomicU8,
    monitor: Option<&'a Mutex<TrackMonitor>>,
}

fn receive_loop(conn: Conn, ctx: &Receiving<'_>, broken: &AtomicBool, stream_oriented: bool) {
    let Receiving {
        world,
        scheduler,
        clock,
        seq,
        monitor,
    } = *ctx;
    let Ok(autopilot) = Autopilot::new(world) else {
        return;
    };
    while !broken.load(Ordering::Relaxed) {
        match conn.recv() {
            Ok((_, MavMessage::MGMOT_TRACK(track))) => {
                // mgmot's output, checked against the truth when a monitor is attached.
                if let Some(Ok(mut mon)) = monitor.map(|m| m.lock()) {
                    match mon.observe(world, &track) {
                        TrackCheck::Matched {
                            object_id,
                            error_m,
                            same_class,
                            ..
                        } => tracing::debug!(
                            track = track.track_id,
                            object = object_id,
                            error_m,
                            same_class,
                            "mgmot track"
                        ),
                        other => {
                            tracing::debug!(track = track.track_id, check = ?other, "mgmot track")
                        }
                    }
                }
            }
            Ok((from, msg)) => {
                // System ids above 255 exist only in MAVLink 2 extensions of the header; the
                // reply targets are u8 fields.
                let sender = (u8::try_from(from.system_id).unwrap_or(0), from.component_id);
                let replies = match scheduler.lock() {
                    Ok(mut s) => autopilot.handle(&msg, sender, clock.get(), &mut s),
                    Err(_) => return,
                };
                for Reply { sender, msg: r } in replies {
                    tracing::debug!(
                        reply = mgmot_sim::telemetry::message_name(&r),
                        ?sender,
                        "answering"
                    );
                    if let Err(e) = conn.send(&header(world, seq, &r, sender), &r) {
                        tracing::debug!(error = %e, "reply not sent");
                    }
                }
            }
            Err(e) => {
                if stream_oriented {
                    tracing::warn!(error = %e, "MAVLink receive failed; reconnecting");
                    broken.store(true, Ordering::Relaxed);
                    return;
                }
                tracing::debug!(error = %e, "MAVLink receive error");
                std::thread::sleep(Duration::from_millis(10));
            }
        }
    }
}
