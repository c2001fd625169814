//! The ONNX policy at run time: bad observations and a failing model give typed errors and no
//! action (never a NaN), nothing is committed on an error, and the same inputs and stamps give
//! the same output bytes.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;
use unitac_core::Stamp;
use unitac_policy::onnx::{NamedInputs, RunError};

#[test]
fn missing_short_and_non_finite_inputs_are_typed_errors() {
    let dir = common::make_policy("run-inputs", &[]);
    let mut p = common::load(&dir);
    let obs = common::Obs::new(1);
    let t = Stamp(1_000_000_000);

    let without = NamedInputs::new()
        .with("observation.state", &obs.state)
        .with("observation.images.wrist", &obs.image);
    let e = p.act(&without, t).unwrap_err();
    assert!(
        matches!(&e, RunError::MissingInput { name, .. } if name == "observation.tactile_latent"),
        "{e}"
    );

    let short = obs.inputs().with("observation.state", &obs.state[..5]);
    assert!(matches!(
        p.act(&short, t).unwrap_err(),
        RunError::InputLength {
            got: 5,
            expected: 6,
            ..
        }
    ));

    let mut latent = obs.latent.clone();
    latent[3] = f32::NAN;
    let bad = obs.inputs().with("observation.tactile_latent", &latent);
    assert!(matches!(
        p.act(&bad, t).unwrap_err(),
        RunError::NonFiniteInput { index: 3, .. }
    ));

    // Features the policy does not read are ignored; nothing above was committed, so this is
    // still the first tick and runs the model.
    let extra = [1.0f32, 2.0];
    let c = p
        .act(&obs.inputs().with("observation.task", &extra), t)
        .unwrap();
    assert!(c.inferred);
    assert_eq!(c.rows(), 8);

    // Inputs are checked on ticks without inference too.
    let t1 = Stamp(t.0 + p.period_ns());
    assert!(matches!(
        p.act(&bad, t1).unwrap_err(),
        RunError::NonFiniteInput { .. }
    ));
    let c = p.act(&obs.inputs(), t1).unwrap();
    assert!(!c.inferred);
    assert_eq!(c.rows(), 7);
}

#[test]
fn a_model_that_returns_nan_gives_an_error_and_no_action() {
    let dir = common::make_policy("run-nan", &["--nan-below-mean"]);
    let mut p = common::load(&dir);
    let mean0 = {
        let m: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(dir.join("manifest.json")).unwrap())
                .unwrap();
        m["inputs"][0]["normalization"]["mean"][0].as_f64().unwrap() as f32
    };
    let mut obs = common::Obs::new(2);
    let t = Stamp(0);
    obs.state[0] = mean0 - 0.01;
    let e = p.act(&obs.inputs(), t).unwrap_err();
    assert!(
        matches!(&e, RunError::NonFiniteAction { row: 0, action, value } if action == "gripper.opening" && value.is_nan()),
        "{e}"
    );
    // The failed inference committed nothing: the same tick with a good observation works,
    // as the first tick.
    obs.state[0] = mean0 + 0.01;
    let c = p.act(&obs.inputs(), t).unwrap();
    assert!(c.inferred && c.data.iter().all(|v| v.is_finite()));
}

#[test]
fn time_going_back_is_an_error_until_reset() {
    let dir = common::make_policy("run-time", &[]);
    let mut p = common::load(&dir);
    let obs = common::Obs::new(3);
    p.act(&obs.inputs(), Stamp(10 * p.period_ns())).unwrap();
    p.act(&obs.inputs(), Stamp(12 * p.period_ns())).unwrap();
    // Half a period back still rounds to the same tick: the same plan again.
    let again = p
        .act(&obs.inputs(), Stamp(12 * p.period_ns() - p.period_ns() / 3))
        .unwrap();
    assert!(!again.inferred);
    assert_eq!(again.rows(), 6);
    assert!(matches!(
        p.act(&obs.inputs(), Stamp(11 * p.period_ns())).unwrap_err(),
        RunError::TimeWentBack(_)
    ));
    p.reset();
    let c = p.act(&obs.inputs(), Stamp(0)).unwrap();
    assert!(c.inferred && c.rows() == 8);
}

#[test]
fn same_inputs_and_stamps_give_the_same_bytes() {
    let dir = common::make_policy("run-determinism", &[]);
    common::edit(&dir, |m| {
        m["temporal_ensemble_coeff"] = 0.05.into();
        m["n_action_steps"] = 2.into();
    });
    let bytes = || {
        let mut p = common::load(&dir);
        let mut out = Vec::new();
        for (i, t) in common::stamps(15).into_iter().enumerate() {
            let obs = common::Obs::new(i as u64 + 10);
            let c = p.act(&obs.inputs(), t).unwrap();
            out.extend(c.data.iter().flat_map(|v| v.to_le_bytes()));
            out.extend(c.start.0.to_le_bytes());
            out.push(u8::from(c.inferred));
        }
        out
    };
    let a = bytes();
    assert!(a.len() > 15 * 3 * 4);
    assert_eq!(a, bytes());
}
