//! Load-time validation: the manifest against itself and against the ONNX model's real inputs
//! and outputs (names, element types, shapes as ONNX Runtime reports them).
//!
//! Every problem is collected as one [`Mismatch`]; the loader reports them all in one error, so a
//! user fixing an exported policy sees the whole list at once. Validation also resolves what the
//! runtime needs (normalisation in float32, feed shapes, bounds), so what was checked is exactly
//! what runs.

use super::manifest::{OutputSpec, PolicyManifest};
use super::normalize::Norm;
use unitac_infer::bundle::Dim;
use unitac_infer::runtime::TensorInfo;

/// Largest input feature \[elements, batch excluded] (a 3 x 480 x 640 image is 0.9 M).
pub const MAX_INPUT_ELEMENTS: usize = 1 << 22;
/// Most inputs a policy may declare.
pub const MAX_INPUTS: usize = 64;
/// Longest action chunk \[rows].
pub const MAX_CHUNK_SIZE: usize = 1024;
/// Most actions per row.
pub const MAX_ACTIONS: usize = 256;
/// The control rate's range \[Hz], the scene's.
pub use crate::params::{MAX_CONTROL_RATE_HZ, MIN_CONTROL_RATE_HZ};
/// The smallest std and min-max range a normalisation may divide by: float32's smallest
/// normal number (a subnormal one, e.g. 1e-45, passes "> 0" and overflows every input).
pub const MIN_SCALE: f32 = f32::MIN_POSITIVE;

/// One problem found at load.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Mismatch {
    #[error("{file}: {msg}")]
    File { file: String, msg: String },
    #[error("{file}: sha256 is {actual}, the manifest says {declared}")]
    Sha256 {
        file: String,
        actual: String,
        declared: String,
    },
    #[error("input '{name}' is declared but the model has {model_has:?}")]
    MissingInput {
        name: String,
        model_has: Vec<String>,
    },
    #[error("the model has input '{name}' that the manifest does not declare")]
    ExtraInput { name: String },
    #[error("output '{name}' is declared but the model has {model_has:?}")]
    MissingOutput {
        name: String,
        model_has: Vec<String>,
    },
    #[error("the model has output '{name}' that the manifest does not declare")]
    ExtraOutput { name: String },
    #[error("{what} '{name}' is declared more than once")]
    Duplicate { what: &'static str, name: String },
    #[error("{tensor}: dtype '{dtype}' is not supported (float32)")]
    UnsupportedDtype { tensor: String, dtype: String },
    #[error("{tensor}: the model's dtype is {model}, the manifest says {declared}")]
    Dtype {
        tensor: String,
        model: String,
        declared: String,
    },
    #[error(
        "{tensor}: the model's rank is {model} ({model_shape:?}), the manifest says {declared}"
    )]
    Rank {
        tensor: String,
        model: usize,
        declared: usize,
        model_shape: Vec<i64>,
    },
    #[error("{tensor}: dim {index} is {model} in the model, the manifest says {declared}")]
    Dim {
        tensor: String,
        index: usize,
        model: i64,
        declared: i64,
    },
    #[error("{tensor}: shape {msg}")]
    Shape { tensor: String, msg: String },
    #[error("{tensor}: no normalization (state mode mean_std, min_max or identity)")]
    MissingNormalization { tensor: String },
    #[error("{tensor}: normalization mode '{mode}' is not mean_std, min_max or identity")]
    UnknownMode { tensor: String, mode: String },
    #[error("{tensor}: normalization {mode} needs '{stat}'")]
    MissingStat {
        tensor: String,
        mode: &'static str,
        stat: &'static str,
    },
    #[error("{tensor}: '{stat}' has {len} values, the feature needs {expected}")]
    StatLength {
        tensor: String,
        stat: &'static str,
        len: usize,
        expected: String,
    },
    #[error("{tensor}: {stat}[{index}] = {value:e} is not a finite float32")]
    NonFiniteStat {
        tensor: String,
        stat: &'static str,
        index: usize,
        value: f64,
    },
    #[error(
        "{tensor}: std[{index}] = {value:e} must be >= {:e} (float32's smallest normal)",
        MIN_SCALE
    )]
    StdNotPositive {
        tensor: String,
        index: usize,
        value: f64,
    },
    #[error("{tensor}: min[{index}] = {min} and max[{index}] = {max} leave no range")]
    EmptyRange {
        tensor: String,
        index: usize,
        min: f64,
        max: f64,
    },
    #[error("action '{action}': bounds [{min}, {max}] must be finite float32 with min < max")]
    Bounds { action: String, min: f64, max: f64 },
    #[error("action {index}: {msg}")]
    Action { index: usize, msg: String },
    #[error("{tensor}: chunk_size is {declared}, {by} {found} rows")]
    Horizon {
        tensor: String,
        declared: usize,
        by: &'static str,
        found: i64,
    },
    #[error("{tensor}: {declared} actions are named, {by} {found} per row")]
    ActionCount {
        tensor: String,
        declared: usize,
        by: &'static str,
        found: i64,
    },
    #[error("chunk_size {0} must be 1..={MAX_CHUNK_SIZE}")]
    ChunkSize(usize),
    #[error("n_action_steps {steps} must be 1..=chunk_size ({chunk_size})")]
    ActionSteps { steps: usize, chunk_size: usize },
    #[error(
        "control_rate_hz {0} must be finite and within [{MIN_CONTROL_RATE_HZ}, {MAX_CONTROL_RATE_HZ}]"
    )]
    ControlRate(f64),
    #[error("temporal_ensemble_coeff {0} must be finite and >= 0")]
    EnsembleCoeff(f64),
    #[error("{0} actions declared, must be 1..={MAX_ACTIONS}")]
    Actions(usize),
    #[error("{0} inputs declared, at most {MAX_INPUTS}")]
    TooManyInputs(usize),
}

/// A checked input: what the runtime feeds.
#[derive(Debug, Clone)]
pub(crate) struct ResolvedInput {
    pub name: String,
    /// Feed shape (batch 1).
    pub shape: Vec<i64>,
    pub numel: usize,
    pub norm: Norm,
}

/// The checked output.
#[derive(Debug, Clone)]
pub(crate) struct ResolvedOutput {
    pub name: String,
    pub horizon: usize,
    pub names: Vec<String>,
    pub units: Vec<String>,
    pub norm: Norm,
    pub lo: Vec<f32>,
    pub hi: Vec<f32>,
}

#[derive(Debug, Clone)]
pub(crate) struct Resolved {
    pub inputs: Vec<ResolvedInput>,
    pub output: ResolvedOutput,
}

fn dims_text(shape: &[Dim]) -> String {
    let v: Vec<String> = shape
        .iter()
        .map(|d| match d {
            Dim::Fixed(v) => v.to_string(),
            Dim::Symbolic(s) => s.clone(),
        })
        .collect();
    format!("[{}]", v.join(", "))
}

/// The manifest's shape rules: batch first (symbolic or 1), every other dimension fixed and
/// positive, at most `max` elements. Returns the feed shape and the element count.
fn feed_shape(
    tensor: &str,
    shape: &[Dim],
    max: usize,
    problems: &mut Vec<Mismatch>,
) -> Option<(Vec<i64>, usize)> {
    let bad = |msg: String| Mismatch::Shape {
        tensor: tensor.to_string(),
        msg: format!("{} {msg}", dims_text(shape)),
    };
    let Some((batch, rest)) = shape.split_first() else {
        problems.push(bad("has no batch dimension".into()));
        return None;
    };
    if rest.is_empty() {
        problems.push(bad("has only a batch dimension".into()));
        return None;
    }
    let mut ok = true;
    if let Dim::Fixed(b) = batch {
        if *b != 1 {
            problems.push(bad(format!("has batch {b}; the runtime feeds 1")));
            ok = false;
        }
    }
    let mut feed = vec![1i64];
    let mut numel: usize = 1;
    for (i, d) in rest.iter().enumerate() {
        match d {
            Dim::Fixed(v) if *v > 0 => {
                feed.push(*v);
                numel = numel.saturating_mul(usize::try_from(*v).unwrap_or(usize::MAX));
            }
            Dim::Fixed(v) => {
                problems.push(bad(format!("dim {} is {v}, must be > 0", i + 1)));
                ok = false;
            }
            Dim::Symbolic(s) => {
                problems.push(bad(format!(
                    "dim {} is symbolic ('{s}'); only the batch dimension may be",
                    i + 1
                )));
                ok = false;
            }
        }
    }
    if ok && numel > max {
        problems.push(bad(format!("has {numel} elements, at most {max}")));
        ok = false;
    }
    ok.then_some((feed, numel))
}

/// Compare a declared tensor with the model's.
fn check_tensor(
    tensor: &str,
    dtype: &str,
    shape: &[Dim],
    actual: &TensorInfo,
    problems: &mut Vec<Mismatch>,
) {
    match actual.dtype {
        None => problems.push(Mismatch::Dtype {
            tensor: tensor.to_string(),
            model: "not a tensor".into(),
            declared: dtype.to_string(),
        }),
        Some(t) if t != dtype => problems.push(Mismatch::Dtype {
            tensor: tensor.to_string(),
            model: t.to_string(),
            declared: dtype.to_string(),
        }),
        Some(_) => {}
    }
    if actual.dtype.is_none() {
        return;
    }
    if actual.shape.len() != shape.len() {
        problems.push(Mismatch::Rank {
            tensor: tensor.to_string(),
            model: actual.shape.len(),
            declared: shape.len(),
            model_shape: actual.shape.clone(),
        });
        return;
    }
    for (index, (&m, d)) in actual.shape.iter().zip(shape).enumerate() {
        // The runtime feeds batch 1 where the manifest leaves the batch symbolic.
        let declared = match d {
            Dim::Fixed(v) => *v,
            Dim::Symbolic(_) if index == 0 => 1,
            Dim::Symbolic(_) => continue,
        };
        if m >= 0 && m != declared {
            problems.push(Mismatch::Dim {
                tensor: tensor.to_string(),
                index,
                model: m,
                declared,
            });
        }
    }
}

fn check_config(m: &PolicyManifest, problems: &mut Vec<Mismatch>) {
    if m.chunk_size == 0 || m.chunk_size > MAX_CHUNK_SIZE {
        problems.push(Mismatch::ChunkSize(m.chunk_size));
    }
    if m.n_action_steps == 0 || m.n_action_steps > m.chunk_size {
        problems.push(Mismatch::ActionSteps {
            steps: m.n_action_steps,
            chunk_size: m.chunk_size,
        });
    }
    let r = m.control_rate_hz;
    if !(r.is_finite() && (MIN_CONTROL_RATE_HZ..=MAX_CONTROL_RATE_HZ).contains(&r)) {
        problems.push(Mismatch::ControlRate(r));
    }
    if let Some(c) = m.temporal_ensemble_coeff {
        if !(c.is_finite() && c >= 0.0) {
            problems.push(Mismatch::EnsembleCoeff(c));
        }
    }
    if m.inputs.len() > MAX_INPUTS {
        problems.push(Mismatch::TooManyInputs(m.inputs.len()));
    }
}

/// The model's action output against `[1, chunk_size, A]` and float32.
fn check_action_tensor(m: &PolicyManifest, t: &TensorInfo, problems: &mut Vec<Mismatch>) {
    let o = &m.output;
    if t.dtype != Some(o.dtype.as_str()) {
        problems.push(Mismatch::Dtype {
            tensor: o.name.clone(),
            model: t.dtype.unwrap_or("not a tensor").to_string(),
            declared: o.dtype.clone(),
        });
    }
    let [b, h, a] = t.shape[..] else {
        if t.dtype.is_some() {
            problems.push(Mismatch::Rank {
                tensor: o.name.clone(),
                model: t.shape.len(),
                declared: 3,
                model_shape: t.shape.clone(),
            });
        }
        return;
    };
    if h >= 0 && h != m.chunk_size as i64 {
        problems.push(Mismatch::Horizon {
            tensor: o.name.clone(),
            declared: m.chunk_size,
            by: "the model predicts",
            found: h,
        });
    }
    if a >= 0 && a != o.actions.len() as i64 {
        problems.push(Mismatch::ActionCount {
            tensor: o.name.clone(),
            declared: o.actions.len(),
            by: "the model predicts",
            found: a,
        });
    }
    if b >= 0 && b != 1 {
        problems.push(Mismatch::Dim {
            tensor: o.name.clone(),
            index: 0,
            model: b,
            declared: 1,
        });
    }
}

fn check_output(
    m: &PolicyManifest,
    model_outputs: Option<&[TensorInfo]>,
    problems: &mut Vec<Mismatch>,
) -> Option<ResolvedOutput> {
    let o: &OutputSpec = &m.output;
    let start = problems.len();
    if o.dtype != "float32" {
        problems.push(Mismatch::UnsupportedDtype {
            tensor: o.name.clone(),
            dtype: o.dtype.clone(),
        });
    }
    let a = o.actions.len();
    if a == 0 || a > MAX_ACTIONS {
        problems.push(Mismatch::Actions(a));
    }
    // The manifest's own shape must be [batch, chunk_size, A].
    if o.shape.len() != 3 {
        problems.push(Mismatch::Shape {
            tensor: o.name.clone(),
            msg: format!(
                "{} must be [batch, chunk_size, actions]",
                dims_text(&o.shape)
            ),
        });
    } else {
        if let Dim::Fixed(h) = o.shape[1] {
            if h != m.chunk_size as i64 {
                problems.push(Mismatch::Horizon {
                    tensor: o.name.clone(),
                    declared: m.chunk_size,
                    by: "the manifest's shape has",
                    found: h,
                });
            }
        }
        if let Dim::Fixed(n) = o.shape[2] {
            if n != a as i64 {
                problems.push(Mismatch::ActionCount {
                    tensor: o.name.clone(),
                    declared: a,
                    by: "the manifest's shape has",
                    found: n,
                });
            }
        }
        if let Dim::Fixed(b) = o.shape[0] {
            if b != 1 {
                problems.push(Mismatch::Shape {
                    tensor: o.name.clone(),
                    msg: format!("{} has batch {b}; the runtime feeds 1", dims_text(&o.shape)),
                });
            }
        }
    }
    if let Some(outs) = model_outputs {
        match outs.iter().find(|t| t.name == o.name) {
            None => problems.push(Mismatch::MissingOutput {
                name: o.name.clone(),
                model_has: outs.iter().map(|t| t.name.clone()).collect(),
            }),
            Some(t) => check_action_tensor(m, t, problems),
        }
        for t in outs {
            if t.name != o.name {
                problems.push(Mismatch::ExtraOutput {
                    name: t.name.clone(),
                });
            }
        }
    }
    let mut lo = Vec::with_capacity(a);
    let mut hi = Vec::with_capacity(a);
    let mut names: Vec<String> = Vec::with_capacity(a);
    for (index, act) in o.actions.iter().enumerate() {
        if act.name.is_empty() {
            problems.push(Mismatch::Action {
                index,
                msg: "has no name".into(),
            });
        } else if names.contains(&act.name) {
            problems.push(Mismatch::Duplicate {
                what: "action",
                name: act.name.clone(),
            });
        }
        if act.unit.is_empty() {
            problems.push(Mismatch::Action {
                index,
                msg: format!("'{}' has no unit (SI, e.g. m, m/s, N)", act.name),
            });
        }
        let (l, h) = (act.min as f32, act.max as f32);
        if !(l.is_finite() && h.is_finite() && l < h) {
            problems.push(Mismatch::Bounds {
                action: act.name.clone(),
                min: act.min,
                max: act.max,
            });
        }
        names.push(act.name.clone());
        lo.push(l);
        hi.push(h);
    }
    let norm = Norm::resolve(&o.name, o.normalization.as_ref(), a, a, problems);
    if problems.len() != start {
        return None;
    }
    Some(ResolvedOutput {
        name: o.name.clone(),
        horizon: m.chunk_size,
        names,
        units: o.actions.iter().map(|x| x.unit.clone()).collect(),
        norm: norm?,
        lo,
        hi,
    })
}

/// Check `m` against itself and, when the model opened, against its real inputs and outputs.
/// All problems come back together.
pub(crate) fn validate(
    m: &PolicyManifest,
    model: Option<(&[TensorInfo], &[TensorInfo])>,
) -> Result<Resolved, Vec<Mismatch>> {
    let mut problems = Vec::new();
    check_config(m, &mut problems);
    let mut inputs = Vec::with_capacity(m.inputs.len());
    for (i, spec) in m.inputs.iter().enumerate() {
        let start = problems.len();
        if m.inputs[..i].iter().any(|s| s.name == spec.name) {
            problems.push(Mismatch::Duplicate {
                what: "input",
                name: spec.name.clone(),
            });
        }
        if spec.dtype != "float32" {
            problems.push(Mismatch::UnsupportedDtype {
                tensor: spec.name.clone(),
                dtype: spec.dtype.clone(),
            });
        }
        let feed = feed_shape(&spec.name, &spec.shape, MAX_INPUT_ELEMENTS, &mut problems);
        if let Some((ins, _)) = model {
            match ins.iter().find(|t| t.name == spec.name) {
                None => problems.push(Mismatch::MissingInput {
                    name: spec.name.clone(),
                    model_has: ins.iter().map(|t| t.name.clone()).collect(),
                }),
                Some(t) => check_tensor(&spec.name, &spec.dtype, &spec.shape, t, &mut problems),
            }
        }
        // Statistics are checked against the feature's size; with no valid shape only their
        // presence is.
        let norm = match &feed {
            Some((shape, numel)) => Norm::resolve(
                &spec.name,
                spec.normalization.as_ref(),
                *numel,
                shape.get(1).map_or(1, |&c| c as usize),
                &mut problems,
            ),
            None => {
                if spec.normalization.is_none() {
                    problems.push(Mismatch::MissingNormalization {
                        tensor: spec.name.clone(),
                    });
                }
                None
            }
        };
        if let (Some((shape, numel)), Some(norm), true) = (feed, norm, problems.len() == start) {
            inputs.push(ResolvedInput {
                name: spec.name.clone(),
                shape,
                numel,
                norm,
            });
        }
    }
    if let Some((ins, _)) = model {
        for t in ins {
            if !m.inputs.iter().any(|s| s.name == t.name) {
                problems.push(Mismatch::ExtraInput {
                    name: t.name.clone(),
                });
            }
        }
    }
    let output = check_output(m, model.map(|(_, o)| o), &mut problems);
    match output {
        Some(output) if problems.is_empty() => Ok(Resolved { inputs, output }),
        _ => Err(problems),
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
    use super::*;
    use crate::onnx::manifest::PolicyManifest;

    /// A valid two-input manifest and the model metadata that matches it.
    fn manifest() -> PolicyManifest {
        PolicyManifest::parse(
            r#"{"policy": "p", "file": "p.onnx", "sha256": "00", "control_rate_hz": 30,
                "chunk_size": 4, "n_action_steps": 2,
                "inputs": [
                  {"name": "observation.state", "dtype": "float32", "shape": ["batch", 2],
                   "normalization": {"mode": "mean_std", "mean": [0, 0], "std": [1, 1]}},
                  {"name": "observation.images.cam", "dtype": "float32", "shape": [1, 3, 2, 2],
                   "normalization": {"mode": "identity"}}],
                "output": {"name": "action", "dtype": "float32", "shape": ["batch", 4, 1],
                  "normalization": {"mode": "min_max", "min": [-1], "max": [1]},
                  "actions": [{"name": "gripper.opening", "unit": "m", "min": 0, "max": 0.085}]}}"#,
        )
        .unwrap()
    }

    fn info(name: &str, shape: &[i64]) -> TensorInfo {
        TensorInfo {
            name: name.into(),
            dtype: Some("float32"),
            shape: shape.to_vec(),
        }
    }

    fn model() -> (Vec<TensorInfo>, Vec<TensorInfo>) {
        (
            vec![
                info("observation.state", &[-1, 2]),
                info("observation.images.cam", &[-1, 3, 2, 2]),
            ],
            vec![info("action", &[-1, 4, 1])],
        )
    }

    fn problems(m: &PolicyManifest, io: &(Vec<TensorInfo>, Vec<TensorInfo>)) -> Vec<Mismatch> {
        validate(m, Some((&io.0, &io.1))).err().unwrap_or_default()
    }

    #[test]
    fn a_matching_manifest_resolves_feed_shapes_and_bounds() {
        let r = validate(&manifest(), Some((&model().0, &model().1))).unwrap();
        assert_eq!(r.inputs[1].shape, [1, 3, 2, 2]);
        assert_eq!(r.inputs[1].numel, 12);
        assert_eq!(r.output.horizon, 4);
        assert_eq!(r.output.hi, [0.085]);
        // Without a model only the manifest's own rules are checked.
        assert!(validate(&manifest(), None).is_ok());
    }

    #[test]
    fn schedule_and_rate_rules() {
        let mut m = manifest();
        m.chunk_size = 0;
        m.n_action_steps = 0;
        m.control_rate_hz = f64::INFINITY;
        m.temporal_ensemble_coeff = Some(-0.1);
        let p = problems(&m, &model());
        assert!(p.contains(&Mismatch::ChunkSize(0)));
        assert!(p.contains(&Mismatch::ActionSteps {
            steps: 0,
            chunk_size: 0
        }));
        assert!(p.contains(&Mismatch::ControlRate(f64::INFINITY)));
        assert!(p.contains(&Mismatch::EnsembleCoeff(-0.1)));
        let mut m = manifest();
        m.control_rate_hz = 0.0;
        m.n_action_steps = 5;
        let p = problems(&m, &model());
        assert_eq!(
            p,
            [
                Mismatch::ActionSteps {
                    steps: 5,
                    chunk_size: 4
                },
                Mismatch::ControlRate(0.0)
            ]
        );
    }

    #[test]
    fn shape_rules_of_the_manifest() {
        let mut m = manifest();
        m.inputs[0].shape = vec![Dim::Fixed(2), Dim::Fixed(2)];
        m.inputs[1].shape = vec![
            Dim::Symbolic("batch".into()),
            Dim::Symbolic("c".into()),
            Dim::Fixed(0),
            Dim::Fixed(2),
        ];
        let p = problems(&m, &model());
        let shape_msgs: Vec<&str> = p
            .iter()
            .filter_map(|x| match x {
                Mismatch::Shape { msg, .. } => Some(msg.as_str()),
                _ => None,
            })
            .collect();
        assert!(shape_msgs.iter().any(|s| s.contains("batch 2")), "{p:?}");
        assert!(shape_msgs.iter().any(|s| s.contains("symbolic")), "{p:?}");
        assert!(shape_msgs.iter().any(|s| s.contains("dim 2 is 0")), "{p:?}");
        let mut m = manifest();
        m.inputs[0].shape = vec![
            Dim::Symbolic("batch".into()),
            Dim::Fixed(1 << 12),
            Dim::Fixed(1 << 11),
        ];
        let p = problems(&m, &model());
        assert!(
            p.iter()
                .any(|x| matches!(x, Mismatch::Shape { msg, .. } if msg.contains("at most"))),
            "{p:?}"
        );
    }

    #[test]
    fn names_units_and_counts() {
        let mut m = manifest();
        m.inputs.push(m.inputs[0].clone());
        m.output.actions.push(m.output.actions[0].clone());
        m.output.actions.push(m.output.actions[0].clone());
        m.output.actions[2].name = String::new();
        m.output.actions[2].unit = String::new();
        let p = problems(&m, &model());
        assert!(p.contains(&Mismatch::Duplicate {
            what: "input",
            name: "observation.state".into()
        }));
        assert!(p.contains(&Mismatch::Duplicate {
            what: "action",
            name: "gripper.opening".into()
        }));
        assert!(
            p.iter().any(
                |x| matches!(x, Mismatch::Action { index: 2, msg } if msg.contains("no name"))
            )
        );
        assert!(
            p.iter().any(
                |x| matches!(x, Mismatch::Action { index: 2, msg } if msg.contains("no unit"))
            )
        );
        let mut m = manifest();
        m.output.actions.clear();
        let p = problems(&m, &model());
        assert!(p.contains(&Mismatch::Actions(0)));
        let mut m = manifest();
        m.inputs = (0..65).map(|_| manifest().inputs[0].clone()).collect();
        assert!(problems(&m, &model()).contains(&Mismatch::TooManyInputs(65)));
    }

    #[test]
    fn model_side_types_and_batch() {
        let mut io = model();
        io.0[1].dtype = None;
        io.1[0].shape = vec![2, 4, 1];
        io.0[0].shape = vec![3, 2];
        let p = problems(&manifest(), &io);
        assert!(p.contains(&Mismatch::Dtype {
            tensor: "observation.images.cam".into(),
            model: "not a tensor".into(),
            declared: "float32".into()
        }));
        assert!(p.contains(&Mismatch::Dim {
            tensor: "action".into(),
            index: 0,
            model: 2,
            declared: 1
        }));
        assert!(p.contains(&Mismatch::Dim {
            tensor: "observation.state".into(),
            index: 0,
            model: 3,
            declared: 1
        }));
        let mut io = model();
        io.1[0].shape = vec![-1, 4];
        let p = problems(&manifest(), &io);
        assert_eq!(
            p,
            [Mismatch::Rank {
                tensor: "action".into(),
                model: 2,
                declared: 3,
                model_shape: vec![-1, 4]
            }]
        );
        // Dynamic horizon and action dims in the model are accepted (checked per run).
        let mut io = model();
        io.1[0].shape = vec![-1, -1, -1];
        assert!(problems(&manifest(), &io).is_empty());
    }
}
