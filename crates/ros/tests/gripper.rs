//! The gripper node against a simulated Robotiq 2F-85 speaking Modbus RTU on a pseudo-terminal
//! (`unitac gripper simulate`), with an rclpy peer: GripperStatus and JointState come out of the
//! node, GripperCommand goes in, and the simulated object (half the stroke wide) is caught and
//! released.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;
use common::{python, root, stop};
use serde_json::Value;
use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// The `unitac` binary of this build (cargo test --workspace builds it next to the tests).
fn unitac() -> PathBuf {
    let exe = std::env::current_exe().unwrap();
    let p = exe.parent().unwrap().parent().unwrap().join("unitac");
    assert!(p.is_file(), "{} missing: build the workspace", p.display());
    p
}

#[test]
fn gripper_node_publishes_status_and_follows_commands_on_a_simulated_robotiq() {
    let dir = std::env::temp_dir().join(format!("unitac-gripper-node-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let link = dir.join("ttyROBOTIQ");
    let device = Command::new(unitac())
        .args(["gripper", "--model", "robotiq_2f85", "--port"])
        .arg(&link)
        .args(["--seconds", "90", "simulate"])
        .stdout(Stdio::null())
        .spawn()
        .unwrap();
    let t = Instant::now();
    while !link.exists() {
        assert!(t.elapsed() < Duration::from_secs(20), "no simulated device");
        std::thread::sleep(Duration::from_millis(50));
    }
    let ns = format!("/grip{}", std::process::id());
    let node = Command::new(env!("CARGO_BIN_EXE_unitac_gripper_node"))
        .args(["--ros-args", "-r", &format!("__ns:={ns}")])
        .args(["-p", &format!("port:={}", link.display())])
        .args(["-p", "model:=robotiq_2f85", "-p", "rate_hz:=100.0"])
        .stdout(Stdio::null())
        .spawn()
        .unwrap();
    let out = Command::new(python())
        .arg(root().join("tests/ros/gripper_peer.py"))
        .args([&ns, "60"])
        .output()
        .unwrap();
    stop(node);
    stop(device);
    std::fs::remove_dir_all(&dir).ok();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "peer failed: {text}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let got: Value = serde_json::from_str(text.trim()).unwrap();
    // The 2F-85's stroke is 85 mm; the simulated object is half of it, 20 000 N/m stiff.
    let caught = &got["caught"];
    assert_eq!(caught["object_detected"], true, "{caught}");
    assert_eq!(caught["motion"], "caught");
    assert_eq!(caught["fault"], "");
    assert_eq!(caught["header"]["frame_id"], "gripper_base");
    let w = caught["opening_m"].as_f64().unwrap();
    assert!(
        (w - 0.0425).abs() < 0.004,
        "caught at {w} m, object 0.0425 m"
    );
    let opened = &got["opened"];
    assert_eq!(opened["object_detected"], false, "{opened}");
    let o = opened["opening_m"].as_f64().unwrap();
    assert!(
        (o - 0.08).abs() < 0.003,
        "opened to {o} m, commanded 0.08 m"
    );
    // joint_states carries the same opening, in the same frame, under the joint's name.
    let joints = got["joints"].as_array().unwrap();
    for (j, s) in joints.iter().zip([caught, opened]) {
        let pos = j[0][0].as_f64().unwrap();
        let want = s["opening_m"].as_f64().unwrap();
        assert!((pos - want).abs() < 0.002, "joint {pos} vs status {want}");
        assert_eq!(j[2], "gripper_base");
        assert_eq!(j[3][0], "gripper_finger_opening");
    }
    assert!(got["statuses"].as_u64().unwrap() > 10);
}
