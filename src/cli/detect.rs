//! `mgmot detect`: run the detector over an image or a folder of images.
//!
//! Writes COCO results JSON (`[{image_id, category_id, bbox, score}]`, with
//! `category_id` SeaDronesSee's id of the class's name: 1 swimmer, 2 boat, 3 jetski,
//! 4 life-saving appliance, 5 buoy, whatever order the model lists them in; see
//! `detect::model::category_ids_for`) to stdout with `--json` and to
//! `OUT/detections.json` with `--out`, where it also draws the boxes on a copy
//! of each image. Each entry also carries `appearance`, the box's colour signature in hex
//! (`mgmot::track::Appearance`), when the box shows enough of the object; `mgmot track`
//! reads it for the appearance gate of its long-gap ReID.

use std::io::Write;
use std::path::{Path, PathBuf};

use super::args::Finite;
use super::stdout::Stdout;
use anyhow::{bail, Context};
use clap::Args as ClapArgs;
use image::{Rgb, RgbImage};
use imageproc::drawing::draw_hollow_rect_mut;
use imageproc::rect::Rect;
use mgmot::detect::{
    BackendConfig, BackendKind, Detection, Detector, DetectorConfig, TilingConfig,
};
use serde::Serialize;

/// Image file extensions picked up from a folder.
const IMAGE_EXTENSIONS: [&str; 4] = ["png", "jpg", "jpeg", "bmp"];

/// Box colours per class id (cycled): swimmer yellow, boat red, then others.
const COLOURS: [[u8; 3]; 6] = [
    [255, 220, 0],
    [255, 40, 40],
    [0, 200, 255],
    [80, 255, 80],
    [255, 0, 255],
    [255, 255, 255],
];

/// Arguments of `mgmot detect`.
#[derive(Debug, ClapArgs)]
pub struct Args {
    /// The ONNX detector: models/mgmot-det-fp32.onnx (fastest on tract),
    /// models/mgmot-det-int8.onnx (fastest on onnxruntime), or a YOLOv8 / YOLO11 export.
    #[arg(long)]
    model: PathBuf,
    /// An image file or a folder of images (png, jpg, bmp).
    input: PathBuf,
    /// Inference engine: tract (pure Rust) or onnxruntime (needs --ort-lib or ORT_DYLIB_PATH).
    /// Default: onnxruntime (the faster, see models/README.md) when --ort-lib or
    /// ORT_DYLIB_PATH names an existing file, else tract (needs nothing installed).
    #[arg(long, value_parser = parse_backend)]
    backend: Option<BackendKind>,
    /// Path of libonnxruntime.so for --backend onnxruntime (default: $ORT_DYLIB_PATH).
    #[arg(long)]
    ort_lib: Option<PathBuf>,
    /// Print COCO results JSON on stdout instead of a summary.
    #[arg(long)]
    json: bool,
    /// Folder for detections.json and the images with their boxes drawn.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Minimum class score, in [0, 1].
    #[arg(long, default_value_t = 0.25, value_parser = Finite::non_negative(1.0).f32())]
    score: f32,
    /// IoU threshold of the class-aware NMS, in [0, 1].
    #[arg(long, default_value_t = mgmot::detect::DEFAULT_NMS_IOU, value_parser = Finite::non_negative(1.0).f32())]
    nms_iou: f32,
    /// IoU threshold of the larger-box-priority suppression, in [0, 1] (1 turns it off).
    #[arg(long, default_value_t = 0.7, value_parser = Finite::non_negative(1.0).f32())]
    larger_box_iou: f32,
    /// Split large frames into overlapping tiles at native resolution.
    #[arg(long)]
    tile: bool,
    /// Side of square tiles in pixels, 1 to 16384, the largest image side decoders handle
    /// here (default: tiles of the model's input size, width x height).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=16384))]
    tile_size: Option<u32>,
    /// Overlap between tiles in pixels, at most 16384 (capped below the tile size).
    #[arg(long, default_value_t = 64, value_parser = clap::value_parser!(u32).range(0..=16384))]
    tile_overlap: u32,
    /// Inference threads, 1 to 256 (more threads than cores only adds contention).
    #[arg(long, default_value_t = 2, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..=256))]
    threads: usize,
    /// Comma-separated class names overriding the model's metadata.
    #[arg(long, value_delimiter = ',')]
    classes: Option<Vec<String>>,
}

fn parse_backend(s: &str) -> Result<BackendKind, String> {
    s.parse()
}

/// One entry of COCO's results format.
#[derive(Debug, Serialize)]
struct CocoResult {
    image_id: u64,
    category_id: usize,
    category_name: String,
    bbox: [f32; 4],
    score: f32,
    file_name: String,
    /// The box's colour signature in hex (`reid.appearance_gate`), when it shows enough.
    #[serde(skip_serializing_if = "Option::is_none")]
    appearance: Option<String>,
}

/// Runs `mgmot detect`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let images = list_images(&args.input)?;
    let mut config = DetectorConfig::new(&args.model);
    config.backend = BackendConfig {
        kind: args.backend.unwrap_or(BackendKind::Tract),
        ort_dylib_path: args.ort_lib.clone(),
    };
    if args.backend.is_none() {
        let library = config.backend.resolved_ort_dylib_path();
        if library.as_deref().is_some_and(Path::is_file) {
            config.backend.kind = BackendKind::OnnxRuntime;
        }
        tracing::info!(backend = %config.backend.kind, library = ?library, "no --backend given");
    }
    config.threads = args.threads;
    config.score_threshold = args.score;
    config.nms_iou = args.nms_iou;
    config.larger_box_iou = (args.larger_box_iou < 1.0).then_some(args.larger_box_iou);
    config.class_names = args.classes.clone();
    config.tiling = args.tile.then_some(TilingConfig {
        tile_px: args.tile_size,
        overlap_px: args.tile_overlap,
        include_full_frame: true,
        frame_budget_us: None,
    });
    let mut detector = Detector::load(config)?;
    let names = detector.model().class_names.clone();
    let categories = detector.model().category_ids.clone();
    let mut stdout = Stdout::lock();
    if !args.json {
        writeln!(
            stdout,
            "{}: backend {}, input {}x{}, classes {}",
            args.model.display(),
            detector.backend(),
            detector.model().input_width_px,
            detector.model().input_height_px,
            names.join(",")
        )?;
    }
    if let Some(out) = &args.out {
        std::fs::create_dir_all(out)
            .with_context(|| format!("cannot create output folder {}", out.display()))?;
    }

    let mut results = Vec::new();
    for (index, path) in images.iter().enumerate() {
        let frame = image::open(path)
            .with_context(|| format!("cannot read image {}", path.display()))?
            .to_rgb8();
        let (dets, t) = detector
            .detect_timed(&frame)
            .with_context(|| format!("detection failed on {}", path.display()))?;
        tracing::info!(image = %path.display(), detections = dets.len(), pre_ms = t.preprocess.as_secs_f64() * 1e3, infer_ms = t.inference.as_secs_f64() * 1e3, post_ms = t.postprocess.as_secs_f64() * 1e3, "frame done");
        let image_id = image_id(path, index);
        let file_name = path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        if !args.json {
            writeln!(stdout, "{}: {} detections", path.display(), dets.len())?;
            for d in &dets {
                writeln!(
                    stdout,
                    "  {:<10} {:.3}  x={:.1} y={:.1} w={:.1} h={:.1}",
                    class_name(&names, d.class_id),
                    d.score,
                    d.bbox.x_px,
                    d.bbox.y_px,
                    d.bbox.w_px,
                    d.bbox.h_px
                )?;
            }
        }
        results.extend(dets.iter().map(|d| CocoResult {
            image_id,
            category_id: categories.get(d.class_id).map_or(0, |&c| c as usize),
            category_name: class_name(&names, d.class_id).to_string(),
            bbox: [d.bbox.x_px, d.bbox.y_px, d.bbox.w_px, d.bbox.h_px],
            score: d.score,
            file_name: file_name.clone(),
            appearance: d.appearance(&frame).map(|a| a.to_hex()),
        }));
        if let Some(out) = &args.out {
            let drawn = draw(frame, &dets);
            let target = out.join(format!(
                "{}.png",
                path.file_stem()
                    .map(|s| s.to_string_lossy())
                    .unwrap_or_default()
            ));
            drawn
                .save(&target)
                .with_context(|| format!("cannot write {}", target.display()))?;
        }
    }
    let json = serde_json::to_string_pretty(&results)?;
    if args.json {
        writeln!(stdout, "{json}")?;
    }
    if let Some(out) = &args.out {
        let target = out.join("detections.json");
        std::fs::write(&target, json)
            .with_context(|| format!("cannot write {}", target.display()))?;
    }
    Ok(())
}

fn class_name(names: &[String], id: usize) -> &str {
    names.get(id).map(String::as_str).unwrap_or("?")
}

/// COCO image id: the file stem when it is a number (SeaDronesSee names frames
/// `3464.jpg`), else the 1-based position in the sorted input list.
fn image_id(path: &Path, index: usize) -> u64 {
    path.file_stem()
        .and_then(|s| s.to_str())
        .and_then(|s| s.parse().ok())
        .unwrap_or(index as u64 + 1)
}

fn list_images(input: &Path) -> anyhow::Result<Vec<PathBuf>> {
    if input.is_file() {
        return Ok(vec![input.to_path_buf()]);
    }
    if !input.is_dir() {
        bail!("input {}: no such file or folder", input.display());
    }
    let mut images: Vec<PathBuf> = std::fs::read_dir(input)
        .with_context(|| format!("cannot list {}", input.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        // Regular files only: a FIFO named `x.png` would block the decoder.
        .filter(|p| p.is_file())
        .filter(|p| {
            p.extension()
                .and_then(|e| e.to_str())
                .is_some_and(|e| IMAGE_EXTENSIONS.contains(&e.to_ascii_lowercase().as_str()))
        })
        .collect();
    images.sort();
    if images.is_empty() {
        bail!(
            "input folder {} holds no png/jpg/bmp images",
            input.display()
        );
    }
    Ok(images)
}

/// Draws each detection as a 2-pixel rectangle in its class colour.
fn draw(mut frame: RgbImage, dets: &[Detection]) -> RgbImage {
    for d in dets {
        let colour = Rgb(COLOURS[d.class_id % COLOURS.len()]);
        for grow in 0..2i32 {
            let x = d.bbox.x_px.round() as i32 - grow;
            let y = d.bbox.y_px.round() as i32 - grow;
            let w = (d.bbox.w_px.round() as i32 + 2 * grow).max(1) as u32;
            let h = (d.bbox.h_px.round() as i32 + 2 * grow).max(1) as u32;
            draw_hollow_rect_mut(&mut frame, Rect::at(x, y).of_size(w, h), colour);
        }
    }
    frame
}
