//! The time limit of one run: a model that loops past its budget is stopped from the deadline
//! thread and comes back as `InferError::OverBudget` soon after the budget, the session runs
//! again afterwards, and a run within its budget gives the same bytes as one without a budget.
//! The models are the stub policies of crates/policy/tests/make_stub_policy.py (a Loop of N
//! tiny iterations), generated here with the project's Python.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use std::path::PathBuf;
use std::time::{Duration, Instant};
use unitac_infer::runtime::{InferError, RuntimeConfig, Session, TensorF32};

fn stub(name: &str, iterations: u64) -> PathBuf {
    let d = std::env::temp_dir().join(format!("unitac-infer-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    let st = std::process::Command::new(common::python())
        .arg(common::root().join("crates/policy/tests/make_stub_policy.py"))
        .arg(&d)
        .args(["--kind", "loop", "--iterations", &iterations.to_string()])
        .status()
        .unwrap();
    assert!(st.success(), "make_stub_policy.py failed");
    d.join("policy.onnx")
}

fn run(s: &mut Session, budget: Option<Duration>) -> Result<Vec<TensorF32>, InferError> {
    let state = [0.5f32; 8];
    let visual = [0.1f32; 5];
    let two = [0.0f32; 2];
    s.run_f32_within(
        &[
            ("observation.state", &[1, 8], &state),
            ("observation.visual", &[1, 5], &visual),
            ("observation.latched", &[1, 2], &two),
            ("observation.arm", &[1, 2], &two),
        ],
        &["action"],
        budget,
    )
}

#[test]
fn a_run_past_its_budget_is_stopped_and_the_session_runs_again() {
    // About 2 us per iteration: minutes without a limit.
    let long = stub("long", 100_000_000);
    let mut s = Session::open("long", &long, &RuntimeConfig::default()).unwrap();
    let t = Instant::now();
    let e = run(&mut s, Some(Duration::from_millis(50))).unwrap_err();
    let took = t.elapsed();
    match &e {
        InferError::OverBudget {
            budget, elapsed, ..
        } => {
            assert_eq!(*budget, Duration::from_millis(50));
            assert!(*elapsed >= *budget, "{e}");
        }
        other => panic!("not over budget: {other}"),
    }
    assert!(
        e.to_string().contains("ran past its budget of 50.0 ms"),
        "{e}"
    );
    assert!(took < Duration::from_secs(5), "stopped after {took:?}");
    // Again: the flag of the first stop does not end the second run at once, nor leave it
    // running.
    let t = Instant::now();
    assert!(matches!(
        run(&mut s, Some(Duration::from_millis(30))),
        Err(InferError::OverBudget { .. })
    ));
    assert!(t.elapsed() >= Duration::from_millis(30));
    assert!(t.elapsed() < Duration::from_secs(5));
}

#[test]
fn a_run_within_its_budget_gives_the_bytes_of_a_run_without_one() {
    let short = stub("short", 2_000);
    let mut s = Session::open("short", &short, &RuntimeConfig::default()).unwrap();
    let free = run(&mut s, None).unwrap();
    // A budget of 1 ns either stops the run or (when the run ends before the deadline thread
    // gets to it, as it may on a loaded machine) returns it as it came: never other bytes ...
    match run(&mut s, Some(Duration::from_nanos(1))) {
        Err(InferError::OverBudget { .. }) => {}
        Ok(v) => assert_eq!(v, free),
        Err(e) => panic!("{e}"),
    }
    // ... and the next run, within a generous budget, is not stopped and equals the free one.
    for _ in 0..3 {
        let within = run(&mut s, Some(Duration::from_secs(10))).unwrap();
        assert_eq!(within, free);
    }
}
