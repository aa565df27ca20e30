//! Subcommands of `mgmot-sim`, each in its own file with an `Args` struct and a `run`.

mod detections;
mod follow;
mod frames;
#[cfg(feature = "v4l2")]
mod frames_v4l2;
mod link;
mod list;
mod render;
mod run;

use anyhow::Context;
use clap::{Parser, Subcommand};
use mgmot_sim::scenario::Scenario;
use mgmot_sim::world::World;
use std::process::ExitCode;

/// Simulated autopilot telemetry and maritime frame generator for mgmot bench tests.
///
/// A scenario (a shipped name from `mgmot-sim list`, or a TOML file; schema in sim/README.md)
/// describes the drone's path, the gimbal program, the camera, the sea, the objects and the
/// metadata faults. Everything is deterministic for a given seed.
///
/// Modes:
///   run         stream MAVLink 2 telemetry (udpout/udpin/tcpin/tcpout/serial) and frames
///               (Unix socket, or a v4l2loopback device) in real time or lockstep
///   render      write an image sequence plus ground truth (MOT gt.txt, world/camera CSV,
///               SeaDronesSee-style JSON)
///   detections  write simulated detections (COCO results JSON or MOT txt) plus ground truth
///   follow      frames only, for a real autopilot (ArduPilot SITL): render the scenario's
///               world around its home from the camera pose it reports, check mgmot's tracks
///   list        list the shipped scenarios
#[derive(Debug, Parser)]
#[command(name = "mgmot-sim", version, verbatim_doc_comment)]
struct Cli {
    /// More log output (repeat for more); RUST_LOG overrides it.
    #[arg(short, long, action = clap::ArgAction::Count, global = true)]
    verbose: u8,
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// List the shipped scenarios.
    List(list::Args),
    /// Stream telemetry and frames (real time or lockstep).
    Run(run::Args),
    /// Render an image sequence with ground truth.
    Render(render::Args),
    /// Simulate a detector: detections derived from the ground truth, plus the ground truth.
    Detections(detections::Args),
    /// Frames only, for a real autopilot: render the scenario's world from the camera pose
    /// the autopilot reports.
    Follow(follow::Args),
}

/// Options shared by every mode that runs a scenario.
#[derive(Debug, Clone, clap::Args)]
pub struct ScenarioArgs {
    /// Scenario: a shipped name (see `mgmot-sim list`) or a path to a TOML file.
    #[arg(long, short = 's')]
    pub scenario: String,
    /// Seed of all random processes (default: the scenario's `seed`).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Simulate only this many seconds (default: the scenario's `duration_s`).
    #[arg(long)]
    pub duration_s: Option<f64>,
    /// Override the camera width (pixels); the FOV is kept.
    #[arg(long)]
    pub width: Option<u32>,
    /// Override the camera height (pixels).
    #[arg(long)]
    pub height: Option<u32>,
    /// Override the frame rate.
    #[arg(long)]
    pub fps: Option<f64>,
    /// Which drone of a scenario with several (`[[vehicles]]`) to fly: 0 (the default) is the
    /// top-level `drone`, K the K-th entry of `vehicles`. The world and its truth are the same
    /// for all.
    #[arg(long, default_value_t = 0)]
    pub vehicle: usize,
}

impl ScenarioArgs {
    /// Loads the scenario, applies the overrides, validates and builds the world.
    pub fn world(&self) -> anyhow::Result<World> {
        let mut s = Scenario::load(&self.scenario)?.for_vehicle(self.vehicle)?;
        if let Some(d) = self.duration_s {
            s.duration_s = d;
        }
        if let Some(w) = self.width {
            s.camera.width_px = w;
        }
        if let Some(h) = self.height {
            s.camera.height_px = h;
        }
        if let Some(f) = self.fps {
            s.camera.fps = f;
        }
        s.validate("(after command-line overrides)")
            .context("invalid command-line override")?;
        let seed = self.seed.unwrap_or(s.seed);
        Ok(World::new(s, seed))
    }
}

/// Logs to stderr: `RUST_LOG` when set, else info, debug with `-v`, trace with `-vv`.
fn init_logging(verbose: u8) {
    let level = match verbose {
        0 => "info",
        1 => "debug",
        _ => "trace",
    };
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new(level));
    // Fails only when a subscriber is already installed, which then keeps logging.
    // Colours only on a terminal: in a file or a pipe they are escape codes.
    let _ = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .try_init();
}

/// Parses the command line, sets up logging and runs the chosen subcommand.
pub fn main() -> ExitCode {
    let cli = Cli::parse();
    init_logging(cli.verbose);
    let result = match cli.command {
        Command::List(a) => list::run(a),
        Command::Run(a) => run::run(a),
        Command::Render(a) => render::run(a),
        Command::Detections(a) => detections::run(a),
        Command::Follow(a) => follow::run(a),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
