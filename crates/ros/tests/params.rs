//! Every key of every stage's params struct reaches the stage identically under `unitac run`
//! and under the ROS nodes, from a scene file and from `<stage>.<key>` ROS parameters; unknown or
//! mistyped keys are one-line errors (exit 1). The nodes print the effective params the stages
//! are built from (`<node>: effective params: <kind>: ...`); `unitac run --print-params` prints
//! `unitac_pipeline::effective_params`, which is what this test compares against.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use serde_json::{Value, json};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Duration;
use unitac_contact::{ContactParams, SlipParams};
use unitac_infer::RuntimeConfig;
use unitac_infer::encoder::CompareParams;
use unitac_infer::predict::SamplerParams;
use unitac_policy::PolicyParams;

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("unitac-params-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d.join(name)
}

/// A value of the same type as `d` that differs from it (and passes the stages' range checks);
/// `special` first.
fn other(key: &str, d: &Value, special: &Value) -> Value {
    if let Some(v) = special.get(key) {
        return v.clone();
    }
    match d {
        Value::Bool(b) => json!(!b),
        Value::Number(n) if n.is_u64() => json!(n.as_u64().unwrap() + 1),
        Value::Number(n) => {
            let f = n.as_f64().unwrap();
            json!(if f > 0.0 && f < 1.0 {
                f / 2.0
            } else {
                f * 1.5 + 0.5
            })
        }
        _ => panic!("{key}: default {d} needs a value in the test's table"),
    }
}

/// Non-default values for every key of `default` (serialized); fails if one is missing or equal.
fn non_default(default: Value, special: Value) -> serde_json::Map<String, Value> {
    let mut out = serde_json::Map::new();
    for (k, d) in default.as_object().unwrap() {
        let v = other(k, d, &special);
        assert_ne!(&v, d, "{k}: the test value must differ from the default");
        out.insert(k.clone(), v);
    }
    out
}

/// (contact, slip, encoder, compare, sampler, policy) params with every key set to a non-default
/// value.
fn full_params() -> [serde_json::Map<String, Value>; 6] {
    let bg = tmp("backgrounds");
    std::fs::create_dir_all(&bg).unwrap();
    // A depth calibration of the scene's sensor (the stage loads and checks it).
    let cal = tmp("depth-cal.json");
    unitac_contact::depth::DepthCalibration {
        format: unitac_contact::depth::model::FORMAT,
        sensor: unitac_core::SensorKind::GELSIGHT_MINI,
        serial: String::new(),
        width: 320,
        height: 240,
        m_per_px: 6.34e-5,
        ball_radius_m: 0.002,
        presses_used: 30,
        fit_rms_slope: 0.01,
        model: unitac_contact::depth::GradientModel {
            gx: vec![0.0; unitac_contact::depth::model::FEATURES],
            gy: vec![0.0; unitac_contact::depth::model::FEATURES],
        },
    }
    .save(&cal)
    .unwrap();
    let contact = non_default(
        serde_json::to_value(ContactParams::default()).unwrap(),
        json!({"mask_markers": true, "background_dir": bg, "episode_labels": ["x", "y"],
               "clip_frames": 6, "depth_calibration": cal, "region": "depth"}),
    );
    let slip = non_default(
        serde_json::to_value(SlipParams::default()).unwrap(),
        json!({}),
    );
    let runtime = json!({"library": std::env::var("UNITAC_ORT_LIB").unwrap_or_default(),
                         "providers": ["cuda", "cpu"], "intra_threads": 2});
    let encoder = non_default(
        serde_json::to_value(RuntimeConfig::default()).unwrap(),
        runtime.clone(),
    );
    let compare = non_default(
        serde_json::to_value(CompareParams::default()).unwrap(),
        json!({"property": "hardness", "pairs": [["x", "y"]]}),
    );
    let mut sampler_special = json!({"solver": "midpoint", "objects": ["fabric_x", "fabric_y"],
                                     "budget_s": 0.05});
    sampler_special
        .as_object_mut()
        .unwrap()
        .extend(runtime.as_object().unwrap().clone());
    let sampler = non_default(
        serde_json::to_value(SamplerParams::default()).unwrap(),
        sampler_special,
    );
    // vtla_pred on a pick task (the scene check passes with encoder and compare after it).
    // `policy: learned` needs a bundle trained for the scene's objects and camera names: its
    // load errors are tested in crates/pipeline/tests/policy_scenes.rs.
    let mut policy_default = serde_json::to_value(PolicyParams::default()).unwrap();
    policy_default.as_object_mut().unwrap().remove("policy");
    let policy = non_default(
        policy_default,
        json!({"mode": "vtla_pred", "task": "pick the rougher fabric", "safe_action": "open",
               "objects": ["fabric_x", "fabric_y"], "visual_names": ["fabric_x_roughness"],
               "stiffness_weights": [1.0, 2.0], "latent_len": 96, "min_opening_m": 0.001,
               "max_opening_m": 0.1, "min_z_m": 0.01, "max_z_m": 0.4,
               "touch_z_m": -0.002, "grasp_z_m": -0.0005, "inference_budget_s": 0.2,
               "vla_rule": "force", "gripper": "robotiq_2f140"}),
    );
    [contact, slip, encoder, compare, sampler, policy]
}

/// A scene with the six stages and these params (empty maps: the defaults, but the policy's
/// mode and latent length, which the stages before it require). The sensor has marker dots (the
/// slip stage refuses a DIGIT).
fn scene(name: &str, p: &[serde_json::Map<String, Value>; 6]) -> PathBuf {
    let mut policy = p[5].clone();
    if policy.is_empty() {
        policy.insert("mode".into(), json!("vtla_pred"));
        policy.insert("latent_len".into(), json!(96));
    }
    let stages = json!([
        {"kind": "contact", "params": p[0]},
        {"kind": "slip", "params": p[1]},
        {"kind": "sampler", "models": ["touch"], "params": p[4]},
        {"kind": "policy", "params": policy},
        // After the policy: vtla_pred reads no live comparison, and the scene check looks at the
        // stages before the policy only.
        {"kind": "encoder", "models": ["reference"], "params": p[2]},
        {"kind": "compare", "params": p[3]},
    ]);
    let yaml = format!(
        "scene: {name}\nsource: {{kind: mock, sensor: gelsight-mini, scenario: fabric_selection}}\n\
         models:\n  reference: ${{UNITAC_MODELS}}/reference/manifest.json\n  \
         touch: ${{UNITAC_MODELS}}/touch/manifest.json\nstages: {stages}\n"
    );
    let path = tmp(&format!("{name}.yaml"));
    std::fs::write(&path, yaml).unwrap();
    path
}

/// What `unitac run --print-params` prints for `scene`.
fn run_lines(scene: &Path) -> Vec<String> {
    let s = unitac_pipeline::load_scene(scene.to_str().unwrap(), None).unwrap();
    unitac_pipeline::effective_params(&s).unwrap()
}

/// A ROS parameter value (YAML flow) for a JSON value.
fn ros_yaml(v: &Value) -> String {
    match v {
        Value::String(s) => format!("\"{s}\""),
        other => other.to_string(),
    }
}

/// Start `exe` with `params` (a ros__parameters body); the effective-params lines it prints (it
/// is stopped once it printed `want` of them or exited), its exit status if it exited, and stderr.
fn node_lines(
    role: &[&str],
    name: &str,
    params: &str,
    want: usize,
) -> (Vec<String>, Option<i32>, String) {
    let file = tmp(&format!("{name}.params.yaml"));
    std::fs::write(&file, format!("/**:\n  ros__parameters:\n{params}")).unwrap();
    let mut c = Command::new(common::STAGE_NODE)
        .args([
            "--ros-args",
            "-r",
            &format!("__ns:=/p{}_{name}", std::process::id()),
        ])
        .args(role)
        .arg("--params-file")
        .arg(&file)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let rx = common::stderr_lines(&mut c);
    let (mut lines, mut all) = (Vec::new(), String::new());
    while let Ok(l) = rx.recv_timeout(Duration::from_secs(30)) {
        all.push_str(&l);
        all.push('\n');
        if let Some((_, rest)) = l.split_once(": effective params: ") {
            lines.push(rest.to_string());
            if lines.len() == want {
                break;
            }
        }
    }
    // Exited (stderr closed) or still running: give it a moment to be reaped, then stop it.
    let mut status = None;
    for _ in 0..40 {
        if let Some(s) = c.try_wait().unwrap() {
            status = s.code();
            if let Some(sig) = std::os::unix::process::ExitStatusExt::signal(&s) {
                all.push_str(&format!("(the node died of signal {sig})\n"));
            }
            break;
        }
        if lines.len() == want {
            break;
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    if status.is_none() {
        c.kill().ok();
        c.wait().ok();
    }
    (lines, status, all)
}

/// The stage node as the launch plan runs it for the contact and the inference group.
const CONTACT: &[&str] = &common::CONTACT;
const INFERENCE: &[&str] = &common::INFERENCE;

#[test]
fn every_key_reaches_the_stages_from_the_scene_file_and_from_ros_parameters() {
    let full = full_params();
    let full_scene = scene("full", &full);
    let want = run_lines(&full_scene);
    assert_eq!(want.len(), 6, "{want:?}");
    // The scene's order: contact, slip, sampler, policy, encoder, compare; the inference node's
    // stages are the sampler, encoder and compare ones, the policy's is the fourth.
    let want_infer: Vec<String> = [2, 4, 5].iter().map(|&i| want[i].clone()).collect();
    // The values really are the non-default ones (not the defaults the scene left out).
    let defaults = run_lines(&scene("defaults", &Default::default()));
    for (w, d) in want.iter().zip(&defaults) {
        assert_ne!(w, d);
    }

    // 1. The same scene file: the nodes build exactly what `unitac run` builds.
    let (contact, _, log) = node_lines(
        CONTACT,
        "c1",
        &format!("    scene: {}\n", full_scene.display()),
        2,
    );
    assert_eq!(contact, want[..2], "{log}");
    let (infer, _, log) = node_lines(
        INFERENCE,
        "i1",
        &format!("    scene: {}\n", full_scene.display()),
        3,
    );
    assert_eq!(infer, want_infer, "{log}");

    // 2. A scene with default params plus `<stage>.<key>` ROS parameters for every key ROS can
    // carry (nested lists such as compare.pairs cannot be ROS parameters: scene file only).
    let mut base: [serde_json::Map<String, Value>; 6] = Default::default();
    base[3].insert("pairs".into(), full[3]["pairs"].clone());
    let default_scene = scene("overridden", &base);
    let overrides = |kind: &str, p: &serde_json::Map<String, Value>| -> String {
        p.iter()
            .filter(|(k, _)| !(kind == "compare" && *k == "pairs"))
            .map(|(k, v)| format!("    {kind}.{k}: {}\n", ros_yaml(v)))
            .collect()
    };
    let head = format!("    scene: {}\n", default_scene.display());
    let (contact, _, log) = node_lines(
        CONTACT,
        "c2",
        &(head.clone() + &overrides("contact", &full[0]) + &overrides("slip", &full[1])),
        2,
    );
    assert_eq!(contact, want[..2], "{log}");
    let body = overrides("encoder", &full[2])
        + &overrides("compare", &full[3])
        + &overrides("sampler", &full[4]);
    let (infer, _, log) = node_lines(INFERENCE, "i2", &(head + &body), 3);
    assert_eq!(infer, want_infer, "{log}");

    // 3. The policy stage (its ROS node comes later): every `policy.<key>` through the same
    // override path the nodes use reaches the typed params exactly as the scene file does.
    let mut s = unitac_pipeline::load_scene(default_scene.to_str().unwrap(), None).unwrap();
    let policy: Vec<(String, serde_yaml::Value)> = full[5]
        .iter()
        .map(|(k, v)| {
            (
                format!("policy.{k}"),
                serde_yaml::from_str(&v.to_string()).unwrap(),
            )
        })
        .collect();
    unitac_pipeline::overrides::apply(&mut s, &["policy"], &policy).unwrap();
    let got = unitac_pipeline::effective_params(&s).unwrap();
    // The stage carries its scene's name (PolicyStatus.scene): the two scenes differ only there.
    assert_eq!(got[3].replace("\"overridden\"", "\"full\""), want[3]);
}

#[test]
fn unknown_and_mistyped_parameters_stop_a_node_with_one_line() {
    for (role, name, params, expect) in [
        (CONTACT, "u1", "    contact.no_such_key: 1\n", "no_such_key"),
        (CONTACT, "u2", "    contact.noise_k: \"loud\"\n", "noise_k"),
        (
            CONTACT,
            "u3",
            "    noise_k: 3.0\n",
            "unknown parameter 'noise_k'",
        ),
        (
            CONTACT,
            "u4",
            "    sampler.steps: 4\n",
            "'sampler' is not a stage this node runs (contact, slip)",
        ),
        (
            INFERENCE,
            "u5",
            "    sampler.no_such_key: 1\n",
            "no_such_key",
        ),
        (
            INFERENCE,
            "u6",
            "    encoder.providers: \"gpu\"\n",
            "provider",
        ),
    ] {
        let (_, status, log) = node_lines(role, name, params, usize::MAX);
        assert_eq!(status, Some(1), "{name}: {log}");
        let errors: Vec<&str> = log
            .lines()
            .filter(|l| !l.contains("effective params"))
            .collect();
        assert_eq!(errors.len(), 1, "{name}: {log}");
        assert!(errors[0].contains(expect), "{name}: {log}");
    }
}
