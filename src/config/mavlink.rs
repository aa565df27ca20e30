//! `[mavlink]`: the link to the autopilot (or mavlink-router), and `[mavlink.signing]`.

use super::problems::{period, Problems};
use serde::{Deserialize, Serialize};
use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::Duration;

/// The MAVLink link.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MavlinkConfig {
    /// `serial:/dev/ttyS0:921600`, `udpin:0.0.0.0:14550`, `udpout:HOST:PORT`, `tcpin:…`,
    /// `tcpout:…`.
    pub connection: String,
    /// Our system id: the vehicle's, since mgmot is one of its components.
    #[serde(default = "one")]
    pub system_id: u8,
    /// Our component id (191 = MAV_COMP_ID_ONBOARD_COMPUTER).
    #[serde(default = "onboard_computer")]
    pub component_id: u8,
    /// The autopilot's component id (1 = MAV_COMP_ID_AUTOPILOT1), target of the stream
    /// requests.
    #[serde(default = "one")]
    pub autopilot_component_id: u8,
    /// Rate asked for position, attitude and gimbal messages (Hz); 0 leaves the autopilot's
    /// own stream rates alone.
    #[serde(default = "default_stream_rate_hz")]
    pub stream_rate_hz: f32,
    /// TIMESYNC requests per second (0 = never; the arrival-time estimate is used instead).
    #[serde(default = "one_f64")]
    pub timesync_hz: f64,
    /// MAVLink 2 signing; absent = no signing.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub signing: Option<SigningConfig>,
    /// `udpin` only: the one peer (`IP:PORT`, the autopilot or router) mgmot answers. Absent:
    /// the first peer that sends a valid frame from the vehicle's system (signed, with signing
    /// on); another peer takes over only after that one has been silent for 5 s.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub udp_peer: Option<SocketAddr>,
}

/// MAVLink 2 signing.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SigningConfig {
    /// The 32-byte secret key as 64 hex digits (the same key as the autopilot and GCS).
    pub key_hex: String,
    /// Link id put in our signatures.
    #[serde(default)]
    pub link_id: u8,
    /// Where the signing timestamps are kept across restarts, so that a signed command
    /// captured before a restart cannot be replayed after it (the signing spec's advice). The
    /// file is written at start-up, every second and at exit; its directory must be writable.
    #[serde(default = "default_signing_state_file")]
    pub state_file: PathBuf,
    /// Use unsigned position, attitude, home, clock and gimbal messages from the autopilot
    /// (an autopilot or router that does not sign). Set false when the autopilot signs its
    /// link (ArduPilot with signing on signs everything): unsigned telemetry is then refused
    /// too. Commands must be signed either way.
    #[serde(default = "yes")]
    pub accept_unsigned_telemetry: bool,
}

/// The validated link settings.
#[derive(Debug, Clone, PartialEq)]
pub struct MavlinkSettings {
    /// The connection string, checked by `mavlink::parse_connection`.
    pub connection: String,
    /// Our system id (1..=255).
    pub system_id: u8,
    /// Our component id (1..=255).
    pub component_id: u8,
    /// The autopilot's component id.
    pub autopilot_component_id: u8,
    /// Rate asked for telemetry streams (Hz, 0..=400); 0 leaves them alone.
    pub stream_rate_hz: f32,
    /// Time between TIMESYNC requests; `None` never sends one.
    pub timesync_every: Option<Duration>,
    /// Signing, with the key decoded.
    pub signing: Option<SigningSettings>,
    /// The one `udpin` peer, if fixed.
    pub udp_peer: Option<SocketAddr>,
}

/// The validated signing settings.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SigningSettings {
    /// The 32-byte secret key.
    pub key: [u8; 32],
    /// Link id put in our signatures.
    pub link_id: u8,
    /// Where the signing timestamps are kept across restarts.
    pub state_file: PathBuf,
    /// Use unsigned telemetry from the autopilot.
    pub accept_unsigned_telemetry: bool,
}

pub(super) fn default_signing_state_file() -> PathBuf {
    PathBuf::from("/var/lib/mgmot/signing-state.json")
}

fn yes() -> bool {
    true
}
fn one() -> u8 {
    1
}
fn one_f64() -> f64 {
    1.0
}
fn onboard_computer() -> u8 {
    crate::mavlink::COMPONENT_ID
}
fn default_stream_rate_hz() -> f32 {
    50.0
}

impl SigningConfig {
    /// The key bytes, if `key_hex` is 64 hex digits.
    pub fn key(&self) -> Option<[u8; 32]> {
        let s = self.key_hex.trim();
        if s.len() != 64 || !s.is_ascii() {
            return None;
        }
        let mut key = [0u8; 32];
        for (i, b) in key.iter_mut().enumerate() {
            *b = u8::from_str_radix(&s[2 * i..2 * i + 2], 16).ok()?;
        }
        Some(key)
    }

    fn validate(&self, p: &mut Problems) -> Option<SigningSettings> {
        let Some(key) = self.key() else {
            p.push(
                "mavlink.signing.key_hex",
                format!(
                    "must be 64 hex digits (32 bytes), got {} characters",
                    self.key_hex.trim().len()
                ),
            );
            return None;
        };
        Some(SigningSettings {
            key,
            link_id: self.link_id,
            state_file: self.state_file.clone(),
            accept_unsigned_telemetry: self.accept_unsigned_telemetry,
        })
    }
}

impl MavlinkConfig {
    /// The link settings, or the section's problems pushed onto `p`.
    pub fn validate(&self, p: &mut Problems) -> Option<MavlinkSettings> {
        let connection = match crate::mavlink::parse_connection(&self.connection) {
            Ok(_) => Some(self.connection.clone()),
            Err(e) => {
                p.push("mavlink.connection", e.to_string());
                None
            }
        };
        let id = |p: &mut Problems, key: &str, v: u8| p.check(v != 0, key, "must be 1..=255", v);
        let system_id = id(p, "mavlink.system_id", self.system_id);
        let component_id = id(p, "mavlink.component_id", self.component_id);
        let stream_rate_hz = p.within_closed(
            "mavlink.stream_rate_hz",
            f64::from(self.stream_rate_hz),
            0.0,
            400.0,
        );
        // Outer `None`: invalid; inner `None`: no TIMESYNC, no signing.
        let timesync_every =
            match p.within_closed("mavlink.timesync_hz", self.timesync_hz, 0.0, 50.0) {
                Some(hz) if hz > 0.0 => period(p, "mavlink.timesync_hz", hz).map(Some),
                Some(_) => Some(None),
                None => None,
            };
        let signing = match &self.signing {
            Some(s) => s.validate(p).map(Some),
            None => Some(None),
        };
        Some(MavlinkSettings {
            connection: connection?,
            system_id: system_id?,
            component_id: component_id?,
            autopilot_component_id: self.autopilot_component_id,
            stream_rate_hz: stream_rate_hz.map(|_| self.stream_rate_hz)?,
            timesync_every: timesync_every?,
            signing: signing?,
            udp_peer: self.udp_peer,
        })
    }
}
