//! `unitac-lab bench policy` runs end to end with tiny counts and reports every row (a smoke test:
//! no timing is judged here).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::process::Command;

mod common;
use common::unitac_lab_within;

/// Every scene per task and mode (`<task>_<mode>` in the scene directories, the list
/// `unitac_pipeline::tasks` finds), so a scene added there and left out of the bench fails here.
fn scenes() -> Vec<String> {
    let v: Vec<String> = unitac_pipeline::tasks(None)
        .iter()
        .flat_map(|(t, modes)| modes.iter().map(|m| unitac_pipeline::mode_scene(t, *m)))
        .collect();
    assert!(v.len() >= 6, "{v:?}");
    v
}

#[test]
fn bench_policy_prints_a_row_per_scene_mode_and_pass_and_the_python_rows() {
    let o = Command::new(env!("CARGO_BIN_EXE_unitac-lab"))
        .args(["bench", "policy", "--repeat", "1", "--ticks", "3", "--json"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let rows = j["rows"].as_array().unwrap();
    let find = |transport: &str, scene: &str, what: &str| {
        rows.iter()
            .find(|r| r["transport"] == transport && r["scene"] == scene && r["what"] == what)
            .unwrap_or_else(|| panic!("no row {transport} {scene} {what}: {rows:?}"))
    };
    for scene in &scenes() {
        let (_, mode) = unitac_pipeline::split_mode(scene).unwrap();
        for what in [
            "controller",
            "controller + onnx act",
            "controller + onnx, paced",
        ] {
            let r = find("embedded", scene, what);
            assert_eq!(r["mode"], mode.as_str(), "{r}");
            assert!(r["tick"]["n"].as_u64().unwrap() > 0, "{r}");
            let phases = r["phases"].as_array().unwrap();
            assert!(!phases.is_empty(), "{r}");
        }
        // An episode runs until the controller is done or failed.
        let phases = find("embedded", scene, "controller")["phases"].to_string();
        assert!(
            phases.contains("\"done\"") || phases.contains("\"failed\""),
            "{scene}: {phases}"
        );
        // The paced pass: 3 ticks, 2 periods.
        let paced = find("embedded", scene, "controller + onnx, paced");
        assert_eq!(paced["tick"]["n"], 3, "{paced}");
        assert_eq!(paced["period"]["periods"], 2, "{paced}");
        assert!(paced["inferred"]["n"].as_u64().unwrap() >= 1, "{paced}");
    }
    let ours = find("embedded", "-", "onnx act");
    let theirs = find("python", "-", "onnx act");
    assert_eq!(ours["tick"]["n"], theirs["tick"]["n"]);
    assert!(ours["inferred"]["n"].as_u64().unwrap() > 0, "{ours}");
    assert_eq!(
        find("python", "-", "onnx act, sleep-paced")["period"]["periods"],
        2
    );
    assert_eq!(
        find("embedded", "-", "onnx act, paced")["period"]["periods"],
        2
    );
    assert!(j["python_over_rust"]["p50"].as_f64().is_some(), "{j}");

    // The text table: a line per row.
    let o = Command::new(env!("CARGO_BIN_EXE_unitac-lab"))
        .args(bench_policy_args("0"))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = String::from_utf8(o.stdout).unwrap();
    for scene in &scenes() {
        assert_eq!(
            text.lines()
                .filter(|l| l.starts_with("embedded") && l.contains(scene))
                .count(),
            2,
            "{scene}: without --ticks no paced row\n{text}"
        );
    }
    assert!(!text.contains("python "), "{text}");
}

/// `unitac-lab bench policy` of one repeat, `ticks` ticks and no Python rows.
fn bench_policy_args(ticks: &str) -> Vec<&str> {
    vec![
        "bench",
        "policy",
        "--repeat",
        "1",
        "--ticks",
        ticks,
        "--no-python",
    ]
}

#[test]
fn a_bad_bundle_and_a_tick_count_out_of_range_are_exit_2_before_any_work() {
    let dir = std::env::temp_dir().join(format!("unitac-bench-bad-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("manifest.json"), "{\"policy\": 1}").unwrap();
    let mut args = bench_policy_args("0");
    args.extend(["--policy", dir.to_str().unwrap()]);
    let o = unitac_lab_within(&args, &[], std::time::Duration::from_secs(120));
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.starts_with("unitac-lab: --policy "), "{err}");
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(o.stdout.is_empty());
    let _ = std::fs::remove_dir_all(&dir);

    let o = unitac_lab_within(
        &bench_policy_args("4294967295"),
        &[],
        std::time::Duration::from_secs(60),
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert_eq!(
        err.trim(),
        "unitac-lab: --ticks 4294967295 is outside 0..=100000",
        "{err}"
    );
}
