//! The latent -> stiffness readout of the controllers (the cup's force, fabric vtla_pred's press
//! force): the linear one of the params (`stiffness_bias_n_per_m + stiffness_weights . mean
//! over the leading dimension`), or a fitted ONNX model the scene names (a policy bundle of
//! [`crate::onnx`] with one input `observation.tactile_latent` of `latent_len` values and one
//! action `cup.stiffness` in N/m; python/unitac_tools/fit_reference_policy.py exports them). Either way the
//! result is clamped to [`min_stiffness_n_per_m`, `max_stiffness_n_per_m`], and a reading that
//! lay outside (the model's own bounds or the params' range) is reported as clipped: a reading at
//! a bound says the latent lies where the readout cannot tell, never a stiffness.
//!
//! [`min_stiffness_n_per_m`]: crate::PolicyParams::min_stiffness_n_per_m
//! [`max_stiffness_n_per_m`]: crate::PolicyParams::max_stiffness_n_per_m

use crate::error::PolicyLoadError;
use crate::onnx::{NamedInputs, OnnxPolicy, RuntimeConfig};
use crate::params::PolicyParams;
use crate::policy::PolicyError;
use std::path::Path;
use unitac_core::Stamp;
use unitac_core::msg::TactileLatent;
use unitac_infer::bundle::Dim;

/// The model's one input and one action (schema/policy.json).
pub use crate::schema::{STIFFNESS_ACTION, STIFFNESS_INPUT, STIFFNESS_UNIT};

/// Where the stiffness comes from.
#[derive(Debug, Default)]
pub enum Readout {
    /// The params' bias and weights.
    #[default]
    Linear,
    /// A fitted ONNX model (its manifest's name in messages).
    Model(Box<OnnxPolicy>),
}

impl Readout {
    /// Load the stiffness model in `dir` for latents of `latent_len` values: every problem (the
    /// bundle's own, checked by [`OnnxPolicy::load`], and this readout's: the input, the action
    /// and its unit) in one error.
    pub fn load(dir: &Path, latent_len: usize) -> Result<Readout, PolicyLoadError> {
        let fail = |problems: Vec<String>| PolicyLoadError::StiffnessModel {
            dir: dir.to_path_buf(),
            problems,
        };
        let policy = OnnxPolicy::load(dir, &RuntimeConfig::default()).map_err(|e| {
            fail(vec![
                e.to_string()
                    .split_whitespace()
                    .collect::<Vec<_>>()
                    .join(" "),
            ])
        })?;
        let m = policy.manifest();
        let mut bad = Vec::new();
        match m.inputs.as_slice() {
            [i] if i.name == STIFFNESS_INPUT => {
                let len: Option<i64> = i.shape.iter().skip(1).try_fold(1i64, |n, d| match d {
                    Dim::Fixed(v) => n.checked_mul(*v),
                    Dim::Symbolic(_) => None,
                });
                if len != i64::try_from(latent_len).ok() {
                    bad.push(format!(
                        "input {STIFFNESS_INPUT} has {} values, the scene's latent_len is {latent_len}",
                        len.map_or("a symbolic number of".into(), |n| n.to_string())
                    ));
                }
            }
            other => bad.push(format!(
                "inputs are {:?}, a stiffness model has one: {STIFFNESS_INPUT}",
                other.iter().map(|i| i.name.as_str()).collect::<Vec<_>>()
            )),
        }
        match m.output.actions.as_slice() {
            [a] if a.name == STIFFNESS_ACTION && a.unit == STIFFNESS_UNIT => {}
            other => bad.push(format!(
                "actions are {:?}, a stiffness model has one: {STIFFNESS_ACTION} in {STIFFNESS_UNIT}",
                other
                    .iter()
                    .map(|a| format!("{} [{}]", a.name, a.unit))
                    .collect::<Vec<_>>()
            )),
        }
        if bad.is_empty() {
            Ok(Readout::Model(Box::new(policy)))
        } else {
            Err(fail(bad))
        }
    }

    /// The stiffness \[N/m] the latent says, at `now` (the model is asked afresh each time),
    /// clamped to the params' range, and whether it was clipped: the raw readout lay outside
    /// that range, or outside the model's bounds (the bundle clamps its action to them).
    pub fn stiffness(
        &mut self,
        p: &PolicyParams,
        latent: &TactileLatent,
        now: Stamp,
    ) -> Result<(f64, bool), PolicyError> {
        let mut clipped = false;
        let k = match self {
            Readout::Linear => linear(p, latent)?,
            Readout::Model(m) => {
                m.reset();
                let chunk = m
                    .act(&NamedInputs::new().with(STIFFNESS_INPUT, &latent.data), now)
                    .map_err(|e| PolicyError::Failed(format!("stiffness model {}: {e}", m.id())))?;
                clipped = chunk.clamped > 0;
                chunk
                    .now(STIFFNESS_ACTION)
                    .map(f64::from)
                    .ok_or_else(|| PolicyError::Failed("stiffness model: no action".into()))?
            }
        };
        if !k.is_finite() {
            return Err(PolicyError::Failed(
                "stiffness readout is not finite".into(),
            ));
        }
        let (lo, hi) = (p.min_stiffness_n_per_m, p.max_stiffness_n_per_m);
        Ok((k.clamp(lo, hi), clipped || k < lo || k > hi))
    }
}

/// `bias + weights . mean over the leading dimension`; empty weights leave the bias, a prior,
/// and the latent only has to be valid.
fn linear(p: &PolicyParams, latent: &TactileLatent) -> Result<f64, PolicyError> {
    let mut k = p.stiffness_bias_n_per_m;
    if !p.stiffness_weights.is_empty() {
        let dim = latent.shape.last().copied().unwrap_or(0) as usize;
        if dim != p.stiffness_weights.len() || dim == 0 || latent.data.len() % dim != 0 {
            return Err(PolicyError::Failed(format!(
                "stiffness_weights has {} values, the latent's last dimension is {dim}",
                p.stiffness_weights.len()
            )));
        }
        let rows = (latent.data.len() / dim) as f64;
        for (j, w) in p.stiffness_weights.iter().enumerate() {
            let mean: f64 = latent
                .data
                .iter()
                .skip(j)
                .step_by(dim)
                .map(|&v| f64::from(v))
                .sum::<f64>()
                / rows;
            k += w * mean;
        }
    }
    Ok(k)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use unitac_core::msg::samples;

    fn k(p: &PolicyParams, l: &TactileLatent) -> Result<f64, PolicyError> {
        Readout::Linear.stiffness(p, l, Stamp::ZERO).map(|(k, _)| k)
    }

    #[test]
    fn linear_readout_pools_the_leading_dimension() {
        let mut p = PolicyParams::default();
        let l = samples::tactile_latent(); // [2, 3]: rows (0.5, -1, 2.25), (3, -0.125, 8)
        assert_eq!(k(&p, &l).unwrap(), 300.0);
        p.stiffness_weights = vec![100.0, 0.0, 10.0];
        // 300 + 100 * 1.75 + 10 * 5.125
        assert!((k(&p, &l).unwrap() - 526.25).abs() < 1e-9);
        p.stiffness_weights = vec![1e9, 0.0, 0.0];
        assert_eq!(k(&p, &l).unwrap(), 5000.0);
        p.stiffness_weights = vec![1.0];
        assert_eq!(
            k(&p, &l).unwrap_err().to_string(),
            "stiffness_weights has 1 values, the latent's last dimension is 3"
        );
    }

    #[test]
    fn a_missing_model_is_a_load_error_naming_it() {
        let e = Readout::load(Path::new("/nonexistent/stiffness"), 64).unwrap_err();
        let e = e.to_string();
        assert!(
            e.starts_with("stiffness model /nonexistent/stiffness: "),
            "{e}"
        );
        assert!(!e.contains('\n'), "{e}");
    }
}
