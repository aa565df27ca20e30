//! MAVLink 2 signing (<https://mavlink.io/en/guide/message_signing.html>) as mgmot uses it.
//!
//! With a key configured, every message mgmot sends is signed (the link id from the
//! configuration; the timestamp is the spec's: 10 µs units since 2015-01-01 UTC, strictly
//! increasing, as `mavlink_core` writes it). Incoming frames:
//!
//! - signed frames are verified by `mavlink_core` (signature and per-stream replay
//!   protection); a frame with a bad signature or a replayed timestamp is dropped before it
//!   reaches mgmot;
//! - unsigned frames are let through the connection (`allow_unsigned`) so that telemetry from
//!   an autopilot or router that does not sign still feeds the geolocation, and
//!   [`is_signed`] tells the receiver which frames were signed: commands that were not are
//!   refused (COMMAND_ACK MAV_RESULT_DENIED) and not carried out.
//!
//! ArduPilot and PX4 drop unsigned packets silently when signing is on. mgmot answers DENIED
//! instead: it is a component behind the autopilot or a router, and a GCS that forgot to sign
//! sees at once why its tracking command did nothing, rather than retrying into a timeout. The
//! answer carries nothing secret and goes only to the sender named in the frame.

use super::dialect::MavMessage;
use mavlink_core::error::ParserError;
use mavlink_core::{MAVLinkMessageRaw, MavHeader, Message, SigningConfig};

/// The connection's signing configuration for `key`: sign everything sent with `link_id`,
/// verify signed frames, pass unsigned ones on (to be sorted by [`is_signed`]).
pub fn signing_config(key: [u8; 32], link_id: u8) -> SigningConfig {
    SigningConfig::new(key, link_id, true, true)
}

/// Whether a received frame carried a signature. On a connection set up with
/// [`signing_config`], a signed frame that arrives has passed verification.
pub fn is_signed(raw: &MAVLinkMessageRaw) -> bool {
    match raw {
        MAVLinkMessageRaw::V1(_) => false,
        MAVLinkMessageRaw::V2(m) => {
            m.incompatibility_flags() & mavlink_core::consts::v2::IFLAG_SIGNED != 0
        }
    }
}

/// The header and message of a received frame.
pub fn parse_raw(raw: &MAVLinkMessageRaw) -> Result<(MavHeader, MavMessage), ParserError> {
    let message = MavMessage::parse(raw.version(), raw.message_id(), raw.payload())?;
    let header = MavHeader {
        system_id: raw.system_id(),
        component_id: raw.component_id(),
        sequence: raw.sequence(),
    };
    Ok((header, message))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mavlink::dialect::{MavCmd, COMMAND_LONG_DATA, HEARTBEAT_DATA};
    use mavlink_core::{MavlinkReader, MavlinkVersion, SigningData};

    const KEY: [u8; 32] = [7; 32];

    fn frame(signing: Option<&SigningData>, system_id: u32, m: &MavMessage) -> Vec<u8> {
        let mut buf = Vec::new();
        let header = MavHeader {
            system_id,
            component_id: 190,
            sequence: 0,
        };
        mavlink_core::write_versioned_msg_signed(&mut buf, MavlinkVersion::V2, header, m, signing)
            .unwrap();
        buf
    }

    fn command() -> MavMessage {
        MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
            target_system: 1,
            target_component: 191,
            command: MavCmd::MAV_CMD_CAMERA_STOP_TRACKING,
            ..Default::default()
        })
    }

    /// Reads every frame of `bytes` the way the runtime's connection does.
    fn receive(bytes: &[u8]) -> Vec<(bool, MavHeader, MavMessage)> {
        let ours = SigningData::from_config(signing_config(KEY, 0));
        let mut reader = MavlinkReader::new(bytes);
        let mut out = Vec::new();
        while let Ok(raw) =
            reader.read_raw_message_signed::<MavMessage>(MavlinkVersion::V2, Some(&ours))
        {
            let (h, m) = parse_raw(&raw).unwrap();
            out.push((is_signed(&raw), h, m));
        }
        out
    }

    #[test]
    fn signed_frames_are_verified_and_unsigned_ones_pass_marked() {
        let good = SigningData::from_config(SigningConfig::new(KEY, 3, true, false));
        let wrong_key = SigningData::from_config(SigningConfig::new([8; 32], 3, true, false));
        let heartbeat = MavMessage::HEARTBEAT(HEARTBEAT_DATA::default());
        let mut bytes = frame(None, 1, &heartbeat);
        bytes.extend(frame(Some(&good), 255, &command()));
        bytes.extend(frame(Some(&wrong_key), 254, &command()));
        bytes.extend(frame(None, 253, &command()));
        let got: Vec<(bool, u32)> = receive(&bytes)
            .into_iter()
            .map(|(signed, h, _)| (signed, h.system_id))
            .collect();
        // The forged command (wrong key) is dropped; the unsigned ones arrive, marked.
        assert_eq!(got, [(false, 1), (true, 255), (false, 253)]);
    }

    #[test]
    fn a_replayed_signed_frame_is_dropped() {
        let gcs = SigningData::from_config(SigningConfig::new(KEY, 0, true, false));
        let once = frame(Some(&gcs), 255, &command());
        let mut twice = once.clone();
        twice.extend(&once);
        assert_eq!(receive(&twice).len(), 1);
    }

    #[test]
    fn outgoing_frames_are_signed_with_our_link_id() {
        let ours = SigningData::from_config(signing_config(KEY, 9));
        let bytes = frame(Some(&ours), 1, &command());
        let mut reader = MavlinkReader::new(&bytes[..]);
        let raw = reader
            .read_raw_message::<MavMessage>(MavlinkVersion::V2)
            .unwrap();
        assert!(is_signed(&raw));
        let MAVLinkMessageRaw::V2(v2) = raw else {
            panic!("not MAVLink 2")
        };
        assert_eq!(v2.signature_link_id(), 9);
    }
}
