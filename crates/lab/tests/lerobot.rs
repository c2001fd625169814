//! Demonstrations in LeRobot's dataset layout v3.0: `unitac-lab demos` records both tasks with every
//! mode's observations, python/unitac_tools/lerobot_dataset.py lays them out, and
//! tests/policy/check_lerobot_v3.py checks with pyarrow what LeRobot's v3 loader reads (the
//! project's Python: `$UNITAC_VENV` or `.venv`). The checker itself must refuse a dataset the
//! loader would refuse, and values outside a feature's bounds or categories. The writer refuses a
//! demos.json with a value that is not finite or beyond any range, an action outside its bounds,
//! an arm target that is no category, a missing key or a wrong type: exit 1, one line naming the
//! episode, tick and feature, nothing written (a small demos.json made here, no recording).
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
    let o = Command::new(env!("CARGO_BIN_EXE_unitac-lab"))
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
        .args(["-m", "unitac_tools.lerobot_dataset"])
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

/// A small demos.json of the cup task in the layout `unitac-lab demos` writes: one demonstration of
/// three ticks, one object, pooled latents 2 wide, every value inside its bounds.
fn small_demos() -> serde_json::Value {
    // The command actions as the recorder names them (one list, unitac_trials::demos).
    let names = unitac_trials::demos::action_names();
    assert_eq!(names.len(), 7, "{names:?}");
    let bounds = [
        [0.0, 0.11],
        [0.0, 0.2],
        [0.0, 40.0],
        [-1.0, 1.0],
        [-1.0, 1.0],
        [0.0, 1.0],
        [0.0, 0.2],
    ];
    let ticks: Vec<serde_json::Value> = (0..3)
        .map(|k| {
            serde_json::json!({
                "t_s": f64::from(k) / 30.0,
                "state": [0.08, 0.08, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0],
                "visual": [0.1, 0.2, 0.3, 0.4, 0.5],
                "contact": [0.0, 0.0, 0.0],
                "latched": [0.0, 0.0],
                "arm": [0.1, 1.0],
                "latent_real": [0.0, 0.0, 0.0],
                "latent_pred": [0.0, 0.0, 0.0],
                "comparison": [0.0, 0.0, 0.0, 0.0, 0.0],
                "action": [0.05, 0.1, 40.0, 0.3, -0.2, 0.1, 0.0],
                "arm_target": k % 2,
            })
        })
        .collect();
    serde_json::json!({
        "instruction": "squeeze the cup by 1 cm",
        "config": {"dt_s": 1.0 / 30.0, "pooled_len": 2},
        "action_names": names,
        "action_bounds": names.iter().zip(bounds).map(|(n, b)| (n.to_string(), serde_json::json!(b))).collect::<serde_json::Map<_, _>>(),
        "demos": [{
            "seed": 2, "trial": 0, "success": true, "objects": ["cup_a"],
            "visual_names": ["x", "y", "z", "w", "h"], "ticks": ticks,
        }],
    })
}

/// Write `demos` (its JSON text through `text`, which may put in what serde_json cannot say,
/// such as NaN) into a directory of its own and run the writer on it, with `--out` a dataset
/// there; the writer's output and the directory.
fn write_dataset(
    name: &str,
    demos: &serde_json::Value,
    text: &dyn Fn(String) -> String,
) -> (Output, PathBuf) {
    let dir = tmpdir(name);
    let path = dir.join("demos.json");
    std::fs::write(&path, text(demos.to_string())).unwrap();
    let o = Command::new(python())
        .args(["-m", "unitac_tools.lerobot_dataset"])
        .arg("--demos")
        .arg(&path)
        .arg("--out")
        .arg(dir.join("dataset"))
        .output()
        .unwrap();
    (o, dir)
}

/// One case of [`refused`]: an edit of the demos, an edit of their JSON text (`FROM=>TO`, or
/// empty), and the pieces the error line must name.
type Case<'a> = (&'a dyn Fn(&mut serde_json::Value), &'a str, &'a [&'a str]);

/// Each edit of the small demos.json is refused: exit 1, one line on stderr naming where (every
/// piece of `want`), no traceback, and nothing written beside demos.json.
fn refused(name: &str, cases: &[Case]) {
    for (k, (edit, text_edit, want)) in cases.iter().enumerate() {
        let mut demos = small_demos();
        edit(&mut demos);
        let (o, dir) = write_dataset(&format!("{name}-{k}"), &demos, &|s| match text_edit
            .split_once("=>")
        {
            Some((from, to)) => s.replacen(from, to, 1),
            None => s,
        });
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{name} {k}: {}", text(&o));
        assert_eq!(err.lines().count(), 1, "{name} {k}: one line: {err}");
        assert!(err.starts_with("lerobot_dataset: "), "{name} {k}: {err}");
        assert!(!err.contains("Traceback"), "{name} {k}: {err}");
        for w in *want {
            assert!(err.contains(w), "{name} {k}: wants {w:?}: {err}");
        }
        let left: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(left, ["demos.json"], "{name} {k}: nothing half-written");
        std::fs::remove_dir_all(&dir).ok();
    }
}

fn tick(d: &mut serde_json::Value, t: usize) -> &mut serde_json::Value {
    &mut d["demos"][0]["ticks"][t]
}

#[test]
fn the_small_demos_make_a_dataset_the_checker_passes() {
    let (o, dir) = write_dataset("small", &small_demos(), &|s| s);
    assert!(o.status.success(), "{}", text(&o));
    let o = py("tests/policy/check_lerobot_v3.py", &[&dir.join("dataset")]);
    assert!(o.status.success(), "{}", text(&o));
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn the_writer_refuses_values_that_are_not_finite_or_beyond_any_range() {
    // serde_json writes no NaN or Infinity; Python's json reads them, so they go in as text.
    let nan = |d: &mut serde_json::Value| tick(d, 1)["action"][2] = "NAN".into();
    let inf = |d: &mut serde_json::Value| tick(d, 2)["state"][0] = "INF".into();
    let ninf = |d: &mut serde_json::Value| tick(d, 0)["latent_pred"][1] = "NINF".into();
    let huge_action = |d: &mut serde_json::Value| tick(d, 0)["action"][3] = 1e30.into();
    let huge_obs = |d: &mut serde_json::Value| tick(d, 2)["latent_real"][1] = 1e30.into();
    let huge_visual = |d: &mut serde_json::Value| tick(d, 1)["visual"][4] = (-1e30).into();
    refused(
        "nonfinite",
        &[
            (
                &nan,
                "\"NAN\"=>NaN",
                &[
                    "episode 0, tick 1",
                    "action[2]",
                    "gripper.force_n",
                    "not finite",
                ],
            ),
            (
                &inf,
                "\"INF\"=>Infinity",
                &["episode 0, tick 2", "observation.state[0]", "not finite"],
            ),
            (
                &ninf,
                "\"NINF\"=>-Infinity",
                &[
                    "episode 0, tick 0",
                    "observation.tactile_latent_pred[1]",
                    "not finite",
                ],
            ),
            (
                &huge_action,
                "",
                &["episode 0, tick 0", "action[3]", "arm.x_m", "1e+30"],
            ),
            (
                &huge_obs,
                "",
                &[
                    "episode 0, tick 2",
                    "observation.tactile_latent_real[1]",
                    "1e+30",
                ],
            ),
            (
                &huge_visual,
                "",
                &["episode 0, tick 1", "observation.visual[4]", "-1e+30"],
            ),
        ],
    );
}

#[test]
fn the_writer_refuses_actions_outside_the_demos_bounds() {
    // The bounds are demos.json's action_bounds: the recording scene's safety layer.
    let force = |d: &mut serde_json::Value| tick(d, 1)["action"][2] = 40.5.into();
    let z = |d: &mut serde_json::Value| tick(d, 2)["action"][5] = (-0.01).into();
    let opening = |d: &mut serde_json::Value| {
        d["action_bounds"]["gripper.position_m"] = serde_json::json!([0.0, 0.04]);
    };
    refused(
        "bounds",
        &[
            (
                &force,
                "",
                &[
                    "episode 0, tick 1",
                    "action[2]",
                    "gripper.force_n",
                    "40.5",
                    "[0, 40]",
                ],
            ),
            (
                &z,
                "",
                &["episode 0, tick 2", "action[5]", "arm.z_m", "[0, 1]"],
            ),
            (
                &opening,
                "",
                &[
                    "episode 0, tick 0",
                    "action[0]",
                    "gripper.position_m",
                    "[0, 0.04]",
                ],
            ),
        ],
    );
}

#[test]
fn the_writer_refuses_arm_targets_that_are_not_categories() {
    // 0 home, k + 1 object k of the demonstration's objects (one here).
    let far = |d: &mut serde_json::Value| tick(d, 1)["arm_target"] = 99.into();
    let negative = |d: &mut serde_json::Value| tick(d, 2)["arm_target"] = (-3).into();
    let two = |d: &mut serde_json::Value| tick(d, 0)["arm_target"] = 2.into();
    let fraction = |d: &mut serde_json::Value| tick(d, 1)["arm_target"] = 1.5.into();
    refused(
        "arm_target",
        &[
            (&far, "", &["episode 0, tick 1", "action.arm_target", "99"]),
            (
                &negative,
                "",
                &["episode 0, tick 2", "action.arm_target", "-3"],
            ),
            (&two, "", &["episode 0, tick 0", "action.arm_target", "2"]),
            (
                &fraction,
                "",
                &["episode 0, tick 1", "action.arm_target", "1.5", "integer"],
            ),
        ],
    );
}

#[test]
fn the_writer_refuses_missing_keys() {
    fn remove(v: &mut serde_json::Value, key: &str) {
        v.as_object_mut().unwrap().remove(key).unwrap();
    }
    let action = |d: &mut serde_json::Value| remove(tick(d, 1), "action");
    let arm_target = |d: &mut serde_json::Value| remove(tick(d, 2), "arm_target");
    let bounds = |d: &mut serde_json::Value| remove(d, "action_bounds");
    let one_bound = |d: &mut serde_json::Value| remove(&mut d["action_bounds"], "arm.y_m");
    let demos = |d: &mut serde_json::Value| remove(d, "demos");
    let objects = |d: &mut serde_json::Value| remove(&mut d["demos"][0], "objects");
    let pooled = |d: &mut serde_json::Value| remove(&mut d["config"], "pooled_len");
    refused(
        "missing",
        &[
            (&action, "", &["episode 0, tick 1", "'action'"]),
            (&arm_target, "", &["episode 0, tick 2", "'arm_target'"]),
            (&bounds, "", &["demos.json", "'action_bounds'"]),
            (&one_bound, "", &["action_bounds", "arm.y_m"]),
            (&demos, "", &["demos.json", "'demos'"]),
            (&objects, "", &["episode 0", "'objects'"]),
            (&pooled, "", &["config", "'pooled_len'"]),
        ],
    );
}

#[test]
fn the_writer_refuses_wrong_types() {
    let text_value = |d: &mut serde_json::Value| tick(d, 1)["action"][0] = "x".into();
    let boolean = |d: &mut serde_json::Value| tick(d, 2)["contact"][0] = true.into();
    let null = |d: &mut serde_json::Value| tick(d, 0)["comparison"][4] = serde_json::Value::Null;
    let object = |d: &mut serde_json::Value| tick(d, 1)["state"] = serde_json::json!({"a": 1});
    let short = |d: &mut serde_json::Value| tick(d, 1)["latched"] = serde_json::json!([0.0]);
    let ticks = |d: &mut serde_json::Value| d["demos"][0]["ticks"] = "abc".into();
    let seed = |d: &mut serde_json::Value| d["demos"][0]["seed"] = "2".into();
    let dt = |d: &mut serde_json::Value| d["config"]["dt_s"] = serde_json::json!([0.03]);
    let top = |d: &mut serde_json::Value| *d = serde_json::json!([1, 2]);
    refused(
        "types",
        &[
            (
                &text_value,
                "",
                &["episode 0, tick 1", "action[0]", "not a number"],
            ),
            (
                &boolean,
                "",
                &[
                    "episode 0, tick 2",
                    "observation.contact[0]",
                    "not a number",
                ],
            ),
            (
                &null,
                "",
                &[
                    "episode 0, tick 0",
                    "observation.comparison[4]",
                    "not a number",
                ],
            ),
            (&object, "", &["episode 0, tick 1", "state", "not an array"]),
            (
                &short,
                "",
                &["episode 0, tick 1", "observation.latched", "not 2"],
            ),
            (&ticks, "", &["episode 0", "ticks", "not an array"]),
            (&seed, "", &["episode 0", "seed", "not an integer"]),
            (&dt, "", &["config", "dt_s", "not a number"]),
            (&top, "", &["demos.json", "not an object"]),
            (&|_| {}, "{=>{{", &["not JSON"]),
        ],
    );
}

#[test]
fn the_writer_replaces_only_a_dataset_or_an_empty_directory() {
    // A directory that holds something else is left as it is.
    let (o, dir) = write_dataset("replace", &small_demos(), &|s| s);
    assert!(o.status.success(), "{}", text(&o));
    let notes = dir.join("notes");
    std::fs::create_dir_all(&notes).unwrap();
    std::fs::write(notes.join("keep.txt"), "mine").unwrap();
    let run = |out: &Path| {
        Command::new(python())
            .args(["-m", "unitac_tools.lerobot_dataset"])
            .arg("--demos")
            .arg(dir.join("demos.json"))
            .arg("--out")
            .arg(out)
            .output()
            .unwrap()
    };
    let o = run(&notes);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("not touched"),
        "{}",
        text(&o)
    );
    assert_eq!(
        std::fs::read_to_string(notes.join("keep.txt")).unwrap(),
        "mine"
    );
    assert_eq!(std::fs::read_dir(&notes).unwrap().count(), 1);
    let o = run(&dir.join("demos.json"));
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    // An existing dataset is replaced whole, by a complete one.
    let ds = dir.join("dataset");
    std::fs::write(ds.join("meta/stale.json"), "{}").unwrap();
    let o = run(&ds);
    assert!(o.status.success(), "{}", text(&o));
    assert!(!ds.join("meta/stale.json").exists());
    let o = py("tests/policy/check_lerobot_v3.py", &[&ds]);
    assert!(o.status.success(), "{}", text(&o));
    // Nothing else beside them: no temporary directory left.
    let mut left: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    left.sort();
    assert_eq!(left, ["dataset", "demos.json", "notes"]);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn the_checker_refuses_values_outside_bounds_or_categories() {
    let (o, dir) = write_dataset("check-bounds", &small_demos(), &|s| s);
    assert!(o.status.success(), "{}", text(&o));
    let ds = dir.join("dataset");
    let info_path = ds.join("meta/info.json");
    let info: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&info_path).unwrap()).unwrap();
    let broken = |edit: &dyn Fn(&mut serde_json::Value), want: &[&str]| {
        let mut i = info.clone();
        edit(&mut i);
        std::fs::write(&info_path, i.to_string()).unwrap();
        let o = py("tests/policy/check_lerobot_v3.py", &[&ds]);
        assert_eq!(o.status.code(), Some(1), "{}", text(&o));
        for w in want {
            assert!(text(&o).contains(w), "{w}: {}", text(&o));
        }
    };
    // The force limit the data sits on (40 N), lowered below it.
    broken(
        &|i| i["features"]["action"]["bounds"]["max"][2] = 39.0.into(),
        &[
            "frame 0",
            "action[2]",
            "gripper.force_n",
            "outside its bounds",
        ],
    );
    // The arm's z above what it went to.
    broken(
        &|i| i["features"]["action"]["bounds"]["min"][5] = 0.5.into(),
        &["action[5]", "arm.z_m", "outside its bounds"],
    );
    // Bounds that are no range.
    broken(
        &|i| i["features"]["action"]["bounds"]["min"][0] = 1.0.into(),
        &["action", "bounds"],
    );
    // The object the arm went to (category 1) no longer among the categories.
    broken(
        &|i| i["features"]["action.arm_target"]["categories"] = serde_json::json!(["home"]),
        &["frame 1", "action.arm_target", "categories"],
    );
    std::fs::write(&info_path, info.to_string()).unwrap();
    let o = py("tests/policy/check_lerobot_v3.py", &[&ds]);
    assert!(o.status.success(), "{}", text(&o));
    std::fs::remove_dir_all(&dir).ok();
}
