//! The policy golden: what the policy stage of `cup_deformation_vla` takes (the camera's estimate
//! and the gripper's status, tick by tick) and sends (GripperCommand, ArmCommand, PolicyStatus)
//! in the first seconds of one unseen-cup trial, committed in
//! tests/golden/policy/cup_deformation_vla.jsonl (inputs carry `"input": true`). The embedded
//! trial reproduces it here; crates/ros/tests/policy_golden.rs feeds the same inputs to the ROS
//! policy node and compares what it publishes. `UNITAC_BLESS=1` rewrites it (scripts/bless-goldens
//! does) after an intended change of the policy's output.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::PathBuf;
use unitac_core::golden::{diff, parse_lines};
use unitac_sim::task::{Split, TaskConfig};
use unitac_trials::{TrialOptions, run_trial};

const SCENE: &str = "cup_deformation_vla";

fn golden_path() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../tests/golden/policy")
        .join(format!("{SCENE}.jsonl"))
}

#[test]
fn the_embedded_trial_reproduces_the_policy_golden() {
    let scene = unitac_pipeline::load_scene(SCENE, None).unwrap();
    let task = TaskConfig::cup(Split::Unseen);
    let opts = TrialOptions {
        max_s: 3.0,
        keep_messages: true,
        ..TrialOptions::for_task(task.kind)
    };
    let r = run_trial(&scene, &task, 1, 0, &opts).unwrap();
    let got: Vec<serde_json::Value> = r.messages.iter().map(|m| m.to_json()).collect();
    let path = golden_path();
    if std::env::var_os("UNITAC_BLESS").is_some() {
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        let text: String = got.iter().map(|v| format!("{v}\n")).collect();
        std::fs::write(&path, text).unwrap();
    }
    let text = std::fs::read_to_string(&path)
        .unwrap_or_else(|e| panic!("{}: {e} (scripts/bless-goldens makes it)", path.display()));
    let want = parse_lines(&text).unwrap();
    // Every tick has its two inputs and three outputs, and the policy moved past its first phase.
    let inputs = want.iter().filter(|v| v["input"] == true).count();
    assert_eq!(
        inputs * 5,
        want.len() * 2,
        "two inputs, three outputs a tick"
    );
    assert!(
        want.iter()
            .any(|v| v["type"] == "policy_status" && v["phase"] != "approach")
    );
    assert_eq!(
        got.len(),
        want.len(),
        "{} messages, golden {}",
        got.len(),
        want.len()
    );
    assert_eq!(diff(&want, &got), None);
}
