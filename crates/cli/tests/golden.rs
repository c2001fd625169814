//! Golden outputs: the event streams of the scenes on the mock sensor (fixed seeds) are
//! committed in tests/golden/<scene>.jsonl; every scene (`unitac scenes`) with such a file is
//! checked, so a scene added with its golden is checked with no other edit. The embedded runtime (`unitac run --fast --events`)
//! and `unitac replay --scene` of the bag that run recorded (`--out`) must both reproduce them
//! (crates/ros/tests/golden.rs checks the ROS nodes on the same bag). `bash scripts/bless-goldens`
//! regenerates them on purpose after an intended change of a stage's output.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::{Path, PathBuf};
use std::process::Command;
use unitac_core::golden::{diff, parse_lines};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The scenes with a golden: every discovered scene that has tests/golden/<scene>.jsonl. A
/// golden file whose scene is gone fails here.
fn golden_scenes() -> Vec<String> {
    let names = unitac_pipeline::scene_names(None);
    let dir = root().join("tests/golden");
    let scenes = unitac_pipeline::scenes::with_golden(&names, &dir);
    for f in std::fs::read_dir(&dir).unwrap() {
        let name = f.unwrap().file_name().into_string().unwrap();
        if let Some(scene) = name.strip_suffix(".jsonl") {
            assert!(
                scenes.iter().any(|s| s == scene),
                "tests/golden/{name} has no scene {scene}"
            );
        }
    }
    assert!(!scenes.is_empty());
    scenes
}

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("unitac-golden-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d.join(name)
}

fn golden(scene: &str) -> Vec<serde_json::Value> {
    let p = root().join(format!("tests/golden/{scene}.jsonl"));
    let text = std::fs::read_to_string(&p)
        .unwrap_or_else(|e| panic!("{}: {e} (bash scripts/bless-goldens makes it)", p.display()));
    parse_lines(&text).unwrap()
}

fn events(args: &[&str]) -> Vec<serde_json::Value> {
    let o = Command::new(env!("CARGO_BIN_EXE_unitac"))
        .args(args)
        .env("RUST_LOG", "warn")
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "unitac {args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    // The event lines (the summary after them is text).
    let text = String::from_utf8_lossy(&o.stdout);
    let events: Vec<&str> = text.lines().filter(|l| l.starts_with('{')).collect();
    parse_lines(&events.join("\n")).unwrap()
}

/// `unitac run --scene S --fast --events --out BAG`: the events and the recorded bag.
fn run(scene: &str) -> (Vec<serde_json::Value>, PathBuf) {
    let bag = tmp(&format!("{scene}.mcap"));
    let got = events(&[
        "run",
        "--scene",
        scene,
        "--fast",
        "--events",
        "--out",
        bag.to_str().unwrap(),
    ]);
    (got, bag)
}

fn replay(bag: &Path, scene: &str) -> Vec<serde_json::Value> {
    events(&[
        "replay",
        bag.to_str().unwrap(),
        "--scene",
        scene,
        "--fast",
        "--events",
    ])
}

#[test]
fn the_embedded_runtime_and_bag_replay_reproduce_the_goldens() {
    for scene in golden_scenes() {
        let scene = scene.as_str();
        let want = golden(scene);
        assert!(want.len() > 100, "{scene}: {} events", want.len());
        let (got, bag) = run(scene);
        if let Some(d) = diff(&want, &got) {
            panic!("{scene}: unitac run differs from tests/golden/{scene}.jsonl: {d}");
        }
        let replayed = replay(&bag, scene);
        if let Some(d) = diff(&want, &replayed) {
            panic!("{scene}: unitac replay of the recorded bag differs from the golden: {d}");
        }
    }
}

#[test]
fn a_changed_stage_output_fails_the_golden_comparison() {
    // The same scene with one contact parameter changed: the comparison must notice.
    let text = std::fs::read_to_string(root().join("launch/scenes/fabric_selection.yaml")).unwrap();
    let changed = text.replace("clip_frames: 8", "clip_frames: 8\n      enter_area_px: 400");
    assert_ne!(changed, text);
    let path = tmp("changed.yaml");
    std::fs::write(&path, changed).unwrap();
    let got = events(&[
        "run",
        "--scene",
        path.to_str().unwrap(),
        "--fast",
        "--events",
    ]);
    let d = diff(&golden("fabric_selection"), &got).expect("a changed stage output must differ");
    assert!(d.starts_with("event "), "{d}");
}
