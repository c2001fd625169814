//! [`OnnxPolicy`]: a manifest-described ONNX policy, loaded and checked once, then asked for an
//! action chunk on every control tick.
//!
//! Per tick: the named inputs are checked (present, sized as declared, finite); when the chunk
//! schedule says an inference is due they are normalised, the model runs through unitac-infer's
//! session (the process's one ONNX Runtime environment), the chunk is checked finite,
//! unnormalised to SI units, checked finite again and clamped to the actions' bounds. A
//! non-finite value anywhere is a typed error and no action: a NaN never leaves this module.

use super::chunk::{Schedule, TimeWentBack};
use super::io::{ActionChunk, NamedInputs};
use super::manifest::{ManifestError, PolicyManifest};
use super::validate::{Mismatch, Resolved, validate};
use std::path::{Path, PathBuf};
use unitac_core::Stamp;
use unitac_infer::bundle::sha256_file;
use unitac_infer::runtime::{InferError, RuntimeConfig, Session};

/// A predicted value further than this share of its action's range beyond a bound counts as
/// beyond it ([`ActionChunk::beyond`]); closer, it is only clamped (schema/policy.json).
pub use crate::schema::FAR_FRACTION;

/// Every problem found loading one policy.
#[derive(Debug, Clone, PartialEq)]
pub struct Mismatches {
    pub policy: String,
    pub dir: PathBuf,
    pub problems: Vec<Mismatch>,
}

impl std::fmt::Display for Mismatches {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "policy '{}' in {}: {} problem(s)",
            self.policy,
            self.dir.display(),
            self.problems.len()
        )?;
        for (i, p) in self.problems.iter().enumerate() {
            write!(f, "\n  {}. {p}", i + 1)?;
        }
        Ok(())
    }
}

#[derive(Debug, thiserror::Error)]
pub enum LoadError {
    #[error("policy manifest {0}")]
    Manifest(#[from] ManifestError),
    /// The ONNX Runtime library itself (nothing else can be checked without it).
    #[error(transparent)]
    Runtime(InferError),
    #[error("{0}")]
    Mismatches(Mismatches),
}

#[derive(Debug, thiserror::Error)]
pub enum RunError {
    #[error("input '{name}' is missing (the policy reads {needed:?})")]
    MissingInput { name: String, needed: Vec<String> },
    #[error("input '{name}' has {got} values, the policy needs {expected}")]
    InputLength {
        name: String,
        got: usize,
        expected: usize,
    },
    #[error("input '{name}'[{index}] is {value}, not finite")]
    NonFiniteInput {
        name: String,
        index: usize,
        value: f32,
    },
    /// A finite input that normalisation took out of float32's range (a tiny std).
    #[error("input '{name}'[{index}] = {value} normalises to {normalised}, not finite")]
    NonFiniteFeature {
        name: String,
        index: usize,
        value: f32,
        normalised: f32,
    },
    /// The inference ran past its time limit ([`OnnxPolicy::set_budget`]) and was stopped.
    #[error(
        "the model ran past its budget of {:.1} ms and was stopped after {:.1} ms",
        .budget.as_secs_f64() * 1e3,
        .elapsed.as_secs_f64() * 1e3
    )]
    OverBudget {
        budget: std::time::Duration,
        elapsed: std::time::Duration,
    },
    #[error("the model predicted {value} for action '{action}' at chunk row {row}")]
    NonFiniteAction {
        row: usize,
        action: String,
        value: f32,
    },
    #[error("the model's action output has shape {got:?}, expected {expected:?}")]
    OutputShape { got: Vec<i64>, expected: Vec<i64> },
    #[error(transparent)]
    Inference(#[from] InferError),
    #[error(transparent)]
    TimeWentBack(#[from] TimeWentBack),
    #[error("no chunk predicts tick {0}")]
    NoPlan(i64),
}

/// A loaded, checked ONNX policy with its chunk schedule.
#[derive(Debug)]
pub struct OnnxPolicy {
    manifest: PolicyManifest,
    id: String,
    io: Resolved,
    session: Session,
    schedule: Schedule,
    /// Normalised inputs, reused across ticks.
    buffers: Vec<Vec<f32>>,
    /// The time limit of one inference (None: none).
    budget: Option<std::time::Duration>,
}

impl OnnxPolicy {
    /// Load `dir/manifest.json` and the ONNX file it names, and check them against each other.
    /// Every problem (file, sha256, the manifest's own rules, each input and output against the
    /// model's metadata) comes back in one [`LoadError::Mismatches`].
    pub fn load(dir: &Path, cfg: &RuntimeConfig) -> Result<OnnxPolicy, LoadError> {
        let manifest = PolicyManifest::read(&dir.join("manifest.json"))?;
        let mut problems = Vec::new();
        let path = dir.join(&manifest.file);
        let file_problem = |msg: String| Mismatch::File {
            file: manifest.file.clone(),
            msg,
        };
        let mut session = None;
        if !path.is_file() {
            problems.push(file_problem(format!("not found in {}", dir.display())));
        } else {
            match sha256_file(&path) {
                Ok(h) if h.eq_ignore_ascii_case(&manifest.sha256) => {}
                Ok(h) => problems.push(Mismatch::Sha256 {
                    file: manifest.file.clone(),
                    actual: h,
                    declared: manifest.sha256.clone(),
                }),
                Err(e) => problems.push(file_problem(e.to_string())),
            }
            // Opened even when the hash differs, so the list also says what else is wrong.
            match Session::open(&manifest.policy, &path, cfg) {
                Ok(s) => session = Some(s),
                Err(e @ InferError::Library(_)) => return Err(LoadError::Runtime(e)),
                Err(e) => problems.push(file_problem(e.to_string())),
            }
        }
        let io = validate(
            &manifest,
            session.as_ref().map(|s| (s.inputs(), s.outputs())),
        );
        let (io, session) = match (io, session) {
            (Ok(io), Some(s)) if problems.is_empty() => (io, s),
            (io, _) => {
                problems.extend(io.err().unwrap_or_default());
                return Err(LoadError::Mismatches(Mismatches {
                    policy: manifest.policy.clone(),
                    dir: dir.to_path_buf(),
                    problems,
                }));
            }
        };
        let period_ns = (1e9 / manifest.control_rate_hz).round() as i64;
        let schedule = Schedule::new(
            manifest.chunk_size,
            io.output.names.len(),
            manifest.n_action_steps,
            manifest.temporal_ensemble_coeff,
            period_ns,
        );
        let id = format!(
            "{}@{}",
            manifest.policy,
            manifest.sha256.get(..8).unwrap_or(&manifest.sha256)
        );
        Ok(OnnxPolicy {
            buffers: io
                .inputs
                .iter()
                .map(|i| Vec::with_capacity(i.numel))
                .collect(),
            manifest,
            id,
            io,
            session,
            schedule,
            budget: None,
        })
    }

    /// Limit each inference to `budget` of wall-clock time (None: no limit): a run still going
    /// then is stopped and the tick is [`RunError::OverBudget`] (nothing committed). A run
    /// that finishes within it gives the bytes it gives without a limit.
    pub fn set_budget(&mut self, budget: Option<std::time::Duration>) {
        self.budget = budget;
    }

    /// `policy@sha256-prefix`, for status messages.
    pub fn id(&self) -> &str {
        &self.id
    }

    pub fn manifest(&self) -> &PolicyManifest {
        &self.manifest
    }

    /// The input names the policy reads, in manifest order.
    pub fn input_names(&self) -> Vec<&str> {
        self.io.inputs.iter().map(|i| i.name.as_str()).collect()
    }

    pub fn action_names(&self) -> &[String] {
        &self.io.output.names
    }

    /// Control period \[ns] (from `control_rate_hz`).
    pub fn period_ns(&self) -> i64 {
        self.schedule.period_ns()
    }

    /// Start a new episode: forget the stored chunks and the tick origin.
    pub fn reset(&mut self) {
        self.schedule.reset();
    }

    /// Check every input the policy reads: present, sized, finite.
    fn check_inputs<'a>(&self, obs: &NamedInputs<'a>) -> Result<Vec<&'a [f32]>, RunError> {
        let mut out = Vec::with_capacity(self.io.inputs.len());
        for i in &self.io.inputs {
            let Some(x) = obs.get(&i.name) else {
                return Err(RunError::MissingInput {
                    name: i.name.clone(),
                    needed: self.io.inputs.iter().map(|i| i.name.clone()).collect(),
                });
            };
            if x.len() != i.numel {
                return Err(RunError::InputLength {
                    name: i.name.clone(),
                    got: x.len(),
                    expected: i.numel,
                });
            }
            if let Some((index, &value)) = x.iter().enumerate().find(|(_, v)| !v.is_finite()) {
                return Err(RunError::NonFiniteInput {
                    name: i.name.clone(),
                    index,
                    value,
                });
            }
            out.push(x);
        }
        Ok(out)
    }

    /// The first non-finite value of a chunk as an error.
    fn finite(&self, chunk: &[f32]) -> Result<(), RunError> {
        let a = self.io.output.names.len().max(1);
        match chunk.iter().enumerate().find(|(_, v)| !v.is_finite()) {
            None => Ok(()),
            Some((i, &value)) => Err(RunError::NonFiniteAction {
                row: i / a,
                action: self.io.output.names[i % a].clone(),
                value,
            }),
        }
    }

    /// One inference: normalise, run, check, unnormalise, check, clamp. Returns the H x A chunk
    /// in SI units, how many values were clamped, and the actions (indices) of those that were
    /// beyond their bound by more than [`FAR_FRACTION`] of its range.
    fn infer(&mut self, features: &[&[f32]]) -> Result<(Vec<f32>, usize, Vec<usize>), RunError> {
        for ((spec, buf), x) in self.io.inputs.iter().zip(&mut self.buffers).zip(features) {
            spec.norm.forward(x, buf);
            if let Some((index, &normalised)) = buf.iter().enumerate().find(|(_, v)| !v.is_finite())
            {
                return Err(RunError::NonFiniteFeature {
                    name: spec.name.clone(),
                    index,
                    value: x.get(index).copied().unwrap_or(f32::NAN),
                    normalised,
                });
            }
        }
        let feeds: Vec<(&str, &[i64], &[f32])> = self
            .io
            .inputs
            .iter()
            .zip(&self.buffers)
            .map(|(i, b)| (i.name.as_str(), i.shape.as_slice(), b.as_slice()))
            .collect();
        let out = &self.io.output;
        let a = out.names.len();
        let ran = self
            .session
            .run_f32_within(&feeds, &[out.name.as_str()], self.budget)
            .map_err(|e| match e {
                InferError::OverBudget {
                    budget, elapsed, ..
                } => RunError::OverBudget { budget, elapsed },
                e => RunError::Inference(e),
            })?;
        let (shape, mut chunk) = ran
            .into_iter()
            .next_back()
            .ok_or_else(|| InferError::Output {
                model: self.manifest.policy.clone(),
                msg: format!("no '{}'", out.name),
            })?;
        let expected = vec![1, out.horizon as i64, a as i64];
        if shape != expected {
            return Err(RunError::OutputShape {
                got: shape,
                expected,
            });
        }
        self.finite(&chunk)?;
        let out = &self.io.output;
        out.norm.inverse_rows(&mut chunk, a);
        self.finite(&chunk)?;
        let mut clamped = 0;
        let mut far = Vec::new();
        for (i, v) in chunk.iter_mut().enumerate() {
            let (lo, hi) = (out.lo[i % a], out.hi[i % a]);
            if *v < lo || *v > hi {
                let margin = FAR_FRACTION * (hi - lo);
                if (*v < lo - margin || *v > hi + margin) && !far.contains(&(i % a)) {
                    far.push(i % a);
                }
                *v = v.clamp(lo, hi);
                clamped += 1;
            }
        }
        far.sort_unstable();
        Ok((chunk, clamped, far))
    }

    /// The plan for control tick `t`: runs the model when the schedule says an inference is due
    /// (the first tick, every `n_action_steps` ticks, or when the plan ran out), otherwise
    /// continues the stored chunks. On an error nothing is committed: the tick can be retried.
    pub fn act(&mut self, obs: &NamedInputs<'_>, t: Stamp) -> Result<ActionChunk, RunError> {
        let features = self.check_inputs(obs)?;
        let tick = self.schedule.tick_of(t)?;
        let inferred = self.schedule.due(tick);
        let (chunk, clamped, beyond) = if inferred {
            let (c, n, far) = self.infer(&features)?;
            (Some(c), n, far)
        } else {
            (None, 0, Vec::new())
        };
        self.schedule.advance(t, tick, chunk);
        let data = self.schedule.plan(tick);
        if data.is_empty() {
            return Err(RunError::NoPlan(tick));
        }
        Ok(ActionChunk {
            names: self.io.output.names.clone(),
            units: self.io.output.units.clone(),
            data,
            start: t,
            period_ns: self.schedule.period_ns(),
            inferred,
            clamped,
            beyond,
        })
    }
}
