//! Helpers shared by the command-line tests: running `unitac` (with a time limit, or as
//! `unitac gripper`), the arguments of `calibrate depth`, the press files of `calibrate
//! mock-presses`, and the command lists of the help pages. Each test file uses some of them.
#![allow(dead_code)]

use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

/// `unitac args`, logging at warn.
pub fn unitac(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_unitac"))
        .args(args)
        .env("RUST_LOG", "warn")
        .output()
        .unwrap()
}

/// `unitac gripper args`.
pub fn unitac_gripper(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_unitac"))
        .arg("gripper")
        .args(args)
        .output()
        .unwrap()
}

/// `unitac args` with the environment variables `env` set, killed after `limit` (a hang is a
/// failure, not a stuck test).
pub fn unitac_within(args: &[&str], env: &[(&str, &str)], limit: Duration) -> Output {
    let mut child = Command::new(env!("CARGO_BIN_EXE_unitac"))
        .args(args)
        .envs(env.iter().copied())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed() > limit {
            child.kill().unwrap();
            let o = child.wait_with_output().unwrap();
            panic!(
                "unitac {args:?} still ran after {limit:?}: {}",
                String::from_utf8_lossy(&o.stderr)
            );
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    child.wait_with_output().unwrap()
}

/// `unitac calibrate depth` for a GelSight Mini pressed with a ball of `radius_mm`, from
/// `background` to `out`: the arguments before the options a test adds and the press files
/// (the radius is the sixth).
pub fn calibrate_depth_args<'a>(
    radius_m: &'a str,
    background: &'a Path,
    out: &'a Path,
) -> Vec<&'a str> {
    vec![
        "calibrate",
        "depth",
        "--sensor",
        "gelsight-mini",
        "--ball-radius-m",
        radius_m,
        "--background",
        background.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]
}

/// The press images `unitac calibrate mock-presses` wrote in `dir` (`press_*`), sorted.
pub fn press_files(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| {
            p.file_name()
                .unwrap()
                .to_string_lossy()
                .starts_with("press_")
        })
        .map(|p| p.display().to_string())
        .collect();
    v.sort();
    v
}

/// The lines of a help page's section (`Commands`, `Arguments`, ...), up to the blank line that
/// ends it; none where the page has no such section.
pub fn help_section<'a>(help: &'a str, title: &str) -> impl Iterator<Item = &'a str> {
    help.split_once(&format!("{title}:\n"))
        .map(|(_, rest)| rest.lines().take_while(|l| !l.trim().is_empty()))
        .into_iter()
        .flatten()
}

/// The subcommands a help page lists under `Commands:` (without `help`).
pub fn help_commands(help: &str) -> Vec<String> {
    help_section(help, "Commands")
        .filter_map(|l| l.split_whitespace().next())
        .filter(|c| *c != "help")
        .map(String::from)
        .collect()
}
