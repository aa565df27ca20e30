//! The detector: one ort session plus the pre- and postprocessing around it.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use image::RgbImage;
use ort::memory::Allocator;
use ort::session::builder::GraphOptimizationLevel;
use ort::session::{HasSelectedOutputs, OutputSelector, RunOptions, Session};
use ort::value::{Tensor, TensorRef, ValueType};
use serde::{Deserialize, Serialize};

use super::backend::{init_backend, BackendConfig, BackendKind};
use super::model::{detect_layout, read_metadata, ModelInfo, OutputLayout};
use super::postprocess::{class_aware_nms, decode, larger_box_priority_suppression};
use super::preprocess::{Preprocessor, Region};
use super::tiling::{keep_in_merge, tile_grid, TileGovernor, TileSwitch, TilingConfig};
use super::{DetectError, Detection};

/// Detector settings. The defaults suit the shipped model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DetectorConfig {
    /// The ONNX model file.
    pub model_path: PathBuf,
    /// Which engine runs it.
    pub backend: BackendConfig,
    /// Intra-op threads (ONNX Runtime; tract runs on one thread).
    pub threads: usize,
    /// Candidates scoring below this are dropped before NMS.
    pub score_threshold: f32,
    /// IoU above which class-aware NMS drops the lower-scoring box.
    pub nms_iou: f32,
    /// IoU above which the paper's larger-box-priority suppression drops the
    /// smaller box (class-agnostic); `None` turns it off.
    pub larger_box_iou: Option<f32>,
    /// At most this many detections per frame.
    pub max_detections: usize,
    /// Class names overriding the model's `names` metadata.
    pub class_names: Option<Vec<String>>,
    /// Overlapping tiles for large frames; `None` letterboxes the whole frame once.
    pub tiling: Option<TilingConfig>,
    /// With tiling on: the model that runs the frames that are tiled (their tiles and their
    /// whole-frame pass), loaded beside `model_path` on the same backend; it must have the
    /// same input size and classes. Frames that are not tiled (tiling off, or `tile = "auto"`
    /// over its frame budget) run `model_path`. `None`: `model_path` runs every frame.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tile_model: Option<PathBuf>,
}

/// Default IoU of the class-aware NMS. 0.3, not the usual 0.5: the shipped model puts two or
/// three boxes on a 10-20 px swimmer (the head, the head with its wake) that overlap at IoU
/// 0.4-0.6, and at 0.5 the survivors start duplicate tracks that re-identification cannot
/// merge (they live at the same time). On 30 s of rendered `calm_baseline` (whole frames,
/// int8, online tracker), 0.5 -> 0.3: IDF1 0.705 -> 0.856, ID switches 11 -> 0, HOTA 0.478 ->
/// 0.552; `gimbal_swings`: HOTA 0.499 -> 0.491, IDF1 0.772 -> 0.774, false positives 113 -> 66.
pub const DEFAULT_NMS_IOU: f32 = 0.3;

impl DetectorConfig {
    /// Defaults for a model file: tract, 2 threads, score 0.25, NMS IoU [`DEFAULT_NMS_IOU`],
    /// larger-box suppression at IoU 0.7, 300 detections, no tiling.
    pub fn new(model_path: impl Into<PathBuf>) -> Self {
        Self {
            model_path: model_path.into(),
            backend: BackendConfig::default(),
            threads: 2,
            score_threshold: 0.25,
            nms_iou: DEFAULT_NMS_IOU,
            larger_box_iou: Some(0.7),
            max_detections: 300,
            class_names: None,
            tiling: None,
            tile_model: None,
        }
    }

    fn validate(&self) -> Result<(), DetectError> {
        let unit = |name: &str, v: f32| {
            if (0.0..=1.0).contains(&v) {
                Ok(())
            } else {
                Err(DetectError::InvalidConfig(format!(
                    "{name} must be in [0, 1], got {v}"
                )))
            }
        };
        unit("score_threshold", self.score_threshold)?;
        unit("nms_iou", self.nms_iou)?;
        if let Some(v) = self.larger_box_iou {
            unit("larger_box_iou", v)?;
        }
        if self.threads == 0 {
            return Err(DetectError::InvalidConfig(
                "threads must be at least 1".into(),
            ));
        }
        if let Some(t) = &self.tiling {
            if t.tile_px == Some(0) {
                return Err(DetectError::InvalidConfig(
                    "tile size must be positive".into(),
                ));
            }
        }
        if self
            .tile_model
            .as_ref()
            .is_some_and(|m| m.as_os_str().is_empty())
        {
            return Err(DetectError::InvalidConfig(
                "tile_model must name an ONNX model file".into(),
            ));
        }
        Ok(())
    }
}

/// Where the time of one [`Detector::detect_timed`] call went.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct DetectTimings {
    /// Letterboxing (resize, pad, HWC -> CHW float).
    pub preprocess: Duration,
    /// The backend's `run`.
    pub inference: Duration,
    /// Decoding, NMS and larger-box suppression.
    pub postprocess: Duration,
}

/// A loaded detector. Not `Sync`: run it on one thread (the pipeline's
/// inference thread) or load one per thread.
#[derive(Debug)]
pub struct Detector {
    session: Session,
    info: ModelInfo,
    config: DetectorConfig,
    backend: BackendKind,
    pre: Preprocessor,
    /// Reused input buffer (3 x H x W floats).
    tensor: Vec<f32>,
    /// How each run goes after the warm-up (see [`Runner`]).
    runner: Runner,
    /// Median model run (µs), measured at load when tiling has a frame budget.
    model_run_us: Option<u64>,
    /// Whether frames of a size are tiled, when tiling has a frame budget: decided on the
    /// first frame of that size, revised in flight ([`TileGovernor`]).
    tiled_sizes: Vec<((u32, u32), TileGovernor)>,
    /// The detector of [`DetectorConfig::tile_model`], which runs the tiled frames.
    tile_detector: Option<Box<Detector>>,
}

/// How the model runs per frame.
///
/// `ort` 2.0.0-rc.14 leaks an `OrtTypeInfo` for every output it allocates itself
/// (`Value::from_session_output_ptr` never releases what `GetTypeInfo` returned): about
/// 270 bytes a run on ONNX Runtime, 64 on the tract shim, a steady growth at 30 frames/s
/// (measured with heaptrack; fixed in rc.15, which `ort-tract` 0.5 cannot use yet). So
/// neither backend lets `ort` allocate outputs once loaded: ONNX Runtime writes into a
/// preallocated output tensor, and tract runs the model through `tract-onnx` directly (the
/// shim ignores preallocated outputs). The `ort` session still loads and checks the model
/// on both, so the errors and the warm-up are the same.
enum Runner {
    /// `Session::run`: only the first (warm-up) run, which finds the output's shape.
    Plain,
    /// ONNX Runtime with run options that hand it the same output tensor every run.
    Preallocated(RunOptions<HasSelectedOutputs>),
    /// tract's optimised plan for the model's fixed input size.
    Tract(TractPlan),
}

/// tract's runnable plan.
type TractPlan = std::sync::Arc<tract_onnx::prelude::TypedSimplePlan>;

/// A loaded model's interface, as [`super::auto::ModelInterface`] reads it from a file (class
/// names as they took effect, `class_names` override included).
fn interface_of(info: &ModelInfo) -> super::auto::ModelInterface {
    super::auto::ModelInterface {
        input_name: info.input_name.clone(),
        output_name: info.output_name.clone(),
        input_size_px: Some((info.input_width_px, info.input_height_px)),
        class_names: Some(info.class_names.clone()),
    }
}

impl std::fmt::Debug for Runner {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Runner::Plain => "Plain",
            Runner::Preallocated(_) => "Preallocated",
            Runner::Tract(_) => "Tract",
        })
    }
}

impl Detector {
    /// Loads the model in `config.model_path` on `config.backend` (which
    /// becomes the process's backend, see [`super::backend`]), checks its
    /// input and output, and runs one warm-up inference.
    pub fn load(config: DetectorConfig) -> Result<Self, DetectError> {
        config.validate()?;
        let path = config.model_path.clone();
        let bytes = std::fs::read(&path).map_err(|source| DetectError::ModelRead {
            path: path.clone(),
            source,
        })?;
        let meta = read_metadata(&path, &bytes)?;
        let env = init_backend(&config.backend)?;
        let backend = config.backend.kind;
        let load_err = |message: String| DetectError::SessionLoad {
            path: path.clone(),
            backend,
            message,
        };
        let mut builder = Session::builder(env)
            .map_err(|e| load_err(e.to_string()))?
            .with_optimization_level(GraphOptimizationLevel::Level3)
            .map_err(|e| load_err(e.to_string()))?
            .with_intra_threads(config.threads)
            .map_err(|e| load_err(e.to_string()))?;
        let session = builder
            .commit_from_memory(&bytes)
            .map_err(|e| load_err(e.to_string()))?;

        let (input_name, in_w, in_h) = check_input(&path, &session, meta.image_size_hw)?;
        let output = session
            .outputs()
            .first()
            .ok_or_else(|| DetectError::UnknownOutputLayout {
                path: path.clone(),
                name: String::new(),
                problem: "the model has no outputs".into(),
            })?;
        let output_name = output.name().to_string();
        let class_names = config.class_names.clone().or(meta.class_names);
        let nc_hint = class_names.as_ref().map(Vec::len);
        // The declared output shape may be dynamic: decide the layout on a
        // warm-up run's real output, which also builds tract's plan up front.
        let mut info = ModelInfo {
            path: path.clone(),
            input_name,
            input_width_px: in_w,
            input_height_px: in_h,
            output_name,
            layout: OutputLayout::ChannelsFirst,
            num_candidates: 0,
            class_names: Vec::new(),
            category_ids: Vec::new(),
        };
        let mut detector = Detector {
            session,
            info: info.clone(),
            config,
            backend,
            pre: Preprocessor::new(),
            tensor: vec![0.0; 3 * (in_w * in_h) as usize],
            runner: Runner::Plain,
            model_run_us: None,
            tiled_sizes: Vec::new(),
            tile_detector: None,
        };
        let dims = detector.run_raw(|dims, _| dims.to_vec())?;
        detector.runner = match backend {
            BackendKind::OnnxRuntime => Runner::Preallocated(
                preallocated_output(&detector.info.output_name, &dims)
                    .map_err(|e| load_err(format!("preallocating the output {dims:?}: {e}")))?,
            ),
            BackendKind::Tract => Runner::Tract(tract_plan(&bytes, in_w, in_h).map_err(load_err)?),
        };
        // The first run the new way: the output must come back in the same shape.
        let again = detector.run_raw(|dims, _| dims.to_vec())?;
        if again != dims {
            return Err(load_err(format!(
                "the output came back as {again:?}, not {dims:?}, after the warm-up"
            )));
        }
        let (layout, nc, n) =
            detect_layout(&dims, nc_hint).map_err(|problem| DetectError::UnknownOutputLayout {
                path: path.clone(),
                name: detector.info.output_name.clone(),
                problem,
            })?;
        info.layout = layout;
        info.num_candidates = n;
        info.class_names = match class_names {
            Some(names) => names,
            None => {
                tracing::warn!(model = %path.display(), "no class names in the model metadata or config; using class0..class{}", nc.saturating_sub(1));
                (0..nc).map(|i| format!("class{i}")).collect()
            }
        };
        let (category_ids, unknown) = super::model::category_ids_for(&info.class_names);
        if !unknown.is_empty() {
            if unknown.len() == info.class_names.len() {
                tracing::warn!(model = %path.display(), classes = ?info.class_names, "no class name is a SeaDronesSee class (swimmer, boat, jetski, life_saving_appliances, buoy); class k is reported as category k + 1");
            } else {
                tracing::warn!(model = %path.display(), unknown = ?unknown, "class names that are none of SeaDronesSee's five are reported as category 0 (other object)");
            }
        }
        info.category_ids = category_ids;
        tracing::info!(model = %path.display(), %backend, input_w = in_w, input_h = in_h, classes = ?info.class_names, categories = ?info.category_ids, candidates = n, "detector loaded");
        detector.info = info;
        if detector
            .config
            .tiling
            .is_some_and(|t| t.frame_budget_us.is_some())
        {
            detector.model_run_us = Some(detector.time_model_runs()?);
        }
        detector.tile_detector = detector.load_tile_detector()?.map(Box::new);
        Ok(detector)
    }

    /// The detector of [`DetectorConfig::tile_model`] when tiling is on: the same settings,
    /// tiling every frame it is handed (this detector decides which frames are tiled), and
    /// the same input size and classes as this one. Not loaded when a frame budget rules
    /// tiling out for every frame size.
    fn load_tile_detector(&self) -> Result<Option<Detector>, DetectError> {
        let (Some(tiling), Some(tile_model)) = (self.config.tiling, &self.config.tile_model) else {
            return Ok(None);
        };
        // A tiled frame is at least two tiles (plus the whole-frame pass): when even that
        // does not fit the frame budget, no frame will be tiled and the tile model never runs.
        let fewest_runs: u64 = if tiling.include_full_frame { 3 } else { 2 };
        if let (Some(budget_us), Some(run_us)) = (tiling.frame_budget_us, self.model_run_us) {
            if run_us.saturating_mul(fewest_runs) > budget_us {
                tracing::info!(tile_model = %tile_model.display(), "detector: tile model not loaded: {fewest_runs} model runs of {:.1} ms, the fewest a tiled frame needs, are over the {:.0} ms frame budget (tile = \"auto\")", run_us as f64 / 1000.0, budget_us as f64 / 1000.0);
                return Ok(None);
            }
        }
        let config = DetectorConfig {
            model_path: tile_model.clone(),
            tiling: Some(TilingConfig {
                frame_budget_us: None,
                ..tiling
            }),
            tile_model: None,
            ..self.config.clone()
        };
        let inner = Detector::load(config)?;
        // The check `mgmot check-config` makes of the files, on the models as loaded.
        let (main, tiles) = (interface_of(&self.info), interface_of(&inner.info));
        if let Some(why) = tiles.mismatch(&main) {
            return Err(DetectError::InvalidConfig(format!(
                "tile model {} cannot run the tiles of {}: {why}",
                tile_model.display(),
                self.info.path.display()
            )));
        }
        tracing::info!(model = %self.info.path.display(), tile_model = %tile_model.display(), "detector: tiled frames run the tile model");
        Ok(Some(inner))
    }

    /// The median of [`super::auto::TIMED_RUNS`] model runs after
    /// [`super::auto::WARM_UP_RUNS`] warm-ups, in µs.
    fn time_model_runs(&mut self) -> Result<u64, DetectError> {
        use super::auto::{TIMED_RUNS, WARM_UP_RUNS};
        let mut runs = Vec::with_capacity(TIMED_RUNS);
        for k in 0..WARM_UP_RUNS + TIMED_RUNS {
            let t = Instant::now();
            self.run_raw(|_, _| ())?;
            if k >= WARM_UP_RUNS {
                runs.push(t.elapsed());
            }
        }
        let median = super::auto::median(runs);
        Ok(u64::try_from(median.as_micros()).unwrap_or(u64::MAX))
    }

    /// Whether tiling is on for `fw x fh` frames in `regions` model runs: always without a
    /// frame budget; with one (`tile = "auto"`), when the runs fit in it at the model run time
    /// measured at load, decided on the first frame of each size and logged, then revised
    /// in flight ([`Detector::revise_tiling`]).
    fn tiles_frames_of(&mut self, fw: u32, fh: u32, regions: usize, t: &TilingConfig) -> bool {
        let (Some(budget_us), Some(run_us)) = (t.frame_budget_us, self.model_run_us) else {
            return true;
        };
        if let Some((_, g)) = self.tiled_sizes.iter().find(|(s, _)| *s == (fw, fh)) {
            return g.tiles();
        }
        // Without the tile model that is configured (not loaded: ruled out at load), tiling
        // never starts in flight either.
        let may_resume = self.config.tile_model.is_none() || self.tile_detector.is_some();
        let governor = TileGovernor::new(budget_us, regions, run_us, may_resume);
        let need_us = run_us.saturating_mul(regions as u64);
        let on = governor.tiles();
        let (ms, need_ms, budget_ms) = (
            run_us as f64 / 1000.0,
            need_us as f64 / 1000.0,
            budget_us as f64 / 1000.0,
        );
        if on {
            tracing::info!(frame_w = fw, frame_h = fh, model_runs = regions, "detector: tiling {fw}x{fh} frames: {regions} model runs of {ms:.1} ms = {need_ms:.0} ms, within the {budget_ms:.0} ms frame budget (tile = \"auto\")");
        } else {
            tracing::info!(frame_w = fw, frame_h = fh, model_runs = regions, "detector: not tiling {fw}x{fh} frames: {regions} model runs of {ms:.1} ms = {need_ms:.0} ms, over the {budget_ms:.0} ms frame budget (tile = \"auto\"); whole frames only");
        }
        self.tiled_sizes.push(((fw, fh), governor));
        on
    }

    /// Under `tile = "auto"`, tells the governor of `fw x fh` frames that one took `elapsed`
    /// for `runs` model runs, and logs a change it makes.
    fn revise_tiling(&mut self, fw: u32, fh: u32, runs: usize, elapsed: Duration) {
        let Some((_, g)) = self.tiled_sizes.iter_mut().find(|(s, _)| *s == (fw, fh)) else {
            return;
        };
        let budget_ms = g.budget_us() / 1000.0;
        match g.observe(runs, elapsed.as_secs_f64() * 1e6) {
            Some(TileSwitch::Stopped { run_us, need_us }) => {
                tracing::info!(frame_w = fw, frame_h = fh, "detector: tiling of {fw}x{fh} frames stopped: in flight a model run takes {:.1} ms, so a tiled frame's runs would take {:.0} ms, over the {budget_ms:.0} ms frame budget (tile = \"auto\"); whole frames until they fit again", run_us / 1000.0, need_us / 1000.0);
            }
            Some(TileSwitch::Resumed { run_us, need_us }) => {
                tracing::info!(frame_w = fw, frame_h = fh, "detector: tiling of {fw}x{fh} frames resumed: in flight a model run takes {:.1} ms, so a tiled frame's runs take {:.0} ms, within the {budget_ms:.0} ms frame budget (tile = \"auto\")", run_us / 1000.0, need_us / 1000.0);
            }
            None => {}
        }
    }

    /// The model's interface (input size, classes, layout).
    pub fn model(&self) -> &ModelInfo {
        &self.info
    }

    /// The backend running this detector.
    pub fn backend(&self) -> BackendKind {
        self.backend
    }

    /// The settings this detector was loaded with.
    pub fn config(&self) -> &DetectorConfig {
        &self.config
    }

    /// Detects objects in one RGB frame; boxes are in the frame's pixels.
    pub fn detect(&mut self, frame: &RgbImage) -> Result<Vec<Detection>, DetectError> {
        self.detect_timed(frame).map(|(d, _)| d)
    }

    /// [`Detector::detect`] plus the time spent in each stage.
    pub fn detect_timed(
        &mut self,
        frame: &RgbImage,
    ) -> Result<(Vec<Detection>, DetectTimings), DetectError> {
        let start = Instant::now();
        let (dets, timings, runs) = self.detect_runs(frame)?;
        if runs > 0 {
            let (fw, fh) = frame.dimensions();
            self.revise_tiling(fw, fh, runs, start.elapsed());
        }
        Ok((dets, timings))
    }

    /// [`Detector::detect_timed`], and how many model runs the frame took.
    fn detect_runs(
        &mut self,
        frame: &RgbImage,
    ) -> Result<(Vec<Detection>, DetectTimings, usize), DetectError> {
        let mut timings = DetectTimings::default();
        let (fw, fh) = frame.dimensions();
        if fw == 0 || fh == 0 {
            return Ok((Vec::new(), timings, 0));
        }
        let (in_w, in_h) = (self.info.input_width_px, self.info.input_height_px);
        let mut whole_frame_scale = None;
        let regions = match self.config.tiling {
            None => vec![Region::full(fw, fh)],
            Some(t) => {
                let (tile_w, tile_h) = t.tile_px.map_or((in_w, in_h), |side| (side, side));
                let mut r = tile_grid(fw, fh, tile_w, tile_h, t.overlap_px);
                if t.include_full_frame && r.len() > 1 {
                    r.push(Region::full(fw, fh));
                    whole_frame_scale =
                        Some((in_w as f32 / fw as f32).min(in_h as f32 / fh as f32));
                }
                if r.len() > 1 && !self.tiles_frames_of(fw, fh, r.len(), &t) {
                    whole_frame_scale = None;
                    r = vec![Region::full(fw, fh)];
                }
                r
            }
        };
        let tiled = regions.len() > 1;
        let runs = regions.len();
        if tiled {
            if let Some(tiles) = self.tile_detector.as_mut() {
                let (dets, timings) = tiles.detect_timed(frame)?;
                return Ok((dets, timings, runs));
            }
        }
        let mut candidates = Vec::new();
        for region in regions {
            let first = candidates.len();
            let t0 = Instant::now();
            let lb = self.pre.letterbox(
                frame,
                region,
                self.info.input_width_px,
                self.info.input_height_px,
                &mut self.tensor,
            );
            let t1 = Instant::now();
            timings.preprocess += t1 - t0;
            let (layout, nc, n) = (
                self.info.layout,
                self.info.class_names.len(),
                self.info.num_candidates,
            );
            let threshold = self.config.score_threshold;
            let mut decode_time = Duration::ZERO;
            let shape = self.run_raw(|dims, data| {
                let td = Instant::now();
                decode(
                    data,
                    layout,
                    nc,
                    n,
                    &lb,
                    fw as f32,
                    fh as f32,
                    threshold,
                    &mut candidates,
                );
                decode_time = td.elapsed();
                dims.to_vec()
            })?;
            let expected = match layout {
                OutputLayout::ChannelsFirst => [1, (4 + nc) as i64, n as i64],
                OutputLayout::ChannelsLast => [1, n as i64, (4 + nc) as i64],
            };
            if shape != expected {
                return Err(DetectError::UnknownOutputLayout {
                    path: self.info.path.clone(),
                    name: self.info.output_name.clone(),
                    problem: format!("shape changed from {expected:?} to {shape:?} between runs"),
                });
            }
            timings.inference += t1.elapsed().saturating_sub(decode_time);
            timings.postprocess += decode_time;
            if tiled {
                let from_region = candidates.split_off(first);
                candidates.extend(from_region.into_iter().filter(|d: &Detection| {
                    keep_in_merge(&d.bbox, &region, fw, fh, whole_frame_scale)
                }));
            }
        }
        let t2 = Instant::now();
        let mut dets = class_aware_nms(candidates, self.config.nms_iou, usize::MAX);
        if let Some(iou) = self.config.larger_box_iou {
            dets = larger_box_priority_suppression(dets, iou);
        }
        dets.truncate(self.config.max_detections);
        timings.postprocess += t2.elapsed();
        Ok((dets, timings, runs))
    }

    /// Runs the session on the current input tensor and hands the first
    /// output's shape and data to `f`.
    fn run_raw<R>(&mut self, f: impl FnOnce(&[i64], &[f32]) -> R) -> Result<R, DetectError> {
        let (w, h) = (
            self.info.input_width_px as usize,
            self.info.input_height_px as usize,
        );
        let path = &self.info.path;
        let backend = self.backend;
        let err = |e: ort::Error| DetectError::Inference {
            path: path.clone(),
            backend,
            message: e.to_string(),
        };
        if let Runner::Tract(plan) = &self.runner {
            let tract_err = |e: tract_onnx::prelude::TractError| DetectError::Inference {
                path: path.clone(),
                backend,
                message: format!("{e:#}"),
            };
            let input = tract_onnx::prelude::Tensor::from_shape(&[1, 3, h, w], &self.tensor)
                .map_err(tract_err)?;
            let mut inputs = tract_onnx::prelude::TVec::new();
            inputs.push(input.into());
            let outputs = plan.run(inputs).map_err(tract_err)?;
            let out = outputs
                .first()
                .ok_or_else(|| DetectError::UnknownOutputLayout {
                    path: path.clone(),
                    name: self.info.output_name.clone(),
                    problem: "the model returned no output".into(),
                })?;
            let data = out
                .try_as_plain_ram()
                .and_then(|v| v.as_slice::<f32>())
                .map_err(|e| DetectError::UnknownOutputLayout {
                    path: path.clone(),
                    name: self.info.output_name.clone(),
                    problem: format!("not a float32 tensor ({e})"),
                })?;
            let shape: Vec<i64> = out.shape().iter().map(|&d| d as i64).collect();
            return Ok(f(&shape, data));
        }
        let input =
            TensorRef::from_array_view(([1usize, 3, h, w], &self.tensor[..])).map_err(err)?;
        let inputs = ort::inputs![self.info.input_name.as_str() => input];
        let outputs = match &self.runner {
            Runner::Preallocated(options) => self.session.run_with_options(inputs, options),
            _ => self.session.run(inputs),
        }
        .map_err(err)?;
        let value = &outputs[0];
        let (shape, data) =
            value
                .try_extract_tensor::<f32>()
                .map_err(|e| DetectError::UnknownOutputLayout {
                    path: path.clone(),
                    name: self.info.output_name.clone(),
                    problem: format!("not a float32 tensor ({e})"),
                })?;
        Ok(f(shape, data))
    }
}

/// Run options that select the output `name` only, written into a float32 tensor of `dims`
/// allocated here once.
fn preallocated_output(name: &str, dims: &[i64]) -> ort::Result<RunOptions<HasSelectedOutputs>> {
    let tensor = Tensor::<f32>::new(&Allocator::default(), dims.to_vec())?;
    Ok(RunOptions::new()?.with_outputs(
        OutputSelector::no_default()
            .with(name)
            .preallocate(name, tensor),
    ))
}

/// tract's plan for the model in `bytes` with its image input fixed at (1, 3, `h`, `w`).
pub(super) fn tract_plan(bytes: &[u8], w: u32, h: u32) -> Result<TractPlan, String> {
    use tract_onnx::prelude::*;
    let shape = [1usize, 3, h as usize, w as usize];
    tract_onnx::onnx()
        .model_for_read(&mut &bytes[..])
        .and_then(|m| m.with_input_fact(0, f32::fact(shape).into()))
        .and_then(|m| m.into_optimized())
        .and_then(|m| m.into_runnable())
        .map_err(|e| format!("tract: {e:#}"))
}

/// Checks the single image input: float32, rank 4, (1, 3, H, W); returns its
/// name and `(W, H)`, taking dynamic sizes from `imgsz` metadata.
fn check_input(
    path: &Path,
    session: &Session,
    image_size_hw: Option<(u32, u32)>,
) -> Result<(String, u32, u32), DetectError> {
    let inputs = session.inputs();
    let first = inputs.first().ok_or_else(|| DetectError::BadInput {
        path: path.to_path_buf(),
        name: String::new(),
        problem: "the model has no inputs".into(),
    })?;
    let name = first.name().to_string();
    let bad = |problem: String| DetectError::BadInput {
        path: path.to_path_buf(),
        name: name.clone(),
        problem,
    };
    if inputs.len() != 1 {
        return Err(bad(format!(
            "expected one image input, the model has {}",
            inputs.len()
        )));
    }
    let ValueType::Tensor { ty, shape, .. } = first.dtype() else {
        return Err(bad(format!("not a tensor: {:?}", first.dtype())));
    };
    if *ty != ort::value::TensorElementType::Float32 {
        return Err(bad(format!("element type is {ty:?}, expected float32")));
    }
    let dims: &[i64] = shape;
    let [b, c, h, w] = dims else {
        return Err(bad(format!(
            "rank {} (shape {dims:?}), expected rank 4 (1, 3, H, W)",
            dims.len()
        )));
    };
    if *b != 1 && *b != -1 {
        return Err(bad(format!("batch dimension is {b}, expected 1")));
    }
    if *c != 3 {
        return Err(bad(format!(
            "{c} channels (shape {dims:?}), expected 3 (RGB)"
        )));
    }
    let (h, w) = match (*h, *w) {
        (h, w) if h > 0 && w > 0 => (h as u32, w as u32),
        _ => image_size_hw.ok_or_else(|| {
            bad(format!(
                "dynamic input size {dims:?} and no `imgsz` metadata to fix it"
            ))
        })?,
    };
    if w < 32 || h < 32 || w > 8192 || h > 8192 {
        return Err(bad(format!(
            "input size {w}x{h} is outside 32..8192 pixels"
        )));
    }
    Ok((name, w, h))
}
