//! The sampler stage (VTLA-pred): a predicted `TactileLatent` without live touch.
//!
//! When the contact stage announces its background (the non-contact frame), the encoder's sensor
//! tokens of that frame become Z_sen. The stage then samples a latent with sensor-prior guidance:
//! prior branch conditioned on [0 | Z_sen | 0], conditional branch on [object | Z_sen | 1], where
//! `object` carries the scene's target properties. The latent is published with its solver, steps,
//! guidance, compute time and the guards' verdict; a latent that failed a guard has valid = false.

use crate::bundle::{Bundle, Model};
use crate::flow::{Guards, OnnxVelocity, SampleConfig, Solver, Velocity, sample};
use crate::preprocess::Preprocess;
use crate::runtime::{InferError, RuntimeConfig};
use serde::Deserialize;
use std::path::Path;
use std::time::Instant;
use unitac_core::msg::{Header, LatentSource, TactileLatent};
use unitac_core::{Clock, Frame, Msg, Stage, StageError};

#[derive(Debug, Clone, PartialEq, Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct SamplerParams {
    pub solver: String,
    pub steps: u32,
    /// SPSS guidance scale s (paper: 1.5).
    pub guidance: f64,
    pub seed: u64,
    /// Target (hardness, roughness, texture) of the object whose touch is predicted, 0..1.
    pub condition: [f32; 3],
    /// Pick solver and steps to fit this compute budget per latent \[ms] instead (live use: the
    /// choice depends on the measured model-call time, so it is not for byte-exact replays).
    pub budget_ms: Option<f64>,
    #[serde(flatten)]
    pub runtime: RuntimeConfig,
}

impl Default for SamplerParams {
    fn default() -> Self {
        Self {
            solver: "heun".into(),
            steps: 16,
            guidance: 1.5,
            seed: 0,
            condition: [0.5; 3],
            budget_ms: None,
            runtime: RuntimeConfig::default(),
        }
    }
}

/// Solver and steps for a budget, from the measured cost of one guided model call. Rule from the
/// error-vs-time table (`unitac report sampler`): a second-order solver is more accurate per unit
/// time from 4 steps on as long as s h <= 4 sigma_min; below that, Euler with as many steps as
/// fit. None if not even the stability bound fits.
pub fn choose_for_budget(
    budget_us: f64,
    call_us: f64,
    guidance: f64,
    sigma_min: f64,
) -> Option<(Solver, u32)> {
    if !(budget_us.is_finite() && call_us.is_finite() && call_us > 0.0) {
        return None;
    }
    let calls = (budget_us / call_us).floor().min(1e5) as u32;
    let min_steps = if guidance > 1.0 {
        (guidance / (4.0 * sigma_min)).ceil() as u32
    } else {
        1
    }
    .max(1);
    let heun = calls / 2;
    if heun >= min_steps.max(4) {
        Some((Solver::Heun, heun))
    } else if calls >= min_steps {
        Some((Solver::Euler, calls))
    } else {
        None
    }
}

/// Largest compute budget per latent a scene may ask for \[ms].
pub const MAX_BUDGET_MS: f64 = 60_000.0;

#[derive(Debug)]
pub struct SamplerStage {
    p: SamplerParams,
    cfg: SampleConfig,
    pre: Preprocess,
    encoder: Model,
    velocity: OnnxVelocity,
    shape: Vec<u32>,
    predicted: bool,
}

impl SamplerStage {
    pub fn new(bundle_dir: &Path, p: SamplerParams) -> Result<Self, InferError> {
        let bad = |msg: String| InferError::Bundle {
            dir: bundle_dir.to_path_buf(),
            msg,
        };
        let solver: Solver = p.solver.parse().map_err(|e| bad(format!("{e}")))?;
        let ok_guidance = p.guidance.is_finite() && (0.0..=100.0).contains(&p.guidance);
        if !ok_guidance || !(1..=10_000).contains(&p.steps) {
            return Err(bad(
                "guidance must be in [0, 100] and steps in 1..=10000".into()
            ));
        }
        if !p.condition.iter().all(|c| (0.0..=1.0).contains(c)) {
            return Err(bad(format!(
                "condition {:?} must be three values in [0, 1]",
                p.condition
            )));
        }
        if let Some(ms) = p.budget_ms {
            if !(ms.is_finite() && ms > 0.0 && ms <= MAX_BUDGET_MS) {
                return Err(bad(format!(
                    "budget_ms {ms:e} is outside (0, {MAX_BUDGET_MS}]"
                )));
            }
        }
        let bundle = Bundle::open(bundle_dir)?;
        let mut models = bundle
            .load(&["encoder", "velocity"], &p.runtime)?
            .into_iter();
        let (Some(encoder), Some(vel)) = (models.next(), models.next()) else {
            return Err(bad("models missing".into()));
        };
        let mut velocity = OnnxVelocity::new(vel)?;
        let d = velocity.dim();
        let side = (d as f64).sqrt() as u32;
        let shape = if (side * side) as usize == d {
            vec![side, side]
        } else {
            vec![1, d as u32]
        };
        let mut cfg = SampleConfig {
            solver,
            steps: p.steps,
            guidance: p.guidance,
            seed: p.seed,
            batched: true,
        };
        if let Some(ms) = p.budget_ms {
            // Measure one batch-2 call (median of 9) on zeros.
            let c = velocity.cond_dim();
            let mut t = Vec::new();
            for _ in 0..9 {
                let t0 = Instant::now();
                velocity.eval(&vec![0.0; 2 * d], &[0.5, 0.5], &vec![0.0; 2 * c], 2)?;
                t.push(t0.elapsed().as_secs_f64() * 1e6);
            }
            let call_us = unitac_core::timing(t).median_us;
            let (s, n) = choose_for_budget(ms * 1e3, call_us, p.guidance, velocity.sigma_min)
                .ok_or_else(|| {
                    bad(format!(
                        "a budget of {ms} ms does not fit a stable solve (one call: {call_us:.0} us)"
                    ))
                })?;
            cfg.solver = s;
            cfg.steps = n;
        }
        Ok(Self {
            pre: bundle.manifest.preprocess,
            p,
            cfg,
            encoder,
            velocity,
            shape,
            predicted: false,
        })
    }

    pub fn config(&self) -> &SampleConfig {
        &self.cfg
    }

    /// Z_sen: mean of the encoder's sensor tokens for the non-contact frame.
    fn sensor_prior(&mut self, bg: &Frame) -> Result<Vec<f32>, StageError> {
        let mut b = Vec::new();
        self.pre.frame_into(bg, &mut b);
        let clip: Vec<f32> = (0..self.pre.clip_frames)
            .flat_map(|_| b.iter().copied())
            .collect();
        let (t, s) = (i64::from(self.pre.clip_frames), i64::from(self.pre.size));
        let outs = self
            .encoder
            .run(&[(&[1, t, 3, s, s], &clip), (&[1, 3, s, s], &b)])
            .map_err(|e| StageError::Model(e.to_string()))?;
        let (shape, sen) = outs
            .into_iter()
            .nth(1)
            .ok_or_else(|| StageError::Model("encoder: no sensor_tokens".into()))?;
        let (n, w) = (
            shape.get(1).copied().unwrap_or(1).max(1) as usize,
            shape.get(2).copied().unwrap_or(0).max(0) as usize,
        );
        if sen.len() != n * w || sen.iter().any(|v| !v.is_finite()) {
            return Err(StageError::Model("encoder: bad sensor tokens".into()));
        }
        Ok((0..w)
            .map(|j| (0..n).map(|i| sen[i * w + j]).sum::<f32>() / n as f32)
            .collect())
    }
}

impl Stage for SamplerStage {
    fn name(&self) -> &str {
        "sampler"
    }
    fn process(&mut self, input: &Msg, clock: &dyn Clock) -> Result<Vec<Msg>, StageError> {
        let Msg::Background(bg) = input else {
            return Ok(Vec::new());
        };
        if self.predicted {
            return Ok(Vec::new());
        }
        let c0 = clock.now();
        let z_sen = self.sensor_prior(bg)?;
        let c = self.velocity.cond_dim();
        let half = (c.saturating_sub(1)) / 2;
        if z_sen.len() != half {
            return Err(StageError::Model(format!(
                "sensor prior has {} values, the velocity model expects {half}",
                z_sen.len()
            )));
        }
        let mut obj = vec![0.0f32; half];
        obj.iter_mut()
            .zip(self.p.condition)
            .for_each(|(o, v)| *o = v);
        let prior: Vec<f32> = vec![0.0; half]
            .into_iter()
            .chain(z_sen.iter().copied())
            .chain([0.0])
            .collect();
        let cond: Vec<f32> = obj.into_iter().chain(z_sen).chain([1.0]).collect();
        let guards = Guards::new(self.velocity.sigma_min);
        let out = sample(&mut self.velocity, &self.cfg, &guards, &prior, &cond)
            .map_err(|e| StageError::Model(e.to_string()))?;
        self.predicted = true;
        Ok(vec![Msg::TactileLatent(TactileLatent {
            header: Header::optical(bg.stamp, &bg.sensor_id),
            source: LatentSource::Predicted,
            sensor_id: bg.sensor_id.clone(),
            shape: self.shape.clone(),
            data: out.x,
            model_id: self.velocity.id().to_string(),
            solver: self.cfg.solver.as_str().into(),
            steps: self.cfg.steps,
            guidance: self.cfg.guidance as f32,
            elapsed_s: clock.now().secs_since(c0).max(0.0),
            valid: out.valid,
            guard_report: out.report,
        })])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn budget_picks_heun_when_it_fits_and_refuses_the_impossible() {
        // 40 us per call, 1.5 ms budget: 37 calls -> Heun 18.
        assert_eq!(
            choose_for_budget(1500.0, 40.0, 1.5, 0.1),
            Some((Solver::Heun, 18))
        );
        // 6 calls: Heun 3 < 4 -> Euler 6 (stable: needs >= 4 for s = 1.5).
        assert_eq!(
            choose_for_budget(240.0, 40.0, 1.5, 0.1),
            Some((Solver::Euler, 6))
        );
        // s = 20 needs 50 steps; 10 calls cannot be stable.
        assert_eq!(choose_for_budget(400.0, 40.0, 20.0, 0.1), None);
        assert_eq!(choose_for_budget(f64::NAN, 40.0, 1.5, 0.1), None);
    }
}
