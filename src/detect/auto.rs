//! `backend = "auto"`: the fastest (backend, model) combination, chosen by measurement.
//!
//! tract runs the shipped int8 QDQ model at about a third of its fp32 speed, while ONNX
//! Runtime runs int8 fastest of all; which pair is fastest depends on the machine and on
//! whether ONNX Runtime is installed. [`select`] times a few model runs of every candidate
//! (each backend that is available with the main model and each alternative model) and
//! returns the fastest.
//!
//! The backend is process-global and chosen once (see [`super::backend`]), so the
//! measurement must not choose it: tract is timed through `tract-onnx` directly (the same
//! plan [`super::Detector`] runs per frame), and ONNX Runtime through its C API table,
//! loaded from the library without handing it to `ort`. Only the winner is then loaded as a
//! [`super::Detector`], which makes its backend the process's.

use std::ffi::{c_void, CStr, CString};
use std::fmt;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use serde::{Deserialize, Serialize};

use super::backend::{active_backend, load_onnxruntime_api, BackendKind};
use super::model::read_metadata;
use super::{DetectError, DetectorConfig};

/// `[detector] backend`: one engine, or `auto`, the faster by measurement.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum BackendChoice {
    /// Measure every available (backend, model) combination at start and take the fastest.
    Auto,
    /// tract only (pure Rust).
    Tract,
    /// ONNX Runtime only.
    #[serde(rename = "onnxruntime")]
    OnnxRuntime,
}

impl BackendChoice {
    /// The one backend this choice names, or `None` for `auto`.
    pub fn fixed(self) -> Option<BackendKind> {
        match self {
            BackendChoice::Auto => None,
            BackendChoice::Tract => Some(BackendKind::Tract),
            BackendChoice::OnnxRuntime => Some(BackendKind::OnnxRuntime),
        }
    }

    /// The name used in configuration.
    pub fn name(self) -> &'static str {
        match self {
            BackendChoice::Auto => "auto",
            BackendChoice::Tract => "tract",
            BackendChoice::OnnxRuntime => "onnxruntime",
        }
    }
}

impl From<BackendKind> for BackendChoice {
    fn from(kind: BackendKind) -> Self {
        match kind {
            BackendKind::Tract => BackendChoice::Tract,
            BackendKind::OnnxRuntime => BackendChoice::OnnxRuntime,
        }
    }
}

impl fmt::Display for BackendChoice {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Warm-up runs before the timed ones (the first runs allocate and fill caches).
pub const WARM_UP_RUNS: usize = 3;
/// Timed runs per candidate; the median is its time.
pub const TIMED_RUNS: usize = 5;

/// What a model file declares, read without loading it: enough to run it bare and to tell
/// whether two models are interchangeable.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ModelInterface {
    /// Name of the image input.
    pub input_name: String,
    /// Name of the (first) output.
    pub output_name: String,
    /// `(width, height)` of the input: the graph's fixed size, else the `imgsz` metadata.
    pub input_size_px: Option<(u32, u32)>,
    /// The `names` metadata, when present.
    pub class_names: Option<Vec<String>>,
}

impl ModelInterface {
    /// Reads `path`'s graph inputs and outputs and its metadata.
    pub fn read(path: &Path) -> Result<Self, DetectError> {
        let bytes = std::fs::read(path).map_err(|source| DetectError::ModelRead {
            path: path.to_path_buf(),
            source,
        })?;
        Self::from_bytes(path, &bytes)
    }

    /// [`ModelInterface::read`] of a file already in memory (`path` names it in errors).
    pub fn from_bytes(path: &Path, bytes: &[u8]) -> Result<Self, DetectError> {
        use tract_onnx::pb::tensor_shape_proto::dimension::Value as Dim;
        use tract_onnx::pb::type_proto::Value as Type;
        use tract_onnx::prelude::Framework;
        let meta = read_metadata(path, bytes)?;
        let parse_err = |message: String| DetectError::ModelParse {
            path: path.to_path_buf(),
            message,
        };
        let proto = tract_onnx::onnx()
            .proto_model_for_read(&mut &bytes[..])
            .map_err(|e| parse_err(format!("{e:#}")))?;
        let graph = proto
            .graph
            .ok_or_else(|| parse_err("the file holds no graph".into()))?;
        let initializers: Vec<&str> = graph.initializer.iter().map(|t| t.name.as_str()).collect();
        let input = graph
            .input
            .iter()
            .find(|i| !initializers.contains(&i.name.as_str()))
            .ok_or_else(|| DetectError::BadInput {
                path: path.to_path_buf(),
                name: String::new(),
                problem: "the model has no inputs".into(),
            })?;
        let output = graph
            .output
            .first()
            .ok_or_else(|| DetectError::UnknownOutputLayout {
                path: path.to_path_buf(),
                name: String::new(),
                problem: "the model has no outputs".into(),
            })?;
        let dims: Vec<Option<i64>> = match input.r#type.as_ref().and_then(|t| t.value.as_ref()) {
            Some(Type::TensorType(t)) => t
                .shape
                .as_ref()
                .map(|s| {
                    s.dim
                        .iter()
                        .map(|d| match d.value {
                            Some(Dim::DimValue(v)) if v > 0 => Some(v),
                            _ => None,
                        })
                        .collect()
                })
                .unwrap_or_default(),
            _ => Vec::new(),
        };
        let fixed = match dims.as_slice() {
            [_, _, Some(h), Some(w)] => u32::try_from(*w).ok().zip(u32::try_from(*h).ok()),
            _ => None,
        };
        Ok(Self {
            input_name: input.name.clone(),
            output_name: output.name.clone(),
            input_size_px: fixed.or(meta.image_size_hw.map(|(h, w)| (w, h))),
            class_names: meta.class_names,
        })
    }

    /// Why a model with this interface cannot stand in for `main`'s (other class names or
    /// another input size), or `None` when it can.
    pub fn mismatch(&self, main: &ModelInterface) -> Option<String> {
        let size =
            |s: Option<(u32, u32)>| s.map_or("unknown".to_owned(), |(w, h)| format!("{w}x{h}"));
        if self.input_size_px != main.input_size_px {
            return Some(format!(
                "its input is {}, the main model's {}",
                size(self.input_size_px),
                size(main.input_size_px)
            ));
        }
        if self.class_names != main.class_names {
            let names = |n: &Option<Vec<String>>| {
                n.as_ref().map_or("none".to_owned(), |n| format!("{n:?}"))
            };
            return Some(format!(
                "its class names are {}, the main model's {}",
                names(&self.class_names),
                names(&main.class_names)
            ));
        }
        None
    }
}

/// One measured (backend, model) combination.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Measurement {
    /// The engine.
    pub backend: BackendKind,
    /// The model file.
    pub model: PathBuf,
    /// Median time of one model run (µs), when the candidate ran.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub median_us: Option<u64>,
    /// Why the candidate could not be measured (it failed to load or run).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

impl fmt::Display for Measurement {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let file = self.model.file_name().map_or_else(
            || self.model.display().to_string(),
            |n| n.to_string_lossy().into_owned(),
        );
        match (self.median_us, &self.error) {
            (Some(us), _) => write!(f, "{} {file} {:.1} ms", self.backend, us as f64 / 1000.0),
            (None, Some(e)) => write!(f, "{} {file} failed ({e})", self.backend),
            (None, None) => write!(f, "{} {file} not measured", self.backend),
        }
    }
}

/// The (backend, model) combination to run, and how it was chosen.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Selection {
    /// What was asked for (`auto`, or one backend).
    pub requested: BackendChoice,
    /// The chosen engine.
    pub backend: BackendKind,
    /// The chosen model file.
    pub model: PathBuf,
    /// Every candidate's time, in the order measured; empty when there was only one
    /// candidate (nothing to choose, nothing measured).
    pub measurements: Vec<Measurement>,
    /// Why backends were left out of the candidates (ONNX Runtime not found).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub not_candidates: Vec<String>,
    /// Time spent measuring (µs): the start-up cost of the choice.
    pub measuring_us: u64,
}

impl Selection {
    /// `base` with the chosen backend and model.
    pub fn apply(&self, base: &DetectorConfig) -> DetectorConfig {
        let mut c = base.clone();
        c.model_path = self.model.clone();
        c.backend.kind = self.backend;
        c
    }
}

/// Chooses the (backend, model) combination for `base` (its model, threads and ONNX Runtime
/// library) under `requested`: the candidates are every backend `requested` allows (for
/// `auto`: tract, and ONNX Runtime when its library is found) times `base.model_path` and
/// `alternatives`. One candidate is taken as is; several are each timed ([`WARM_UP_RUNS`]
/// then [`TIMED_RUNS`] model runs on a grey frame of the model's input size) and the fastest
/// median wins. Logs one INFO line with every candidate's time and the choice.
///
/// Alternatives whose class names or input size differ from the main model's are refused
/// ([`DetectError::InvalidConfig`]); a candidate that fails to load or run is logged and
/// left out, and only when every candidate fails is the first failure returned.
pub fn select(
    base: &DetectorConfig,
    requested: BackendChoice,
    alternatives: &[PathBuf],
) -> Result<Selection, DetectError> {
    let started = Instant::now();
    let mut models = vec![base.model_path.clone()];
    for alt in alternatives {
        if !models.contains(alt) {
            models.push(alt.clone());
        }
    }
    let mut not_candidates = Vec::new();
    let mut backends = match requested.fixed() {
        Some(kind) => vec![kind],
        None => {
            let mut b = vec![BackendKind::Tract];
            match base.backend.resolved_ort_dylib_path() {
                Some(lib) if lib.is_file() => b.push(BackendKind::OnnxRuntime),
                Some(lib) => not_candidates.push(format!(
                    "onnxruntime: the ONNX Runtime library {} is not a file",
                    lib.display()
                )),
                None => not_candidates.push(format!(
                    "onnxruntime: no ONNX Runtime library (neither `ort_library` nor {} names one)",
                    super::ORT_DYLIB_ENV
                )),
            }
            b
        }
    };
    if let Some(active) = active_backend() {
        if backends.contains(&active) && backends.len() > 1 {
            backends.retain(|b| *b == active);
            not_candidates.push(format!(
                "this process already runs the {active} backend, which cannot be changed"
            ));
        }
    }
    for why in &not_candidates {
        tracing::info!("detector: not a candidate: {why}");
    }
    let candidates: Vec<(BackendKind, PathBuf)> = backends
        .iter()
        .flat_map(|b| models.iter().map(move |m| (*b, m.clone())))
        .collect();
    let chosen = |backend: BackendKind, model: PathBuf, measurements: Vec<Measurement>| Selection {
        requested,
        backend,
        model,
        measurements,
        not_candidates: not_candidates.clone(),
        measuring_us: u64::try_from(started.elapsed().as_micros()).unwrap_or(u64::MAX),
    };
    if let [(backend, model)] = candidates.as_slice() {
        return Ok(chosen(*backend, model.clone(), Vec::new()));
    }

    // Every model is read once; alternatives must stand in for the main model.
    let mut files = Vec::with_capacity(models.len());
    for model in &models {
        let bytes = std::fs::read(model).map_err(|source| DetectError::ModelRead {
            path: model.clone(),
            source,
        })?;
        let interface = ModelInterface::from_bytes(model, &bytes)?;
        files.push((bytes, interface));
    }
    let main = files[0].1.clone();
    for (model, (_, interface)) in models.iter().zip(&files).skip(1) {
        if let Some(why) = interface.mismatch(&main) {
            return Err(DetectError::InvalidConfig(format!(
                "alternative model {} cannot stand in for {}: {why}",
                model.display(),
                base.model_path.display()
            )));
        }
    }
    let (w, h) = main.input_size_px.ok_or_else(|| DetectError::BadInput {
        path: base.model_path.clone(),
        name: main.input_name.clone(),
        problem: "dynamic input size and no `imgsz` metadata to fix it".into(),
    })?;

    let ort_api = if backends.contains(&BackendKind::OnnxRuntime) {
        match base.backend.resolved_ort_dylib_path() {
            Some(lib) => Some(load_onnxruntime_api(&lib).map_err(|e| e.to_string())),
            None => Some(Err(DetectError::OrtLibraryNotConfigured.to_string())),
        }
    } else {
        None
    };
    let input = vec![114.0_f32 / 255.0; 3 * w as usize * h as usize];
    let mut measurements = Vec::with_capacity(candidates.len());
    let mut first_error = None;
    for (backend, model) in &candidates {
        let index = models.iter().position(|m| m == model).unwrap_or(0);
        let (bytes, interface) = &files[index];
        let runs = match backend {
            BackendKind::Tract => time_tract(bytes, w, h, &input),
            BackendKind::OnnxRuntime => match &ort_api {
                Some(Ok(api)) => {
                    ort_raw::time_runs(api, bytes, interface, w, h, base.threads, &input)
                }
                Some(Err(e)) => Err(e.clone()),
                None => Err("ONNX Runtime is not loaded".into()),
            },
        };
        let measurement = match runs {
            Ok(median) => Measurement {
                backend: *backend,
                model: model.clone(),
                median_us: Some(u64::try_from(median.as_micros()).unwrap_or(u64::MAX)),
                error: None,
            },
            Err(e) => {
                tracing::warn!(%backend, model = %model.display(), error = %e, "detector: candidate failed, left out");
                first_error.get_or_insert_with(|| DetectError::SessionLoad {
                    path: model.clone(),
                    backend: *backend,
                    message: e.clone(),
                });
                Measurement {
                    backend: *backend,
                    model: model.clone(),
                    median_us: None,
                    error: Some(e),
                }
            }
        };
        measurements.push(measurement);
    }
    let best = measurements
        .iter()
        .filter_map(|m| m.median_us.map(|us| (us, m)))
        .min_by_key(|(us, _)| *us)
        .map(|(_, m)| (m.backend, m.model.clone()));
    let Some((backend, model)) = best else {
        return Err(first_error.unwrap_or_else(|| {
            DetectError::InvalidConfig("no detector candidate could be measured".into())
        }));
    };
    let selection = chosen(backend, model, measurements);
    let listed: Vec<String> = selection
        .measurements
        .iter()
        .map(ToString::to_string)
        .collect();
    let winner = selection
        .measurements
        .iter()
        .find(|m| m.backend == selection.backend && m.model == selection.model)
        .map(ToString::to_string)
        .unwrap_or_default();
    tracing::info!(
        requested = %requested,
        backend = %selection.backend,
        model = %selection.model.display(),
        measuring_ms = selection.measuring_us / 1000,
        "detector: chose {winner}, the fastest of {} (median model run of {TIMED_RUNS} after {WARM_UP_RUNS} warm-ups, {w}x{h} input; measuring took {:.1} s)",
        listed.join(", "),
        selection.measuring_us as f64 / 1e6,
    );
    Ok(selection)
}

/// The median of `runs`.
pub(super) fn median(mut runs: Vec<Duration>) -> Duration {
    runs.sort();
    runs.get(runs.len() / 2).copied().unwrap_or_default()
}

/// tract's plan for `bytes` (the one [`super::Detector`] runs), timed on `input`.
fn time_tract(bytes: &[u8], w: u32, h: u32, input: &[f32]) -> Result<Duration, String> {
    use tract_onnx::prelude::{TVec, Tensor};
    let plan = super::detector::tract_plan(bytes, w, h)?;
    let tensor = Tensor::from_shape(&[1, 3, h as usize, w as usize], input)
        .map_err(|e| format!("tract: {e:#}"))?;
    let mut runs = Vec::with_capacity(TIMED_RUNS);
    for k in 0..WARM_UP_RUNS + TIMED_RUNS {
        let mut inputs = TVec::new();
        inputs.push(tensor.clone().into());
        let t = Instant::now();
        plan.run(inputs).map_err(|e| format!("tract: {e:#}"))?;
        if k >= WARM_UP_RUNS {
            runs.push(t.elapsed());
        }
    }
    Ok(median(runs))
}

/// ONNX Runtime through its C API table directly, without `ort` (whose table is set once per
/// process): a session, runs, and everything released again.
mod ort_raw {
    use super::*;
    use ort::sys::{
        GraphOptimizationLevel, ONNXTensorElementDataType, OrtAllocatorType, OrtApi, OrtEnv,
        OrtLoggingLevel, OrtMemType, OrtMemoryInfo, OrtSession, OrtSessionOptions, OrtStatusPtr,
        OrtValue,
    };

    /// An ONNX Runtime object released by its `Release*` function when dropped.
    struct Owned<T> {
        ptr: *mut T,
        release: unsafe extern "system" fn(*mut T),
    }

    impl<T> Drop for Owned<T> {
        fn drop(&mut self) {
            if !self.ptr.is_null() {
                // SAFETY: `ptr` was created by the ONNX Runtime call paired with `release` and
                // is released once, here.
                unsafe { (self.release)(self.ptr) }
            }
        }
    }

    /// `Ok` for a null status, else its message (the status is released).
    fn check(api: &OrtApi, status: OrtStatusPtr) -> Result<(), String> {
        if status.0.is_null() {
            return Ok(());
        }
        // SAFETY: a non-null status from ONNX Runtime; its message is a NUL-terminated string
        // that lives until the status is released, which happens after it is copied.
        let message = unsafe {
            let text = (api.GetErrorMessage)(status.0);
            let message = if text.is_null() {
                "unknown error".to_owned()
            } else {
                CStr::from_ptr(text).to_string_lossy().into_owned()
            };
            (api.ReleaseStatus)(status.0);
            message
        };
        Err(format!("onnxruntime: {message}"))
    }

    /// Builds a session for `bytes` as [`super::super::Detector`] does (layout-level graph
    /// optimisation, `threads` intra-op threads) and returns the median of the timed runs.
    pub(super) fn time_runs(
        api: &OrtApi,
        bytes: &[u8],
        interface: &ModelInterface,
        w: u32,
        h: u32,
        threads: usize,
        input: &[f32],
    ) -> Result<Duration, String> {
        let name = |s: &str| CString::new(s).map_err(|e| format!("name `{s}`: {e}"));
        let (input_name, output_name) =
            (name(&interface.input_name)?, name(&interface.output_name)?);
        let log_id = name("mgmot-detector-selection")?;
        let threads = i32::try_from(threads).unwrap_or(i32::MAX);
        let mut data = input.to_vec();
        let shape = [1_i64, 3, i64::from(h), i64::from(w)];
        // SAFETY: every call follows ONNX Runtime's C API contract: out-pointers are valid
        // locals, every created object is wrapped in `Owned` (released in reverse order of
        // creation, the environment last), and the input tensor borrows `data`, which
        // outlives it.
        unsafe {
            let mut env: *mut OrtEnv = std::ptr::null_mut();
            check(
                api,
                (api.CreateEnv)(
                    OrtLoggingLevel::ORT_LOGGING_LEVEL_ERROR,
                    log_id.as_ptr(),
                    &mut env,
                ),
            )?;
            let env = Owned {
                ptr: env,
                release: api.ReleaseEnv,
            };
            let mut options: *mut OrtSessionOptions = std::ptr::null_mut();
            check(api, (api.CreateSessionOptions)(&mut options))?;
            let options = Owned {
                ptr: options,
                release: api.ReleaseSessionOptions,
            };
            check(api, (api.SetIntraOpNumThreads)(options.ptr, threads))?;
            check(
                api,
                (api.SetSessionGraphOptimizationLevel)(
                    options.ptr,
                    GraphOptimizationLevel::ORT_ENABLE_LAYOUT,
                ),
            )?;
            let mut session: *mut OrtSession = std::ptr::null_mut();
            check(
                api,
                (api.CreateSessionFromArray)(
                    env.ptr,
                    bytes.as_ptr().cast::<c_void>(),
                    bytes.len(),
                    options.ptr,
                    &mut session,
                ),
            )?;
            let session = Owned {
                ptr: session,
                release: api.ReleaseSession,
            };
            let mut memory: *mut OrtMemoryInfo = std::ptr::null_mut();
            check(
                api,
                (api.CreateCpuMemoryInfo)(
                    OrtAllocatorType::OrtArenaAllocator,
                    OrtMemType::OrtMemTypeDefault,
                    &mut memory,
                ),
            )?;
            let memory = Owned {
                ptr: memory,
                release: api.ReleaseMemoryInfo,
            };
            let mut value: *mut OrtValue = std::ptr::null_mut();
            check(
                api,
                (api.CreateTensorWithDataAsOrtValue)(
                    memory.ptr,
                    data.as_mut_ptr().cast::<c_void>(),
                    std::mem::size_of_val(data.as_slice()),
                    shape.as_ptr(),
                    shape.len(),
                    ONNXTensorElementDataType::ONNX_TENSOR_ELEMENT_DATA_TYPE_FLOAT,
                    &mut value,
                ),
            )?;
            let value = Owned {
                ptr: value,
                release: api.ReleaseValue,
            };
            let input_names = [input_name.as_ptr()];
            let output_names = [output_name.as_ptr()];
            let inputs = [value.ptr.cast_const()];
            let mut runs = Vec::with_capacity(TIMED_RUNS);
            for k in 0..WARM_UP_RUNS + TIMED_RUNS {
                let mut output: *mut OrtValue = std::ptr::null_mut();
                let t = Instant::now();
                let status = (api.Run)(
                    session.ptr,
                    std::ptr::null(),
                    input_names.as_ptr(),
                    inputs.as_ptr(),
                    1,
                    output_names.as_ptr(),
                    1,
                    &mut output,
                );
                let elapsed = t.elapsed();
                drop(Owned {
                    ptr: output,
                    release: api.ReleaseValue,
                });
                check(api, status)?;
                if k >= WARM_UP_RUNS {
                    runs.push(elapsed);
                }
            }
            drop((value, memory, session, options, env));
            Ok(median(runs))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn model(name: &str) -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("models")
            .join(name)
    }

    #[test]
    fn choice_names_parse_and_name_themselves() {
        #[derive(Deserialize)]
        struct C {
            backend: BackendChoice,
        }
        for (text, choice) in [
            ("auto", BackendChoice::Auto),
            ("tract", BackendChoice::Tract),
            ("onnxruntime", BackendChoice::OnnxRuntime),
        ] {
            let c: C = toml::from_str(&format!("backend = {text:?}")).unwrap();
            assert_eq!(c.backend, choice);
            assert_eq!(choice.name(), text);
        }
        assert!(toml::from_str::<C>("backend = \"cuda\"").is_err());
        assert_eq!(BackendChoice::Auto.fixed(), None);
        assert_eq!(
            BackendChoice::from(BackendKind::OnnxRuntime).fixed(),
            Some(BackendKind::OnnxRuntime)
        );
    }

    #[test]
    fn the_shipped_models_are_interchangeable() {
        let fp32 = ModelInterface::read(&model("mgmot-det-fp32.onnx")).unwrap();
        let int8 = ModelInterface::read(&model("mgmot-det-int8.onnx")).unwrap();
        assert_eq!(fp32.input_name, "images");
        assert_eq!(fp32.output_name, "output0");
        assert_eq!(fp32.input_size_px, Some((800, 448)));
        assert_eq!(int8.mismatch(&fp32), None);
        let mut other = fp32.clone();
        other.class_names = Some(vec!["kayak".into()]);
        assert!(other.mismatch(&fp32).unwrap().contains("class names"));
        other = fp32.clone();
        other.input_size_px = Some((640, 640));
        let why = other.mismatch(&fp32).unwrap();
        assert!(why.contains("640x640") && why.contains("800x448"), "{why}");
    }

    #[test]
    fn one_candidate_is_taken_without_measuring() {
        let base = DetectorConfig::new(model("mgmot-det-fp32.onnx"));
        let s = select(&base, BackendChoice::Tract, &[]).unwrap();
        assert_eq!(
            (s.backend, s.model.clone()),
            (BackendKind::Tract, base.model_path.clone())
        );
        assert!(s.measurements.is_empty());
        assert_eq!(s.apply(&base), base);
    }

    #[test]
    fn tract_times_both_models_and_takes_the_faster() {
        let base = DetectorConfig::new(model("mgmot-det-int8.onnx"));
        let alt = model("mgmot-det-fp32.onnx");
        let s = select(&base, BackendChoice::Tract, &[alt.clone(), alt.clone()]).unwrap();
        assert_eq!(s.measurements.len(), 2, "{s:?}");
        let fastest = s
            .measurements
            .iter()
            .min_by_key(|m| m.median_us.unwrap())
            .unwrap();
        assert_eq!((s.backend, &s.model), (fastest.backend, &fastest.model));
        assert!(s.measurements.iter().all(|m| m.median_us.unwrap() > 0));
        let chosen = s.apply(&base);
        assert_eq!(chosen.model_path, s.model);
        assert_eq!(chosen.threads, base.threads);
    }

    #[test]
    fn an_alternative_with_other_classes_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let base = DetectorConfig::new(model("mgmot-det-fp32.onnx"));
        // A copy of the model whose `names` say `swimmex` for `swimmer` (same length, so the
        // protobuf stays valid), whatever the other classes.
        let mut bytes = std::fs::read(&base.model_path).unwrap();
        let at = bytes
            .windows(9)
            .position(|w| w == b"'swimmer'")
            .expect("the shipped model's names");
        bytes[at..at + 9].copy_from_slice(b"'swimmex'");
        let other = dir.path().join("other.onnx");
        std::fs::write(&other, bytes).unwrap();
        let e = select(&base, BackendChoice::Tract, std::slice::from_ref(&other))
            .unwrap_err()
            .to_string();
        assert!(e.contains("other.onnx") && e.contains("class names"), "{e}");
    }
}
