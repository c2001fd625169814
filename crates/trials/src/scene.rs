//! What a closed-loop scene asks of the sim world: the task its policy stage names (`squeeze the
//! cup ...` is the cup task, `pick the ...` the fabric task). The trials, the policy benchmark and
//! the ROS sim node all take the task from the scene this way, so no list maps scene names to
//! tasks.

use crate::gripper::TrialGripper;
use crate::run::{TrialError, policy_params};
use unitac_core::Scene;
use unitac_policy::PolicyParams;
use unitac_policy::task::{Task, TaskError};
use unitac_sim::task::{TaskConfig, TaskKind};

/// The sim task of a policy's task string.
pub fn task_kind(p: &PolicyParams) -> Result<TaskKind, TaskError> {
    Ok(match Task::parse(&p.task)? {
        Task::Pick { .. } => TaskKind::Fabric,
        Task::Squeeze { .. } => TaskKind::Cup,
    })
}

/// The scene's policy params (checked) and the sim task they ask for.
pub fn scene_task(scene: &Scene) -> Result<(PolicyParams, TaskKind), TrialError> {
    let p = policy_params(scene)?;
    let kind = task_kind(&p).map_err(|e| TrialError::Scene {
        scene: scene.name.clone(),
        msg: e.to_string(),
    })?;
    Ok((p, kind))
}

/// `scene` with its policy stage's `key` set to `value`.
fn with_policy_param(scene: &Scene, key: &str, value: &str) -> Scene {
    let mut s = scene.clone();
    for stage in s.stages.iter_mut().filter(|st| st.kind == "policy") {
        if stage.params.is_null() {
            stage.params = serde_yaml::Value::Mapping(Default::default());
        }
        if let serde_yaml::Value::Mapping(m) = &mut stage.params {
            m.insert(key.into(), value.into());
        }
    }
    s
}

/// `scene` with its policy stage's `vla_rule` set to `rule` (the cup VLA scene's other
/// camera-only rule, run as a baseline column by `unitac trials`).
pub fn with_vla_rule(scene: &Scene, rule: unitac_policy::VlaRule) -> Scene {
    with_policy_param(scene, "vla_rule", rule.as_str())
}

/// The scene and world a trial with `gripper` runs: a serial model's profile named in the policy
/// stage (its safety bounds inside the model's stroke, grip and speed), and the world's gripper
/// that of the profile the policy stage names (the model's, or one the scene names itself; else
/// the task's as given). One profile, both sides.
pub fn for_gripper(
    scene: &Scene,
    task: &TaskConfig,
    gripper: TrialGripper,
) -> Result<(Scene, PolicyParams, TaskConfig), TrialError> {
    let scene = match gripper {
        TrialGripper::Serial(m) => with_policy_param(scene, "gripper", m.name()),
        TrialGripper::InProcess => scene.clone(),
    };
    let params = policy_params(&scene)?;
    let mut task = task.clone();
    if let Ok(Some(p)) = params.profile() {
        task.gripper = task.gripper.with_profile(p);
    }
    Ok((scene, params, task))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_task_string_names_the_sim_task() {
        let p = |task: &str| PolicyParams {
            task: task.into(),
            ..PolicyParams::default()
        };
        assert_eq!(task_kind(&p("squeeze the cup by 1 cm")), Ok(TaskKind::Cup));
        assert_eq!(
            task_kind(&p("pick the rougher fabric")),
            Ok(TaskKind::Fabric)
        );
        assert!(task_kind(&p("dance")).is_err());
    }
}
