//! The one harness of the simulator's integration tests (the `mgmot` crate's `tests/common/` is
//! its counterpart for the runtime):
//!
//! - [`TestDir`]: a temporary folder per test, removed when the test passes, kept (and its path
//!   printed) when the test fails or `MGMOT_KEEP_TEST_DIRS=1` is set;
//! - [`SIM_BIN`], [`sim`], [`run_sim`], [`spawn_sim`]: the `mgmot-sim` binary of this build, run
//!   to its end or started in the background;
//! - [`Proc`]: a running child process, killed and reaped when it is dropped, so that a test
//!   that panics leaves no process behind;
//! - [`free_tcp_port`], [`free_udp_port`]: loopback ports nobody listens on;
//! - [`connect_frames`], [`read_frame`], [`read_frames`]: a consumer of the simulator's frame socket;
//! - [`stderr_text`]: a process's log without colours.
//!
//! Each area uses a part of it.

use mgmot_sim::framing::{FrameHeader, HEADER_LEN};
use mgmot_wire::sim_framing::is_end_of_stream;
use std::io::Read;
use std::os::unix::net::UnixStream;
use std::path::Path;
use std::process::{Child, ChildStderr, Command, ExitStatus, Output, Stdio};
use std::time::{Duration, Instant};

pub use mgmot_testkit::{free_tcp_port, free_udp_port, TestDir};

/// The `mgmot-sim` binary this test build built.
pub const SIM_BIN: &str = env!("CARGO_BIN_EXE_mgmot-sim");

/// `mgmot-sim` with `args`, logging warnings and errors (`RUST_LOG=warn`), stdin closed.
pub fn sim(args: &[&str]) -> Command {
    let mut c = Command::new(SIM_BIN);
    c.args(args).env("RUST_LOG", "warn").stdin(Stdio::null());
    c
}

/// Runs `mgmot-sim` with `args` to its end (`RUST_LOG=warn`), stdout and stderr captured.
pub fn run_sim(args: &[&str]) -> Output {
    sim(args).output().expect("mgmot-sim runs")
}

/// Starts `mgmot-sim` with `args` in the background, logging at `info` (the tests read its
/// counts and acknowledgements): stdout discarded, stderr piped
/// ([`Proc::wait_with_output`] reads it).
pub fn spawn_sim(args: &[&str]) -> Proc {
    Proc::start(
        sim(args)
            .env("RUST_LOG", "info")
            .stdout(Stdio::null())
            .stderr(Stdio::piped()),
    )
}

/// A child process, killed and reaped when dropped: when the test ends, passed or not.
pub struct Proc {
    /// `None` once [`Proc::wait_with_output`] took it.
    child: Option<Child>,
}

impl Proc {
    /// Starts `cmd`.
    pub fn start(cmd: &mut Command) -> Proc {
        let child = cmd
            .spawn()
            .unwrap_or_else(|e| panic!("starting {cmd:?}: {e}"));
        Proc { child: Some(child) }
    }

    fn child(&mut self) -> &mut Child {
        self.child.as_mut().expect("a running process")
    }

    /// Its process id.
    pub fn id(&mut self) -> u32 {
        self.child().id()
    }

    /// Its exit status if it has ended.
    pub fn exited(&mut self) -> Option<ExitStatus> {
        self.child()
            .try_wait()
            .expect("waiting for a child process")
    }

    /// Waits up to `limit` for it to end; `None` if it is still running.
    pub fn wait_within(&mut self, limit: Duration) -> Option<ExitStatus> {
        let until = Instant::now() + limit;
        loop {
            if let Some(status) = self.exited() {
                return Some(status);
            }
            if Instant::now() >= until {
                return None;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// Waits for it to end.
    pub fn wait(&mut self) -> ExitStatus {
        self.child().wait().expect("waiting for a child process")
    }

    /// Waits for it to end, collecting what it wrote on the pipes it was started with.
    pub fn wait_with_output(mut self) -> Output {
        let child = self.child.take().expect("a running process");
        child
            .wait_with_output()
            .expect("waiting for a child process")
    }

    /// Its stderr pipe (once), when it was started with a piped stderr.
    pub fn take_stderr(&mut self) -> ChildStderr {
        self.child().stderr.take().expect("a piped stderr")
    }
}

impl Drop for Proc {
    fn drop(&mut self) {
        if let Some(mut child) = self.child.take() {
            let _ = child.kill();
            let _ = child.wait();
        }
    }
}

/// Connects to the simulator's frame socket `path`, retrying for up to 20 s while the
/// simulator starts.
pub fn connect_frames(path: &Path) -> UnixStream {
    let deadline = Instant::now() + Duration::from_secs(20);
    loop {
        match UnixStream::connect(path) {
            Ok(s) => return s,
            Err(_) if Instant::now() < deadline => {
                std::thread::sleep(Duration::from_millis(20));
            }
            Err(e) => panic!("cannot connect to {}: {e}", path.display()),
        }
    }
}

/// One frame of the frame socket.
pub struct Frame {
    /// Its header.
    pub header: FrameHeader,
    /// Its pixels (`header.payload_len` bytes).
    pub pixels: Vec<u8>,
    /// When it had arrived whole.
    pub arrived: Instant,
}

/// The next frame on the socket; `None` at the end of the stream (the end-of-stream header, or
/// the socket closed).
pub fn read_frame(s: &mut UnixStream) -> Option<Frame> {
    let mut h = [0u8; HEADER_LEN];
    s.read_exact(&mut h).ok()?;
    if is_end_of_stream(&h) {
        return None;
    }
    let header = FrameHeader::decode(&h).expect("a valid header");
    let mut pixels = vec![0u8; header.payload_len as usize];
    s.read_exact(&mut pixels).ok()?;
    Some(Frame {
        header,
        pixels,
        arrived: Instant::now(),
    })
}

/// Every frame up to the end of the stream.
pub fn read_frames(s: &mut UnixStream) -> Vec<Frame> {
    let mut frames = Vec::new();
    while let Some(f) = read_frame(s) {
        frames.push(f);
    }
    frames
}

/// What a process wrote on stderr, as text. Its log must carry no ANSI colour sequences: stderr
/// is a pipe here, not a terminal (in a file or the journal they would be escape codes).
pub fn stderr_text(out: &Output) -> String {
    let text = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(
        !text.contains('\u{1b}'),
        "colour codes in a log that is no terminal: {text:?}"
    );
    text
}
