//! `unitac-lab report`: the simulator's numerics report writes its tables and plots.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::PathBuf;
use std::process::Output;

mod common;
use common::unitac_lab;

fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("unitac-lab-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

#[test]
fn report_sim_writes_tables_and_plots() {
    let dir = tmpdir("report-sim");
    let out = dir.join("figs");
    let o = unitac_lab(&["report", "sim", "--json", "--out", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    // Three cups x (three methods x nine steps + three sub-stepped runs).
    assert_eq!(j["accuracy"].as_array().unwrap().len(), 3 * (3 * 9 + 3));
    assert_eq!(j["references"].as_array().unwrap().len(), 3);
    assert_eq!(j["map_disagreements"], 0);
    for f in j["plots"].as_array().unwrap() {
        let p = PathBuf::from(f.as_str().unwrap());
        assert!(std::fs::metadata(&p).unwrap().len() > 10_000, "{p:?}");
    }
    // An unusable --out is a configuration error (exit 2).
    let file = dir.join("a-file");
    std::fs::write(&file, b"x").unwrap();
    let o = unitac_lab(&["report", "sim", "--out", file.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    std::fs::remove_dir_all(&dir).ok();
}
