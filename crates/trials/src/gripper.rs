//! The gripper side of a trial, behind one seam: what the policy reads of the gripper each tick,
//! what the world's gripper is driven with, and what happens after the world steps.
//!
//! Two sides:
//! - in-process (`sim`, the default): the world's own gripper, its status read from the
//!   world's gripper through its measurement model ([`crate::bridge::GripperGauge`]) and the
//!   command passed through unchanged;
//! - serial ([`crate::serial`]): the real Modbus RTU driver talking to a simulated device on a
//!   pseudo-terminal whose fingers are the world's gripper.
//!
//! Per tick the loop calls `GripperSide::status` (the world after the previous step), then
//! `GripperSide::command` with the policy's setpoint (it returns the setpoint the world is
//! stepped with), then, after the step, `GripperSide::stepped` with the world's new truth.

use crate::bridge::GripperGauge;
use crate::serial::{SerialError, SerialReport, SerialSide};
use std::fmt;
use std::str::FromStr;
use unitac_core::msg::GripperStatus;
use unitac_gripper::{Model, UnknownModel};
use unitac_sim::task::{GripperSetpoint, TaskTruth};

/// Which gripper a trial drives.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum TrialGripper {
    /// The task world's gripper, in process.
    #[default]
    InProcess,
    /// The serial driver and a simulated device of this model on a pty, its fingers the world's.
    Serial(Model),
}

impl TrialGripper {
    /// The grippers a trial can drive: the world's own, then each serial model (in
    /// [`Model::all`]'s order, by name) whose stroke opens around the narrowest unseen cup with a gel pad
    /// on each finger (objects/split.yaml; 84 + 2 x 3 mm): a narrower one collides with every
    /// unseen cup.
    pub fn offered() -> Vec<TrialGripper> {
        let narrowest_m = unitac_sim::task::split::SPLIT.cups.unseen_diameter_m.0
            + 2.0 * unitac_sim::task::GripperLimits::default().pad_m;
        std::iter::once(TrialGripper::InProcess)
            .chain(
                Model::all()
                    .into_iter()
                    .filter(|m| m.calibration().limits.max_opening_m >= narrowest_m)
                    .map(TrialGripper::Serial),
            )
            .collect()
    }

    /// `sim` or the model's name.
    pub fn name(self) -> &'static str {
        match self {
            TrialGripper::InProcess => "sim",
            TrialGripper::Serial(m) => m.name(),
        }
    }

    /// Start the side for a world whose truth at reset is `truth`; `gauge` reads the world's
    /// gripper in process.
    pub(crate) fn start(
        self,
        truth: &TaskTruth,
        gauge: GripperGauge,
    ) -> Result<Box<dyn GripperSide>, SerialError> {
        Ok(match self {
            TrialGripper::InProcess => Box::new(InProcess {
                target_m: f64::NAN,
                gauge,
            }),
            TrialGripper::Serial(m) => Box::new(SerialSide::start(m, truth)?),
        })
    }
}

impl fmt::Display for TrialGripper {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A trial gripper name that is neither `sim` nor a gripper model.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{0}, or sim")]
pub struct UnknownTrialGripper(pub UnknownModel);

impl FromStr for TrialGripper {
    type Err = UnknownTrialGripper;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        if s == "sim" {
            return Ok(TrialGripper::InProcess);
        }
        s.parse::<Model>()
            .map(TrialGripper::Serial)
            .map_err(UnknownTrialGripper)
    }
}

/// One trial's gripper.
pub(crate) trait GripperSide {
    /// The status the policy sees at the world's time `truth.t_s`.
    fn status(&mut self, truth: &TaskTruth) -> Result<GripperStatus, SerialError>;
    /// The policy's setpoint in; the setpoint the world's gripper is stepped with out.
    fn command(&mut self, want: GripperSetpoint) -> Result<GripperSetpoint, SerialError>;
    /// The world stepped; `truth` is its new state.
    fn stepped(&mut self, truth: &TaskTruth) -> Result<(), SerialError>;
    /// What went over the wire (None in process).
    fn report(&self) -> Option<SerialReport>;
}

/// The world's own gripper, read through its measurement model.
struct InProcess {
    /// The opening the last command asked for (NaN before the first).
    target_m: f64,
    gauge: GripperGauge,
}

impl GripperSide for InProcess {
    fn status(&mut self, truth: &TaskTruth) -> Result<GripperStatus, SerialError> {
        Ok(self.gauge.status(truth, self.target_m))
    }
    fn command(&mut self, want: GripperSetpoint) -> Result<GripperSetpoint, SerialError> {
        self.target_m = want.opening_m;
        Ok(want)
    }
    fn stepped(&mut self, _truth: &TaskTruth) -> Result<(), SerialError> {
        Ok(())
    }
    fn report(&self) -> Option<SerialReport> {
        None
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn names_parse_back() {
        for g in [
            TrialGripper::InProcess,
            TrialGripper::Serial(Model::named("robotiq_2f140").unwrap()),
            TrialGripper::Serial(Model::named("dh_ag95").unwrap()),
        ] {
            assert_eq!(g.name().parse::<TrialGripper>().unwrap(), g);
        }
        let e = "robotiq_3f"
            .parse::<TrialGripper>()
            .unwrap_err()
            .to_string();
        assert!(e.contains("robotiq_2f140") && e.ends_with("or sim"), "{e}");
    }

    #[test]
    fn offered_are_the_world_and_the_models_that_open_around_an_unseen_cup() {
        // 84 mm + two 3 mm pads: the 85 mm 2F-85 and the 50 mm PGE-50 cannot.
        assert_eq!(
            TrialGripper::offered(),
            [
                TrialGripper::InProcess,
                TrialGripper::Serial(Model::named("dh_ag95").unwrap()),
                TrialGripper::Serial(Model::named("robotiq_2f140").unwrap()),
            ]
        );
    }
}
