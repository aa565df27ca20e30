//! The simulator's frame-stream framing, shared by its writer (`mgmot-sim run --frames
//! unix:PATH`) and the runtime's reader (`mgmot::camera::SimSocketSource`), so the two ends cannot
//! drift apart. Documented in `sim/README.md`.
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
/// Magic of the end-of-stream header: the simulator finished its run on purpose. A stream
/// that closes without it was cut (the simulator crashed or restarted) and the reader
/// reconnects.
pub const END_MAGIC: [u8; 4] = *b"MGSE";
/// Framing version.
pub const VERSION: u16 = 1;
/// Header length in bytes.
pub const HEADER_LEN: usize = 40;
/// FourCC of packed RGB24 (the V4L2 name).
pub const FOURCC_RGB3: [u8; 4] = *b"RGB3";

/// Payloads larger than this (bytes) are refused by the reader: 8K RGB is 100 MB; a bigger
/// length is a corrupt header, and allocating it would be the bug.
pub const MAX_PAYLOAD: usize = 7680 * 4320 * 3;

/// The end-of-stream header: [`END_MAGIC`], the version and header length, zeros after.
pub fn end_of_stream() -> [u8; HEADER_LEN] {
    let mut b = [0u8; HEADER_LEN];
    b[0..4].copy_from_slice(&END_MAGIC);
    b[4..6].copy_from_slice(&VERSION.to_le_bytes());
    b[6..8].copy_from_slice(&(HEADER_LEN as u16).to_le_bytes());
    b
}

/// Whether `b` (a whole header) is the end-of-stream header.
pub fn is_end_of_stream(b: &[u8]) -> bool {
    b.get(0..4) == Some(&END_MAGIC[..])
}

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

/// Why a header could not be decoded or does not describe an RGB24 frame.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum FramingError {
    /// Fewer than [`HEADER_LEN`] bytes.
    #[error("frame header truncated: {0} bytes, need {HEADER_LEN}")]
    Truncated(usize),
    /// Wrong magic.
    #[error("bad frame magic {0:?}, expected \"MGSF\"")]
    BadMagic([u8; 4]),
    /// Unknown version or header length.
    #[error("unsupported frame header version {version} / length {len}, expected 1 / 40")]
    Unsupported {
        /// Version field.
        version: u16,
        /// Header length field.
        len: u16,
    },
    /// A pixel format other than `RGB3`.
    #[error("pixel format {0:?}, expected \"RGB3\"")]
    PixelFormat([u8; 4]),
    /// The payload length does not match the size, or is zero or absurdly large.
    #[error("payload length {len} does not fit {width}x{height} RGB24")]
    PayloadLength {
        /// Payload length field.
        len: u32,
        /// Width field.
        width: u32,
        /// Height field.
        height: u32,
    },
}

impl FrameHeader {
    /// The header of a packed RGB24 frame of `width` x `height` pixels.
    pub fn rgb24(index: u64, capture_time_us: u64, width: u32, height: u32) -> Self {
        Self {
            index,
            capture_time_us,
            width,
            height,
            fourcc: FOURCC_RGB3,
            payload_len: width.saturating_mul(height).saturating_mul(3),
        }
    }

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

    /// Decodes a header from the first [`HEADER_LEN`] bytes of `b` (magic, version and
    /// header length checked; the pixel format is not: see [`FrameHeader::rgb24_len`]).
    pub fn decode(b: &[u8]) -> Result<FrameHeader, FramingError> {
        let Some(b) = b.get(..HEADER_LEN) else {
            return Err(FramingError::Truncated(b.len()));
        };
        let arr4 = |o: usize| [b[o], b[o + 1], b[o + 2], b[o + 3]];
        let u16_at = |o: usize| u16::from_le_bytes([b[o], b[o + 1]]);
        let u32_at = |o: usize| u32::from_le_bytes(arr4(o));
        let u64_at = |o: usize| u64::from(u32_at(o)) | (u64::from(u32_at(o + 4)) << 32);
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

    /// The payload length of a well-formed RGB24 frame: `RGB3`, non-empty, equal to
    /// `width * height * 3` and at most [`MAX_PAYLOAD`].
    pub fn rgb24_len(&self) -> Result<usize, FramingError> {
        if self.fourcc != FOURCC_RGB3 {
            return Err(FramingError::PixelFormat(self.fourcc));
        }
        let expected = (self.width as usize)
            .checked_mul(self.height as usize)
            .and_then(|n| n.checked_mul(3));
        let len = self.payload_len as usize;
        if expected != Some(len) || len == 0 || len > MAX_PAYLOAD {
            return Err(FramingError::PayloadLength {
                len: self.payload_len,
                width: self.width,
                height: self.height,
            });
        }
        Ok(len)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The byte layout of the table above, written out field by field.
    fn by_hand(index: u64, t_us: u64, w: u32, h: u32, len: u32) -> Vec<u8> {
        let mut b = Vec::with_capacity(HEADER_LEN);
        b.extend_from_slice(b"MGSF");
        b.extend_from_slice(&1u16.to_le_bytes());
        b.extend_from_slice(&40u16.to_le_bytes());
        b.extend_from_slice(&index.to_le_bytes());
        b.extend_from_slice(&t_us.to_le_bytes());
        b.extend_from_slice(&w.to_le_bytes());
        b.extend_from_slice(&h.to_le_bytes());
        b.extend_from_slice(b"RGB3");
        b.extend_from_slice(&len.to_le_bytes());
        b
    }

    #[test]
    fn encode_matches_the_documented_layout() {
        let h = FrameHeader::rgb24(7, 123_456_789_012, 1280, 720);
        assert_eq!(
            h.encode().to_vec(),
            by_hand(7, 123_456_789_012, 1280, 720, 1280 * 720 * 3)
        );
        assert_eq!(FrameHeader::decode(&h.encode()), Ok(h));
        assert_eq!(h.rgb24_len(), Ok(1280 * 720 * 3));
    }

    #[test]
    fn decode_errors() {
        let b = FrameHeader::rgb24(0, 0, 4, 2).encode();
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
        let mut v2 = b;
        v2[4] = 2;
        assert_eq!(
            FrameHeader::decode(&v2),
            Err(FramingError::Unsupported {
                version: 2,
                len: 40
            })
        );
    }

    #[test]
    fn rgb24_len_rejects_mismatches() {
        let mut h = FrameHeader::rgb24(0, 0, 4, 2);
        h.payload_len = 25;
        assert!(matches!(
            h.rgb24_len(),
            Err(FramingError::PayloadLength { len: 25, .. })
        ));
        let mut yuyv = FrameHeader::rgb24(0, 0, 4, 2);
        yuyv.fourcc = *b"YUYV";
        assert_eq!(yuyv.rgb24_len(), Err(FramingError::PixelFormat(*b"YUYV")));
        let huge = FrameHeader {
            payload_len: 0,
            ..FrameHeader::rgb24(0, 0, u32::MAX, u32::MAX)
        };
        assert!(huge.rgb24_len().is_err());
        assert!(FrameHeader::rgb24(0, 0, 0, 0).rgb24_len().is_err());
    }
}
