//! The two inference backends behind `ort`'s one API, chosen once per process.
//!
//! `ort` is built with its `alternative-backend` feature, so it links no
//! ONNX Runtime at all and calls whatever `OrtApi` function table it is given
//! through [`ort::set_api`]:
//!
//! - [`BackendKind::Tract`]: `ort-tract`'s table, pure Rust, nothing to install;
//! - [`BackendKind::OnnxRuntime`]: the table of an ONNX Runtime shared library
//!   loaded at run time from a configured path or `ORT_DYLIB_PATH` (the
//!   `onnxruntime` wheel on PyPI carries `libonnxruntime.so`; see
//!   `scripts/detect_fetch_onnxruntime.sh`).
//!
//! The table is process-global: the first successful [`init_backend`] decides
//! the backend for the life of the process. Asking again for the same backend
//! is a no-op; asking for the other one is [`DetectError::BackendConflict`].
//! A program that wants to compare both (the parity test, the benchmark)
//! runs one process per backend.

use std::ffi::CStr;
use std::fmt;
use std::path::{Path, PathBuf};
use std::str::FromStr;
use std::sync::{Arc, Mutex, OnceLock};

use serde::{Deserialize, Serialize};

use super::DetectError;

/// Environment variable naming the ONNX Runtime shared library (the same name
/// `ort`'s own `load-dynamic` feature reads).
pub const ORT_DYLIB_ENV: &str = "ORT_DYLIB_PATH";

/// Which engine runs the ONNX graph.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum BackendKind {
    /// tract, pure Rust, through `ort-tract`: works on a fresh machine.
    Tract,
    /// Microsoft ONNX Runtime, loaded dynamically.
    #[serde(rename = "onnxruntime")]
    OnnxRuntime,
}

impl BackendKind {
    /// Both backends, in the order the CLI lists them.
    pub const ALL: [BackendKind; 2] = [BackendKind::Tract, BackendKind::OnnxRuntime];

    /// The name used on the command line and in configuration.
    pub fn name(self) -> &'static str {
        match self {
            BackendKind::Tract => "tract",
            BackendKind::OnnxRuntime => "onnxruntime",
        }
    }
}

impl fmt::Display for BackendKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for BackendKind {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.to_ascii_lowercase().as_str() {
            "tract" => Ok(BackendKind::Tract),
            "onnxruntime" | "ort" | "onnx-runtime" => Ok(BackendKind::OnnxRuntime),
            other => Err(format!(
                "unknown backend `{other}` (expected `tract` or `onnxruntime`)"
            )),
        }
    }
}

/// Backend selection as it appears in configuration.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct BackendConfig {
    /// The engine to use; see [`BackendConfig::default`] for the default.
    pub kind: BackendKind,
    /// Path of `libonnxruntime.so` for [`BackendKind::OnnxRuntime`]; when absent
    /// `ORT_DYLIB_PATH` is used.
    pub ort_dylib_path: Option<PathBuf>,
}

impl Default for BackendConfig {
    /// tract: the only backend that works on a fresh machine with nothing
    /// installed. Where ONNX Runtime is available it is the faster one (see the
    /// benchmark table in `models/README.md`).
    fn default() -> Self {
        Self {
            kind: BackendKind::Tract,
            ort_dylib_path: None,
        }
    }
}

impl BackendConfig {
    /// The ONNX Runtime library this configuration points at: the configured
    /// path, else `ORT_DYLIB_PATH`, else `None`.
    pub fn resolved_ort_dylib_path(&self) -> Option<PathBuf> {
        self.ort_dylib_path.clone().or_else(|| {
            std::env::var_os(ORT_DYLIB_ENV)
                .filter(|v| !v.is_empty())
                .map(PathBuf::from)
        })
    }
}

/// The backend this process has chosen, if any.
static ACTIVE: Mutex<Option<BackendKind>> = Mutex::new(None);
/// The ort environment, created once right after the API table is set.
static ENVIRONMENT: OnceLock<ort::environment::Environment> = OnceLock::new();

/// The backend this process runs, once one has been initialised.
pub fn active_backend() -> Option<BackendKind> {
    *ACTIVE.lock().unwrap_or_else(|e| e.into_inner())
}

/// Makes `config.kind` this process's backend (see the module docs) and
/// returns the ort environment sessions are built in.
pub fn init_backend(
    config: &BackendConfig,
) -> Result<&'static ort::environment::Environment, DetectError> {
    let mut active = ACTIVE.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(kind) = *active {
        if kind != config.kind {
            return Err(DetectError::BackendConflict {
                active: kind,
                requested: config.kind,
            });
        }
    } else {
        let api = match config.kind {
            BackendKind::Tract => ort_tract::api(),
            BackendKind::OnnxRuntime => {
                let path = config
                    .resolved_ort_dylib_path()
                    .ok_or(DetectError::OrtLibraryNotConfigured)?;
                load_onnxruntime_api(&path)?
            }
        };
        if !ort::set_api(api) {
            // Someone outside this module set a table first; we cannot tell which.
            return Err(DetectError::InvalidConfig(
                "ort's API table was already set outside mgmot::detect::backend".into(),
            ));
        }
        tracing::info!(backend = %config.kind, "inference backend selected for this process");
        *active = Some(config.kind);
    }
    if let Some(env) = ENVIRONMENT.get() {
        return Ok(env);
    }
    let env = ort::init()
        .with_name("mgmot")
        .with_logger(Arc::new(forward_ort_log))
        .build()
        .map_err(|e| {
            DetectError::InvalidConfig(format!("cannot create the ort environment: {e}"))
        })?;
    if config.kind == BackendKind::OnnxRuntime {
        // ONNX Runtime starts at VERBOSE (ort asks for it) and says some 600 things at INFO
        // while it builds a session; from here on it only tells of warnings. (ort-tract has no
        // log level to set, and logs nothing.)
        env.set_log_level(ort::logging::LogLevel::Warning);
    }
    Ok(ENVIRONMENT.get_or_init(|| env))
}

/// ONNX Runtime's log, as `tracing` events of target `ort`: warnings and errors as such; what
/// it says at INFO and VERBOSE (only before [`init_backend`] sets its level to WARNING) at
/// DEBUG and TRACE, so that it never floods a run's log.
fn forward_ort_log(
    level: ort::logging::LogLevel,
    category: &str,
    _id: &str,
    code_location: &str,
    message: &str,
) {
    use ort::logging::LogLevel;
    match level {
        LogLevel::Verbose => {
            tracing::trace!(target: "ort", category, code_location, "{message}")
        }
        LogLevel::Info => tracing::debug!(target: "ort", category, code_location, "{message}"),
        LogLevel::Warning => tracing::warn!(target: "ort", category, code_location, "{message}"),
        LogLevel::Error | LogLevel::Fatal => {
            tracing::error!(target: "ort", category, code_location, "{message}")
        }
    }
}

/// Loads ONNX Runtime from `path` and returns a copy of its C API table for
/// the API version this build of ort was compiled against.
///
/// The library is never unloaded: ort keeps calling into it until the process ends.
pub(super) fn load_onnxruntime_api(path: &Path) -> Result<ort::sys::OrtApi, DetectError> {
    let err = |problem: String| DetectError::OrtLibrary {
        path: path.to_path_buf(),
        problem,
    };
    if !path.is_file() {
        return Err(err("no such file".into()));
    }
    // SAFETY: loading a shared library runs its initialisers; the user pointed
    // us at ONNX Runtime, which is what we trust it to be.
    let lib = unsafe { libloading::Library::new(path) }.map_err(|e| err(e.to_string()))?;
    type GetApiBase = unsafe extern "C" fn() -> *const ort::sys::OrtApiBase;
    // SAFETY: `OrtGetApiBase` has this signature in every ONNX Runtime release.
    let get_base = unsafe { lib.get::<GetApiBase>(b"OrtGetApiBase") }
        .map_err(|e| err(format!("not an ONNX Runtime library ({e})")))?;
    // SAFETY: the function takes no arguments and returns a static table or null.
    let base = unsafe { get_base() };
    if base.is_null() {
        return Err(err("OrtGetApiBase returned null".into()));
    }
    // SAFETY: `base` is non-null and points at ONNX Runtime's static OrtApiBase.
    let (version, api) = unsafe {
        let v = ((*base).GetVersionString)();
        let version = if v.is_null() {
            "unknown".to_string()
        } else {
            CStr::from_ptr(v).to_string_lossy().into_owned()
        };
        (version, ((*base).GetApi)(ort::sys::ORT_API_VERSION))
    };
    if api.is_null() {
        return Err(err(format!(
            "ONNX Runtime {version} does not provide C API version {} (ONNX Runtime 1.{} or newer is needed)",
            ort::sys::ORT_API_VERSION,
            ort::sys::ORT_API_VERSION
        )));
    }
    // SAFETY: `api` is non-null and points at a table at least as large as the
    // version we asked for; OrtApi is a plain struct of function pointers.
    let table = unsafe { std::ptr::read(api) };
    tracing::info!(path = %path.display(), %version, "loaded ONNX Runtime");
    std::mem::forget(lib);
    Ok(table)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn backend_names_round_trip() {
        for kind in BackendKind::ALL {
            assert_eq!(kind.name().parse::<BackendKind>(), Ok(kind));
        }
        assert!("cuda".parse::<BackendKind>().is_err());
    }

    #[test]
    fn missing_library_names_the_file() {
        let e = load_onnxruntime_api(Path::new("/nonexistent/libonnxruntime.so")).unwrap_err();
        let msg = e.to_string();
        assert!(msg.contains("/nonexistent/libonnxruntime.so"), "{msg}");
        assert!(msg.contains("no such file"), "{msg}");
    }

    #[test]
    fn non_library_file_is_rejected() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("libonnxruntime.so");
        std::fs::write(&p, b"not a library").unwrap();
        let msg = load_onnxruntime_api(&p).unwrap_err().to_string();
        assert!(msg.contains("libonnxruntime.so"), "{msg}");
    }
}
