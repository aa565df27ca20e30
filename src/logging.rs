//! Log set-up shared by the binaries (`mgmot`, `mgmot-sim`): `tracing` to stderr, so that
//! machine-readable output on stdout stays clean; and [`LogThrottle`], which every log line
//! that input can repeat goes through.

use std::time::{Duration, Instant};

/// Rate-limited log lines repeat at most this often (with the number suppressed between).
pub const LOG_EVERY: Duration = Duration::from_secs(10);

/// Rate-limits one kind of log line: at most one per [`LOG_EVERY`], the next one saying how
/// many were suppressed meanwhile. A line that a sender or a fault can make repeat (a flood of
/// commands, a forged message, a flapping source) goes through one, so no input can flood
/// the log.
#[derive(Debug, Default)]
pub struct LogThrottle {
    last: Option<Instant>,
    suppressed: u64,
}

impl LogThrottle {
    /// `Some(suppressed since the last one)` when a line may be logged now.
    pub fn allow(&mut self) -> Option<u64> {
        self.allow_at(Instant::now())
    }

    /// [`LogThrottle::allow`] at `now`.
    pub fn allow_at(&mut self, now: Instant) -> Option<u64> {
        if self.last.is_some_and(|t| now.duration_since(t) < LOG_EVERY) {
            self.suppressed += 1;
            return None;
        }
        self.last = Some(now);
        Some(std::mem::take(&mut self.suppressed))
    }
}

/// Installs a stderr `tracing` subscriber. `RUST_LOG` wins; otherwise `verbose` picks the level
/// above `default_level` (each step one level more: info, debug, trace). Calling it twice is
/// harmless (the second call does nothing).
pub fn init(default_level: tracing::Level, verbose: u8) {
    const LEVELS: [tracing::Level; 5] = [
        tracing::Level::ERROR,
        tracing::Level::WARN,
        tracing::Level::INFO,
        tracing::Level::DEBUG,
        tracing::Level::TRACE,
    ];
    let base = LEVELS.iter().position(|l| *l == default_level).unwrap_or(1);
    let level = LEVELS[(base + usize::from(verbose)).min(LEVELS.len() - 1)];
    let filter = tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| {
        tracing_subscriber::EnvFilter::new(level.as_str().to_ascii_lowercase())
    });
    // Colours only on a terminal: in the journal, a file or a pipe they are escape codes.
    let _ = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .try_init();
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_line_per_period_then_the_count_suppressed() {
        let mut t = LogThrottle::default();
        let t0 = Instant::now();
        assert_eq!(t.allow_at(t0), Some(0));
        for k in 1..=1000u64 {
            assert_eq!(t.allow_at(t0 + Duration::from_millis(k)), None);
        }
        assert_eq!(t.allow_at(t0 + LOG_EVERY), Some(1000));
        assert_eq!(t.allow_at(t0 + LOG_EVERY), None);
    }
}
