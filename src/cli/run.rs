//! `mgmot run`: the onboard runtime (what flies).

use super::signals::run_until_signal;
use anyhow::Context;
use clap::Args as ClapArgs;
use mgmot::config::Config;
use mgmot::pipeline;
use std::io::Write;
use std::path::PathBuf;

/// Run the onboard pipeline: MAVLink link, frames, detector, tracker, track messages.
/// SIGINT / SIGTERM stop it cleanly (exit 0).
#[derive(Debug, ClapArgs)]
pub struct Args {
    /// The configuration file (see systemd/mgmot.example.toml; check it with `mgmot
    /// check-config`).
    #[arg(long)]
    config: PathBuf,
    /// At exit, write the run's counters and per-stage latency percentiles (µs) as JSON to
    /// this file (for benchmarks; scripts/bench_runtime.sh reads it).
    #[arg(long)]
    stats_json: Option<PathBuf>,
}

/// Runs the subcommand.
pub fn run(args: Args) -> anyhow::Result<()> {
    // The configuration is validated into typed settings once, before anything starts.
    let (config, settings) = Config::load(&args.config)?;
    // The configuration as it takes effect (defaults filled in), for the flight record.
    let effective = toml::to_string(&config).context("serialising the configuration")?;
    // Opened (and emptied, so no stale stats survive a failed run) before the run starts: an
    // unwritable path is an error now, not after a flight.
    let mut stats_file = args
        .stats_json
        .as_ref()
        .map(|path| {
            std::fs::OpenOptions::new()
                .write(true)
                .create(true)
                .truncate(true)
                .open(path)
                .map(|file| (path, file))
                .with_context(|| {
                    format!(
                        "cannot open the --stats-json file {} for writing",
                        path.display()
                    )
                })
        })
        .transpose()?;
    run_until_signal(|shutdown| async move {
        let stats = pipeline::run(settings, &effective, shutdown).await?;
        eprintln!(
            "mgmot run: {} frames captured, {} processed ({} without pose), {} dropped, {} detector errors, {} track messages",
            stats.frames_captured,
            stats.frames_processed,
            stats.frames_without_pose,
            stats.frames_dropped,
            stats.detector_errors,
            stats.track_messages
        );
        if let Some((path, file)) = &mut stats_file {
            let json = serde_json::to_string_pretty(&stats).context("serialising the stats")?;
            file.write_all((json + "\n").as_bytes())
                .and_then(|()| file.flush())
                .with_context(|| format!("writing the stats to {}", path.display()))?;
        }
        Ok(())
    })
}
