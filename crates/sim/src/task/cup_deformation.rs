//! The cup deformation task (the paper's unseen-size cup deformation grasp): one cup
//! ([`super::cup`]) placed in front of the robot; grasp it, compress its wall by the target
//! (1 cm, +- 2 mm, never beyond) and lift it. The camera reports the cup's place and size.
//!
//! The expert: open wide, bring the fingertips to half the cup's height, close at 20 mm/s to the
//! opening at which the world's static equilibrium gives the target deformation
//! ([`static_finger_for`] on the cup's wall: the squeeze whose settled deformation is the
//! target), wait until the wall has settled there, lift 5 cm.
//!
//! The paper's counts (real robot, 20 trials per mode): lift 18, 20, 19; target deformation 0,
//! 20, 18; overall 0, 20, 18 (VLA, VTLA-real, VTLA-pred).

use super::expert::{CLOSE_M_S, command, home, placed};
use super::kind::{Judged, PlotKind, Sweep, Task};
use super::observe::per_object;
use super::split::SPLIT;
use super::{
    CupOutcome, CupSpec, ObjectSpec, Split, TaskCommand, TaskConfig, TaskObject, TaskOutcome,
    TaskTruth, TrialSpec, Uniform,
};
use crate::rng::SplitMix64;
use crate::world::static_finger_for;

/// Lift height of the expert \[m].
pub const CUP_LIFT_M: f64 = 0.05;

/// The cup deformation task.
#[derive(Debug, Clone, Copy)]
pub struct CupDeformation;

impl Task for CupDeformation {
    fn name(&self) -> &'static str {
        "cup_deformation"
    }
    fn objects(&self) -> &'static str {
        "cups"
    }
    fn describe(&self, split: Split) -> String {
        let c = SPLIT.cups;
        let (which, d) = match split {
            Split::Unseen => ("unseen", c.unseen_diameter_m),
            Split::Train => ("training", c.train_diameter_m),
        };
        format!("{which} cups ({:.0}-{:.0} mm)", d.0 * 1e3, d.1 * 1e3)
    }

    fn draw(&self, cfg: &TaskConfig, rng: &mut SplitMix64) -> Vec<TaskObject> {
        vec![draw_cup(cfg, rng)]
    }
    fn visual_names(&self) -> Vec<String> {
        cup_visual_names()
    }

    fn criteria(&self) -> &'static [&'static str] {
        &["lift", "target deformation", "overall"]
    }
    fn judge(&self, cfg: &TaskConfig, j: &Judged) -> TaskOutcome {
        let held = j.held.is_some();
        TaskOutcome::Cup(CupOutcome::judge(
            &cfg.cup_criteria,
            held,
            j.lift_m,
            if held {
                j.truth.contact.deformation_m
            } else {
                0.0
            },
            j.truth.peak_deformation_m,
            j.truth.collision,
        ))
    }
    fn paper(&self, criterion: &str, mode: &str) -> Option<u32> {
        let row: [u32; 3] = match criterion {
            "lift" => [18, 20, 19],
            "target deformation" => [0, 20, 18],
            "overall" => [0, 20, 18],
            _ => return None,
        };
        super::kind::paper_column(row, mode)
    }

    fn expert(
        &self,
        truth: &TaskTruth,
        spec: &TrialSpec,
        cfg: &TaskConfig,
        _choice: Option<&str>,
    ) -> TaskCommand {
        cup_command(truth, spec, cfg)
    }

    fn expert_run(&self) -> (f64, f64) {
        (1.0 / 30.0, 6.0)
    }
    fn trial_s(&self) -> f64 {
        40.0
    }
    fn probe_first(&self) -> bool {
        true
    }
    fn approach_width(&self) -> Option<&'static str> {
        Some("cup.diameter_m")
    }
    fn demo_s(&self) -> f64 {
        4.0
    }

    fn sweep(&self) -> Vec<Sweep> {
        vec![
            Sweep::CameraNoise(0.5),
            Sweep::CameraNoise(2.0),
            Sweep::CupStiffness(0.5),
            Sweep::CupStiffness(2.0),
            Sweep::CupSize(-0.01),
            Sweep::CupSize(0.01),
        ]
    }
    fn plot(&self) -> PlotKind {
        PlotKind::Deformation
    }
}

/// One cup called `cup`, drawn from the config's cup variation and placed around its centre.
pub fn draw_cup(cfg: &TaskConfig, rng: &mut SplitMix64) -> TaskObject {
    let c = CupSpec::draw(&cfg.cup, rng);
    let v = &cfg.cup;
    let placed_m = [
        v.centre_m[0] + Uniform(-v.spread_m[0], v.spread_m[0]).draw(rng),
        v.centre_m[1] + Uniform(-v.spread_m[1], v.spread_m[1]).draw(rng),
    ];
    TaskObject {
        name: "cup".into(),
        spec: ObjectSpec::Cup(c),
        placed_m,
    }
}

/// The camera's values of a cup called `cup`.
pub fn cup_visual_names() -> Vec<String> {
    per_object("cup", &["x_m", "y_m", "z_m", "diameter_m", "height_m"])
}

fn cup_command(t: &TaskTruth, spec: &TrialSpec, cfg: &TaskConfig) -> TaskCommand {
    let Some(cup) = spec.cup() else {
        return home(cfg);
    };
    let g = cfg.gripper;
    let target_m = cfg.cup_criteria.target_deformation_m;
    let finger_m = static_finger_for(&cup.wall, &cfg.gel, target_m, g.max_force_n);
    let squeeze = (cup.diameter_m - 2.0 * finger_m + 2.0 * g.pad_m).max(0.0);
    // Lift once the wall has settled at the squeeze.
    let settled = t.arm.arrived
        && (t.gripper.opening_m - squeeze).abs() < 5e-5
        && t.contact.deformation_rate_m_s.abs() < 1e-3;
    grip_and_lift(t, spec, cfg, squeeze, settled)
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
    let stopped =
        t.arm.arrived && ((t.gripper.opening_m - opening_m).abs() < 1e-4 || t.gripper.stalled);
    grip_and_lift(t, spec, cfg, opening_m, stopped)
}

/// Open wide (the cup's diameter + 2 cm) to the cup at half its height, close to `opening_m`
/// once around it, and lift when `ready` (the cup between the fingers) or once the lift is under
/// way (the arm heads above the grasp height, the cup in the grip).
fn grip_and_lift(
    t: &TaskTruth,
    spec: &TrialSpec,
    cfg: &TaskConfig,
    opening_m: f64,
    ready: bool,
) -> TaskCommand {
    let Some(cup) = spec.cup() else {
        return home(cfg);
    };
    let g = cfg.gripper;
    let z = 0.5 * cup.height_m;
    let around = t.contact.object == "cup";
    let lifting = around && t.gripper.force_n > 0.0 && t.arm.target_m[2] > z + 1e-4;
    let (opening_m, speed, lift) = if lifting || (around && ready) {
        (opening_m, CLOSE_M_S, CUP_LIFT_M)
    } else if around && (t.arm.arrived || t.gripper.force_n > 0.0) {
        (opening_m, CLOSE_M_S, 0.0)
    } else {
        let wide = (cup.diameter_m + 0.02 + 2.0 * g.pad_m).min(g.max_opening_m);
        (wide, g.max_speed_m_s, 0.0)
    };
    command(
        opening_m,
        speed,
        g.max_force_n,
        placed(spec, "cup"),
        z,
        lift,
    )
}
