//! MAVLink telemetry and commands: bytes -> the link's own frame parser (as `mgmot run` reads
//! a stream or a datagram) and its signature check, and mavlink-core's MAVLink 2 frame reader
//! (with and without signature verification) -> `parse_raw` -> `decode` /
//! `decode_mount_status`; and arbitrary well-formed messages through encode -> read -> decode.

use super::{geodetic_ok, unit_quaternion_ok, Input};
use mavlink_core::{
    MAVLinkMessageRaw, MavHeader, MavlinkReader, MavlinkVersion, Message, SigningConfig,
    SigningData,
};
use mgmot::mavlink::dialect::MavMessage;
use mgmot::mavlink::link::frames::FrameParser;
use mgmot::mavlink::signing::Signer;
use mgmot::mavlink::{decode, decode_mount_status, is_signed, parse_raw, Incoming};
use mgmot::telemetry::AutopilotTimeUs;

/// The signing key of the seed corpus's signed frames (and of the verifying reader).
pub const KEY: [u8; 32] = [0x5a; 32];

/// A key nobody signs with.
const WRONG_KEY: [u8; 32] = [0xa5; 32];

/// The system and component ids the decoder is run as (mgmot's defaults).
pub const OUR_SYSTEM: u8 = 1;

/// mgmot's component id.
pub const OUR_COMPONENT: u8 = mgmot::mavlink::COMPONENT_ID;

/// Raw bytes as they arrive on a link: every MAVLink 2 frame mavlink-core's reader finds
/// (CRC-checked; once with no signing, once verifying signatures with [`KEY`] and letting
/// unsigned frames through, as `mgmot run` does) goes through `parse_raw` and the decoders.
pub fn frames(data: &[u8]) {
    link_parser(data);
    let verify = SigningData::from_config(mgmot::mavlink::signing_config(KEY, 0));
    for signing in [None, Some(&verify)] {
        let mut reader = MavlinkReader::new(data);
        // Every frame consumes at least one byte, so this bounds a reader that loops.
        for _ in 0..=data.len() {
            let Ok(raw) = reader.read_raw_message_signed::<MavMessage>(MavlinkVersion::V2, signing)
            else {
                break;
            };
            if signing.is_some() && is_signed(&raw) {
                // Through a verifying reader, a signed frame must carry our key's signature.
                let MAVLinkMessageRaw::V2(v2) = &raw else {
                    panic!("a signed frame that is not MAVLink 2");
                };
                let mut expected = [0u8; 6];
                v2.calculate_signature(&KEY, &mut expected);
                assert_eq!(
                    v2.signature_value(),
                    &expected[..],
                    "forged signature accepted"
                );
            }
            let Ok((header, msg)) = parse_raw(&raw) else {
                continue;
            };
            assert_eq!(msg.message_id(), raw.message_id());
            check_decoders(&msg, header.component_id, u64::from(header.sequence));
            round_trip(&msg, header, None);
        }
    }
}

/// The link's frame parser on `data`: cut into pieces anywhere it gives the frames it gives
/// for the whole bytes at once; each frame it returns (as a stream or a datagram) is read back
/// from its own bytes by mavlink-core, goes through the decoders, and a signed one the link's
/// signer accepts carries our key's signature.
fn link_parser(data: &[u8]) {
    fn bytes_of(raw: &MAVLinkMessageRaw) -> &[u8] {
        match raw {
            MAVLinkMessageRaw::V1(v1) => v1.raw_bytes(),
            MAVLinkMessageRaw::V2(v2) => v2.raw_bytes(),
        }
    }
    let whole = FrameParser::new().push(data);
    // Beyond this the parser drops unparsed bytes as garbage, where the cut matters.
    if data.len() < 64 * 1024 {
        let piece = data.first().map_or(1, |&b| 1 + usize::from(b % 23));
        let mut parser = FrameParser::new();
        let mut cut: Vec<_> = Vec::new();
        for chunk in data.chunks(piece) {
            cut.extend(parser.push(chunk));
        }
        let bytes = |frames: &[MAVLinkMessageRaw]| -> Vec<Vec<u8>> {
            frames.iter().map(|f| bytes_of(f).to_vec()).collect()
        };
        assert_eq!(bytes(&cut), bytes(&whole), "pieces of {piece} bytes");
    }
    let datagram = FrameParser::new().push_datagram(data);
    let mut signer = Signer::new(KEY, 0, None).expect("no state file to read");
    for raw in whole.iter().chain(&datagram) {
        let version = match raw {
            MAVLinkMessageRaw::V1(_) => MavlinkVersion::V1,
            MAVLinkMessageRaw::V2(_) => MavlinkVersion::V2,
        };
        let back = MavlinkReader::new(bytes_of(raw))
            .read_raw_message::<MavMessage>(version)
            .unwrap_or_else(|e| panic!("the link took a frame mavlink-core refuses: {e}"));
        assert_eq!(bytes_of(&back), bytes_of(raw));
        if let MAVLinkMessageRaw::V2(v2) = raw {
            if is_signed(raw) {
                // At the frame's own time (the accepting path) and with no clock.
                for wall in [v2.signature_timestamp(), 0] {
                    if signer.check_at(v2, wall).is_ok() {
                        let mut expected = [0u8; 6];
                        v2.calculate_signature(&KEY, &mut expected);
                        assert_eq!(v2.signature_value(), &expected[..], "forged signature");
                    }
                }
            }
        }
        if let Ok((header, msg)) = parse_raw(raw) {
            check_decoders(&msg, header.component_id, u64::from(header.sequence));
        }
    }
}

/// A well-formed message with arbitrary field values: `data` = message id (3 bytes, LE; an id
/// the dialect lacks picks one of its ids), system, component, sequence, whether to sign, link
/// id, then the payload. The payload is parsed by the dialect, so every field takes any value
/// its type allows (every float bit pattern, every enum value); then the message goes
/// through the decoders and encode -> frame -> read -> parse.
pub fn messages(data: &[u8]) {
    let mut input = Input::new(data);
    let id = u32::from_le_bytes([input.u8(), input.u8(), input.u8(), 0]);
    let ids = MavMessage::all_ids();
    let id = if ids.contains(&id) {
        id
    } else {
        ids[id as usize % ids.len()]
    };
    let header = MavHeader {
        system_id: input.u8().into(),
        component_id: input.u8(),
        sequence: input.u8(),
    };
    let sign = input.bool();
    let link_id = input.u8();
    let payload = input.bytes(255);
    let Ok(msg) = MavMessage::parse(MavlinkVersion::V2, id, payload) else {
        return;
    };
    assert_eq!(msg.message_id(), id);
    check_decoders(&msg, header.component_id, u64::from(header.sequence));
    let signer =
        sign.then(|| SigningData::from_config(SigningConfig::new(KEY, link_id, true, false)));
    round_trip(&msg, header, signer.as_ref());
}

/// Encodes `msg` in a MAVLink 2 frame (signed with `signer`) and reads it back as the runtime
/// does: it must arrive, marked signed or not, with its header and the same payload; a
/// signed frame must be refused under another key, an unsigned one where signing is required.
fn round_trip(msg: &MavMessage, header: MavHeader, signer: Option<&SigningData>) {
    let mut bytes = Vec::new();
    mavlink_core::write_versioned_msg_signed(&mut bytes, MavlinkVersion::V2, header, msg, signer)
        .expect("writing to a Vec cannot fail");
    let ours = SigningData::from_config(mgmot::mavlink::signing_config(KEY, 0));
    let raw = MavlinkReader::new(&bytes[..])
        .read_raw_message_signed::<MavMessage>(MavlinkVersion::V2, Some(&ours))
        .unwrap_or_else(|e| panic!("{} frame not read back: {e}", msg.message_name()));
    assert_eq!(is_signed(&raw), signer.is_some());
    let (h, back) = parse_raw(&raw)
        .unwrap_or_else(|e| panic!("{} frame not parsed back: {e}", msg.message_name()));
    assert_eq!(
        (h.system_id, h.component_id, h.sequence),
        (header.system_id, header.component_id, header.sequence)
    );
    assert_eq!(payload(&back), payload(msg), "{}", msg.message_name());

    let strict = |key| SigningData::from_config(SigningConfig::new(key, 0, false, false));
    let refused = |key| {
        MavlinkReader::new(&bytes[..])
            .read_raw_message_signed::<MavMessage>(MavlinkVersion::V2, Some(&strict(key)))
            .is_err()
    };
    if signer.is_some() {
        assert!(
            refused(WRONG_KEY),
            "signed frame accepted under another key"
        );
    } else {
        assert!(
            refused(KEY),
            "unsigned frame accepted where signing is required"
        );
    }
}

/// The serialised payload (bit-exact, so NaN fields compare equal to themselves).
fn payload(msg: &MavMessage) -> Vec<u8> {
    let mut buf = [0u8; 255];
    let n = msg.ser(MavlinkVersion::V2, &mut buf);
    buf[..n].to_vec()
}

/// Runs `decode` (as mgmot, and as every other component) and `decode_mount_status` on a
/// message: what they hand on as valid must be finite, and of the message's kind.
fn check_decoders(msg: &MavMessage, from_component: u8, time_us: u64) {
    for (our_system, our_component) in [(OUR_SYSTEM, OUR_COMPONENT), (255, 1)] {
        let Some(incoming) = decode(msg, from_component, our_system, our_component) else {
            continue;
        };
        let name = msg.message_name();
        let kind_ok = match incoming {
            Incoming::AutopilotHeartbeat => name == "HEARTBEAT",
            Incoming::Position(p) => {
                assert!(geodetic_ok(&p.sample.position), "{name}: {p:?}");
                assert!(
                    p.velocity_ned_mps
                        .is_none_or(|v| v.iter().all(|c| c.is_finite())),
                    "{name}: {p:?}"
                );
                name == "GLOBAL_POSITION_INT"
            }
            Incoming::Attitude(a) => {
                assert!(unit_quaternion_ok(&a.attitude), "{name}: {a:?}");
                name == "ATTITUDE"
            }
            Incoming::Gimbal {
                sample: g,
                quaternion_norm,
            } => {
                assert!(unit_quaternion_ok(&g.attitude), "{name}: {g:?}");
                assert!(quaternion_norm.is_none_or(f64::is_finite), "{name}: {g:?}");
                matches!(name, "GIMBAL_DEVICE_ATTITUDE_STATUS" | "MOUNT_ORIENTATION")
            }
            Incoming::Home(h) => {
                assert!(geodetic_ok(&h), "{name}: {h:?}");
                name == "HOME_POSITION"
            }
            Incoming::GnssAccuracy { h_acc_m } => {
                assert!(h_acc_m.is_finite() && h_acc_m > 0.0, "{name}: {h_acc_m}");
                name == "GPS_RAW_INT"
            }
            Incoming::TimeSyncAnswer { tc1_ns, .. } => tc1_ns != 0 && name == "TIMESYNC",
            Incoming::Command { .. }
            | Incoming::CameraInformationRequest
            | Incoming::UnsupportedCommand { .. } => {
                assert!(incoming.is_command() && incoming.mav_cmd().is_some());
                matches!(name, "COMMAND_LONG" | "COMMAND_INT")
            }
        };
        assert!(kind_ok, "{name} decoded as {incoming:?}");
    }
    if let Some(g) = decode_mount_status(msg, AutopilotTimeUs(time_us)) {
        assert_eq!(msg.message_name(), "MOUNT_STATUS");
        assert!(unit_quaternion_ok(&g.attitude), "MOUNT_STATUS: {g:?}");
        assert_eq!(g.time, AutopilotTimeUs(time_us));
    }
}
