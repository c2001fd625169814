//! The fabric selection task (the paper's towel selection and grasp): two folded fabrics of
//! different types ([`super::fabric`]) that a camera cannot tell apart; touch both, decide which
//! is the smoother, grasp a single layer of it at the fold and lift it without slip. Selection
//! and grasp are scored apart, as in the paper.
//!
//! The expert:
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
//! The paper's counts (real robot, 20 trials per mode): selection 11, 20, 18; grasp 6, 19, 16;
//! overall 4, 19, 16 (VLA, VTLA-real, VTLA-pred).

use super::expert::{CLOSE_M_S, command, home, placed};
use super::kind::{Judged, Task};
use super::observe::per_object;
use super::split::{FabricType, SPLIT};
use super::{
    FabricOutcome, FabricSpec, ObjectSpec, Split, TaskCommand, TaskConfig, TaskObject, TaskOutcome,
    TaskTruth, TrialSpec, Uniform,
};
use crate::rng::SplitMix64;

/// How long a fabric is pressed before the expert counts it as touched \[s].
pub const TOUCH_DWELL_S: f64 = 0.3;
/// Lift height of the expert \[m].
pub const FABRIC_LIFT_M: f64 = 0.08;
/// The expert's touch force \[N].
const TOUCH_FORCE_N: f64 = 1.5;

/// The fabric selection task.
#[derive(Debug, Clone, Copy)]
pub struct FabricSelection;

impl Task for FabricSelection {
    fn name(&self) -> &'static str {
        "fabric_selection"
    }
    fn objects(&self) -> &'static str {
        "fabrics"
    }
    fn describe(&self, split: Split) -> String {
        match split {
            Split::Unseen => "fabric selection, unseen fabric types".into(),
            Split::Train => "fabric selection, training fabric types".into(),
        }
    }

    fn draw(&self, cfg: &TaskConfig, rng: &mut SplitMix64) -> Vec<TaskObject> {
        let v = &cfg.fabric;
        let types: Vec<&FabricType> = v
            .types
            .iter()
            .filter_map(|t| SPLIT.fabrics.get(t))
            .collect();
        let n = types.len();
        // Two different types (the build script checks each split lists two or more).
        let i = ((rng.uniform() * n as f64) as usize).min(n.saturating_sub(1));
        let j = ((rng.uniform() * n.saturating_sub(1) as f64) as usize).min(n.saturating_sub(2));
        let j = if j >= i { j + 1 } else { j };
        [("fabric_a", i, 0), ("fabric_b", j, 1)]
            .into_iter()
            .filter_map(|(name, k, place)| {
                let f = FabricSpec::draw(types.get(k)?, v, rng);
                let s = Uniform(-v.spread_m, v.spread_m);
                let p = v.places_m[place];
                Some(TaskObject {
                    name: name.into(),
                    spec: ObjectSpec::Fabric(f),
                    placed_m: [p[0] + s.draw(rng), p[1] + s.draw(rng)],
                })
            })
            .collect()
    }
    fn visual_names(&self) -> Vec<String> {
        let f = ["x_m", "y_m", "z_m", "edge_height_m"];
        let mut v = per_object("fabric_a", &f);
        v.extend(per_object("fabric_b", &f));
        // Last, so that the other values' per-trial bias draws stay what they were.
        v.extend(per_object("fabric_a", &["roughness_ra_m"]));
        v.extend(per_object("fabric_b", &["roughness_ra_m"]));
        v
    }

    fn criteria(&self) -> &'static [&'static str] {
        &["selection", "grasp", "overall"]
    }
    fn judge(&self, cfg: &TaskConfig, j: &Judged) -> TaskOutcome {
        let name = |i: Option<usize>| {
            i.and_then(|i| j.truth.objects.get(i))
                .map_or("", |o| o.name.as_str())
        };
        // The decision: the object of the first grasp attempt, else the one the policy
        // announced, else the one it holds.
        let chosen = name(j.attempted.or(j.announced).or(j.held));
        TaskOutcome::Fabric(FabricOutcome::judge(
            &cfg.fabric_criteria,
            chosen,
            name(j.held),
            j.spec.smoother(),
            if j.held.is_some() {
                j.truth.contact.layers
            } else {
                0
            },
            j.lift_m,
            j.truth.contact.slip_total_m,
            j.truth.collision,
        ))
    }
    fn paper(&self, criterion: &str, mode: &str) -> Option<u32> {
        let row: [u32; 3] = match criterion {
            "selection" => [11, 20, 18],
            "grasp" => [6, 19, 16],
            "overall" => [4, 19, 16],
            _ => return None,
        };
        super::kind::paper_column(row, mode)
    }

    fn expert(
        &self,
        truth: &TaskTruth,
        spec: &TrialSpec,
        cfg: &TaskConfig,
        choice: Option<&str>,
    ) -> TaskCommand {
        fabric_command(truth, spec, cfg, choice)
    }
    fn decides(&self) -> bool {
        true
    }
    fn awaits_decision(&self, truth: &TaskTruth, spec: &TrialSpec, cfg: &TaskConfig) -> bool {
        fabric_touched_both(truth, spec, cfg)
    }
    fn camera_choice<'a>(
        &self,
        spec: &'a TrialSpec,
        seen: &dyn Fn(&str) -> Option<f64>,
    ) -> Option<&'a str> {
        camera_choice(spec, seen)
    }

    fn expert_run(&self) -> (f64, f64) {
        (1.0 / 30.0, 12.0)
    }
    fn trial_s(&self) -> f64 {
        90.0
    }
}

/// Whether fabric `name` has been pressed long enough to count as touched.
fn touched(t: &TaskTruth, name: &str) -> bool {
    t.objects
        .iter()
        .any(|o| o.name == name && o.touch_s >= TOUCH_DWELL_S)
}

/// The opening at which the fingers are clear of fabric `f` \[m].
fn fabric_wide(f: &FabricSpec, cfg: &TaskConfig) -> f64 {
    f.stack_m() + 0.01 + 2.0 * cfg.gripper.pad_m
}

/// Whether the fabric expert has touched both fabrics and let go of the second (the fingers
/// pressing nothing, open clear of the fabric they are around): the point at which it waits for
/// the decision (the expert's `choice`).
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
