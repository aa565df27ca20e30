//! `flight.tlog`: every MAVLink packet in and out, in the format QGroundControl and Mission
//! Planner write and MAVExplorer / pymavlink's `mavutil` read: per packet, its arrival (or
//! sending) time as 8 bytes big-endian microseconds since the UNIX epoch, then the packet's
//! bytes as they were on the wire (MAVLink 1 or 2, signature included).

use std::io::{self, Write};

/// One packet of a tlog.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TlogEntry {
    /// When it was received or sent (µs since the UNIX epoch).
    pub unix_us: u64,
    /// The raw packet.
    pub packet: Vec<u8>,
}

impl TlogEntry {
    /// The sender's system id.
    pub fn system_id(&self) -> u8 {
        match self.packet.first() {
            Some(&MAGIC_V2) => self.packet.get(5).copied().unwrap_or(0),
            _ => self.packet.get(3).copied().unwrap_or(0),
        }
    }

    /// The sender's component id.
    pub fn component_id(&self) -> u8 {
        match self.packet.first() {
            Some(&MAGIC_V2) => self.packet.get(6).copied().unwrap_or(0),
            _ => self.packet.get(4).copied().unwrap_or(0),
        }
    }

    /// The message id.
    pub fn message_id(&self) -> u32 {
        let b = |i: usize| u32::from(self.packet.get(i).copied().unwrap_or(0));
        match self.packet.first() {
            Some(&MAGIC_V2) => b(7) | (b(8) << 8) | (b(9) << 16),
            _ => b(5),
        }
    }
}

const MAGIC_V1: u8 = 0xFE;
const MAGIC_V2: u8 = 0xFD;

/// Appends one packet.
pub fn write_entry(out: &mut impl Write, unix_us: u64, packet: &[u8]) -> io::Result<()> {
    out.write_all(&unix_us.to_be_bytes())?;
    out.write_all(packet)
}

/// The length of the packet at the start of `b` (header, payload, checksum and signature),
/// or `None` when `b` does not start with a MAVLink magic byte or is cut short.
fn packet_len(b: &[u8]) -> Option<usize> {
    let len = match *b.first()? {
        MAGIC_V2 => {
            let payload = usize::from(*b.get(1)?);
            let signed = b.get(2)? & 0x01 != 0;
            10 + payload + 2 + if signed { 13 } else { 0 }
        }
        MAGIC_V1 => 6 + usize::from(*b.get(1)?) + 2,
        _ => return None,
    };
    (b.len() >= len).then_some(len)
}

/// Parses a tlog. Stops at the first entry that is cut short or malformed (a crash or a full
/// disk leaves at most a partial last entry): the entries before it and whether the file
/// ended cleanly.
pub fn parse(bytes: &[u8]) -> (Vec<TlogEntry>, bool) {
    let mut entries = Vec::new();
    let mut rest = bytes;
    while !rest.is_empty() {
        let Some((stamp, packet)) = rest.split_first_chunk::<8>() else {
            return (entries, false);
        };
        let Some(len) = packet_len(packet) else {
            return (entries, false);
        };
        entries.push(TlogEntry {
            unix_us: u64::from_be_bytes(*stamp),
            packet: packet[..len].to_vec(),
        });
        rest = &packet[len..];
    }
    (entries, true)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn heartbeat_v2(seq: u8, signed: bool) -> Vec<u8> {
        let mut p = vec![MAGIC_V2, 9, u8::from(signed), 0, seq, 1, 191, 0, 0, 0];
        p.extend([0u8; 9]);
        p.extend([0xAB, 0xCD]);
        if signed {
            p.extend([7u8; 13]);
        }
        p
    }

    #[test]
    fn entries_round_trip_and_a_cut_last_entry_is_dropped() {
        let mut out = Vec::new();
        write_entry(&mut out, 1_700_000_000_000_001, &heartbeat_v2(1, false)).unwrap();
        write_entry(&mut out, 1_700_000_000_000_002, &heartbeat_v2(2, true)).unwrap();
        let v1 = [MAGIC_V1, 2, 5, 1, 1, 30, 0, 0, 9, 9];
        write_entry(&mut out, 1_700_000_000_000_003, &v1).unwrap();
        let (entries, clean) = parse(&out);
        assert!(clean);
        assert_eq!(entries.len(), 3);
        assert_eq!(entries[1].packet.len(), 10 + 9 + 2 + 13);
        assert_eq!(
            (entries[0].system_id(), entries[0].component_id()),
            (1, 191)
        );
        assert_eq!((entries[2].message_id(), entries[2].system_id()), (30, 1));
        assert_eq!(entries[2].unix_us, 1_700_000_000_000_003);
        // The last entry is 8 + 10 bytes: any cut inside it loses it alone.
        for cut in 1..18 {
            let (e, clean) = parse(&out[..out.len() - cut]);
            assert!(!clean);
            assert_eq!(e.len(), 2, "cut {cut}");
        }
    }
}
