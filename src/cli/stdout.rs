//! Standard output for the subcommands, ending quietly when the reader goes away.
//!
//! Rust ignores SIGPIPE, so a write to a closed pipe (`mgmot check-config FILE | head -1`)
//! returns `BrokenPipe`, on which `println!` panics. Every subcommand writes its stdout
//! through [`Stdout`] instead: a `BrokenPipe` there becomes an error carrying
//! [`StdoutClosed`], which stops the command (nothing more can be shown), and `main` turns it
//! into a quiet exit with status [`CLOSED_EXIT_CODE`] (141 = 128 + SIGPIPE), what a shell
//! reports for a C tool killed by SIGPIPE: in a pipeline without `pipefail` the pipeline's
//! status is the reader's, and with `pipefail` a script sees that mgmot did not finish (for
//! `mgmot detect` the per-image lines come while it works, so `--out` may be incomplete).
//!
//! SIGPIPE is deliberately left ignored rather than restored to its default: `mgmot run`
//! writes to MAVLink TCP links and the simulator's socket, where a peer going away must be an
//! error the runtime reports, not a signal that kills it. Only stdout's `BrokenPipe` is
//! treated this way; one from a socket or a file is an ordinary error.

use std::io::{self, Write};

/// Exit status after stdout was closed by its reader (128 + SIGPIPE).
pub const CLOSED_EXIT_CODE: u8 = 141;

/// Stdout was closed by its reader; the payload of the `io::Error` [`Stdout`] returns then.
#[derive(Debug, thiserror::Error)]
#[error("standard output was closed")]
pub struct StdoutClosed;

/// Whether `error` (anywhere in its chain) is stdout being closed by its reader.
pub fn is_closed(error: &anyhow::Error) -> bool {
    error.chain().any(|cause| {
        cause.is::<StdoutClosed>()
            || cause
                .downcast_ref::<io::Error>()
                .and_then(|e| e.get_ref())
                .is_some_and(|inner| inner.is::<StdoutClosed>())
    })
}

/// Locked standard output whose `BrokenPipe` errors carry [`StdoutClosed`].
pub struct Stdout(io::StdoutLock<'static>);

impl Stdout {
    /// Locks stdout (line-buffered, as `println!`'s).
    pub fn lock() -> Self {
        Self(io::stdout().lock())
    }
}

/// Marks a `BrokenPipe` as stdout's.
fn mark(e: io::Error) -> io::Error {
    if e.kind() == io::ErrorKind::BrokenPipe {
        io::Error::new(io::ErrorKind::BrokenPipe, StdoutClosed)
    } else {
        e
    }
}

impl Write for Stdout {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.0.write(buf).map_err(mark)
    }

    fn flush(&mut self) -> io::Result<()> {
        self.0.flush().map_err(mark)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_stdouts_broken_pipe_counts_as_closed() {
        let closed = anyhow::Error::new(mark(io::Error::from(io::ErrorKind::BrokenPipe)))
            .context("printing the summary");
        assert!(is_closed(&closed));
        let socket = anyhow::Error::new(io::Error::from(io::ErrorKind::BrokenPipe));
        assert!(!is_closed(&socket));
        let other = anyhow::Error::new(mark(io::Error::from(io::ErrorKind::PermissionDenied)));
        assert!(!is_closed(&other));
    }
}
