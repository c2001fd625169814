//! The policy node on a ros2_control gripper: `gripper_output:=action` sends its commands as
//! control_msgs/action/GripperCommand goals to an rclpy GripperActionController stand-in
//! (tests/ros/gripper_action_server.py; control_msgs built from its upstream text by setup), and
//! reads the gripper from joint_states. Abort and preemption by another client get the safe
//! action on the next control tick; arm targets come out as PoseStamped in `arm_frame`; a VTLA-real
//! cup trial in the ROS sim with the sim's gripper behind the action server ends as the same
//! trial with the policy's GripperCommands. scripts/test runs this in a loopback-only network
//! namespace; the times compared are stamps (sim time), not wall clocks.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;
use common::closed_loop::{
    ACTION_POLICY, GripperPath, Launcher, Loop, Observer, PERIOD_NS, SCENE, heard, here, phases,
    statuses,
};
use common::stop;
use serde_json::Value;
use std::time::Duration;

const HERE: Launcher = &here;
/// The stand-in's joint states come every 10 ms of its sim time: a tick is the first at or after
/// its due time.
const STATE_PERIOD_NS: i64 = 10_000_000;

/// One test at a time: each runs several processes on a small machine.
static SERIAL: std::sync::Mutex<()> = std::sync::Mutex::new(());

fn ns(name: &str) -> String {
    format!("/ga{}_{name}", std::process::id())
}

/// The policy's ticks around a fault at `t` (the controller's sim time when it failed the goal):
/// the last tick before was in control, the first after is the safe action with the fault's
/// reason, one control period after the tick before it; and a later tick is in control again
/// (the safe action's own goal succeeded).
fn check_fault(st: &[Value], t: i64, why: &str) {
    let stamp = |s: &Value| s["stamp"].as_i64().unwrap();
    let before = st
        .iter()
        .rev()
        .find(|s| stamp(s) <= t)
        .expect("a tick before");
    assert_eq!(before["safety_ok"], true, "{before}");
    let first = st.iter().find(|s| stamp(s) > t).expect("a tick after");
    assert_eq!(first["safety_ok"], false, "{first}");
    let msg = first["message"].as_str().unwrap();
    assert!(msg.contains(why), "{why}: {first}");
    let gap = stamp(first) - stamp(before);
    assert!(
        gap <= PERIOD_NS + STATE_PERIOD_NS,
        "safe action {gap} ns after the last tick: {first}"
    );
    assert!(stamp(first) - t <= PERIOD_NS + STATE_PERIOD_NS);
    assert!(
        st.iter()
            .any(|s| stamp(s) > stamp(first) && s["safety_ok"] == true),
        "no control after the fault {why}"
    );
}

/// Ask the controller for a fault (`abort` or `preempt`) on the policy's next goal: the sim
/// time it happened at.
fn fault(ctl: &mut Observer, cmd: &str, answer: &str) -> i64 {
    ctl.send(cmd);
    let got = ctl.wait_for(|l| l.starts_with(answer) || l == "no goal", 30);
    assert_ne!(got, "no goal", "{cmd}: the policy sent no goal within 20 s");
    got[answer.len()..].parse().unwrap()
}

#[test]
fn abort_and_preemption_get_the_safe_action_on_the_next_tick_and_arm_targets_are_poses() {
    let _one = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let n = ns("faults");
    let mut ctl = Observer::script(
        HERE,
        "gripper_action_server.py",
        &[&n, "gripper_cmd", "120", "own"],
    );
    ctl.wait_for(|l| l == "ready", 30);
    let (policy, log) = common::closed_loop::node_heard(
        HERE,
        "robot",
        env!("CARGO_BIN_EXE_unitac_policy_node"),
        &n,
        &[
            &[
                "-p",
                "scene:=cup_deformation_vla",
                "-p",
                "use_sim_time:=true",
                "-p",
                "arm_frame:=table",
            ][..],
            &ACTION_POLICY,
        ]
        .concat(),
    );
    // The policy's first goal (the approach's opening), then a second of control. Each fault
    // ends the policy's latest goal once it sent one, and the controller's clock waits from that goal until the
    // policy has heard of the fault: the claim is about the policy's next tick, not about how
    // fast the end reaches it.
    const ABORTED: &str = "gripper action: goal aborted by the server";
    const PREEMPTED: &str = "gripper action: goal preempted or canceled by another client";
    ctl.wait_for(|l| l.starts_with("goal "), 60);
    std::thread::sleep(Duration::from_secs(1));
    let aborted = fault(&mut ctl, "abort", "aborted ");
    heard(&log, ABORTED, 30);
    ctl.send("resume");
    std::thread::sleep(Duration::from_millis(500));
    let preempted = fault(&mut ctl, "preempt", "preempted ");
    heard(&log, PREEMPTED, 30);
    ctl.send("resume");
    std::thread::sleep(Duration::from_secs(2));
    ctl.send("end");
    let got: Value = serde_json::from_str(&ctl.wait_for(|l| l.starts_with('{'), 30)).unwrap();
    stop(policy);
    let st = got["status"].as_array().unwrap();
    eprintln!(
        "goals {}; ends {}; {} ticks",
        got["goals"],
        got["ends"],
        st.len()
    );
    check_fault(st, aborted, ABORTED);
    check_fault(st, preempted, PREEMPTED);
    // Arm targets: in the arm frame, at the camera's cup (x 0.45 m, y 0), the tool turned over.
    let poses = got["poses"].as_array().unwrap();
    assert!(!poses.is_empty());
    for p in poses {
        assert_eq!(p["frame_id"], "table", "{p}");
        let xyz = p["position"].as_array().unwrap();
        assert!((xyz[0].as_f64().unwrap() - 0.45).abs() < 1e-9, "{p}");
        assert!(xyz[1].as_f64().unwrap().abs() < 1e-9, "{p}");
        assert!(xyz[2].as_f64().unwrap().is_finite());
        let qx = p["orientation"][0].as_f64().unwrap();
        assert!((qx.abs() - 1.0).abs() < 1e-9, "{p}");
    }
}

/// The sim's cup outcome (deformation, over-compression, lift, collision, overall) and the
/// policy's phases for one trial through `path`.
fn trial(path: GripperPath) -> (Value, Vec<String>, Option<Value>) {
    let n = ns(&format!("{path:?}").to_lowercase());
    let obs = Observer::start(HERE, &n, 90);
    let mut l = Loop::start_with(HERE, &n, 12.0, &obs, path);
    obs.wait_for(|s| s == "outcome", 80);
    let got = obs.finish();
    let controller = l.controller.take().map(|mut c| {
        c.send("end");
        serde_json::from_str::<Value>(&c.wait_for(|l| l.starts_with('{'), 30)).unwrap()
    });
    l.stop();
    let phases = phases(&got).into_iter().map(String::from).collect();
    for s in statuses(&got) {
        assert_eq!(s["scene"], SCENE);
    }
    (got["outcome"]["outcome"]["cup"].clone(), phases, controller)
}

#[test]
fn a_vtla_real_cup_trial_through_the_gripper_action_ends_as_through_gripper_commands() {
    let _one = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let (direct, direct_phases, _) = trial(GripperPath::Commands);
    let (action, action_phases, controller) = trial(GripperPath::Action);
    eprintln!("direct {direct}\n{direct_phases:?}\naction {action}\n{action_phases:?}");
    let controller = controller.unwrap();
    eprintln!(
        "controller: goals {}, ends {}",
        controller["goals"], controller["ends"]
    );
    for k in [
        "deformation",
        "over_compressed",
        "lift",
        "collision",
        "overall",
    ] {
        assert_eq!(
            direct[k], action[k],
            "{k}: direct {direct}, action {action}"
        );
    }
    assert_eq!(action["overall"], true, "{action}");
    // The same course: the probe touch, its latent, the squeeze, the lift.
    for want in ["probe", "await_latent", "squeeze", "hold", "lift", "done"] {
        assert!(
            action_phases.iter().any(|p| p == want),
            "{want}: {action_phases:?}"
        );
    }
    // Goals were sent on changes, not once per tick (a 12 s trial is 360 ticks).
    let goals = controller["goals"].as_array().unwrap().len();
    assert!((3..200).contains(&goals), "{goals} goals");
}
