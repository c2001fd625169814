//! The one list of scenes and of the tasks run in each mode, discovered from the scene
//! directories ([`scene_dirs`]): a YAML file added under `launch/scenes` is a scene everywhere
//! (`unitac scenes`, `unitac-lab trials`, `unitac-lab bench policy`, the golden tests, the
//! scripts), with no other edit.
//!
//! A closed-loop scene is named `<task>_<mode>` with a mode of [`Mode::ALL`]
//! (`cup_deformation_vtla_real`); `<task>` is what `unitac-lab trials --scene` takes, and runs each
//! of its modes.

use crate::registry::scene_dirs;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use unitac_policy::Mode;

/// Every scene name found in [`scene_dirs`] (`extra` first), sorted, each once.
pub fn scene_names(extra: Option<PathBuf>) -> Vec<String> {
    names_in(&scene_dirs(extra))
}

/// Scene names (file stems of `*.yaml`) in these directories, sorted, each once.
pub fn names_in(dirs: &[PathBuf]) -> Vec<String> {
    let mut names: Vec<String> = dirs
        .iter()
        .flat_map(|d| unitac_core::scene::list(d))
        .collect();
    names.sort();
    names.dedup();
    names
}

/// The task and mode of a closed-loop scene name (`cup_deformation_vla` -> (`cup_deformation`,
/// vla)); None for a name that ends in no mode.
pub fn split_mode(scene: &str) -> Option<(&str, Mode)> {
    Mode::ALL.into_iter().find_map(|m| {
        scene
            .strip_suffix(m.as_str())
            .and_then(|t| t.strip_suffix('_'))
            .filter(|t| !t.is_empty())
            .map(|t| (t, m))
    })
}

/// The scene of a task in a mode: `<task>_<mode>`.
pub fn mode_scene(task: &str, mode: Mode) -> String {
    format!("{task}_{}", mode.as_str())
}

/// Each task (a `<task>_<mode>` scene exists) with its modes, in [`Mode::ALL`]'s order.
pub fn tasks_in(names: &[String]) -> BTreeMap<String, Vec<Mode>> {
    let mut tasks: BTreeMap<String, Vec<Mode>> = BTreeMap::new();
    for n in names {
        if let Some((t, m)) = split_mode(n) {
            tasks.entry(t.to_string()).or_default().push(m);
        }
    }
    for modes in tasks.values_mut() {
        modes.sort_by_key(|m| Mode::ALL.iter().position(|a| a == m));
        modes.dedup();
    }
    tasks
}

/// [`tasks_in`] of [`scene_names`].
pub fn tasks(extra: Option<PathBuf>) -> BTreeMap<String, Vec<Mode>> {
    tasks_in(&scene_names(extra))
}

/// The scenes among `names` that have a committed golden event stream, `<golden_dir>/<scene>.jsonl`.
pub fn with_golden(names: &[String], golden_dir: &Path) -> Vec<String> {
    names
        .iter()
        .filter(|n| golden_dir.join(format!("{n}.jsonl")).is_file())
        .cloned()
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_task_is_the_name_before_a_mode() {
        assert_eq!(
            split_mode("cup_deformation_vtla_real"),
            Some(("cup_deformation", Mode::VtlaReal))
        );
        assert_eq!(split_mode("a_b_vla"), Some(("a_b", Mode::Vla)));
        for not in ["cup_deformation", "vla", "_vla", "cupvla", "x_vtla"] {
            assert_eq!(split_mode(not), None, "{not}");
        }
        assert_eq!(mode_scene("a_b", Mode::VtlaPred), "a_b_vtla_pred");
        let names: Vec<String> = ["t_vtla_pred", "t", "t_vla", "u_vtla_real"]
            .map(String::from)
            .to_vec();
        let t = tasks_in(&names);
        assert_eq!(
            t.into_iter().collect::<Vec<_>>(),
            [
                ("t".to_string(), vec![Mode::Vla, Mode::VtlaPred]),
                ("u".to_string(), vec![Mode::VtlaReal])
            ]
        );
    }

    #[test]
    fn the_shipped_scenes_are_found_with_their_tasks() {
        let names = scene_names(None);
        assert!(names.iter().any(|n| n == "fabric_selection"), "{names:?}");
        let t = tasks(None);
        assert_eq!(t.get("cup_deformation"), Some(&Mode::ALL.to_vec()));
    }
}
