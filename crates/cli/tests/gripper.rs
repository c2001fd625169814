//! `unitac gripper` against the simulated device (`--port sim`) and bad ports.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::process::{Command, Output};

mod common;
use common::unitac_gripper as unitac;

fn text(o: &Output) -> (String, String) {
    (
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

#[test]
fn activate_and_status_on_the_simulated_gripper() {
    let o = unitac(&["--port", "sim", "--model", "robotiq_2f85", "status"]);
    let (out, err) = text(&o);
    assert!(o.status.success(), "{err}");
    assert!(
        out.contains("robotiq_2f85 on /dev/pts/") && out.contains("inactive"),
        "{out}"
    );
    let o = unitac(&["--port", "sim", "--model", "dh_ag95", "--json", "activate"]);
    let (out, err) = text(&o);
    assert!(o.status.success(), "{err}");
    let v: serde_json::Value = serde_json::from_str(out.trim()).unwrap();
    assert_eq!(v["activation"], "active");
    assert_eq!(v["fault"], serde_json::Value::Null);
}

#[test]
fn bad_ports_get_messages_that_say_what_is_wrong() {
    let o = unitac(&[
        "--port",
        "/dev/ttyUSB-unitac-none",
        "--model",
        "robotiq_2f85",
        "status",
    ]);
    let (_, err) = text(&o);
    // A port that is not there is bad configuration, found before any work.
    assert_eq!(o.status.code(), Some(2));
    assert!(
        err.contains("/dev/ttyUSB-unitac-none: no such serial device"),
        "{err}"
    );
    let o = unitac(&["--port", "/dev/null", "--model", "dh_ag95", "status"]);
    let (_, err) = text(&o);
    assert!(err.contains("/dev/null: not a serial port"), "{err}");
    assert_eq!(o.status.code(), Some(1));
    let o = unitac(&["--port", "sim", "--model", "robotiq_3f", "status"]);
    let (_, err) = text(&o);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        err.contains("known: dh_ag95, dh_pge50, robotiq_2f140, robotiq_2f85"),
        "{err}"
    );
}

#[test]
fn a_simulated_gripper_in_one_process_is_driven_from_another() {
    let link = std::env::temp_dir().join(format!("unitac-gripper-cli-{}", std::process::id()));
    let mut sim = Command::new(env!("CARGO_BIN_EXE_unitac"))
        .args([
            "gripper",
            "--port",
            link.to_str().unwrap(),
            "--model",
            "robotiq_2f85",
        ])
        .args(["--seconds", "20", "simulate"])
        .stdout(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let t0 = std::time::Instant::now();
    while !link.exists() && t0.elapsed() < std::time::Duration::from_secs(10) {
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    let port = link.to_str().unwrap();
    let o = unitac(&["--port", port, "--model", "robotiq_2f85", "activate"]);
    assert!(o.status.success(), "{:?}", text(&o));
    // Close on the simulated 42.5 mm object at 100 N: stops where the contact force is 100 N.
    let o = unitac(&[
        "--port",
        port,
        "--model",
        "robotiq_2f85",
        "--force",
        "100",
        "--json",
        "close",
    ]);
    let (out, err) = text(&o);
    assert!(o.status.success(), "{err}");
    let v: serde_json::Value = serde_json::from_str(out.trim()).unwrap();
    assert_eq!(v["motion"], "caught", "{out}");
    let opening = v["opening_m"].as_f64().unwrap();
    assert!(
        (opening - (0.0425 - 100.0 / 20_000.0)).abs() < 0.0008,
        "{opening}"
    );
    // A new process reads it still caught: nothing was reset on start.
    let o = unitac(&[
        "--port",
        port,
        "--model",
        "robotiq_2f85",
        "--json",
        "status",
    ]);
    let v: serde_json::Value = serde_json::from_str(text(&o).0.trim()).unwrap();
    assert_eq!(v["motion"], "caught");
    assert_eq!(v["activation"], "active");
    sim.kill().unwrap();
    let _ = sim.wait();
    let _ = std::fs::remove_file(&link);
}

/// A `simulate` process serving a Robotiq 2F-85 at a fresh link (`extra`: more arguments of
/// `simulate`), and the link.
fn simulated(tag: &str, extra: &[&str]) -> (std::process::Child, std::path::PathBuf) {
    let link =
        std::env::temp_dir().join(format!("unitac-gripper-cli-{tag}-{}", std::process::id()));
    let sim = Command::new(env!("CARGO_BIN_EXE_unitac"))
        .args([
            "gripper",
            "--port",
            link.to_str().unwrap(),
            "--model",
            "robotiq_2f85",
        ])
        .args(["--seconds", "30"])
        .args(extra)
        .arg("simulate")
        .stdout(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let t0 = std::time::Instant::now();
    while !link.exists() && t0.elapsed() < std::time::Duration::from_secs(10) {
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    (sim, link)
}

#[test]
fn bench_reads_status_only_unless_motion_is_allowed() {
    let (mut sim, link) = simulated("bench", &[]);
    let port = link.to_str().unwrap();
    let status = |port: &str| {
        let o = unitac(&[
            "--port",
            port,
            "--model",
            "robotiq_2f85",
            "--json",
            "status",
        ]);
        serde_json::from_str::<serde_json::Value>(text(&o).0.trim()).unwrap()
    };
    let before = status(port);
    assert_eq!(before["activation"], "inactive", "{before}");
    let o = unitac(&[
        "--port",
        port,
        "--model",
        "robotiq_2f85",
        "--seconds",
        "0.3",
        "bench",
    ]);
    let (out, err) = text(&o);
    assert!(o.status.success(), "{out}{err}");
    assert!(out.contains("status reads only"), "{out}");
    // The bench wrote nothing: the gripper is still inactive, the fingers where they were.
    let after = status(port);
    assert_eq!(after["activation"], "inactive", "{after}");
    assert_eq!(after["raw_position"], before["raw_position"], "{after}");
    // With --allow-motion it says what it writes, and does.
    let o = unitac(&[
        "--port",
        port,
        "--model",
        "robotiq_2f85",
        "--seconds",
        "0.3",
        "--allow-motion",
        "bench",
    ]);
    let (out, err) = text(&o);
    assert!(o.status.success(), "{out}{err}");
    assert!(err.contains("an inactive gripper is activated"), "{err}");
    assert_ne!(status(port)["activation"], "inactive");
    sim.kill().unwrap();
    let _ = sim.wait();
    let _ = std::fs::remove_file(&link);
}

#[test]
fn activate_clears_a_major_fault_and_open_refuses_while_it_is_there() {
    let (mut sim, link) = simulated("fault", &["--inject", "overcurrent"]);
    let port = link.to_str().unwrap();
    let o = unitac(&["--port", port, "--model", "robotiq_2f85", "status"]);
    let (out, _) = text(&o);
    assert_eq!(o.status.code(), Some(1), "{out}");
    assert!(out.contains("MAJOR fault 0x0E"), "{out}");
    assert!(out.contains("activate"), "says how to clear it: {out}");
    // No motion command while the fault is there: it says what to do instead.
    let o = unitac(&["--port", port, "--model", "robotiq_2f85", "open"]);
    let (out, err) = text(&o);
    assert_eq!(o.status.code(), Some(1), "{out}{err}");
    assert!(
        err.contains("major fault 0x0E") && err.contains("activate"),
        "{err}"
    );
    // activate writes rACT 0 then 1: the fault is gone, the gripper active.
    let o = unitac(&[
        "--port",
        port,
        "--model",
        "robotiq_2f85",
        "--json",
        "activate",
    ]);
    let (out, err) = text(&o);
    assert!(o.status.success(), "{out}{err}");
    let v: serde_json::Value = serde_json::from_str(out.trim()).unwrap();
    assert_eq!(v["activation"], "active", "{out}");
    assert_eq!(v["fault"], serde_json::Value::Null, "{out}");
    sim.kill().unwrap();
    let _ = sim.wait();
    let _ = std::fs::remove_file(&link);
}

#[test]
fn a_major_fault_that_persists_after_re_activation_is_refused_with_what_to_do() {
    let (mut sim, link) = simulated("stuck", &["--inject", "overcurrent-persistent"]);
    let port = link.to_str().unwrap();
    let o = unitac(&["--port", port, "--model", "robotiq_2f85", "activate"]);
    let (out, err) = text(&o);
    assert_eq!(o.status.code(), Some(1), "{out}{err}");
    assert!(err.contains("persists after re-activation"), "{err}");
    assert!(err.contains("power"), "{err}");
    sim.kill().unwrap();
    let _ = sim.wait();
    let _ = std::fs::remove_file(&link);
}

/// `unitac gripper --port LINK --model MODEL [extra] --seconds 1 status`: (exit code, stderr).
fn status_of(link: &std::path::Path, model: &str, extra: &[&str]) -> (Option<i32>, String) {
    let mut args = vec!["--port", link.to_str().unwrap(), "--model", model];
    args.extend_from_slice(extra);
    args.extend_from_slice(&["--seconds", "1", "status"]);
    let o = unitac(&args);
    (o.status.code(), text(&o).1)
}

#[test]
fn a_device_that_answers_wrongly_is_not_reported_as_silent() {
    // A DH controller on the bus where a Robotiq is expected: it answers Robotiq's status read
    // (FC 0x04) with an exception.
    let link = std::env::temp_dir().join(format!("unitac-gripper-cli-dh-{}", std::process::id()));
    let mut sim = Command::new(env!("CARGO_BIN_EXE_unitac"))
        .args([
            "gripper",
            "--port",
            link.to_str().unwrap(),
            "--model",
            "dh_ag95",
        ])
        .args(["--seconds", "30", "simulate"])
        .stdout(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let t0 = std::time::Instant::now();
    while !link.exists() && t0.elapsed() < std::time::Duration::from_secs(10) {
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    let (code, err) = status_of(&link, "robotiq_2f85", &["--slave", "1"]);
    assert_eq!(code, Some(1), "{err}");
    assert!(!err.contains("no reply"), "{err}");
    assert!(err.contains("Modbus exception 0x01"), "{err}");
    assert!(err.contains("--model"), "{err}");
    sim.kill().unwrap();
    let _ = sim.wait();
    let _ = std::fs::remove_file(&link);

    // Replies that all fail their CRC.
    let (mut sim, link) = simulated("crc", &["--inject", "bad-crc"]);
    let (code, err) = status_of(&link, "robotiq_2f85", &[]);
    assert_eq!(code, Some(1), "{err}");
    assert!(!err.contains("no reply"), "{err}");
    assert!(err.contains("CRC"), "{err}");
    assert!(err.contains("--baud"), "{err}");
    sim.kill().unwrap();
    let _ = sim.wait();
    let _ = std::fs::remove_file(&link);

    // A silent bus is still "no reply" (a slave id nobody answers to).
    let (mut sim, link) = simulated("silent", &[]);
    let (code, err) = status_of(&link, "robotiq_2f85", &["--slave", "7"]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("no reply from slave 7"), "{err}");
    sim.kill().unwrap();
    let _ = sim.wait();
    let _ = std::fs::remove_file(&link);
}
