//! Frame sinks of `run`: a Unix-domain socket server speaking the framing of
//! [`mgmot_sim::framing`], or a v4l2loopback output device (cargo feature `v4l2`).

use anyhow::Context;
use mgmot_sim::framing::FrameHeader;
use std::io::{ErrorKind, Write};
use std::os::unix::fs::FileTypeExt;
use std::os::unix::net::{UnixListener, UnixStream};
use std::path::PathBuf;
use std::time::{Duration, Instant};

/// A frame consumer that stops reading for this long is treated as gone.
const WRITE_TIMEOUT: Duration = Duration::from_secs(5);

/// Where frames go.
pub enum FrameSink {
    /// A Unix-domain socket server.
    Unix(UnixServer),
    /// A v4l2loopback device.
    #[cfg(feature = "v4l2")]
    V4l2(super::frames_v4l2::V4l2Sink),
}

impl FrameSink {
    /// Parses `unix:/path.sock` or `v4l2:/dev/videoN`.
    pub fn open(spec: &str, width: u32, height: u32) -> anyhow::Result<FrameSink> {
        if let Some(path) = spec.strip_prefix("unix:") {
            return Ok(FrameSink::Unix(UnixServer::bind(PathBuf::from(path))?));
        }
        if let Some(dev) = spec.strip_prefix("v4l2:") {
            #[cfg(feature = "v4l2")]
            {
                return Ok(FrameSink::V4l2(super::frames_v4l2::V4l2Sink::open(
                    dev, width, height,
                )?));
            }
            #[cfg(not(feature = "v4l2"))]
            {
                let _ = (width, height);
                anyhow::bail!(
                    "v4l2 output ({dev}) needs mgmot-sim built with the `v4l2` cargo feature"
                );
            }
        }
        anyhow::bail!("invalid --frames `{spec}`: expected unix:/path/to.sock or v4l2:/dev/videoN")
    }

    /// Sends one frame. `wait` (lockstep) blocks until a consumer takes it, up to `wait_for`.
    pub fn send(
        &mut self,
        header: &FrameHeader,
        rgb: &[u8],
        wait: bool,
        wait_for: Duration,
    ) -> anyhow::Result<bool> {
        match self {
            FrameSink::Unix(s) => s.send(header, rgb, wait, wait_for),
            #[cfg(feature = "v4l2")]
            FrameSink::V4l2(s) => s.send(rgb).map(|_| true),
        }
    }

    /// Tells the consumer the run is over (the end-of-stream header), so that it ends too
    /// rather than reconnecting; best effort.
    pub fn finish(&mut self) {
        if let FrameSink::Unix(s) = self {
            if let Some(client) = s.client.as_mut() {
                let end = mgmot_wire::sim_framing::end_of_stream();
                if let Err(e) = client.write_all(&end).and_then(|()| client.flush()) {
                    tracing::debug!(error = %e, "end-of-stream header not delivered");
                }
            }
        }
    }

    /// True when a consumer is connected (accepting a waiting one first; always true for
    /// v4l2).
    pub fn ready(&mut self) -> anyhow::Result<bool> {
        match self {
            FrameSink::Unix(s) => {
                if s.client.is_none() {
                    s.try_accept()?;
                }
                Ok(s.client.is_some())
            }
            #[cfg(feature = "v4l2")]
            FrameSink::V4l2(_) => Ok(true),
        }
    }
}

/// Serves frames to one consumer at a time on a Unix socket.
pub struct UnixServer {
    path: PathBuf,
    listener: UnixListener,
    client: Option<UnixStream>,
}

impl UnixServer {
    fn bind(path: PathBuf) -> anyhow::Result<UnixServer> {
        if let Ok(meta) = std::fs::symlink_metadata(&path) {
            anyhow::ensure!(
                meta.file_type().is_socket(),
                "{} exists and is not a socket; not replacing it",
                path.display()
            );
            std::fs::remove_file(&path)
                .with_context(|| format!("cannot remove stale socket {}", path.display()))?;
        }
        let listener = UnixListener::bind(&path)
            .with_context(|| format!("cannot listen on {}", path.display()))?;
        listener.set_nonblocking(true)?;
        tracing::info!(path = %path.display(), "frame socket listening");
        Ok(UnixServer {
            path,
            listener,
            client: None,
        })
    }

    fn try_accept(&mut self) -> anyhow::Result<()> {
        match self.listener.accept() {
            Ok((stream, _)) => {
                stream.set_nonblocking(false)?;
                stream.set_write_timeout(Some(WRITE_TIMEOUT))?;
                tracing::info!(path = %self.path.display(), "frame consumer connected");
                self.client = Some(stream);
                Ok(())
            }
            Err(e) if e.kind() == ErrorKind::WouldBlock => Ok(()),
            Err(e) => Err(e).context("accepting a frame consumer"),
        }
    }

    /// Returns whether the frame was delivered.
    fn send(
        &mut self,
        header: &FrameHeader,
        rgb: &[u8],
        wait: bool,
        wait_for: Duration,
    ) -> anyhow::Result<bool> {
        let deadline = Instant::now() + wait_for;
        loop {
            if self.client.is_none() {
                self.try_accept()?;
            }
            if let Some(client) = self.client.as_mut() {
                let result = client
                    .write_all(&header.encode())
                    .and_then(|_| client.write_all(rgb));
                match result {
                    Ok(()) => return Ok(true),
                    Err(e) => {
                        tracing::warn!(error = %e, "frame consumer disconnected; waiting for another");
                        self.client = None;
                        if !wait {
                            return Ok(false);
                        }
                    }
                }
            }
            if !wait {
                return Ok(false);
            }
            anyhow::ensure!(
                Instant::now() < deadline,
                "no frame consumer on {} within {:.0} s (lockstep mode waits for one)",
                self.path.display(),
                wait_for.as_secs_f64()
            );
            std::thread::sleep(Duration::from_millis(20));
        }
    }
}

impl Drop for UnixServer {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.path);
    }
}
