//! The URDF/xacro descriptions expand with the real `xacro` and contain every frame_id the nodes
//! publish, as a proper tree with REP 103 optical frames.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use serde_json::Value;
use std::collections::{HashMap, HashSet};
use std::path::PathBuf;
use std::process::Command;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn expand(file: &str, args: &[&str]) -> Value {
    let py = std::env::var_os("UNITAC_VENV")
        .map(PathBuf::from)
        .unwrap_or_else(|| root().join(".venv"))
        .join("bin/python");
    let o = Command::new(py)
        .arg(root().join("tests/ros/check_urdf.py"))
        .arg(root().join("urdf").join(file))
        .args(args)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    serde_json::from_slice(&o.stdout).unwrap()
}

#[test]
fn example_mount_has_the_frames_the_nodes_publish() {
    // The node tests publish with sensor_id "gsmini" (sensor node) and images framed
    // "gs1_optical_frame" (contact node peer); the mock default is "mock_gelsight_mini".
    for (left, right) in [
        ("gsmini", "digit1"),
        ("gs1", "mock_digit"),
        ("mock_gelsight_mini", "d2"),
    ] {
        let u = expand(
            "example_gripper.urdf.xacro",
            &[
                &format!("left_sensor:={left}"),
                &format!("right_sensor:={right}"),
            ],
        );
        let links: HashSet<&str> = u["links"]
            .as_array()
            .unwrap()
            .iter()
            .map(|l| l.as_str().unwrap())
            .collect();
        for s in [left, right] {
            assert!(
                links.contains(format!("{s}_optical_frame").as_str()),
                "{s}: {links:?}"
            );
            assert!(links.contains(format!("{s}_link").as_str()));
        }
        // A tree: every link but the root is the child of exactly one joint, and every joint
        // connects existing links.
        let joints = u["joints"].as_array().unwrap();
        let mut parent_of: HashMap<&str, &str> = HashMap::new();
        for j in joints {
            let (p, c) = (j["parent"].as_str().unwrap(), j["child"].as_str().unwrap());
            assert!(links.contains(p) && links.contains(c), "{j}");
            assert!(parent_of.insert(c, p).is_none(), "{c} has two parents");
        }
        let roots: Vec<&&str> = links
            .iter()
            .filter(|l| !parent_of.contains_key(**l))
            .collect();
        assert_eq!(roots, vec![&"gripper_base"]);
        // REP 103 optical frames: rpy (-pi/2, 0, -pi/2) from the body (x out of the gel).
        for j in joints
            .iter()
            .filter(|j| j["child"].as_str().unwrap().ends_with("_optical_frame"))
        {
            let rpy: Vec<f64> = j["rpy"]
                .as_array()
                .unwrap()
                .iter()
                .map(|v| v.as_f64().unwrap())
                .collect();
            let h = std::f64::consts::FRAC_PI_2;
            assert!(
                (rpy[0] + h).abs() < 1e-9 && rpy[1].abs() < 1e-9 && (rpy[2] + h).abs() < 1e-9,
                "{j}"
            );
        }
    }
}
