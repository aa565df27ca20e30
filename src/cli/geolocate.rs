//! `mgmot geolocate`: every box of a SeaDronesSee file (ground truth or detections) to the
//! sea surface.

use super::args::Finite;
use super::stdout::Stdout;
use anyhow::{bail, Context};
use clap::Args as ClapArgs;
use mgmot::formats::geopoints::{write_geo_rows, GeoFormat, GeoRow};
use mgmot::formats::{coco, seadronessee};
use mgmot::geo::{CameraModel, Geolocator, Pixel, PoseNoise};
use serde::Serialize;
use std::collections::HashMap;
use std::io::Write;
use std::path::PathBuf;

/// Largest attitude noise (deg): the position std is a first-order propagation about the
/// reported pose, which stops meaning anything long before the ray could swing past the
/// horizon; 45 deg is far beyond any gimbal's error.
const MAX_ATTITUDE_STD_DEG: f64 = 45.0;
/// Largest altitude noise (m): well above any drone's flying height (120 m in the EU's open
/// category).
const MAX_ALTITUDE_STD_M: f64 = 1000.0;
/// Largest pixel noise (px): wider than any frame.
const MAX_PIXEL_STD_PX: f64 = 10_000.0;

/// Geolocate boxes on the sea surface from the drone's per-frame metadata.
///
/// Each box's centre is intersected with the sea (paper Eq. 1-4). north_m / east_m are relative
/// to the first frame of the box's video (the point on the water below the drone).
#[derive(Debug, ClapArgs)]
pub struct Args {
    /// SeaDronesSee JSON: images with `meta` (and the annotations to geolocate).
    #[arg(long)]
    annotations: PathBuf,
    /// COCO results JSON: geolocate these detections instead of the annotations.
    #[arg(long)]
    detections: Option<PathBuf>,
    /// Horizontal field of view of the camera (deg, in (0, 180)); 70 fits SeaDronesSee's DJI
    /// footage.
    #[arg(long, default_value_t = 70.0, value_parser = Finite::between(0.0, 180.0).f64())]
    fov_deg: f64,
    /// Output file: .csv or .geojson.
    #[arg(long)]
    out: PathBuf,
    /// Attitude noise for the position std (deg, 0 to 45).
    #[arg(long, default_value_t = PoseNoise::default().attitude_std_deg,
          value_parser = Finite::non_negative(MAX_ATTITUDE_STD_DEG).f64())]
    attitude_std_deg: f64,
    /// Altitude noise for the position std (m, 0 to 1000).
    #[arg(long, default_value_t = PoseNoise::default().altitude_std_m,
          value_parser = Finite::non_negative(MAX_ALTITUDE_STD_M).f64())]
    altitude_std_m: f64,
    /// Box-centre pixel noise for the position std (px, 0 to 10000).
    #[arg(long, default_value_t = PoseNoise::default().pixel_std_px,
          value_parser = Finite::non_negative(MAX_PIXEL_STD_PX).f64())]
    pixel_std_px: f64,
    /// Print a machine-readable summary on stdout.
    #[arg(long)]
    json: bool,
}

/// One output row (the CSV header is these field names, in this order).
#[derive(Debug, Serialize)]
struct Row {
    image_id: u64,
    id: u64,
    category_id: u32,
    lat_deg: f64,
    lon_deg: f64,
    north_m: f64,
    east_m: f64,
    range_m: f64,
    h_std_m: f64,
}

impl GeoRow for Row {
    fn lat_deg(&self) -> f64 {
        self.lat_deg
    }
    fn lon_deg(&self) -> f64 {
        self.lon_deg
    }
}

/// A box that was not geolocated, and why.
#[derive(Debug, Serialize)]
struct Skipped {
    image_id: u64,
    id: u64,
    reason: String,
}

/// A box to geolocate: (image id, row id, category, bbox).
type BoxIn = (u64, u64, u32, [f64; 4]);

/// Runs the subcommand.
pub fn run(args: Args) -> anyhow::Result<()> {
    GeoFormat::from_path(&args.out)?;
    let ds = seadronessee::read_dataset(&args.annotations)?;
    let boxes: Vec<BoxIn> = match &args.detections {
        Some(path) => coco::read_detections(path)?
            .into_iter()
            .enumerate()
            .map(|(i, d)| (d.image_id, i as u64, d.category_id, d.bbox))
            .collect(),
        None => ds
            .annotations
            .iter()
            .map(|a| (a.image_id, a.id, a.category_id, a.bbox))
            .collect(),
    };
    let noise = PoseNoise {
        attitude_std_deg: args.attitude_std_deg,
        altitude_std_m: args.altitude_std_m,
        pixel_std_px: args.pixel_std_px,
        ..PoseNoise::default()
    };

    // Per image: its sequence's reference (first frame with metadata, nadir on the water).
    let mut reference_of_image = HashMap::new();
    for seq in ds.sequences(seadronessee::DEFAULT_VIDEO_FPS) {
        let reference = seq
            .frames
            .iter()
            .find_map(|f| ds.images[f.image_index].meta.as_ref())
            .map(|m| m.to_frame_metadata().map(|fm| fm.nadir_on_water()))
            .transpose()
            .with_context(|| format!("sequence {}: bad metadata", seq.name))?;
        for f in &seq.frames {
            reference_of_image.insert(f.image_id, (f.image_index, reference));
        }
    }

    let mut rows = Vec::with_capacity(boxes.len());
    let mut skipped = Vec::new();
    for (image_id, id, category_id, bbox) in boxes {
        let skip = |reason: String| Skipped {
            image_id,
            id,
            reason,
        };
        let Some(&(image_index, reference)) = reference_of_image.get(&image_id) else {
            skipped.push(skip(format!(
                "image {image_id} is not in {}",
                args.annotations.display()
            )));
            continue;
        };
        let image = &ds.images[image_index];
        let (Some(meta), Some(reference)) = (image.meta.as_ref(), reference) else {
            skipped.push(skip("image has no drone metadata".into()));
            continue;
        };
        let camera = CameraModel::from_hfov(image.width, image.height, args.fov_deg)
            .with_context(|| format!("image {image_id}: camera model"))?;
        let geolocator = Geolocator::new(reference, camera, noise);
        let located = meta.to_frame_metadata().and_then(|fm| {
            let frame = geolocator.frame(&fm)?;
            frame.locate(Pixel::new(bbox[0] + bbox[2] / 2.0, bbox[1] + bbox[3] / 2.0))
        });
        match located {
            Ok(g) => rows.push(Row {
                image_id,
                id,
                category_id,
                lat_deg: g.geodetic.lat_deg,
                lon_deg: g.geodetic.lon_deg,
                north_m: g.ned_m.x,
                east_m: g.ned_m.y,
                range_m: g.range_m,
                h_std_m: g.h_std_m(),
            }),
            Err(e) => skipped.push(skip(e.to_string())),
        }
    }
    for s in &skipped {
        tracing::info!(image_id = s.image_id, id = s.id, reason = %s.reason, "box not geolocated");
    }
    write_geo_rows(&args.out, &rows)?;
    let mut stdout = Stdout::lock();
    if args.json {
        let summary = serde_json::json!({
            "out": args.out,
            "located": rows.len(),
            "skipped": skipped,
        });
        writeln!(stdout, "{}", serde_json::to_string_pretty(&summary)?)?;
    } else {
        writeln!(
            stdout,
            "geolocated {} boxes -> {} ({} skipped{})",
            rows.len(),
            args.out.display(),
            skipped.len(),
            if skipped.is_empty() {
                ""
            } else {
                "; run with -v to see why"
            }
        )?;
    }
    if rows.is_empty() && !skipped.is_empty() {
        bail!("no box could be geolocated ({} skipped)", skipped.len());
    }
    Ok(())
}
