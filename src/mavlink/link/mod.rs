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
//! - **pose, home and clock** (GLOBAL_POSITION_INT, ATTITUDE, GPS_RAW_INT, HOME_POSITION, TIMESYNC,
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

mod admission;
pub mod command_budget;
mod events;
pub mod frames;
mod sender;
mod settings;
pub mod streams;
mod task;
pub mod timesync;
pub mod transport;

pub use crate::logging::LOG_EVERY;
pub use events::{LinkEvent, LinkStats, Received};
pub use sender::{LinkSender, OnSent};
pub use settings::{
    LinkError, LinkSettings, PacketTap, SigningSettings, TapFn, AUTOPILOT_SILENCE, EVENT_QUEUE,
    FLUSH_TIMEOUT, OUT_QUEUE, PEER_TIMEOUT, RECONNECT_INITIAL, RECONNECT_MAX, WRITE_TIMEOUT,
};

use task::LinkTask;
use tokio::sync::{mpsc, oneshot};
use tokio::task::JoinHandle;

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
        let (out_tx, out_rx) = mpsc::channel(OUT_QUEUE);
        let (event_tx, event_rx) = mpsc::channel(EVENT_QUEUE);
        let (stop, stop_rx) = oneshot::channel();
        let task = LinkTask::new(settings, event_tx)?;
        let task = tokio::spawn(task.run(out_rx, stop_rx));
        Ok((Link { stop, task }, LinkSender::new(out_tx), event_rx))
    }

    /// Stops the link: what is queued is sent (for at most [`FLUSH_TIMEOUT`]), the signing
    /// state persisted, the counters returned.
    pub async fn close(self) -> LinkStats {
        let _ = self.stop.send(());
        self.task.await.unwrap_or_default()
    }
}
