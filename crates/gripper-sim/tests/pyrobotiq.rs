//! pyRobotiqGripper, a Robotiq client users run today, drives the simulated 2F-85 on a pty:
//! activate, move, open, close on an object, status, object detection and re-activation
//! (tests/gripper/pyrobotiq_client.py, with the project's Python: `$UNITAC_VENV` or `.venv`,
//! where scripts/setup.sh installs the pinned pyrobotiqgripper). It writes at 0x03E9 and reads
//! at 0x07D0 with FC 0x04, 0x10 and 0x17: the register map as the manual gives it.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::PathBuf;
use std::process::Command;
use unitac_gripper::Model;
use unitac_gripper_sim::device::physics::SimObject;
use unitac_gripper_sim::device::{DeviceConfig, SimDevice};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn python() -> PathBuf {
    std::env::var_os("UNITAC_VENV")
        .map(PathBuf::from)
        .unwrap_or_else(|| root().join(".venv"))
        .join("bin/python")
}

/// The client's JSON line for `step`.
fn step<'a>(lines: &'a [serde_json::Value], name: &str) -> &'a serde_json::Value {
    lines
        .iter()
        .find(|l| l["step"] == name)
        .unwrap_or_else(|| panic!("no step {name} in {lines:?}"))
}

#[test]
fn pyrobotiqgripper_drives_the_simulated_2f85() {
    let mut cfg = DeviceConfig::new(Model::named("robotiq_2f85").unwrap());
    cfg.activation_s = 0.2;
    // A 40 mm object, fingers open at 85 mm.
    cfg.object = Some(SimObject {
        width_m: 0.040,
        stiffness_n_per_m: 20_000.0,
    });
    let dev = SimDevice::spawn(cfg).unwrap();
    let out = Command::new(python())
        .arg(root().join("tests/gripper/pyrobotiq_client.py"))
        .arg(dev.path())
        .output()
        .unwrap_or_else(|e| panic!("{}: {e} (run scripts/setup.sh)", python().display()));
    let (stdout, stderr) = (
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr),
    );
    assert!(out.status.success(), "{stdout}\n{stderr}");
    let lines: Vec<serde_json::Value> = stdout
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    println!("{stdout}");

    // Before activation: in reset.
    let s = &step(&lines, "connected")["status"];
    assert_eq!(
        (s["gACT"].as_i64(), s["gSTA"].as_i64()),
        (Some(0), Some(0)),
        "{s}"
    );
    let a = step(&lines, "activated");
    assert_eq!(a["activated"], true, "{a}");
    assert_eq!(a["status"]["gFLT"], 0, "{a}");
    // move(100): raw 100 (47.5 mm), short of the object.
    let m = step(&lines, "move");
    assert!((m["position"].as_i64().unwrap() - 100).abs() <= 1, "{m}");
    assert_eq!(m["status"]["gOBJ"], 3, "{m}");
    // open: at 0, nothing held, and no current at rest.
    let o = step(&lines, "open");
    assert!(o["position"].as_i64().unwrap() <= 1, "{o}");
    assert_eq!(o["object"], 3, "{o}");
    assert_eq!(o["status"]["gCU"], 0, "idle current: {o}");
    // close at the lowest force: stopped on the 40 mm object (raw ~120), detected while closing,
    // the motor current holding it.
    let c = step(&lines, "close");
    assert_eq!(c["object"], 2, "{c}");
    let p = c["position"].as_i64().unwrap();
    assert!((115..=128).contains(&p), "{c}");
    assert!(c["status"]["gCU"].as_i64().unwrap() > 0, "{c}");
    assert_eq!(step(&lines, "open_again")["object"], 3);
    // Re-activated after a catch: the old detection is gone.
    let r = step(&lines, "reactivated");
    assert_eq!(r["activated"], true, "{r}");
    assert_eq!(r["object"], 3, "stale gOBJ after re-activation: {r}");
    let snap = dev.snapshot();
    assert_eq!(snap.activations, 2, "{snap:?}");
    assert_eq!(snap.fault, 0, "{snap:?}");
}
