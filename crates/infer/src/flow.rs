//! Rectified-flow sampling with Sensor-Prior Sampling (SPSS) guidance, guards, and an exact oracle.
//!
//! Time: tau in [0, 1], tau = 0 noise (x_0 = z ~ N(0, I)), tau = 1 data; N steps of h = 1/N ending
//! exactly at tau = 1 (the paper's loop, read literally, takes one step too many).
//!
//! Guidance: v = v(x | tau, c_prior) + s (v(x | tau, c) - v(x | tau, c_prior)). For SPSS the prior
//! branch is conditioned on the sensor only (Z_sen, from the non-contact frame), the conditional
//! branch on object + sensor. Both branches are evaluated as ONE batch-2 model call; at s = 1 the
//! prior branch is skipped.
//!
//! Guards (a failed latent is never valid): the guided ODE's Jacobian reaches about
//! -s / (2 sigma_min) near tau = 1, so explicit steps need s h <= 4 sigma_min; every step checks
//! that x and v are finite and that |x| does not grow by more than `growth` per step.

use crate::bundle::Model;
use crate::runtime::InferError;
use serde::Serialize;
use std::time::Instant;
use thiserror::Error;

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Solver {
    Euler,
    Midpoint,
    Heun,
}

impl Solver {
    pub const ALL: [Solver; 3] = [Solver::Euler, Solver::Midpoint, Solver::Heun];
    pub fn as_str(self) -> &'static str {
        match self {
            Solver::Euler => "euler",
            Solver::Midpoint => "midpoint",
            Solver::Heun => "heun",
        }
    }
}

/// A solver name that is none of [`Solver::ALL`].
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[error("unknown solver '{0}' (euler, midpoint, heun)")]
pub struct UnknownSolver(pub String);

impl std::str::FromStr for Solver {
    type Err = UnknownSolver;
    fn from_str(s: &str) -> Result<Self, UnknownSolver> {
        Solver::ALL
            .into_iter()
            .find(|v| v.as_str() == s)
            .ok_or_else(|| UnknownSolver(s.to_string()))
    }
}

/// A velocity field: `eval` writes v for a batch of states at times `t` with conditions `cond`.
pub trait Velocity {
    fn dim(&self) -> usize;
    fn cond_dim(&self) -> usize;
    fn eval(
        &mut self,
        x: &[f32],
        t: &[f32],
        cond: &[f32],
        batch: usize,
    ) -> Result<Vec<f32>, InferError>;
}

/// A velocity model from a bundle, adapted to the sampler's time convention. Its inputs are
/// `x [batch, D]`, `t [batch, 1]` and one or more condition inputs `[batch, C_i]`; the sampler
/// sees one condition of `sum C_i` values per row, split over the inputs in their order.
#[derive(Debug)]
pub struct OnnxVelocity {
    model: Model,
    dim: usize,
    /// Width of each condition input, in input order.
    cond_dims: Vec<usize>,
    /// The model was trained with t' = 1 - tau as noise: feed 1 - tau and negate.
    flipped: bool,
    pub sigma_min: f64,
}

impl OnnxVelocity {
    pub fn new(model: Model) -> Result<Self, InferError> {
        let err = |m: &str| InferError::Model {
            model: model.name.clone(),
            msg: m.to_string(),
        };
        let shape_err = "inputs must be x [batch, D], t [batch, 1] and condition inputs [batch, C] with fixed D and C";
        let fixed = |i: usize| match model.spec.inputs.get(i).and_then(|t| t.shape.get(1)) {
            Some(crate::bundle::Dim::Fixed(v)) if *v > 0 && *v <= 1 << 20 => Ok(*v as usize),
            _ => Err(err(shape_err)),
        };
        let dim = fixed(0)?;
        let n = model.spec.inputs.len();
        if n < 3 {
            return Err(err(shape_err));
        }
        let cond_dims = (2..n).map(fixed).collect::<Result<Vec<_>, _>>()?;
        let flipped = match model.spec.time_convention.as_deref() {
            Some("tau_data_at_1") | None => false,
            Some("tau_noise_at_1") => true,
            Some(other) => return Err(err(&format!("unknown time_convention '{other}'"))),
        };
        let sigma_min = model.spec.sigma_min.unwrap_or(0.05);
        if !(sigma_min.is_finite() && sigma_min > 0.0) {
            return Err(err("sigma_min must be > 0"));
        }
        Ok(Self {
            model,
            dim,
            cond_dims,
            flipped,
            sigma_min,
        })
    }
    pub fn id(&self) -> &str {
        &self.model.id
    }
    /// The model's manifest entry (condition sources, latent map).
    pub fn spec(&self) -> &crate::bundle::ModelSpec {
        &self.model.spec
    }
    /// Width of each condition input, in input order.
    pub fn cond_dims(&self) -> &[usize] {
        &self.cond_dims
    }
}

impl Velocity for OnnxVelocity {
    fn dim(&self) -> usize {
        self.dim
    }
    fn cond_dim(&self) -> usize {
        self.cond_dims.iter().sum()
    }
    fn eval(
        &mut self,
        x: &[f32],
        t: &[f32],
        cond: &[f32],
        batch: usize,
    ) -> Result<Vec<f32>, InferError> {
        let b = batch as i64;
        let c = self.cond_dim();
        if x.len() != batch * self.dim || t.len() != batch || cond.len() != batch * c {
            return Err(InferError::Input(format!(
                "velocity: {} states, {} times, {} condition values for batch {batch} (D {}, C {c})",
                x.len(),
                t.len(),
                cond.len(),
                self.dim
            )));
        }
        let tt: Vec<f32> = if self.flipped {
            t.iter().map(|v| 1.0 - v).collect()
        } else {
            t.to_vec()
        };
        // Each condition input's columns of every row.
        let mut parts: Vec<Vec<f32>> = Vec::with_capacity(self.cond_dims.len());
        let mut at = 0;
        for &w in &self.cond_dims {
            let mut p = Vec::with_capacity(batch * w);
            for r in 0..batch {
                p.extend_from_slice(&cond[r * c + at..r * c + at + w]);
            }
            parts.push(p);
            at += w;
        }
        let shapes: Vec<[i64; 2]> = self.cond_dims.iter().map(|&w| [b, w as i64]).collect();
        let (xs, ts) = ([b, self.dim as i64], [b, 1]);
        let mut inputs: Vec<(&[i64], &[f32])> = vec![(&xs, x), (&ts, &tt)];
        inputs.extend(shapes.iter().zip(&parts).map(|(s, p)| (&s[..], &p[..])));
        let outs = self.model.run(&inputs)?;
        let (_, mut v) = outs.into_iter().next().ok_or_else(|| InferError::Output {
            model: self.model.name.clone(),
            msg: "no output".into(),
        })?;
        if v.len() != batch * self.dim {
            return Err(InferError::Output {
                model: self.model.name.clone(),
                msg: format!("{} values for batch {batch} x {}", v.len(), self.dim),
            });
        }
        if self.flipped {
            v.iter_mut().for_each(|e| *e = -*e);
        }
        Ok(v)
    }
}

#[derive(Debug, Clone, Serialize)]
pub struct Guards {
    pub enabled: bool,
    /// Smallest target sigma of the model (from the manifest).
    pub sigma_min: f64,
    /// Largest allowed growth of rms(x) per step (relative to max(rms, 1)).
    pub growth: f64,
}

impl Guards {
    pub fn new(sigma_min: f64) -> Self {
        Self {
            enabled: true,
            sigma_min,
            growth: 4.0,
        }
    }
}

#[derive(Debug, Clone, Serialize)]
pub struct SampleConfig {
    pub solver: Solver,
    pub steps: u32,
    /// Guidance scale s (1 = no guidance; the paper uses 1.5).
    pub guidance: f64,
    pub seed: u64,
    /// Evaluate both guidance branches in one batch-2 call (false: two calls, for comparison).
    pub batched: bool,
}

#[derive(Debug, Clone, Serialize)]
pub struct Outcome {
    pub x: Vec<f32>,
    pub valid: bool,
    /// What the guards saw ("" when nothing happened).
    pub report: String,
    pub model_calls: u32,
    pub elapsed_s: f64,
}

/// Deterministic standard normal noise (SplitMix64 + Box-Muller).
pub fn noise(seed: u64, n: usize) -> Vec<f32> {
    let mut state = seed;
    let mut next = || {
        state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    };
    let mut out = Vec::with_capacity(n + 1);
    while out.len() < n {
        let (u1, u2) = (next().max(1e-300), next());
        let r = (-2.0 * u1.ln()).sqrt();
        out.push((r * (std::f64::consts::TAU * u2).cos()) as f32);
        out.push((r * (std::f64::consts::TAU * u2).sin()) as f32);
    }
    out.truncate(n);
    out
}

fn rms(x: &[f64]) -> f64 {
    (x.iter().map(|v| v * v).sum::<f64>() / x.len().max(1) as f64).sqrt()
}

/// The guided field at (x, tau); counts model calls.
fn guided(
    v: &mut dyn Velocity,
    x: &[f64],
    tau: f64,
    cond_prior: &[f32],
    cond: &[f32],
    cfg: &SampleConfig,
    calls: &mut u32,
) -> Result<Vec<f64>, InferError> {
    let d = v.dim();
    let xf: Vec<f32> = x.iter().map(|&e| e as f32).collect();
    let s = cfg.guidance;
    if s == 1.0 {
        *calls += 1;
        return Ok(v
            .eval(&xf, &[tau as f32], cond, 1)?
            .into_iter()
            .map(f64::from)
            .collect());
    }
    let (vp, vc) = if cfg.batched {
        *calls += 1;
        let x2: Vec<f32> = xf.iter().chain(&xf).copied().collect();
        let c2: Vec<f32> = cond_prior.iter().chain(cond).copied().collect();
        let out = v.eval(&x2, &[tau as f32; 2], &c2, 2)?;
        let (a, b) = out.split_at(d);
        (a.to_vec(), b.to_vec())
    } else {
        *calls += 2;
        (
            v.eval(&xf, &[tau as f32], cond_prior, 1)?,
            v.eval(&xf, &[tau as f32], cond, 1)?,
        )
    };
    Ok(vp
        .iter()
        .zip(&vc)
        .map(|(&p, &c)| f64::from(p) + s * (f64::from(c) - f64::from(p)))
        .collect())
}

/// Sample one latent. Errors are model failures; numerical trouble is an invalid `Outcome`.
pub fn sample(
    v: &mut dyn Velocity,
    cfg: &SampleConfig,
    guards: &Guards,
    cond_prior: &[f32],
    cond: &[f32],
) -> Result<Outcome, InferError> {
    let t0 = Instant::now();
    let d = v.dim();
    if cond.len() != v.cond_dim() || cond_prior.len() != v.cond_dim() {
        return Err(InferError::Input(format!(
            "conditions need {} values, got {} and {}",
            v.cond_dim(),
            cond_prior.len(),
            cond.len()
        )));
    }
    if cfg.steps == 0 || cfg.steps > 100_000 || !cfg.guidance.is_finite() {
        return Err(InferError::Input(
            "steps must be 1..=100000 and the guidance finite".into(),
        ));
    }
    let h = 1.0 / f64::from(cfg.steps);
    let mut x: Vec<f64> = noise(cfg.seed, d).into_iter().map(f64::from).collect();
    let done = |x: Vec<f64>, valid: bool, report: String, calls: u32| Outcome {
        x: x.into_iter().map(|e| e as f32).collect(),
        valid,
        report,
        model_calls: calls,
        elapsed_s: t0.elapsed().as_secs_f64(),
    };
    if guards.enabled && cfg.guidance > 1.0 && cfg.guidance * h > 4.0 * guards.sigma_min {
        let report = format!(
            "stiff: s*h = {:.3} exceeds 4*sigma_min = {:.3} (explicit steps are unstable near tau = 1); use at least {} steps",
            cfg.guidance * h,
            4.0 * guards.sigma_min,
            (cfg.guidance / (4.0 * guards.sigma_min)).ceil()
        );
        return Ok(done(x, false, report, 0));
    }
    let mut calls = 0u32;
    for k in 0..cfg.steps {
        let tau = f64::from(k) * h;
        let before = rms(&x);
        let k1 = guided(v, &x, tau, cond_prior, cond, cfg, &mut calls)?;
        let step: Vec<f64> = match cfg.solver {
            Solver::Euler => k1,
            Solver::Midpoint => {
                let xm: Vec<f64> = x.iter().zip(&k1).map(|(a, b)| a + 0.5 * h * b).collect();
                guided(v, &xm, tau + 0.5 * h, cond_prior, cond, cfg, &mut calls)?
            }
            Solver::Heun => {
                let xp: Vec<f64> = x.iter().zip(&k1).map(|(a, b)| a + h * b).collect();
                let k2 = guided(v, &xp, tau + h, cond_prior, cond, cfg, &mut calls)?;
                k1.iter().zip(&k2).map(|(a, b)| 0.5 * (a + b)).collect()
            }
        };
        for (a, b) in x.iter_mut().zip(&step) {
            *a += h * b;
        }
        if guards.enabled {
            if x.iter().any(|e| !e.is_finite()) {
                return Ok(done(
                    x,
                    false,
                    format!("non-finite state at step {} of {}", k + 1, cfg.steps),
                    calls,
                ));
            }
            let after = rms(&x);
            if after > guards.growth * before.max(1.0) {
                let report = format!(
                    "growth: rms(x) went from {before:.3e} to {after:.3e} at step {} of {}",
                    k + 1,
                    cfg.steps
                );
                return Ok(done(x, false, report, calls));
            }
        }
    }
    Ok(done(x, true, String::new(), calls))
}

/// Exact endpoint of the (guided) flow between two Gaussian targets, per coordinate:
/// prior N(mu_p, sig_p^2), conditional N(mu_c, sig_c^2), guidance s, start z.
/// The guided ODE is affine, dx/dt = a(t) + b(t) x, with Phi(t) = s_p(t)^(1-s) s_c(t)^s and
/// x(1) = Phi(1) (z + integral_0^1 a / Phi), integrated by composite Gauss-Legendre in f64.
pub fn exact_gaussian(z: f64, mu_p: f64, sig_p: f64, mu_c: f64, sig_c: f64, s: f64) -> f64 {
    let st = |t: f64, sg: f64| ((1.0 - t).powi(2) + t * t * sg * sg).sqrt();
    let b = |t: f64, sg: f64| (t * sg * sg - (1.0 - t)) / st(t, sg).powi(2);
    let phi = |t: f64| st(t, sig_p).powf(1.0 - s) * st(t, sig_c).powf(s);
    let a =
        |t: f64| (1.0 - s) * mu_p * (1.0 - t * b(t, sig_p)) + s * mu_c * (1.0 - t * b(t, sig_c));
    // 8-point Gauss-Legendre nodes and weights on [-1, 1].
    const X: [f64; 4] = [
        0.183_434_642_495_649_8,
        0.525_532_409_916_329,
        0.796_666_477_413_626_7,
        0.960_289_856_497_536_3,
    ];
    const W: [f64; 4] = [
        0.362_683_783_378_362,
        0.313_706_645_877_887_3,
        0.222_381_034_453_374_5,
        0.101_228_536_290_376_3,
    ];
    let panels = 512;
    let mut integral = 0.0;
    for p in 0..panels {
        let (lo, hi) = (p as f64 / panels as f64, (p + 1) as f64 / panels as f64);
        let (c, r) = ((lo + hi) / 2.0, (hi - lo) / 2.0);
        for (x, w) in X.iter().zip(W) {
            for t in [c - r * x, c + r * x] {
                integral += w * r * a(t) / phi(t);
            }
        }
    }
    phi(1.0) * (z + integral)
}

/// A Gaussian velocity field computed in Rust (f64), for tests of the integrator itself.
#[derive(Debug, Clone)]
pub struct GaussianField {
    pub dim: usize,
}

impl Velocity for GaussianField {
    fn dim(&self) -> usize {
        self.dim
    }
    fn cond_dim(&self) -> usize {
        self.dim + 1
    }
    fn eval(
        &mut self,
        x: &[f32],
        t: &[f32],
        cond: &[f32],
        batch: usize,
    ) -> Result<Vec<f32>, InferError> {
        let d = self.dim;
        let mut out = Vec::with_capacity(batch * d);
        for i in 0..batch {
            let (c, tt) = (&cond[i * (d + 1)..(i + 1) * (d + 1)], f64::from(t[i]));
            let s2 = (2.0 * f64::from(c[d])).exp();
            let b = (tt * s2 - (1.0 - tt)) / ((1.0 - tt).powi(2) + tt * tt * s2);
            for j in 0..d {
                let mu = f64::from(c[j]);
                out.push((mu + b * (f64::from(x[i * d + j]) - tt * mu)) as f32);
            }
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cond(mu: &[f32], log_sigma: f32) -> Vec<f32> {
        mu.iter().copied().chain([log_sigma]).collect()
    }

    #[test]
    fn unguided_flow_maps_noise_to_the_target_exactly() {
        // s = 1: x(1) = mu + sigma z, closed form.
        for (mu, sg) in [(1.5, 0.5), (-0.3, 2.0), (0.0, 0.1)] {
            let e = exact_gaussian(0.7, 0.0, 1.0, mu, sg, 1.0);
            assert!((e - (mu + sg * 0.7)).abs() < 1e-10, "{e}");
        }
        // s = 0 gives the prior.
        assert!((exact_gaussian(0.7, 0.2, 1.0, 5.0, 0.3, 0.0) - 0.9).abs() < 1e-10);
    }

    #[test]
    fn noise_is_standard_normal_and_seeded() {
        let n = noise(3, 100_000);
        let m = n.iter().map(|&v| f64::from(v)).sum::<f64>() / n.len() as f64;
        let v = n.iter().map(|&x| (f64::from(x) - m).powi(2)).sum::<f64>() / n.len() as f64;
        assert!(m.abs() < 0.01 && (v - 1.0).abs() < 0.02);
        assert_eq!(noise(3, 5), noise(3, 5));
        assert_ne!(noise(3, 5), noise(4, 5));
    }

    /// Error of the sampler on the Rust Gaussian field at N steps (RMS over coordinates).
    fn err(solver: Solver, steps: u32, s: f64) -> f64 {
        let d = 16;
        let mu: Vec<f32> = (0..d).map(|i| (i as f32 * 0.37).sin()).collect();
        let (cp, cc) = (cond(&vec![0.0; d], 0.0), cond(&mu, (0.5f32).ln()));
        let cfg = SampleConfig {
            solver,
            steps,
            guidance: s,
            seed: 9,
            batched: true,
        };
        let mut f = GaussianField { dim: d };
        let out = sample(
            &mut f,
            &cfg,
            &Guards {
                enabled: false,
                sigma_min: 0.1,
                growth: 4.0,
            },
            &cp,
            &cc,
        )
        .unwrap();
        let z = noise(9, d);
        let e2: f64 = (0..d)
            .map(|i| {
                (f64::from(out.x[i])
                    - exact_gaussian(f64::from(z[i]), 0.0, 1.0, f64::from(mu[i]), 0.5, s))
                .powi(2)
            })
            .sum();
        (e2 / d as f64).sqrt()
    }

    /// Measured order from 32 and 64 steps: Euler ~1; Heun and midpoint at least 2 (midpoint
    /// superconverges to ~3 on this linear field at s = 1).
    #[test]
    fn convergence_orders_on_the_exact_gaussian() {
        for s in [1.0, 1.5, 3.0] {
            for (solver, lo, hi) in [
                (Solver::Euler, 0.8, 1.25),
                (Solver::Midpoint, 1.75, 3.2),
                (Solver::Heun, 1.75, 2.3),
            ] {
                let (e1, e2) = (err(solver, 32, s), err(solver, 64, s));
                let p = (e1 / e2).log2();
                assert!(
                    (lo..hi).contains(&p),
                    "{solver:?} s={s}: order {p:.2} ({e1:.2e} -> {e2:.2e})"
                );
            }
        }
    }

    #[test]
    fn guided_closed_form_is_matched_with_enough_steps() {
        assert!(err(Solver::Heun, 256, 3.0) < 1e-4);
        assert!(err(Solver::Euler, 4096, 7.5) < 5e-3);
    }

    #[test]
    fn strong_guidance_with_few_steps_is_caught() {
        let d = 16;
        let mu: Vec<f32> = vec![1.0; d];
        let (cp, cc) = (cond(&vec![0.0; d], 0.0), cond(&mu, (0.05f32).ln()));
        let mut f = GaussianField { dim: d };
        let cfg = SampleConfig {
            solver: Solver::Euler,
            steps: 4,
            guidance: 20.0,
            seed: 1,
            batched: true,
        };
        // The s*h guard flags it before any model call.
        let out = sample(&mut f, &cfg, &Guards::new(0.1), &cp, &cc).unwrap();
        assert!(
            !out.valid && out.report.starts_with("stiff"),
            "{}",
            out.report
        );
        assert_eq!(out.model_calls, 0);
        // Without the s*h guard, the growth guard sees the blow-up.
        let g = Guards {
            sigma_min: 1e6,
            ..Guards::new(0.1)
        };
        let out = sample(&mut f, &cfg, &g, &cp, &cc).unwrap();
        assert!(
            !out.valid && out.report.starts_with("growth"),
            "{}",
            out.report
        );
        // The same settings with enough steps are fine.
        let ok = SampleConfig { steps: 64, ..cfg };
        let out = sample(&mut f, &ok, &Guards::new(0.1), &cp, &cc).unwrap();
        assert!(out.valid, "{}", out.report);
    }

    #[test]
    fn batched_and_two_call_guidance_agree() {
        let d = 8;
        let (cp, cc) = (cond(&vec![0.0; d], 0.0), cond(&vec![0.5; d], -0.5));
        let mut f = GaussianField { dim: d };
        let a = SampleConfig {
            solver: Solver::Heun,
            steps: 16,
            guidance: 1.5,
            seed: 2,
            batched: true,
        };
        let b = SampleConfig {
            batched: false,
            ..a.clone()
        };
        let (oa, ob) = (
            sample(&mut f, &a, &Guards::new(0.1), &cp, &cc).unwrap(),
            sample(&mut f, &b, &Guards::new(0.1), &cp, &cc).unwrap(),
        );
        assert_eq!(oa.x, ob.x);
        assert_eq!((oa.model_calls, ob.model_calls), (32, 64));
        // s = 1 skips the prior branch.
        let one = SampleConfig { guidance: 1.0, ..a };
        assert_eq!(
            sample(&mut f, &one, &Guards::new(0.1), &cp, &cc)
                .unwrap()
                .model_calls,
            32
        );
    }
}
