//! r2r <-> rclpy interop with unitac_msgs, both directions, against a real ROS 2 (PyPI wheels).
//!
//! Needs the environment of scripts/env.sh (scripts/test provides it and runs this inside a
//! network namespace with only loopback up). Each test uses its own topic prefix.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use serde_json::Value;
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn python() -> PathBuf {
    let venv = std::env::var_os("UNITAC_VENV")
        .map(PathBuf::from)
        .unwrap_or_else(|| root().join(".venv"));
    venv.join("bin/python")
}

fn peer(mode: &str, prefix: &str) -> Child {
    Command::new(python())
        .arg(root().join("tests/ros/peer.py"))
        .args([mode, prefix])
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .expect("start the rclpy peer (run through scripts/test, which sets up .venv)")
}

fn ours(mode: &str, prefix: &str) -> Child {
    Command::new(env!("CARGO_BIN_EXE_unitac_ros_interop"))
        .args([mode, "--topic-prefix", prefix])
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .unwrap()
}

/// Wait for a child with a deadline; kill it if it overruns. None if it was killed.
fn finish_within(c: &mut Child, limit: Duration) -> Option<std::process::ExitStatus> {
    let t0 = Instant::now();
    loop {
        if let Some(s) = c.try_wait().unwrap() {
            return Some(s);
        }
        if t0.elapsed() > limit {
            c.kill().ok();
            c.wait().ok();
            return None;
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// Wait (with a deadline) and parse the child's stdout as JSON lines.
fn finish(mut c: Child, limit: Duration) -> (bool, Vec<Value>) {
    let status = finish_within(&mut c, limit);
    let mut out = String::new();
    std::io::Read::read_to_string(c.stdout.as_mut().unwrap(), &mut out).unwrap();
    let lines = out
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    (status.is_some_and(|s| s.success()), lines)
}

fn prefix(name: &str) -> String {
    format!("/unitac_test_{}_{name}", std::process::id())
}

#[test]
fn r2r_publishes_rclpy_receives() {
    let p = prefix("r2r_to_rclpy");
    let sub = peer("sub", &p);
    let publisher = ours("publish", &p);
    let (sub_ok, lines) = finish(sub, Duration::from_secs(45));
    // The publisher stops once the subscriber has left (it may take discovery a moment to say so).
    let (pub_ok, _) = finish(publisher, Duration::from_secs(40));
    assert!(
        sub_ok,
        "rclpy subscriber did not get every message: {lines:?}"
    );
    assert!(pub_ok);
    let cs = &lines.iter().find(|l| l["type"] == "contact_state").unwrap()["msg"];
    assert_eq!(cs["header"]["stamp"]["sec"], 1_700_000_001);
    assert_eq!(cs["header"]["stamp"]["nanosec"], 250_000_000);
    assert_eq!(cs["header"]["frame_id"], "gsmini_optical_frame");
    assert_eq!(cs["sensor_id"], "GS-0A1B-2C3D");
    assert_eq!(cs["frame_seq"], 4_294_967_301u64);
    assert_eq!(cs["in_contact"], true);
    assert_eq!(cs["area_px"], 1234.5);
    assert!((cs["area_m2"].as_f64().unwrap() - 4.9619e-6).abs() < 1e-11);
    assert_eq!(cs["centroid_px"], serde_json::json!([160.25, 119.75]));
    assert_eq!(cs["bbox_px"], serde_json::json!([140, 100, 181, 141]));
    assert_eq!(cs["strength"], 0.625);
    assert_eq!(cs["episode_id"], 7);
    assert_eq!(cs["background_age_s"], 12.5);

    let pc = &lines
        .iter()
        .find(|l| l["type"] == "property_comparison")
        .unwrap()["msg"];
    assert_eq!(pc["header"]["stamp"]["nanosec"], 1);
    assert_eq!(pc["property"], "roughness");
    assert_eq!(
        (pc["episode_a"].as_u64(), pc["episode_b"].as_u64()),
        (Some(1), Some(2))
    );
    assert_eq!(
        (pc["label_a"].as_str(), pc["label_b"].as_str()),
        (Some("fabric_a"), Some("fabric_b"))
    );
    assert_eq!(pc["winner"], 0, "WINNER_A");
    assert_eq!(
        (pc["score_a"].as_f64(), pc["score_b"].as_f64()),
        (Some(0.8125), Some(0.1875))
    );
    assert_eq!(pc["margin"], 0.625);
    assert_eq!(pc["confidence"], 0.9375);
    assert_eq!(pc["sentence"], "B is smoother than A");

    let ac = &lines.iter().find(|l| l["type"] == "arm_command").unwrap()["msg"];
    assert_eq!(ac["header"]["stamp"]["sec"], 1_700_000_005);
    assert_eq!(ac["header"]["stamp"]["nanosec"], 2);
    assert_eq!(ac["header"]["frame_id"], "base_link");
    assert_eq!(ac["target"], "fabric_b");
    assert_eq!(ac["z_m"], 0.004);
    assert_eq!(
        (ac["x_m"].as_f64(), ac["y_m"].as_f64()),
        (Some(0.4375), Some(-0.125))
    );
    assert_eq!(ac["lift_m"], 0.0625);
    assert_eq!(ac["reason"], "grasp the smoother fabric (B)");
}

#[test]
fn rclpy_publishes_r2r_receives() {
    let p = prefix("rclpy_to_r2r");
    let echo = ours("echo", &p);
    let publisher = peer("pub", &p);
    let (echo_ok, lines) = finish(echo, Duration::from_secs(45));
    // SIGINT, so rclpy shuts down cleanly and leaves no Fast DDS shared-memory files behind.
    let mut publisher = publisher;
    Command::new("kill")
        .args(["-INT", &publisher.id().to_string()])
        .status()
        .ok();
    let _ = finish_within(&mut publisher, Duration::from_secs(5));
    assert!(echo_ok, "r2r echo did not get every message: {lines:?}");

    let lat = lines
        .iter()
        .find(|l| l["type"] == "tactile_latent")
        .unwrap();
    assert_eq!(lat["header"]["stamp"], 1_700_000_003_000_000_500i64);
    assert_eq!(lat["header"]["frame_id"], "gsmini_optical_frame");
    assert_eq!(lat["source"], "predicted");
    assert_eq!(lat["sensor_id"], "D00045");
    assert_eq!(lat["shape"], serde_json::json!([2, 3]));
    let data: Vec<f32> = lat["data"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap() as f32)
        .collect();
    assert_eq!(data, vec![0.5, -1.25, 3.0e-8, 1.0e30, -0.0, 7.0]);
    assert_eq!(lat["model_id"], "reference@1234abcd");
    assert_eq!(lat["solver"], "heun");
    assert_eq!(lat["steps"], 8);
    assert_eq!(lat["guidance"], 1.5);
    assert_eq!(lat["elapsed_s"], 0.00165);
    assert_eq!(lat["valid"], true);

    let cmd = lines
        .iter()
        .find(|l| l["type"] == "gripper_command")
        .unwrap();
    assert_eq!(cmd["header"]["stamp"], 1_700_000_004_999_999_999i64);
    assert_eq!(cmd["header"]["frame_id"], "gripper_base");
    assert_eq!(cmd["mode"], "force");
    assert_eq!(cmd["position_m"], 0.042);
    assert_eq!(cmd["speed_m_s"], 0.01);
    assert_eq!(cmd["force_n"], 12.5);
    assert_eq!(cmd["reason"], "grasp the smoother fabric (B)");

    let gs = lines
        .iter()
        .find(|l| l["type"] == "gripper_status")
        .unwrap();
    assert_eq!(gs["header"]["stamp"], 1_700_000_006_000_000_007i64);
    assert_eq!(gs["header"]["frame_id"], "gripper_base");
    assert_eq!(gs["opening_m"], 0.0375);
    assert_eq!(gs["target_m"], 0.03125);
    assert_eq!(gs["force_n"], 6.5);
    // NaN (unknown) crosses as NaN; serde_json writes it as null.
    assert!(gs["current_a"].is_null(), "{gs}");
    assert_eq!(gs["object_detected"], true);
    assert_eq!(gs["activation"], "active");
    assert_eq!(gs["motion"], "stopped");
    assert_eq!(gs["fault"], "");

    let vis = lines
        .iter()
        .find(|l| l["type"] == "visual_observation")
        .unwrap();
    assert_eq!(vis["header"]["stamp"], 1_700_000_007_000_000_008i64);
    assert_eq!(vis["names"], serde_json::json!(["cup_width_m", "cup_x_m"]));
    assert_eq!(vis["values"], serde_json::json!([0.0815, -0.125]));
}
