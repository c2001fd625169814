//! The scripted expert: a function (truth, trial, config, decision) -> command per control tick,
//! each task's own ([`super::Task::expert`]: the cup's in [`super::cup_deformation`], the
//! fabrics' in [`super::fabric_selection`]), and the demonstration record the reference policies
//! are fitted on.
//!
//! The expert reads the truth only for what a teleoperator sees: where the objects were placed,
//! the fingers' geometry (what is between them, how long each object was pressed, where the arm
//! is) and the visible deformation. Whatever a policy could not see, it does not decide from:
//! the object to grasp is the caller's decision, made from what the imitating mode observes
//! (crates/trials demos.rs: the live PropertyComparison for vtla_real, the camera's guesses for
//! vla and vtla_pred; [`run_expert`] here: the camera's, [`super::Task::camera_choice`]).
//!
//! Stateless: the phase follows from what is seen and the decision passed in.

use serde::Serialize;

use super::{
    ArmSetpoint, ArmTarget, GripperSetpoint, TaskCommand, TaskConfig, TaskOutcome, TaskTruth,
    TaskWorld, TrialSpec, VisualObservation, trial_rng,
};
use crate::world::WorldError;

/// Closing speed on contact \[m/s].
pub(super) const CLOSE_M_S: f64 = 0.02;
/// Most control ticks one demonstration may record.
pub const MAX_DEMO_STEPS: usize = 100_000;

/// A command toward the object called `target` (placed at `xy_m`: the expert reads where the
/// trial placed it, the truth).
pub(super) fn command(
    opening_m: f64,
    speed_m_s: f64,
    force_n: f64,
    (target, xy_m): (&str, [f64; 2]),
    z_m: f64,
    lift_m: f64,
) -> TaskCommand {
    TaskCommand {
        gripper: GripperSetpoint {
            opening_m,
            speed_m_s,
            force_n,
        },
        arm: ArmSetpoint {
            target: ArmTarget::named(target),
            xy_m,
            z_m,
            lift_m,
        },
    }
}

/// The object called `name` and where the trial placed it (truth).
pub(super) fn placed<'a>(spec: &TrialSpec, name: &'a str) -> (&'a str, [f64; 2]) {
    (name, spec.object(name).map_or([0.0, 0.0], |o| o.placed_m))
}

/// The expert's command for this tick: the task's ([`super::Task::expert`]). `choice`: the
/// object to grasp, once the caller has decided (tasks that decide; None until then).
pub fn expert_command(
    truth: &TaskTruth,
    spec: &TrialSpec,
    cfg: &TaskConfig,
    choice: Option<&str>,
) -> TaskCommand {
    cfg.kind.expert(truth, spec, cfg, choice)
}

pub(super) fn home(cfg: &TaskConfig) -> TaskCommand {
    let g = cfg.gripper;
    command(
        g.max_opening_m,
        g.max_speed_m_s,
        0.0,
        ("home", [0.0, 0.0]),
        0.0,
        0.0,
    )
}

/// One control tick of a demonstration: what was observed (truth and camera) at `t_s` and the
/// command given then.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DemoStep {
    pub t_s: f64,
    pub truth: TaskTruth,
    pub visual: VisualObservation,
    pub command: TaskCommand,
}

/// A demonstration: the trial, the ticks, and the outcome at the end.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Demonstration {
    pub spec: TrialSpec,
    pub dt_s: f64,
    pub steps: Vec<DemoStep>,
    pub final_truth: TaskTruth,
    pub outcome: TaskOutcome,
}

/// Salt of the camera's per-frame noise stream (separate from the trial's draw).
const VISION_SALT: u64 = 0x5649_5349_4F4E_0001;

/// Run the expert for `duration_s` at control period `dt_s` on trial `trial` of `seed`. In a task
/// that decides, the object to grasp is the camera's: once the expert waits for the decision
/// ([`super::Task::awaits_decision`]), the task's [`super::Task::camera_choice`] from the
/// camera's values averaged over its frames so far; what a vision-only policy could decide,
/// right or wrong.
pub fn run_expert(
    cfg: &TaskConfig,
    seed: u64,
    trial: u32,
    dt_s: f64,
    duration_s: f64,
) -> Result<Demonstration, WorldError> {
    let mut sum: Vec<f64> = Vec::new();
    let mut frames = 0.0;
    let mut choice: Option<String> = None;
    run_seeing(cfg, seed, trial, dt_s, duration_s, |t, spec, seen| {
        if sum.len() != seen.values.len() {
            sum = vec![0.0; seen.values.len()];
            frames = 0.0;
        }
        for (s, v) in sum.iter_mut().zip(&seen.values) {
            *s += v;
        }
        frames += 1.0;
        if choice.is_none() && cfg.kind.decides() && cfg.kind.awaits_decision(t, spec, cfg) {
            let mean = |name: &str| {
                let i = seen.names.iter().position(|n| n == name)?;
                sum.get(i).map(|s| s / frames)
            };
            choice = cfg.kind.camera_choice(spec, &mean).map(str::to_string);
        }
        expert_command(t, spec, cfg, choice.as_deref())
    })
}

/// Run `policy` (truth and trial -> command; a baseline or the expert: they may read truth) for
/// `duration_s` at control period `dt_s` on trial `trial` of `seed`, recorded tick by tick.
pub fn run_policy(
    cfg: &TaskConfig,
    seed: u64,
    trial: u32,
    dt_s: f64,
    duration_s: f64,
    mut policy: impl FnMut(&TaskTruth, &TrialSpec) -> TaskCommand,
) -> Result<Demonstration, WorldError> {
    run_seeing(cfg, seed, trial, dt_s, duration_s, |t, spec, _| {
        policy(t, spec)
    })
}

/// [`run_policy`] with the policy also given the camera's observation of the tick.
fn run_seeing(
    cfg: &TaskConfig,
    seed: u64,
    trial: u32,
    dt_s: f64,
    duration_s: f64,
    mut policy: impl FnMut(&TaskTruth, &TrialSpec, &VisualObservation) -> TaskCommand,
) -> Result<Demonstration, WorldError> {
    if !(dt_s.is_finite() && dt_s > 0.0 && dt_s <= super::MAX_STEP_S) {
        return Err(WorldError::BadStep(dt_s));
    }
    let n = (duration_s / dt_s).ceil();
    if !(n.is_finite() && n >= 1.0 && n <= MAX_DEMO_STEPS as f64) {
        return Err(WorldError::BadCommand {
            field: "duration_s",
            value: duration_s,
            why: "must be positive and at most MAX_DEMO_STEPS control periods",
        });
    }
    let mut w = TaskWorld::reset(cfg, seed, trial);
    let mut rng = trial_rng(seed ^ VISION_SALT, trial);
    let mut truth = w.truth();
    let mut steps = Vec::with_capacity(n as usize);
    for _ in 0..n as usize {
        let visual = w.observe_visual(&mut rng);
        let cmd = policy(&truth, w.spec(), &visual);
        let next = w.step(&cmd, dt_s)?;
        steps.push(DemoStep {
            t_s: truth.t_s,
            truth,
            visual,
            command: cmd,
        });
        truth = next;
    }
    Ok(Demonstration {
        spec: w.spec().clone(),
        dt_s,
        steps,
        final_truth: truth,
        outcome: w.outcome(),
    })
}
