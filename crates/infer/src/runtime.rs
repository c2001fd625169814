//! The ONNX Runtime environment and sessions.
//!
//! ONNX Runtime allows ONE environment per process, ever (also after dropping it), so it lives in
//! a `static OnceLock`; the first caller's library path wins and later callers get the same
//! environment (or the same error). The library is loaded with `ort::init_from`, which returns an
//! error for a missing or incompatible library instead of panicking.
//!
//! [`Session`] is a model file opened in that environment, described and run with float32
//! tensors without ort types, so other crates (model bundles here, ONNX policies in
//! unitac-policy) check a file against their own declarations and run it through one code path.

use serde::Deserialize;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Condvar, Mutex, OnceLock};
use std::time::{Duration, Instant};
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
    /// A run stopped at its time budget ([`Session::run_f32_within`]).
    #[error("model '{model}' ran past its budget of {:.1} ms and was stopped after {:.1} ms", .budget.as_secs_f64() * 1e3, .elapsed.as_secs_f64() * 1e3)]
    OverBudget {
        model: String,
        budget: std::time::Duration,
        elapsed: std::time::Duration,
    },
}

/// Where models run. Only CPU can be tested on this project's machines (no GPU in CI); CUDA and
/// TensorRT are registered through ort when the loaded library (onnxruntime-gpu) has them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Deserialize, serde::Serialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum ExecutionProvider {
    #[default]
    Cpu,
    Cuda,
    Tensorrt,
}

impl ExecutionProvider {
    pub const ALL: [ExecutionProvider; 3] = [Self::Cpu, Self::Cuda, Self::Tensorrt];
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Cpu => "cpu",
            Self::Cuda => "cuda",
            Self::Tensorrt => "tensorrt",
        }
    }
    /// Whether the process's ONNX Runtime library has this provider (the environment must be
    /// loaded: [`environment`]).
    pub fn available(self) -> Result<bool, ort::Error> {
        use ort::ep::ExecutionProvider as _;
        match self {
            Self::Cpu => Ok(true),
            Self::Cuda => ort::ep::CUDA::is_available(),
            Self::Tensorrt => ort::ep::TensorRT::is_available(),
        }
    }
}

impl std::fmt::Display for ExecutionProvider {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// One provider name or a list of them.
fn one_or_many<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Vec<ExecutionProvider>, D::Error> {
    #[derive(Deserialize)]
    #[serde(untagged)]
    enum OneOrMany {
        One(ExecutionProvider),
        Many(Vec<ExecutionProvider>),
    }
    Ok(match OneOrMany::deserialize(d)? {
        OneOrMany::One(p) => vec![p],
        OneOrMany::Many(v) => v,
    })
}

#[derive(Debug, Clone, PartialEq, Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct RuntimeConfig {
    /// libonnxruntime.so path; None = `$UNITAC_ORT_LIB`.
    pub library: Option<PathBuf>,
    /// Intra-op threads per session (1 was fastest and steadiest on a shared 2-core machine).
    pub intra_threads: usize,
    /// Execution providers in order of preference (one name or a list; default `[cpu]`): a model
    /// runs on the first one the loaded ONNX Runtime library has. One it lacks is passed over
    /// with one line on stderr (once per provider and process) when another follows, e.g.
    /// `[cuda, cpu]` on a CPU-only library; when none is left it is an error, never a silent
    /// fall-back.
    #[serde(deserialize_with = "one_or_many")]
    pub providers: Vec<ExecutionProvider>,
}

impl Default for RuntimeConfig {
    fn default() -> Self {
        Self {
            library: None,
            intra_threads: 1,
            providers: vec![ExecutionProvider::Cpu],
        }
    }
}

/// Providers already reported missing in this process.
static NOTICED: OnceLock<std::sync::Mutex<Vec<ExecutionProvider>>> = OnceLock::new();

/// The first of `providers` this library has. A missing one followed by another is reported on
/// stderr in one line (once per provider and process); the line is returned too.
pub fn choose_provider(
    model: &str,
    providers: &[ExecutionProvider],
) -> Result<(ExecutionProvider, Option<String>), InferError> {
    let err = |msg: String| InferError::Model {
        model: model.to_string(),
        msg,
    };
    let mut notice = None;
    for (i, &p) in providers.iter().enumerate() {
        let why = match p.available() {
            Ok(true) => return Ok((p, notice)),
            Ok(false) => "not in this ONNX Runtime library".to_string(),
            Err(e) => e.to_string().lines().next().unwrap_or("").to_string(),
        };
        let Some(next) = providers.get(i + 1) else {
            return Err(err(format!("provider {p} is not available: {why}")));
        };
        let line = format!("execution provider {p} is {why}; models that ask for it run on {next}");
        let seen = NOTICED.get_or_init(Default::default);
        let first = seen.lock().map(|mut s| {
            let new = !s.contains(&p);
            if new {
                s.push(p);
            }
            new
        });
        if first.unwrap_or(true) {
            eprintln!("unitac: {line}");
        }
        notice.get_or_insert(line);
    }
    Err(err(
        "no execution provider given (providers: [cpu] runs everywhere)".into(),
    ))
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
) -> Result<(ort::session::Session, ExecutionProvider), InferError> {
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
    let (provider, _) = choose_provider(model, &cfg.providers)?;
    b = match provider {
        ExecutionProvider::Cpu => b,
        // Available, so a failure to register it is an error, never a silent fall-back to CPU.
        ExecutionProvider::Cuda => b
            .with_execution_providers([ort::ep::CUDA::default().build().error_on_failure()])
            .map_err(|e| err(format!("provider cuda is not available: {e}")))?,
        ExecutionProvider::Tensorrt => b
            .with_execution_providers([ort::ep::TensorRT::default().build().error_on_failure()])
            .map_err(|e| err(format!("provider tensorrt is not available: {e}")))?,
    };
    let session = b.commit_from_file(path).map_err(|e| err(e.to_string()))?;
    Ok((session, provider))
}

/// Largest tensor a model may return \[elements].
pub const MAX_OUTPUT_ELEMENTS: usize = 64 << 20;

/// A float32 tensor: shape and row-major data.
pub type TensorF32 = (Vec<i64>, Vec<f32>);

/// One input or output of a model file as ONNX Runtime reports it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TensorInfo {
    pub name: String,
    /// `float32`, `int64`, ... (`other` for element types this crate never feeds); `None` when
    /// the value is not a tensor (a sequence, map or optional).
    pub dtype: Option<&'static str>,
    /// Dimensions, -1 where the file leaves one dynamic (a symbolic dimension such as "batch").
    pub shape: Vec<i64>,
}

/// The manifest spelling of an ONNX element type.
pub fn dtype_name(t: ort::value::TensorElementType) -> &'static str {
    use ort::value::TensorElementType as T;
    match t {
        T::Float32 => "float32",
        T::Float64 => "float64",
        T::Float16 => "float16",
        T::Int64 => "int64",
        T::Int32 => "int32",
        T::Uint8 => "uint8",
        T::Int8 => "int8",
        T::Bool => "bool",
        _ => "other",
    }
}

fn describe(outlets: &[ort::value::Outlet]) -> Vec<TensorInfo> {
    outlets
        .iter()
        .map(|o| match o.dtype() {
            ort::value::ValueType::Tensor { ty, shape, .. } => TensorInfo {
                name: o.name().to_string(),
                dtype: Some(dtype_name(*ty)),
                shape: shape.to_vec(),
            },
            _ => TensorInfo {
                name: o.name().to_string(),
                dtype: None,
                shape: Vec::new(),
            },
        })
        .collect()
}

/// What the deadline thread of a session watches: the armed run (its deadline and number),
/// the number of the last run it stopped, and whether to end.
#[derive(Debug, Default)]
struct Watch {
    armed: Option<(Instant, u64)>,
    fired: Option<u64>,
    stop: bool,
}

type Shared = Arc<(Mutex<Watch>, Condvar)>;

/// A thread that sets a session's terminate flag when an armed run passes its deadline (ONNX
/// Runtime checks the flag between nodes, also inside a Loop's body, and the run returns an
/// error). Started at the first run with a budget; ended and joined when the session drops.
struct Deadline {
    shared: Shared,
    options: Arc<ort::session::RunOptions>,
    thread: Option<std::thread::JoinHandle<()>>,
    /// Runs armed so far.
    runs: u64,
}

impl std::fmt::Debug for Deadline {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Deadline")
            .field("runs", &self.runs)
            .finish_non_exhaustive()
    }
}

impl Deadline {
    fn new() -> Result<Self, String> {
        let mut options = ort::session::RunOptions::new().map_err(|e| e.to_string())?;
        // A stopped run's error comes back as a value; ONNX Runtime's own log line for it
        // (once per stopped run, on stderr) would only repeat it.
        options
            .set_log_level(ort::logging::LogLevel::Fatal)
            .map_err(|e| e.to_string())?;
        Ok(Self {
            shared: Arc::new((Mutex::new(Watch::default()), Condvar::new())),
            options: Arc::new(options),
            thread: None,
            runs: 0,
        })
    }

    /// The watching loop: sleeps until the armed deadline (or a change), then terminates.
    fn watch(shared: &Shared, options: &ort::session::RunOptions) {
        let (lock, cv) = &**shared;
        let Ok(mut w) = lock.lock() else { return };
        while !w.stop {
            match w.armed {
                None => match cv.wait(w) {
                    Ok(g) => w = g,
                    Err(_) => return,
                },
                Some((deadline, run)) => {
                    let now = Instant::now();
                    if now >= deadline {
                        // Returns at once; the run stops at its next node.
                        let _ = options.terminate();
                        w.fired = Some(run);
                        w.armed = None;
                    } else {
                        match cv.wait_timeout(w, deadline - now) {
                            Ok((g, _)) => w = g,
                            Err(_) => return,
                        }
                    }
                }
            }
        }
    }

    /// Arm a run with `budget` from now; the thread is started on first use.
    fn arm(&mut self, budget: Duration) -> Result<u64, String> {
        if self.thread.is_none() {
            let (shared, options) = (self.shared.clone(), self.options.clone());
            let t = std::thread::Builder::new()
                .name("unitac-ort-deadline".into())
                .spawn(move || Self::watch(&shared, &options))
                .map_err(|e| format!("starting the deadline thread: {e}"))?;
            self.thread = Some(t);
        }
        self.runs = self.runs.wrapping_add(1);
        let (lock, cv) = &*self.shared;
        let mut w = lock
            .lock()
            .map_err(|_| "deadline lock poisoned".to_string())?;
        // A budget too large for the clock is no deadline.
        w.armed = Instant::now()
            .checked_add(budget)
            .map(|deadline| (deadline, self.runs));
        cv.notify_one();
        Ok(self.runs)
    }

    /// Disarm run `run`: whether the thread stopped it. The terminate flag is cleared for the
    /// next run either way.
    fn disarm(&self, run: u64) -> bool {
        let (lock, _) = &*self.shared;
        let fired = match lock.lock() {
            Ok(mut w) => {
                w.armed = None;
                w.fired == Some(run)
            }
            Err(_) => true,
        };
        if fired {
            let _ = self.options.unterminate();
        }
        fired
    }
}

impl Drop for Deadline {
    fn drop(&mut self) {
        let (lock, cv) = &*self.shared;
        if let Ok(mut w) = lock.lock() {
            w.stop = true;
            cv.notify_one();
        }
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// A model file opened in the process's environment ([`session`]'s threads and provider), with
/// its inputs and outputs as the file declares them.
#[derive(Debug)]
pub struct Session {
    model: String,
    provider: ExecutionProvider,
    inputs: Vec<TensorInfo>,
    outputs: Vec<TensorInfo>,
    inner: ort::session::Session,
    /// The time limit's watcher, made at the first run with a budget.
    deadline: Option<Deadline>,
}

impl Session {
    /// Open `path`; `model` names it in errors.
    pub fn open(model: &str, path: &Path, cfg: &RuntimeConfig) -> Result<Session, InferError> {
        let (inner, provider) = session(model, path, cfg)?;
        Ok(Session {
            provider,
            model: model.to_string(),
            inputs: describe(inner.inputs()),
            outputs: describe(inner.outputs()),
            inner,
            deadline: None,
        })
    }

    pub fn inputs(&self) -> &[TensorInfo] {
        &self.inputs
    }
    /// The execution provider the model runs on.
    pub fn provider(&self) -> ExecutionProvider {
        self.provider
    }

    pub fn outputs(&self) -> &[TensorInfo] {
        &self.outputs
    }

    /// Run with float32 inputs given by name as (name, shape, data); returns the named float32
    /// outputs in the order asked for. Output sizes are bounded by [`MAX_OUTPUT_ELEMENTS`].
    pub fn run_f32(
        &mut self,
        inputs: &[(&str, &[i64], &[f32])],
        outputs: &[&str],
    ) -> Result<Vec<TensorF32>, InferError> {
        self.run_f32_within(inputs, outputs, None)
    }

    /// [`Session::run_f32`] with a time limit: a run still going `budget` after it started is
    /// stopped from another thread (ONNX Runtime's terminate flag, checked between nodes) and
    /// is [`InferError::OverBudget`]. A run that finishes is returned as it came, whatever the
    /// clock said, so a model within its budget gives the same bytes with or without one.
    pub fn run_f32_within(
        &mut self,
        inputs: &[(&str, &[i64], &[f32])],
        outputs: &[&str],
        budget: Option<Duration>,
    ) -> Result<Vec<TensorF32>, InferError> {
        let model = self.model.clone();
        let err = |msg: String| InferError::Model {
            model: model.clone(),
            msg,
        };
        let mut values: Vec<(
            std::borrow::Cow<'_, str>,
            ort::session::SessionInputValue<'_>,
        )> = Vec::with_capacity(inputs.len());
        for (name, shape, data) in inputs {
            let n: i64 = shape.iter().product();
            if n < 0 || n as usize != data.len() {
                return Err(err(format!(
                    "input '{name}': shape {shape:?} needs {n} values, got {}",
                    data.len()
                )));
            }
            let t = ort::value::TensorRef::from_array_view((shape.to_vec(), *data))
                .map_err(|e| err(e.to_string()))?;
            values.push(((*name).into(), t.into()));
        }
        let results = match budget {
            None => self.inner.run(values).map_err(|e| err(e.to_string()))?,
            Some(budget) => {
                if self.deadline.is_none() {
                    self.deadline = Some(Deadline::new().map_err(err)?);
                }
                let Some(deadline) = self.deadline.as_mut() else {
                    return Err(err("no deadline thread".into()));
                };
                let run = deadline.arm(budget).map_err(err)?;
                let start = Instant::now();
                let r = self.inner.run_with_options(values, &*deadline.options);
                let stopped = deadline.disarm(run);
                match r {
                    Ok(results) => results,
                    Err(_) if stopped => {
                        return Err(InferError::OverBudget {
                            model: model.clone(),
                            budget,
                            elapsed: start.elapsed(),
                        });
                    }
                    Err(e) => return Err(err(e.to_string())),
                }
            }
        };
        let out_err = |msg: String| InferError::Output {
            model: model.clone(),
            msg,
        };
        let mut out = Vec::with_capacity(outputs.len());
        for n in outputs {
            let v = results
                .get(n)
                .ok_or_else(|| out_err(format!("missing '{n}'")))?;
            let (shape, data) = v
                .try_extract_tensor::<f32>()
                .map_err(|e| out_err(format!("'{n}': {e}")))?;
            if data.len() > MAX_OUTPUT_ELEMENTS {
                return Err(out_err(format!("'{n}' has {} elements", data.len())));
            }
            out.push((shape.to_vec(), data.to_vec()));
        }
        Ok(out)
    }
}
