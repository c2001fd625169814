//! `unitac-lab trials`: the table has every criterion for every mode, beside the paper's, and each
//! trial's outcome; bad arguments are exit 2.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;
use common::unitac_lab;

#[test]
fn one_cup_trial_per_mode_gives_every_row_and_each_outcome() {
    let dir = std::env::temp_dir().join(format!("unitac-cli-trials-{}", std::process::id()));
    let o = unitac_lab(&[
        "trials",
        "--scene",
        "cup_deformation",
        "--trials",
        "1",
        "--seed",
        "2",
        "--json",
        "--plot",
        dir.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(
        (j["task"].as_str(), j["split"].as_str()),
        (Some("cup_deformation"), Some("unseen"))
    );
    let rows = j["table"].as_array().unwrap();
    let criteria: Vec<&str> = rows
        .iter()
        .map(|r| r["criterion"].as_str().unwrap())
        .collect();
    assert_eq!(criteria, ["lift", "target deformation", "overall"]);
    // VLA's force rule is a column of its own beside its position rule (no paper figure).
    let paper = [
        [Some(18), None, Some(20), Some(19)],
        [Some(0), None, Some(20), Some(18)],
        [Some(0), None, Some(20), Some(18)],
    ];
    for (r, want) in rows.iter().zip(paper) {
        let cells = r["cells"].as_array().unwrap();
        let modes: Vec<&str> = cells.iter().map(|c| c["mode"].as_str().unwrap()).collect();
        assert_eq!(modes, ["vla", "vla_force", "vtla_real", "vtla_pred"]);
        for (c, p) in cells.iter().zip(want) {
            assert_eq!((c["trials"].as_u64(), c["paper"].as_u64()), (Some(1), p));
            assert!(c["ours"].as_u64().unwrap() <= 1);
        }
    }
    // Each cell is the count of its mode's trial outcomes.
    let modes = j["modes"].as_array().unwrap();
    assert_eq!(modes.len(), 4);
    for (i, m) in modes.iter().enumerate() {
        let t = &m["trials"].as_array().unwrap()[0];
        let cup = &t["outcome"]["cup"];
        assert!(cup["deformation_m"].is_f64(), "{t}");
        for (row, key) in rows.iter().zip(["lift", "deformation", "overall"]) {
            let ours = row["cells"][i]["ours"].as_u64().unwrap();
            assert_eq!(ours, u64::from(cup[key].as_bool().unwrap()), "{key} of {m}");
        }
        let mode = m["mode"].as_str().unwrap();
        let scene = if mode == "vla_force" { "vla" } else { mode };
        assert_eq!(m["scene"], format!("cup_deformation_{scene}"));
        // The force rules and the touch readouts name the stiffness they read and the cup's.
        if mode != "vla" {
            let s = &t["stiffness"];
            assert!(
                s["read_n_per_m"].as_f64().unwrap() > 0.0
                    && s["true_n_per_m"].as_f64().unwrap() > 0.0,
                "{t}"
            );
            assert_eq!(s["camera_width_m"].is_f64(), mode == "vla_force", "{t}");
            assert!(m["stiffness"]["median_relative_error"].is_f64(), "{m}");
        }
    }
    let png = std::fs::read(dir.join("cup_deformation.png")).unwrap();
    assert_eq!(&png[1..4], b"PNG");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn the_text_table_names_each_criterion_and_bad_arguments_are_exit_2() {
    let o = unitac_lab(&[
        "trials",
        "--scene",
        "cup_deformation",
        "--modes",
        "vla",
        "--trials",
        "1",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = String::from_utf8_lossy(&o.stdout);
    for row in ["criterion", "lift", "target deformation", "overall"] {
        assert!(text.lines().any(|l| l.starts_with(row)), "{row} in {text}");
    }
    assert!(text.contains("(paper 18/20)"), "{text}");
    for bad in [
        &["trials", "--scene", "cup_deformation", "--trials", "0"][..],
        &["trials", "--scene", "teapot"],
        &[
            "trials",
            "--scene",
            "fabric_selection",
            "--modes",
            "vla,vtla_fake",
        ],
        // 85 mm of stroke: not offered for the 90 mm cup.
        &[
            "trials",
            "--scene",
            "cup_deformation",
            "--gripper",
            "robotiq_2f85",
        ],
    ] {
        let o = unitac_lab(bad);
        assert_eq!(
            o.status.code(),
            Some(2),
            "{bad:?}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        assert!(o.stdout.is_empty());
    }
}

#[test]
fn a_serial_gripper_trial_reports_its_wire_in_the_json() {
    let o = unitac_lab(&[
        "trials",
        "--scene",
        "cup_deformation",
        "--modes",
        "vla",
        "--trials",
        "1",
        "--gripper",
        "robotiq_2f140",
        "--json",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(j["gripper"], "robotiq_2f140");
    let t = &j["modes"][0]["trials"][0];
    let s = &t["serial"];
    assert_eq!(s["model"], "robotiq_2f140", "{t}");
    assert_eq!(s["device_activations"], 1, "{t}");
    assert!(s["commands"].as_u64().unwrap() > 0, "{t}");
    assert!(
        s["device_requests"].as_u64().unwrap() >= s["exchanges"].as_u64().unwrap(),
        "{t}"
    );
    assert!(s["last_raw_position"].is_u64(), "{t}");
    // The in-process gripper has no wire to report.
    let o = unitac_lab(&[
        "trials",
        "--scene",
        "cup_deformation",
        "--modes",
        "vla",
        "--trials",
        "1",
        "--json",
    ]);
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(j["gripper"], "sim");
    assert!(j["modes"][0]["trials"][0].get("serial").is_none());
}

#[test]
fn the_sweep_the_clamps_and_the_noise_sources_are_in_the_json() {
    // The cup VLA (no model to load): the sweep's six variations of the world, each a table of
    // the same shape; per mode the ticks and clamps; every noise figure with its source.
    let o = unitac_lab(&[
        "trials",
        "--scene",
        "cup_deformation",
        "--modes",
        "vla",
        "--trials",
        "2",
        "--seed",
        "3",
        "--sweep",
        "--json",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let sweep = j["sweep"].as_array().unwrap();
    let names: Vec<&str> = sweep
        .iter()
        .map(|s| s["variant"]["name"].as_str().unwrap())
        .collect();
    assert_eq!(
        names,
        [
            "camera noise x0.5",
            "camera noise x2",
            "cup stiffness x0.5",
            "cup stiffness x2",
            "cup size -10 mm",
            "cup size +10 mm"
        ]
    );
    for s in sweep {
        assert_eq!(s["table"].as_array().unwrap().len(), 3);
    }
    let clamps = &j["modes"][0]["clamps"];
    assert!(clamps["ticks"].as_u64().unwrap() > 100, "{clamps}");
    assert!(clamps["clamped"].is_object() && clamps["reflex"].is_object());
    let figures = j["noise_figures"].as_array().unwrap();
    assert!(figures.len() >= 10);
    for f in figures {
        let source = f["source"].as_str().unwrap();
        assert!(
            !source.is_empty() && f["value"].as_f64().unwrap() > 0.0,
            "{f}"
        );
    }
    // The camera's assumed figures say they are swept.
    assert!(figures.iter().any(
        |f| f["name"].as_str().unwrap().starts_with("camera position")
            && f["source"].as_str().unwrap().contains("swept")
    ));
}

#[test]
fn the_vla_rule_is_calibrated_on_training_cups_only() {
    let o = unitac_lab(&[
        "trials",
        "--scene",
        "cup_deformation",
        "--modes",
        "vla",
        "--train",
        "--trials",
        "3",
        "--seed",
        "1",
        "--calibrate-vla",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = String::from_utf8_lossy(&o.stdout);
    let line = text
        .lines()
        .find_map(|l| l.strip_prefix("vla_offset_m: "))
        .unwrap_or_else(|| panic!("{text}"));
    let v: f64 = line.trim().parse().unwrap();
    assert!(v.is_finite() && v.abs() < 0.01, "{v}");
    // Not on the unseen split, nor another mode.
    for args in [
        &[
            "trials",
            "--scene",
            "cup_deformation",
            "--modes",
            "vla",
            "--calibrate-vla",
        ][..],
        &[
            "trials",
            "--scene",
            "cup_deformation",
            "--modes",
            "vtla_real",
            "--train",
            "--calibrate-vla",
        ][..],
    ] {
        assert_eq!(unitac_lab(args).status.code(), Some(2), "{args:?}");
    }
}

/// The project's Python (the venv scripts/setup.sh makes).
fn python() -> std::path::PathBuf {
    std::env::var_os("UNITAC_VENV")
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|| root().join(".venv"))
        .join("bin/python")
}

fn root() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// A stub policy bundle (crates/policy/tests/make_stub_policy.py: the learned cup VLA policy's
/// inputs and actions) in `dir`.
fn stub(dir: &std::path::Path, args: &[&str]) {
    let st = std::process::Command::new(python())
        .arg(root().join("crates/policy/tests/make_stub_policy.py"))
        .arg(dir)
        .args(args)
        .status()
        .unwrap();
    assert!(st.success(), "make_stub_policy.py failed");
}

/// A copy of the learned cup VLA scene in `dir` as `<task>_learned_vla.yaml`, naming `bundle`
/// (a manifest.json) and with `extra` params lines.
fn learned_scene(dir: &std::path::Path, task: &str, bundle: &std::path::Path, extra: &str) {
    let text =
        std::fs::read_to_string(root().join("launch/scenes/cup_deformation_learned_vla.yaml"))
            .unwrap();
    let mut out = String::new();
    for line in text.lines() {
        if line.starts_with("scene:") {
            out.push_str(&format!("scene: {task}_learned_vla\n"));
        } else if line.trim_start().starts_with("policy: ${UNITAC_MODELS}") {
            out.push_str(&format!("  policy: {}\n", bundle.display()));
        } else if line.trim_start().starts_with("policy: learned") {
            out.push_str(line);
            out.push('\n');
            for e in extra.lines() {
                out.push_str(&format!("      {e}\n"));
            }
        } else {
            out.push_str(line);
            out.push('\n');
        }
    }
    std::fs::write(dir.join(format!("{task}_learned_vla.yaml")), out).unwrap();
}

/// `unitac-lab args` (warnings and errors logged), killed after `limit`.
fn unitac_lab_within(args: &[&str], limit: std::time::Duration) -> std::process::Output {
    common::unitac_lab_within(args, &[("RUST_LOG", "warn")], limit)
}

/// `unitac-lab trials` of one training trial of the learned policy in `scene`, found in the scene
/// directory `dir`.
fn learned_trial_args<'a>(scene: &'a str, dir: &'a std::path::Path) -> Vec<&'a str> {
    vec![
        "trials",
        "--scene",
        scene,
        "--policy",
        "learned",
        "--trials",
        "1",
        "--train",
        "--scene-dir",
        dir.to_str().unwrap(),
    ]
}

fn tmp(name: &str) -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("unitac-cli-trials-{}-{name}", std::process::id()));
    std::fs::remove_dir_all(&d).ok();
    std::fs::create_dir_all(&d).unwrap();
    d
}

#[test]
fn a_learned_policy_that_fails_on_every_tick_is_counted_warned_and_exit_1() {
    let d = tmp("nan");
    stub(&d.join("nan"), &["--kind", "nan"]);
    learned_scene(&d, "stubnan", &d.join("nan/manifest.json"), "");
    let args = learned_trial_args("stubnan", &d);
    let mut json_args = args.clone();
    json_args.push("--json");
    let o = unitac_lab_within(&json_args, std::time::Duration::from_secs(300));
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let m = &j["modes"][0];
    let t = &m["policy_ticks"];
    let ticks = t["ticks"].as_u64().unwrap();
    assert!(ticks > 100, "{t}");
    assert_eq!(t["acted"], 0, "{t}");
    assert_eq!(t["policy_error"].as_u64(), Some(ticks), "{t}");
    assert!(t["first_failure"].as_str().unwrap().contains("NaN"), "{t}");
    assert_eq!(m["never_acted"], serde_json::json!([0]), "{m}");
    assert_eq!(m["trials"][0]["policy_ticks"], *t);
    assert!(
        err.contains(&format!(
            "unitac-lab: warning: vla: the policy gave no usable action on {ticks} of {ticks} ticks \
             (policy error {ticks}, inference over budget 0, action refused 0) in 1 trial(s); first: \
             policy: learned policy: "
        )),
        "{err}"
    );
    assert!(
        err.contains("unitac-lab: vla: the policy never acted in trial(s) 0"),
        "{err}"
    );
    // The text table says it too.
    let o = unitac_lab_within(&args, std::time::Duration::from_secs(300));
    assert_eq!(o.status.code(), Some(1));
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.contains(&format!(
            "vla: the policy gave no usable action on {ticks} of {ticks} ticks"
        )),
        "{text}"
    );
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn a_learned_policy_over_its_inference_budget_does_not_hang_the_trial() {
    let d = tmp("loop");
    // About 2 us per iteration: minutes per inference without a limit.
    stub(
        &d.join("loop"),
        &["--kind", "loop", "--iterations", "100000000"],
    );
    learned_scene(
        &d,
        "stubloop",
        &d.join("loop/manifest.json"),
        "inference_budget_s: 0.002",
    );
    let mut args = learned_trial_args("stubloop", &d);
    args.push("--json");
    let o = unitac_lab_within(&args, std::time::Duration::from_secs(240));
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let t = &j["modes"][0]["policy_ticks"];
    let ticks = t["ticks"].as_u64().unwrap();
    assert!(ticks > 100, "{t}");
    assert_eq!(t["over_budget"].as_u64(), Some(ticks), "{t}");
    assert!(
        t["first_failure"]
            .as_str()
            .unwrap()
            .starts_with("policy: inference over budget: learned policy stub_loop@"),
        "{t}"
    );
    assert!(err.contains("inference over budget "), "{err}");
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn training_seed_moves_only_a_bundle_in_the_seed_layout() {
    // The copied scene names its own bundle; a seed0 bundle of the same name sits beside its
    // directory, as <grandparent>/seed0/<name>: the scene's bundle acts, the other would not.
    let d = tmp("seed");
    stub(&d.join("custom/stub"), &["--kind", "ok"]);
    stub(&d.join("seed0/stub"), &["--kind", "nan"]);
    learned_scene(&d, "stubseed", &d.join("custom/stub/manifest.json"), "");
    let mut base = learned_trial_args("stubseed", &d);
    base.push("--json");
    let o = unitac_lab_within(&base, std::time::Duration::from_secs(300));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let t = &j["modes"][0]["policy_ticks"];
    assert_eq!(t["acted"], t["ticks"], "the scene's own bundle ran: {t}");
    assert!(j["training_seed"].is_null(), "{}", j["training_seed"]);
    // Asked for a training seed, a bundle outside the layout is refused, not rewritten.
    let mut args = base.clone();
    args.extend(["--training-seed", "0"]);
    let o = unitac_lab_within(&args, std::time::Duration::from_secs(300));
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.starts_with("unitac-lab: stubseed_learned_vla: --training-seed 0: the policy bundle ")
            && err.contains("is not at <root>/seed<K>/<name>/manifest.json"),
        "{err}"
    );
    assert_eq!(err.lines().count(), 1, "{err}");
    let _ = std::fs::remove_dir_all(&d);
}
