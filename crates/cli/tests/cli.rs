//! The `unitac` command line contract: what users and scripts rely on.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::PathBuf;
use std::process::{Command, Output};

fn unitac(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_unitac"))
        .args(args)
        .env("RUST_LOG", "warn")
        .output()
        .unwrap()
}

fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("unitac-cli-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

#[test]
fn fabric_selection_on_mock_prints_a_json_summary() {
    let o = unitac(&[
        "run",
        "--scene",
        "fabric_selection",
        "--sensor",
        "mock",
        "--fast",
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(j["scene"], "fabric_selection");
    assert_eq!(j["ended"], "source_end");
    assert_eq!(j["frames"], 140);
    assert_eq!(j["stages"][0]["name"], "contact");
    assert_eq!(j["stages"][0]["dropped"], 0);
    let eps = j["episodes"].as_array().unwrap();
    assert_eq!(eps.len(), 2);
    assert_eq!(
        (eps[0]["label"].as_str(), eps[1]["label"].as_str()),
        (Some("fabric_a"), Some("fabric_b"))
    );
    assert_eq!(j["event_counts"]["contact_episode"], 2);
}

#[test]
fn text_summary_names_the_episodes() {
    let o = unitac(&["run", "--scene", "cup_deformation", "--fast"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let s = String::from_utf8(o.stdout).unwrap();
    assert!(s.starts_with("scene cup_deformation on mock"), "{s}");
    assert!(s.contains("episode 1 cup"), "{s}");
}

#[test]
fn events_are_byte_identical_across_runs() {
    let args = [
        "run",
        "--scene",
        "fabric_selection",
        "--fast",
        "--events",
        "--max-frames",
        "80",
    ];
    let (a, b) = (unitac(&args), unitac(&args));
    assert!(a.status.success());
    let lines = |o: &Output| -> Vec<String> {
        // The last line is the summary, whose wall-clock timings differ; events must not.
        let s = String::from_utf8_lossy(&o.stdout).into_owned();
        s.lines()
            .filter(|l| l.starts_with('{'))
            .map(str::to_string)
            .collect()
    };
    let (la, lb) = (lines(&a), lines(&b));
    let count = |t: &str| {
        la.iter()
            .filter(|l| serde_json::from_str::<serde_json::Value>(l).unwrap()["type"] == t)
            .count()
    };
    assert_eq!(
        count("contact_state"),
        70,
        "70 contact states after 10 learning frames"
    );
    assert_eq!(count("contact_episode"), 1);
    assert_eq!(count("tactile_properties"), 1);
    assert_eq!(count("tactile_latent"), 1);
    assert_eq!(la, lb);
}

fn assert_config_error(o: &Output, needle: &str) {
    assert_eq!(o.status.code(), Some(2), "stderr: {}", stderr(o));
    let e = stderr(o);
    assert_eq!(e.trim_end().lines().count(), 1, "one line: {e}");
    assert!(e.contains(needle), "expected '{needle}' in: {e}");
    assert!(o.stdout.is_empty());
}

#[test]
fn unknown_stage_is_exit_2_one_line() {
    let d = tmpdir("unknown-stage");
    let p = d.join("bad.yaml");
    std::fs::write(
        &p,
        "scene: bad\nsource: {kind: mock}\nstages:\n  - kind: contact\n  - kind: teleport\n",
    )
    .unwrap();
    let o = unitac(&["run", "--scene", p.to_str().unwrap()]);
    assert_config_error(&o, "stage 2 has unknown kind 'teleport'");
}

#[test]
fn missing_scene_file_is_exit_2_one_line() {
    let o = unitac(&["run", "--scene", "no_such_scene"]);
    assert_config_error(&o, "scene 'no_such_scene' not found");
    assert!(
        stderr(&o).contains("fabric_selection"),
        "lists what is available"
    );
    let o = unitac(&["run", "--scene", "/nonexistent/dir/x.yaml"]);
    assert_config_error(&o, "not found");
}

#[test]
fn missing_model_and_bad_values_are_exit_2() {
    let d = tmpdir("bad-values");
    let p = d.join("m.yaml");
    std::fs::write(
        &p,
        "scene: m\nsource: {kind: mock}\nmodels: {encoder: missing.onnx}\nstages:\n  - kind: contact\n    models: [encoder]\n",
    )
    .unwrap();
    assert_config_error(
        &unitac(&["run", "--scene", p.to_str().unwrap()]),
        "model 'encoder': file not found",
    );
    std::fs::write(
        &p,
        "scene: m\nsource: {kind: mock}\nstages:\n  - kind: contact\n    params: {stride: 0}\n",
    )
    .unwrap();
    assert_config_error(
        &unitac(&["run", "--scene", p.to_str().unwrap()]),
        "stride 0 is outside",
    );
    std::fs::write(
        &p,
        "scene: m\nsource: {kind: mock}\nstages:\n  - kind: contact\n    params: {strid: 2}\n",
    )
    .unwrap();
    assert_config_error(
        &unitac(&["run", "--scene", p.to_str().unwrap()]),
        "unknown field `strid`",
    );
    std::fs::write(
        &p,
        "scene: m\nsource: {kind: mock, scenario: juggling}\nstages: [{kind: contact}]\n",
    )
    .unwrap();
    assert_config_error(
        &unitac(&["run", "--scene", p.to_str().unwrap()]),
        "unknown mock scenario 'juggling'",
    );
}

#[test]
fn unavailable_sources_and_bad_flags_are_exit_2() {
    assert_config_error(
        &unitac(&[
            "run",
            "--scene",
            "fabric_selection",
            "--sensor",
            "v4l:D00045",
        ]),
        "v4l",
    );
    let o = unitac(&["run", "--scene", "fabric_selection", "--sensor", "usb"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("mock, v4l"));
}

#[test]
fn scenes_lists_the_shipped_scenes() {
    let o = unitac(&["scenes"]);
    let s = String::from_utf8(o.stdout).unwrap();
    assert!(
        s.lines().any(|l| l == "fabric_selection") && s.lines().any(|l| l == "cup_deformation"),
        "{s}"
    );
}

#[test]
fn ctrl_c_stops_a_real_time_run_cleanly() {
    let child = Command::new(env!("CARGO_BIN_EXE_unitac"))
        .args(["run", "--scene", "fabric_selection", "--json"])
        .stdout(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // Real-time pacing: 1.8 s in, the sensor is pressing fabric A.
    std::thread::sleep(std::time::Duration::from_millis(1800));
    let st = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(st.success());
    let o = child.wait_with_output().unwrap();
    assert!(o.status.success(), "SIGINT is a clean stop, exit 0");
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(j["ended"], "stopped");
    let frames = j["frames"].as_u64().unwrap();
    assert!((30..100).contains(&frames), "{frames}");
    assert_eq!(
        j["episodes"].as_array().unwrap().len(),
        1,
        "the open episode is flushed on stop"
    );
}

/// A flat grey RGB PNG of `w` x `h` at `level`.
fn flat_png(path: &std::path::Path, w: u32, h: u32, level: u8) {
    image::RgbImage::from_pixel(w, h, image::Rgb([level; 3]))
        .save(path)
        .unwrap();
}

/// Frames of one file name in different folders get overlays named by their folders too (a
/// calibration set laid out as `N/gelsight.png`); names that would still write one file are
/// refused before any work, naming both (not one overlay silently overwriting the other).
#[test]
fn overlays_of_frames_with_one_name_are_told_apart_by_their_folders() {
    let d = tmpdir("overlay-names");
    std::fs::create_dir_all(d.join("a")).unwrap();
    std::fs::create_dir_all(d.join("b")).unwrap();
    let (bg, a, b) = (d.join("bg.png"), d.join("a/f.png"), d.join("b/f.png"));
    flat_png(&bg, 320, 240, 128);
    flat_png(&a, 320, 240, 128);
    flat_png(&b, 320, 240, 130);
    let ov = d.join("overlay");
    let args = |frames: &[&PathBuf]| {
        let mut v = vec![
            "contact".to_string(),
            "--sensor".into(),
            "gelsight-mini".into(),
            "--background".into(),
            bg.display().to_string(),
            "--overlay".into(),
            ov.display().to_string(),
        ];
        v.extend(frames.iter().map(|f| f.display().to_string()));
        v
    };
    let run = |v: Vec<String>| {
        Command::new(env!("CARGO_BIN_EXE_unitac"))
            .args(v)
            .output()
            .unwrap()
    };
    // Two files of one name in two folders: each overlay named by its folder too.
    let o = run(args(&[&a, &b]));
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(ov.join("a_f.overlay.png").is_file() && ov.join("b_f.overlay.png").is_file());
    assert!(!ov.join("f.overlay.png").exists());
    // One file given twice writes one overlay, the same picture: not refused.
    let o = run(args(&[&a, &a]));
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(ov.join("f.overlay.png").is_file());
    // Two names that would write one file are refused before anything is written.
    std::fs::remove_dir_all(&ov).unwrap();
    let clash: Vec<PathBuf> = ["x_y/f.png", "z/f.png", "x/y_f.png", "w/y_f.png"]
        .iter()
        .map(|f| d.join(f))
        .collect();
    for f in &clash {
        std::fs::create_dir_all(f.parent().unwrap()).unwrap();
        flat_png(f, 320, 240, 128);
    }
    let o = run(args(&clash.iter().collect::<Vec<_>>()));
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{e}");
    let last = e.trim_end().lines().last().unwrap_or("");
    assert!(
        last.starts_with("unitac: --overlay") && last.contains("x_y_f.overlay.png"),
        "{e}"
    );
    assert!(!ov.join("x_y_f.overlay.png").exists(), "nothing written");
    std::fs::remove_dir_all(&d).ok();
}

/// A warning on a run that succeeds reads as a warning (`unitac: warning: ...`), not as the
/// error line `unitac: ...` that ends a run: the overlay's marker arrows on a gel without
/// markers found.
#[test]
fn warnings_read_as_warnings() {
    let d = tmpdir("warning-form");
    let (bg, f) = (d.join("bg.png"), d.join("f.png"));
    flat_png(&bg, 320, 240, 128);
    flat_png(&f, 320, 240, 128);
    let o = unitac(&[
        "contact",
        "--sensor",
        "gelsight-mini",
        "--background",
        bg.to_str().unwrap(),
        "--overlay",
        d.join("ov").to_str().unwrap(),
        f.to_str().unwrap(),
    ]);
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(0), "{e}");
    assert!(e.contains("no marker arrows"), "{e}");
    for line in e.lines() {
        assert!(line.starts_with("unitac: warning: "), "{line}");
    }
    std::fs::remove_dir_all(&d).ok();
}
