//! Scene controllers: explicit state machines implementing [`crate::policy::Policy`], one per
//! task family. Their phase is PolicyStatus.phase. They see observations only (never ground
//! truth) and know time only through the observation's stamp.

pub mod cup;
pub mod fabric;

use crate::params::PolicyParams;
use crate::policy::{Action, ArmAction, GripperAction, PolicyError};
use unitac_core::Stamp;
use unitac_core::msg::{GripperMode, TactileLatent};

pub use cup::CupController;
pub use fabric::FabricController;

/// A phase and when it began.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Timed<P> {
    pub phase: P,
    pub since: Option<Stamp>,
}

impl<P: Copy + PartialEq> Timed<P> {
    pub fn new(phase: P) -> Self {
        Self { phase, since: None }
    }
    /// Seconds in the current phase at `now` (its first tick is 0).
    pub fn elapsed(&mut self, now: Stamp) -> f64 {
        let since = *self.since.get_or_insert(now);
        now.secs_since(since).max(0.0)
    }
    pub fn go(&mut self, phase: P) {
        self.phase = phase;
        self.since = None;
    }
}

/// Latent -> expected stiffness \[N/m]: `bias + weights . mean over the leading dimension`,
/// clamped to the params' range. The coefficients are scene params (fitted offline); empty
/// weights leave the bias, a prior, and the latent only has to be valid.
pub fn stiffness(p: &PolicyParams, latent: &TactileLatent) -> Result<f64, PolicyError> {
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
    if !k.is_finite() {
        return Err(PolicyError::Failed(
            "stiffness readout is not finite".into(),
        ));
    }
    Ok(k.clamp(p.min_stiffness_n_per_m, p.max_stiffness_n_per_m))
}

pub(crate) fn arm(target: &str, z_m: f64, lift_m: f64) -> ArmAction {
    ArmAction {
        target: target.to_string(),
        z_m,
        lift_m,
    }
}

pub(crate) fn position(position_m: f64, speed_m_s: f64, force_n: f64) -> GripperAction {
    GripperAction {
        mode: GripperMode::Position,
        position_m,
        speed_m_s,
        force_n,
    }
}

pub(crate) fn force(toward_m: f64, speed_m_s: f64, force_n: f64) -> GripperAction {
    GripperAction {
        mode: GripperMode::Force,
        position_m: toward_m,
        speed_m_s,
        force_n,
    }
}

pub(crate) fn action(gripper: GripperAction, arm: ArmAction, note: impl Into<String>) -> Action {
    Action {
        gripper,
        arm,
        note: note.into(),
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use unitac_core::msg::samples;

    #[test]
    fn stiffness_readout_pools_the_leading_dimension() {
        let mut p = PolicyParams::default();
        let l = samples::tactile_latent(); // [2, 3]: rows (0.5, -1, 2.25), (3, -0.125, 8)
        assert_eq!(stiffness(&p, &l).unwrap(), 300.0);
        p.stiffness_weights = vec![100.0, 0.0, 10.0];
        // 300 + 100 * 1.75 + 10 * 5.125
        assert!((stiffness(&p, &l).unwrap() - 526.25).abs() < 1e-9);
        p.stiffness_weights = vec![1e9, 0.0, 0.0];
        assert_eq!(stiffness(&p, &l).unwrap(), 5000.0);
        p.stiffness_weights = vec![1.0];
        assert_eq!(
            stiffness(&p, &l).unwrap_err().to_string(),
            "stiffness_weights has 1 values, the latent's last dimension is 3"
        );
    }
}
