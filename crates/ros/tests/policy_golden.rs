//! The policy golden over ROS: the policy node (`cup_deformation_vla`, its stage through the one
//! chain driver) is fed the inputs of tests/golden/policy/cup_deformation_vla.jsonl by an rclpy
//! peer (tests/ros/policy_replay_peer.py), tick by tick, and publishes the GripperCommands,
//! ArmCommands and PolicyStatuses the golden holds, field by field (floats within
//! unitac_core::golden::FLOAT_TOLERANCE). The embedded trial reproduces the same file
//! (crates/trials/tests/policy_golden.rs). Under `use_sim_time` with no /clock the node's timer
//! reads time 0, so its watchdog stays quiet: every tick is a gripper status of the golden.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;
use common::{python, root, stop};
use serde_json::Value;
use std::process::{Command, Stdio};
use unitac_bag::RosMessage;
use unitac_core::Msg;
use unitac_core::golden::{diff, parse_lines};
use unitac_core::msg::{
    ArmCommand, GripperCommand, GripperStatus, PolicyStatus, VisualObservation,
};

const SCENE: &str = "cup_deformation_vla";

/// JSON writes NaN as null; the golden's nulls come back as this and are turned into NaN.
const NULL: f64 = f64::MAX;

fn nulls_to(v: &mut Value) {
    match v {
        Value::Null => *v = Value::from(NULL),
        Value::Array(a) => a.iter_mut().for_each(nulls_to),
        Value::Object(o) => o.values_mut().for_each(nulls_to),
        _ => {}
    }
}

fn nan(x: f64) -> f64 {
    if x == NULL { f64::NAN } else { x }
}

/// A golden line's message without the line's own keys.
fn fields<T: serde::de::DeserializeOwned>(v: &Value) -> T {
    let mut v = v.clone();
    let o = v.as_object_mut().unwrap();
    o.remove("type");
    o.remove("input");
    nulls_to(&mut v);
    serde_json::from_value(v).unwrap()
}

fn gripper_status(v: &Value) -> GripperStatus {
    let mut g: GripperStatus = fields(v);
    for x in [
        &mut g.opening_m,
        &mut g.target_m,
        &mut g.force_n,
        &mut g.current_a,
    ] {
        *x = nan(*x);
    }
    g
}

fn visual(v: &Value) -> VisualObservation {
    let mut m: VisualObservation = fields(v);
    m.values.iter_mut().for_each(|x| *x = nan(*x));
    m
}

#[test]
fn the_policy_node_publishes_the_policy_golden() {
    let text =
        std::fs::read_to_string(root().join(format!("tests/golden/policy/{SCENE}.jsonl"))).unwrap();
    let golden = parse_lines(&text).unwrap();
    let (inputs, outputs): (Vec<&Value>, Vec<&Value>) =
        golden.iter().partition(|v| v["input"] == true);
    let dir = std::env::temp_dir().join(format!("unitac-policy-golden-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let feed = dir.join("inputs.jsonl");
    let lines: String = inputs
        .iter()
        .map(|v| {
            let (topic, cdr) = match v["type"].as_str().unwrap() {
                "visual_observation" => ("visual_observation", visual(v).to_cdr()),
                "gripper_status" => ("gripper_status", gripper_status(v).to_cdr()),
                other => panic!("not a policy input: {other}"),
            };
            let hex: String = cdr.iter().map(|b| format!("{b:02x}")).collect();
            format!("{}\n", serde_json::json!({"topic": topic, "cdr": hex}))
        })
        .collect();
    std::fs::write(&feed, lines).unwrap();

    let ns = format!("/t{}_policy_golden", std::process::id());
    let node = Command::new(env!("CARGO_BIN_EXE_unitac_policy_node"))
        .args(["--ros-args", "-r", &format!("__ns:={ns}")])
        .args(["-p", &format!("scene:={SCENE}"), "-p", "use_sim_time:=true"])
        .stdout(Stdio::null())
        .stderr(Stdio::inherit())
        .spawn()
        .unwrap();
    let peer = Command::new(python())
        .arg(root().join("tests/ros/policy_replay_peer.py"))
        .args([&ns, feed.to_str().unwrap()])
        .output()
        .unwrap();
    stop(node);
    assert!(
        peer.status.success(),
        "peer: {}",
        String::from_utf8_lossy(&peer.stderr)
    );
    let mut got: Vec<(String, Value)> = Vec::new();
    for line in String::from_utf8_lossy(&peer.stdout).lines() {
        let v: Value = serde_json::from_str(line).unwrap();
        let topic = v["topic"].as_str().unwrap().to_string();
        if topic == "missed" {
            assert_eq!(v["value"], 0, "ticks the node did not answer");
            continue;
        }
        let hex = v["cdr"].as_str().unwrap();
        let bytes: Vec<u8> = (0..hex.len())
            .step_by(2)
            .map(|i| u8::from_str_radix(&hex[i..i + 2], 16).unwrap())
            .collect();
        let msg = match topic.as_str() {
            "gripper_command" => Msg::GripperCommand(GripperCommand::from_cdr(&bytes).unwrap()),
            "arm_command" => Msg::ArmCommand(ArmCommand::from_cdr(&bytes).unwrap()),
            "policy_status" => Msg::PolicyStatus(PolicyStatus::from_cdr(&bytes).unwrap()),
            other => panic!("unexpected topic {other}"),
        };
        got.push((topic, msg.to_json()));
    }
    for kind in ["gripper_command", "arm_command", "policy_status"] {
        let want: Vec<Value> = outputs
            .iter()
            .filter(|v| v["type"] == kind)
            .map(|v| (*v).clone())
            .collect();
        let have: Vec<Value> = got
            .iter()
            .filter(|(t, _)| t == kind)
            .map(|(_, v)| v.clone())
            .collect();
        assert!(!want.is_empty());
        assert_eq!(
            have.len(),
            want.len(),
            "{kind}: {} published, golden {}",
            have.len(),
            want.len()
        );
        assert_eq!(diff(&want, &have), None, "{kind}");
    }
    std::fs::remove_dir_all(&dir).ok();
}
