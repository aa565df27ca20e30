//! `mgmot oracle`: detections labelled with their true ids (`mgmot::eval::oracle`), the
//! identity ceiling that `scripts/bench_tracking.sh` prints beside every tracker run.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::PathBuf;

use anyhow::Context;
use mgmot::eval::oracle::label_detections;
use mgmot::eval::BoxXywh;
use mgmot::formats::coco;
use mgmot::formats::mot::{self, MotRecord};

/// Arguments of `mgmot oracle`.
#[derive(Debug, clap::Args)]
#[command(after_long_help = "\
Every detection that overlaps a considered ground-truth box with IoU >= --min-iou
(one optimal assignment per frame) is written with that object's id; the other
detections are dropped. `mgmot eval --gt GT --pred OUT` then scores what a
tracker that never confuses identities would score with these detections: the
ceiling for identity metrics (IDF1, AssA) that the detector leaves.")]
pub struct Args {
    /// Ground truth, a MOTChallenge txt file (`gt/gt.txt`).
    #[arg(long, value_name = "GT.txt")]
    gt: PathBuf,
    /// Detections: a MOTChallenge detection file (`frame,-1,x,y,w,h,score[,class]`, as
    /// `mgmot-sim detections -o FILE.txt` writes) or COCO results `.json` (as `mgmot detect`
    /// writes), whose `image_id` is taken as the MOTChallenge frame number (true of the
    /// simulator's and SeaDronesSee-style annotations: frame index + 1).
    #[arg(long, value_name = "DET.txt|DET.json")]
    detections: PathBuf,
    /// Smallest IoU for a detection to count as the object's.
    #[arg(long, default_value_t = 0.5, value_parser = parse_iou)]
    min_iou: f64,
    /// Output MOTChallenge results file.
    #[arg(long, value_name = "OUT.txt")]
    out: PathBuf,
}

/// Detections from a MOTChallenge or COCO results file, as MOTChallenge records.
fn read_detections(path: &std::path::Path) -> anyhow::Result<Vec<MotRecord>> {
    if path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("json"))
    {
        return Ok(coco::read_detections(path)?
            .into_iter()
            .map(|d| MotRecord {
                frame: d.image_id,
                id: -1,
                bbox: BoxXywh {
                    x: d.bbox[0],
                    y: d.bbox[1],
                    w: d.bbox[2],
                    h: d.bbox[3],
                },
                conf: d.score,
                class: i64::from(d.category_id),
                visibility: None,
                appearance: None,
            })
            .collect());
    }
    Ok(mot::read_detections(path)?)
}

fn parse_iou(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) if v > 0.0 && v <= 1.0 => Ok(v),
        _ => Err(format!("expected a number in (0, 1], got {s:?}")),
    }
}

/// Runs `mgmot oracle`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let gt: Vec<_> = mot::read_file(&args.gt)?
        .iter()
        .map(MotRecord::to_gt_annotation)
        .collect();
    let dets = read_detections(&args.detections)?;
    let det_ann: Vec<_> = dets.iter().map(MotRecord::to_pred_annotation).collect();
    let records: Vec<MotRecord> = label_detections(&gt, &det_ann, args.min_iou)
        .into_iter()
        .map(|(k, id)| MotRecord { id, ..dets[k] })
        .collect();
    let file =
        File::create(&args.out).with_context(|| format!("cannot create {}", args.out.display()))?;
    let mut out = BufWriter::new(file);
    mot::write(&mut out, &records)?;
    out.flush()
        .with_context(|| format!("cannot write {}", args.out.display()))?;
    tracing::info!(
        detections = dets.len(),
        labelled = records.len(),
        "oracle written"
    );
    Ok(())
}
