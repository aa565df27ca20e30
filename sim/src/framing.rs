//! The frame-stream framing used on the Unix-domain socket (documented in `sim/README.md`).
//!
//! Every frame is a fixed 40-byte little-endian header followed by `payload_len` bytes of
//! pixels:
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 4 | magic `MGSF` |
//! | 4 | 2 | version (1) |
//! | 6 | 2 | header length in bytes (40) |
//! | 8 | 8 | frame index (0-based, u64) |
//! | 16 | 8 | capture time on the autopilot clock (`time_boot` in microseconds, u64) |
//! | 24 | 4 | width in pixels (u32) |
//! | 28 | 4 | height in pixels (u32) |
//! | 32 | 4 | pixel format FourCC (`RGB3`: packed 8-bit R, G, B; rows not padded) |
//! | 36 | 4 | payload length in bytes (u32) = width * height * 3 for `RGB3` |

/// Frame magic.
pub const MAGIC: [u8; 4] = *b"MGSF";
/// Framing version.
pub const VERSION: u16 = 1;
/// Header length in bytes.
pub const HEADER_LEN: usize = 40;
/// FourCC of packed RGB24 (the V4L2 name).
pub const FOURCC_RGB3: [u8; 4] = *b"RGB3";

/// A frame header.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FrameHeader {
    /// Frame index (0-based).
    pub index: u64,
    /// Capture time on the autopilot's clock (time since its boot), microseconds.
    pub capture_time_us: u64,
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Pixel format FourCC.
    pub fourcc: [u8; 4],
    /// Bytes of pixels that follow.
    pub payload_len: u32,
}

/// Why a header could not be decoded.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum FramingError {
    /// Fewer than [`HEADER_LEN`] bytes.
    #[error("frame header truncated: {0} bytes, need {HEADER_LEN}")]
    Truncated(usize),
    /// Wrong magic.
    #[error("bad frame magic {0:?}, expected \"MGSF\"")]
    BadMagic([u8; 4]),
    /// Unknown version or header length.
    #[error("unsupported frame header version {version} / length {len}")]
    Unsupported {
        /// Version field.
        version: u16,
        /// Header length field.
        len: u16,
    },
}

impl FrameHeader {
    /// Encodes the header.
    pub fn encode(&self) -> [u8; HEADER_LEN] {
        let mut b = [0u8; HEADER_LEN];
        b[0..4].copy_from_slice(&MAGIC);
        b[4..6].copy_from_slice(&VERSION.to_le_bytes());
        b[6..8].copy_from_slice(&(HEADER_LEN as u16).to_le_bytes());
        b[8..16].copy_from_slice(&self.index.to_le_bytes());
        b[16..24].copy_from_slice(&self.capture_time_us.to_le_bytes());
        b[24..28].copy_from_slice(&self.width.to_le_bytes());
        b[28..32].copy_from_slice(&self.height.to_le_bytes());
        b[32..36].copy_from_slice(&self.fourcc);
        b[36..40].copy_from_slice(&self.payload_len.to_le_bytes());
        b
    }

    /// Decodes a header from the first [`HEADER_LEN`] bytes of `b`.
    pub fn decode(b: &[u8]) -> Result<FrameHeader, FramingError> {
        if b.len() < HEADER_LEN {
            return Err(FramingError::Truncated(b.len()));
        }
        let arr4 = |o: usize| [b[o], b[o + 1], b[o + 2], b[o + 3]];
        let u16_at = |o: usize| u16::from_le_bytes([b[o], b[o + 1]]);
        let u32_at = |o: usize| u32::from_le_bytes(arr4(o));
        let u64_at = |o: usize| {
            let mut a = [0u8; 8];
            a.copy_from_slice(&b[o..o + 8]);
            u64::from_le_bytes(a)
        };
        if arr4(0) != MAGIC {
            return Err(FramingError::BadMagic(arr4(0)));
        }
        let (version, len) = (u16_at(4), u16_at(6));
        if version != VERSION || usize::from(len) != HEADER_LEN {
            return Err(FramingError::Unsupported { version, len });
        }
        Ok(FrameHeader {
            index: u64_at(8),
            capture_time_us: u64_at(16),
            width: u32_at(24),
            height: u32_at(28),
            fourcc: arr4(32),
            payload_len: u32_at(36),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_errors() {
        let h = FrameHeader {
            index: 7,
            capture_time_us: 123_456_789,
            width: 1280,
            height: 720,
            fourcc: FOURCC_RGB3,
            payload_len: 1280 * 720 * 3,
        };
        let b = h.encode();
        assert_eq!(&b[0..4], b"MGSF");
        assert_eq!(FrameHeader::decode(&b), Ok(h));
        assert_eq!(
            FrameHeader::decode(&b[..10]),
            Err(FramingError::Truncated(10))
        );
        let mut bad = b;
        bad[0] = b'X';
        assert!(matches!(
            FrameHeader::decode(&bad),
            Err(FramingError::BadMagic(_))
        ));
    }
}
