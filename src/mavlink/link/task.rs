//! The link's task: the connection loop (connect, read, write, reconnect with back-off), the
//! periodic work (stream requests, TIMESYNC, the signing state) and sending.

use super::command_budget::CommandBudget;
use super::events::{LinkEvent, LinkStats};
use super::frames::FrameParser;
use super::sender::{OnSent, Outgoing};
use super::settings::{
    LinkError, LinkSettings, AUTOPILOT_SILENCE, FLUSH_TIMEOUT, RECONNECT_INITIAL, RECONNECT_MAX,
    WRITE_TIMEOUT,
};
use super::streams::StreamRequests;
use super::timesync::TimeSyncRequests;
use super::transport::{Connection, Endpoint, Received as Transported};

use crate::logging::LogThrottle;
use crate::mavlink::dialect::MavMessage;
use crate::mavlink::encode::{message_interval_request, timesync_request};
use crate::mavlink::signing::Signer;
use crate::telemetry::RebootDetector;
use mavlink_core::{MAVLinkV2MessageRaw, MavHeader};
use std::net::SocketAddr;
use std::time::{Duration, Instant};
use tokio::sync::{mpsc, oneshot};

pub(super) struct LinkTask {
    pub(super) settings: LinkSettings,
    pub(super) endpoint: Endpoint,
    pub(super) signer: Option<Signer>,
    pub(super) streams: StreamRequests,
    pub(super) timesync: TimeSyncRequests,
    /// `udpin`: the peer answered.
    pub(super) peer: Option<SocketAddr>,
    pub(super) peer_heard: Option<Instant>,
    pub(super) sequence: u8,
    pub(super) started: Instant,
    pub(super) autopilot_heard: Option<Instant>,
    /// Whether the autopilot's stamps say it rebooted: the same judge as the clock mapping's
    /// and the pose buffer's, so a stray or forged stamp near zero is no reboot here either.
    pub(super) autopilot_clock: RebootDetector,
    /// When the streams were last asked for again (since start).
    pub(super) streams_reset_at: Option<Duration>,
    pub(super) throttle_restart: LogThrottle,
    /// Commands each sender may have answered.
    pub(super) commands: CommandBudget,
    pub(super) throttle_commands: LogThrottle,
    pub(super) throttle_unknown: LogThrottle,
    pub(super) last_timesync: Option<Instant>,
    pub(super) last_persist: Instant,
    pub(super) stats: LinkStats,
    pub(super) throttle_peer: LogThrottle,
    pub(super) throttle_telemetry: LogThrottle,
    pub(super) throttle_signing: LogThrottle,
    pub(super) throttle_connect: LogThrottle,
    pub(super) events: mpsc::Sender<LinkEvent>,
}

impl LinkTask {
    /// The task of a link with these settings, handing its events to `events`. Fails on a bad
    /// connection string or an unusable signing state file.
    pub(super) fn new(
        settings: LinkSettings,
        events: mpsc::Sender<LinkEvent>,
    ) -> Result<Self, LinkError> {
        let endpoint = Endpoint::parse(&settings.connection)?;
        let signer = match &settings.signing {
            Some(s) => Some(Signer::new(s.key, s.link_id, s.state_file.as_deref())?),
            None => None,
        };
        Ok(LinkTask {
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
            events,
        })
    }

    pub(super) fn since_start(&self) -> Duration {
        self.started.elapsed()
    }

    pub(super) async fn run(
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
    pub(super) async fn flush(
        &mut self,
        conn: &mut Connection,
        out_rx: &mut mpsc::Receiver<Outgoing>,
    ) {
        let deadline = Instant::now() + FLUSH_TIMEOUT;
        while let Ok(o) = out_rx.try_recv() {
            if Instant::now() >= deadline || !self.send(conn, o).await {
                break;
            }
        }
    }

    /// The peer to send to on `udpin` (`None` elsewhere: the connection knows).
    pub(super) fn destination(&self, conn: &Connection) -> Option<SocketAddr> {
        if self.endpoint.is_udp_in() {
            self.peer
        } else {
            conn.fixed_remote()
        }
    }

    /// `message` under our header and next sequence number, laid out for signing when
    /// signing is on, not yet signed.
    pub(super) fn serialize(&mut self, message: &MavMessage) -> MAVLinkV2MessageRaw {
        let header = MavHeader {
            system_id: u32::from(self.settings.system_id),
            component_id: self.settings.component_id,
            sequence: self.sequence,
        };
        self.sequence = self.sequence.wrapping_add(1);
        let mut raw = MAVLinkV2MessageRaw::new();
        if self.signer.is_some() {
            raw.serialize_message_for_signing(header, message);
        } else {
            raw.serialize_message(header, message);
        }
        raw
    }

    /// `message` ready to send: serialized and, when signing is on, signed.
    pub(super) fn encode(&mut self, message: &MavMessage) -> MAVLinkV2MessageRaw {
        let mut raw = self.serialize(message);
        if let Some(signer) = &mut self.signer {
            signer.sign(&mut raw);
        }
        raw
    }

    /// Sends one message; `false` when a stream peer stopped reading (reconnect).
    pub(super) async fn send(&mut self, conn: &mut Connection, out: Outgoing) -> bool {
        let raw = self.encode(&out.message);
        self.send_raw(conn, raw.raw_bytes(), out.on_sent).await
    }

    pub(super) async fn send_raw(
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
    pub(super) async fn periodic(&mut self, conn: &mut Connection) -> bool {
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
    pub(super) fn stream_request_due(&mut self) -> Option<MavMessage> {
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
    pub(super) fn timesync_due(&mut self) -> Option<MavMessage> {
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

    pub(super) fn persist_signing(&mut self) {
        if let Some(s) = self.signer.as_mut().filter(|s| s.is_dirty()) {
            if let Err(e) = s.persist() {
                if let Some(suppressed) = self.throttle_signing.allow() {
                    tracing::warn!(error = %e, suppressed, "signing state not saved");
                }
            }
        }
    }
}
