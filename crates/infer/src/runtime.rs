//! The ONNX Runtime environment and sessions.
//!
//! ONNX Runtime allows ONE environment per process, ever (also after dropping it), so it lives in
//! a `static OnceLock`; the first caller's library path wins and later callers get the same
//! environment (or the same error). The library is loaded with `ort::init_from`, which returns an
//! error for a missing or incompatible library instead of panicking.

use serde::Deserialize;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use thiserror::Error;

/// Why the ONNX Runtime library could not be used (kept for the life of the process: the first
/// attempt decides).
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum LibraryError {
    #[error("no library given and UNITAC_ORT_LIB is not set (run scripts/setup.sh)")]
    NotConfigured,
    #[error("{} does not exist", .0.display())]
    Missing(PathBuf),
    #[error("{}: {msg}", path.display())]
    Load { path: PathBuf, msg: String },
}

#[derive(Debug, Error)]
pub enum InferError {
    #[error("ONNX Runtime library: {0}")]
    Library(#[from] LibraryError),
    #[error("model bundle {dir}: {msg}")]
    Bundle { dir: PathBuf, msg: String },
    #[error("model '{model}': {msg}")]
    Model { model: String, msg: String },
    #[error("model '{model}' output: {msg}")]
    Output { model: String, msg: String },
    #[error("bad input: {0}")]
    Input(String),
}

/// Where models run. Only CPU can be tested on this project's machines (no GPU in CI); CUDA and
/// TensorRT are registered through ort when the loaded library (onnxruntime-gpu) has them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, serde::Serialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum ExecutionProvider {
    #[default]
    Cpu,
    Cuda,
    Tensorrt,
}

#[derive(Debug, Clone, PartialEq, Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct RuntimeConfig {
    /// libonnxruntime.so path; None = `$UNITAC_ORT_LIB`.
    pub library: Option<PathBuf>,
    /// Intra-op threads per session (1 was fastest and steadiest on a shared 2-core machine).
    pub intra_threads: usize,
    pub provider: ExecutionProvider,
}

impl Default for RuntimeConfig {
    fn default() -> Self {
        Self {
            library: None,
            intra_threads: 1,
            provider: ExecutionProvider::Cpu,
        }
    }
}

static ENV: OnceLock<Result<ort::environment::Environment, LibraryError>> = OnceLock::new();

/// The process's ONNX Runtime environment, created on first use from `library` (or
/// `$UNITAC_ORT_LIB`).
pub fn environment(
    library: Option<&Path>,
) -> Result<&'static ort::environment::Environment, InferError> {
    let r = ENV.get_or_init(|| {
        let path = library
            .map(Path::to_path_buf)
            .or_else(|| std::env::var_os("UNITAC_ORT_LIB").map(PathBuf::from))
            .ok_or(LibraryError::NotConfigured)?;
        if !path.is_file() {
            return Err(LibraryError::Missing(path));
        }
        let load = |msg: String| LibraryError::Load {
            path: path.clone(),
            msg,
        };
        let builder = ort::init_from(&path).map_err(|e| load(e.to_string()))?;
        builder
            .with_name("unitac")
            .build()
            .map_err(|e| load(e.to_string()))
    });
    r.as_ref().map_err(|e| InferError::Library(e.clone()))
}

/// Open a session on `path` with the configured threads and provider.
pub fn session(
    model: &str,
    path: &Path,
    cfg: &RuntimeConfig,
) -> Result<ort::session::Session, InferError> {
    let env = environment(cfg.library.as_deref())?;
    let err = |e: String| InferError::Model {
        model: model.to_string(),
        msg: e,
    };
    let mut b = ort::session::Session::builder(env).map_err(|e| err(e.to_string()))?;
    b = b
        .with_intra_threads(cfg.intra_threads.clamp(1, 64))
        .map_err(|e| err(e.to_string()))?;
    if cfg.intra_threads > 1 {
        // Spinning threads triple the median latency on a loaded machine.
        b = b
            .with_config_entry("session.intra_op.allow_spinning", "0")
            .map_err(|e| err(e.to_string()))?;
    }
    b = match cfg.provider {
        ExecutionProvider::Cpu => b,
        // A provider that cannot be registered is an error, never a silent fall-back to CPU.
        ExecutionProvider::Cuda => b
            .with_execution_providers([ort::ep::CUDA::default().build().error_on_failure()])
            .map_err(|e| err(format!("provider cuda is not available: {e}")))?,
        ExecutionProvider::Tensorrt => b
            .with_execution_providers([ort::ep::TensorRT::default().build().error_on_failure()])
            .map_err(|e| err(format!("provider tensorrt is not available: {e}")))?,
    };
    b.commit_from_file(path).map_err(|e| err(e.to_string()))
}
