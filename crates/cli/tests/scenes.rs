//! A scene is a file: copies of shipped scenes under new names in a further scene directory (so
//! the tree is not touched) appear, with no other edit, in `unitac scenes`, in the golden list
//! (when a golden is committed for them) and pass its comparison, in scripts/bench-footprint's
//! list, and as a task of `unitac trials`. The launch side: crates/ros/tests/launch.rs.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use unitac_core::golden::{diff, parse_lines};

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

/// `launch/scenes/<from>.yaml` as `<dir>/<to>.yaml`, its `scene:` renamed.
fn copy_scene(dir: &Path, from: &str, to: &str) {
    let text = std::fs::read_to_string(root().join(format!("launch/scenes/{from}.yaml"))).unwrap();
    let renamed = text.replace(&format!("scene: {from}\n"), &format!("scene: {to}\n"));
    assert_ne!(renamed, text, "{from}");
    std::fs::write(dir.join(format!("{to}.yaml")), renamed).unwrap();
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

    // `unitac trials`: the copy's task, in the one mode it has a scene for (and, a cup VLA
    // scene, its force rule's column beside it, from the same scene).
    let o = unitac(
        &["trials", "--scene", "cup_copy", "--trials", "1", "--json"],
        Some(&scenes),
    );
    let j: serde_json::Value = serde_json::from_str(&lines(&o).join("\n")).unwrap();
    assert_eq!(j["task"], "cup_copy");
    let modes = j["modes"].as_array().unwrap();
    assert_eq!(modes.len(), 2, "{j}");
    assert_eq!(modes[0]["mode"], "vla");
    assert_eq!(modes[0]["scene"], "cup_copy_vla");
    assert_eq!(modes[1]["mode"], "vla_force");
    assert_eq!(modes[1]["scene"], "cup_copy_vla");
    assert!(modes[0]["trials"][0]["outcome"]["cup"].is_object(), "{j}");
    std::fs::remove_dir_all(&tmp).ok();
}
