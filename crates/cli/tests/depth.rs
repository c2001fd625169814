//! `unitac calibrate depth` on mock ball presses, review and corrected circles, bad inputs.
//! (`unitac-lab eval depth` against the mock's exact depth: crates/lab/tests/depth.rs.)
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;

mod common;
use common::{calibrate_depth_args, press_files as presses};

fn dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("unitac-depth-cli-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn unitac(args: &[&str]) -> (Option<i32>, String, String) {
    let o = Command::new(env!("CARGO_BIN_EXE_unitac"))
        .args(args)
        .output()
        .unwrap();
    (
        o.status.code(),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

fn json(path: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

#[test]
fn calibrate_review_correct_and_refuse() {
    let d = dir("cal");
    let out = d.join("mock");
    let (code, _, err) = unitac(&[
        "calibrate",
        "mock-presses",
        "--count",
        "12",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, Some(0), "{err}");
    let files = presses(&out);
    assert_eq!(files.len(), 12);
    let bg = out.join("background.png");
    let cal = d.join("cal.json");
    let review = d.join("review");
    let mut args = calibrate_depth_args("0.002", &bg, &cal);
    args.extend([
        "--serial",
        "MOCK-0001",
        "--review",
        review.to_str().unwrap(),
    ]);
    args.extend(files.iter().map(String::as_str));
    let (code, _, err) = unitac(&args);
    assert_eq!(code, Some(0), "{err}");
    let c = json(&cal);
    assert_eq!(c["width"], 320);
    assert_eq!(c["height"], 240);
    assert_eq!(c["serial"], "MOCK-0001");
    assert_eq!(c["presses_used"], 12);
    assert!(c["fit_rms_slope"].as_f64().unwrap() < 0.02, "{c}");
    // Review: a PNG per press with the circle drawn, and the circles found, near the truth.
    let circles = json(&review.join("circles.json"));
    let truth = json(&out.join("truth.json"));
    assert_eq!(circles.as_array().unwrap().len(), 12);
    for (c, t) in circles
        .as_array()
        .unwrap()
        .iter()
        .zip(truth.as_array().unwrap())
    {
        assert_eq!(c["file"], t["file"]);
        assert_eq!(c["found"], true);
        let off = (c["x"].as_f64().unwrap() - t["x"].as_f64().unwrap())
            .hypot(c["y"].as_f64().unwrap() - t["y"].as_f64().unwrap());
        assert!(off < 1.5, "{c} vs {t}");
        let name = c["file"].as_str().unwrap().replace(".png", ".review.png");
        let img = image::open(review.join(name)).unwrap().to_rgb8();
        let (x, y) = (c["x"].as_f64().unwrap(), c["y"].as_f64().unwrap());
        let r = c["r"].as_f64().unwrap();
        assert_eq!(
            img.get_pixel((x + r).round() as u32, y.round() as u32).0,
            [255, 0, 0],
            "the circle is drawn"
        );
    }
    // Corrected circles: skip one press, give another by hand.
    let mut edited = circles.clone();
    edited[0]["skip"] = Value::Bool(true);
    edited[1]["x"] = truth[1]["x"].clone();
    edited[1]["y"] = truth[1]["y"].clone();
    let edited_path = d.join("circles.json");
    std::fs::write(&edited_path, edited.to_string()).unwrap();
    let cal2 = d.join("cal2.json");
    let mut args2: Vec<&str> = args.clone();
    let i = args2
        .iter()
        .position(|a| *a == cal.to_str().unwrap())
        .unwrap();
    args2[i] = cal2.to_str().unwrap();
    args2.extend(["--circles", edited_path.to_str().unwrap()]);
    let (code, _, err) = unitac(&args2);
    assert_eq!(code, Some(0), "{err}");
    assert_eq!(json(&cal2)["presses_used"], 11);
    // A press of another size: named on stderr, the rest still fitted, exit 1.
    let small = d.join("small.png");
    image::RgbImage::new(100, 80).save(&small).unwrap();
    let cal3 = d.join("cal3.json");
    let mut args3: Vec<&str> = args.clone();
    let i = args3
        .iter()
        .position(|a| *a == cal.to_str().unwrap())
        .unwrap();
    args3[i] = cal3.to_str().unwrap();
    args3.push(small.to_str().unwrap());
    let (code, _, err) = unitac(&args3);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("small.png") && err.contains("100x80"), "{err}");
    assert_eq!(json(&cal3)["presses_used"], 12);
    // `unitac contact` with the calibration: depth's area near the physical disc, overlays.
    let ov = d.join("overlay");
    let (code, out, err) = unitac(&[
        "contact",
        "--sensor",
        "gelsight-mini",
        "--background",
        bg.to_str().unwrap(),
        "--depth-calibration",
        cal.to_str().unwrap(),
        "--overlay",
        ov.to_str().unwrap(),
        "--json",
        &files[2],
        &files[3],
    ]);
    assert_eq!(code, Some(0), "{err}");
    for (line, t) in out.lines().zip(&truth.as_array().unwrap()[2..4]) {
        let v: Value = serde_json::from_str(line).unwrap();
        let disc = std::f64::consts::PI * t["contact_radius_px"].as_f64().unwrap().powi(2);
        let ratio = v["depth"]["area_px"].as_f64().unwrap() / disc;
        assert!((0.75..1.25).contains(&ratio), "{v} vs disc {disc}");
        let pen = v["depth"]["penetration_m"].as_f64().unwrap();
        assert!(
            (pen - t["approach_m"].as_f64().unwrap()).abs() < 0.05e-3,
            "{v} {t}"
        );
        let name = t["file"].as_str().unwrap().replace(".png", ".overlay.png");
        let img = image::open(ov.join(name)).unwrap().to_rgb8();
        assert_eq!((img.width(), img.height()), (640, 240));
        assert!(
            img.pixels().any(|p| p.0 == [255, 0, 0]),
            "the outline is drawn"
        );
    }
    let (code, _, err) = unitac(&[
        "contact",
        "--sensor",
        "digit",
        "--background",
        bg.to_str().unwrap(),
        "--depth-calibration",
        cal.to_str().unwrap(),
        &files[2],
    ]);
    assert_eq!(code, Some(2), "{err}");
    assert!(
        err.contains("gelsight-mini") && err.contains("digit"),
        "{err}"
    );
    // Not a ball; too few presses.
    let mut bad = args.clone();
    bad[5] = "-1";
    let (code, _, err) = unitac(&bad);
    assert_ne!(code, Some(0));
    assert!(err.contains("ball"), "{err}");
    let few = [
        &args[..14],
        &files[..2].iter().map(String::as_str).collect::<Vec<_>>()[..],
    ]
    .concat();
    let (code, _, err) = unitac(&few);
    assert_ne!(code, Some(0));
    assert!(err.contains("at least 3"), "{err}");
    std::fs::remove_dir_all(&d).ok();
}

/// `unitac` with `args`, killed after `limit`: (exit code, stderr); `None` code when it was
/// still running.
fn unitac_limited(args: &[&str], limit: std::time::Duration) -> (Option<i32>, String) {
    let t0 = std::time::Instant::now();
    let mut child = Command::new(env!("CARGO_BIN_EXE_unitac"))
        .args(args)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    loop {
        if let Some(s) = child.try_wait().unwrap() {
            let mut err = String::new();
            std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut err).unwrap();
            return (s.code(), err);
        }
        if t0.elapsed() > limit {
            child.kill().unwrap();
            child.wait().unwrap();
            return (None, "still running".into());
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
}

/// A calibration set laid out as `N/gelsight.png` (gs_sdk's): each press keeps its own review
/// file and its own entry in circles.json (by its folder), and an edited circles.json finds each
/// press again; before, every press wrote `gelsight.review.png` over the last one.
#[test]
fn presses_of_one_file_name_in_numbered_folders_are_reviewed_apart() {
    let d = dir("folders");
    let (bg, files) = mock(&d, "4");
    let mut nested = Vec::new();
    for (k, f) in files.iter().enumerate() {
        let to = d.join(format!("set/{k}/gelsight.png"));
        std::fs::create_dir_all(to.parent().unwrap()).unwrap();
        std::fs::copy(f, &to).unwrap();
        nested.push(to.to_str().unwrap().to_string());
    }
    let (cal, review) = (d.join("cal.json"), d.join("review"));
    let mut args = calibrate_depth_args("0.002", &bg, &cal);
    args.extend(["--review", review.to_str().unwrap()]);
    args.extend(nested.iter().map(String::as_str));
    let (code, _, err) = unitac(&args);
    assert_eq!(code, Some(0), "{err}");
    let circles = json(&review.join("circles.json"));
    let keys: Vec<&str> = circles
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c["file"].as_str().unwrap())
        .collect();
    assert_eq!(
        keys,
        [
            "0/gelsight.png",
            "1/gelsight.png",
            "2/gelsight.png",
            "3/gelsight.png"
        ]
    );
    for k in 0..4 {
        assert!(review.join(format!("{k}_gelsight.review.png")).is_file());
    }
    // Skipping the press of folder 2 by its key leaves the other three.
    let mut edited = circles.clone();
    edited[2]["skip"] = Value::Bool(true);
    let edited_path = d.join("circles.json");
    std::fs::write(&edited_path, edited.to_string()).unwrap();
    let cal2 = d.join("cal2.json");
    let mut args2 = calibrate_depth_args("0.002", &bg, &cal2);
    args2.extend(["--circles", edited_path.to_str().unwrap()]);
    args2.extend(nested.iter().map(String::as_str));
    let (code, _, err) = unitac(&args2);
    assert_eq!(code, Some(0), "{err}");
    assert_eq!(json(&cal)["presses_used"], 4);
    assert_eq!(json(&cal2)["presses_used"], 3);
    std::fs::remove_dir_all(&d).ok();
}

/// Mock presses (`count`) in `d/mock`: the background and the press files.
fn mock(d: &Path, count: &str) -> (PathBuf, Vec<String>) {
    let out = d.join("mock");
    let (code, _, err) = unitac(&[
        "calibrate",
        "mock-presses",
        "--count",
        count,
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, Some(0), "{err}");
    (out.join("background.png"), presses(&out))
}

/// Circles in --circles larger than the image or centred outside it are refused before any
/// work (exit 2, one line): with --review the drawing of a 1e300 px circle never ends, without
/// it a garbage calibration was written with exit 0.
#[test]
fn circles_beyond_the_image_are_refused_at_once() {
    let d = dir("circles");
    let (bg, files) = mock(&d, "4");
    let cal = d.join("cal.json");
    let circles = d.join("circles.json");
    let review = d.join("review");
    for (x, y, r, with_review) in [
        (160.0, 120.0, 1e300, true),
        (160.0, 120.0, 1e9, true),
        (160.0, 120.0, 121.0, false),
        (-50.0, 120.0, 20.0, false),
        (160.0, 1e6, 20.0, false),
    ] {
        let list: Vec<Value> = files
            .iter()
            .map(|f| {
                let name = Path::new(f).file_name().unwrap().to_string_lossy();
                serde_json::json!({"file": name, "x": x, "y": y, "r": r})
            })
            .collect();
        std::fs::write(&circles, Value::Array(list).to_string()).unwrap();
        std::fs::remove_file(&cal).ok();
        let mut args = calibrate_depth_args("0.002", &bg, &cal);
        args.extend(["--circles", circles.to_str().unwrap()]);
        if with_review {
            args.extend(["--review", review.to_str().unwrap()]);
        }
        args.extend(files.iter().map(String::as_str));
        let (code, err) = unitac_limited(&args, std::time::Duration::from_secs(30));
        assert_eq!(code, Some(2), "x {x} y {y} r {r}: {err}");
        assert_eq!(err.trim_end().lines().count(), 1, "{err}");
        assert!(
            err.starts_with("unitac: --circles") && err.contains("320x240"),
            "{err}"
        );
        assert!(!cal.exists(), "no calibration written");
    }
    std::fs::remove_dir_all(&d).ok();
}

/// Degenerate values are refused with the inclusive range the check applies, and the ends of
/// that range are taken.
#[test]
fn degenerate_calibration_values_are_refused() {
    let d = dir("degenerate");
    let (bg, files) = mock(&d, "3");
    let cal = d.join("cal.json");
    let depth = |radius: &str, extra: &[&str]| {
        let mut args = calibrate_depth_args(radius, &bg, &cal);
        args.extend(extra);
        args.extend(files.iter().map(String::as_str));
        unitac(&args)
    };
    let refused = |(code, _, err): (Option<i32>, String, String), needle: &str| {
        assert_eq!(code, Some(2), "{err}");
        assert_eq!(err.trim_end().lines().count(), 1, "{err}");
        assert!(err.starts_with("unitac: ") && err.contains(needle), "{err}");
    };
    refused(
        depth("0.002", &["--m-per-px", "1e-9"]),
        "--m-per-px <M_PER_PX>': 0.000000001 is outside 0.000001 to 0.001 (inclusive)",
    );
    refused(
        depth("0.002", &["--m-per-px", "1e9"]),
        "0.000001 to 0.001 (inclusive)",
    );
    for r in ["NaN", "0", "1e9", "0.0000999", "0.1005"] {
        refused(depth(r, &[]), "0.0001 to 0.1 (inclusive)");
    }
    // The range's ends are ball radii: the run goes past the check (the fit itself may still
    // fail on presses of another ball, exit 1).
    for r in ["0.0001", "0.1"] {
        let (code, _, err) = depth(r, &[]);
        assert_ne!(code, Some(2), "{r}: {err}");
        assert!(!err.contains("ball-radius"), "{r}: {err}");
    }
    let mock_out = d.join("mock2");
    let mock = |flag: &str, v: &str| {
        unitac(&[
            "calibrate",
            "mock-presses",
            flag,
            v,
            "--out",
            mock_out.to_str().unwrap(),
        ])
    };
    refused(mock("--noise-dn", "NaN"), "0 to 64 (inclusive)");
    refused(mock("--shading-dn", "inf"), "0 to 255 (inclusive)");
    for r in ["NaN", "0", "1e9"] {
        refused(mock("--ball-radius-m", r), "0.0005 to 0.01 (inclusive)");
    }
    refused(mock("--count", "0"), "1 to 500 (inclusive)");
    assert!(!mock_out.exists(), "nothing written");
    std::fs::remove_dir_all(&d).ok();
}
