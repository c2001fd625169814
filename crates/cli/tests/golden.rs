//! Golden outputs: the event streams of the scenes on the mock sensor (fixed seeds) are
//! committed in tests/golden/<scene>.jsonl; every scene (`unitac scenes`) with such a file is
//! checked, so a scene added with its golden is checked with no other edit. The embedded runtime (`unitac run --fast --events`)
//! and `unitac replay --scene` of the bag that run recorded (`--out`) must both reproduce them
//! (crates/ros/tests/golden.rs checks the ROS nodes on the same bag). `bash scripts/bless-goldens`
//! regenerates them on purpose after an intended change of a stage's output. The depth maps of a
//! contact stage with a depth calibration (no committed scene has one) have their own summary,
//! tests/golden/depth/fabric_selection_depth.jsonl, checked here for the runtime and replay and
//! in crates/ros/tests/depth.rs for the nodes.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::{Path, PathBuf};
use std::process::Command;
use unitac_core::golden::{diff, parse_lines};

mod common;

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

/// The committed summary of the depth maps of fabric_selection's contact stage with a depth
/// calibration (stamp, size, pixel size, known pixels, deepest value per map; the values' digest
/// is left out, as float sums may round differently on another CPU).
fn depth_golden_path() -> PathBuf {
    root().join("tests/golden/depth/fabric_selection_depth.jsonl")
}

/// A depth calibration from mock ball presses (`unitac calibrate mock-presses`, `calibrate
/// depth`: seeded, the same file every time) and fabric_selection's contact stage with it, in
/// `dir` (crates/ros/tests/depth.rs makes the same).
fn depth_scene(dir: &Path) -> PathBuf {
    let mock = dir.join("mock");
    events(&[
        "calibrate",
        "mock-presses",
        "--count",
        "30",
        "--out",
        mock.to_str().unwrap(),
    ]);
    let presses = common::press_files(&mock);
    let cal = dir.join("cal.json");
    let bg = mock.join("background.png");
    let mut args = common::calibrate_depth_args("0.002", &bg, &cal);
    args.extend(presses.iter().map(String::as_str));
    events(&args);
    let text = std::fs::read_to_string(root().join("launch/scenes/fabric_selection.yaml")).unwrap();
    let contact = text
        .split("  - kind: encoder")
        .next()
        .unwrap()
        .replace("scene: fabric_selection", "scene: fabric_selection_depth")
        .replace(
            "clip_frames: 8",
            &format!("clip_frames: 8\n      depth_calibration: {}", cal.display()),
        );
    assert!(contact.contains("depth_calibration"));
    let scene = dir.join("fabric_selection_depth.yaml");
    std::fs::write(&scene, contact).unwrap();
    scene
}

/// The depth events of a stream.
fn depth_events(all: &[serde_json::Value]) -> Vec<serde_json::Value> {
    all.iter()
        .filter(|e| e["type"] == "depth")
        .cloned()
        .collect()
}

/// The embedded runtime's and bag replay's depth maps: the same values (digests), and the
/// committed summary. `UNITAC_BLESS=1` rewrites the summary (scripts/bless-goldens does) after
/// an intended change of the depth.
#[test]
fn depth_maps_of_the_embedded_runtime_and_bag_replay_match_their_golden() {
    let dir = tmp("depth");
    std::fs::create_dir_all(&dir).unwrap();
    let scene = depth_scene(&dir);
    let scene = scene.to_str().unwrap();
    let bag = dir.join("run.mcap");
    let run = depth_events(&events(&[
        "run",
        "--scene",
        scene,
        "--fast",
        "--events",
        "--max-frames",
        "50",
        "--out",
        bag.to_str().unwrap(),
    ]));
    let replayed = depth_events(&events(&[
        "replay",
        bag.to_str().unwrap(),
        "--topic",
        "/unitac/image_raw",
        "--scene",
        scene,
        "--fast",
        "--events",
    ]));
    assert!(run.len() >= 30, "{} depth maps", run.len());
    assert!(
        run == replayed,
        "bag replay's depth maps differ from the embedded runtime's"
    );
    let got: Vec<serde_json::Value> = run
        .into_iter()
        .map(|mut e| {
            e.as_object_mut().unwrap().remove("digest");
            e
        })
        .collect();
    let path = depth_golden_path();
    if std::env::var_os("UNITAC_BLESS").is_some() {
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        let text: String = got.iter().map(|v| format!("{v}\n")).collect();
        std::fs::write(&path, text).unwrap();
    }
    let text = std::fs::read_to_string(&path)
        .unwrap_or_else(|e| panic!("{}: {e} (scripts/bless-goldens makes it)", path.display()));
    let want = parse_lines(&text).unwrap();
    if let Some(d) = diff(&want, &got) {
        panic!("depth maps differ from {}: {d}", path.display());
    }
    std::fs::remove_dir_all(&dir).ok();
}
