//! What the link hands the pipeline ([`LinkEvent`]) and its counters ([`LinkStats`]).

use crate::mavlink::dialect::MavMessage;
use crate::telemetry::{AutopilotTimeUs, CompanionTimeUs};

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
