//! The sampler stage (VTLA-pred): a predicted `TactileLatent` per object, before touching it.
//!
//! The condition is built from messages that exist before contact, as the velocity model's
//! manifest names them (`condition`, one entry per condition input):
//! - `object`: the object-level condition of one object (its category and the camera's values
//!   for it, [`crate::condition`]) from the latest VisualObservation;
//! - `sensor_tokens`: Z_sen, the encoder's sensor tokens of the contact stage's background
//!   ([`crate::prior`]).
//!
//! Once both have arrived, the stage samples one latent per object of its `objects` with
//! sensor-prior guidance (SPSS): the prior branch is conditioned on the sensor alone (object
//! values zero), the conditional branch on both. The sample is mapped to the encoder's latent
//! space by the manifest's `latent_offset`/`latent_scale` and published with its object, solver,
//! steps, guidance, compute time, the guards' verdict (valid = false if one failed) and its
//! condition's provenance (the messages it came from and their ages). A new background (the
//! sensor changed) predicts again.

use crate::bundle::{Bundle, ConditionSource, ModelSpec};
use crate::condition::object_condition;
use crate::flow::{Guards, OnnxVelocity, SampleConfig, Solver, Velocity, sample};
use crate::prior::SensorPrior;
use crate::runtime::{InferError, RuntimeConfig};
use serde::Deserialize;
use std::path::Path;
use std::time::Instant;
use unitac_core::msg::{Header, LatentSource, TactileLatent, VisualObservation};
use unitac_core::{Clock, Msg, Stage, StageError, Stamp};

/// The sensor prior the stage holds does not fit the velocity model's sensor input (a
/// [`StageError::Model`]: the bundle and the encoder disagree).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("sensor prior has {got} values, the velocity model's {input} takes {want}")]
pub struct PriorWidth {
    pub got: usize,
    pub input: String,
    pub want: usize,
}

/// Most objects one sampler stage predicts for.
pub const MAX_OBJECTS: usize = 8;
/// Most samples averaged per object.
pub const MAX_SAMPLES: u32 = 64;

#[derive(Debug, Clone, PartialEq, Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct SamplerParams {
    pub solver: String,
    pub steps: u32,
    /// SPSS guidance scale s (paper: 1.5).
    pub guidance: f64,
    pub seed: u64,
    /// The camera objects to predict a latent for (names as in the VisualObservation, e.g.
    /// `cup`, `fabric_a`); each gets its own latent.
    pub objects: Vec<String>,
    /// Seeded samples per object; the published latent is their mean (a point estimate for
    /// readouts; 1: the sample itself). Object i's sample k is seeded `seed + i * samples + k`.
    pub samples: u32,
    /// Pick solver and steps to fit this compute budget per latent \[s] instead (live use: the
    /// choice depends on the measured model-call time, so it is not for byte-exact replays).
    pub budget_s: Option<f64>,
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
            objects: vec!["cup".into()],
            samples: 1,
            budget_s: None,
            runtime: RuntimeConfig::default(),
        }
    }
}
/// Solver and steps for a budget, from the measured cost of one guided model call. Rule from the
/// error-vs-time table (`unitac-lab report sampler`): a second-order solver is more accurate per
/// unit time from 4 steps on as long as s h <= 4 sigma_min; below that, Euler with as many steps
/// as fit. None if not even the stability bound fits.
pub fn choose_for_budget(
    budget_s: f64,
    call_s: f64,
    guidance: f64,
    sigma_min: f64,
) -> Option<(Solver, u32)> {
    if !(budget_s.is_finite() && call_s.is_finite() && call_s > 0.0) {
        return None;
    }
    let calls = (budget_s / call_s).floor().min(1e5) as u32;
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

/// Largest compute budget per latent a scene may ask for \[s].
pub const MAX_BUDGET_S: f64 = 60.0;

/// The conditional and the prior (sensor-only) conditions of `object` for a velocity model whose
/// manifest entry is `spec` and whose condition inputs are `dims` wide: flat, in input order.
pub fn conditions(
    spec: &ModelSpec,
    dims: &[usize],
    object: &str,
    z_sen: &[f32],
    visual: &VisualObservation,
) -> Result<(Vec<f32>, Vec<f32>), StageError> {
    let (mut cond, mut prior) = (Vec::new(), Vec::new());
    for (c, &w) in spec.condition.iter().zip(dims) {
        match c.source {
            ConditionSource::Object => {
                let v =
                    object_condition(&c.fields, object, visual).map_err(StageError::bad_input)?;
                prior.extend(std::iter::repeat_n(0.0, v.len()));
                cond.extend(v);
            }
            ConditionSource::SensorTokens => {
                if z_sen.len() != w {
                    return Err(StageError::model(PriorWidth {
                        got: z_sen.len(),
                        input: c.input.clone(),
                        want: w,
                    }));
                }
                prior.extend_from_slice(z_sen);
                cond.extend_from_slice(z_sen);
            }
        }
    }
    Ok((cond, prior))
}

/// What the stage holds until it samples.
#[derive(Debug, Default)]
struct Inputs {
    /// Z_sen and the background's stamp and sensor.
    sensor: Option<(Vec<f32>, Stamp, String)>,
    visual: Option<VisualObservation>,
}

#[derive(Debug)]
pub struct SamplerStage {
    p: SamplerParams,
    cfg: SampleConfig,
    prior: SensorPrior,
    velocity: OnnxVelocity,
    shape: Vec<u32>,
    inputs: Inputs,
    predicted: bool,
}

/// The velocity model's condition inputs and latent map checked against the stage: one declared
/// source per condition input, in order; each object field set the right width and computable
/// for every object the stage predicts for; offset and scale of the latent's width. The latent's
/// shape comes back (the manifest's, or [1, d]). The error is one line for the bundle's.
fn latent_shape(
    spec: &ModelSpec,
    cond_dims: &[usize],
    d: usize,
    objects: &[String],
) -> Result<Vec<u32>, String> {
    let inputs: Vec<&str> = spec
        .inputs
        .iter()
        .skip(2)
        .map(|t| t.name.as_str())
        .collect();
    let declared: Vec<&str> = spec.condition.iter().map(|c| c.input.as_str()).collect();
    if inputs != declared {
        return Err(format!(
            "velocity: its condition inputs are {inputs:?}, the manifest's `condition` describes {declared:?} (a stage needs one source per input, in order)"
        ));
    }
    for (c, &w) in spec.condition.iter().zip(cond_dims) {
        if c.source == ConditionSource::Object && c.fields.len() != w {
            return Err(format!(
                "velocity: condition input {} has {w} values but {} fields",
                c.input,
                c.fields.len()
            ));
        }
    }
    for o in objects {
        let probe = VisualObservation {
            header: Header::new(Stamp(0), ""),
            names: Vec::new(),
            values: Vec::new(),
        };
        for c in spec
            .condition
            .iter()
            .filter(|c| c.source == ConditionSource::Object)
        {
            object_condition(&c.fields, o, &probe).map_err(|e| e.to_string())?;
        }
    }
    let affine_ok = |v: &[f32]| v.is_empty() || (v.len() == d && v.iter().all(|x| x.is_finite()));
    if !affine_ok(&spec.latent_offset) || !affine_ok(&spec.latent_scale) {
        return Err(format!(
            "velocity: latent_offset and latent_scale need {d} finite values each (or none)"
        ));
    }
    let shape = if spec.latent_shape.is_empty() {
        vec![1, d as u32]
    } else {
        spec.latent_shape.clone()
    };
    if shape.iter().map(|&v| v as usize).product::<usize>() != d {
        return Err(format!(
            "velocity: latent_shape {shape:?} does not hold {d} values"
        ));
    }
    Ok(shape)
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
        if p.objects.is_empty() || p.objects.len() > MAX_OBJECTS {
            return Err(bad(format!(
                "objects: name 1 to {MAX_OBJECTS} camera objects to predict for (got {})",
                p.objects.len()
            )));
        }
        if !(1..=MAX_SAMPLES).contains(&p.samples) {
            return Err(bad(format!(
                "samples must be 1 to {MAX_SAMPLES} (got {})",
                p.samples
            )));
        }
        if let Some(b) = p.budget_s {
            if !(b.is_finite() && b > 0.0 && b <= MAX_BUDGET_S) {
                return Err(bad(format!(
                    "budget_s {b:e} is outside (0, {MAX_BUDGET_S}]"
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
        let shape =
            latent_shape(velocity.spec(), velocity.cond_dims(), d, &p.objects).map_err(bad)?;
        let mut cfg = SampleConfig {
            solver,
            steps: p.steps,
            guidance: p.guidance,
            seed: p.seed,
            batched: true,
        };
        if let Some(budget_s) = p.budget_s {
            // Measure one batch-2 call (median of 9) on zeros.
            let c = velocity.cond_dim();
            let mut t = Vec::new();
            for _ in 0..9 {
                let t0 = Instant::now();
                velocity.eval(&vec![0.0; 2 * d], &[0.5, 0.5], &vec![0.0; 2 * c], 2)?;
                t.push(t0.elapsed().as_secs_f64());
            }
            let call_s = unitac_core::timing(t).median_s;
            let (s, n) = choose_for_budget(budget_s, call_s, p.guidance, velocity.sigma_min)
                .ok_or_else(|| {
                    bad(format!(
                        "a budget of {budget_s} s does not fit a stable solve (one call: {:.0} us)",
                        call_s * 1e6
                    ))
                })?;
            cfg.solver = s;
            cfg.steps = n;
        }
        Ok(Self {
            prior: SensorPrior::new(bundle.manifest.preprocess, encoder),
            p,
            cfg,
            velocity,
            shape,
            inputs: Inputs::default(),
            predicted: false,
        })
    }

    pub fn config(&self) -> &SampleConfig {
        &self.cfg
    }

    fn predict(&mut self, clock: &dyn Clock) -> Result<Vec<Msg>, StageError> {
        let (Some((z_sen, bg_stamp, sensor_id)), Some(visual)) =
            (&self.inputs.sensor, &self.inputs.visual)
        else {
            return Ok(Vec::new());
        };
        if self.predicted {
            return Ok(Vec::new());
        }
        let now = clock.now();
        let uses =
            |s: ConditionSource| self.velocity.spec().condition.iter().any(|c| c.source == s);
        let mut sources = Vec::new();
        let mut ages = Vec::new();
        if uses(ConditionSource::Object) {
            sources.push("visual_observation".to_string());
            ages.push(now.secs_since(visual.header.stamp).max(0.0));
        }
        if uses(ConditionSource::SensorTokens) {
            sources.push("background".to_string());
            ages.push(now.secs_since(*bg_stamp).max(0.0));
        }
        let spec = self.velocity.spec().clone();
        let guards = Guards::new(self.velocity.sigma_min);
        let mut out = Vec::with_capacity(self.p.objects.len());
        for (i, object) in self.p.objects.iter().enumerate() {
            let (cond, prior) = conditions(
                self.velocity.spec(),
                self.velocity.cond_dims(),
                object,
                z_sen,
                visual,
            )?;
            let k = self.p.samples;
            let mut sum = vec![0.0f64; self.velocity.dim()];
            let (mut valid, mut report) = (true, String::new());
            for j in 0..k {
                let cfg = SampleConfig {
                    seed: self
                        .cfg
                        .seed
                        .wrapping_add(i as u64 * u64::from(k) + u64::from(j)),
                    ..self.cfg.clone()
                };
                let s = sample(&mut self.velocity, &cfg, &guards, &prior, &cond)
                    .map_err(StageError::model)?;
                valid &= s.valid;
                if report.is_empty() {
                    report = s.report;
                }
                sum.iter_mut()
                    .zip(&s.x)
                    .for_each(|(a, &x)| *a += f64::from(x));
            }
            let data: Vec<f32> = sum
                .iter()
                .enumerate()
                .map(|(j, x)| {
                    let mean = (x / f64::from(k)) as f32;
                    spec.latent_offset.get(j).copied().unwrap_or(0.0)
                        + spec.latent_scale.get(j).copied().unwrap_or(1.0) * mean
                })
                .collect();
            out.push(Msg::TactileLatent(TactileLatent {
                header: Header::optical(now, sensor_id),
                source: LatentSource::Predicted,
                sensor_id: sensor_id.clone(),
                shape: self.shape.clone(),
                data,
                model_id: self.velocity.id().to_string(),
                solver: self.cfg.solver.as_str().into(),
                steps: self.cfg.steps,
                guidance: self.cfg.guidance as f32,
                elapsed_s: clock.now().secs_since(now).max(0.0),
                valid,
                guard_report: report,
                object: object.clone(),
                condition_sources: sources.clone(),
                condition_age_s: ages.clone(),
            }));
        }
        self.predicted = true;
        Ok(out)
    }
}

impl Stage for SamplerStage {
    fn name(&self) -> &str {
        "sampler"
    }
    fn process(&mut self, input: &Msg, clock: &dyn Clock) -> Result<Vec<Msg>, StageError> {
        match input {
            Msg::Background(bg) => {
                let z = self.prior.of(bg).map_err(StageError::model)?;
                // A new background (the sensor changed): predict again.
                self.predicted = false;
                self.inputs.sensor = Some((z, bg.stamp, bg.sensor_id.clone()));
            }
            Msg::VisualObservation(v) if !self.predicted => {
                self.inputs.visual = Some(v.clone());
            }
            _ => return Ok(Vec::new()),
        }
        self.predict(clock)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn budget_picks_heun_when_it_fits_and_refuses_the_impossible() {
        // 40 ms per call, 1.5 s budget: 37 calls -> Heun 18.
        assert_eq!(
            choose_for_budget(1.5, 0.04, 1.5, 0.1),
            Some((Solver::Heun, 18))
        );
        // 6 calls: Heun 3 < 4 -> Euler 6 (stable: needs >= 4 for s = 1.5).
        assert_eq!(
            choose_for_budget(0.25, 0.04, 1.5, 0.1),
            Some((Solver::Euler, 6))
        );
        // s = 20 needs 50 steps; 10 calls cannot be stable.
        assert_eq!(choose_for_budget(0.41, 0.04, 20.0, 0.1), None);
        assert_eq!(choose_for_budget(f64::NAN, 0.04, 1.5, 0.1), None);
    }
}
