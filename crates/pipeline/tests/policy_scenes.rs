//! The policy stage in scenes: the shipped scene per task and mode loads and builds its typed
//! params; a mode whose inputs no stage produces, or a stage the mode does not use, is rejected at
//! load with one line; `policy.<key>` overrides reach the typed params.
#![allow(clippy::unwrap_used, clippy::panic)]

use serde_yaml::Value;
use std::path::{Path, PathBuf};
use unitac_pipeline::{StageConfig, load_scene, overrides, stage_configs};
use unitac_policy::Mode;

fn policy_of(cfgs: &[StageConfig]) -> (unitac_policy::PolicyParams, String, Option<PathBuf>) {
    match cfgs.last().unwrap() {
        StageConfig::Policy {
            params,
            scene,
            model,
        } => ((**params).clone(), scene.clone(), model.clone()),
        other => panic!("the policy stage is last: {other:?}"),
    }
}

#[test]
fn every_shipped_task_and_mode_loads_only_what_its_mode_uses() {
    for (task, mode, kinds) in [
        ("cup_deformation", Mode::Vla, vec!["policy"]),
        (
            "cup_deformation",
            Mode::VtlaReal,
            vec!["contact", "encoder", "policy"],
        ),
        (
            "cup_deformation",
            Mode::VtlaPred,
            vec!["contact", "sampler", "policy"],
        ),
        ("fabric_selection", Mode::Vla, vec!["policy"]),
        (
            "fabric_selection",
            Mode::VtlaReal,
            vec!["contact", "encoder", "compare", "policy"],
        ),
        (
            "fabric_selection",
            Mode::VtlaPred,
            vec!["contact", "sampler", "policy"],
        ),
    ] {
        let name = format!("{task}_{}", mode.as_str());
        let s = load_scene(&name, None).unwrap();
        let cfgs = stage_configs(&s).unwrap();
        let got: Vec<&str> = cfgs.iter().map(|c| c.kind()).collect();
        assert_eq!(got, kinds, "{name}");
        let (p, scene, model) = policy_of(&cfgs);
        assert_eq!(p.mode, mode, "{name}");
        assert_eq!(scene, name);
        // The cup's tactile modes read the stiffness from a fitted model (the real latent's:
        // `scripts/setup.sh policy`; the pooled predicted latent's: the touch bundle's, stage touch),
        // the others have nothing learned to load.
        let want = match (task, mode) {
            ("cup_deformation", Mode::VtlaReal) => Some("cup_stiffness_real"),
            ("cup_deformation", Mode::VtlaPred) => Some("stiffness"),
            _ => None,
        };
        assert_eq!(
            model
                .as_ref()
                .and_then(|m| m.file_name())
                .and_then(|n| n.to_str()),
            want,
            "{name}"
        );
        unitac_pipeline::build_stage(&s, cfgs.last().unwrap().clone()).unwrap();
    }
}

fn write(name: &str, stages: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("unitac-policy-scenes-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(format!("{name}.yaml"));
    std::fs::write(
        &path,
        format!(
            "scene: {name}\nsource: {{kind: mock, sensor: gelsight-mini, scenario: cup_deformation}}\n\
             models:\n  reference: ${{UNITAC_MODELS}}/reference/manifest.json\nstages:\n{stages}"
        ),
    )
    .unwrap();
    path
}

#[test]
fn a_mode_and_its_stages_must_agree_at_load() {
    let cup = "task: squeeze the cup, objects: [cup]";
    for (name, stages, want) in [
        (
            "vla_with_encoder",
            format!(
                "  - kind: contact\n  - kind: encoder\n    models: [reference]\n  - kind: policy\n    params: {{mode: vla, {cup}, visual_names: [cup_width_m]}}\n"
            ),
            "mode vla does not use the contact stage's output: remove it from the scene",
        ),
        (
            "real_with_sampler",
            format!(
                "  - kind: contact\n  - kind: encoder\n    models: [reference]\n  - kind: sampler\n    models: [reference]\n  - kind: policy\n    params: {{mode: vtla_real, {cup}, latent_len: 3072}}\n"
            ),
            "mode vtla_real does not use the sampler stage's output",
        ),
        (
            "pred_without_sampler",
            format!(
                "  - kind: contact\n  - kind: policy\n    params: {{mode: vtla_pred, {cup}, latent_len: 64}}\n"
            ),
            "mode vtla_pred reads latent_pred (predicted tactile latent), which only a sampler stage produces",
        ),
        (
            "unknown_task",
            "  - kind: policy\n    params: {mode: vla, task: juggle the cup}\n".to_string(),
            "task 'juggle the cup' is not understood",
        ),
    ] {
        let path = write(name, &stages);
        let e = load_scene(path.to_str().unwrap(), None)
            .unwrap_err()
            .to_string();
        assert!(e.contains(want), "{name}: {e}");
        assert!(
            e.contains("stages[") && e.contains("(policy)"),
            "{name}: {e}"
        );
        assert!(!e.contains('\n'), "{name}: {e}");
    }
}

#[test]
fn policy_overrides_reach_the_typed_params() {
    let mut s = load_scene("cup_deformation_vla", None).unwrap();
    overrides::apply(
        &mut s,
        &["policy"],
        &[
            ("policy.max_force_n".into(), Value::from(12.5)),
            ("policy.safe_action".into(), Value::from("open")),
            ("policy.task".into(), Value::from("squeeze the cup by 8 mm")),
        ],
    )
    .unwrap();
    let (p, _, _) = policy_of(&stage_configs(&s).unwrap());
    assert_eq!(p.limits.max_force_n, 12.5);
    assert_eq!(p.safe_action, unitac_policy::safety::SafeAction::Open);
    assert_eq!(p.task, "squeeze the cup by 8 mm");
    for (k, v, want) in [
        ("policy.task", Value::from("dance"), "task 'dance'"),
        ("policy.max_force_n", Value::from(-1.0), "max_force_n = -1"),
        ("policy.no_such_key", Value::from(1), "no_such_key"),
        ("policy.mode", Value::from("vlx"), "vlx"),
    ] {
        let mut s = load_scene("cup_deformation_vla", None).unwrap();
        let e = overrides::apply(&mut s, &["policy"], &[(k.into(), v)])
            .unwrap_err()
            .to_string();
        assert!(e.contains(want), "{k}: {e}");
        assert!(!e.contains('\n'), "{k}: {e}");
    }
}

/// A cup scene whose policy stage names the stiffness model at `model` (a manifest path).
fn with_model(name: &str, mode: &str, latent_len: usize, model: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("unitac-policy-scenes-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(format!("{name}.yaml"));
    let producer = if mode == "vtla_real" {
        "encoder"
    } else {
        "sampler"
    };
    std::fs::write(
        &path,
        format!(
            "scene: {name}\nsource: {{kind: mock, sensor: gelsight-mini, scenario: cup_deformation}}\n\
             models:\n  reference: ${{UNITAC_MODELS}}/reference/manifest.json\n  stiffness: {model}\n\
             stages:\n  - kind: contact\n  - kind: {producer}\n    models: [reference]\n\
             \x20 - kind: policy\n    models: [stiffness]\n    params: {{mode: {mode}, task: squeeze the cup, objects: [cup], latent_len: {latent_len}}}\n"
        ),
    )
    .unwrap();
    path
}

/// The load error of the scene's policy stage, as its message.
fn refused(scene: &Path) -> String {
    build_policy(scene).unwrap_err().to_string()
}

fn build_policy(path: &Path) -> Result<(), Box<dyn std::error::Error>> {
    let s = load_scene(path.to_str().unwrap(), None)?;
    let cfgs = stage_configs(&s)?;
    unitac_pipeline::build_stage(&s, cfgs.last().unwrap().clone())?;
    Ok(())
}

#[test]
fn a_missing_or_wrong_model_is_a_load_error() {
    let models = PathBuf::from(std::env::var_os("UNITAC_MODELS").unwrap());
    // The fitted model loads for the latent it was fitted on.
    let real = models.join("policy/cup_stiffness_real/manifest.json");
    build_policy(&with_model(
        "stiff_ok",
        "vtla_real",
        3072,
        real.to_str().unwrap(),
    ))
    .unwrap();
    // Missing: the scene does not load.
    let e = refused(&with_model(
        "stiff_missing",
        "vtla_real",
        3072,
        "${UNITAC_MODELS}/policy/no_such_model/manifest.json",
    ));
    assert!(e.contains("no_such_model"), "{e}");
    // Wrong: the real-latent model for the sampler's 64 values.
    let e = refused(&with_model(
        "stiff_wrong_len",
        "vtla_pred",
        64,
        real.to_str().unwrap(),
    ));
    assert!(
        e.contains("stiffness model")
            && e.contains(
                "input observation.tactile_latent has 3072 values, the scene's latent_len is 64"
            ),
        "{e}"
    );
    assert!(!e.contains('\n'), "{e}");
    // Wrong: a bundle that is no stiffness model (the reference encoder's manifest is no
    // policy manifest at all).
    let e = refused(&with_model(
        "stiff_not_policy",
        "vtla_real",
        3072,
        "${UNITAC_MODELS}/reference/manifest.json",
    ));
    assert!(e.contains("stiffness model"), "{e}");
}

/// A cup VLA scene whose policy stage is `policy: learned` with `models` (`""`: none), the
/// camera's `visual` names and the `extra` params (`, key: value`).
fn learned(name: &str, model: &str, visual: &str, extra: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("unitac-policy-scenes-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(format!("{name}.yaml"));
    let (models, names) = if model.is_empty() {
        (String::new(), String::new())
    } else {
        (
            format!("models:\n  policy: {model}\n"),
            "    models: [policy]\n".to_string(),
        )
    };
    std::fs::write(
        &path,
        format!(
            "scene: {name}\nsource: {{kind: mock, sensor: gelsight-mini, scenario: cup_deformation}}\n\
             {models}stages:\n  - kind: policy\n{names}    params: {{policy: learned, mode: vla, \
             task: squeeze the cup by 1 cm, objects: [cup], visual_names: [{visual}], max_opening_m: 0.11{extra}}}\n"
        ),
    )
    .unwrap();
    path
}

#[test]
fn a_learned_policy_loads_only_a_bundle_that_fits_the_scene() {
    let all = "cup_x_m, cup_y_m, cup_z_m, cup_width_m, cup_height_m";
    let bundle = "${UNITAC_MODELS}/learned/seed0/cup_deformation_vla/manifest.json";
    build_policy(&learned("learned_ok", bundle, all, "")).unwrap();
    let e = refused(&learned("learned_none", "", all, ""));
    assert!(e.contains("a learned policy needs its bundle"), "{e}");
    // The scripted scene's camera names: the network reads five, in the demonstrations' order.
    let e = refused(&learned(
        "learned_names",
        bundle,
        "cup_x_m, cup_y_m, cup_width_m",
        "",
    ));
    assert!(e.contains("observation.visual reads"), "{e}");
    // A stiffness readout is no learned policy: every problem in one line.
    let e = refused(&learned(
        "learned_readout",
        "${UNITAC_MODELS}/policy/cup_stiffness_real/manifest.json",
        all,
        "",
    ));
    assert!(
        e.contains("no action 'gripper.position_m'") && !e.contains('\n'),
        "{e}"
    );
    // A scene holding the force lower than the demonstrations' scene: the network's range is
    // beyond the safety layer's.
    let e = refused(&learned(
        "learned_force",
        bundle,
        all,
        ", max_force_n: 30.0",
    ));
    assert!(
        e.contains(
            "action 'gripper.force_n' ranges [0, 40], beyond the scene's safety bounds [0, 30]"
        ),
        "{e}"
    );
}

/// A policy waits only for what its scene makes: for every shipped scene with a policy stage
/// (scripted and learned), each input the built stage awaits at start comes from outside (the
/// gripper, the camera) or from a stage of that scene, so a transport watching the producers
/// never holds for a topic nothing in the scene publishes. (A learned VTLA-real cup policy's
/// model has a comparison slot, which stays zero: the cup scene has no compare stage.)
#[test]
fn a_policy_awaits_only_inputs_its_scene_produces() {
    let mut checked = 0;
    for name in unitac_pipeline::scene_names(None) {
        let s = load_scene(&name, None).unwrap();
        let kinds: Vec<&str> = s.stages.iter().map(|st| st.kind.as_str()).collect();
        if !kinds.contains(&"policy") {
            continue;
        }
        let stages = unitac_pipeline::build_stages(&s).unwrap();
        let policy = stages.last().unwrap();
        let awaited = policy.awaited_inputs();
        assert!(awaited.contains(&"gripper"), "{name}: {awaited:?}");
        for input in awaited {
            let spec = unitac_policy::observation::input(input).unwrap();
            if let Some(producer) = spec.produced_by {
                assert!(
                    kinds.contains(&producer),
                    "{name}: awaits {input}, made by a {producer} stage it does not have"
                );
            }
        }
        checked += 1;
    }
    assert_eq!(checked, 12);
}
