//! `mgmot-sim render`: an image sequence with its ground truth, in a MOTChallenge-like
//! sequence folder.

use super::ScenarioArgs;
use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};
use mgmot_sim::output::{self, SeaDronesSee};
use mgmot_sim::render::Renderer;
use mgmot_sim::truth::{frame_truth, FrameTruth, Optics};
use mgmot_sim::world::World;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// Image format of the sequence.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ImageFormat {
    /// Lossless PNG.
    Png,
    /// JPEG (quality `render.jpeg_quality` of the scenario, default 85).
    Jpg,
    /// No images: ground truth only.
    None,
}

/// Arguments of `render`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    scenario: ScenarioArgs,
    /// Output folder (created): img1/NNNNNN.png|jpg, gt/gt.txt, world.csv, camera.csv,
    /// annotations.json (SeaDronesSee style), seqinfo.ini.
    #[arg(long, short = 'o')]
    out: PathBuf,
    /// Image format.
    #[arg(long, value_enum, default_value = "png")]
    format: ImageFormat,
    /// Keep every N-th frame only (frame numbers stay those of the full sequence).
    #[arg(long, default_value_t = 1)]
    every: u64,
}

/// Writes the ground-truth files of a sequence folder as frames arrive.
pub struct TruthWriter {
    dir: PathBuf,
    gt: BufWriter<File>,
    world_csv: BufWriter<File>,
    camera_csv: BufWriter<File>,
    sds: SeaDronesSee,
    frames: u64,
}

impl TruthWriter {
    /// Creates `dir` and the truth files in it.
    pub fn create(dir: &Path, world: &World) -> anyhow::Result<TruthWriter> {
        std::fs::create_dir_all(dir.join("gt"))
            .with_context(|| format!("cannot create {}", dir.display()))?;
        let open = |p: PathBuf| -> anyhow::Result<BufWriter<File>> {
            Ok(BufWriter::new(File::create(&p).with_context(|| {
                format!("cannot create {}", p.display())
            })?))
        };
        let gt = open(dir.join("gt").join("gt.txt"))?;
        let mut world_csv = open(dir.join("world.csv"))?;
        world_csv.write_all(output::WORLD_CSV_HEADER.as_bytes())?;
        let mut camera_csv = open(dir.join("camera.csv"))?;
        camera_csv.write_all(output::CAMERA_CSV_HEADER.as_bytes())?;
        Ok(TruthWriter {
            dir: dir.to_path_buf(),
            gt,
            world_csv,
            camera_csv,
            sds: SeaDronesSee::new(world),
            frames: 0,
        })
    }

    /// Adds one frame's truth; `file_name` is the image path relative to the folder.
    pub fn add(
        &mut self,
        world: &World,
        optics: &Optics,
        ft: &FrameTruth,
        file_name: &str,
    ) -> anyhow::Result<()> {
        self.gt.write_all(output::mot_gt_lines(ft).as_bytes())?;
        self.world_csv
            .write_all(output::world_csv_lines(ft, optics).as_bytes())?;
        self.camera_csv
            .write_all(output::camera_csv_line(ft, optics).as_bytes())?;
        self.sds.add_frame(world, optics, ft, file_name);
        self.frames += 1;
        Ok(())
    }

    /// Writes the JSON and seqinfo.ini and flushes everything.
    pub fn finish(mut self, world: &World, image_ext: &str) -> anyhow::Result<()> {
        self.gt.flush()?;
        self.world_csv.flush()?;
        self.camera_csv.flush()?;
        let json = self.sds.to_json()?;
        let p = self.dir.join("annotations.json");
        std::fs::write(&p, json).with_context(|| format!("cannot write {}", p.display()))?;
        let s = &world.scenario;
        let ini = format!(
            "[Sequence]\nname={}\nimDir=img1\nframeRate={}\nseqLength={}\nimWidth={}\nimHeight={}\nimExt=.{}\n",
            s.name,
            s.camera.fps,
            s.frame_count(),
            s.camera.width_px,
            s.camera.height_px,
            image_ext
        );
        std::fs::write(self.dir.join("seqinfo.ini"), ini)?;
        tracing::info!(frames = self.frames, dir = %self.dir.display(), "ground truth written");
        Ok(())
    }
}

/// Progress bar for `n` frames (hidden when stderr is not a terminal).
pub fn progress(n: u64) -> ProgressBar {
    let pb = ProgressBar::new(n);
    if let Ok(style) =
        ProgressStyle::with_template("{bar:40} {pos}/{len} frames {per_sec} eta {eta}")
    {
        pb.set_style(style);
    }
    pb
}

/// Renders the sequence.
pub fn run(args: Args) -> anyhow::Result<()> {
    anyhow::ensure!(args.every >= 1, "--every must be at least 1");
    let world = args.scenario.world()?;
    let optics = Optics::new(&world.scenario).context("camera or origin invalid")?;
    let renderer = Renderer::new(&world.scenario, world.seed);
    let ext = match args.format {
        ImageFormat::Png => "png",
        ImageFormat::Jpg | ImageFormat::None => "jpg",
    };
    let img_dir = args.out.join("img1");
    if args.format != ImageFormat::None {
        std::fs::create_dir_all(&img_dir)
            .with_context(|| format!("cannot create {}", img_dir.display()))?;
    }
    let mut truth = TruthWriter::create(&args.out, &world)?;
    let n = world.scenario.frame_count();
    let pb = progress(n.div_ceil(args.every));
    let mut rgb = vec![0u8; renderer.frame_bytes()];
    let (w, h) = (renderer.width() as u32, renderer.height() as u32);
    let quality = world.scenario.render.jpeg_quality.clamp(1, 100);
    for index in (0..n).step_by(args.every as usize) {
        let ft = frame_truth(&world, &optics, index);
        let file_name = format!("img1/{:06}.{ext}", index + 1);
        if args.format != ImageFormat::None {
            renderer.render(&world, &optics, ft.t_s, &mut rgb, true);
            let path = args.out.join(&file_name);
            save_image(&path, &rgb, w, h, args.format, quality)?;
        }
        truth.add(&world, &optics, &ft, &file_name)?;
        pb.inc(1);
    }
    pb.finish_and_clear();
    truth.finish(&world, ext)
}

fn save_image(
    path: &Path,
    rgb: &[u8],
    w: u32,
    h: u32,
    format: ImageFormat,
    quality: u8,
) -> anyhow::Result<()> {
    let file = File::create(path).with_context(|| format!("cannot create {}", path.display()))?;
    let mut out = BufWriter::new(file);
    match format {
        ImageFormat::Png => {
            let enc = image::codecs::png::PngEncoder::new_with_quality(
                &mut out,
                image::codecs::png::CompressionType::Fast,
                image::codecs::png::FilterType::Adaptive,
            );
            image::ImageEncoder::write_image(enc, rgb, w, h, image::ExtendedColorType::Rgb8)
        }
        ImageFormat::Jpg => {
            let enc = image::codecs::jpeg::JpegEncoder::new_with_quality(&mut out, quality);
            image::ImageEncoder::write_image(enc, rgb, w, h, image::ExtendedColorType::Rgb8)
        }
        ImageFormat::None => return Ok(()),
    }
    .with_context(|| format!("cannot encode {}", path.display()))?;
    out.flush()?;
    Ok(())
}
