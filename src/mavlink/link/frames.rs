//! Raw MAVLink frames out of a byte stream or a datagram: finds the start byte, waits for the
//! whole frame, checks its CRC against the dialect, and resynchronises one byte further on
//! garbage. Pure (no IO); the link feeds it what its transport read.

use super::super::dialect::MavMessage;
use mavlink_core::{MAVLinkMessageRaw, MAVLinkV1MessageRaw, MAVLinkV2MessageRaw};

const STX_V1: u8 = 0xFE;
const STX_V2: u8 = 0xFD;
/// MAVLink 2 header after the start byte (len, incompat, compat, seq, sys, comp, msgid x3).
const V2_HEADER: usize = 9;
/// MAVLink 1 header after the start byte (len, seq, sys, comp, msgid).
const V1_HEADER: usize = 5;
const CRC: usize = 2;
const SIGNATURE: usize = 13;
/// More unparsed bytes than this without a frame is garbage, not a slow frame.
const MAX_PENDING: usize = 64 * 1024;

/// What the parser saw besides frames.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub struct ParseCounters {
    /// Whole frames with a valid CRC.
    pub frames: u64,
    /// Frames whose CRC did not match (corrupt, or a message id the dialect does not know).
    pub bad_crc: u64,
    /// Bytes skipped while looking for a start byte.
    pub skipped_bytes: u64,
}

/// Incremental frame parser.
#[derive(Debug, Default)]
pub struct FrameParser {
    pending: Vec<u8>,
    counters: ParseCounters,
}

impl FrameParser {
    /// An empty parser.
    pub fn new() -> Self {
        Self::default()
    }

    /// What was seen so far.
    pub fn counters(&self) -> ParseCounters {
        self.counters
    }

    /// Forgets a partial frame (a new connection starts clean).
    pub fn reset(&mut self) {
        self.pending.clear();
    }

    /// Parses one whole datagram: frames never span datagrams, so a start byte whose frame
    /// would run past the end is garbage, skipped, and parsing goes on after it. Nothing is
    /// kept for the next datagram.
    pub fn push_datagram(&mut self, bytes: &[u8]) -> Vec<MAVLinkMessageRaw> {
        self.pending.clear();
        let mut frames = self.push(bytes);
        while !self.pending.is_empty() {
            self.pending.remove(0);
            self.counters.skipped_bytes += 1;
            frames.extend(self.push(&[]));
        }
        frames
    }

    /// Adds `bytes` of a stream and returns every frame they complete; a partial frame waits
    /// for the next bytes.
    pub fn push(&mut self, bytes: &[u8]) -> Vec<MAVLinkMessageRaw> {
        self.pending.extend_from_slice(bytes);
        let mut frames = Vec::new();
        let mut at = 0;
        while at < self.pending.len() {
            let rest = &self.pending[at..];
            let stx = rest[0];
            if stx != STX_V1 && stx != STX_V2 {
                at += 1;
                self.counters.skipped_bytes += 1;
                continue;
            }
            let Some(len) = frame_len(rest) else {
                break; // header incomplete
            };
            if rest.len() < len {
                break; // frame incomplete
            }
            match to_raw(&rest[..len]) {
                Some(raw) => {
                    frames.push(raw);
                    self.counters.frames += 1;
                    at += len;
                }
                None => {
                    self.counters.bad_crc += 1;
                    at += 1; // resynchronise after this start byte
                }
            }
        }
        self.pending.drain(..at);
        if self.pending.len() > MAX_PENDING {
            self.counters.skipped_bytes += self.pending.len() as u64;
            self.pending.clear();
        }
        frames
    }
}

/// The whole length of the frame starting at `b[0]` (a start byte), once the header is there.
fn frame_len(b: &[u8]) -> Option<usize> {
    match b[0] {
        STX_V2 => {
            let payload = usize::from(*b.get(1)?);
            let incompat = *b.get(2)?;
            let signed = incompat & mavlink_core::consts::v2::IFLAG_SIGNED != 0;
            Some(1 + V2_HEADER + payload + CRC + if signed { SIGNATURE } else { 0 })
        }
        _ => Some(1 + V1_HEADER + usize::from(*b.get(1)?) + CRC),
    }
}

/// A frame with a valid CRC for the dialect, or `None`.
fn to_raw(b: &[u8]) -> Option<MAVLinkMessageRaw> {
    if b[0] == STX_V2 {
        let mut raw = MAVLinkV2MessageRaw::new();
        raw.as_mut_slice().get_mut(..b.len())?.copy_from_slice(b);
        // Unknown incompatibility flags mean a frame we cannot read (the spec: drop it).
        if raw.incompatibility_flags() & !mavlink_core::consts::v2::IFLAG_SIGNED != 0 {
            return None;
        }
        raw.has_valid_crc::<MavMessage>()
            .then_some(MAVLinkMessageRaw::V2(raw))
    } else {
        let mut raw = MAVLinkV1MessageRaw::new();
        raw.as_mut_slice().get_mut(..b.len())?.copy_from_slice(b);
        raw.has_valid_crc::<MavMessage>()
            .then_some(MAVLinkMessageRaw::V1(raw))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mavlink::dialect::{HEARTBEAT_DATA, SYSTEM_TIME_DATA};
    use mavlink_core::{MavHeader, MavlinkVersion, Message};

    fn bytes(m: &MavMessage, version: MavlinkVersion) -> Vec<u8> {
        let mut buf = Vec::new();
        let h = MavHeader {
            system_id: 1,
            component_id: 1,
            sequence: 7,
        };
        mavlink_core::write_versioned_msg(&mut buf, version, h, m).unwrap();
        buf
    }

    #[test]
    fn frames_split_anywhere_and_garbage_between_them() {
        let hb = MavMessage::HEARTBEAT(HEARTBEAT_DATA::default());
        let st = MavMessage::SYSTEM_TIME(SYSTEM_TIME_DATA {
            time_unix_usec: 42,
            time_boot_ms: 9,
        });
        let mut stream = vec![0x00, 0xFD, 0x03];
        stream.extend(bytes(&hb, MavlinkVersion::V2));
        stream.extend([0x11, 0x22]);
        stream.extend(bytes(&st, MavlinkVersion::V1));
        stream.extend(bytes(&st, MavlinkVersion::V2));
        for split in 0..stream.len() {
            let mut p = FrameParser::new();
            let mut got = p.push(&stream[..split]);
            got.extend(p.push(&stream[split..]));
            let ids: Vec<u32> = got.iter().map(|r| r.message_id()).collect();
            assert_eq!(ids, [0, 2, 2], "split at {split}");
            let parsed = MavMessage::parse(got[1].version(), 2, got[1].payload()).unwrap();
            assert_eq!(parsed, st);
        }
    }

    /// In a datagram, a stray start byte announcing a frame longer than what is left does not
    /// hide the frames after it.
    #[test]
    fn a_datagram_with_a_stray_start_byte_keeps_its_frames() {
        let st = MavMessage::SYSTEM_TIME(SYSTEM_TIME_DATA {
            time_unix_usec: 42,
            time_boot_ms: 9,
        });
        let mut d = vec![0xFE, 0xFE, 0x11];
        d.extend(bytes(&st, MavlinkVersion::V1));
        d.extend([0xFD, 0xF0]);
        d.extend(bytes(&st, MavlinkVersion::V2));
        let mut p = FrameParser::new();
        let got = p.push_datagram(&d);
        assert_eq!(got.len(), 2);
        assert!(p.pending.is_empty());
    }

    #[test]
    fn a_corrupt_frame_is_counted_and_the_next_one_found() {
        let hb = MavMessage::HEARTBEAT(HEARTBEAT_DATA::default());
        let mut bad = bytes(&hb, MavlinkVersion::V2);
        let n = bad.len();
        bad[n - 1] ^= 0xFF;
        bad.extend(bytes(&hb, MavlinkVersion::V2));
        let mut p = FrameParser::new();
        assert_eq!(p.push(&bad).len(), 1);
        assert_eq!(p.counters().bad_crc, 1);
    }

    #[test]
    fn endless_garbage_is_not_kept() {
        let mut p = FrameParser::new();
        for _ in 0..100 {
            // A start byte announcing a long frame, then bytes that never complete it.
            assert!(p.push(&[0xFD, 0xFF, 0x00, 0x00]).is_empty());
            assert!(p.push(&[0u8; 4096]).is_empty());
        }
        assert!(p.pending.len() <= MAX_PENDING);
    }
}
