//! `mgmot firmware-check`: check autopilot parameter files against parameter metadata.

use super::stdout::Stdout;
use anyhow::Context;
use clap::{Args as ClapArgs, ValueEnum};
use mgmot::firmware::{self, Autopilot, ParamTable};
use std::io::Write;
use std::path::PathBuf;

/// Which autopilot the files are for.
#[derive(Debug, Clone, Copy, ValueEnum)]
enum Kind {
    /// ArduPilot `.parm` (`NAME VALUE` per line).
    Ardupilot,
    /// QGroundControl `.params` for PX4 (`vehicle-id component-id name value type`).
    Px4,
}

/// Check autopilot parameter files (firmware-config/) against parameter metadata tables:
/// every name known, every value of its type, range and documented values.
#[derive(Debug, ClapArgs)]
pub struct Args {
    /// The parameter files.
    #[arg(required = true)]
    files: Vec<PathBuf>,
    /// The autopilot the files are for.
    #[arg(long, value_enum)]
    autopilot: Kind,
    /// A metadata table (TSV from scripts/firmware_extract_params.py) instead of the shipped
    /// one (firmware-config/metadata/: ArduCopter at ArduPilot 90700977c5, PX4).
    #[arg(long)]
    table: Option<PathBuf>,
    /// Machine-readable output: one JSON object with the problems of every file.
    #[arg(long)]
    json: bool,
}

/// Runs the subcommand: prints every problem as FILE:LINE: ..., fails if there is one.
pub fn run(args: Args) -> anyhow::Result<()> {
    let autopilot = match args.autopilot {
        Kind::Ardupilot => Autopilot::ArduPilot,
        Kind::Px4 => Autopilot::Px4,
    };
    let table = match &args.table {
        Some(path) => ParamTable::load(path)?,
        None => {
            ParamTable::parse(autopilot.shipped_table()).context("the shipped metadata table")?
        }
    };
    let mut out = Stdout::lock();
    let mut total = 0usize;
    let mut report = serde_json::Map::new();
    for file in &args.files {
        let problems = firmware::check_file(autopilot, file, &table)?;
        total += problems.len();
        if args.json {
            let list: Vec<serde_json::Value> = problems
                .iter()
                .map(|p| serde_json::json!({"line": p.line, "name": p.name, "message": p.message}))
                .collect();
            report.insert(file.display().to_string(), list.into());
        } else if problems.is_empty() {
            writeln!(out, "{}: ok", file.display())?;
        } else {
            for p in &problems {
                writeln!(
                    out,
                    "{}:{}",
                    file.display(),
                    p.to_string().trim_start_matches("line ")
                )?;
            }
        }
    }
    if args.json {
        writeln!(out, "{}", serde_json::Value::Object(report))?;
    }
    if total > 0 {
        anyhow::bail!("{total} problem(s) in the parameter files");
    }
    Ok(())
}
