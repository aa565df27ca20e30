//! `mgmot-sim`: simulated autopilot telemetry (MAVLink 2) and maritime frame generator with
//! ground truth, for bench-testing `mgmot`. See `sim/README.md` and `mgmot-sim --help`.
mod cli;

fn main() -> std::process::ExitCode {
    cli::main()
}
