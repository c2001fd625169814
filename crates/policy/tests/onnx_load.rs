//! Loading ONNX policies: the manifest is checked against the real model's inputs and outputs
//! (as ONNX Runtime reports them), and every problem comes back in one error.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;
use serde_json::json;
use unitac_policy::onnx::{LoadError, Mismatch, OnnxPolicy, RuntimeConfig};

#[test]
fn the_test_policy_loads_with_its_names_and_rate() {
    let dir = common::make_policy("load-ok", &[]);
    let p = common::load(&dir);
    assert!(p.id().starts_with("test_mlp@"));
    assert_eq!(
        p.input_names(),
        [
            "observation.state",
            "observation.tactile_latent",
            "observation.images.wrist"
        ]
    );
    assert_eq!(
        p.action_names(),
        ["gripper.opening", "gripper.speed", "gripper.force"]
    );
    assert_eq!(p.period_ns(), 33_333_333);
}

#[test]
fn every_mismatch_is_reported_at_once() {
    let dir = common::make_policy("load-all", &[]);
    common::edit(&dir, |m| {
        // Missing input (and so an extra one in the model).
        m["inputs"][0]["name"] = "observation.environment_state".into();
        // Wrong dimension.
        m["inputs"][1]["shape"] = json!(["batch", 15]);
        // Missing normalisation.
        m["inputs"][2]
            .as_object_mut()
            .unwrap()
            .remove("normalization");
        // Horizon: the model and the manifest's shape predict 8 rows.
        m["chunk_size"] = 10.into();
        // Bad bounds, std <= 0 and a statistic that is not a finite float32.
        m["output"]["actions"][1]["min"] = 0.2.into();
        m["output"]["normalization"]["std"][2] = 0.0.into();
        m["output"]["normalization"]["mean"][0] = 1e39.into();
    });
    let p = common::mismatches(&dir);
    println!(
        "{}",
        unitac_policy::onnx::LoadError::Mismatches(unitac_policy::onnx::Mismatches {
            policy: "test_mlp".into(),
            dir: "DIR".into(),
            problems: p.clone()
        })
    );
    let has = |f: &dyn Fn(&Mismatch) -> bool| p.iter().any(f);
    assert!(has(
        &|m| matches!(m, Mismatch::MissingInput { name, model_has }
        if name == "observation.environment_state" && model_has.len() == 3)
    ));
    assert!(has(
        &|m| matches!(m, Mismatch::ExtraInput { name } if name == "observation.state")
    ));
    assert!(has(
        &|m| matches!(m, Mismatch::Dim { tensor, index: 1, model: 16, declared: 15 }
        if tensor == "observation.tactile_latent")
    ));
    // The latent's statistics no longer fit its declared size either.
    assert!(has(
        &|m| matches!(m, Mismatch::StatLength { tensor, len: 16, .. }
        if tensor == "observation.tactile_latent")
    ));
    assert!(has(
        &|m| matches!(m, Mismatch::MissingNormalization { tensor }
        if tensor == "observation.images.wrist")
    ));
    assert!(has(
        &|m| matches!(m, Mismatch::Horizon { declared: 10, found: 8, by, .. }
        if by.contains("model"))
    ));
    assert!(has(
        &|m| matches!(m, Mismatch::Horizon { declared: 10, found: 8, by, .. }
        if by.contains("manifest"))
    ));
    assert!(has(
        &|m| matches!(m, Mismatch::Bounds { action, .. } if action == "gripper.speed")
    ));
    assert!(has(&|m| matches!(
        m,
        Mismatch::StdNotPositive { index: 2, .. }
    )));
    assert!(has(&|m| matches!(
        m,
        Mismatch::NonFiniteStat {
            stat: "mean",
            index: 0,
            ..
        }
    )));
    assert_eq!(p.len(), 11, "{p:#?}");
}

#[test]
fn action_count_rank_and_output_name_against_the_model() {
    let dir = common::make_policy("load-out", &[]);
    common::edit(&dir, |m| {
        m["output"]["actions"].as_array_mut().unwrap().pop();
        m["output"]["normalization"]["mean"]
            .as_array_mut()
            .unwrap()
            .pop();
        m["output"]["normalization"]["std"]
            .as_array_mut()
            .unwrap()
            .pop();
        m["inputs"][0]["shape"] = json!(["batch", 2, 3]);
    });
    let p = common::mismatches(&dir);
    assert!(p.iter().any(|m| matches!(m,
        Mismatch::ActionCount { declared: 2, found: 3, by, .. } if by.contains("model"))));
    assert!(p.iter().any(|m| matches!(m,
        Mismatch::Rank { tensor, model: 2, declared: 3, .. } if tensor == "observation.state")));

    common::edit(&dir, |m| m["output"]["name"] = "actions".into());
    let p = common::mismatches(&dir);
    assert!(p.iter().any(|m| matches!(m,
        Mismatch::MissingOutput { name, model_has } if name == "actions" && model_has == &["action"])));
    assert!(
        p.iter()
            .any(|m| matches!(m, Mismatch::ExtraOutput { name } if name == "action"))
    );
}

#[test]
fn dtypes_the_model_has_and_the_runtime_feeds() {
    // The model takes float64 state; the manifest says float32.
    let dir = common::make_policy("load-f64", &["--state-dtype", "float64"]);
    let p = common::mismatches(&dir);
    assert_eq!(
        p,
        [Mismatch::Dtype {
            tensor: "observation.state".into(),
            model: "float64".into(),
            declared: "float32".into()
        }]
    );
    // Declaring float64 matches the model but is not something the runtime feeds.
    common::edit(&dir, |m| m["inputs"][0]["dtype"] = "float64".into());
    let p = common::mismatches(&dir);
    assert_eq!(
        p,
        [Mismatch::UnsupportedDtype {
            tensor: "observation.state".into(),
            dtype: "float64".into()
        }]
    );
}

#[test]
fn wrong_sha256_is_listed_with_the_other_problems() {
    let dir = common::make_policy("load-sha", &[]);
    common::edit(&dir, |m| {
        m["sha256"] = "00".repeat(32).into();
        m["n_action_steps"] = 9.into();
    });
    let p = common::mismatches(&dir);
    assert!(
        matches!(&p[..], [
            Mismatch::Sha256 { declared, .. },
            Mismatch::ActionSteps { steps: 9, chunk_size: 8 },
        ] if declared.starts_with("0000")),
        "{p:?}"
    );
}

#[test]
fn a_missing_or_corrupt_model_file_is_a_mismatch_not_a_crash() {
    let dir = common::make_policy("load-file", &[]);
    std::fs::write(dir.join("policy.onnx"), b"not an onnx file").unwrap();
    let p = common::mismatches(&dir);
    assert!(p.iter().any(|m| matches!(m, Mismatch::Sha256 { .. })));
    assert!(
        p.iter()
            .any(|m| matches!(m, Mismatch::File { file, .. } if file == "policy.onnx"))
    );
    std::fs::remove_file(dir.join("policy.onnx")).unwrap();
    let p = common::mismatches(&dir);
    assert!(
        matches!(&p[..], [Mismatch::File { msg, .. }] if msg.contains("not found")),
        "{p:?}"
    );
}

#[test]
fn unreadable_manifests_are_one_clear_error() {
    let dir = common::make_policy("load-text", &[]);
    let path = dir.join("manifest.json");
    let text = std::fs::read_to_string(&path).unwrap();
    // Python's json.dump writes NaN for a NaN statistic unless told not to.
    std::fs::write(&path, text.replacen("0.04,", "NaN,", 1)).unwrap();
    match OnnxPolicy::load(&dir, &RuntimeConfig::default()) {
        Err(e @ LoadError::Manifest(_)) => {
            assert!(e.to_string().contains("JSON has no NaN"), "{e}")
        }
        other => panic!("{other:?}"),
    }
    std::fs::remove_file(&path).unwrap();
    assert!(matches!(
        OnnxPolicy::load(&dir, &RuntimeConfig::default()),
        Err(LoadError::Manifest(_))
    ));
}
