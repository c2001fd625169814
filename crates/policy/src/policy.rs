//! The one place a policy plugs in: [`Policy`] maps an observation to an action chunk. The scene
//! controllers implement it; so does the ONNX policy (src/onnx). Whatever it returns goes through
//! the safety layer before it becomes a command.

use crate::observation::Observation;
use thiserror::Error;
use unitac_core::msg::GripperMode;

/// What the gripper should do (SI units), before the safety layer.
#[derive(Debug, Clone, PartialEq)]
pub struct GripperAction {
    pub mode: GripperMode,
    /// Finger opening \[m]: the target (position mode) or the opening to close toward (force).
    pub position_m: f64,
    pub speed_m_s: f64,
    /// Force target (force mode) or limit (position mode) \[N].
    pub force_n: f64,
}

/// Where the arm should bring the fingers (SI units), before the safety layer.
#[derive(Debug, Clone, PartialEq)]
pub struct ArmAction {
    /// "home" or an object name of the scene.
    pub target: String,
    /// Where over the table (table frame): the policy's estimate of the target's place, from
    /// its observations \[m].
    pub x_m: f64,
    pub y_m: f64,
    pub z_m: f64,
    pub lift_m: f64,
}

/// One control tick's action.
#[derive(Debug, Clone, PartialEq)]
pub struct Action {
    pub gripper: GripperAction,
    pub arm: ArmAction,
    /// Why (goes into the commands' reason and PolicyStatus.message).
    pub note: String,
}

impl Action {
    /// The numbers of the action with their names (for the finiteness check and for policies
    /// that output a flat vector, e.g. `action.gripper.position_m`).
    pub fn values(&self) -> [(&'static str, f64); 7] {
        let [position, speed, force, x, y, z, lift] = crate::schema::COMMANDS;
        [
            (position, self.gripper.position_m),
            (speed, self.gripper.speed_m_s),
            (force, self.gripper.force_n),
            (x, self.arm.x_m),
            (y, self.arm.y_m),
            (z, self.arm.z_m),
            (lift, self.arm.lift_m),
        ]
    }
}

/// A policy's failure at one tick: the safety layer answers it with the safe action.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum PolicyError {
    #[error("timed out: {0}")]
    Timeout(String),
    /// An inference ran past its time limit and was stopped (the model's id and the figures).
    #[error("inference over budget: {0}")]
    OverBudget(String),
    #[error("{0}")]
    Failed(String),
}

/// Observation -> action chunk (the actions of the next ticks, first first; at least one).
pub trait Policy: Send + std::fmt::Debug {
    /// The current phase (PolicyStatus.phase).
    fn phase(&self) -> &str;
    /// The inputs that must be fresh and valid now; the watchdog answers any other state of one
    /// of them with the safe action before the policy is asked.
    fn required(&self) -> Vec<&'static str>;
    /// The inputs whose producer must be alive now: the required ones, plus those the policy is
    /// still waiting for (e.g. the probe touch's latent). A transport that sees the producer of
    /// one of them disappear tells the stage ([`crate::PolicyStage::set_input_lost`]), and the
    /// safe action follows in that tick.
    fn awaited(&self) -> Vec<&'static str> {
        self.required()
    }
    fn act(&mut self, obs: &Observation) -> Result<Vec<Action>, PolicyError>;
    /// What the policy clamped inside itself since it was last asked (e.g. a readout beyond its
    /// range: `readout.stiffness`), reported in PolicyStatus.clamped with the safety layer's.
    fn take_clamped(&mut self) -> Vec<&'static str> {
        Vec::new()
    }
}
