//! The fitted latent -> stiffness readouts as the controllers run them (`Readout`) against the
//! Python onnxruntime oracle (tests/policy/policy_oracle.py) on the same latents: the real
//! latent's model setup fitted on the expert's demonstrations (python/unitac_tools/fit_reference_policy.py),
//! the touch bundle's pooled-latent model (python/unitac_tools/train_projector.py), and one fitted here on synthetic demonstrations with a known linear law, which
//! the fit must recover.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;
mod rig;
use std::path::{Path, PathBuf};
use std::process::Command;
use unitac_core::Msg;
use unitac_core::Stamp;
use unitac_core::msg::{LatentSource, TactileLatent, samples};
use unitac_policy::PolicyParams;
use unitac_policy::readout::Readout;

/// Largest difference accepted \[N/m]: both run the same float32 graph on the same float32
/// normalisation (measured: 0, printed with --nocapture).
const TOLERANCE_N_PER_M: f64 = 1e-3;

fn latent(shape: [u32; 2], seed: u64, offset: f32) -> TactileLatent {
    let n = (shape[0] * shape[1]) as usize;
    TactileLatent {
        source: LatentSource::Real,
        shape: shape.to_vec(),
        data: unitac_infer::flow::noise(seed, n)
            .iter()
            .map(|v| v + offset)
            .collect(),
        ..samples::tactile_latent()
    }
}

/// Rust readout and oracle on the same latents: (ours, theirs) in N/m.
fn both(dir: &Path, latents: &[TactileLatent]) -> (Vec<f64>, Vec<f64>) {
    let len = latents[0].data.len();
    let mut r = Readout::load(dir, len).unwrap();
    let p = PolicyParams::default();
    let stamp = |i: usize| Stamp(1_000_000_000 + (i as i64) * 33_333_333);
    let ours: Vec<f64> = latents
        .iter()
        .enumerate()
        .map(|(i, l)| r.stiffness(&p, l, stamp(i)).unwrap().0)
        .collect();
    let ticks: Vec<serde_json::Value> = latents
        .iter()
        .enumerate()
        .map(|(i, l)| {
            serde_json::json!({"t": stamp(i).0, "inputs": {"observation.tactile_latent": l.data}})
        })
        .collect();
    let tmp = common::tmpdir(&format!("stiffness-oracle-{len}"));
    let v = common::run_oracle(dir, ticks, &tmp);
    let plans: Vec<Vec<Vec<f64>>> = serde_json::from_value(v["plans"].clone()).unwrap();
    let theirs = plans
        .iter()
        .map(|p| f64::from(p[0][0] as f32)) // JSON text back to the float32 it was
        .collect();
    (ours, theirs)
}

fn worst(name: &str, ours: &[f64], theirs: &[f64]) -> f64 {
    assert_eq!(ours.len(), theirs.len());
    let w = ours
        .iter()
        .zip(theirs)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    let (lo, hi) = ours
        .iter()
        .fold((f64::MAX, f64::MIN), |(a, b), &k| (a.min(k), b.max(k)));
    println!(
        "{name}: largest difference to the oracle {w:.3e} N/m over {} latents ({lo:.1} to {hi:.1} N/m)",
        ours.len()
    );
    w
}

#[test]
fn the_setup_fitted_models_match_the_oracle() {
    let models =
        PathBuf::from(std::env::var_os("UNITAC_MODELS").expect("UNITAC_MODELS (scripts/env.sh)"));
    // Each readout on latents like its training ones: their mean + 0.5 std x noise, the same
    // draw in every row so the pooled vector varies as theirs does. The real latent's statistics
    // are its input normalisation; the pooled latent's come with the touch bundle's readout.
    let json = |p: PathBuf| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
    };
    let stat = |v: &serde_json::Value| -> Vec<f64> { serde_json::from_value(v.clone()).unwrap() };
    let real = models.join("policy/cup_stiffness_real");
    let m = json(real.join("manifest.json"));
    let n = &m["inputs"][0]["normalization"];
    let pooled = models.join("touch/stiffness");
    let c = json(pooled.join("latents.json"));
    for (name, dir, shape, mean, std) in [
        (
            "cup_stiffness_real",
            real.clone(),
            [64, 48],
            stat(&n["mean"]),
            stat(&n["std"]),
        ),
        (
            "touch/stiffness",
            pooled,
            [2, 48],
            stat(&c["mean"]),
            stat(&c["std"]),
        ),
    ] {
        let latents: Vec<TactileLatent> = (0..12)
            .map(|i| {
                let dim = shape[1] as usize;
                let noise = unitac_infer::flow::noise(40 + i, dim);
                let mut l = latent(shape, 0, 0.0);
                for (j, v) in l.data.iter_mut().enumerate() {
                    *v = (mean[j] + 0.5 * std[j] * f64::from(noise[j % dim])) as f32;
                }
                l
            })
            .collect();
        let (ours, theirs) = both(&dir, &latents);
        assert!(
            worst(name, &ours, &theirs) <= TOLERANCE_N_PER_M,
            "{ours:?} vs {theirs:?}"
        );
        // Inside the bounds, and not pinned to one of them (the comparison is of the model).
        assert!(ours.iter().all(|k| *k > 20.0 && *k < 5000.0), "{ours:?}");
    }
}

/// Synthetic demonstrations: latents [rows, 6] whose row mean carries the stiffness linearly,
/// `k = 500 + 80 z0 - 40 z3`, three cup diameters for the cross-validation.
fn law(l: &TactileLatent) -> f64 {
    let mean = |j: usize| {
        l.data
            .iter()
            .skip(j)
            .step_by(6)
            .map(|&v| f64::from(v))
            .sum::<f64>()
            / 4.0
    };
    500.0 + 80.0 * mean(0) - 40.0 * mean(3)
}

fn synthetic_demos(path: &Path) {
    let mut json = Vec::new();
    for i in 0..30u64 {
        let l = latent([4, 6], 100 + i, 0.0);
        let k = law(&l);
        let diameter_m = [0.06, 0.065, 0.07][(i % 3) as usize];
        json.push(serde_json::json!({
            "diameter_m": diameter_m,
            "stiffness_n_per_m": k,
            "latents": [{"t_s": 1.0, "touch": 1, "source": "real", "shape": [4, 6], "data": l.data}],
        }));
    }
    std::fs::write(path, serde_json::json!({ "demos": json }).to_string()).unwrap();
}

/// The fit script on the synthetic demonstrations, into a fresh directory.
fn fit_synthetic(name: &str) -> PathBuf {
    let tmp = common::tmpdir(name);
    let train = tmp.join("train.json");
    synthetic_demos(&train);
    let dir = tmp.join("model");
    let st = Command::new(common::python())
        .args(["-m", "unitac_tools.fit_reference_policy"])
        .args(["--train", train.to_str().unwrap(), "--source", "real"])
        .args(["--name", "synthetic", "--out", dir.to_str().unwrap()])
        .stdout(std::process::Stdio::null())
        .status()
        .unwrap();
    assert!(st.success(), "fit_reference_policy.py failed");
    dir
}

#[test]
fn a_fit_recovers_a_linear_law_and_matches_the_oracle() {
    let dir = fit_synthetic("stiffness-fit");
    // New latents, the same law: the readout recovers it (ridge shrinks a little).
    let fresh: Vec<TactileLatent> = (0..10).map(|i| latent([4, 6], 900 + i, 0.0)).collect();
    let truth: Vec<f64> = fresh.iter().map(law).collect();
    let (ours, theirs) = both(&dir, &fresh);
    assert!(worst("synthetic", &ours, &theirs) <= TOLERANCE_N_PER_M);
    let err = ours
        .iter()
        .zip(&truth)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    let spread = truth.iter().cloned().fold(f64::MIN, f64::max)
        - truth.iter().cloned().fold(f64::MAX, f64::min);
    println!("synthetic: largest error to the law {err:.2} N/m (spread {spread:.1} N/m)");
    assert!(spread > 50.0 && err < 0.1 * spread, "{ours:?} vs {truth:?}");
}

#[test]
fn the_cup_controller_squeezes_with_the_models_stiffness() {
    let dir = fit_synthetic("stiffness-stage");
    let p = rig::params(
        "{mode: vtla_pred, task: squeeze the cup by 1 cm, objects: [cup], latent_len: 24, \
         visual_names: [cup_x_m, cup_y_m, cup_width_m]}",
    );
    let stage = unitac_policy::PolicyStage::load("test_scene", p.clone(), Some(&dir)).unwrap();
    let mut rig = rig::Rig::with_stage(stage);
    let data = latent([4, 6], 77, 0.0).data;
    let sent = rig.latent(LatentSource::Predicted, data.clone());
    let Msg::TactileLatent(l) = &sent else {
        panic!("a latent")
    };
    let k = Readout::load(&dir, 24)
        .unwrap()
        .stiffness(&p, l, Stamp(rig.now))
        .unwrap()
        .0;
    assert!((k - law(l)).abs() < 1.0 && (k - 300.0).abs() > 10.0, "{k}");
    rig.send(sent);
    // Close in force mode toward F = k x 1 cm (ramped 2 N per tick).
    let mut close = None;
    for _ in 0..60 {
        let cam = Msg::VisualObservation(unitac_core::msg::VisualObservation {
            header: rig.header(),
            names: vec!["cup_x_m".into(), "cup_y_m".into(), "cup_width_m".into()],
            values: vec![0.45, 0.0, 0.08],
        });
        rig.send(cam);
        let t = rig.tick();
        rig.follow(&t.cmd, None);
        if t.status.phase == "close" {
            close = Some(t);
        }
    }
    let t = close.expect("the controller reached close");
    assert!(t.status.safety_ok, "{t:?}");
    let f = k * 0.01;
    assert!((t.cmd.force_n - f).abs() < 1e-9, "{} vs {f}", t.cmd.force_n);
    assert!(
        t.status.message.contains(&format!("{f:.2} N")),
        "{}",
        t.status.message
    );
}
