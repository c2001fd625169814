//! `unitac gripper`'s flags under hostile values, its help, and its log lines on a pipe.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

fn unitac(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_unitac"))
        .args(args)
        .output()
        .unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Exit 2 with clap's usage error naming `flag`, before any device is opened.
fn usage_error<S: AsRef<str> + std::fmt::Debug>(args: &[S], flag: &str) {
    let v: Vec<&str> = args.iter().map(|s| s.as_ref()).collect();
    let o = unitac(&v);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
    assert!(err.contains(flag), "{args:?}: {err}");
    assert!(o.stdout.is_empty(), "{args:?}");
}

#[test]
fn broadcast_slave_zero_baud_and_bad_seconds_are_usage_errors() {
    let base = ["gripper", "--port", "sim", "--model", "robotiq_2f85"];
    let with = |extra: &[&str]| {
        let mut v: Vec<String> = base.iter().map(|s| s.to_string()).collect();
        v.extend(extra.iter().map(|s| s.to_string()));
        v.push("status".into());
        v
    };
    usage_error(&with(&["--slave", "0"]), "--slave");
    usage_error(&with(&["--slave", "248"]), "--slave");
    usage_error(&with(&["--baud", "0"]), "--baud");
    usage_error(&with(&["--baud", "99999999"]), "--baud");
    for bad in ["0", "-1", "nan", "inf", "3601", "x"] {
        usage_error(&with(&[&format!("--seconds={bad}")]), "--seconds");
    }
    usage_error(&with(&["--force", "nan"]), "--force");
    usage_error(&with(&["--speed=-1"]), "--speed");
    // simulate and bench take the same checks.
    let o = unitac(&[
        "gripper",
        "--port",
        "sim",
        "--model",
        "dh_ag95",
        "--slave",
        "0",
        "--seconds",
        "1",
        "simulate",
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    usage_error(
        &[
            "gripper",
            "--port",
            "sim",
            "--model",
            "dh_ag95",
            "--seconds",
            "0",
            "bench",
        ],
        "--seconds",
    );
    // The edges are accepted.
    let edges = with(&["--slave", "9", "--baud", "115200", "--seconds", "3600"]);
    let o = unitac(&edges.iter().map(|s| s.as_str()).collect::<Vec<_>>());
    assert!(o.status.success(), "{}", stderr(&o));
}

#[test]
fn the_gripper_summary_names_every_action() {
    let o = unitac(&["--help"]);
    let out = String::from_utf8_lossy(&o.stdout);
    let line = out
        .lines()
        .find(|l| l.trim_start().starts_with("gripper"))
        .unwrap_or_else(|| panic!("{out}"));
    for action in ["activate", "open", "close", "status", "bench", "simulate"] {
        assert!(line.contains(action), "{line}");
    }
    let o = unitac(&["gripper", "--help"]);
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(out.contains("simulate"), "{out}");
    assert!(out.contains("1 to 247"), "{out}");
}

#[test]
fn log_lines_on_a_pipe_carry_no_colour_codes() {
    let link = std::env::temp_dir().join(format!("unitac-gripper-args-{}", std::process::id()));
    let _ = std::fs::remove_file(&link);
    let port = link.to_str().unwrap();
    let mut sim = Command::new(env!("CARGO_BIN_EXE_unitac"))
        .args(["gripper", "--port", port, "--model", "robotiq_2f85"])
        .args(["--seconds", "30", "simulate"])
        .stdout(Stdio::null())
        .spawn()
        .unwrap();
    let t0 = Instant::now();
    while !link.exists() {
        assert!(t0.elapsed() < Duration::from_secs(10), "no simulator link");
        std::thread::sleep(Duration::from_millis(20));
    }
    let g = |extra: &[&str]| {
        let mut v = vec!["gripper", "--port", port, "--model", "robotiq_2f85"];
        v.extend_from_slice(extra);
        unitac(&v)
    };
    let o = g(&["activate"]);
    assert!(o.status.success(), "{}", stderr(&o));
    // 1 N is below the 2F-85's 20 N: the driver logs the clamp (a warning) on stderr, a pipe.
    let o = g(&["--force", "1", "close"]);
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("clamped"), "{err}");
    assert!(!err.contains('\u{1b}'), "{err:?}");
    sim.kill().unwrap();
    let _ = sim.wait();
    let _ = std::fs::remove_file(&link);
}
