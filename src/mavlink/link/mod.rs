//! [`Link`]: the MAVLink connection and everything that keeps it honest and alive.
//!
//! The link owns its transport (reconnecting with back-off), the framing, MAVLink 2 signing
//! ([`super::signing::Signer`]), who may talk to mgmot, the telemetry stream requests and their
//! re-sending, and TIMESYNC. It hands the pipeline [`LinkEvent`]s that already passed those
//! checks, and takes messages to send through a [`LinkSender`].
//!
//! Who is listened to:
//! - **the peer** (`udpin`): replies go to one peer only, never simply to whoever sent the
//!   last datagram: the configured `udp_peer`, or else the first peer that sends a valid frame
//!   from the vehicle's system (signed and verified, when signing is on). Another peer takes
//!   over only after the current one has been silent for [`PEER_TIMEOUT`]. `udpout` accepts
//!   datagrams from its remote only.
//! - **pose, home and clock** (GLOBAL_POSITION_INT, ATTITUDE, HOME_POSITION, TIMESYNC,
//!   HEARTBEAT): only from the configured autopilot (the vehicle's system id and the
//!   autopilot's component id); gimbal attitude from any component of the vehicle's system.
//!   Anyone else's are dropped, counted and logged at a limited rate.
//! - **TIMESYNC answers** count only when they answer one of our outstanding requests
//!   ([`timesync`]), from the autopilot. Others' TIMESYNC are normal traffic, not spoofing:
//!   ArduPilot forwards our requests to its other links and brings their ground stations'
//!   answers back (307 in 6 min on SITL). They are counted and logged at debug only.
//! - **commands** from anyone are passed on with whether they were signed; a command
//!   addressed to mgmot whose id the dialect does not know is answered
//!   MAV_RESULT_UNSUPPORTED here (it cannot be decoded into a typed message).
//!
//! What is kept alive: the telemetry streams are asked for once the autopilot has been heard
//! (those some autopilot type does not send, once its HEARTBEAT has named its type),
//! again whenever they stop flowing, and from scratch after the autopilot reboots (its boot
//! clock goes back) or comes back after silence ([`streams`]). TCP and serial reconnect with
//! back-off; a peer that stops reading cannot stall the link (writes time out).

pub mod command_budget;
pub mod frames;
pub mod streams;
pub mod timesync;
pub mod transport;

use super::address::AddressError;
use super::dialect::{self, MavCmd, MavMessage, MavResult, COMMAND_ACK_DATA};
use super::encode::{message_interval_request, timesync_request};
use super::signing::{Refusal, Signer, SigningStateError};
use crate::logging::LogThrottle;
use crate::telemetry::{AutopilotTimeUs, CompanionTimeUs, RebootDetector, StampVerdict};
use command_budget::{CommandBudget, COMMANDS_PER_S};
use frames::FrameParser;
use mavlink_core::{MAVLinkMessageRaw, MAVLinkV2MessageRaw, MavHeader, Message, MessageData};
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};
use streams::{AckOutcome, StreamRequests};
use timesync::TimeSyncRequests;
use tokio::sync::{mpsc, oneshot};
use tokio::task::JoinHandle;
use transport::{Connection, Endpoint, Received as Transported};

/// A `udpin` peer silent this long may be replaced by another.
pub const PEER_TIMEOUT: Duration = Duration::from_secs(5);
/// The autopilot silent this long is "gone": when it is heard again, its streams are asked
/// for again (it may have rebooted without us seeing its clock go back).
pub const AUTOPILOT_SILENCE: Duration = Duration::from_secs(3);
/// Reconnect back-off: first wait and longest wait.
pub const RECONNECT_INITIAL: Duration = Duration::from_millis(200);
/// See [`RECONNECT_INITIAL`].
pub const RECONNECT_MAX: Duration = Duration::from_secs(5);
/// A stream write that takes longer than this means the peer stopped reading: reconnect.
pub const WRITE_TIMEOUT: Duration = Duration::from_secs(2);
/// At shutdown, queued messages are flushed for at most this long.
pub const FLUSH_TIMEOUT: Duration = Duration::from_secs(1);
/// Outgoing queue: enough for every track of a busy frame; beyond it messages are dropped and
/// counted rather than stalling the caller.
pub const OUT_QUEUE: usize = 1024;
/// Events waiting for the pipeline.
pub const EVENT_QUEUE: usize = 4096;
pub use crate::logging::LOG_EVERY;

/// Why the link could not be set up.
#[derive(Debug, thiserror::Error)]
pub enum LinkError {
    /// The connection string.
    #[error(transparent)]
    Address(#[from] AddressError),
    /// The persisted signing state.
    #[error(transparent)]
    Signing(#[from] SigningStateError),
}

/// MAVLink 2 signing settings.
#[derive(Debug, Clone)]
pub struct SigningSettings {
    /// The secret key.
    pub key: [u8; 32],
    /// Link id of our signatures.
    pub link_id: u8,
    /// Where the signing timestamps persist across restarts (none: replay protection ends
    /// with the process).
    pub state_file: Option<PathBuf>,
}

/// What the link needs to know.
#[derive(Debug, Clone)]
pub struct LinkSettings {
    /// Connection string.
    pub connection: String,
    /// The vehicle's (and our) system id.
    pub system_id: u8,
    /// Our component id.
    pub component_id: u8,
    /// The autopilot's component id.
    pub autopilot_component_id: u8,
    /// `udpin` only: the one peer to answer (none: the first valid one).
    pub udp_peer: Option<SocketAddr>,
    /// Signing, if on.
    pub signing: Option<SigningSettings>,
    /// Telemetry streams to ask for: (message id, rate Hz). Empty: leave the rates alone.
    pub streams: Vec<(u32, f32)>,
    /// TIMESYNC requests per second (0: none).
    pub timesync_hz: f64,
    /// With signing on: whether unsigned pose, home, clock and gimbal messages from the
    /// autopilot are still used (an autopilot or router that does not sign). Commands must be
    /// signed either way.
    pub accept_unsigned_telemetry: bool,
    /// Called with every valid frame received and every frame sent, as on the wire (the
    /// flight record's `flight.tlog`).
    pub tap: Option<PacketTap>,
}

/// What a [`PacketTap`] calls.
pub type TapFn = dyn Fn(&[u8]) + Send + Sync;

/// Sees the raw bytes of every MAVLink frame in and out (must not block).
#[derive(Clone)]
pub struct PacketTap(pub std::sync::Arc<TapFn>);

impl std::fmt::Debug for PacketTap {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("PacketTap")
    }
}

/// A message that passed the link's checks.
#[derive(Debug, Clone)]
pub struct Received {
    /// The message.
    pub message: MavMessage,
    /// Sender system id.
    pub system_id: u8,
    /// Sender component id.
    pub component_id: u8,
    /// Whether it was signed (and the signature verified).
    pub signed: bool,
    /// When it arrived.
    pub at: CompanionTimeUs,
}

/// What the link hands the pipeline.
#[derive(Debug, Clone)]
pub enum LinkEvent {
    /// A message from the autopilot (telemetry), the vehicle's gimbal, or a command (boxed:
    /// a message is large, the other variants small).
    Message(Box<Received>),
    /// A TIMESYNC round trip answering one of our requests, from the autopilot.
    TimeSync {
        /// Our request's companion time.
        sent: CompanionTimeUs,
        /// The autopilot's time in its answer.
        autopilot: AutopilotTimeUs,
        /// When the answer arrived.
        at: CompanionTimeUs,
    },
}

/// Called with the time a message went out on the socket.
pub type OnSent = Box<dyn FnOnce(CompanionTimeUs) + Send>;

struct Outgoing {
    message: MavMessage,
    on_sent: Option<OnSent>,
}

/// Queues messages for the link (cheap to clone). When the queue is full, messages are
/// dropped and counted rather than blocking.
#[derive(Clone)]
pub struct LinkSender {
    tx: mpsc::Sender<Outgoing>,
    dropped: Arc<AtomicU64>,
}

impl std::fmt::Debug for LinkSender {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LinkSender")
            .field("dropped", &self.dropped())
            .finish_non_exhaustive()
    }
}

impl LinkSender {
    /// Queues `message`.
    pub fn send(&self, message: MavMessage) {
        self.queue(Outgoing {
            message,
            on_sent: None,
        });
    }

    /// Queues `message`; `on_sent` is called with the time it was written to the socket.
    pub fn send_then(&self, message: MavMessage, on_sent: OnSent) {
        self.queue(Outgoing {
            message,
            on_sent: Some(on_sent),
        });
    }

    fn queue(&self, out: Outgoing) {
        if self.tx.try_send(out).is_err() {
            self.dropped.fetch_add(1, Ordering::Relaxed);
        }
    }

    /// Messages dropped because the queue was full.
    pub fn dropped(&self) -> u64 {
        self.dropped.load(Ordering::Relaxed)
    }
}

/// The link's counters, returned by [`Link::close`].
#[derive(Debug, Default, Clone, PartialEq, Eq, serde::Serialize)]
pub struct LinkStats {
    /// Frames with a valid CRC.
    pub frames_received: u64,
    /// Frames with a bad CRC (or an id the dialect does not know).
    pub frames_bad_crc: u64,
    /// Messages sent.
    pub messages_sent: u64,
    /// Messages that could not be sent (no peer yet, socket error).
    pub messages_not_sent: u64,
    /// Datagrams from a peer other than the one the link answers.
    pub from_other_peers: u64,
    /// Telemetry (pose, home, clock) from a system or component other than the autopilot.
    pub telemetry_from_others: u64,
    /// Signed frames refused (bad signature, replay, timestamp out of bounds).
    pub signing_refused: u64,
    /// TIMESYNC answers from the autopilot that answered no request of ours.
    pub timesync_unmatched: u64,
    /// TIMESYNC (answers and requests) from senders other than the autopilot: ground
    /// stations answering the requests the autopilot forwarded to them.
    pub timesync_from_others: u64,
    /// Events dropped because the pipeline fell behind.
    pub events_dropped: u64,
    /// Connections (re)opened.
    pub connects: u64,
    /// Autopilot reboots or returns after silence (streams asked for again).
    pub autopilot_restarts: u64,
    /// SET_MESSAGE_INTERVAL requests sent.
    pub stream_requests: u64,
    /// Commands dropped unanswered: their sender was beyond its budget
    /// ([`command_budget::COMMANDS_PER_S`]).
    pub commands_over_budget: u64,
}

/// The running link: [`Link::close`] stops it.
#[derive(Debug)]
pub struct Link {
    stop: oneshot::Sender<()>,
    task: JoinHandle<LinkStats>,
}

impl Link {
    /// Starts the link. Fails only on a bad connection string or an unusable signing state
    /// file; a peer that is not there yet is waited for (with back-off), not an error.
    pub fn start(
        settings: LinkSettings,
    ) -> Result<(Link, LinkSender, mpsc::Receiver<LinkEvent>), LinkError> {
        let endpoint = Endpoint::parse(&settings.connection)?;
        let signer = match &settings.signing {
            Some(s) => Some(Signer::new(s.key, s.link_id, s.state_file.as_deref())?),
            None => None,
        };
        let (out_tx, out_rx) = mpsc::channel(OUT_QUEUE);
        let (event_tx, event_rx) = mpsc::channel(EVENT_QUEUE);
        let (stop, stop_rx) = oneshot::channel();
        let task = LinkTask {
            streams: StreamRequests::new(&settings.streams),
            peer: settings.udp_peer,
            settings,
            endpoint,
            signer,
            timesync: TimeSyncRequests::new(),
            peer_heard: None,
            sequence: 0,
            started: Instant::now(),
            autopilot_heard: None,
            autopilot_clock: RebootDetector::new(),
            streams_reset_at: None,
            commands: CommandBudget::default(),
            throttle_commands: LogThrottle::default(),
            throttle_unknown: LogThrottle::default(),
            throttle_restart: LogThrottle::default(),
            last_timesync: None,
            last_persist: Instant::now(),
            stats: LinkStats::default(),
            throttle_peer: LogThrottle::default(),
            throttle_telemetry: LogThrottle::default(),
            throttle_signing: LogThrottle::default(),
            throttle_connect: LogThrottle::default(),
            events: event_tx,
        };
        let task = tokio::spawn(task.run(out_rx, stop_rx));
        Ok((
            Link { stop, task },
            LinkSender {
                tx: out_tx,
                dropped: Arc::new(AtomicU64::new(0)),
            },
            event_rx,
        ))
    }

    /// Stops the link: what is queued is sent (for at most [`FLUSH_TIMEOUT`]), the signing
    /// state persisted, the counters returned.
    pub async fn close(self) -> LinkStats {
        let _ = self.stop.send(());
        self.task.await.unwrap_or_default()
    }
}

struct LinkTask {
    settings: LinkSettings,
    endpoint: Endpoint,
    signer: Option<Signer>,
    streams: StreamRequests,
    timesync: TimeSyncRequests,
    /// `udpin`: the peer answered.
    peer: Option<SocketAddr>,
    peer_heard: Option<Instant>,
    sequence: u8,
    started: Instant,
    autopilot_heard: Option<Instant>,
    /// Whether the autopilot's stamps say it rebooted: the same judge as the clock mapping's
    /// and the pose buffer's, so a stray or forged stamp near zero is no reboot here either.
    autopilot_clock: RebootDetector,
    /// When the streams were last asked for again (since start).
    streams_reset_at: Option<Duration>,
    throttle_restart: LogThrottle,
    /// Commands each sender may have answered.
    commands: CommandBudget,
    throttle_commands: LogThrottle,
    throttle_unknown: LogThrottle,
    last_timesync: Option<Instant>,
    last_persist: Instant,
    stats: LinkStats,
    throttle_peer: LogThrottle,
    throttle_telemetry: LogThrottle,
    throttle_signing: LogThrottle,
    throttle_connect: LogThrottle,
    events: mpsc::Sender<LinkEvent>,
}

/// What kind of sender a message must come from.
enum Origin {
    /// The autopilot (system and component); from anyone else it is a spoofing attempt (or a
    /// misconfiguration), counted and logged.
    Autopilot,
    /// Only the autopilot's is used; others' are normal traffic on a shared link (a ground
    /// station's HEARTBEAT, acks meant for others), dropped quietly.
    AutopilotQuiet,
    /// TIMESYNC: only the autopilot's is used; others' are ground stations answering the
    /// requests the autopilot forwarded to them, counted and dropped quietly.
    AutopilotClock,
    /// Any component of the vehicle's system.
    Vehicle,
    /// Anyone (commands).
    Anyone,
    /// Not for the pipeline.
    Ignored,
}

#[allow(deprecated)] // MOUNT_ORIENTATION: deprecated in common.xml, still sent by some gimbals
fn origin(m: &MavMessage) -> Origin {
    match m {
        MavMessage::GLOBAL_POSITION_INT(_)
        | MavMessage::ATTITUDE(_)
        | MavMessage::HOME_POSITION(_) => Origin::Autopilot,
        MavMessage::TIMESYNC(_) => Origin::AutopilotClock,
        MavMessage::HEARTBEAT(_) | MavMessage::SYSTEM_TIME(_) | MavMessage::COMMAND_ACK(_) => {
            Origin::AutopilotQuiet
        }
        MavMessage::GIMBAL_DEVICE_ATTITUDE_STATUS(_)
        | MavMessage::MOUNT_ORIENTATION(_)
        | MavMessage::MOUNT_STATUS(_) => Origin::Vehicle,
        MavMessage::COMMAND_LONG(_) | MavMessage::COMMAND_INT(_) => Origin::Anyone,
        _ => Origin::Ignored,
    }
}

/// The autopilot's boot time in a message, where it has one.
fn boot_ms(m: &MavMessage) -> Option<u32> {
    match m {
        MavMessage::GLOBAL_POSITION_INT(p) => Some(p.time_boot_ms),
        MavMessage::ATTITUDE(a) => Some(a.time_boot_ms),
        MavMessage::SYSTEM_TIME(s) => Some(s.time_boot_ms),
        _ => None,
    }
}

impl LinkTask {
    fn since_start(&self) -> Duration {
        self.started.elapsed()
    }

    async fn run(
        mut self,
        mut out_rx: mpsc::Receiver<Outgoing>,
        mut stop: oneshot::Receiver<()>,
    ) -> LinkStats {
        let mut backoff = RECONNECT_INITIAL;
        let mut parser = FrameParser::new();
        let mut buf = vec![0u8; 65_536];
        let mut tick = tokio::time::interval(Duration::from_millis(50));
        tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
        'connect: loop {
            let opened = tokio::select! {
                _ = &mut stop => break 'connect,
                c = Connection::open(&self.endpoint) => c,
            };
            let mut conn = match opened {
                Ok(c) => {
                    self.stats.connects += 1;
                    tracing::info!(link = %c.describe(), "MAVLink link open");
                    backoff = RECONNECT_INITIAL;
                    c
                }
                Err(e) => {
                    if let Some(suppressed) = self.throttle_connect.allow() {
                        tracing::warn!(
                            connection = %self.settings.connection, error = %e,
                            retry_in_ms = backoff.as_millis() as u64, suppressed,
                            "MAVLink link cannot open; retrying"
                        );
                    }
                    tokio::select! {
                        _ = &mut stop => break 'connect,
                        _ = tokio::time::sleep(backoff) => {}
                    }
                    backoff = (backoff * 2).min(RECONNECT_MAX);
                    // Messages queued meanwhile would be stale: count them as not sent.
                    while out_rx.try_recv().is_ok() {
                        self.stats.messages_not_sent += 1;
                    }
                    continue 'connect;
                }
            };
            parser.reset();
            loop {
                tokio::select! {
                    _ = &mut stop => {
                        self.flush(&mut conn, &mut out_rx).await;
                        break 'connect;
                    }
                    got = conn.recv(&mut buf) => match got {
                        Transported::Bytes(bytes, from) => {
                            // A datagram holds whole frames; a stream may split them.
                            let frames = if from.is_some() {
                                parser.push_datagram(&bytes)
                            } else {
                                parser.push(&bytes)
                            };
                            for raw in frames {
                                self.handle(raw, from, &mut conn).await;
                            }
                        }
                        Transported::Closed => {
                            tracing::warn!(link = %conn.describe(), "MAVLink peer closed the link; reconnecting");
                            continue 'connect;
                        }
                        Transported::Error(e) => {
                            tracing::debug!(error = %e, "MAVLink receive");
                            tokio::time::sleep(Duration::from_millis(10)).await;
                        }
                    },
                    out = out_rx.recv() => match out {
                        Some(o) => {
                            if !self.send(&mut conn, o).await {
                                tracing::warn!(link = %conn.describe(), "MAVLink peer stopped reading; reconnecting");
                                continue 'connect;
                            }
                        }
                        None => break 'connect,
                    },
                    _ = tick.tick() => {
                        if !self.periodic(&mut conn).await {
                            continue 'connect;
                        }
                    }
                }
            }
        }
        self.stats.frames_received = parser.counters().frames;
        self.stats.frames_bad_crc = parser.counters().bad_crc;
        if let Some(s) = &mut self.signer {
            if let Err(e) = s.persist() {
                tracing::warn!(error = %e, "signing state not saved");
            }
        }
        self.stats
    }

    /// Sends what is queued, for at most [`FLUSH_TIMEOUT`].
    async fn flush(&mut self, conn: &mut Connection, out_rx: &mut mpsc::Receiver<Outgoing>) {
        let deadline = Instant::now() + FLUSH_TIMEOUT;
        while let Ok(o) = out_rx.try_recv() {
            if Instant::now() >= deadline || !self.send(conn, o).await {
                break;
            }
        }
    }

    /// The peer to send to on `udpin` (`None` elsewhere: the connection knows).
    fn destination(&self, conn: &Connection) -> Option<SocketAddr> {
        if self.endpoint.is_udp_in() {
            self.peer
        } else {
            conn.fixed_remote()
        }
    }

    fn encode(&mut self, message: &MavMessage) -> MAVLinkV2MessageRaw {
        let header = MavHeader {
            system_id: u32::from(self.settings.system_id),
            component_id: self.settings.component_id,
            sequence: self.sequence,
        };
        self.sequence = self.sequence.wrapping_add(1);
        let mut raw = MAVLinkV2MessageRaw::new();
        match &mut self.signer {
            Some(signer) => {
                raw.serialize_message_for_signing(header, message);
                signer.sign(&mut raw);
            }
            None => raw.serialize_message(header, message),
        }
        raw
    }

    /// Sends one message; `false` when a stream peer stopped reading (reconnect).
    async fn send(&mut self, conn: &mut Connection, out: Outgoing) -> bool {
        let raw = self.encode(&out.message);
        self.send_raw(conn, raw.raw_bytes(), out.on_sent).await
    }

    async fn send_raw(
        &mut self,
        conn: &mut Connection,
        bytes: &[u8],
        on_sent: Option<OnSent>,
    ) -> bool {
        let to = self.destination(conn);
        if self.endpoint.is_udp_in() && to.is_none() {
            self.stats.messages_not_sent += 1;
            return true;
        }
        match tokio::time::timeout(WRITE_TIMEOUT, conn.send(bytes, to)).await {
            Ok(Ok(true)) => {
                self.stats.messages_sent += 1;
                if let Some(tap) = &self.settings.tap {
                    (tap.0)(bytes);
                }
                if let Some(f) = on_sent {
                    f(crate::clock::now());
                }
                true
            }
            Ok(Ok(false)) => {
                self.stats.messages_not_sent += 1;
                true
            }
            Ok(Err(e)) => {
                self.stats.messages_not_sent += 1;
                tracing::debug!(error = %e, "MAVLink send failed");
                // UDP errors pass; a stream that fails is reconnected.
                matches!(conn, Connection::Udp { .. })
            }
            Err(_) => {
                self.stats.messages_not_sent += 1;
                false
            }
        }
    }

    /// Timers: stream requests, TIMESYNC, signing state. `false`: reconnect.
    async fn periodic(&mut self, conn: &mut Connection) -> bool {
        let autopilot_here = self
            .autopilot_heard
            .is_some_and(|t| t.elapsed() < AUTOPILOT_SILENCE);
        if autopilot_here {
            for message in [self.stream_request_due(), self.timesync_due()]
                .into_iter()
                .flatten()
            {
                let out = Outgoing {
                    message,
                    on_sent: None,
                };
                if !self.send(conn, out).await {
                    return false;
                }
            }
        }
        if self.last_persist.elapsed() >= Duration::from_secs(1) {
            self.last_persist = Instant::now();
            self.persist_signing();
        }
        true
    }

    /// The next SET_MESSAGE_INTERVAL request, when one is due.
    fn stream_request_due(&mut self) -> Option<MavMessage> {
        if self.settings.streams.is_empty() {
            return None;
        }
        let req = self.streams.poll(self.since_start())?;
        self.stats.stream_requests += 1;
        tracing::debug!(
            message_id = req.message_id,
            rate_hz = req.rate_hz,
            "requesting stream"
        );
        Some(message_interval_request(
            self.settings.system_id,
            self.settings.autopilot_component_id,
            req.message_id,
            req.rate_hz,
        ))
    }

    /// The next TIMESYNC request, when one is due (recorded as outstanding).
    fn timesync_due(&mut self) -> Option<MavMessage> {
        let hz = self.settings.timesync_hz;
        let due = hz > 0.0
            && self
                .last_timesync
                .is_none_or(|t| t.elapsed().as_secs_f64() >= 1.0 / hz);
        if !due {
            return None;
        }
        self.last_timesync = Some(Instant::now());
        let now = crate::clock::now();
        let ts1 = i64::try_from(now.0.saturating_mul(1000)).unwrap_or(i64::MAX);
        self.timesync.sent(ts1);
        Some(match timesync_request(now) {
            MavMessage::TIMESYNC(mut t) => {
                // Addressed to the autopilot: a ground station that also answers broadcast
                // requests is not asked.
                t.target_system = self.settings.system_id;
                t.target_component = self.settings.autopilot_component_id;
                MavMessage::TIMESYNC(t)
            }
            other => other,
        })
    }

    fn persist_signing(&mut self) {
        if let Some(s) = self.signer.as_mut().filter(|s| s.is_dirty()) {
            if let Err(e) = s.persist() {
                if let Some(suppressed) = self.throttle_signing.allow() {
                    tracing::warn!(error = %e, suppressed, "signing state not saved");
                }
            }
        }
    }

    /// One frame from `from` (UDP) or the stream.
    async fn handle(
        &mut self,
        raw: MAVLinkMessageRaw,
        from: Option<SocketAddr>,
        conn: &mut Connection,
    ) {
        let at = crate::clock::now();
        if let Some(tap) = &self.settings.tap {
            let bytes = match &raw {
                MAVLinkMessageRaw::V1(r) => r.raw_bytes(),
                MAVLinkMessageRaw::V2(r) => r.raw_bytes(),
            };
            (tap.0)(bytes);
        }
        // 1. The peer.
        if let (Some(from), Some(remote)) = (from, conn.fixed_remote()) {
            if from != remote {
                self.foreign_peer(from);
                return;
            }
        }
        let udp_in = self.endpoint.is_udp_in();
        let configured_peer = self.settings.udp_peer.is_some();
        let peer_may_change = udp_in
            && !configured_peer
            && self.peer_heard.is_none_or(|t| t.elapsed() >= PEER_TIMEOUT);
        if udp_in && self.peer.is_some() && from != self.peer && !peer_may_change {
            if let Some(f) = from {
                self.foreign_peer(f);
            }
            return;
        }
        // 2. The signature.
        let signed_flag = matches!(&raw, MAVLinkMessageRaw::V2(v2)
            if v2.incompatibility_flags() & mavlink_core::consts::v2::IFLAG_SIGNED != 0);
        let mut signed = false;
        if let (Some(signer), MAVLinkMessageRaw::V2(v2)) = (&mut self.signer, &raw) {
            if signed_flag {
                match signer.check(v2) {
                    Ok(()) => signed = true,
                    Err(why) => {
                        self.stats.signing_refused += 1;
                        if let Some(suppressed) = self.throttle_signing.allow() {
                            tracing::warn!(
                                system_id = raw.system_id(), component_id = raw.component_id(),
                                reason = ?why, suppressed,
                                "signed MAVLink frame refused"
                            );
                        }
                        let _: Refusal = why;
                        return;
                    }
                }
            }
        }
        let (Ok(system_id), component_id) = (u8::try_from(raw.system_id()), raw.component_id())
        else {
            return;
        };
        let vehicle = system_id == self.settings.system_id;
        // 3. A udpin peer is taken on a valid frame from the vehicle (signed, with signing on).
        if udp_in && from != self.peer && peer_may_change {
            let from_autopilot_ids =
                vehicle && component_id == self.settings.autopilot_component_id;
            let authenticated = self.signer.is_none()
                || signed
                || (self.settings.accept_unsigned_telemetry && from_autopilot_ids);
            if !(vehicle && authenticated) || from.is_none() {
                if let Some(f) = from {
                    self.foreign_peer(f);
                }
                return;
            }
            tracing::info!(peer = ?from, previous = ?self.peer, "MAVLink peer");
            self.peer = from;
        }
        if udp_in && from == self.peer {
            self.peer_heard = Some(Instant::now());
        }
        // 4. A command beyond its sender's budget is dropped unanswered (and counted).
        let id = raw.message_id();
        if (id == dialect::COMMAND_LONG_DATA::ID || id == dialect::COMMAND_INT_DATA::ID)
            && !self
                .commands
                .admit((system_id, component_id), Instant::now())
        {
            self.stats.commands_over_budget += 1;
            if let Some(suppressed) = self.throttle_commands.allow() {
                tracing::warn!(
                    system_id,
                    component_id,
                    suppressed,
                    "commands beyond {COMMANDS_PER_S} a second from one sender dropped unanswered"
                );
            }
            return;
        }
        // 5. The message.
        let message = match MavMessage::parse(raw.version(), raw.message_id(), raw.payload()) {
            Ok(m) => m,
            Err(_) => {
                self.unknown_command(&raw, system_id, component_id, conn)
                    .await;
                return;
            }
        };
        let from_autopilot = vehicle && component_id == self.settings.autopilot_component_id;
        let telemetry_ok =
            signed || self.signer.is_none() || self.settings.accept_unsigned_telemetry;
        let allowed = match origin(&message) {
            Origin::Autopilot => from_autopilot && telemetry_ok,
            Origin::AutopilotQuiet if !from_autopilot => return,
            Origin::AutopilotQuiet => telemetry_ok,
            Origin::AutopilotClock if !from_autopilot => {
                self.stats.timesync_from_others += 1;
                tracing::debug!(
                    system_id,
                    component_id,
                    "TIMESYNC from a sender other than the autopilot ignored"
                );
                return;
            }
            Origin::AutopilotClock => telemetry_ok,
            Origin::Vehicle => vehicle && telemetry_ok,
            Origin::Anyone => true,
            Origin::Ignored => return,
        };
        if !allowed {
            self.stats.telemetry_from_others += 1;
            if let Some(suppressed) = self.throttle_telemetry.allow() {
                tracing::warn!(
                    system_id, component_id, message = message.message_name(), suppressed,
                    signed,
                    "telemetry from a sender other than the configured autopilot (or unsigned while signed telemetry is required) ignored"
                );
            }
            return;
        }
        if from_autopilot {
            self.autopilot_message(&message);
        }
        match &message {
            MavMessage::TIMESYNC(t) if t.tc1 != 0 => {
                if self.timesync.answer(t.ts1, at.0) {
                    let sent = CompanionTimeUs(u64::try_from(t.ts1 / 1000).unwrap_or(0));
                    let autopilot = AutopilotTimeUs(u64::try_from(t.tc1 / 1000).unwrap_or(0));
                    self.emit(LinkEvent::TimeSync {
                        sent,
                        autopilot,
                        at,
                    });
                } else {
                    self.stats.timesync_unmatched += 1;
                    tracing::debug!(
                        ts1 = t.ts1,
                        "TIMESYNC answer from the autopilot to no request of ours ignored"
                    );
                }
                return;
            }
            MavMessage::TIMESYNC(_) => return,
            MavMessage::COMMAND_ACK(a) => {
                if a.command == MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL {
                    let outcome = match a.result {
                        MavResult::MAV_RESULT_ACCEPTED | MavResult::MAV_RESULT_IN_PROGRESS => {
                            AckOutcome::Accepted
                        }
                        MavResult::MAV_RESULT_DENIED
                        | MavResult::MAV_RESULT_UNSUPPORTED
                        | MavResult::MAV_RESULT_FAILED => AckOutcome::Refused,
                        _ => AckOutcome::Retry,
                    };
                    if outcome == AckOutcome::Refused {
                        tracing::info!(result = ?a.result, "the autopilot refused a stream request (not asked again until it reboots)");
                    }
                    self.streams.ack(outcome, self.since_start());
                }
                return;
            }
            _ => {}
        }
        if signed
            && matches!(
                message,
                MavMessage::COMMAND_LONG(_) | MavMessage::COMMAND_INT(_)
            )
        {
            // A signed command is acted on only once its stream's timestamp is on disk: after
            // a SIGKILL or a power cut right after it, a replay of it is refused.
            self.persist_signing();
        }
        self.emit(LinkEvent::Message(Box::new(Received {
            message,
            system_id,
            component_id,
            signed,
            at,
        })));
    }

    fn emit(&mut self, e: LinkEvent) {
        if self.events.try_send(e).is_err() {
            self.stats.events_dropped += 1;
        }
    }

    fn foreign_peer(&mut self, from: SocketAddr) {
        self.stats.from_other_peers += 1;
        if let Some(suppressed) = self.throttle_peer.allow() {
            tracing::warn!(%from, peer = ?self.peer, suppressed, "MAVLink datagram from another peer ignored");
        }
    }

    /// Bookkeeping for a message from the autopilot: presence, reboots, stream arrivals.
    fn autopilot_message(&mut self, m: &MavMessage) {
        let now = self.since_start();
        let returned = self
            .autopilot_heard
            .is_some_and(|t| t.elapsed() >= AUTOPILOT_SILENCE);
        let at = CompanionTimeUs(u64::try_from(now.as_micros()).unwrap_or(u64::MAX));
        let rebooted = boot_ms(m).is_some_and(|ms| {
            let stamp = AutopilotTimeUs::from_boot_ms(ms);
            matches!(
                self.autopilot_clock.observe(stamp, at),
                StampVerdict::Rebooted { .. }
            )
        });
        // A reboot confirmed by the stamps of streams just asked for again after the
        // autopilot's silence is the same event: the streams are not asked for twice.
        let just_asked = self
            .streams_reset_at
            .is_some_and(|t| now.saturating_sub(t) < AUTOPILOT_SILENCE);
        if returned || (rebooted && !just_asked) {
            self.streams_reset_at = Some(now);
            self.stats.autopilot_restarts += 1;
            if let Some(suppressed) = self.throttle_restart.allow() {
                tracing::warn!(
                    rebooted,
                    suppressed,
                    "autopilot back ({}); asking for its streams again",
                    if rebooted {
                        "it rebooted"
                    } else {
                        "after silence"
                    }
                );
            }
            self.streams.reset(now);
        }
        self.autopilot_heard = Some(Instant::now());
        if let MavMessage::HEARTBEAT(hb) = m {
            self.streams.autopilot_type(hb.autopilot);
        }
        self.streams.seen(m.message_id(), now);
    }

    /// A frame that does not decode: if it is a COMMAND_LONG / COMMAND_INT addressed to us
    /// with a command id the dialect does not know, answer MAV_RESULT_UNSUPPORTED.
    async fn unknown_command(
        &mut self,
        raw: &MAVLinkMessageRaw,
        system_id: u8,
        component_id: u8,
        conn: &mut Connection,
    ) {
        let id = raw.message_id();
        if id != dialect::COMMAND_LONG_DATA::ID && id != dialect::COMMAND_INT_DATA::ID {
            return;
        }
        // Both carry `command` at byte 28 and the target at 30..32 (MAVLink 2 trims trailing
        // zero bytes, so the payload is padded back).
        let mut p = [0u8; 35];
        let payload = raw.payload();
        let n = payload.len().min(p.len());
        p[..n].copy_from_slice(&payload[..n]);
        let command = u16::from_le_bytes([p[28], p[29]]);
        let (target_system, target_component) = (p[30], p[31]);
        let for_us = (target_system == 0 || target_system == self.settings.system_id)
            && target_component == self.settings.component_id;
        if !for_us {
            return;
        }
        if let Some(suppressed) = self.throttle_unknown.allow() {
            tracing::info!(
                command,
                from_system = system_id,
                suppressed,
                "unknown command answered UNSUPPORTED"
            );
        }
        let bytes = self.unsupported_ack(command, system_id, component_id);
        self.send_raw(conn, &bytes, None).await;
    }

    /// COMMAND_ACK UNSUPPORTED for a command id the typed dialect cannot hold: encoded with
    /// a placeholder command, then the id written into the payload and the CRC (and
    /// signature) made again.
    fn unsupported_ack(
        &mut self,
        command: u16,
        target_system: u8,
        target_component: u8,
    ) -> Vec<u8> {
        let ack = MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
            command: MavCmd::MAV_CMD_NAV_WAYPOINT,
            result: MavResult::MAV_RESULT_UNSUPPORTED,
            progress: 0,
            result_param2: 0,
            target_system,
            target_component,
        });
        let header = MavHeader {
            system_id: u32::from(self.settings.system_id),
            component_id: self.settings.component_id,
            sequence: self.sequence,
        };
        self.sequence = self.sequence.wrapping_add(1);
        let mut raw = MAVLinkV2MessageRaw::new();
        if self.signer.is_some() {
            raw.serialize_message_for_signing(header, &ack);
        } else {
            raw.serialize_message(header, &ack);
        }
        let len = usize::from(raw.payload_length());
        let bytes = raw.as_mut_slice();
        bytes[10..12].copy_from_slice(&command.to_le_bytes());
        let crc = mavlink_core::calculate_crc(&bytes[1..10 + len], COMMAND_ACK_DATA::EXTRA_CRC);
        bytes[10 + len..12 + len].copy_from_slice(&crc.to_le_bytes());
        if let Some(signer) = &mut self.signer {
            signer.sign(&mut raw);
        }
        raw.raw_bytes().to_vec()
    }
}
