//! Admission: who may talk to mgmot. Each frame from the transport is checked here (peer, signing,
//! origin by message type, the autopilot's clock, the command budget) before it becomes a
//! [`LinkEvent`](super::LinkEvent).

use super::command_budget::COMMANDS_PER_S;
use super::events::{LinkEvent, Received};
use super::settings::{AUTOPILOT_SILENCE, PEER_TIMEOUT};
use super::streams::AckOutcome;
use super::task::LinkTask;
use super::transport::Connection;

use crate::mavlink::dialect::{self, MavCmd, MavMessage, MavResult, COMMAND_ACK_DATA};
use crate::mavlink::signing::Refusal;
use crate::telemetry::{AutopilotTimeUs, CompanionTimeUs, StampVerdict};
use mavlink_core::{MAVLinkMessageRaw, Message, MessageData};
use std::net::SocketAddr;
use std::time::Instant;

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
        | MavMessage::GPS_RAW_INT(_)
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
    /// One frame from `from` (UDP) or the stream.
    pub(super) async fn handle(
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

    pub(super) fn emit(&mut self, e: LinkEvent) {
        if self.events.try_send(e).is_err() {
            self.stats.events_dropped += 1;
        }
    }

    pub(super) fn foreign_peer(&mut self, from: SocketAddr) {
        self.stats.from_other_peers += 1;
        if let Some(suppressed) = self.throttle_peer.allow() {
            tracing::warn!(%from, peer = ?self.peer, suppressed, "MAVLink datagram from another peer ignored");
        }
    }

    /// Bookkeeping for a message from the autopilot: presence, reboots, stream arrivals.
    pub(super) fn autopilot_message(&mut self, m: &MavMessage) {
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
    pub(super) async fn unknown_command(
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
    pub(super) fn unsupported_ack(
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
        let mut raw = self.serialize(&ack);
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
