//! `mgmot check-config`: load and validate a runtime configuration without running anything.

use super::stdout::Stdout;
use anyhow::Context;
use clap::Args as ClapArgs;
use mgmot::config::{Config, ConfigError, Problems};
use mgmot::formats::input::{self, InputKind};
use std::io::Write;
use std::path::PathBuf;

/// Check a runtime configuration file (TOML) and print what it sets up.
#[derive(Debug, ClapArgs)]
pub struct Args {
    /// The configuration file (see systemd/mgmot.example.toml).
    file: PathBuf,
}

/// Runs the subcommand: prints a summary, or fails with every problem found (in the values,
/// then in the files the detector needs).
pub fn run(args: Args) -> anyhow::Result<()> {
    // `Config::load` reads whatever the path names; refuse devices, FIFOs and huge files
    // first (a FIFO without a writer would block, /dev/zero would fill memory).
    input::open(&args.file, InputKind::Config).with_context(|| args.file.display().to_string())?;
    let (config, settings) = Config::load(&args.file)?;
    // The files the run needs at start (the model, ONNX Runtime): `mgmot run` would fail on them.
    let mut problems = Problems::default();
    settings.detector.check_files(&mut problems);
    if !problems.is_empty() {
        return Err(ConfigError::Invalid {
            path: args.file.clone(),
            problems: problems.into_vec(),
        }
        .into());
    }
    let mut out = Stdout::lock();
    writeln!(out, "{}: ok", args.file.display())?;
    writeln!(
        out,
        "  mavlink: {} as {}/{}{}",
        settings.mavlink.connection,
        settings.mavlink.system_id,
        settings.mavlink.component_id,
        if settings.mavlink.signing.is_some() {
            ", signed"
        } else {
            ""
        }
    )?;
    writeln!(out, "  frames: {}", settings.frames)?;
    writeln!(
        out,
        "  outputs: tracks at {} Hz{}, heartbeat at {} Hz",
        config.outputs.track_rate_hz,
        if settings.outputs.target_absolute {
            " (+ TARGET_ABSOLUTE)"
        } else {
            ""
        },
        config.outputs.heartbeat_hz
    )?;
    match &settings.recording {
        Some(r) => writeln!(
            out,
            "  recording: {} (cap {}, keyframes {})",
            r.dir.display(),
            r.max_total_bytes
                .map_or("none".to_owned(), |b| format!("{} MB", b >> 20)),
            r.keyframe_every
                .map_or("off".to_owned(), |d| format!("every {} s", d.as_secs_f64()))
        )?,
        None => writeln!(out, "  recording: off")?,
    }
    Ok(())
}
