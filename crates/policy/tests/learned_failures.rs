//! A learned policy that fails is never silent, and a bundle that would fail is refused at load:
//! - a model that returns NaN on every tick gives the safe action on every tick, and every one
//!   is counted as a policy error (`TickCounts`, from the ticks' PolicyStatus);
//! - a std below float32's smallest normal (1e-45 passes "> 0") is a load error, and a finite
//!   input that normalisation still takes out of range fails its tick with a typed error;
//! - a control rate outside [0.1, 1000] Hz is a load error, and so is a policy rate other than
//!   the scene's;
//! - an inference past its time limit is stopped: the tick returns with the safe action, is
//!   counted as over budget, and a model within its budget gives the same bytes with the limit.
//!
//! The bundles are the stubs of tests/make_stub_policy.py (the learned cup VLA policy's inputs
//! and actions), generated here with the project's Python.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;
mod rig;

use std::path::{Path, PathBuf};
use std::time::Duration;
use unitac_core::Stamp;
use unitac_policy::onnx::{
    ActionChunk, Mismatch, NamedInputs, OnnxPolicy, RunError, RuntimeConfig,
};
use unitac_policy::{PolicyParams, PolicyStage, TickCounts, TickKind};

fn stub(name: &str, args: &[&str]) -> PathBuf {
    let d = common::tmpdir(name);
    let st = std::process::Command::new(common::python())
        .arg(common::root().join("crates/policy/tests/make_stub_policy.py"))
        .arg(&d)
        .args(args)
        .status()
        .unwrap();
    assert!(st.success(), "make_stub_policy.py failed");
    d
}

/// The learned cup VLA scene's policy params (launch/scenes/cup_deformation_learned_vla.yaml).
fn params(extra: &str) -> PolicyParams {
    rig::params(&format!(
        "policy: learned\nmode: vla\ntask: squeeze the cup by 1 cm\nobjects: [cup]\n\
         visual_names: [cup_x_m, cup_y_m, cup_z_m, cup_width_m, cup_height_m]\n\
         max_opening_m: 0.11\napproach_s: 1.5\nrun_s: 10\n{extra}"
    ))
}

fn rig(dir: &Path, p: PolicyParams) -> rig::Rig {
    let stage = PolicyStage::load("stub_scene", p, Some(dir)).unwrap();
    let mut r = rig::Rig::with_stage(stage);
    r.camera = Some((
        [
            "cup_x_m",
            "cup_y_m",
            "cup_z_m",
            "cup_width_m",
            "cup_height_m",
        ]
        .map(String::from)
        .to_vec(),
        vec![0.45, 0.0, 0.04, 0.08, 0.1],
    ));
    r
}

/// The policy's act on `state`, with the cup's visual features at 0.1 and the latched and arm
/// inputs at 0.
fn act(p: &mut OnnxPolicy, state: &[f32; 8], t: Stamp) -> Result<ActionChunk, RunError> {
    let (visual, two) = ([0.1f32; 5], [0.0f32; 2]);
    let named = NamedInputs::new()
        .with("observation.state", state)
        .with("observation.visual", &visual)
        .with("observation.latched", &two)
        .with("observation.arm", &two);
    p.act(&named, t)
}

fn counts(r: &rig::Rig) -> TickCounts {
    let mut c = TickCounts::default();
    for t in &r.ticks {
        c.count(&t.status);
    }
    c
}

#[test]
fn a_policy_that_returns_nan_on_every_tick_is_counted_on_every_tick() {
    let dir = stub("nan", &["--kind", "nan"]);
    let mut r = rig(&dir, params(""));
    for _ in 0..10 {
        let t = r.tick();
        assert!(!t.status.safety_ok, "{:?}", t.status);
        assert!(
            t.status.message.starts_with("policy: learned policy: ")
                && t.status.message.contains("NaN"),
            "{}",
            t.status.message
        );
        assert_eq!(TickKind::of(&t.status), TickKind::PolicyError);
    }
    let c = counts(&r);
    assert_eq!(
        (c.ticks, c.acted, c.policy_error, c.failed()),
        (10, 0, 10, 10)
    );
    assert!(c.never_acted());
    assert!(c.first_failure.unwrap().contains("NaN"));
    // The same stub with finite actions acts on every tick.
    let dir = stub("ok", &["--kind", "ok"]);
    let mut r = rig(&dir, params(""));
    for _ in 0..10 {
        r.tick();
    }
    let c = counts(&r);
    assert_eq!((c.ticks, c.acted, c.failed()), (10, 10, 0), "{c:?}");
}

#[test]
fn a_std_below_the_smallest_normal_float_is_refused_at_load() {
    for std in ["1e-45", "0"] {
        let dir = stub(&format!("std{std}"), &["--kind", "ok", "--input-std", std]);
        let p = common::mismatches(&dir);
        assert!(
            p.iter().any(|m| matches!(
                m,
                Mismatch::StdNotPositive { tensor, index: 0, .. } if tensor == "observation.state"
            )),
            "std {std}: {p:?}"
        );
    }
    // At the floor it loads; an input that still normalises out of range fails its tick.
    let dir = stub("stdmin", &["--kind", "ok", "--input-std", "1.2e-38"]);
    let mut p = OnnxPolicy::load(&dir, &RuntimeConfig::default()).unwrap();
    match act(&mut p, &[100.0; 8], Stamp(0)) {
        Err(e @ RunError::NonFiniteFeature { index: 0, .. }) => {
            assert!(e.to_string().contains("normalises to inf"), "{e}");
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn a_control_rate_out_of_range_or_unlike_the_scenes_is_refused_at_load() {
    for rate in ["1e-12", "0.05", "5000"] {
        let dir = stub(&format!("rate{rate}"), &["--kind", "ok", "--rate", rate]);
        let p = common::mismatches(&dir);
        assert!(
            p.iter().any(|m| matches!(m, Mismatch::ControlRate(_))),
            "rate {rate}: {p:?}"
        );
        assert!(
            p.iter()
                .any(|m| m.to_string().contains("within [0.1, 1000]")),
            "{p:?}"
        );
    }
    // 10 Hz is a valid rate, but not the 30 Hz scene's.
    let dir = stub("rate10", &["--kind", "ok", "--rate", "10"]);
    let e = PolicyStage::load("stub_scene", params(""), Some(&dir)).unwrap_err();
    assert!(
        e.to_string()
            .contains("the policy runs at control_rate_hz 10, the scene at 30"),
        "{e}"
    );
    // The same policy in a 10 Hz scene loads.
    PolicyStage::load("stub_scene", params("control_rate_hz: 10\n"), Some(&dir)).unwrap();
}

#[test]
fn an_inference_over_its_budget_gives_the_safe_action_and_the_tick_returns() {
    // About 2 us per iteration: minutes per call without a limit.
    let dir = stub("loop", &["--kind", "loop", "--iterations", "100000000"]);
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let mut r = rig(&dir, params("inference_budget_s: 0.005\n"));
        for _ in 0..3 {
            let t = r.tick();
            tx.send(t.status).unwrap();
        }
    });
    for _ in 0..3 {
        let s = rx
            .recv_timeout(Duration::from_secs(30))
            .expect("a tick with a looping model did not return");
        assert!(!s.safety_ok, "{s:?}");
        assert!(
            s.message
                .starts_with("policy: inference over budget: learned policy stub_loop@"),
            "{}",
            s.message
        );
        assert!(s.message.contains("budget of 5.0 ms"), "{}", s.message);
        assert_eq!(TickKind::of(&s), TickKind::OverBudget);
    }
}

#[test]
fn the_default_budget_is_three_control_periods_and_within_it_the_bytes_are_the_same() {
    assert_eq!(params("").inference_budget(), Duration::from_millis(100));
    assert_eq!(
        params("control_rate_hz: 100\n").inference_budget(),
        Duration::from_millis(30)
    );
    assert_eq!(
        params("inference_budget_s: 0.25\n").inference_budget(),
        Duration::from_millis(250)
    );
    let e = params("inference_budget_s: 60\n").check().unwrap_err();
    assert!(
        e.to_string()
            .contains("inference_budget_s = 60 is outside [0.001, 10]"),
        "{e}"
    );
    let dir = stub("short", &["--kind", "loop", "--iterations", "1000"]);
    let run = |budget: Option<Duration>| {
        let mut p = OnnxPolicy::load(&dir, &RuntimeConfig::default()).unwrap();
        p.set_budget(budget);
        (0..5)
            .map(|i| {
                let c = act(&mut p, &[0.01 * i as f32; 8], Stamp(i * 33_333_333)).unwrap();
                c.data.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
            })
            .collect::<Vec<_>>()
    };
    assert_eq!(run(None), run(Some(Duration::from_secs(1))));
}
