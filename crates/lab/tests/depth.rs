//! `unitac-lab eval depth` against the mock's exact depth: the accuracy crates/contact/README.md
//! states ("Depth"), and its PNGs.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use serde_json::Value;
use std::path::PathBuf;

mod common;

fn dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("unitac-depth-lab-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// `unitac-lab args`: (exit code, stdout, stderr).
fn unitac_lab(args: &[&str]) -> (Option<i32>, String, String) {
    let o = common::unitac_lab(args);
    (
        o.status.code(),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

#[test]
fn eval_depth_meets_the_readme() {
    let d = dir("eval");
    let (code, out, err) = unitac_lab(&["eval", "depth", "--json", "--out", d.to_str().unwrap()]);
    assert_eq!(code, Some(0), "{err}");
    let v: Value = serde_json::from_str(out.trim()).unwrap();
    let rows = v["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 20);
    for r in rows {
        let a = r["approach_m"].as_f64().unwrap();
        assert!(r["rmse_m"].as_f64().unwrap() < 0.03e-3, "{r}");
        assert!(
            r["penetration_err_max_m"].as_f64().unwrap() < 0.05 * a + 0.01e-3,
            "{r}"
        );
        let area = r["area_over_hertz"].as_f64().unwrap();
        assert!((0.8..1.15).contains(&area), "{r}");
    }
    let pngs = v["pngs"].as_array().unwrap();
    assert_eq!(pngs.len(), 5);
    let img = image::open(pngs[0].as_str().unwrap()).unwrap();
    assert_eq!((img.width(), img.height()), (960, 240));
    std::fs::remove_dir_all(&d).ok();
}
