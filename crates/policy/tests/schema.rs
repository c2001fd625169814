//! schema/policy.json is the one definition of the policies' layout: the Rust stages that fill
//! it and the Python side that reads it (python/unitac_tools/schema.py, which the dataset writer and
//! the trainers import) both agree with it.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use serde_json::{Value, json};
use std::process::Command;
use unitac_core::msg::{Msg, samples};
use unitac_policy::observation::{INPUTS, Layout};
use unitac_policy::schema::*;
use unitac_policy::{Action, ArmAction, GripperAction, Mode};

fn python_view() -> Value {
    let out = Command::new(common::python())
        .args(["-m", "unitac_tools.schema"])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

#[test]
fn python_reads_what_rust_generated() {
    let py = python_view();
    let fixed = json!({
        STATE: STATE_NAMES, LATCHED: LATCHED_NAMES, ARM: ARM_NAMES, CONTACT: CONTACT_NAMES,
        COMPARISON: COMPARISON_NAMES,
    });
    assert_eq!(py["fixed"], fixed);
    let keys: Vec<&str> = py["features"]
        .as_object()
        .unwrap()
        .keys()
        .map(String::as_str)
        .collect();
    let mut rust = FEATURES.to_vec();
    rust.sort_unstable();
    let mut keys = keys;
    keys.sort_unstable();
    assert_eq!(keys, rust);
    assert_eq!(py["modes"], json!(MODES));
    let learned: serde_json::Map<String, Value> = LEARNED_FEATURES
        .iter()
        .map(|(m, f)| (m.to_string(), json!(f)))
        .collect();
    assert_eq!(py["learned_features"], Value::Object(learned));
    assert_eq!(py["dataset_features"], json!(DATASET_FEATURES));
    assert_eq!(py["action"], ACTION);
    assert_eq!(py["commands"], json!(COMMANDS));
    assert_eq!(py["units"], json!(COMMAND_UNITS));
    assert_eq!(py["arm_target"], ARM_TARGET);
    assert_eq!(py["arm_target_prefix"], ARM_TARGET_PREFIX);
    assert_eq!(py["arm_target_unit"], ARM_TARGET_UNIT);
    assert_eq!(py["far_fraction"].as_f64().unwrap() as f32, FAR_FRACTION);
    assert_eq!(py["max_since_target_s"], json!(MAX_SINCE_TARGET_S));
    assert_eq!(
        py["stiffness"],
        json!({"input": STIFFNESS_INPUT, "action": STIFFNESS_ACTION, "unit": STIFFNESS_UNIT,
               "min": STIFFNESS_MIN_N_PER_M, "max": STIFFNESS_MAX_N_PER_M,
               "prior": STIFFNESS_PRIOR_N_PER_M})
    );
    assert_eq!(
        py["manifest"],
        json!({"file": MANIFEST_FILE, "output": OUTPUT, "dtype": DTYPE})
    );
}

#[test]
fn the_stage_inputs_fill_the_schemas_features_with_its_widths() {
    // Every input of the observation table is in the schema, and the other way round.
    let mut table: Vec<(&str, &str)> = INPUTS.iter().map(|i| (i.name, i.feature())).collect();
    let mut schema = STAGE_INPUTS.to_vec();
    table.sort_unstable();
    schema.sort_unstable();
    assert_eq!(table, schema);
    // Each fixed-width input writes as many values as the schema names.
    let layout = Layout {
        latent_len: samples::tactile_latent().data.len(),
        visual_names: samples::visual_observation().names,
        stroke_m: None,
    };
    let sample = |name: &str| match name {
        "gripper" => Msg::GripperStatus(unitac_core::msg::GripperStatus {
            fault: String::new(),
            ..samples::gripper_status()
        }),
        "contact" => Msg::ContactState(samples::contact_state()),
        "comparison" => Msg::PropertyComparison(samples::property_comparison()),
        "visual" => Msg::VisualObservation(samples::visual_observation()),
        _ => Msg::TactileLatent(samples::tactile_latent()),
    };
    let want = |key: &str| match key {
        STATE => STATE_LEN,
        CONTACT => CONTACT_LEN,
        COMPARISON => COMPARISON_LEN,
        VISUAL => layout.visual_names.len(),
        LATENT => layout.latent_len,
        other => panic!("a stage input fills {other}"),
    };
    for spec in INPUTS {
        let m = sample(spec.name);
        if !(spec.accepts)(&m) {
            continue; // the predicted latent: the sample is a live one
        }
        let mut out = Vec::new();
        (spec.features)(&m, &layout, &mut out).unwrap();
        assert_eq!(out.len(), want(spec.feature()), "{}", spec.name);
        assert_eq!((spec.width)(&layout), want(spec.feature()), "{}", spec.name);
    }
}

#[test]
fn modes_actions_and_the_learned_memory_follow_the_schema() {
    assert_eq!(Mode::names(), MODES);
    for m in Mode::ALL {
        for fabric in [false, true] {
            let inputs = m.inputs(fabric);
            assert!(
                inputs.contains(&"gripper") && inputs.contains(&"visual"),
                "{m} {inputs:?}"
            );
            assert!(inputs.iter().all(|i| input_feature(i).is_some()));
        }
        assert!(learned_features(m.as_str()).is_some(), "{m}");
    }
    let a = Action {
        gripper: GripperAction {
            mode: unitac_core::msg::GripperMode::Position,
            position_m: 0.0,
            speed_m_s: 0.0,
            force_n: 0.0,
        },
        arm: ArmAction {
            target: String::new(),
            x_m: 0.0,
            y_m: 0.0,
            z_m: 0.0,
            lift_m: 0.0,
        },
        note: String::new(),
    };
    let names: Vec<&str> = a.values().iter().map(|(n, _)| *n).collect();
    assert_eq!(names, COMMANDS);
    // The learned policy's memory holds the schema's features at their widths.
    let m = unitac_policy::learned::Memory::new(&["a".into(), "b".into()], 4, 1.0);
    for (key, v) in m.features() {
        let want = match key {
            LATCHED => LATCHED_LEN,
            CONTACT => CONTACT_LEN,
            COMPARISON => COMPARISON_LEN,
            LATENT_REAL | LATENT_PRED => 2 * (4 + 1),
            other => panic!("the memory holds {other}, not in the schema"),
        };
        assert_eq!(v.len(), want, "{key}");
    }
    assert_eq!(m.arm(0.0).len(), ARM_LEN);
}
