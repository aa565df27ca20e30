//! Log set-up shared by the binaries (`mgmot`, `mgmot-sim`): `tracing` to stderr, so that
//! machine-readable output on stdout stays clean.

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
    let _ = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .try_init();
}
