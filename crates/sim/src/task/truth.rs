//! Ground truth of a task world after a step, and the task's outcome.

use std::collections::BTreeMap;

use serde::Serialize;

use super::{ArmState, CupOutcome, FabricOutcome};

/// The gripper's truth.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Default)]
pub struct GripperTruth {
    pub opening_m: f64,
    /// Contact force per finger \[N].
    pub force_n: f64,
    /// Closing was stopped by the commanded force bound.
    pub stalled: bool,
}

/// The contact between the gels and the object between them.
#[derive(Debug, Clone, PartialEq, Serialize, Default)]
pub struct ContactTruth {
    /// The object between the fingers ("" when none).
    pub object: String,
    /// Fabric layers between the fingers (1 for a cup, 0 when none).
    pub layers: u32,
    /// Gel penetration \[m] (negative: the gap to the object).
    pub penetration_m: f64,
    /// Loss of the object's width between the fingers (cup diameter, fabric stack) \[m] and its
    /// rate \[m/s].
    pub deformation_m: f64,
    pub deformation_rate_m_s: f64,
    /// Vertical friction force on the object, both fingers, up positive \[N].
    pub friction_n: f64,
    /// Displacement of each gel's surface by that force, along the sensor's y axis (world down
    /// positive) \[m].
    pub tangential_m: f64,
    /// Relative motion of object and fingers in this step, signed (object down positive) \[m],
    /// and summed unsigned since the grasp.
    pub slip_step_m: f64,
    pub slip_total_m: f64,
    /// Object and fingers move together.
    pub stuck: bool,
}

/// An object's truth.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ObjectTruth {
    pub name: String,
    /// (x, y) where it is, z its lift above where it rests \[m].
    pub position_m: [f64; 3],
    /// Between the fingers with a grip force.
    pub held: bool,
    /// Time it was pressed by the gels with at least 0.2 N \[s].
    pub touch_s: f64,
}

/// Ground truth after a step.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TaskTruth {
    pub t_s: f64,
    pub arm: ArmState,
    pub gripper: GripperTruth,
    pub contact: ContactTruth,
    pub objects: Vec<ObjectTruth>,
    /// Largest cup deformation so far \[m] (0 in the fabric task).
    pub peak_deformation_m: f64,
    /// The fingers met an object while too closed to pass around it (sticky).
    pub collision: bool,
    /// An object slipped out of the fingers (sticky).
    pub dropped: bool,
    /// Squeeze-world integrator steps in this step.
    pub substeps: u32,
}

/// A task's outcome: the shipped tasks' with the values behind each criterion, or any task's
/// criteria by name.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum TaskOutcome {
    Cup(CupOutcome),
    Fabric(FabricOutcome),
    Criteria(CriteriaOutcome),
}

/// An outcome as criteria met or not (`overall` among them) and the values behind them.
#[derive(Debug, Clone, PartialEq, Serialize, Default)]
pub struct CriteriaOutcome {
    pub met: BTreeMap<String, bool>,
    pub values: BTreeMap<String, f64>,
}

impl TaskOutcome {
    pub fn overall(&self) -> bool {
        self.meets("overall")
    }
    /// Whether the outcome meets the criterion called so (false for one it does not judge).
    pub fn meets(&self, criterion: &str) -> bool {
        match (self, criterion) {
            (TaskOutcome::Cup(c), "lift") => c.lift,
            (TaskOutcome::Cup(c), "target deformation") => c.deformation,
            (TaskOutcome::Cup(c), "overall") => c.overall,
            (TaskOutcome::Fabric(f), "selection") => f.selection,
            (TaskOutcome::Fabric(f), "grasp") => f.grasp,
            (TaskOutcome::Fabric(f), "overall") => f.overall,
            (TaskOutcome::Criteria(c), name) => c.met.get(name).copied().unwrap_or(false),
            _ => false,
        }
    }
}
