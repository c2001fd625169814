//! Two hosts on one machine: a "robot" and a "gpu" network namespace joined by a veth pair (the
//! test's own addresses, only on that veth, inside namespaces it creates and always deletes).
//! (`scripts/two-hosts`.) The robot runs the sensor and contact nodes and an rclpy observer; the gpu host runs the
//! inference node. DDS crosses the veth over UDP (no shared memory: FASTDDS_BUILTIN_TRANSPORTS=
//! UDPv4), discovery by multicast on the veth's subnet plus static peers (the deployment recipe
//! in crates/ros/README.md). Checked: the properties and the comparison of the episodes the robot
//! detected come back from the gpu host, and only clips and the background cross, not the image
//! stream (bytes on the veth against a run where the gpu host subscribes to the raw images).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;
use common::{python, root, stop};
use serde_json::Value;
use std::process::{Child, Command, Stdio};
use std::time::Instant;

/// The two hosts of `scripts/two-hosts` (the one place that creates them); dropping it deletes
/// both namespaces (and with them the veth), also when the test fails.
struct Hosts {
    id: String,
}

fn two_hosts(args: &[&str]) -> Command {
    let mut c = Command::new("bash");
    c.arg(root().join("scripts/two-hosts")).args(args);
    c
}

impl Hosts {
    fn up() -> Hosts {
        let h = Hosts {
            id: std::process::id().to_string(),
        };
        let s = two_hosts(&["up", &h.id]).status().unwrap();
        assert!(s.success(), "scripts/two-hosts up failed");
        h
    }

    /// `program` run on `host` (robot | gpu) with the two-host DDS settings.
    fn exec(&self, host: &str, program: &str) -> Command {
        two_hosts(&["exec", host, &self.id, program])
    }

    /// Bytes sent plus received on the robot's end of the veth so far.
    fn veth_bytes(&self) -> u64 {
        let o = two_hosts(&["bytes", &self.id]).output().unwrap();
        assert!(o.status.success());
        String::from_utf8_lossy(&o.stdout).trim().parse().unwrap()
    }
}

impl Drop for Hosts {
    fn drop(&mut self) {
        let _ = two_hosts(&["down", &self.id]).status();
    }
}

fn node(mut c: Command, ns: &str, args: &[&str]) -> Child {
    c.args(["--ros-args", "-r", &format!("__ns:={ns}")])
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::inherit())
        .spawn()
        .unwrap()
}

fn sensor(h: &Hosts, ns: &str) -> Child {
    node(
        h.exec("robot", env!("CARGO_BIN_EXE_unitac_sensor_node")),
        ns,
        &[
            "-p",
            "scene:=fabric_selection",
            "-p",
            "sensor_id:=gsmini",
            "-p",
            "wait_subscribers:=2",
        ],
    )
}

#[test]
fn inference_on_a_second_host_answers_the_robots_episodes_and_only_clips_cross() {
    let h = Hosts::up();
    let py = python();
    let py = py.to_str().unwrap();
    let peer = root().join("tests/ros/contact_peer.py");
    let peer = peer.to_str().unwrap();
    let ns = format!("/two{}", std::process::id());

    // Clips only: contact on the robot, inference on the gpu host.
    let contact = node(
        h.exec("robot", env!("CARGO_BIN_EXE_unitac_contact_node")),
        &ns,
        &["-r", "image:=image_raw", "-p", "scene:=fabric_selection"],
    );
    let inference = node(
        h.exec("gpu", env!("CARGO_BIN_EXE_unitac_inference_node")),
        &ns,
        &["-p", "scene:=fabric_selection"],
    );
    // The observer waits until the gpu host's comparison publisher is discovered on the robot.
    let opts = serde_json::json!({"until": {"comparisons": 1, "episodes": 2},
        "wait_for": ["/contact_state", "/contact_episode", "/property_comparison"]});
    let listener = h
        .exec("robot", py)
        .args([peer, "listen", &ns, "90", &opts.to_string()])
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let b0 = h.veth_bytes();
    let t0 = Instant::now();
    let s = sensor(&h, &ns);
    let out = listener.wait_with_output().unwrap();
    let (clips_bytes, clips_s) = (h.veth_bytes() - b0, t0.elapsed().as_secs_f64());
    stop(s);
    stop(contact);
    stop(inference);
    assert!(out.status.success());
    let got: Value = serde_json::from_slice(&out.stdout).unwrap();
    let labels = |k: &str| common::labels(&got, k);
    assert_eq!(labels("episodes"), ["fabric_a", "fabric_b"], "{got}");
    assert_eq!(labels("properties"), ["fabric_a", "fabric_b"], "{got}");
    let cmp = got["comparisons"].as_array().unwrap();
    assert_eq!(cmp.len(), 1, "{cmp:?}");
    assert!(
        cmp[0]["sentence"]
            .as_str()
            .unwrap()
            .contains("fabric_b is smoother than fabric_a"),
        "{cmp:?}"
    );
    let images = got["images"].as_u64().unwrap() as f64;

    // Raw images: the same sensor with a subscriber to image_raw on the gpu host instead.
    let raw_sub = h
        .exec("gpu", py)
        .args([peer, "slow", &ns, "12", "0"])
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let local = h
        .exec("robot", py)
        .args([peer, "slow", &ns, "12", "0"])
        .stdout(Stdio::null())
        .spawn()
        .unwrap();
    let b1 = h.veth_bytes();
    let t1 = Instant::now();
    let s = sensor(&h, &ns);
    let raw_out = raw_sub.wait_with_output().unwrap();
    let (raw_bytes, raw_s) = (h.veth_bytes() - b1, t1.elapsed().as_secs_f64());
    stop(s);
    let _ = local.wait_with_output();
    let raw: Value = serde_json::from_slice(&raw_out.stdout).unwrap();
    let raw_images = raw["images"].as_u64().unwrap() as f64;
    assert!(
        raw_images > 50.0,
        "the gpu host received {raw_images} images"
    );

    let (clips_rate, raw_rate) = (clips_bytes as f64 / clips_s, raw_bytes as f64 / raw_s);
    eprintln!(
        "two hosts, one 25 fps 320x240 sensor: clips + background {clips_rate:.0} B/s \
         ({clips_bytes} B in {clips_s:.1} s, {images} images on the robot); raw images \
         {raw_rate:.0} B/s ({raw_bytes} B in {raw_s:.1} s, {raw_images} images on the gpu host)"
    );
    // Every raw image crosses: at least its pixels per image.
    assert!(raw_bytes as f64 >= raw_images * 230_400.0, "{raw_bytes} B");
    // Clips are 8 frames per episode plus the background: far less than the stream.
    assert!(
        (clips_bytes as f64) < 0.5 * images * 230_400.0,
        "{clips_bytes} B crossed for {images} images"
    );
}
