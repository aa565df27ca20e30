//! What the integration tests of `mgmot` and `mgmot-sim` share (each crate's own harness,
//! `tests/common/`, builds on it):
//!
//! - [`TestDir`]: a temporary folder per test, removed when the test passes, kept (and its
//!   path printed) when the test fails or `MGMOT_KEEP_TEST_DIRS=1` is set, to look at the
//!   configs, logs and outputs a failed run left;
//! - [`free_udp_port`], [`free_tcp_port`]: loopback ports nobody listens on right now.

#![warn(missing_docs)]

use std::net::{TcpListener, UdpSocket};
use std::path::{Path, PathBuf};

/// A temporary folder for one test: removed when it is dropped, unless the test is failing
/// (the drop happens while it panics) or `MGMOT_KEEP_TEST_DIRS` is set (to anything but `0`):
/// then it stays, and its path is printed on stderr, which the test's output shows.
pub struct TestDir {
    dir: tempfile::TempDir,
}

impl TestDir {
    /// A new, empty folder, named `mgmot-test-*` in the system's temporary folder.
    pub fn new() -> TestDir {
        let dir = tempfile::Builder::new()
            .prefix("mgmot-test-")
            .tempdir()
            .expect("creating a temporary folder");
        TestDir { dir }
    }

    /// The folder.
    pub fn path(&self) -> &Path {
        self.dir.path()
    }

    /// `path` inside the folder.
    pub fn join(&self, path: impl AsRef<Path>) -> PathBuf {
        self.dir.path().join(path)
    }

    /// Writes `contents` to `name` in the folder; its path.
    pub fn write(&self, name: impl AsRef<Path>, contents: impl AsRef<[u8]>) -> PathBuf {
        let path = self.join(name);
        std::fs::write(&path, contents).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        path
    }
}

impl Default for TestDir {
    fn default() -> Self {
        Self::new()
    }
}

impl Drop for TestDir {
    fn drop(&mut self) {
        let asked =
            std::env::var_os("MGMOT_KEEP_TEST_DIRS").is_some_and(|v| !v.is_empty() && v != "0");
        if std::thread::panicking() || asked {
            self.dir.disable_cleanup(true);
            eprintln!("test folder kept: {}", self.dir.path().display());
        }
    }
}

/// A UDP port free right now on loopback.
pub fn free_udp_port() -> u16 {
    UdpSocket::bind("127.0.0.1:0")
        .and_then(|s| s.local_addr())
        .expect("binding a loopback UDP socket")
        .port()
}

/// A TCP port free right now on loopback.
pub fn free_tcp_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .and_then(|s| s.local_addr())
        .expect("binding a loopback TCP socket")
        .port()
}
