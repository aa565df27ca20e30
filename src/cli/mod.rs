//! Subcommands of the `mgmot` binary. Each one lives in its own file and exposes
//! an `Args` struct (clap) and a `run(args) -> anyhow::Result<()>` function.

mod detect;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

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
    /// Detect swimmers and boats in images with an ONNX model.
    Detect(detect::Args),
}

/// Parses the command line, sets up logging and runs the chosen subcommand.
pub fn main() -> ExitCode {
    let cli = Cli::parse();
    init_logging(cli.verbose);
    let result: anyhow::Result<()> = match cli.command {
        Command::Detect(args) => detect::run(args),
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
