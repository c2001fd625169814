//! `unitac-lab demos` writes the demonstrations and refuses scenes without touch or of two tasks.
//! `--mode M`: whose demonstrations. The same command writes the same bytes twice;
//! vtla_real's fabric demonstrations decide from the comparison they hold, vla's from the camera,
//! and the mode is recorded in demos.json's config; a name that is no mode is a configuration
//! error (exit 2, one line). Without `--mode` the first scene's mode decides (the reference fit's
//! `--scene cup_deformation_vtla_real` records vtla_real's probe, as before).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::{Path, PathBuf};
use std::process::Output;

mod common;
use common::unitac_lab;

fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("unitac-demos-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// `unitac-lab demos` of one fabric trial (seed 1, trial 0) with `extra` arguments into `out`;
/// demos.json's bytes.
fn fabric(out: &Path, extra: &[&str]) -> Vec<u8> {
    let mut args = vec![
        "demos",
        "--scene",
        "fabric_selection_vtla_real,fabric_selection_vtla_pred",
        "--seeds",
        "1",
        "--trials",
        "1",
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend(extra);
    let o = unitac_lab(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    std::fs::read(out.join("demos.json")).unwrap()
}

#[test]
fn each_mode_records_its_own_decisions_the_same_bytes_twice() {
    let dir = tmpdir("modes");
    let real = fabric(&dir.join("a"), &["--mode", "vtla_real"]);
    assert_eq!(real, fabric(&dir.join("b"), &["--mode", "vtla_real"]));
    // The first scene's mode is the default.
    assert_eq!(real, fabric(&dir.join("c"), &[]));
    let vla = fabric(&dir.join("d"), &["--mode", "vla"]);
    for (bytes, mode) in [(&real, "vtla_real"), (&vla, "vla")] {
        let j: serde_json::Value = serde_json::from_slice(bytes).unwrap();
        assert_eq!(j["config"]["mode"], mode);
        let d = &j["demos"][0];
        let chosen = d["chosen"].as_str().unwrap();
        assert!(["fabric_a", "fabric_b"].contains(&chosen), "{chosen}");
        let decided = d["decided_s"].as_f64().unwrap();
        let at = d["ticks"]
            .as_array()
            .unwrap()
            .iter()
            .find(|t| t["t_s"].as_f64().unwrap() >= decided)
            .unwrap();
        let known: f64 = (0..3).map(|i| at["comparison"][i].as_f64().unwrap()).sum();
        if mode == "vtla_real" {
            // It holds the comparison it decided from.
            assert_eq!(known, 1.0, "{}", at["comparison"]);
        }
    }
    let o = unitac_lab(&[
        "demos",
        "--scene",
        "fabric_selection_vtla_real",
        "--mode",
        "vtla",
        "--out",
        dir.join("e").to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert_eq!(stderr(&o).trim_end().lines().count(), 1, "{}", stderr(&o));
    assert!(stderr(&o).contains("unknown mode 'vtla'"), "{}", stderr(&o));
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn demos_writes_the_demonstrations_and_refuses_scenes_without_touch() {
    let dir = tmpdir("demos");
    let out = dir.join("d");
    let o = unitac_lab(&[
        "demos",
        "--scene",
        "cup_deformation_vtla_real",
        "--seeds",
        "3",
        "--trials",
        "2",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let s = String::from_utf8_lossy(&o.stdout);
    assert!(
        s.starts_with("2 demonstrations of cup_deformation_vtla_real (Train cups)"),
        "{s}"
    );
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("demos.json")).unwrap()).unwrap();
    let demos = j["demos"].as_array().unwrap();
    assert_eq!(demos.len(), 2);
    assert_eq!(demos[0]["latents"][0]["source"], "real");
    assert_eq!(demos[0]["latents"][0]["touch"], 1);
    // No tactile stage, or scenes of two tasks: a configuration error, one line, exit 2.
    for scene in [
        "cup_deformation_vla",
        "cup_deformation_vtla_real,fabric_selection_vtla_real",
    ] {
        let o = unitac_lab(&["demos", "--scene", scene, "--out", out.to_str().unwrap()]);
        assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
        assert_eq!(stderr(&o).trim_end().lines().count(), 1, "{}", stderr(&o));
    }
    std::fs::remove_dir_all(&dir).ok();
}
