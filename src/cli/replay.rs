//! `mgmot replay`: re-runs tracking over a recorded flight (`[recording]`) from its recorded
//! detections and poses, and writes what `mgmot track` writes. Online with the flight's own
//! parameters it reproduces the flight's tracks exactly, and says whether it did.

use super::stdout::Stdout;
use super::track_output::{track_frames, write_results, FrameTime, Mode, ResultArgs, Tracked};
use anyhow::{bail, Context};
use clap::Args as ClapArgs;
use indicatif::{ProgressBar, ProgressStyle};
use mgmot::config::Config;
use mgmot::formats::input::{self, InputKind};
use mgmot::frame::{FrameClock, GeoSettings, InputBuilder};
use mgmot::geo::AttitudeSmoothing;
use mgmot::record::format::FrameRecord;
use mgmot::record::Flight;
use mgmot::track::{Detection, FrameInput, TrackerParams};
use serde::Serialize;
use std::io::Write;
use std::path::PathBuf;

/// Re-run tracking over a recorded flight and write MOTChallenge results, geolocated tracks
/// and a summary.
///
/// Writes `flight.txt` (MOTChallenge results, frame = the camera's frame index + 1),
/// `flight_tracks.csv` (or .geojson) and `summary.json`. Online with the flight's own tracker
/// parameters (no --config), the replay is compared with the tracks recorded in the air.
#[derive(Debug, ClapArgs)]
pub struct Args {
    /// The flight's folder (`recording.dir`/<UTC start>-sys<id>).
    flight: PathBuf,
    /// online: frame by frame as in the air; offline: the paper's post-processing
    /// (interpolation -> ReID -> interpolation) over the whole flight.
    #[arg(long, value_enum, default_value_t = Mode::Online)]
    mode: Mode,
    /// Tracker parameters (TOML, the keys of `TrackerParams`, as `mgmot track --config`)
    /// instead of the flight's own (its config.toml's `[tracker]`).
    #[arg(long)]
    config: Option<PathBuf>,
    /// Where and how the results are written.
    #[command(flatten)]
    results: ResultArgs,
}

/// How the replay compares with what was recorded in the air.
#[derive(Debug, Serialize)]
struct Comparison {
    /// Frames whose tracks match exactly (ids, boxes, world states).
    frames_identical: usize,
    /// Frames compared.
    frames_compared: usize,
    /// The first frame that differs, and how.
    first_difference: Option<String>,
}

#[derive(Debug, Serialize)]
struct Summary {
    flight: PathBuf,
    mode: Mode,
    parameters: &'static str,
    frames: usize,
    detections: usize,
    detections_geolocated: usize,
    tracks: usize,
    track_boxes: usize,
    merges: usize,
    /// Frame records the recorder dropped or lost (the replay cannot be exact past them).
    records_missing: u64,
    /// Lines of frames.ndjson that could not be read (a crash cuts the last one).
    bad_lines: Vec<usize>,
    ended_cleanly: bool,
    /// Online with the flight's own parameters: the replay against the recorded tracks.
    reproduces_recording: Option<Comparison>,
    mot_results: PathBuf,
    geo_tracks: PathBuf,
}

/// Runs the subcommand.
pub fn run(args: Args) -> anyhow::Result<()> {
    let flight = Flight::load(&args.flight)?;
    let config = Config::parse(&flight.config_toml)
        .map_err(|e| anyhow::anyhow!("{}: {e}", flight.dir.join("config.toml").display()))?;
    let own_parameters = args.config.is_none();
    let params = match &args.config {
        Some(path) => {
            let text = input::read_to_string(path, InputKind::Config)
                .with_context(|| format!("reading {}", path.display()))?;
            toml::from_str::<TrackerParams>(&text)
                .with_context(|| format!("{}: invalid tracker parameters", path.display()))?
        }
        None => config.tracker.clone(),
    };
    params.validate().context("tracker parameters")?;
    // The motion compensation's attitude smoothing is part of the tracker parameters: a
    // replay with other parameters smooths as they say.
    let geo = geo_settings(&config, params.baseline.cmc_smoothing)?;
    if flight.frames.is_empty() {
        bail!(
            "{}: the flight has no frame records (nothing was tracked)",
            flight.dir.display()
        );
    }
    let (inputs, builder) = rebuild_inputs(&flight.frames, geo)?;
    std::fs::create_dir_all(&args.results.out)
        .with_context(|| format!("creating {}", args.results.out.display()))?;
    let progress = if args.results.json {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(inputs.len() as u64)
    };
    progress.set_style(
        ProgressStyle::with_template("replay [{bar:40}] {pos}/{len} frames ({per_sec}, eta {eta})")
            .map_err(|e| anyhow::anyhow!("progress bar template: {e}"))?
            .progress_chars("=> "),
    );
    let tracked = track_frames(
        &inputs,
        args.mode,
        &params,
        args.results.withhold_provisional,
        &progress,
    )?;
    progress.finish_and_clear();
    let frames: Vec<FrameTime> = flight
        .frames
        .iter()
        .map(|f| FrameTime {
            frame_number: f.frame + 1,
            time_s: f.time_s,
        })
        .collect();
    let written = write_results(
        &args.results.out,
        "flight",
        &frames,
        &tracked,
        builder.geolocator().map(|g| g.reference()),
        args.results.class_column,
        args.results.geo_format,
    )?;
    // The end record counts every loss; without one (a crash) the gaps are what is known.
    let records_missing = match &flight.end {
        Some(e) => e.frames_dropped_queue + e.frames_lost_stopped,
        None => flight.gaps.iter().map(|g| g.frames_lost).sum(),
    };
    let summary = Summary {
        flight: flight.dir.clone(),
        mode: args.mode,
        parameters: if own_parameters { "flight" } else { "--config" },
        frames: inputs.len(),
        detections: inputs.iter().map(|i| i.detections.len()).sum(),
        detections_geolocated: inputs
            .iter()
            .flat_map(|i| &i.detections)
            .filter(|d| d.world.is_some())
            .count(),
        tracks: written.tracks,
        track_boxes: written.track_boxes,
        merges: tracked.merges.len(),
        records_missing,
        bad_lines: flight.bad_lines.clone(),
        ended_cleanly: flight.end.is_some(),
        reproduces_recording: (own_parameters
            && args.mode == Mode::Online
            && !args.results.withhold_provisional)
            .then(|| compare(&flight.frames, &tracked)),
        mot_results: written.mot_results,
        geo_tracks: written.geo_tracks,
    };
    let path = args.results.out.join("summary.json");
    std::fs::write(&path, serde_json::to_string_pretty(&summary)? + "\n")
        .with_context(|| format!("writing {}", path.display()))?;
    let mut stdout = Stdout::lock();
    if args.results.json {
        writeln!(stdout, "{}", serde_json::to_string_pretty(&summary)?)?;
        return Ok(());
    }
    writeln!(
        stdout,
        "{}: {} frames, {} detections ({} geolocated), {} tracks, {} merges -> {}, {}",
        summary.flight.display(),
        summary.frames,
        summary.detections,
        summary.detections_geolocated,
        summary.tracks,
        summary.merges,
        summary.mot_results.display(),
        summary.geo_tracks.display()
    )?;
    if !summary.ended_cleanly {
        writeln!(
            stdout,
            "the run did not end cleanly (no end record): replayed what was recorded"
        )?;
    }
    if !summary.bad_lines.is_empty() {
        writeln!(
            stdout,
            "skipped unreadable line(s) of frames.ndjson: {:?}",
            summary.bad_lines
        )?;
    }
    if let Some(c) = &summary.reproduces_recording {
        match &c.first_difference {
            None => writeln!(
                stdout,
                "the replay reproduces the recorded tracks exactly ({} frames)",
                c.frames_compared
            )?,
            Some(d) => writeln!(
                stdout,
                "the replay differs from the recorded tracks: {} of {} frames identical; first difference: {d}{}",
                c.frames_identical,
                c.frames_compared,
                if summary.records_missing > 0 {
                    format!(" ({} frame records were missing from the recording)", summary.records_missing)
                } else {
                    String::new()
                }
            )?,
        }
    }
    Ok(())
}

/// The flight's camera and geolocation settings (as configured in the air), with the motion
/// compensation's attitude smoothing of the tracker parameters the replay runs with.
fn geo_settings(
    config: &Config,
    motion_smoothing: AttitudeSmoothing,
) -> anyhow::Result<GeoSettings> {
    let mut problems = mgmot::config::Problems::default();
    let camera = config.camera.validate(&mut problems);
    let geolocation = config.geolocation.validate(&mut problems);
    match (camera, geolocation) {
        (Some(c), Some(g)) if problems.is_empty() => Ok(GeoSettings {
            hfov_deg: c.hfov_deg,
            noise: g.noise,
            max_range_m: g.max_range_m,
            motion_smoothing,
        }),
        _ => bail!(
            "the flight's config.toml: {}",
            problems
                .into_vec()
                .iter()
                .map(ToString::to_string)
                .collect::<Vec<_>>()
                .join("; ")
        ),
    }
}

/// The tracker's inputs, rebuilt from the recorded detections and poses the way the air did.
fn rebuild_inputs(
    frames: &[FrameRecord],
    geo: GeoSettings,
) -> anyhow::Result<(Vec<FrameInput>, InputBuilder)> {
    let mut builder = InputBuilder::new(geo);
    let mut inputs = Vec::with_capacity(frames.len());
    for f in frames {
        let meta = f
            .pose
            .as_ref()
            .map(|p| p.to_meta())
            .transpose()
            .with_context(|| format!("frame {}: recorded pose", f.frame))?;
        let detections = f.detections.iter().map(|d| Detection { world: None, ..*d });
        // The recorded times are the tracker's own (already continuous): replayed as they are.
        let (input, _, _) = builder.build(
            f.frame,
            FrameClock::source(f.time_s),
            (f.width_px, f.height_px),
            detections,
            meta.as_ref(),
        );
        builder.taken(f.frame);
        inputs.push(input);
    }
    Ok((inputs, builder))
}

/// The replayed tracks against the recorded ones, frame by frame: ids, boxes, scores,
/// classes and world states must be equal, bit for bit.
fn compare(recorded: &[FrameRecord], tracked: &Tracked) -> Comparison {
    let mut by_frame: Vec<Vec<_>> = vec![Vec::new(); recorded.len()];
    for (pos, t) in &tracked.boxes {
        if let Some(v) = by_frame.get_mut(*pos) {
            v.push(t);
        }
    }
    let mut identical = 0;
    let mut first_difference = None;
    for (f, replayed) in recorded.iter().zip(&by_frame) {
        let same = f.tracks.len() == replayed.len()
            && f.tracks.iter().zip(replayed).all(|(r, t)| {
                r.track.id == t.id
                    && r.track.bbox == t.bbox
                    && r.track.score == t.score
                    && r.track.class_id == t.class_id
                    && r.track.world == t.world
            });
        if same {
            identical += 1;
        } else if first_difference.is_none() {
            let ids = |v: &mut dyn Iterator<Item = u64>| v.collect::<Vec<_>>();
            first_difference = Some(format!(
                "frame {}: recorded track ids {:?}, replayed {:?}",
                f.frame,
                ids(&mut f.tracks.iter().map(|t| t.track.id)),
                ids(&mut replayed.iter().map(|t| t.id)),
            ));
        }
    }
    Comparison {
        frames_identical: identical,
        frames_compared: recorded.len(),
        first_difference,
    }
}
