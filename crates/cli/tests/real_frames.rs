//! `unitac contact` on the repository's real frames (tests/real/*/: real sensors' ball presses,
//! each set with its source, licence and the contact circles annotated here): every press, one
//! by one, reads within x1.5 of its annotated disc with its centroid within 0.6 radii, and the
//! background alone is no contact. The same command a user runs on their own frames.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use serde_json::Value;
use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use std::process::Command;

/// Largest area ratio (either way) of a press to its annotated disc.
const AREA_FACTOR: f64 = 1.5;
/// Farthest centroid from the annotated centre, in annotated radii.
const CENTROID_RADII: f64 = 0.6;

fn sets() -> Vec<PathBuf> {
    let real = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/real");
    let mut sets: Vec<PathBuf> = std::fs::read_dir(&real)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.join("annotations.json").is_file())
        .collect();
    sets.sort();
    sets
}

fn json(path: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// `unitac ARGS...` run in `set`, which must exit 0: its stdout.
fn unitac(set: &Path, args: &[&OsStr]) -> String {
    let o = Command::new(env!("CARGO_BIN_EXE_unitac"))
        .current_dir(set)
        .args(args)
        .output()
        .unwrap();
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8(o.stdout).unwrap()
}

fn os<'a>(args: &[&'a str]) -> Vec<&'a OsStr> {
    args.iter().map(|a| OsStr::new(*a)).collect()
}

/// `unitac contact --json` on `frames` of `set` (with `extra` flags): one object per frame.
fn contact(set: &Path, sensor: &str, extra: &[&OsStr], frames: &[String]) -> Vec<Value> {
    let mut args = os(&["contact", "--json", "--sensor", sensor]);
    args.extend(os(&["--background", "background.png"]));
    args.extend_from_slice(extra);
    args.extend(frames.iter().map(OsStr::new));
    unitac(set, &args)
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

/// The annotated presses of `set`.
fn presses(set: &Path) -> Vec<Value> {
    json(&set.join("annotations.json"))["presses"]
        .as_array()
        .unwrap()
        .clone()
}

/// The files of `presses`.
fn files(presses: &[Value]) -> Vec<String> {
    presses
        .iter()
        .map(|p| p["file"].as_str().unwrap().to_string())
        .collect()
}

/// The presses of the source's `split` part `k` (train, test).
fn split(source: &Value, k: &str) -> Vec<String> {
    source["split"][k]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap().to_string())
        .collect()
}

/// Each press's `reading` (a contact line, or its `depth`) against its annotated disc: printed
/// one line each (`what` names the area) and a summary headed `heading`; the presses off by more
/// than x1.5 in area or 0.6 radii in centroid, or read as no contact, are pushed to `bad`.
fn judge<'a>(
    name: &str,
    what: &str,
    heading: &str,
    presses: &[Value],
    readings: impl Iterator<Item = &'a Value>,
    bad: &mut Vec<String>,
) {
    let mut ratios = Vec::new();
    for (p, l) in presses.iter().zip(readings) {
        let g = |v: &Value, k: &str| v[k].as_f64().unwrap();
        let (x, y, r) = (g(p, "x"), g(p, "y"), g(p, "r"));
        let ratio = g(l, "area_px") / (std::f64::consts::PI * r * r);
        let c = l["centroid"].as_array().unwrap();
        let off = (c[0].as_f64().unwrap() - x).hypot(c[1].as_f64().unwrap() - y) / r;
        let line = format!(
            "{name}/{}: {what}area x{ratio:.2} of the disc, centroid {off:.2} r off",
            p["file"].as_str().unwrap()
        );
        println!("{line}");
        ratios.push(ratio);
        let in_area = (1.0 / AREA_FACTOR..=AREA_FACTOR).contains(&ratio);
        if l["contact"] != true || !in_area || off > CENTROID_RADII {
            bad.push(line);
        }
    }
    ratios.sort_by(f64::total_cmp);
    println!(
        "{name}: {heading}, area / disc median {:.2} (range {:.2}-{:.2})",
        ratios[ratios.len() / 2],
        ratios[0],
        ratios[ratios.len() - 1]
    );
}

/// `unitac calibrate depth --sensor S --background background.png --ball-radius-m R --out OUT`
/// with `extra` flags on `presses` of `set`: its stdout.
fn calibrate(
    set: &Path,
    sensor: &str,
    ball_m: f64,
    out: &Path,
    extra: &[&OsStr],
    presses: &[String],
) -> String {
    let ball = ball_m.to_string();
    let mut args = os(&["calibrate", "depth", "--sensor", sensor]);
    args.extend(os(&[
        "--background",
        "background.png",
        "--ball-radius-m",
        &ball,
    ]));
    args.extend([OsStr::new("--out"), out.as_os_str()]);
    args.extend_from_slice(extra);
    args.extend(presses.iter().map(OsStr::new));
    unitac(set, &args)
}

#[test]
fn every_real_press_reads_near_its_annotated_disc() {
    let sets = sets();
    assert!(!sets.is_empty(), "no real-frame set under tests/real");
    let mut failed = Vec::new();
    for set in &sets {
        let source = json(&set.join("source.json"));
        let sensor = source["sensor"].as_str().unwrap();
        let presses = presses(set);
        assert!(!presses.is_empty());
        let lines = contact(set, sensor, &[], &files(&presses));
        assert_eq!(lines.len(), presses.len());
        let name = set.file_name().unwrap().to_string_lossy();
        let heading = format!("{} presses", presses.len());
        judge(&name, "", &heading, &presses, lines.iter(), &mut failed);
        // The gel at rest is no contact.
        let bg = contact(set, sensor, &[], &["background.png".to_string()]);
        if bg[0]["contact"] != false {
            failed.push(format!("{name}/background.png: {}", bg[0]));
        }
    }
    assert!(failed.is_empty(), "{failed:#?}");
}

/// `unitac calibrate depth` on each set's training presses (the source's split) finds every
/// press that does not touch the frame's border, near its annotated circle; the calibration's
/// depth contour then reads the set's test presses within x1.5 of their discs.
#[test]
fn a_calibration_from_real_presses_finds_their_circles_and_reads_the_others() {
    for set in sets() {
        let source = json(&set.join("source.json"));
        let sensor = source["sensor"].as_str().unwrap();
        let name = set.file_name().unwrap().to_string_lossy().into_owned();
        let ball_m = source["indenter"]["diameter_mm"].as_f64().unwrap() * 0.5e-3;
        let (train, test) = (split(&source, "train"), split(&source, "test"));
        let tmp = std::env::temp_dir().join(format!("unitac-real-{}-{name}", std::process::id()));
        std::fs::create_dir_all(&tmp).unwrap();
        let (cal, review) = (tmp.join("cal.json"), tmp.join("review"));
        let review_flag = [OsStr::new("--review"), review.as_os_str()];
        calibrate(&set, sensor, ball_m, &cal, &review_flag, &train);
        let ann = presses(&set);
        let annotated = |f: &str| ann.iter().find(|p| p["file"] == f).unwrap().clone();
        let size = source["size"].as_array().unwrap();
        let (w, h) = (size[0].as_f64().unwrap(), size[1].as_f64().unwrap());
        let mut bad = Vec::new();
        for c in json(&review.join("circles.json")).as_array().unwrap() {
            let f = c["file"].as_str().unwrap();
            let a = annotated(f);
            let g = |v: &Value, k: &str| v[k].as_f64().unwrap();
            let (x, y, r) = (g(&a, "x"), g(&a, "y"), g(&a, "r"));
            let inside = x - r >= 0.0 && y - r >= 0.0 && x + r <= w && y + r <= h;
            if !inside {
                continue;
            }
            let off = (g(c, "x") - x).hypot(g(c, "y") - y);
            let line = format!(
                "{name}/{f}: found {} r {:.1} vs {r:.1}, centre {off:.1} px off",
                c["found"],
                g(c, "r")
            );
            println!("{line}");
            if c["found"] != true || (g(c, "r") - r).abs() > 2.0 || off > 0.15 * r {
                bad.push(line);
            }
        }
        let depth = [OsStr::new("--depth-calibration"), cal.as_os_str()];
        for v in contact(&set, sensor, &depth, &test) {
            let f = v["file"].as_str().unwrap();
            let r = annotated(f)["r"].as_f64().unwrap();
            // With a calibration the region is the depth's (`--region auto`).
            assert_eq!(v["region"], "depth", "{v}");
            let ratio = v["depth"]["area_px"].as_f64().unwrap() / (std::f64::consts::PI * r * r);
            let line = format!("{name}/{f}: depth's area x{ratio:.2} of the disc");
            println!("{line}");
            if !(1.0 / AREA_FACTOR..=AREA_FACTOR).contains(&ratio) {
                bad.push(line);
            }
        }
        std::fs::remove_dir_all(&tmp).ok();
        assert!(bad.is_empty(), "{bad:#?}");
    }
}

/// Before a unit is calibrated: the sensor kind's default photometric model (its profile's
/// `photometric`), which `unitac contact` uses when no calibration is named, reads every press of
/// every set of a kind that has one from depth within x1.5 of its annotated disc, with its
/// centroid within 0.6 radii, and the background alone as no contact; so does the contact region
/// with `--region depth`, which is that depth's. The model itself is what
/// `unitac calibrate depth --linear` fits on the training presses of the set its source names.
#[test]
fn the_kinds_default_photometric_model_reads_every_press_from_depth() {
    let mut checked = 0;
    for set in sets() {
        let source = json(&set.join("source.json"));
        let sensor = source["sensor"].as_str().unwrap();
        let kind: unitac_core::SensorKind = sensor.parse().unwrap();
        let Some(model) = kind.profile().photometric else {
            continue;
        };
        checked += 1;
        let name = set.file_name().unwrap().to_string_lossy().into_owned();
        let presses = presses(&set);
        let mut files = files(&presses);
        files.push("background.png".into());
        let lines = contact(&set, sensor, &[], &files);
        for l in &lines {
            assert_eq!(l["depth"]["model"], "kind default", "{l}");
            assert_eq!(l["region"], "residual", "{l}");
        }
        let mut bad = Vec::new();
        let depths = lines.iter().map(|l| &l["depth"]);
        let heading = "depth from the kind's model";
        judge(&name, "depth's ", heading, &presses, depths, &mut bad);
        let bg = &lines[lines.len() - 1]["depth"];
        if bg["contact"] != false {
            bad.push(format!("{name}/background.png: depth {bg}"));
        }
        // `--region depth`: the contact region is that depth's, where the residual finds the
        // press.
        let lines = contact(&set, sensor, &os(&["--region", "depth"]), &files);
        for l in &lines {
            assert_eq!(l["region"], "depth", "{l}");
            if l["contact"] == true {
                assert_eq!(l["area_px"].as_f64(), l["depth"]["area_px"].as_f64(), "{l}");
            }
        }
        let heading = "the region from the kind's model";
        judge(&name, "", heading, &presses, lines.iter(), &mut bad);
        let bg = &lines[lines.len() - 1];
        if bg["contact"] != false {
            bad.push(format!("{name}/background.png: {bg}"));
        }
        if model.source.contains(&format!("tests/real/{name}")) {
            let tmp =
                std::env::temp_dir().join(format!("unitac-kind-{}-{name}", std::process::id()));
            std::fs::create_dir_all(&tmp).unwrap();
            let linear = [OsStr::new("--linear")];
            let train = split(&source, "train");
            let out = calibrate(
                &set,
                sensor,
                model.ball_radius_m,
                &tmp.join("cal.json"),
                &linear,
                &train,
            );
            std::fs::remove_dir_all(&tmp).ok();
            let fitted: Vec<f32> = out
                .trim()
                .trim_start_matches("photometric: {slope_per_dn: ")
                .trim_end_matches('}')
                .split(|c: char| "[], ".contains(c))
                .filter(|s| !s.is_empty())
                .map(|s| s.parse().unwrap())
                .collect();
            let shipped: Vec<f32> = model.slope_per_dn.iter().flatten().copied().collect();
            assert_eq!(fitted.len(), 6, "{out}");
            for (f, s) in fitted.iter().zip(&shipped) {
                // Printed to four significant digits.
                assert!(
                    (f - s).abs() <= 2e-6,
                    "fitted {fitted:?}, profile {shipped:?}"
                );
            }
        }
        assert!(bad.is_empty(), "{bad:#?}");
    }
    assert!(
        checked > 0,
        "no real-frame set of a kind with a photometric model"
    );
}

/// A gel the stack has no model of: every set read as `generic` with `--region depth`, whose
/// depth comes from a linear model fitted on each press itself (up to scale: no penetration),
/// reads every press within x1.5 of its annotated disc, centroid within 0.6 radii, and the
/// background as no contact (with no depth: no press to fit on).
#[test]
fn a_self_calibrated_depth_reads_every_press_of_a_gel_without_a_model() {
    let mut bad = Vec::new();
    for set in sets() {
        let name = set.file_name().unwrap().to_string_lossy().into_owned();
        let presses = presses(&set);
        let mut files = files(&presses);
        files.push("background.png".into());
        let lines = contact(&set, "generic", &os(&["--region", "depth"]), &files);
        // (The gel at rest has no press to fit a model on: no depth.)
        for l in &lines[..lines.len() - 1] {
            assert_eq!(l["region"], "depth", "{l}");
            assert_eq!(l["depth"]["model"], "self-calibrated", "{l}");
            assert!(l["depth"]["penetration_m"].is_null(), "{l}");
        }
        let heading = "generic, self-calibrated depth";
        judge(&name, "", heading, &presses, lines.iter(), &mut bad);
        let bg = &lines[lines.len() - 1];
        if bg["contact"] != false {
            bad.push(format!("{name}/background.png: {bg}"));
        }
    }
    assert!(bad.is_empty(), "{bad:#?}");
}
