//! A scene is a file: copies of shipped scenes under new names in a further scene directory (so
//! the tree is not touched) appear, with no other edit, in `unitac scenes`, in the golden list
//! (when a golden is committed for them) and pass its comparison, and in
//! scripts/bench-footprint's list. As a task of `unitac-lab trials`: crates/lab/tests/scenes.rs;
//! the launch side: crates/ros/tests/launch.rs.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use unitac_core::golden::{diff, parse_lines};

mod common;
use common::shared::copy_scene;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn unitac(args: &[&str], scenes: Option<&Path>) -> Output {
    let mut c = Command::new(env!("CARGO_BIN_EXE_unitac"));
    c.args(args).env("RUST_LOG", "warn");
    match scenes {
        Some(d) => c.env("UNITAC_SCENES", d),
        None => c.env_remove("UNITAC_SCENES"),
    };
    c.output().unwrap()
}

fn lines(o: &Output) -> Vec<String> {
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    String::from_utf8_lossy(&o.stdout)
        .lines()
        .map(str::to_string)
        .collect()
}

#[test]
fn a_scene_file_added_is_a_scene_everywhere_with_no_other_edit() {
    let tmp = std::env::temp_dir().join(format!("unitac-cli-scenes-{}", std::process::id()));
    let (scenes, goldens) = (tmp.join("scenes"), tmp.join("golden"));
    std::fs::create_dir_all(&scenes).unwrap();
    std::fs::create_dir_all(&goldens).unwrap();
    copy_scene(&scenes, "fabric_selection", "fabric_copy");
    copy_scene(&scenes, "cup_deformation_vla", "cup_copy_vla");
    std::fs::copy(
        root().join("tests/golden/fabric_selection.jsonl"),
        goldens.join("fabric_copy.jsonl"),
    )
    .unwrap();

    // `unitac scenes`: the shipped scenes and the copies, by --scene-dir or $UNITAC_SCENES.
    let shipped = lines(&unitac(&["scenes"], None));
    assert!(
        shipped.iter().any(|s| s == "fabric_selection"),
        "{shipped:?}"
    );
    let mut want = shipped.clone();
    want.extend(["cup_copy_vla".to_string(), "fabric_copy".to_string()]);
    want.sort();
    let by_flag = lines(&unitac(
        &["scenes", "--scene-dir", scenes.to_str().unwrap()],
        None,
    ));
    assert_eq!(by_flag, want);
    assert_eq!(lines(&unitac(&["scenes"], Some(&scenes))), want);

    // The golden list: every listed scene with a golden; the copy's run reproduces it.
    let names = unitac_pipeline::scene_names(Some(scenes.clone()));
    assert_eq!(names, want);
    let with = unitac_pipeline::scenes::with_golden(&names, &goldens);
    assert_eq!(with, ["fabric_copy"]);
    let o = unitac(
        &["run", "--scene", "fabric_copy", "--fast", "--events"],
        Some(&scenes),
    );
    let events: Vec<String> = lines(&o)
        .into_iter()
        .filter(|l| l.starts_with('{'))
        .collect();
    let got = parse_lines(&events.join("\n")).unwrap();
    let golden =
        parse_lines(&std::fs::read_to_string(goldens.join("fabric_copy.jsonl")).unwrap()).unwrap();
    assert_eq!(diff(&golden, &got), None);

    // scripts/bench-footprint: the listed scenes, then the all-stages one.
    let o = Command::new("bash")
        .arg(root().join("scripts/bench-footprint"))
        .arg("--list")
        .env("UNITAC_EXE", env!("CARGO_BIN_EXE_unitac"))
        .env("UNITAC_SCENES", &scenes)
        .output()
        .unwrap();
    let mut bench = want.clone();
    bench.push("bench/scenes/all_stages.yaml".into());
    assert_eq!(lines(&o), bench);

    std::fs::remove_dir_all(&tmp).ok();
}

/// The footprint benchmark's all-stages scene (scripts/bench-footprint) really loads every stage
/// kind a scene can name.
#[test]
fn the_all_stages_scene_loads_every_stage_kind() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let path = root.join("bench/scenes/all_stages.yaml");
    let scene = unitac_pipeline::load_scene(path.to_str().unwrap(), None).unwrap();
    let cfgs = unitac_pipeline::stage_configs(&scene).unwrap();
    let kinds: Vec<&str> = cfgs.iter().map(|c| c.kind()).collect();
    for k in unitac_pipeline::KNOWN_STAGES {
        assert!(
            kinds.contains(k),
            "all_stages.yaml lacks a {k} stage: {kinds:?}"
        );
    }
    // Every model the scene names is used by a stage.
    let named: Vec<&String> = scene.models.keys().collect();
    for m in named {
        assert!(
            scene.stages.iter().any(|s| s.models.contains(m)),
            "model {m} is loaded by no stage"
        );
    }
}
