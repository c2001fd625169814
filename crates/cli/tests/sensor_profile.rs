//! A sensor kind is a file: a profile added in `$UNITAC_SENSORS` (a copy of DIGIT's under a new
//! name, lit differently) is a kind a scene names, with no code edit: the mock sensor renders it
//! with its lighting and size, the contact stage finds the scene's touches on it. Without the
//! directory the kind is a one-line error naming the known kinds, and a broken file is an error
//! naming the file.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn run(scene: &Path, sensors: Option<&Path>) -> Output {
    let mut c = Command::new(env!("CARGO_BIN_EXE_unitac"));
    c.args(["run", "--fast", "--json", "--scene"])
        .arg(scene)
        .env("RUST_LOG", "warn");
    match sensors {
        Some(d) => c.env("UNITAC_SENSORS", d),
        None => c.env_remove("UNITAC_SENSORS"),
    };
    c.output().unwrap()
}

/// A contact-only scene of the fabric touches on the sensor kind `kind`.
fn scene(dir: &Path, kind: &str) -> PathBuf {
    let path = dir.join(format!("touch_{}.yaml", kind.replace('-', "_")));
    std::fs::write(
        &path,
        format!(
            "scene: touch_{}\nsource: {{kind: mock, sensor: {kind}, scenario: fabric_selection, seed: 7}}\n\
             stages:\n  - kind: contact\n    params: {{episode_labels: [fabric_a, fabric_b]}}\n",
            kind.replace('-', "_")
        ),
    )
    .unwrap();
    path
}

fn episodes(o: &Output) -> (Vec<String>, u64) {
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let labels = j["episodes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| e["label"].as_str().unwrap().to_string())
        .collect();
    (labels, j["frames"].as_u64().unwrap())
}

#[test]
fn a_sensor_profile_file_is_a_sensor_kind_with_no_code_edit() {
    let tmp = std::env::temp_dir().join(format!("unitac-cli-sensors-{}", std::process::id()));
    let sensors = tmp.join("sensors");
    std::fs::create_dir_all(&sensors).unwrap();
    let digit = std::fs::read_to_string(root().join("sensors/digit.yaml")).unwrap();
    let profile = digit
        .replace("name: digit\n", "name: test-cam\n")
        .replace("  - [70.0, 110.0, u]\n", "  - [60.0, 100.0, 1-u]\n")
        .replace("urdf: digit\n", "");
    assert_ne!(profile, digit);
    std::fs::write(sensors.join("test-cam.yaml"), profile).unwrap();

    let (theirs, ours) = (scene(&tmp, "digit"), scene(&tmp, "test-cam"));
    let want = ["fabric_a", "fabric_b"].map(String::from).to_vec();
    let (d_labels, d_frames) = episodes(&run(&theirs, None));
    assert_eq!(d_labels, want);
    let (labels, frames) = episodes(&run(&ours, Some(&sensors)));
    assert_eq!(labels, want, "the new kind's touches");
    assert_eq!(frames, d_frames, "DIGIT's rate and scenario");

    // Without the directory the kind is unknown: one line naming the known ones.
    let o = run(&ours, None);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains(
            "unknown sensor kind 'test-cam' (known: digit, gelsight-2017, gelsight-mini, generic)"
        ),
        "{err}"
    );
    assert_eq!(err.trim().lines().count(), 1, "{err}");

    // A broken profile names its file and every problem.
    let broken = tmp.join("broken");
    std::fs::create_dir_all(&broken).unwrap();
    std::fs::write(
        broken.join("test-cam.yaml"),
        std::fs::read_to_string(sensors.join("test-cam.yaml"))
            .unwrap()
            .replace("fps: 60.0", "fps: -1"),
    )
    .unwrap();
    let o = run(&ours, Some(&broken));
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("test-cam.yaml") && err.contains("fps = -1"),
        "{err}"
    );
    std::fs::remove_dir_all(&tmp).unwrap();
}

/// Every shipped kind, whatever its size and scale, finds the fabric scene's two touches on its
/// mock sensor, and reads their peak contact at the same physical area (the press is the same
/// world's): within 10 % of GelSight Mini's.
#[test]
fn every_shipped_kind_reads_the_same_touches_at_the_same_physical_area() {
    let tmp = std::env::temp_dir().join(format!("unitac-cli-kinds-{}", std::process::id()));
    std::fs::create_dir_all(&tmp).unwrap();
    let areas = |kind: &str| -> Vec<f64> {
        let o = run(&scene(&tmp, kind), None);
        let (labels, _) = episodes(&o);
        assert_eq!(labels, ["fabric_a", "fabric_b"], "{kind}");
        let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        j["episodes"]
            .as_array()
            .unwrap()
            .iter()
            .map(|e| e["peak_area_m2"].as_f64().unwrap())
            .collect()
    };
    let mini = areas("gelsight-mini");
    for kind in unitac_core::SensorKind::SHIPPED {
        let a = areas(kind.as_str());
        for (x, m) in a.iter().zip(&mini) {
            assert!(
                (x / m - 1.0).abs() < 0.1,
                "{kind}: {a:?} against GelSight Mini's {mini:?}"
            );
        }
    }
    std::fs::remove_dir_all(&tmp).unwrap();
}
