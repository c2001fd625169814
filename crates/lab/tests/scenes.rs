//! A scene is a file: a copy of a shipped scene under a new name in a further scene directory (so
//! the tree is not touched) is, with no other edit, a task of `unitac-lab trials`. The scene list,
//! the goldens and the footprint bench: crates/cli/tests/scenes.rs.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::process::Command;

mod common;
use common::shared::copy_scene;

#[test]
fn a_scene_file_added_is_a_trials_task_with_no_other_edit() {
    let scenes = std::env::temp_dir().join(format!("unitac-lab-scenes-{}", std::process::id()));
    std::fs::create_dir_all(&scenes).unwrap();
    copy_scene(&scenes, "cup_deformation_vla", "cup_copy_vla");

    // The copy's task, in the one mode it has a scene for (and, a cup VLA scene, its force
    // rule's column beside it, from the same scene).
    let o = Command::new(common::EXE)
        .args(["trials", "--scene", "cup_copy", "--trials", "1", "--json"])
        .env("RUST_LOG", "warn")
        .env("UNITAC_SCENES", &scenes)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(j["task"], "cup_copy");
    let modes = j["modes"].as_array().unwrap();
    assert_eq!(modes.len(), 2, "{j}");
    assert_eq!(modes[0]["mode"], "vla");
    assert_eq!(modes[0]["scene"], "cup_copy_vla");
    assert_eq!(modes[1]["mode"], "vla_force");
    assert_eq!(modes[1]["scene"], "cup_copy_vla");
    assert!(modes[0]["trials"][0]["outcome"]["cup"].is_object(), "{j}");
    std::fs::remove_dir_all(&scenes).ok();
}
