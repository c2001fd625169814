//! The Rust ONNX policy runtime against an independent oracle: Python onnxruntime for the model
//! and numpy for normalisation, unnormalisation, clamping, chunk scheduling and ACT temporal
//! ensembling (tests/policy/policy_oracle.py), on the same observations and stamps.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;
use unitac_policy::onnx::ActionChunk;

/// Largest difference accepted, as a fraction of each action's bound range. The model runs
/// bit-identically in both; normalisation is the same float32 operations; ensembling
/// accumulates in float64 on both sides, so only the summation order may differ (measured: 0,
/// printed by `cargo test -p unitac-policy --test onnx_oracle -- --nocapture`).
const TOLERANCE: f64 = 1e-6;

struct Run {
    plans: Vec<Vec<Vec<f64>>>,
    inferred: Vec<bool>,
    clamped: Vec<usize>,
}

fn rust(dir: &std::path::Path, n: usize) -> (Run, Vec<ActionChunk>) {
    let mut p = common::load(dir);
    let mut chunks = Vec::new();
    for (i, t) in common::stamps(n).into_iter().enumerate() {
        let obs = common::Obs::new(i as u64 + 1);
        chunks.push(p.act(&obs.inputs(), t).unwrap());
    }
    let run = Run {
        plans: chunks
            .iter()
            .map(|c| {
                (0..c.rows())
                    .map(|r| c.row(r).unwrap().iter().map(|&v| f64::from(v)).collect())
                    .collect()
            })
            .collect(),
        inferred: chunks.iter().map(|c| c.inferred).collect(),
        clamped: chunks.iter().map(|c| c.clamped).collect(),
    };
    (run, chunks)
}

fn python(dir: &std::path::Path, n: usize) -> Run {
    let ticks: Vec<serde_json::Value> = common::stamps(n)
        .into_iter()
        .enumerate()
        .map(
            |(i, t)| serde_json::json!({"t": t.0, "inputs": common::Obs::new(i as u64 + 1).json()}),
        )
        .collect();
    let v = common::run_oracle(dir, ticks, dir);
    Run {
        plans: serde_json::from_value(v["plans"].clone()).unwrap(),
        inferred: serde_json::from_value(v["inferred"].clone()).unwrap(),
        clamped: serde_json::from_value(v["clamped"].clone()).unwrap(),
    }
}

/// Compare both runs; returns the largest relative difference.
fn compare(name: &str, dir: &std::path::Path, n: usize) -> (f64, Vec<ActionChunk>) {
    let (ours, chunks) = rust(dir, n);
    let theirs = python(dir, n);
    assert_eq!(ours.inferred, theirs.inferred, "{name}: inference ticks");
    assert_eq!(ours.clamped, theirs.clamped, "{name}: clamped counts");
    let range = [0.085, 0.13, 215.0];
    let mut worst = 0f64;
    for (tick, (a, b)) in ours.plans.iter().zip(&theirs.plans).enumerate() {
        assert_eq!(a.len(), b.len(), "{name}: plan length at tick {tick}");
        for (ra, rb) in a.iter().zip(b) {
            for (j, (x, y)) in ra.iter().zip(rb).enumerate() {
                // The oracle's float32 values come back through JSON as float64 text;
                // rounding them to float32 undoes the parser's last-bit error.
                let y = f64::from(*y as f32);
                worst = worst.max((x - y).abs() / range[j]);
            }
        }
    }
    println!("{name}: largest difference to the oracle {worst:.3e} of the bound range");
    assert!(worst <= TOLERANCE, "{name}: {worst} > {TOLERANCE}");
    (worst, chunks)
}

#[test]
fn chunks_of_k_rows_match_the_oracle() {
    let dir = common::make_policy("oracle-plain", &[]);
    let (_, chunks) = compare("plain k=4", &dir, 20);
    // Not vacuous: inference every 4 ticks (the 7th stamp is missed, so one chunk runs 3
    // rows), values clamped somewhere, and every value within bounds.
    let inferred: Vec<usize> = (0..chunks.len()).filter(|&i| chunks[i].inferred).collect();
    assert_eq!(inferred, [0, 4, 7, 11, 15, 19]);
    assert!(chunks.iter().map(|c| c.clamped).sum::<usize>() > 0);
    let bounds = [(0.0, 0.085), (0.02, 0.15), (20.0, 235.0)];
    for c in &chunks {
        for (i, v) in c.data.iter().enumerate() {
            let (lo, hi) = bounds[i % 3];
            assert!(v.is_finite() && *v >= lo && *v <= hi, "{v}");
        }
    }
}

#[test]
fn temporal_ensembling_matches_the_oracle() {
    for (m, k) in [(0.1, 1), (0.01, 2), (0.0, 3)] {
        let dir = common::make_policy(&format!("oracle-ens-{k}"), &[]);
        common::edit(&dir, |j| {
            j["temporal_ensemble_coeff"] = m.into();
            j["n_action_steps"] = k.into();
        });
        let (_, ens) = compare(&format!("ensemble m={m} k={k}"), &dir, 20);
        // The ensemble is not the newest chunk alone: the same policy without ensembling
        // executes different actions.
        common::edit(&dir, |j| {
            j["temporal_ensemble_coeff"] = serde_json::Value::Null
        });
        let (_, plain) = rust(&dir, 20);
        let differs = ens
            .iter()
            .zip(&plain)
            .skip(1)
            .any(|(a, b)| a.row(0) != b.row(0));
        assert!(differs, "m={m} k={k}: ensembling changed nothing");
    }
}
