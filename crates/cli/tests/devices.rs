//! `unitac devices` and `unitac run --sensor v4l:<serial>` on sysfs fixture trees (no hardware).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::PathBuf;
use std::process::{Command, Output};

fn fixture(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../driver/tests/fixtures")
        .join(name)
}

fn unitac(root: &PathBuf, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_unitac"))
        .args(args)
        .env("UNITAC_SYSFS_ROOT", root)
        .env("RUST_LOG", "warn")
        .output()
        .unwrap()
}

#[test]
fn devices_lists_sensors_from_sysfs() {
    let root = fixture("two_sensors");
    let o = unitac(&root, &["devices", "--json"]);
    assert!(o.status.success());
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let s = j["sensors"].as_array().unwrap();
    assert_eq!(s.len(), 3);
    assert_eq!(s[0]["model"], "digit");
    assert_eq!(s[0]["serial"], "D00045");
    assert_eq!(s[0]["firmware"], "0200");
    assert!(s[0]["node"].as_str().unwrap().ends_with("dev/video0"));
    assert_eq!(s[1]["model"], "gelsight-mini");
    assert!(s[1]["node"].as_str().unwrap().ends_with("dev/video2"));
    // No device nodes in a fixture: modes are empty and say why.
    assert_eq!(s[1]["modes"].as_array().unwrap().len(), 0);
    assert!(s[1]["error"].is_string());
    assert_eq!(j["firmware_update_mode"][0], "D00051");
    let text = String::from_utf8(unitac(&root, &["devices"]).stdout).unwrap();
    assert!(text.contains("gelsight-mini 28J3-CWXU"), "{text}");
    assert!(
        text.contains("ignored camera: 0c45:636d USB Camera"),
        "{text}"
    );
}

#[test]
fn devices_with_nothing_connected_says_so() {
    for root in [
        fixture("no_sensors"),
        PathBuf::from("/nonexistent-unitac-root"),
    ] {
        let o = unitac(&root, &["devices", "--json"]);
        assert!(o.status.success());
        let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        assert_eq!(j["sensors"].as_array().unwrap().len(), 0);
        assert!(
            j["message"]
                .as_str()
                .unwrap()
                .starts_with("no tactile sensors found"),
            "{j}"
        );
    }
}

#[test]
fn run_with_a_v4l_sensor_finds_it_by_serial_and_reports_why_it_cannot_open() {
    let root = fixture("two_sensors");
    // The GelSight Mini is found; its node does not exist in a fixture tree.
    let o = unitac(
        &root,
        &[
            "run",
            "--scene",
            "fabric_selection",
            "--sensor",
            "v4l:28J3-CWXU",
        ],
    );
    assert_eq!(o.status.code(), Some(2));
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("v4l:28J3-CWXU") && e.contains("video2"), "{e}");
    assert!(!e.contains("not in this build"), "{e}");
    // A DIGIT for a GelSight scene is a configuration error.
    let o = unitac(
        &root,
        &[
            "run",
            "--scene",
            "fabric_selection",
            "--sensor",
            "v4l:D00045",
        ],
    );
    assert_eq!(o.status.code(), Some(2));
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("D00045 is a digit"), "{e}");
    // Without a serial: the only GelSight Mini on the bus is taken.
    let o = unitac(
        &root,
        &["run", "--scene", "fabric_selection", "--sensor", "v4l"],
    );
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("v4l:28J3-CWXU"), "{e}");
    // Unknown serial: the message lists what is connected.
    let o = unitac(
        &root,
        &[
            "run",
            "--scene",
            "fabric_selection",
            "--sensor",
            "v4l:ABCD-EFGH",
        ],
    );
    let e = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2));
    assert!(e.contains("D00045") && e.contains("28J3-CWXU"), "{e}");
}
