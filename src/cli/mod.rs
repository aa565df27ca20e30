//! Subcommands of the `mgmot` binary. Each one lives in its own file and exposes
//! an `Args` struct (clap) and a `run(args) -> anyhow::Result<()>` function.

use clap::{Parser, Subcommand};
use std::process::ExitCode;

mod args;
mod check_config;
mod detect;
mod eval;
mod firmware_check;
mod geolocate;
mod ground;
mod oracle;
mod replay;
mod review;
mod run;
mod signals;
mod stdout;
mod track;
mod track_output;

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
    /// Detect swimmers and boats in images with an ONNX model.
    Detect(detect::Args),
    /// Check a runtime configuration file.
    CheckConfig(check_config::Args),
    /// Check autopilot parameter files against parameter metadata.
    FirmwareCheck(firmware_check::Args),
    /// Run the onboard pipeline (MAVLink, frames, detector, tracker, track messages).
    Run(run::Args),
    /// Review a recorded flight: an HTML report plus GeoJSON and KML of the tracks.
    Review(review::Args),
    /// Re-run tracking over a recorded flight (online reproduces it; offline post-processes).
    Replay(replay::Args),
    /// Fuse every drone's tracks into one ground picture (live map, GeoJSON, CoT, recording).
    Ground(ground::Args),
    /// Label detections with their true ids: the identity ceiling for tracking benchmarks.
    Oracle(oracle::Args),
}

/// Parses the command line, sets up logging and runs the chosen subcommand.
pub fn main() -> ExitCode {
    let cli = Cli::parse();
    mgmot::logging::init(tracing::Level::WARN, cli.verbose);
    let result: anyhow::Result<()> = match cli.command {
        Command::Geolocate(args) => geolocate::run(args),
        Command::Eval(args) => eval::run(args),
        Command::Track(args) => track::run(args),
        Command::Detect(args) => detect::run(args),
        Command::CheckConfig(args) => check_config::run(args),
        Command::FirmwareCheck(args) => firmware_check::run(args),
        Command::Run(args) => run::run(args),
        Command::Review(args) => review::run(args),
        Command::Replay(args) => replay::run(args),
        Command::Ground(args) => ground::run(args),
        Command::Oracle(args) => oracle::run(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        // The reader of stdout went away (`mgmot ... | head`): nothing to report.
        Err(e) if stdout::is_closed(&e) => ExitCode::from(stdout::CLOSED_EXIT_CODE),
        Err(e) => {
            eprintln!("error: {}", said_once(&e));
            ExitCode::FAILURE
        }
    }
}

/// The error and its causes in one line, each said once: an error whose message already
/// includes its cause's (`#[error("model: {0}")]` over a `#[source]`) does not repeat it,
/// as `{:#}` would ("cannot read: No such file: No such file").
fn said_once(e: &anyhow::Error) -> String {
    let mut line = e.to_string();
    for cause in e.chain().skip(1) {
        let cause = cause.to_string();
        if !line.contains(&cause) {
            line += ": ";
            line += &cause;
        }
    }
    line
}
