//! `mgmot review`: a recorded flight as one self-contained HTML report, plus
//! `tracks.geojson` and `tracks.kml` beside it.

use super::stdout::Stdout;
use anyhow::Context;
use clap::Args as ClapArgs;
use indicatif::{ProgressBar, ProgressStyle};
use mgmot::record::Flight;
use mgmot::review::{self, Review, Truth};
use std::io::Write;
use std::path::PathBuf;
use std::time::Duration;

/// Review a recorded flight: map, timeline, tracks, telemetry health, keyframes.
///
/// Writes one HTML file that opens without a network (inline SVG and script, keyframes
/// embedded), and `tracks.geojson` and `tracks.kml` in the same folder (QGIS, Google Earth).
#[derive(Debug, ClapArgs)]
pub struct Args {
    /// The flight's folder (`<recording.dir>/<UTC start>-sys<id>`, holding flight.json), or
    /// a `mgmot ground --record` file (the fused picture: a table of the fused ids and
    /// `ground_tracks.geojson` of their paths beside the report).
    flight: PathBuf,
    /// The report (HTML); its folder is created if missing.
    #[arg(long)]
    out: PathBuf,
    /// The simulator's truth folder (`mgmot-sim run --truth-out DIR`): adds the error of the
    /// reported positions per true object.
    #[arg(long)]
    truth: Option<PathBuf>,
}

/// A spinner on stderr (hidden when stderr is not a terminal).
fn spinner() -> ProgressBar {
    let pb = ProgressBar::new_spinner();
    if let Ok(style) = ProgressStyle::with_template("{spinner} {msg} ({elapsed})") {
        pb.set_style(style);
    }
    pb.enable_steady_tick(Duration::from_millis(120));
    pb
}

/// Runs the subcommand.
pub fn run(args: Args) -> anyhow::Result<()> {
    if args.flight.is_file() {
        return run_ground(&args);
    }
    let pb = spinner();
    pb.set_message("reading the flight");
    let flight = Flight::load(&args.flight).with_context(|| {
        format!(
            "{} is not a readable mgmot flight folder",
            args.flight.display()
        )
    })?;
    let (tlog, tlog_clean) = match flight.tlog() {
        Ok(t) => t,
        Err(e) => {
            tracing::warn!(error = %e, "flight.tlog unreadable; telemetry health will be empty");
            (Vec::new(), false)
        }
    };
    let truth = match &args.truth {
        Some(dir) => {
            pb.set_message("reading the truth");
            Some(Truth::load(dir)?)
        }
        None => None,
    };
    pb.set_message("computing the review");
    let mut review = Review::build(&flight, &tlog, tlog_clean, truth.as_ref());
    pb.set_message("writing the report");
    let written = review::write(&mut review, &flight.dir, &args.out)?;
    pb.finish_and_clear();
    tracing::info!(
        frames = flight.frames.len(),
        tracks = review.tracks.len(),
        "flight reviewed"
    );
    let mut out = Stdout::lock();
    writeln!(
        out,
        "{}: {} frames, {} tracks{}",
        args.flight.display(),
        flight.frames.len(),
        review.tracks.len(),
        if flight.end.is_none() {
            " (the run did not end cleanly)"
        } else {
            ""
        }
    )?;
    if let Some(t) = &review.truth {
        writeln!(
            out,
            "truth: {} reports matched, error median {:.2} m, p95 {:.2} m, max {:.2} m; \
             {} unmatched, {} timed by the companion's clock, {} without a time in the truth",
            t.matched,
            t.overall.median_m,
            t.overall.p95_m,
            t.overall.max_m,
            t.unmatched,
            t.retimed,
            t.untimed
        )?;
    }
    writeln!(out, "report:  {}", written.report.display())?;
    writeln!(out, "geojson: {}", written.geojson.display())?;
    writeln!(out, "kml:     {}", written.kml.display())?;
    Ok(())
}

/// Reviews a `mgmot ground` recording.
fn run_ground(args: &Args) -> anyhow::Result<()> {
    anyhow::ensure!(
        args.truth.is_none(),
        "--truth is for flight folders; {} is a file (a ground recording?)",
        args.flight.display()
    );
    let (_, pictures) = mgmot::ground::record::read(&args.flight).map_err(anyhow::Error::msg)?;
    let lives = review::ground::lives(&pictures);
    let folder = match args.out.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_owned(),
        _ => PathBuf::from("."),
    };
    std::fs::create_dir_all(&folder).with_context(|| format!("creating {}", folder.display()))?;
    let html = review::ground::html(&lives, pictures.len(), &args.flight.display().to_string());
    std::fs::write(&args.out, html).with_context(|| format!("writing {}", args.out.display()))?;
    let geojson = folder.join("ground_tracks.geojson");
    std::fs::write(&geojson, review::ground::paths_geojson(&lives).to_string())
        .with_context(|| format!("writing {}", geojson.display()))?;
    let mut out = Stdout::lock();
    writeln!(
        out,
        "{}: {} updates, {} fused ids",
        args.flight.display(),
        pictures.len(),
        lives.len()
    )?;
    writeln!(out, "report:  {}", args.out.display())?;
    writeln!(out, "geojson: {}", geojson.display())?;
    Ok(())
}
