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
    /// The flight's folder (`<recording.dir>/<UTC start>-sys<id>`, holding flight.json).
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
