//! A scene whose generated models are missing (a fresh checkout, or `UNITAC_MODELS` pointing at an
//! empty directory) fails with exit 2 and one line that names the missing file and the setup
//! command that makes what the scene names; a model the user gave by path gets no such hint.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use std::time::Duration;

/// `unitac run --scene SCENE` with an empty model directory: exit 2, the one stderr line.
fn run_without_models(scene: &str) -> String {
    let empty = std::env::temp_dir().join(format!("unitac-no-models-{}", std::process::id()));
    std::fs::create_dir_all(&empty).unwrap();
    let out = common::shared::run_within(
        env!("CARGO_BIN_EXE_unitac"),
        &["run", "--scene", scene, "--fast", "--max-frames", "1"],
        &[("UNITAC_MODELS", empty.to_str().unwrap())],
        Duration::from_secs(60),
    );
    std::fs::remove_dir_all(&empty).ok();
    assert_eq!(out.status.code(), Some(2), "{out:?}");
    let err = String::from_utf8(out.stderr).unwrap();
    assert_eq!(err.lines().count(), 1, "{err}");
    err
}

#[test]
fn a_missing_generated_model_names_the_setup_stage_of_its_scene() {
    for (scene, bundle) in [
        ("fabric_selection", "reference"),
        ("cup_deformation_vtla_pred", "touch"),
    ] {
        let err = run_without_models(scene);
        assert!(
            err.contains(&format!("{bundle}/manifest.json")),
            "{scene}: {err}"
        );
        let hint = "`bash scripts/setup.sh scene:";
        assert!(err.contains(hint), "{scene}: {err}");
        assert!(err.contains(&format!("{scene}.yaml`")), "{scene}: {err}");
    }
}

#[test]
fn a_missing_model_outside_the_generated_directory_gets_no_setup_hint() {
    let dir = std::env::temp_dir().join(format!("unitac-own-model-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let scene = dir.join("own.yaml");
    std::fs::write(
        &scene,
        "scene: own\nsource: {kind: mock, sensor: gelsight-mini, scenario: fabric_selection}\n\
         models: {reference: ./nowhere/manifest.json}\n\
         stages:\n  - kind: contact\n  - kind: encoder\n    models: [reference]\n",
    )
    .unwrap();
    let out = common::shared::run_within(
        env!("CARGO_BIN_EXE_unitac"),
        &["run", "--scene", scene.to_str().unwrap(), "--fast"],
        &[],
        Duration::from_secs(60),
    );
    std::fs::remove_dir_all(&dir).ok();
    assert_eq!(out.status.code(), Some(2), "{out:?}");
    let err = String::from_utf8(out.stderr).unwrap();
    assert!(err.contains("file not found"), "{err}");
    assert!(!err.contains("setup.sh"), "{err}");
}
