//! `mgmot ground`: the fused ground picture of every drone (live map, GeoJSON, CoT,
//! recording).

use super::signals::run_until_signal;
use anyhow::Context;
use clap::Args as ClapArgs;
use mgmot::ground::{self, GroundConfig};
use std::path::PathBuf;
use std::time::Duration;

/// Fuse the tracks of every drone into one picture: one id per object across drones.
/// Serves a live map (http://127.0.0.1:8080/ by default). SIGINT / SIGTERM stop it.
#[derive(Debug, ClapArgs)]
pub struct Args {
    /// Configuration file (every key has a default; see systemd/mgmot-ground.example.toml).
    #[arg(long)]
    config: Option<PathBuf>,
    /// MAVLink input, replacing `input.connections` (repeat for several):
    /// udpin:HOST:PORT or udpout:HOST:PORT.
    #[arg(long = "connection", value_name = "ENDPOINT")]
    connections: Vec<String>,
    /// The live map's address, replacing `outputs.http` ("" for none).
    #[arg(long, value_name = "HOST:PORT")]
    http: Option<String>,
    /// Write the picture as GeoJSON to this file at every update.
    #[arg(long, value_name = "FILE")]
    geojson: Option<PathBuf>,
    /// Record the fused picture to this file (JSON lines; `mgmot review --ground FILE`).
    #[arg(long, value_name = "FILE")]
    record: Option<PathBuf>,
    /// Send fused Cursor-on-Target here (udp://, tcp:// or tls:// as `[outputs.cot].url`;
    /// turns the CoT output on).
    #[arg(long, value_name = "URL")]
    cot: Option<String>,
    /// Stop after this many seconds (default: run until SIGINT / SIGTERM).
    #[arg(long, value_name = "S")]
    duration_s: Option<f64>,
    /// At exit, write the run's counters as JSON to this file.
    #[arg(long, value_name = "FILE")]
    stats_json: Option<PathBuf>,
}

/// Runs the subcommand.
pub fn run(args: Args) -> anyhow::Result<()> {
    let mut config = match &args.config {
        Some(path) => GroundConfig::load(path)?,
        None => GroundConfig::default(),
    };
    if !args.connections.is_empty() {
        config.input.connections = args.connections.clone();
    }
    if let Some(http) = &args.http {
        config.outputs.http = http.clone();
    }
    if let Some(path) = &args.geojson {
        config.outputs.geojson = path.clone();
    }
    if let Some(path) = &args.record {
        config.outputs.record = path.clone();
    }
    if let Some(url) = &args.cot {
        config.outputs.cot.enabled = true;
        config.outputs.cot.url = url.clone();
    }
    let duration = args
        .duration_s
        .map(|s| {
            anyhow::ensure!(
                s.is_finite() && s > 0.0,
                "--duration-s must be a positive number of seconds, not {s}"
            );
            Ok(Duration::from_secs_f64(s))
        })
        .transpose()?;
    let source = args
        .config
        .clone()
        .unwrap_or_else(|| PathBuf::from("(defaults and flags)"));
    let settings = config.validate(&source)?;
    let effective = serde_json::to_value(&config).context("serialising the configuration")?;
    let stats = run_until_signal(|shutdown| async move {
        Ok(ground::run(settings, effective, shutdown, duration).await?)
    })?;
    eprintln!(
        "mgmot ground: {} drones, {} MGMOT_TRACK ({} used, {} provisional, {} without position), {} digest positions, {} fused ids ({} merged away), {} updates",
        stats.drones,
        stats.ingest.track_messages,
        stats.ingest.track_reports_used,
        stats.ingest.provisional,
        stats.ingest.not_geolocated,
        stats.ingest.digest_positions,
        stats.fused_ids,
        stats.retired,
        stats.updates,
    );
    if let Some(path) = &args.stats_json {
        let json = serde_json::to_string_pretty(&stats).context("serialising the stats")?;
        std::fs::write(path, json + "\n")
            .with_context(|| format!("writing the stats to {}", path.display()))?;
    }
    Ok(())
}
