//! Demonstrations in LeRobot's dataset layout v3.0: `unitac demos` records both tasks with every
//! mode's observations, scripts/lerobot_dataset.py lays them out, and
//! tests/policy/check_lerobot_v3.py checks with pyarrow what LeRobot's v3 loader reads (the
//! project's Python: `$UNITAC_VENV` or `.venv`). The checker itself must refuse a dataset the
//! loader would refuse.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn python() -> PathBuf {
    std::env::var_os("UNITAC_VENV")
        .map(PathBuf::from)
        .unwrap_or_else(|| root().join(".venv"))
        .join("bin/python")
}

fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("unitac-lerobot-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

fn py(script: &str, args: &[&Path]) -> Output {
    Command::new(python())
        .arg(root().join(script))
        .args(args)
        .output()
        .expect("run the project's Python (scripts/setup.sh makes .venv)")
}

/// Record `trials` demonstrations of the two scenes' task and lay them out in `dir/dataset`.
fn dataset(dir: &Path, scenes: &str, trials: &str) -> PathBuf {
    let demos = dir.join("demos");
    let o = Command::new(env!("CARGO_BIN_EXE_unitac"))
        .args([
            "demos", "--scene", scenes, "--seeds", "2", "--trials", trials,
        ])
        .arg("--out")
        .arg(&demos)
        .env("RUST_LOG", "warn")
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", text(&o));
    let out = dir.join("dataset");
    let o = Command::new(python())
        .arg(root().join("scripts/lerobot_dataset.py"))
        .arg("--demos")
        .arg(demos.join("demos.json"))
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", text(&o));
    out
}

#[test]
fn both_tasks_demonstrations_pass_the_v3_loader_checks() {
    let dir = tmpdir("both");
    for (scenes, trials, task, max_opening_m) in [
        (
            "cup_deformation_vtla_real,cup_deformation_vtla_pred",
            "2",
            "squeeze the cup by 1 cm",
            0.11,
        ),
        (
            "fabric_selection_vtla_real,fabric_selection_vtla_pred",
            "1",
            "pick the smoother fabric",
            0.04,
        ),
    ] {
        let sub = dir.join(trials);
        let ds = dataset(&sub, scenes, trials);
        let o = py("tests/policy/check_lerobot_v3.py", &[&ds]);
        assert!(o.status.success(), "{}", text(&o));
        assert!(
            text(&o).starts_with(&format!("ok: v3.0, {trials} episodes")),
            "{}",
            text(&o)
        );
        let info: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(ds.join("meta/info.json")).unwrap())
                .unwrap();
        assert_eq!(info["fps"], 30);
        let f = &info["features"];
        // The gripper's real interface plus where the arm goes: the policy's action values.
        assert_eq!(
            f["action"]["names"],
            serde_json::json!([
                "gripper.position_m",
                "gripper.speed_m_s",
                "gripper.force_n",
                "arm.x_m",
                "arm.y_m",
                "arm.z_m",
                "arm.lift_m"
            ])
        );
        // Their bounds: the recording scene's safety layer (its opening, the 40 N force limit,
        // the workspace), in the same order.
        let b = &f["action"]["bounds"];
        assert_eq!(b["max"][0], max_opening_m, "{b}");
        assert_eq!(b["max"][2], 40.0, "{b}");
        assert_eq!(b["min"].as_array().unwrap().len(), 7, "{b}");
        // Pooled latents per object (96 + known), not the encoder's 64 x 48 token grid.
        let objects = if task.contains("cup") { 1 } else { 2 };
        for k in [
            "observation.tactile_latent_real",
            "observation.tactile_latent_pred",
        ] {
            assert_eq!(f[k]["shape"], serde_json::json!([97 * objects]), "{k}");
        }
        // No ground truth among the observations: nothing named after a true quantity.
        for (k, v) in f.as_object().unwrap() {
            let names = v["names"].to_string();
            for hidden in ["stiffness", "diameter_m\"", "smoother", "deformation"] {
                assert!(!names.contains(hidden), "{k}: {names}");
            }
        }
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn the_checker_refuses_what_the_loader_would_refuse() {
    let dir = tmpdir("broken");
    let ds = dataset(&dir, "cup_deformation_vtla_real", "1");
    let info_path = ds.join("meta/info.json");
    let info = std::fs::read_to_string(&info_path).unwrap();
    let broken = |edit: &dyn Fn(&str) -> String, want: &str| {
        std::fs::write(&info_path, edit(&info)).unwrap();
        let o = py("tests/policy/check_lerobot_v3.py", &[&ds]);
        assert_eq!(o.status.code(), Some(1), "{}", text(&o));
        assert!(text(&o).contains(want), "{want}: {}", text(&o));
    };
    // An older layout, a wrong total, a feature the data files do not have.
    broken(&|s| s.replace("\"v3.0\"", "\"v2.1\""), "codebase_version");
    broken(
        &|s| s.replace("\"total_frames\": ", "\"total_frames\": 1"),
        "total_frames",
    );
    broken(
        &|s| {
            s.replacen(
                "\"features\": {",
                "\"features\": {\"observation.extra\": {\"dtype\": \"float32\", \"shape\": [2], \"names\": [\"a\", \"b\"]},",
                1,
            )
        },
        "observation.extra",
    );
    std::fs::write(&info_path, &info).unwrap();
    let o = py("tests/policy/check_lerobot_v3.py", &[&ds]);
    assert!(o.status.success(), "{}", text(&o));
    std::fs::remove_dir_all(&dir).ok();
}
