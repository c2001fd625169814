//! The sampler through ONNX Runtime: exact Gaussian oracle, guards on a NaN model.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;
use unitac_infer::flow::{
    Guards, OnnxVelocity, SampleConfig, Solver, exact_gaussian, noise, sample,
};
use unitac_infer::{Bundle, RuntimeConfig};

fn gaussian() -> OnnxVelocity {
    let m = Bundle::open(&common::reference())
        .unwrap()
        .load(&["velocity_gaussian"], &RuntimeConfig::default())
        .unwrap();
    OnnxVelocity::new(m.into_iter().next().unwrap()).unwrap()
}

fn rms_error(v: &mut OnnxVelocity, solver: Solver, steps: u32, s: f64) -> f64 {
    let d = 64;
    let mu: Vec<f32> = (0..d).map(|i| ((i as f32) * 0.61).cos()).collect();
    let cp: Vec<f32> = vec![0.0; d + 1];
    let cc: Vec<f32> = mu.iter().copied().chain([(0.4f32).ln()]).collect();
    let cfg = SampleConfig {
        solver,
        steps,
        guidance: s,
        seed: 5,
        batched: true,
    };
    let out = sample(v, &cfg, &Guards::new(0.1), &cp, &cc).unwrap();
    assert!(out.valid, "{}", out.report);
    let z = noise(5, d);
    let e2: f64 = (0..d)
        .map(|i| {
            (f64::from(out.x[i])
                - exact_gaussian(f64::from(z[i]), 0.0, 1.0, f64::from(mu[i]), 0.4, s))
            .powi(2)
        })
        .sum();
    (e2 / d as f64).sqrt()
}

#[test]
fn onnx_gaussian_converges_at_the_solver_orders() {
    let mut v = gaussian();
    for s in [1.0, 1.5] {
        let (e1, e2) = (
            rms_error(&mut v, Solver::Euler, 32, s),
            rms_error(&mut v, Solver::Euler, 64, s),
        );
        let p = (e1 / e2).log2();
        assert!((0.8..1.25).contains(&p), "euler s={s}: {p}");
        let (e1, e2) = (
            rms_error(&mut v, Solver::Heun, 32, s),
            rms_error(&mut v, Solver::Heun, 64, s),
        );
        let p = (e1 / e2).log2();
        assert!(
            (1.75..2.3).contains(&p),
            "heun s={s}: {p} ({e1:.2e} {e2:.2e})"
        );
    }
}

#[test]
fn a_nan_model_is_caught_and_not_valid() {
    let dir = common::copy_reference("nan");
    let st = std::process::Command::new(common::python())
        .arg(common::root().join("tests/infer/make_fixtures.py"))
        .arg(&dir)
        .status()
        .unwrap();
    assert!(st.success());
    // Declare it as the bundle's velocity model.
    let p = dir.join("manifest.json");
    let mut m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&p).unwrap()).unwrap();
    m["models"]["velocity_gaussian"]["file"] = "velocity_nan.onnx".into();
    m["models"]["velocity_gaussian"]["sha256"] =
        unitac_infer::bundle::sha256_file(&dir.join("velocity_nan.onnx"))
            .unwrap()
            .into();
    std::fs::write(&p, m.to_string()).unwrap();
    let model = Bundle::open(&dir)
        .unwrap()
        .load(&["velocity_gaussian"], &RuntimeConfig::default())
        .unwrap();
    let mut v = OnnxVelocity::new(model.into_iter().next().unwrap()).unwrap();
    let cfg = SampleConfig {
        solver: Solver::Heun,
        steps: 8,
        guidance: 1.5,
        seed: 1,
        batched: true,
    };
    let out = sample(
        &mut v,
        &cfg,
        &Guards::new(0.1),
        &vec![0.0; 65],
        &vec![0.0; 65],
    )
    .unwrap();
    assert!(!out.valid);
    assert!(
        out.report.starts_with("non-finite state at step 1"),
        "{}",
        out.report
    );
}
