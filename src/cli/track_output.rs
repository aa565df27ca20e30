//! What `mgmot track` and `mgmot replay` share: running the tracker over a sequence of
//! inputs (online, frame by frame as in the air, or offline with the paper's
//! post-processing) and writing the results: MOTChallenge rows and geolocated tracks.

use anyhow::Context;
use clap::ValueEnum;
use indicatif::ProgressBar;
use mgmot::eval::BoxXywh;
use mgmot::formats::geopoints::{write_geo_rows, GeoRow};
use mgmot::formats::mot;
use mgmot::frame::geo_fix;
use mgmot::geo::LocalTangentFrame;
use mgmot::track::{
    track_sequence, BBox, FrameInput, MergeEvent, SequenceTrack, Tracker, TrackerParams,
};
use serde::Serialize;
use std::io::Write;
use std::path::{Path, PathBuf};

/// Tracking mode.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum, Serialize)]
#[serde(rename_all = "lowercase")]
pub(super) enum Mode {
    /// Frame by frame as in the air.
    Online,
    /// The paper's post-processing over the whole sequence.
    Offline,
}

/// Geo track file format.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub(super) enum GeoOut {
    /// CSV.
    Csv,
    /// GeoJSON.
    Geojson,
}

/// The flags of the results, shared by `mgmot track` and `mgmot replay`.
#[derive(Debug, clap::Args)]
pub(super) struct ResultArgs {
    /// Write each track's class id in column 8 of the MOTChallenge results (for
    /// `mgmot eval --per-class`). Off by default: column 8 is then -1, the MOTChallenge results
    /// convention that TrackEval's MOT loader requires.
    #[arg(long)]
    pub class_column: bool,
    /// Geo track file format.
    #[arg(long, value_enum, default_value_t = GeoOut::Csv)]
    pub geo_format: GeoOut,
    /// Output directory (created if missing).
    #[arg(long)]
    pub out: PathBuf,
    /// Print the summary as JSON on stdout.
    #[arg(long)]
    pub json: bool,
    /// Online mode: leave provisional tracks out of the results (a new track whose ReID
    /// decision is pending while an ended track of its class is within the ReID gate), as
    /// an operator display that hides them shows the flight. Default: every confirmed track,
    /// the paper's convention.
    #[arg(long)]
    pub withhold_provisional: bool,
}

/// Every reported track box of a sequence, with the position of its frame in the sequence,
/// and the merges the online tracker decided.
pub(super) struct Tracked {
    pub boxes: Vec<(usize, SequenceTrack)>,
    pub merges: Vec<MergeEvent>,
}

/// Runs the tracker over `inputs` in `mode`.
pub(super) fn track_frames(
    inputs: &[FrameInput],
    mode: Mode,
    params: &TrackerParams,
    withhold_provisional: bool,
    progress: &ProgressBar,
) -> anyhow::Result<Tracked> {
    let mut boxes: Vec<(usize, SequenceTrack)> = Vec::new();
    let mut merges = Vec::new();
    match mode {
        Mode::Online => {
            let mut tracker = Tracker::new(params.clone())?;
            for (pos, input) in inputs.iter().enumerate() {
                let out = tracker.step(input)?;
                let shown = out
                    .tracks
                    .iter()
                    .filter(|t| !(withhold_provisional && t.provisional));
                boxes.extend(shown.map(|t| {
                    let st = SequenceTrack {
                        id: t.id,
                        bbox: t.bbox,
                        score: t.score,
                        class_id: t.class_id,
                        world: t.world,
                        interpolated: false,
                    };
                    (pos, st)
                }));
                merges.extend(out.merges);
                progress.inc(1);
            }
            merges.extend(tracker.finish());
        }
        Mode::Offline => {
            let result = track_sequence(inputs, params)?;
            for (pos, frame) in result.frames.iter().enumerate() {
                boxes.extend(frame.tracks.iter().map(|t| (pos, *t)));
            }
            progress.inc(inputs.len() as u64);
        }
    }
    Ok(Tracked { boxes, merges })
}

/// A frame's number in the results (1-based for MOTChallenge) and its time (s).
pub(super) struct FrameTime {
    pub frame_number: u64,
    pub time_s: f64,
}

/// One track in one frame, geolocated.
#[derive(Debug, Serialize)]
struct TrackRow {
    frame: u64,
    time_s: f64,
    track_id: u64,
    class_id: u32,
    score: f32,
    lat_deg: f64,
    lon_deg: f64,
    north_m: f64,
    east_m: f64,
    vel_north_mps: f64,
    vel_east_mps: f64,
    h_std_m: f64,
    interpolated: bool,
}

impl GeoRow for TrackRow {
    fn lat_deg(&self) -> f64 {
        self.lat_deg
    }
    fn lon_deg(&self) -> f64 {
        self.lon_deg
    }
}

/// What [`write_results`] wrote.
pub(super) struct Written {
    pub mot_results: PathBuf,
    pub geo_tracks: PathBuf,
    /// Distinct track ids.
    pub tracks: usize,
    /// Track boxes (MOTChallenge rows).
    pub track_boxes: usize,
}

/// Writes `OUT/<name>.txt` (MOTChallenge results: frame,id,x,y,w,h,conf,class,-1) and
/// `OUT/<name>_tracks.csv` (or .geojson: one row per geolocated track per frame).
/// `frames[pos]` numbers and times the sequence's frames; `reference` is the local frame the
/// tracks' world positions are in.
pub(super) fn write_results(
    out: &Path,
    name: &str,
    frames: &[FrameTime],
    tracked: &Tracked,
    reference: Option<&LocalTangentFrame>,
    class_column: bool,
    geo_format: GeoOut,
) -> anyhow::Result<Written> {
    let mut mot_rows = Vec::with_capacity(tracked.boxes.len());
    let mut geo_rows = Vec::with_capacity(tracked.boxes.len());
    for (pos, t) in &tracked.boxes {
        let Some(f) = frames.get(*pos) else {
            continue;
        };
        mot_rows.push(mot_result(
            f.frame_number,
            t.id,
            &t.bbox,
            t.score,
            class_column.then_some(t.class_id),
        ));
        if let (Some(world), Some(reference)) = (&t.world, reference) {
            let fix = geo_fix(reference, world, None);
            geo_rows.push(TrackRow {
                frame: f.frame_number,
                time_s: f.time_s,
                track_id: t.id,
                class_id: t.class_id,
                score: t.score,
                lat_deg: fix.position.lat_deg,
                lon_deg: fix.position.lon_deg,
                north_m: world.pos_ne_m.x,
                east_m: world.pos_ne_m.y,
                vel_north_mps: fix.vel_n_mps,
                vel_east_mps: fix.vel_e_mps,
                h_std_m: fix.h_std_m,
                interpolated: t.interpolated,
            });
        }
    }
    let mot_path = out.join(format!("{name}.txt"));
    let file = std::fs::File::create(&mot_path)
        .with_context(|| format!("creating {}", mot_path.display()))?;
    let mut writer = std::io::BufWriter::new(file);
    mot::write(&mut writer, &mot_rows)
        .and_then(|()| writer.flush())
        .with_context(|| format!("writing {}", mot_path.display()))?;
    let ext = match geo_format {
        GeoOut::Csv => "csv",
        GeoOut::Geojson => "geojson",
    };
    let geo_path = out.join(format!("{name}_tracks.{ext}"));
    write_geo_rows(&geo_path, &geo_rows)?;
    let mut ids: Vec<i64> = mot_rows.iter().map(|r| r.id).collect();
    ids.sort_unstable();
    ids.dedup();
    Ok(Written {
        mot_results: mot_path,
        geo_tracks: geo_path,
        tracks: ids.len(),
        track_boxes: mot_rows.len(),
    })
}

/// A MOTChallenge results row: `frame,id,x,y,w,h,conf,class,-1` (class -1 when `class_id` is
/// `None`).
fn mot_result(frame: u64, id: u64, b: &BBox, score: f32, class_id: Option<u32>) -> mot::MotRecord {
    mot::MotRecord {
        frame,
        id: i64::try_from(id).unwrap_or(i64::MAX),
        bbox: BoxXywh {
            x: b.x,
            y: b.y,
            w: b.w,
            h: b.h,
        },
        conf: f64::from(score),
        class: class_id.map_or(-1, i64::from),
        visibility: None,
        appearance: None,
    }
}
