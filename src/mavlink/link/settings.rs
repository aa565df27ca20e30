//! What the link is set up with: its settings, signing, the tap that sees every frame, its
//! fixed limits and timeouts, and why it could not be set up.

use crate::mavlink::address::AddressError;
use crate::mavlink::signing::SigningStateError;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::Duration;

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
