//! The simulator's frame stream: a Unix-domain socket on which `mgmot-sim run --frames
//! unix:PATH` serves frames, each a 40-byte little-endian header and the pixels:
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 4 | magic `MGSF` |
//! | 4 | 2 | version (1) |
//! | 6 | 2 | header length (40) |
//! | 8 | 8 | frame index (u64) |
//! | 16 | 8 | capture time on the autopilot clock, µs (u64) |
//! | 24 | 4 | width (u32) |
//! | 28 | 4 | height (u32) |
//! | 32 | 4 | FourCC, `RGB3` (packed RGB24) |
//! | 36 | 4 | payload length (u32) = width * height * 3 |
//!
//! (The simulator's `framing` module is the writer; this is the reader. They are two ends of a
//! wire protocol between processes, so each side has its own code, tested against the table
//! above.)

use super::{CaptureTime, Frame};
use crate::telemetry::AutopilotTimeUs;
use std::io::Read;
use std::os::unix::net::UnixStream;
use std::path::{Path, PathBuf};

/// Header length in bytes.
pub const SIM_HEADER_LEN: usize = 40;

/// Frames larger than this (bytes of pixels) are refused: 8K RGB is 100 MB; a bigger length is
/// a corrupt header, and allocating it would be the bug.
const MAX_PAYLOAD: usize = 7680 * 4320 * 3;

/// What is wrong with the stream.
#[derive(Debug, thiserror::Error)]
pub enum SimFramingError {
    /// Connecting or reading failed (the simulator is gone or not started).
    #[error("{}: {source}", path.display())]
    Io {
        /// The socket.
        path: PathBuf,
        /// The IO error.
        source: std::io::Error,
    },
    /// The header is not a frame header this reader understands.
    #[error("{}: bad frame header: {problem}", path.display())]
    Header {
        /// The socket.
        path: PathBuf,
        /// What is wrong.
        problem: String,
    },
}

/// A connected simulator frame stream.
#[derive(Debug)]
pub struct SimSocketSource {
    path: PathBuf,
    stream: UnixStream,
}

impl SimSocketSource {
    /// Connects to the simulator's socket.
    pub fn connect(path: &Path) -> Result<Self, SimFramingError> {
        let stream = UnixStream::connect(path).map_err(|source| SimFramingError::Io {
            path: path.to_owned(),
            source,
        })?;
        Ok(Self {
            path: path.to_owned(),
            stream,
        })
    }

    /// Reads the next frame, reusing `buf`'s allocation for the pixels when the caller hands
    /// one back. `Ok(None)` at a clean end of stream (the simulator finished).
    pub fn next_frame(&mut self) -> Result<Option<Frame>, SimFramingError> {
        let mut header = [0u8; SIM_HEADER_LEN];
        match read_full(&mut self.stream, &mut header) {
            Ok(true) => {}
            Ok(false) => return Ok(None),
            Err(source) => {
                return Err(SimFramingError::Io {
                    path: self.path.clone(),
                    source,
                })
            }
        }
        let h = decode_header(&header).map_err(|problem| SimFramingError::Header {
            path: self.path.clone(),
            problem,
        })?;
        let mut rgb = vec![0u8; h.payload_len];
        self.stream
            .read_exact(&mut rgb)
            .map_err(|source| SimFramingError::Io {
                path: self.path.clone(),
                source,
            })?;
        Ok(Some(Frame {
            index: h.index,
            captured: CaptureTime::Autopilot(AutopilotTimeUs(h.capture_time_us)),
            width_px: h.width,
            height_px: h.height,
            rgb,
        }))
    }
}

/// Fills `buf`; `Ok(false)` if the stream ended before the first byte.
fn read_full(r: &mut impl Read, buf: &mut [u8]) -> std::io::Result<bool> {
    let mut got = 0;
    while got < buf.len() {
        match r.read(&mut buf[got..]) {
            Ok(0) if got == 0 => return Ok(false),
            Ok(0) => return Err(std::io::ErrorKind::UnexpectedEof.into()),
            Ok(n) => got += n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(true)
}

#[derive(Debug, PartialEq)]
struct Header {
    index: u64,
    capture_time_us: u64,
    width: u32,
    height: u32,
    payload_len: usize,
}

fn decode_header(b: &[u8; SIM_HEADER_LEN]) -> Result<Header, String> {
    let u16_at = |o: usize| u16::from_le_bytes([b[o], b[o + 1]]);
    let u32_at = |o: usize| u32::from_le_bytes([b[o], b[o + 1], b[o + 2], b[o + 3]]);
    let u64_at = |o: usize| u64::from(u32_at(o)) | (u64::from(u32_at(o + 4)) << 32);
    if &b[0..4] != b"MGSF" {
        return Err(format!("magic {:?}, expected \"MGSF\"", &b[0..4]));
    }
    let (version, len) = (u16_at(4), u16_at(6));
    if version != 1 || usize::from(len) != SIM_HEADER_LEN {
        return Err(format!(
            "version {version} / header length {len}, expected 1 / 40"
        ));
    }
    if &b[32..36] != b"RGB3" {
        return Err(format!("pixel format {:?}, expected \"RGB3\"", &b[32..36]));
    }
    let (width, height) = (u32_at(24), u32_at(28));
    let payload_len = u32_at(36) as usize;
    let expected = (width as usize)
        .checked_mul(height as usize)
        .and_then(|n| n.checked_mul(3));
    if expected != Some(payload_len) || payload_len > MAX_PAYLOAD || payload_len == 0 {
        return Err(format!(
            "payload length {payload_len} does not fit {width}x{height} RGB24"
        ));
    }
    Ok(Header {
        index: u64_at(8),
        capture_time_us: u64_at(16),
        width,
        height,
        payload_len,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;
    use std::os::unix::net::UnixListener;

    fn header(index: u64, t_us: u64, w: u32, h: u32, len: u32) -> Vec<u8> {
        let mut b = Vec::with_capacity(SIM_HEADER_LEN);
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
    fn reads_frames_then_end_of_stream() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("f.sock");
        let listener = UnixListener::bind(&path).unwrap();
        let server = std::thread::spawn(move || {
            let (mut s, _) = listener.accept().unwrap();
            for k in 0..3u64 {
                s.write_all(&header(k, 1_000_000 + k * 33_333, 4, 2, 24))
                    .unwrap();
                s.write_all(&[k as u8; 24]).unwrap();
            }
        });
        let mut src = SimSocketSource::connect(&path).unwrap();
        for k in 0..3u64 {
            let f = src.next_frame().unwrap().unwrap();
            assert_eq!(f.index, k);
            assert_eq!(
                f.captured,
                CaptureTime::Autopilot(AutopilotTimeUs(1_000_000 + k * 33_333))
            );
            assert_eq!((f.width_px, f.height_px), (4, 2));
            assert_eq!(f.rgb, vec![k as u8; 24]);
        }
        server.join().unwrap();
        assert!(src.next_frame().unwrap().is_none());
    }

    #[test]
    fn bad_headers_are_named() {
        let mut h: [u8; 40] = header(0, 0, 4, 2, 24).try_into().unwrap();
        assert!(decode_header(&h).is_ok());
        h[36] = 25;
        assert!(decode_header(&h).unwrap_err().contains("payload length"));
        let mut m: [u8; 40] = header(0, 0, 4, 2, 24).try_into().unwrap();
        m[0] = b'X';
        assert!(decode_header(&m).unwrap_err().contains("magic"));
        let huge: [u8; 40] = header(0, 0, u32::MAX, u32::MAX, 0).try_into().unwrap();
        assert!(decode_header(&huge).is_err());
    }

    #[test]
    fn missing_socket_names_the_path() {
        let e = SimSocketSource::connect(Path::new("/nonexistent/mgmot.sock")).unwrap_err();
        assert!(e.to_string().contains("/nonexistent/mgmot.sock"));
    }
}
