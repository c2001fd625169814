//! The Rust ort path gives bit-identical outputs to Python onnxruntime on the same inputs.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;
use std::process::Command;
use unitac_infer::{Bundle, RuntimeConfig};

fn inputs(shapes: &[Vec<i64>], seed: u64) -> Vec<Vec<f32>> {
    shapes
        .iter()
        .enumerate()
        .map(|(i, s)| {
            unitac_infer::flow::noise(seed + i as u64, s.iter().product::<i64>() as usize)
        })
        .collect()
}

fn check(model: &str, shapes: Vec<Vec<i64>>) {
    let dir = common::reference();
    let mut m = Bundle::open(&dir)
        .unwrap()
        .load(&[model], &RuntimeConfig::default())
        .unwrap()
        .pop()
        .unwrap();
    let data = inputs(&shapes, 11);
    let args: Vec<(&[i64], &[f32])> = shapes
        .iter()
        .zip(&data)
        .map(|(s, d)| (s.as_slice(), d.as_slice()))
        .collect();
    let ours = m.run(&args).unwrap();

    let tmp = common::tmpdir(&format!("oracle-{model}"));
    let mut spec = Vec::new();
    for ((t, s), d) in m.spec.inputs.iter().zip(&shapes).zip(&data) {
        let f = tmp.join(format!("{}.f32", t.name));
        common::write_f32(&f, d);
        spec.push(serde_json::json!({"name": t.name, "shape": s, "file": f}));
    }
    std::fs::write(
        tmp.join("spec.json"),
        serde_json::json!({"inputs": spec}).to_string(),
    )
    .unwrap();
    let st = Command::new(common::python())
        .arg(common::root().join("tests/infer/ort_oracle.py"))
        .arg(dir.join(&m.spec.file))
        .arg(tmp.join("spec.json"))
        .arg(tmp.join("out"))
        .status()
        .unwrap();
    assert!(st.success());
    for (o, (_, v)) in m.spec.outputs.iter().zip(&ours) {
        let theirs = common::read_f32(&tmp.join(format!("out.{}.f32", o.name)));
        assert_eq!(theirs.len(), v.len());
        let same = theirs
            .iter()
            .zip(v)
            .all(|(a, b)| a.to_bits() == b.to_bits());
        assert!(
            same,
            "{model}/{}: outputs differ from Python onnxruntime",
            o.name
        );
    }
}

#[test]
fn encoder_matches_python_bit_for_bit() {
    check("encoder", vec![vec![2, 4, 3, 64, 64], vec![2, 3, 64, 64]]);
}

#[test]
fn timing_fixture_velocity_matches_python_bit_for_bit() {
    check(
        "velocity_timing_fixture",
        vec![vec![3, 64], vec![3, 1], vec![3, 97]],
    );
}
