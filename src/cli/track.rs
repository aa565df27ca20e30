//! `mgmot track`: track every video of a SeaDronesSee file from its detections, offline or as
//! the onboard (online) tracker would, and write MOTChallenge results plus geolocated tracks.

use super::args::Finite;
use super::stdout::Stdout;
use super::track_output::{track_frames, write_results, FrameTime, Mode, ResultArgs};
use anyhow::{bail, Context};
use clap::Args as ClapArgs;
use indicatif::{ProgressBar, ProgressStyle};
use mgmot::formats::input::{self, InputKind};
use mgmot::formats::seadronessee::{self, Dataset, Sequence};
use mgmot::formats::{coco, mot};
use mgmot::frame::{tracker_input, CameraMotion};
use mgmot::geo::{CameraModel, Geolocator, PoseNoise};
use mgmot::track::{Appearance, BBox, Detection, MergeEvent, TrackerParams};
use serde::Serialize;
use std::collections::HashMap;
use std::io::Write;
use std::path::{Component, Path, PathBuf};

/// Largest metadata lag either way (s): SeaDronesSee's logs lag by about 1 s; a minute covers
/// any clock offset between a camera and a flight log, and beyond it every frame of a short
/// clip would get the clamped first or last record.
const MAX_METADATA_LAG_S: f64 = 60.0;
/// Highest frame rate (fps): above any camera a drone carries (high-speed modes reach 240).
const MAX_FPS: f64 = 1000.0;

/// Track each video of a SeaDronesSee file and geolocate the tracks.
///
/// Writes, per video, `<video>.txt` (MOTChallenge results: frame,id,x,y,w,h,conf,-1,-1),
/// `<video>_tracks.csv` (or .geojson: one row per track per frame with lat/lon), and a
/// `summary.json` with the counts and the online mode's merge events.
#[derive(Debug, ClapArgs)]
pub struct Args {
    /// SeaDronesSee JSON with the frames and their drone metadata.
    #[arg(long)]
    annotations: PathBuf,
    /// Detections: COCO results JSON (.json) or MOTChallenge det.txt (.txt; frame numbers are
    /// 1-based positions in the video, which must then be the only one or chosen by --video).
    #[arg(long)]
    detections: PathBuf,
    /// online: frame by frame as in the air (ReID links a new track after w frames and reports
    /// a merge); offline: the paper's post-processing over the whole video.
    #[arg(long, value_enum, default_value_t = Mode::Online)]
    mode: Mode,
    /// Ignore the drone metadata: the BoT-SORT baseline, no geolocation or ReID (it still
    /// coasts by `baseline.coast_frames`; a config with 0 gives BoT-SORT's exact output).
    #[arg(long)]
    no_metadata: bool,
    /// Only this video.
    #[arg(long)]
    video: Option<String>,
    /// Tracker parameters (TOML, the keys of `TrackerParams`); defaults are the paper's.
    #[arg(long)]
    config: Option<PathBuf>,
    /// Horizontal field of view of the camera (deg, in (0, 180)).
    #[arg(long, default_value_t = 70.0, value_parser = Finite::between(0.0, 180.0).f64())]
    fov_deg: f64,
    /// How long the metadata lags the video (s, -60 to 60; negative: it leads): each metadata
    /// record describes the moment this long before the frame it comes with; the pose is
    /// interpolated between records. SeaDronesSee's DJI logs lag by about 1 s; simulator
    /// output has no lag.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true,
          value_parser = Finite::in_range(-MAX_METADATA_LAG_S, MAX_METADATA_LAG_S).f64())]
    metadata_lag_s: f64,
    /// Frame rate used to time frames from `source.frame_no` when images have no `date_time`
    /// (fps, in (0, 1000]).
    #[arg(long, default_value_t = seadronessee::DEFAULT_VIDEO_FPS,
          value_parser = Finite::positive(MAX_FPS).f64())]
    fps: f64,
    /// Where and how the results are written.
    #[command(flatten)]
    results: ResultArgs,
}

/// Per-video outcome.
#[derive(Debug, Serialize)]
struct VideoSummary {
    video: String,
    frames: usize,
    detections: usize,
    detections_geolocated: usize,
    tracks: usize,
    track_boxes: usize,
    mot_results: PathBuf,
    geo_tracks: PathBuf,
    merges: Vec<MergeEvent>,
}

/// Detections of one image: (category, bbox, score).
type Dets = Vec<(u32, [f64; 4], f64, Option<Appearance>)>;

/// Runs the subcommand.
pub fn run(args: Args) -> anyhow::Result<()> {
    let params = match &args.config {
        Some(path) => {
            let text = input::read_to_string(path, InputKind::Config)
                .with_context(|| format!("reading {}", path.display()))?;
            let p: TrackerParams = toml::from_str(&text)
                .with_context(|| format!("{}: invalid tracker parameters", path.display()))?;
            p
        }
        None => TrackerParams::default(),
    };
    params.validate().context("tracker parameters")?;
    let ds = seadronessee::read_dataset(&args.annotations)?;
    let mut sequences = ds.sequences(args.fps);
    if let Some(name) = &args.video {
        sequences.retain(|s| &s.name == name);
        if sequences.is_empty() {
            bail!("no video named {name:?} in {}", args.annotations.display());
        }
    }
    for seq in &sequences {
        check_output_name(&ds, seq)?;
    }
    let dets_by_image = load_detections(&args, &ds, &sequences)?;
    std::fs::create_dir_all(&args.results.out)
        .with_context(|| format!("creating {}", args.results.out.display()))?;

    let total_frames: usize = sequences.iter().map(|s| s.frames.len()).sum();
    let progress = if args.results.json {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(total_frames as u64)
    };
    progress.set_style(
        ProgressStyle::with_template(
            "{msg:>24} [{bar:40}] {pos}/{len} frames ({per_sec}, eta {eta})",
        )
        .map_err(|e| anyhow::anyhow!("progress bar template: {e}"))?
        .progress_chars("=> "),
    );

    let mut summaries = Vec::new();
    for seq in &sequences {
        progress.set_message(seq.name.clone());
        summaries.push(track_video(
            &args,
            &params,
            &ds,
            seq,
            &dets_by_image,
            &progress,
        )?);
    }
    progress.finish_and_clear();

    let summary = serde_json::json!({ "mode": args.mode, "metadata": !args.no_metadata, "videos": summaries });
    let summary_path = args.results.out.join("summary.json");
    std::fs::write(
        &summary_path,
        serde_json::to_string_pretty(&summary)? + "\n",
    )
    .with_context(|| format!("writing {}", summary_path.display()))?;
    let mut stdout = Stdout::lock();
    if args.results.json {
        writeln!(stdout, "{}", serde_json::to_string_pretty(&summary)?)?;
    } else {
        for s in &summaries {
            writeln!(
                stdout,
                "{}: {} frames, {} detections ({} geolocated), {} tracks, {} merges -> {}, {}",
                s.video,
                s.frames,
                s.detections,
                s.detections_geolocated,
                s.tracks,
                s.merges.len(),
                s.mot_results.display(),
                s.geo_tracks.display()
            )?;
        }
    }
    Ok(())
}

/// Checks that a video's name can name its output files: `DIR/<video>.txt` and
/// `DIR/<video>_tracks.csv` must stay inside `--out`.
///
/// The name comes from the input (`videos[].name`, `source.folder_name` or the stem of
/// `source.video`) and must be a single plain path component: not empty, not `.` or `..`, no
/// `/` (so not absolute either). Other names are refused, with an error naming the video and
/// the field it came from, rather than sanitised: a rewritten name could collide with another
/// video's and silently overwrite its results, and the user would not find the files under the
/// name their data gives.
fn check_output_name(ds: &Dataset, seq: &Sequence) -> anyhow::Result<()> {
    let name = seq.name.as_str();
    let mut components = Path::new(name).components();
    let single = matches!(
        (components.next(), components.next()),
        (Some(Component::Normal(c)), None) if c == name
    );
    if single && !name.contains('/') {
        return Ok(());
    }
    let field = seq
        .frames
        .first()
        .map(|f| {
            let i = f.image_index;
            let im = &ds.images[i];
            let video = im.video_id.and_then(|vid| {
                ds.videos
                    .as_ref()
                    .and_then(|vs| vs.iter().position(|v| v.id == vid))
            });
            let source = im.source.as_ref();
            match video {
                Some(k) => format!("videos[{k}].name"),
                None if source.is_some_and(|s| s.folder_name.is_some()) => {
                    format!("images[{i}].source.folder_name")
                }
                None => format!("images[{i}].source.video"),
            }
        })
        .unwrap_or_else(|| "the video name".to_owned());
    bail!(
        "video {name:?} (from {field}): its name cannot name an output file inside --out; \
         it must be a plain file name, not empty, `.` or `..`, without `/`"
    )
}

/// Detections grouped by image id.
fn load_detections(
    args: &Args,
    ds: &Dataset,
    sequences: &[Sequence],
) -> anyhow::Result<HashMap<u64, Dets>> {
    let mut by_image: HashMap<u64, Dets> = HashMap::new();
    let is_txt = args
        .detections
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("txt"));
    if is_txt {
        let [seq] = sequences else {
            bail!(
                "{}: a MOT detection file covers one video, but {} has {}; choose one with --video",
                args.detections.display(),
                args.annotations.display(),
                sequences.len()
            );
        };
        let rows = mot::read_detections(&args.detections)?;
        for r in rows {
            let Some(frame) = usize::try_from(r.frame)
                .ok()
                .and_then(|f| f.checked_sub(1))
                .and_then(|i| seq.frames.get(i))
            else {
                bail!(
                    "{}: frame {} is outside video {} (1..={})",
                    args.detections.display(),
                    r.frame,
                    seq.name,
                    seq.frames.len()
                );
            };
            let class_id = u32::try_from(r.class).unwrap_or(0);
            by_image.entry(frame.image_id).or_default().push((
                class_id,
                [r.bbox.x, r.bbox.y, r.bbox.w, r.bbox.h],
                r.conf,
                r.appearance,
            ));
        }
    } else {
        let known: std::collections::HashSet<u64> = ds.images.iter().map(|i| i.id).collect();
        let mut unknown = 0usize;
        for d in coco::read_detections(&args.detections)? {
            if !known.contains(&d.image_id) {
                unknown += 1;
                continue;
            }
            by_image.entry(d.image_id).or_default().push((
                d.category_id,
                d.bbox,
                d.score,
                d.signature(),
            ));
        }
        if unknown > 0 {
            tracing::warn!(
                unknown,
                "detections for images not in the annotations file were ignored"
            );
        }
    }
    Ok(by_image)
}

fn track_video(
    args: &Args,
    params: &TrackerParams,
    ds: &Dataset,
    seq: &Sequence,
    dets_by_image: &HashMap<u64, Dets>,
    progress: &ProgressBar,
) -> anyhow::Result<VideoSummary> {
    let Some(first) = seq.frames.first() else {
        bail!("video {} has no frames", seq.name);
    };
    let first_image = &ds.images[first.image_index];
    let camera = CameraModel::from_hfov(first_image.width, first_image.height, args.fov_deg)
        .with_context(|| format!("video {}: camera model", seq.name))?;
    if let Some(image) = seq
        .frames
        .iter()
        .map(|f| &ds.images[f.image_index])
        .find(|im| (im.width, im.height) != (first_image.width, first_image.height))
    {
        bail!(
            "video {}: image {} is {}x{}, unlike the video's first frame",
            seq.name,
            image.id,
            image.width,
            image.height
        );
    }
    let metas = if args.no_metadata {
        vec![None; seq.frames.len()]
    } else {
        ds.frame_metadata(seq, args.metadata_lag_s)
            .with_context(|| format!("video {}: metadata", seq.name))?
    };
    let reference = metas.iter().flatten().next().map(|m| m.nadir_on_water());
    let geolocator = reference.map(|r| Geolocator::new(r, camera, PoseNoise::default()));

    // Build the tracker's input: boxes, world observations and metadata motion compensation.
    let mut inputs = Vec::with_capacity(seq.frames.len());
    let mut geolocated = 0usize;
    let mut n_dets = 0usize;
    // Consecutive entries of the video (its frames as annotated) are consecutive for the
    // motion compensation, whatever their frame numbers.
    let mut motion = CameraMotion::new(params.baseline.cmc_smoothing);
    for (position, (f, meta)) in (0u64..).zip(seq.frames.iter().zip(&metas)) {
        let image = &ds.images[f.image_index];
        let geometry = match (&geolocator, meta) {
            (Some(g), Some(m)) => g.frame(m).ok(),
            _ => None,
        };
        let detections = dets_by_image.get(&f.image_id).into_iter().flatten().map(
            |(class_id, b, score, appearance)| Detection {
                bbox: BBox::new(b[0], b[1], b[2], b[3]),
                score: *score as f32,
                class_id: *class_id,
                world: None,
                appearance: *appearance,
            },
        );
        let image_motion = geolocator
            .as_ref()
            .and_then(|g| motion.image_motion(g, position, f.time_s, meta.as_ref()));
        motion.taken(position);
        let input = tracker_input(
            f.video_frame,
            f.time_s,
            (image.width, image.height),
            detections,
            geometry.as_ref(),
            image_motion,
        );
        n_dets += input.detections.len();
        geolocated += input
            .detections
            .iter()
            .filter(|d| d.world.is_some())
            .count();
        inputs.push(input);
    }

    let tracked = track_frames(
        &inputs,
        args.mode,
        params,
        args.results.withhold_provisional,
        progress,
    )?;
    let frames: Vec<FrameTime> = seq
        .frames
        .iter()
        .map(|f| FrameTime {
            frame_number: f.frame_number,
            time_s: f.time_s,
        })
        .collect();
    let written = write_results(
        &args.results.out,
        &seq.name,
        &frames,
        &tracked,
        geolocator.as_ref().map(|g| g.reference()),
        args.results.class_column,
        args.results.geo_format,
    )?;
    Ok(VideoSummary {
        video: seq.name.clone(),
        frames: inputs.len(),
        detections: n_dets,
        detections_geolocated: geolocated,
        tracks: written.tracks,
        track_boxes: written.track_boxes,
        mot_results: written.mot_results,
        geo_tracks: written.geo_tracks,
        merges: tracked.merges,
    })
}
