//! The contact and sensor nodes as processes against an rclpy peer (real ROS 2 from the wheels;
//! scripts/test runs this in a loopback-only network namespace).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use serde_json::Value;
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn python() -> PathBuf {
    std::env::var_os("UNITAC_VENV")
        .map(PathBuf::from)
        .unwrap_or_else(|| root().join(".venv"))
        .join("bin/python")
}

fn node(bin: &str, ns: &str, params: Option<&str>) -> Child {
    let mut c = Command::new(bin);
    c.args(["--ros-args", "-r", &format!("__ns:={ns}")]);
    if let Some(p) = params {
        c.args(["--params-file", p]);
    }
    c.stdout(Stdio::null())
        .stderr(Stdio::inherit())
        .spawn()
        .unwrap()
}

fn stop(mut c: Child) {
    Command::new("kill")
        .args(["-INT", &c.id().to_string()])
        .status()
        .ok();
    let t = Instant::now();
    while t.elapsed() < Duration::from_secs(5) {
        if c.try_wait().unwrap().is_some() {
            return;
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    c.kill().ok();
    c.wait().ok();
}

fn peer(args: &[&str]) -> Value {
    let o = Command::new(python())
        .arg(root().join("tests/ros/contact_peer.py"))
        .args(args)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    serde_json::from_slice(&o.stdout).unwrap()
}

fn ns(name: &str) -> String {
    format!("/t{}_{name}", std::process::id())
}

fn params_file(name: &str, body: &str) -> PathBuf {
    let p = std::env::temp_dir().join(format!("unitac-{}-{name}.yaml", std::process::id()));
    std::fs::write(&p, body).unwrap();
    p
}

#[test]
fn contact_node_answers_every_image_with_a_contact_state() {
    let n = ns("contact");
    let p = params_file(
        "contact",
        "/**:\n  ros__parameters:\n    sensor_kind: generic\n    enter_area_px: 100.0\n    exit_area_px: 50.0\n",
    );
    let c = node(env!("CARGO_BIN_EXE_unitac_contact_node"), &n, p.to_str());
    let got = peer(&["images", &n, "40"]);
    stop(c);
    let states = got["states"].as_array().unwrap();
    // 40 images, the first 10 learn the background: 30 states, in order, with the images' stamps.
    assert_eq!(states.len(), 30, "{got}");
    assert!(
        states
            .iter()
            .all(|s| s["frame_id"] == "gs1_optical_frame" && s["sensor_id"] == "gs1")
    );
    let stamps: Vec<i64> = states
        .iter()
        .map(|s| s["stamp"].as_i64().unwrap())
        .collect();
    assert!(stamps.windows(2).all(|w| w[0] < w[1]));
    assert_eq!(
        stamps[0], 1_700_000_000_400_000_000,
        "the 11th image's capture stamp"
    );
    let on: Vec<bool> = states
        .iter()
        .map(|s| s["in_contact"].as_bool().unwrap())
        .collect();
    // The disc is in images 15..25 = states 5..15; debounce makes contact start one frame late.
    assert!(
        !on[..5].iter().any(|&v| v) && on[6..15].iter().all(|&v| v) && !on[17..].iter().any(|&v| v),
        "{on:?}"
    );
    let eps = got["episodes"].as_array().unwrap();
    assert_eq!(eps.len(), 1, "{got}");
    assert!(eps[0]["peak"].as_f64().unwrap() > 300.0);
    // Diagnostics from the node, with its counters.
    let d = got["diag"].as_array().unwrap();
    assert!(
        d.iter().any(
            |s| s["name"].as_str().unwrap().starts_with("unitac_contact")
                && s["values"]["frames_in"] != "0"
        ),
        "{d:?}"
    );
}

#[test]
fn parameters_from_a_yaml_file_take_effect() {
    let n = ns("params");
    // An enter area larger than the image: the same disc is never a contact.
    let p = params_file(
        "params",
        "/**:\n  ros__parameters:\n    sensor_kind: generic\n    enter_area_px: 100000.0\n    exit_area_px: 50.0\n",
    );
    let c = node(env!("CARGO_BIN_EXE_unitac_contact_node"), &n, p.to_str());
    let got = peer(&["images", &n, "40"]);
    stop(c);
    let states = got["states"].as_array().unwrap();
    assert_eq!(states.len(), 30, "{got}");
    assert!(states.iter().all(|s| s["in_contact"] == false));
    assert!(got["episodes"].as_array().unwrap().is_empty());
}

#[test]
fn sensor_and_contact_nodes_find_the_fabric_episodes() {
    let n = ns("pipeline");
    let sp = params_file(
        "sensor",
        "/**:\n  ros__parameters:\n    sensor_id: gsmini\n    scenario: fabric_selection\n    fps: 25.0\n    wait_subscribers: 2\n",
    );
    let cp = params_file(
        "cnode",
        "/**:\n  ros__parameters:\n    sensor_kind: gelsight-mini\n",
    );
    let contact = Command::new(env!("CARGO_BIN_EXE_unitac_contact_node"))
        .args([
            "--ros-args",
            "-r",
            &format!("__ns:={n}"),
            "-r",
            "image:=image_raw",
            "--params-file",
            cp.to_str().unwrap(),
        ])
        .stderr(Stdio::inherit())
        .spawn()
        .unwrap();
    let listener = Command::new(python())
        .arg(root().join("tests/ros/contact_peer.py"))
        .args(["listen", &n, "40", "2"])
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let sensor = node(env!("CARGO_BIN_EXE_unitac_sensor_node"), &n, sp.to_str());
    let out = listener.wait_with_output().unwrap();
    stop(sensor);
    stop(contact);
    let got: Value = serde_json::from_slice(&out.stdout).unwrap();
    // How many images a Python subscriber keeps up with depends on the machine's load; that it
    // sees them, with the right frame_id, does not.
    assert!(got["images"].as_u64().unwrap() > 0, "{}", got["images"]);
    assert_eq!(
        got["image_frames"],
        serde_json::json!(["gsmini_optical_frame"])
    );
    assert_eq!(
        got["episodes"].as_array().unwrap().len(),
        2,
        "{}",
        got["episodes"]
    );
    assert!(
        got["states"]
            .as_array()
            .unwrap()
            .iter()
            .all(|s| s["frame_id"] == "gsmini_optical_frame")
    );
}
