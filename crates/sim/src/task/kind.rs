//! What a task is: one [`Task`] implementation per task, each in its own module
//! ([`super::cup_deformation`], [`super::fabric_selection`]), and [`TaskKind`], the handle every
//! crate passes around. A scene names its task (`task: cup_deformation`); the policy's sentence
//! is only the task's text for the policy.
//!
//! A task says which objects a trial draws and how, what the camera reports of them, how the
//! world judges a trial (its criteria, the rows of the success table), how the scripted expert
//! solves it and decides, and how long its runs last. The world's physics (the arm, the gripper,
//! the squeeze world, friction and slip) is the same for every task: a task draws objects of the
//! kinds the world knows ([`super::ObjectSpec`]).
//!
//! A task defined outside this crate is a `static` implementing [`Task`] wrapped in
//! [`TaskKind::new`]; the scene loaders take such tasks beside [`TaskKind::SHIPPED`].

use std::fmt;

use serde::{Serialize, Serializer};

use super::{
    Split, TaskCommand, TaskConfig, TaskObject, TaskOutcome, TaskTruth, TrialSpec,
    cup_deformation::CupDeformation, fabric_selection::FabricSelection,
};
use crate::rng::SplitMix64;

/// What the outcome of a trial is judged on: the truth at the end and what the world recorded.
#[derive(Debug, Clone, Copy)]
pub struct Judged<'a> {
    pub truth: &'a TaskTruth,
    pub spec: &'a TrialSpec,
    /// The object held at the end (a grip force on it), its lift \[m].
    pub held: Option<usize>,
    pub lift_m: f64,
    /// The object of the first grasp attempt, and the one the policy announced
    /// ([`super::TaskWorld::decide`]).
    pub attempted: Option<usize>,
    pub announced: Option<usize>,
}

/// One variation of the world the trials' sweep runs beside the nominal table.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Sweep {
    /// The camera's noise (bias and per frame) times this.
    CameraNoise(f64),
    /// The cups' wall stiffness times this.
    CupStiffness(f64),
    /// The cups' diameter plus this \[m].
    CupSize(f64),
}

impl Sweep {
    /// The sweep row's name.
    pub fn name(self) -> String {
        match self {
            Sweep::CameraNoise(f) => format!("camera noise x{f}"),
            Sweep::CupStiffness(f) => format!("cup stiffness x{f}"),
            Sweep::CupSize(d) => format!("cup size {:+.0} mm", d * 1e3),
        }
    }
    /// `cfg` varied so.
    pub fn apply(self, cfg: &TaskConfig) -> TaskConfig {
        let mut t = cfg.clone();
        match self {
            Sweep::CameraNoise(f) => t.vision = t.vision.scaled(f),
            Sweep::CupStiffness(f) => t.cup.stiffness_scale *= f,
            Sweep::CupSize(d) => t.cup.size_offset_m += d,
        }
        t
    }
}

/// Which time series the trials' figure plots for a task.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PlotKind {
    /// The loss of diameter over time, with the target band.
    Deformation,
    /// The grip force and the slip since the grasp over time.
    ForceAndSlip,
}

/// A task: its objects, the criteria its trials are judged by, its expert (module docs).
pub trait Task: Send + Sync + 'static {
    /// The name a scene gives it (`task: <name>`), and the prefix of its `<name>_<mode>` scenes.
    fn name(&self) -> &'static str;
    /// Its objects in a sentence's plural (`cups`).
    fn objects(&self) -> &'static str;
    /// The trials' one-line description of a split's objects.
    fn describe(&self, split: Split) -> String;

    /// The trial's objects, drawn from `rng` (the trial's own stream, first).
    fn draw(&self, cfg: &TaskConfig, rng: &mut SplitMix64) -> Vec<TaskObject>;
    /// The camera's values, `<object>.<field>` in SI units, in order.
    fn visual_names(&self) -> Vec<String>;

    /// The success table's rows, `overall` last.
    fn criteria(&self) -> &'static [&'static str];
    /// The trial's outcome, judged on `j`.
    fn judge(&self, cfg: &TaskConfig, j: &Judged) -> TaskOutcome;
    /// The paper's count (of 20 real-robot trials) for a criterion and mode (`vla`,
    /// `vtla_real`, `vtla_pred`); None where the paper reports none.
    fn paper(&self, _criterion: &str, _mode: &str) -> Option<u32> {
        None
    }

    /// The scripted expert's command for this tick; it may read the truth of what a teleoperator
    /// sees, never a hidden property. `choice`: the object to grasp, once decided
    /// ([`Task::decides`]).
    fn expert(
        &self,
        truth: &TaskTruth,
        spec: &TrialSpec,
        cfg: &TaskConfig,
        choice: Option<&str>,
    ) -> TaskCommand;
    /// Whether the expert waits for a decision between objects, and whether it waits now.
    fn decides(&self) -> bool {
        false
    }
    fn awaits_decision(&self, _truth: &TaskTruth, _spec: &TrialSpec, _cfg: &TaskConfig) -> bool {
        false
    }
    /// The decision a camera alone makes from its values (`seen`: e.g. their mean so far).
    fn camera_choice<'a>(
        &self,
        _spec: &'a TrialSpec,
        _seen: &dyn Fn(&str) -> Option<f64>,
    ) -> Option<&'a str> {
        None
    }

    /// The expert's control period and run length in the examples and tests \[s].
    fn expert_run(&self) -> (f64, f64);
    /// A closed-loop trial's longest run \[s].
    fn trial_s(&self) -> f64;
    /// A demonstration: whether vtla_real's probe touch comes first (an approach to the object,
    /// a touch, a release), the camera value the approach opens the fingers to (plus the
    /// pre-grasp margin), and how long the expert then runs \[s].
    fn probe_first(&self) -> bool {
        false
    }
    fn approach_width(&self) -> Option<&'static str> {
        None
    }
    fn demo_s(&self) -> f64 {
        self.expert_run().1
    }

    /// The world variations the trials' sweep runs.
    fn sweep(&self) -> Vec<Sweep> {
        vec![Sweep::CameraNoise(0.5), Sweep::CameraNoise(2.0)]
    }
    /// What the trials' figure shows.
    fn plot(&self) -> PlotKind {
        PlotKind::ForceAndSlip
    }
}

/// The paper's count of a `[vla, vtla_real, vtla_pred]` row for `mode`.
pub fn paper_column(row: [u32; 3], mode: &str) -> Option<u32> {
    let col = match mode {
        "vla" => 0,
        "vtla_real" => 1,
        "vtla_pred" => 2,
        _ => return None,
    };
    row.get(col).copied()
}

/// A task, by reference: cheap to copy, compared and serialized by its name.
#[derive(Clone, Copy)]
pub struct TaskKind(&'static dyn Task);

/// No task of that name.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("no task '{name}' (known: {known})")]
pub struct UnknownTask {
    pub name: String,
    pub known: String,
}

impl TaskKind {
    /// The paper's unseen-size cup deformation grasp.
    pub const CUP: TaskKind = TaskKind(&CupDeformation);
    /// The paper's fabric selection grasp.
    pub const FABRIC: TaskKind = TaskKind(&FabricSelection);
    /// The tasks this crate ships.
    pub const SHIPPED: [TaskKind; 2] = [TaskKind::CUP, TaskKind::FABRIC];

    /// A task defined elsewhere.
    pub const fn new(task: &'static dyn Task) -> TaskKind {
        TaskKind(task)
    }

    /// The task called `name` among `extra` and the shipped ones.
    pub fn named(name: &str, extra: &[TaskKind]) -> Result<TaskKind, UnknownTask> {
        let all = || extra.iter().chain(&TaskKind::SHIPPED);
        all()
            .find(|t| t.name() == name)
            .copied()
            .ok_or_else(|| UnknownTask {
                name: name.chars().take(64).collect(),
                known: all().map(|t| t.name()).collect::<Vec<_>>().join(", "),
            })
    }
}

impl std::ops::Deref for TaskKind {
    type Target = dyn Task;
    fn deref(&self) -> &Self::Target {
        self.0
    }
}

impl PartialEq for TaskKind {
    fn eq(&self, other: &Self) -> bool {
        self.name() == other.name()
    }
}

impl Eq for TaskKind {}

impl fmt::Debug for TaskKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl fmt::Display for TaskKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl Serialize for TaskKind {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.name())
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn tasks_are_found_by_the_name_a_scene_gives() {
        assert_eq!(
            TaskKind::named("cup_deformation", &[]).unwrap(),
            TaskKind::CUP
        );
        assert_eq!(
            TaskKind::named("fabric_selection", &[]).unwrap(),
            TaskKind::FABRIC
        );
        let e = TaskKind::named("cup", &[]).unwrap_err();
        assert_eq!(
            e.to_string(),
            "no task 'cup' (known: cup_deformation, fabric_selection)"
        );
        assert_eq!(TaskKind::CUP.to_string(), "cup_deformation");
        for t in TaskKind::SHIPPED {
            assert_eq!(t.criteria().last(), Some(&"overall"), "{t}");
        }
    }
}
