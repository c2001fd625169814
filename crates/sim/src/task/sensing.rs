//! What the gripper measures of itself, the way an electric parallel gripper does: the opening
//! from its encoder, the motor current, the force estimated from that current, and whether it
//! stopped on an object. Never the world's contact force: the force a gripper reports is its
//! current times a nominal force constant, with the current's resolution and noise and this
//! gripper's own gain error (drawn per trial, unknown to everyone but the world).
//!
//! Figures and where they come from (`TaskConfig::noise_figures` lists them with every other noise figure):
//! - current resolution 10 mA: the Robotiq 2F-85 / 2F-140 status register gCU ("the current is
//!   approximately 10 x value read in mA", Robotiq 2F-85 & 2F-140 instruction manual, 4.7);
//! - current noise 5 mA (one standard deviation per reading): a modelling choice;
//! - force constant 100 N/A nominal and a gain error of 15 % (one standard deviation, per
//!   trial): modelling choices (a 2F-140 grips 10-125 N; friction in the screw drive makes force from
//!   current a rough estimate, which is why grippers quote force ranges, not accuracies);
//! - opening resolution 0.1 mm: a modelling choice (encoder).
//! - object detection: the fingers stopped short of their target with the current at or above
//!   20 mA (two counts; a modelling choice), what gOBJ reports on a Robotiq.

use serde::Serialize;

use super::GripperTruth;
use crate::rng::SplitMix64;

/// The gripper's measurement model.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct GripperSensing {
    /// Nominal force constant [N/A] (what the driver converts current with).
    pub force_per_amp: f64,
    /// Per-trial gain error of the true force constant (one standard deviation, relative).
    pub gain_error_sd: f64,
    /// Current resolution and noise (one standard deviation) \[A].
    pub current_step_a: f64,
    pub current_noise_a: f64,
    /// Opening resolution \[m].
    pub opening_step_m: f64,
    /// Current at which a stop counts as an object \[A].
    pub detect_a: f64,
}

impl Default for GripperSensing {
    fn default() -> Self {
        Self {
            force_per_amp: 100.0,
            gain_error_sd: 0.15,
            current_step_a: 0.010,
            current_noise_a: 0.005,
            opening_step_m: 1e-4,
            detect_a: 0.020,
        }
    }
}

/// One reading of the gripper.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct GripperReading {
    pub opening_m: f64,
    pub current_a: f64,
    /// Force estimated from the current with the nominal constant \[N].
    pub force_n: f64,
    /// Stopped on an object (short of the target, current above the detection level).
    pub object_detected: bool,
    /// The fingers are not moving (stalled on something).
    pub stalled: bool,
}

fn quantize(v: f64, step: f64) -> f64 {
    if step > 0.0 && step.is_finite() {
        (v / step).round() * step
    } else {
        v
    }
}

impl GripperSensing {
    /// Draw this trial's gain (the true force constant over the nominal one).
    pub fn draw_gain(&self, rng: &mut SplitMix64) -> f64 {
        (1.0 + self.gain_error_sd * rng.gaussian()).clamp(0.5, 1.5)
    }

    /// What the gripper reads now: `gain` is the trial's, the noise drawn from `rng`.
    pub fn read(&self, truth: &GripperTruth, gain: f64, rng: &mut SplitMix64) -> GripperReading {
        let true_a = truth.force_n.max(0.0) / (self.force_per_amp * gain).max(1e-9);
        let noise = self.current_noise_a * rng.gaussian();
        let current_a = quantize((true_a + noise).max(0.0), self.current_step_a);
        GripperReading {
            opening_m: quantize(truth.opening_m, self.opening_step_m),
            current_a,
            force_n: current_a * self.force_per_amp,
            object_detected: truth.stalled && current_a >= self.detect_a,
            stalled: truth.stalled,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_force_is_read_from_the_current_not_from_the_world() {
        let s = GripperSensing::default();
        let truth = GripperTruth {
            opening_m: 0.081_234,
            force_n: 10.0,
            stalled: true,
        };
        // A gripper whose true constant is 20 % high reads 20 % less current, so less force.
        let mut rng = SplitMix64::new(3);
        let n = 2000;
        let mean = |gain: f64, rng: &mut SplitMix64| {
            (0..n)
                .map(|_| s.read(&truth, gain, rng).force_n)
                .sum::<f64>()
                / f64::from(n)
        };
        let nominal = mean(1.0, &mut rng);
        let high = mean(1.2, &mut rng);
        assert!((nominal - 10.0).abs() < 0.2, "{nominal}");
        assert!((high - 10.0 / 1.2).abs() < 0.2, "{high}");
        let r = s.read(&truth, 1.0, &mut rng);
        // Current on the 10 mA grid, opening on the 0.1 mm grid.
        assert!((r.current_a / 0.01 - (r.current_a / 0.01).round()).abs() < 1e-9);
        assert!((r.opening_m - 0.0812).abs() < 1e-12);
        assert!(r.object_detected);
        // No force, no object, whatever the stall says.
        let idle = GripperTruth {
            force_n: 0.0,
            ..truth
        };
        assert!((0..100).all(|_| !s.read(&idle, 1.0, &mut rng).object_detected));
    }
}
