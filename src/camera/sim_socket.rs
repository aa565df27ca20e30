//! The simulator's frame stream: a Unix-domain socket on which `mgmot-sim run --frames
//! unix:PATH` serves frames in the framing of [`super::sim_framing`].

use super::sim_framing::{is_end_of_stream, FrameHeader, FramingError, HEADER_LEN};
use super::{CameraError, CaptureTime, Frame, FrameSource};
use crate::telemetry::AutopilotTimeUs;
use std::io::Read;
use std::os::unix::net::UnixStream;
use std::path::{Path, PathBuf};

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
    #[error("{}: bad frame header: {source}", path.display())]
    Header {
        /// The socket.
        path: PathBuf,
        /// What is wrong.
        source: FramingError,
    },
}

/// A connected simulator frame stream.
#[derive(Debug)]
pub struct SimSocketSource {
    path: PathBuf,
    stream: UnixStream,
}

impl SimSocketSource {
    /// Connects to the simulator's socket. A read that waits longer than `timeout` for the
    /// next bytes fails (a frozen simulator is a lost camera, reconnected, and never blocks a
    /// shutdown for longer than that).
    pub fn connect(path: &Path, timeout: std::time::Duration) -> Result<Self, SimFramingError> {
        let io = |source| SimFramingError::Io {
            path: path.to_owned(),
            source,
        };
        let stream = UnixStream::connect(path).map_err(io)?;
        stream
            .set_read_timeout(Some(timeout.max(std::time::Duration::from_millis(1))))
            .map_err(io)?;
        Ok(Self {
            path: path.to_owned(),
            stream,
        })
    }

    /// Reads the next frame. `Ok(None)` at the end-of-stream header (the simulator finished
    /// its run); a stream that closes without it is an error (the simulator was cut off), so
    /// the capture loop reconnects.
    pub fn read_frame(&mut self) -> Result<Option<Frame>, SimFramingError> {
        read_sim_frame(&mut self.stream, &self.path)
    }
}

/// Reads the next frame of the simulator's frame stream from `stream`, as
/// [`SimSocketSource::read_frame`] does from the socket; `path` only names the stream in
/// errors. `Ok(None)` at the end-of-stream header; a stream that closes without it is an
/// [`SimFramingError::Io`] (`UnexpectedEof`).
pub fn read_sim_frame(
    stream: &mut impl Read,
    path: &Path,
) -> Result<Option<Frame>, SimFramingError> {
    let io = |source| SimFramingError::Io {
        path: path.to_owned(),
        source,
    };
    let header = |source| SimFramingError::Header {
        path: path.to_owned(),
        source,
    };
    let mut bytes = [0u8; HEADER_LEN];
    match read_full(stream, &mut bytes) {
        Ok(true) => {}
        Ok(false) => {
            return Err(io(std::io::Error::new(
                std::io::ErrorKind::UnexpectedEof,
                "the stream closed without its end-of-stream header",
            )))
        }
        Err(e) => return Err(io(e)),
    }
    if is_end_of_stream(&bytes) {
        return Ok(None);
    }
    let h = FrameHeader::decode(&bytes).map_err(header)?;
    let len = h.rgb24_len().map_err(header)?;
    let mut rgb = vec![0u8; len];
    stream.read_exact(&mut rgb).map_err(io)?;
    Ok(Some(Frame {
        index: h.index,
        captured: CaptureTime::Autopilot(AutopilotTimeUs(h.capture_time_us)),
        width_px: h.width,
        height_px: h.height,
        rgb,
    }))
}

impl FrameSource for SimSocketSource {
    fn next_frame(&mut self) -> Result<Option<Frame>, CameraError> {
        Ok(self.read_frame()?)
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

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;
    use std::os::unix::net::UnixListener;
    use std::time::{Duration, Instant};

    const TIMEOUT: Duration = Duration::from_secs(5);

    /// Writer and reader through the shared header code, over a real socket.
    #[test]
    fn reads_frames_then_end_of_stream() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("f.sock");
        let listener = UnixListener::bind(&path).unwrap();
        let server = std::thread::spawn(move || {
            let (mut s, _) = listener.accept().unwrap();
            for k in 0..3u64 {
                let h = FrameHeader::rgb24(k, 1_000_000 + k * 33_333, 4, 2);
                s.write_all(&h.encode()).unwrap();
                s.write_all(&[k as u8; 24]).unwrap();
            }
            s.write_all(&crate::camera::sim_framing::end_of_stream())
                .unwrap();
        });
        let mut src = SimSocketSource::connect(&path, TIMEOUT).unwrap();
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

    /// A stream closed without the end-of-stream header was cut off (the simulator crashed
    /// or restarted): an error, so the capture loop reconnects instead of ending the run.
    #[test]
    fn a_close_without_the_end_header_is_an_error() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("f.sock");
        let listener = UnixListener::bind(&path).unwrap();
        let server = std::thread::spawn(move || {
            let (mut s, _) = listener.accept().unwrap();
            s.write_all(&FrameHeader::rgb24(0, 0, 4, 2).encode())
                .unwrap();
            s.write_all(&[0; 24]).unwrap();
        });
        let mut src = SimSocketSource::connect(&path, TIMEOUT).unwrap();
        assert!(src.next_frame().unwrap().is_some());
        server.join().unwrap();
        let e = src.next_frame().unwrap_err();
        assert!(e.to_string().contains("end-of-stream"), "{e}");
    }

    /// A simulator that connects and then sends nothing: the read gives up after the
    /// timeout instead of blocking the capture thread (and a shutdown) for ever.
    #[test]
    fn a_frozen_stream_times_out() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("f.sock");
        let listener = UnixListener::bind(&path).unwrap();
        let server = std::thread::spawn(move || {
            let (s, _) = listener.accept().unwrap();
            std::thread::sleep(Duration::from_secs(2));
            drop(s);
        });
        let mut src = SimSocketSource::connect(&path, Duration::from_millis(200)).unwrap();
        let started = Instant::now();
        assert!(src.next_frame().is_err());
        assert!(
            started.elapsed() < Duration::from_secs(1),
            "{:?}",
            started.elapsed()
        );
        server.join().unwrap();
    }

    #[test]
    fn bad_header_and_cut_payload_are_errors_naming_the_socket() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("f.sock");
        let listener = UnixListener::bind(&path).unwrap();
        let server = std::thread::spawn(move || {
            let (mut s, _) = listener.accept().unwrap();
            let mut h = FrameHeader::rgb24(0, 0, 4, 2);
            h.payload_len = 25;
            s.write_all(&h.encode()).unwrap();
            let (mut s, _) = listener.accept().unwrap();
            s.write_all(&FrameHeader::rgb24(0, 0, 4, 2).encode())
                .unwrap();
            s.write_all(&[0; 10]).unwrap();
        });
        let e = SimSocketSource::connect(&path, TIMEOUT)
            .unwrap()
            .next_frame()
            .unwrap_err();
        assert!(e.to_string().contains("f.sock"), "{e}");
        assert!(e.to_string().contains("payload length 25"), "{e}");
        let e = SimSocketSource::connect(&path, TIMEOUT)
            .unwrap()
            .next_frame()
            .unwrap_err();
        server.join().unwrap();
        assert!(matches!(e, CameraError::Sim(SimFramingError::Io { .. })));
    }

    #[test]
    fn reads_frames_from_any_byte_stream() {
        let mut bytes = Vec::new();
        for k in 0..2u64 {
            bytes.extend(FrameHeader::rgb24(k, 10 + k, 2, 1).encode());
            bytes.extend([k as u8; 6]);
        }
        let cut = bytes.len();
        bytes.extend(crate::camera::sim_framing::end_of_stream());
        let mut stream = &bytes[..];
        let path = Path::new("bytes");
        for k in 0..2u64 {
            let f = read_sim_frame(&mut stream, path).unwrap().unwrap();
            assert_eq!((f.index, f.rgb), (k, vec![k as u8; 6]));
        }
        assert!(read_sim_frame(&mut stream, path).unwrap().is_none());
        // Closed without the end-of-stream header: an error (the simulator was cut off).
        let mut closed = &bytes[..cut];
        for _ in 0..2 {
            read_sim_frame(&mut closed, path).unwrap().unwrap();
        }
        let e = read_sim_frame(&mut closed, path).unwrap_err();
        assert!(matches!(e, SimFramingError::Io { .. }), "{e}");
        // A header cut short is an IO error, not the end of the stream.
        let e = read_sim_frame(&mut &bytes[..20], path).unwrap_err();
        assert!(matches!(e, SimFramingError::Io { .. }), "{e}");
    }

    #[test]
    fn missing_socket_names_the_path() {
        let e =
            SimSocketSource::connect(Path::new("/nonexistent/mgmot.sock"), TIMEOUT).unwrap_err();
        assert!(e.to_string().contains("/nonexistent/mgmot.sock"));
    }
}
