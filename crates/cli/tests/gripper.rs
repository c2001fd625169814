//! `unitac gripper` against the simulated device (`--port sim`) and bad ports.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::process::{Command, Output};

fn unitac(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_unitac"))
        .arg("gripper")
        .args(args)
        .output()
        .unwrap()
}

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
    assert_eq!(o.status.code(), Some(1));
    assert!(
        err.contains("/dev/ttyUSB-unitac-none: no such serial device"),
        "{err}"
    );
    let o = unitac(&["--port", "/dev/null", "--model", "dh_ag95", "status"]);
    let (_, err) = text(&o);
    assert!(err.contains("/dev/null: not a serial port"), "{err}");
    let o = unitac(&["--port", "sim", "--model", "robotiq_3f", "status"]);
    let (_, err) = text(&o);
    assert_eq!(o.status.code(), Some(2));
    assert!(err.contains("known: robotiq_2f85"), "{err}");
}
