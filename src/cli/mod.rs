//! Subcommands of the `mgmot` binary. Each one lives in its own file and exposes
//! an `Args` struct (clap) and a `run(args) -> anyhow::Result<()>` function.

use clap::{Parser, Subcommand};
use std::process::ExitCode;

mod check_config;
mod eval;
mod geolocate;
mod run;
mod track;

/// Metadata-guided multi-object tracking for maritime search-and-rescue drones.
#[derive(Debug, Parser)]
#[command(name = "mgmot", version, about, long_about = None)]
struct Cli {
    /// More log output (repeat for more); RUST_LOG overrides it.
    #[arg(short, long, action = clap::ArgAction::Count, global = true)]
    verbose: u8,
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Geolocate boxes (ground truth or detections) on the sea surface.
    Geolocate(geolocate::Args),
    /// Evaluate tracking results against ground truth (HOTA, CLEAR, Identity).
    Eval(eval::Args),
    /// Track the videos of a SeaDronesSee file and geolocate the tracks.
    Track(track::Args),
    /// Check a runtime configuration file.
    CheckConfig(check_config::Args),
    /// Run the onboard pipeline (MAVLink, frames, detector, tracker, track messages).
    Run(run::Args),
}

/// Parses the command line, sets up logging and runs the chosen subcommand.
pub fn main() -> ExitCode {
    let cli = Cli::parse();
    init_logging(cli.verbose);
    let result: anyhow::Result<()> = match cli.command {
        Command::Geolocate(args) => geolocate::run(args),
        Command::Eval(args) => eval::run(args),
        Command::Track(args) => track::run(args),
        Command::CheckConfig(args) => check_config::run(args),
        Command::Run(args) => run::run(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

fn init_logging(verbose: u8) {
    let default = match verbose {
        0 => "warn",
        1 => "info",
        2 => "debug",
        _ => "trace",
    };
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new(default));
    // Logs go to stderr so that `--json` output on stdout stays machine-readable.
    let _ = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .try_init();
}
