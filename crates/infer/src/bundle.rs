//! Model bundles: a directory with `manifest.json` and the `.onnx` files it lists.
//!
//! On load, each requested model's file must exist, match its sha256, open in ONNX Runtime, and
//! have exactly the declared inputs and outputs (names, dtypes, ranks, fixed dimensions; a
//! declared symbolic dimension such as "batch" matches anything). Every mismatch of every
//! requested model is listed in one error, so a user fixing an exported bundle sees all problems
//! at once. A scene loads only the models it names.

use crate::preprocess::Preprocess;
use crate::runtime::{InferError, RuntimeConfig, Session, TensorInfo};
pub use crate::runtime::{MAX_OUTPUT_ELEMENTS, TensorF32};
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::collections::BTreeMap;
use std::io::Read;
use std::path::{Path, PathBuf};

/// Largest manifest accepted [bytes].
const MAX_MANIFEST_BYTES: u64 = 1 << 20;

#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum Dim {
    Fixed(i64),
    Symbolic(String),
}

#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TensorSpec {
    pub name: String,
    pub dtype: String,
    pub shape: Vec<Dim>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ModelSpec {
    pub file: String,
    pub sha256: String,
    pub inputs: Vec<TensorSpec>,
    pub outputs: Vec<TensorSpec>,
    /// Velocity models: "tau_data_at_1" (tau = 0 noise, output d x/d tau) or "tau_noise_at_1"
    /// (fed 1 - tau, output negated).
    #[serde(default)]
    pub time_convention: Option<String>,
    /// Velocity models: smallest target sigma they represent (sets the s*h guard).
    #[serde(default)]
    pub sigma_min: Option<f64>,
    /// Velocity models a sampler stage runs: what each condition input carries, in the model's
    /// input order after `x` and `t` (empty: the model is only timed, never run by a stage).
    #[serde(default)]
    pub condition: Vec<ConditionSpec>,
    /// Velocity models: the latent a sample stands for, `offset + scale * x` per element, and
    /// the shape it is published with (empty: the sample itself, as [1, D]).
    #[serde(default)]
    pub latent_offset: Vec<f32>,
    #[serde(default)]
    pub latent_scale: Vec<f32>,
    #[serde(default)]
    pub latent_shape: Vec<u32>,
    /// Anything else the generator recorded (fit statistics, ...).
    #[serde(flatten)]
    pub extra: BTreeMap<String, serde_json::Value>,
}

/// Where a velocity model's condition input comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ConditionSource {
    /// The object-level condition of one object: `fields` in order, each either
    /// `category:<name>` (1 when the object is of that category, else 0) or a camera value of
    /// the object (`<field>` read as `<object>_<field>` from the VisualObservation; 0 when the
    /// camera has no such value for it). All zeros is the unconditional branch.
    Object,
    /// The sensor-level condition: the mean of the encoder's sensor tokens of the background.
    SensorTokens,
}

/// One condition input of a velocity model.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ConditionSpec {
    /// The model's input name.
    pub input: String,
    pub source: ConditionSource,
    /// `object`: what each value is (see [`ConditionSource::Object`]).
    #[serde(default)]
    pub fields: Vec<String>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LatentSpec {
    pub tokens: u32,
    pub dim: u32,
    pub sampler_dim: u32,
    pub cond_dim: u32,
}

#[derive(Debug, Clone, PartialEq, Deserialize)]
pub struct Manifest {
    pub bundle: String,
    pub version: String,
    #[serde(default)]
    pub description: String,
    pub preprocess: Preprocess,
    pub latent: LatentSpec,
    pub properties: Vec<String>,
    #[serde(default)]
    pub sensor_tokens: BTreeMap<String, u32>,
    pub models: BTreeMap<String, ModelSpec>,
}

/// An opened bundle (manifest parsed and checked; no model loaded yet).
#[derive(Debug, Clone)]
pub struct Bundle {
    pub dir: PathBuf,
    pub manifest: Manifest,
}

/// A loaded, checked model.
#[derive(Debug)]
pub struct Model {
    pub name: String,
    pub spec: ModelSpec,
    /// `bundle@sha256-prefix`, for messages.
    pub id: String,
    session: Session,
}

pub fn sha256_file(path: &Path) -> std::io::Result<String> {
    let mut f = std::fs::File::open(path)?;
    let mut h = Sha256::new();
    let mut buf = vec![0u8; 1 << 16];
    loop {
        let n = f.read(&mut buf)?;
        if n == 0 {
            break;
        }
        h.update(&buf[..n]);
    }
    Ok(h.finalize().iter().map(|b| format!("{b:02x}")).collect())
}

/// Compare declared tensors with the file's; push one line per mismatch.
fn check_io(
    model: &str,
    kind: &str,
    declared: &[TensorSpec],
    actual: &[TensorInfo],
    problems: &mut Vec<String>,
) {
    let names: Vec<&str> = actual.iter().map(|o| o.name.as_str()).collect();
    for d in declared {
        let Some(a) = actual.iter().find(|o| o.name == d.name) else {
            problems.push(format!(
                "{model}: {kind} '{}' is declared but the file has {names:?}",
                d.name
            ));
            continue;
        };
        let (Some(ty), shape) = (a.dtype, &a.shape) else {
            problems.push(format!(
                "{model}: {kind} '{}' is not a tensor in the file",
                d.name
            ));
            continue;
        };
        if ty != d.dtype {
            problems.push(format!(
                "{model}: {kind} '{}' is {ty} in the file, declared {}",
                d.name, d.dtype
            ));
        }
        if shape.len() != d.shape.len() {
            problems.push(format!(
                "{model}: {kind} '{}' has rank {} in the file ({shape:?}), declared {} ({:?})",
                d.name,
                shape.len(),
                d.shape.len(),
                d.shape
            ));
            continue;
        }
        for (i, (fd, dd)) in shape.iter().zip(&d.shape).enumerate() {
            if let Dim::Fixed(v) = dd {
                if *fd >= 0 && fd != v {
                    problems.push(format!(
                        "{model}: {kind} '{}' dim {i} is {fd} in the file, declared {v}",
                        d.name
                    ));
                }
            }
        }
    }
    for a in actual {
        if !declared.iter().any(|d| d.name == a.name) {
            problems.push(format!(
                "{model}: the file has {kind} '{}' that the manifest does not declare",
                a.name
            ));
        }
    }
}

/// The clip the preprocessing makes must be the one the encoder declares: `clip` is
/// [batch, clip_frames, 3, size, size] and `background` [batch, 3, size, size] (fixed dimensions
/// only; a symbolic one matches anything). Checked when the bundle opens, so a mismatch is one
/// line at load instead of an ONNX Runtime error on every episode (and, for a large `size`, a
/// large allocation per episode first). One line per mismatch.
fn encoder_input_problems(m: &Manifest) -> Vec<String> {
    let Some(enc) = m.models.get("encoder") else {
        return Vec::new();
    };
    let (t, s) = (
        i64::from(m.preprocess.clip_frames),
        i64::from(m.preprocess.size),
    );
    let want: [(&str, Vec<Option<i64>>); 2] = [
        ("clip", vec![None, Some(t), Some(3), Some(s), Some(s)]),
        ("background", vec![None, Some(3), Some(s), Some(s)]),
    ];
    let mut problems = Vec::new();
    for (i, (role, dims)) in want.iter().enumerate() {
        let Some(spec) = enc.inputs.get(i) else {
            problems.push(format!("encoder has no input {} ({role})", i + 1));
            continue;
        };
        let fits = spec.shape.len() == dims.len()
            && spec.shape.iter().zip(dims).all(|(d, w)| match (d, w) {
                (Dim::Fixed(d), Some(w)) => d == w,
                _ => true,
            });
        if !fits {
            let shape: Vec<String> = spec
                .shape
                .iter()
                .map(|d| match d {
                    Dim::Fixed(v) => v.to_string(),
                    Dim::Symbolic(n) => n.clone(),
                })
                .collect();
            problems.push(format!(
                "encoder input '{}' is [{}], preprocess (clip_frames {t}, size {s}) makes [{}]",
                spec.name,
                shape.join(", "),
                dims.iter()
                    .map(|d| d.map_or("batch".to_string(), |v| v.to_string()))
                    .collect::<Vec<_>>()
                    .join(", ")
            ));
        }
    }
    problems
}

impl Bundle {
    pub fn open(dir: &Path) -> Result<Bundle, InferError> {
        let err = |msg: String| InferError::Bundle {
            dir: dir.to_path_buf(),
            msg,
        };
        let path = dir.join("manifest.json");
        let meta = std::fs::metadata(&path).map_err(|e| err(format!("manifest.json: {e}")))?;
        if meta.len() > MAX_MANIFEST_BYTES {
            return Err(err(format!(
                "manifest.json is {} bytes, more than {MAX_MANIFEST_BYTES}",
                meta.len()
            )));
        }
        let text =
            std::fs::read_to_string(&path).map_err(|e| err(format!("manifest.json: {e}")))?;
        let manifest: Manifest =
            serde_json::from_str(&text).map_err(|e| err(format!("manifest.json: {e}")))?;
        manifest
            .preprocess
            .check()
            .map_err(|e| err(e.to_string()))?;
        let problems = encoder_input_problems(&manifest);
        if !problems.is_empty() {
            return Err(err(format!("manifest.json: {}", problems.join("; "))));
        }
        Ok(Bundle {
            dir: dir.to_path_buf(),
            manifest,
        })
    }

    /// Load and check the named models. All problems of all of them come back in one error.
    pub fn load(&self, names: &[&str], cfg: &RuntimeConfig) -> Result<Vec<Model>, InferError> {
        let mut problems = Vec::new();
        let mut out = Vec::new();
        for &name in names {
            let Some(spec) = self.manifest.models.get(name) else {
                problems.push(format!(
                    "{name}: not in the manifest (it has {:?})",
                    self.manifest.models.keys().collect::<Vec<_>>()
                ));
                continue;
            };
            let path = self.dir.join(&spec.file);
            if !path.is_file() {
                problems.push(format!("{name}: file not found: {}", path.display()));
                continue;
            }
            match sha256_file(&path) {
                Ok(h) if h.eq_ignore_ascii_case(&spec.sha256) => {}
                Ok(h) => {
                    problems.push(format!(
                        "{name}: sha256 of {} is {h}, the manifest says {}",
                        spec.file, spec.sha256
                    ));
                    continue;
                }
                Err(e) => {
                    problems.push(format!("{name}: {}: {e}", path.display()));
                    continue;
                }
            }
            let session = match Session::open(name, &path, cfg) {
                Ok(s) => s,
                Err(InferError::Library(e)) => return Err(InferError::Library(e)),
                Err(e) => {
                    problems.push(e.to_string());
                    continue;
                }
            };
            let before = problems.len();
            check_io(name, "input", &spec.inputs, session.inputs(), &mut problems);
            check_io(
                name,
                "output",
                &spec.outputs,
                session.outputs(),
                &mut problems,
            );
            if problems.len() == before {
                let id = format!(
                    "{}@{}",
                    self.manifest.bundle,
                    spec.sha256.get(..8).unwrap_or(&spec.sha256)
                );
                out.push(Model {
                    name: name.to_string(),
                    spec: spec.clone(),
                    id,
                    session,
                });
            }
        }
        if problems.is_empty() {
            Ok(out)
        } else {
            Err(InferError::Bundle {
                dir: self.dir.clone(),
                msg: problems.join("; "),
            })
        }
    }
}

impl Model {
    /// Run with float32 inputs given in the manifest's input order as (shape, data); returns
    /// float32 outputs in the manifest's output order as (shape, data). Output sizes are bounded.
    /// The execution provider the model runs on.
    pub fn provider(&self) -> crate::runtime::ExecutionProvider {
        self.session.provider()
    }
    pub fn run(&mut self, inputs: &[(&[i64], &[f32])]) -> Result<Vec<TensorF32>, InferError> {
        if inputs.len() != self.spec.inputs.len() {
            return Err(InferError::Model {
                model: self.name.clone(),
                msg: format!(
                    "{} inputs given, {} declared",
                    inputs.len(),
                    self.spec.inputs.len()
                ),
            });
        }
        let named: Vec<(&str, &[i64], &[f32])> = self
            .spec
            .inputs
            .iter()
            .zip(inputs)
            .map(|(spec, (shape, data))| (spec.name.as_str(), *shape, *data))
            .collect();
        let outputs: Vec<&str> = self.spec.outputs.iter().map(|o| o.name.as_str()).collect();
        self.session.run_f32(&named, &outputs)
    }
}
