//! What a closed-loop scene asks of the sim world: the task it names (`task: cup_deformation`).
//! The trials, the demonstrations, the policy benchmark and the ROS sim node all take the task
//! from the scene this way; the policy's sentence is only the task's text for the policy.

use crate::gripper::TrialGripper;
use crate::run::{TrialError, policy_params};
use unitac_core::Scene;
use unitac_policy::PolicyParams;
use unitac_sim::task::{TaskConfig, TaskKind};

/// The task a scene names, among `extra` and the shipped tasks.
pub fn scene_kind(scene: &Scene, extra: &[TaskKind]) -> Result<TaskKind, TrialError> {
    let bad = |msg: String| TrialError::Scene {
        scene: scene.name.clone(),
        msg,
    };
    let name = scene
        .task
        .as_deref()
        .ok_or_else(|| bad("names no task (task: <name>)".into()))?;
    TaskKind::named(name, extra).map_err(|e| bad(e.to_string()))
}

/// The scene's policy params (checked) and the shipped task it names.
pub fn scene_task(scene: &Scene) -> Result<(PolicyParams, TaskKind), TrialError> {
    scene_task_in(scene, &[])
}

/// [`scene_task`] with tasks defined elsewhere (`extra`) beside the shipped ones.
pub fn scene_task_in(
    scene: &Scene,
    extra: &[TaskKind],
) -> Result<(PolicyParams, TaskKind), TrialError> {
    let p = policy_params(scene)?;
    Ok((p, scene_kind(scene, extra)?))
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
/// camera-only rule, run as a baseline column by `unitac-lab trials`).
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
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn the_scene_names_the_sim_task() {
        let scene = |task: Option<&str>| Scene {
            task: task.map(String::from),
            ..unitac_pipeline::load_scene("cup_deformation_vla", None).unwrap()
        };
        assert_eq!(
            scene_kind(&scene(Some("fabric_selection")), &[]).unwrap(),
            TaskKind::FABRIC
        );
        assert_eq!(
            scene_kind(&scene(None), &[]).unwrap_err().to_string(),
            "scene 'cup_deformation_vla': names no task (task: <name>)"
        );
        assert!(
            scene_kind(&scene(Some("dance")), &[])
                .unwrap_err()
                .to_string()
                .contains("no task 'dance' (known: cup_deformation, fabric_selection)")
        );
    }
}
