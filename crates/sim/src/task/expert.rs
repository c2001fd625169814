//! The scripted expert: a function (truth, trial, config, decision) -> command per control tick
//! that solves both tasks, and the demonstration record the reference policies are fitted on.
//!
//! The expert reads the truth only for what a teleoperator sees: where the objects were placed,
//! the fingers' geometry (what is between them, how long each fabric was pressed, where the arm
//! is) and the visible deformation. Whatever a policy could not see, it does not decide from:
//! the fabric to grasp is the caller's decision, made from what the imitating mode observes
//! (crates/trials demos.rs: the live PropertyComparison for vtla_real, the camera's roughness
//! guesses for vla and vtla_pred; [`run_expert`] here: the camera's, [`camera_choice`]).
//!
//! Cup: open wide, bring the fingertips to half the cup's height, close at 20 mm/s to the opening
//! at which the world's static equilibrium gives the target deformation
//! ([`static_finger_for`] on the cup's wall: the squeeze whose settled deformation is the
//! target), wait until the wall has settled there, lift 5 cm.
//!
//! Fabric:
//!
//! ```text
//! touch A:   pinch fabric A at its single-layer height with 1.5 N until pressed 0.3 s
//! release A: open wide (the contact episode ends: the encoder sees A's clip)
//! touch B:   the same on fabric B
//! release B: open wide at B and wait, open, for the caller's decision
//! grasp:     pinch the chosen fabric at its single-layer height with twice the force friction
//!            needs to carry it (the first close after both touches: the grasp attempt)
//! lift:      8 cm
//! ```
//!
//! Stateless: the phase follows from what is seen (what is between the fingers, how long each
//! fabric was pressed, where the arm is) and the decision passed in.

use serde::Serialize;

use super::{
    ArmSetpoint, ArmTarget, GripperSetpoint, TaskCommand, TaskConfig, TaskKind, TaskOutcome,
    TaskTruth, TaskWorld, TrialSpec, VisualObservation, trial_rng,
};
use crate::world::{WorldError, static_finger_for};

/// How long a fabric is pressed before the expert counts it as touched \[s].
pub const TOUCH_DWELL_S: f64 = 0.3;
/// Lift heights of the expert \[m].
pub const CUP_LIFT_M: f64 = 0.05;
pub const FABRIC_LIFT_M: f64 = 0.08;
/// Closing speed on contact \[m/s] and the touch force \[N].
const CLOSE_M_S: f64 = 0.02;
const TOUCH_FORCE_N: f64 = 1.5;
/// Most control ticks one demonstration may record.
pub const MAX_DEMO_STEPS: usize = 100_000;

/// A command toward the object called `target` (placed at `xy_m`: the expert reads where the
/// trial placed it, the truth).
fn command(
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
fn placed<'a>(spec: &TrialSpec, name: &'a str) -> (&'a str, [f64; 2]) {
    (name, spec.object(name).map_or([0.0, 0.0], |o| o.placed_m))
}

/// The expert's command for this tick. `choice`: the fabric to grasp, once the caller has
/// decided (fabric; None until then: the expert touches both, lets go and waits open; see
/// [`fabric_touched_both`]). The cup task ignores it.
pub fn expert_command(
    truth: &TaskTruth,
    spec: &TrialSpec,
    cfg: &TaskConfig,
    choice: Option<&str>,
) -> TaskCommand {
    match cfg.kind {
        TaskKind::Cup => cup_command(truth, spec, cfg),
        TaskKind::Fabric => fabric_command(truth, spec, cfg, choice),
    }
}

fn home(cfg: &TaskConfig) -> TaskCommand {
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

fn cup_command(t: &TaskTruth, spec: &TrialSpec, cfg: &TaskConfig) -> TaskCommand {
    let Some(cup) = spec.cup() else {
        return home(cfg);
    };
    let g = cfg.gripper;
    let z = 0.5 * cup.height_m;
    let target_mm = cfg.cup_criteria.target_deformation_m * 1e3;
    let finger_mm = static_finger_for(&cup.wall, &cfg.gel, target_mm, g.max_force_n);
    let squeeze = (cup.diameter_m - 2.0 * finger_mm * 1e-3 + 2.0 * g.pad_m).max(0.0);
    let wide = (cup.diameter_m + 0.02 + 2.0 * g.pad_m).min(g.max_opening_m);
    let around = t.contact.object == "cup";
    // Once the lift is under way (the arm heads above the grasp height, the cup in the grip),
    // keep lifting; start it when the wall has settled at the squeeze.
    let lifting = around && t.gripper.force_n > 0.0 && t.arm.target_m[2] > z + 1e-4;
    let settled = around
        && t.arm.arrived
        && (t.gripper.opening_m - squeeze).abs() < 5e-5
        && t.contact.deformation_rate_m_s.abs() < 1e-3;
    if lifting || settled {
        command(
            squeeze,
            CLOSE_M_S,
            g.max_force_n,
            placed(spec, "cup"),
            z,
            CUP_LIFT_M,
        )
    } else if around && (t.arm.arrived || t.gripper.force_n > 0.0) {
        command(
            squeeze,
            CLOSE_M_S,
            g.max_force_n,
            placed(spec, "cup"),
            z,
            0.0,
        )
    } else {
        command(
            wide,
            g.max_speed_m_s,
            g.max_force_n,
            placed(spec, "cup"),
            z,
            0.0,
        )
    }
}

/// Whether fabric `name` has been pressed long enough to count as touched.
fn touched(t: &TaskTruth, name: &str) -> bool {
    t.objects
        .iter()
        .any(|o| o.name == name && o.touch_s >= TOUCH_DWELL_S)
}

/// The opening at which the fingers are clear of fabric `f` \[m].
fn fabric_wide(f: &super::FabricSpec, cfg: &TaskConfig) -> f64 {
    f.stack_m() + 0.01 + 2.0 * cfg.gripper.pad_m
}

/// Whether the fabric expert has touched both fabrics and let go of the second (the fingers
/// pressing nothing, open clear of the fabric they are around): the point at which it waits for
/// the decision ([`expert_command`]'s `choice`).
pub fn fabric_touched_both(t: &TaskTruth, spec: &TrialSpec, cfg: &TaskConfig) -> bool {
    let names: Vec<&str> = spec
        .objects
        .iter()
        .filter(|o| spec.fabric(&o.name).is_some())
        .map(|o| o.name.as_str())
        .collect();
    if names.is_empty() || !names.iter().all(|n| touched(t, n)) {
        return false;
    }
    let clear = match spec.fabric(&t.contact.object) {
        Some(f) => t.gripper.opening_m >= fabric_wide(f, cfg) - 1e-4,
        None => true,
    };
    t.gripper.force_n <= 0.0 && clear
}

/// The fabric whose camera roughness guess (`<name>.roughness_ra_m`, from `roughness`: the
/// camera's estimate the caller keeps, e.g. its mean so far) is the lowest; the first on a tie,
/// None when no fabric has a guess.
pub fn camera_choice(spec: &TrialSpec, roughness: impl Fn(&str) -> Option<f64>) -> Option<&str> {
    let mut best: Option<(&str, f64)> = None;
    for o in &spec.objects {
        if spec.fabric(&o.name).is_none() {
            continue;
        }
        let Some(r) = roughness(&format!("{}.roughness_ra_m", o.name)).filter(|r| r.is_finite())
        else {
            continue;
        };
        if best.is_none_or(|(_, b)| r < b) {
            best = Some((&o.name, r));
        }
    }
    best.map(|(n, _)| n)
}

fn fabric_command(
    t: &TaskTruth,
    spec: &TrialSpec,
    cfg: &TaskConfig,
    choice: Option<&str>,
) -> TaskCommand {
    let g = cfg.gripper;
    let first = spec.objects.first().map_or("", |o| o.name.as_str());
    let second = spec.objects.get(1).map_or("", |o| o.name.as_str());
    let (goal, grasp) = if !touched(t, first) {
        (first, false)
    } else if !touched(t, second) {
        (second, false)
    } else if let Some(c) = choice {
        (c, true)
    } else {
        // Both touched, no decision yet: let go of the second and wait there, open.
        ("", false)
    };
    // Let go of another fabric before moving on (and of the second while undecided).
    let other = t.contact.object.as_str();
    if !other.is_empty()
        && other != goal
        && let Some(o) = spec.fabric(other)
    {
        let wide = fabric_wide(o, cfg);
        if t.gripper.force_n > 0.0 || t.gripper.opening_m < wide - 1e-4 || goal.is_empty() {
            return command(
                wide,
                g.max_speed_m_s,
                TOUCH_FORCE_N,
                placed(spec, other),
                o.single_layer_z_m(),
                0.0,
            );
        }
    }
    let goal = if goal.is_empty() { second } else { goal };
    let Some(f) = spec.fabric(goal) else {
        return home(cfg);
    };
    let z = f.single_layer_z_m();
    let wide = fabric_wide(f, cfg);
    if !grasp && touched(t, goal) {
        // Undecided, away from the fabrics' grip: wait open above the second one.
        return command(
            wide,
            g.max_speed_m_s,
            TOUCH_FORCE_N,
            placed(spec, goal),
            z,
            0.0,
        );
    }
    let around = t.contact.object == goal;
    let force = if grasp {
        // Twice what static friction must carry at the top of the lift, accelerating.
        let (m, down) = f.load(FABRIC_LIFT_M, 0.1);
        let need = down + m * cfg.arm.max_accel_m_s2;
        (need / f.friction_static).max(TOUCH_FORCE_N)
    } else {
        TOUCH_FORCE_N
    };
    let lifting = around && grasp && t.gripper.force_n > 0.0 && t.arm.target_m[2] > z + 1e-4;
    let gripped = around && grasp && t.arm.arrived && t.gripper.force_n >= 0.9 * force;
    if lifting || gripped {
        command(0.0, CLOSE_M_S, force, placed(spec, goal), z, FABRIC_LIFT_M)
    } else if around && (t.arm.arrived || t.gripper.force_n > 0.0) {
        command(0.0, CLOSE_M_S, force, placed(spec, goal), z, 0.0)
    } else {
        command(wide, g.max_speed_m_s, force, placed(spec, goal), z, 0.0)
    }
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

/// Run the expert for `duration_s` at control period `dt_s` on trial `trial` of `seed`. The
/// fabric to grasp is the camera's: once both are touched ([`fabric_touched_both`]), the one
/// whose roughness guess, averaged over the camera's frames so far, is the lowest
/// ([`camera_choice`]); what a vision-only policy could decide, right or wrong.
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
        if choice.is_none() && cfg.kind == TaskKind::Fabric && fabric_touched_both(t, spec, cfg) {
            let mean = |name: &str| {
                let i = seen.names.iter().position(|n| n == name)?;
                sum.get(i).map(|s| s / frames)
            };
            choice = camera_choice(spec, mean).map(str::to_string);
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

/// A size-blind cup grip, the baseline that shows the task is not trivial: the expert's approach
/// and lift, but it always closes to one opening (e.g. the one learned on a training cup) instead
/// of the cup's own, and lifts once the fingers stop (reached or stalled).
pub fn fixed_opening_command(
    t: &TaskTruth,
    spec: &TrialSpec,
    cfg: &TaskConfig,
    opening_m: f64,
) -> TaskCommand {
    let Some(cup) = spec.cup() else {
        return home(cfg);
    };
    let g = cfg.gripper;
    let z = 0.5 * cup.height_m;
    let wide = (cup.diameter_m + 0.02 + 2.0 * g.pad_m).min(g.max_opening_m);
    let around = t.contact.object == "cup";
    let lifting = around && t.gripper.force_n > 0.0 && t.arm.target_m[2] > z + 1e-4;
    let stopped = around
        && t.arm.arrived
        && ((t.gripper.opening_m - opening_m).abs() < 1e-4 || t.gripper.stalled);
    if lifting || stopped {
        command(
            opening_m,
            CLOSE_M_S,
            g.max_force_n,
            placed(spec, "cup"),
            z,
            CUP_LIFT_M,
        )
    } else if around && (t.arm.arrived || t.gripper.force_n > 0.0) {
        command(
            opening_m,
            CLOSE_M_S,
            g.max_force_n,
            placed(spec, "cup"),
            z,
            0.0,
        )
    } else {
        command(
            wide,
            g.max_speed_m_s,
            g.max_force_n,
            placed(spec, "cup"),
            z,
            0.0,
        )
    }
}

/// Control period and duration the example and tests run the expert at \[s].
pub fn default_run(kind: TaskKind) -> (f64, f64) {
    match kind {
        TaskKind::Cup => (1.0 / 30.0, 6.0),
        TaskKind::Fabric => (1.0 / 30.0, 12.0),
    }
}
