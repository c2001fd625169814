//! Helpers shared by the command-line tests: running `unitac gripper`, the arguments of
//! `calibrate depth`, the press files of `calibrate mock-presses`; and [`shared`],
//! what the tests of `unitac-lab` do as well. Each test file uses some of them.
#![allow(dead_code)]

pub mod shared;

use std::path::Path;
use std::process::{Command, Output};

/// `unitac gripper args`.
pub fn unitac_gripper(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_unitac"))
        .arg("gripper")
        .args(args)
        .output()
        .unwrap()
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
