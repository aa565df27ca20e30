//! `mgmot-sim detections`: simulated detector output plus the ground truth.

use super::render::{progress, TruthWriter};
use super::ScenarioArgs;
use anyhow::Context;
use mgmot_sim::detections::{detect, mot_det_lines, with_appearance, Detection};
use mgmot_sim::render::Renderer;
use mgmot_sim::truth::{frame_truth, Optics};
use std::io::Write;
use std::path::PathBuf;

/// Arguments of `detections`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    scenario: ScenarioArgs,
    /// Output file: `.json` for COCO results (`[{image_id, category_id, bbox, score}]`, image
    /// ids as in the SeaDronesSee JSON), `.txt` for MOT detections
    /// (`frame,-1,x,y,w,h,score,class,-1,-1`).
    #[arg(long, short = 'o')]
    out: PathBuf,
    /// Folder for the ground truth (gt/gt.txt, world.csv, camera.csv, annotations.json);
    /// default: beside the output file, `<stem>_gt/`.
    #[arg(long)]
    gt_dir: Option<PathBuf>,
    /// Add each box's colour signature (an eleventh column of a MOT file, a field
    /// `appearance` of a COCO entry, in hex): the box is rendered as `mgmot-sim render`
    /// would draw the frame there and the signature computed as `mgmot` does from real
    /// pixels (`reid.appearance_gate`).
    #[arg(long)]
    appearance: bool,
}

/// Writes the detections and the ground truth.
pub fn run(args: Args) -> anyhow::Result<()> {
    let ext = args
        .out
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    let coco = match ext.as_deref() {
        Some("json") => true,
        Some("txt") => false,
        _ => anyhow::bail!(
            "{}: output must end in .json (COCO results) or .txt (MOT detections)",
            args.out.display()
        ),
    };
    let world = args.scenario.world()?;
    let renderer = args
        .appearance
        .then(|| Renderer::new(&world.scenario, world.seed));
    let optics = Optics::new(&world.scenario).context("camera or origin invalid")?;
    let gt_dir = args.gt_dir.clone().unwrap_or_else(|| {
        let stem = args
            .out
            .file_stem()
            .and_then(|s| s.to_str())
            .unwrap_or("detections");
        args.out.with_file_name(format!("{stem}_gt"))
    });
    let mut truth = TruthWriter::create(&gt_dir, &world)?;
    let n = world.scenario.frame_count();
    let pb = progress(n);
    let mut all: Vec<Detection> = Vec::new();
    let mut txt = String::new();
    for index in 0..n {
        let ft = frame_truth(&world, &optics, index);
        let mut dets = detect(&world, &optics, &ft);
        if let Some(renderer) = &renderer {
            with_appearance(renderer, &world, &optics, &ft, &mut dets);
        }
        if coco {
            all.extend_from_slice(&dets);
        } else {
            txt.push_str(&mot_det_lines(index, &dets));
        }
        truth.add(&world, &optics, &ft, &format!("img1/{:06}.jpg", index + 1))?;
        pb.inc(1);
    }
    pb.finish_and_clear();
    if let Some(parent) = args.out.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent)
            .with_context(|| format!("cannot create {}", parent.display()))?;
    }
    let mut f = std::io::BufWriter::new(
        std::fs::File::create(&args.out)
            .with_context(|| format!("cannot create {}", args.out.display()))?,
    );
    if coco {
        serde_json::to_writer(&mut f, &all)?;
    } else {
        f.write_all(txt.as_bytes())?;
    }
    f.flush()?;
    truth.finish(&world, "jpg")?;
    tracing::info!(out = %args.out.display(), gt = %gt_dir.display(), "detections written");
    Ok(())
}
