//! The trained touch projector (unitac_tools.train_projector, in the touch bundle): ONNX Runtime
//! gives what the trainer computed on its probe inputs (the trainer's gradient check is
//! python/tests/test_train_projector.py's); the sampler stage predicts one latent per object once it has both the
//! background and the camera's values, shaped and mapped as the manifest says, with its
//! condition's provenance; a stiff solver setting is published but never valid; a camera value
//! that is not a measurement is a clear error.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;
use unitac_core::clock::ManualClock;
use unitac_core::msg::{Header, LatentSource, Msg, VisualObservation};
use unitac_core::{Frame, Stage, Stamp};
use unitac_infer::flow::{OnnxVelocity, Velocity};
use unitac_infer::predict::{SamplerParams, SamplerStage};
use unitac_infer::{Bundle, RuntimeConfig};

#[test]
fn onnx_runtime_agrees_with_the_trainer() {
    let dir = common::touch();
    let check: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("check.json")).unwrap()).unwrap();
    let rows = |k: &str| -> Vec<Vec<f32>> {
        check[k]
            .as_array()
            .unwrap()
            .iter()
            .map(|r| match r.as_array() {
                Some(a) => a.iter().map(|v| v.as_f64().unwrap() as f32).collect(),
                None => vec![r.as_f64().unwrap() as f32],
            })
            .collect()
    };
    let (x, t, o, s, want) = (
        rows("x"),
        rows("t"),
        rows("object"),
        rows("sensor"),
        rows("v"),
    );
    let b = Bundle::open(&dir).unwrap();
    let m = b
        .load(&["velocity"], &RuntimeConfig::default())
        .unwrap()
        .into_iter()
        .next()
        .unwrap();
    let mut v = OnnxVelocity::new(m).unwrap();
    let n = x.len();
    let flat = |a: &[Vec<f32>]| a.concat();
    let cond: Vec<f32> = o
        .iter()
        .zip(&s)
        .flat_map(|(a, b)| a.iter().chain(b).copied())
        .collect();
    let got = v.eval(&flat(&x), &flat(&t), &cond, n).unwrap();
    let want = flat(&want);
    let scale = want.iter().fold(0.0f32, |m, w| m.max(w.abs()));
    let worst = got
        .iter()
        .zip(&want)
        .fold(0.0f32, |m, (g, w)| m.max((g - w).abs()));
    assert!(
        worst <= 1e-4 * scale,
        "max |ort - trainer| {worst} (scale {scale})"
    );
}

fn background() -> Frame {
    let (w, h) = (320u32, 240u32);
    let data: Vec<u8> = (0..w * h * 3).map(|i| (100 + (i % 7) * 3) as u8).collect();
    Frame::new("mock_gelsight_mini", 0, Stamp(1_000_000_000), w, h, data).unwrap()
}

fn visual(stamp: i64, diameter: f64) -> Msg {
    Msg::VisualObservation(VisualObservation {
        header: Header::new(Stamp(stamp), "camera"),
        names: vec!["cup_width_m".into(), "cup_height_m".into()],
        values: vec![diameter, 0.1],
    })
}

fn stage() -> SamplerStage {
    let p = SamplerParams {
        objects: vec!["cup".into()],
        samples: 2,
        ..SamplerParams::default()
    };
    SamplerStage::new(&common::touch(), p).unwrap()
}

#[test]
fn a_stiff_setting_is_published_but_never_valid() {
    // s = 20 with 4 Euler steps: s h = 5 is beyond the guard's 4 sigma_min.
    let p = SamplerParams {
        objects: vec!["cup".into()],
        solver: "euler".into(),
        steps: 4,
        guidance: 20.0,
        ..SamplerParams::default()
    };
    let mut st = SamplerStage::new(&common::touch(), p).unwrap();
    let clock = ManualClock::new(Stamp(1_500_000_000));
    st.process(&visual(1_200_000_000, 0.09), &clock).unwrap();
    let out = st.process(&Msg::Background(background()), &clock).unwrap();
    let [Msg::TactileLatent(l)] = out.as_slice() else {
        panic!("{out:?}")
    };
    assert!(!l.valid);
    assert!(l.guard_report.starts_with("stiff"), "{}", l.guard_report);
}

#[test]
fn the_stage_predicts_once_it_has_the_background_and_the_camera() {
    let clock = ManualClock::new(Stamp(1_500_000_000));
    let mut st = stage();
    assert!(
        st.process(&visual(1_200_000_000, 0.09), &clock)
            .unwrap()
            .is_empty()
    );
    let out = st.process(&Msg::Background(background()), &clock).unwrap();
    let [Msg::TactileLatent(l)] = out.as_slice() else {
        panic!("{out:?}")
    };
    assert_eq!(l.source, LatentSource::Predicted);
    assert_eq!(l.object, "cup");
    assert_eq!(l.shape, [2, 48]);
    assert_eq!(l.data.len(), 96);
    assert!(l.valid && l.data.iter().all(|v| v.is_finite()));
    assert_eq!(l.condition_sources, ["visual_observation", "background"]);
    let ages = &l.condition_age_s;
    assert!(ages.len() == 2 && (ages[0] - 0.3).abs() < 1e-9 && (ages[1] - 0.5).abs() < 1e-9);
    // Once per background: more camera values change nothing.
    assert!(
        st.process(&visual(1_600_000_000, 0.07), &clock)
            .unwrap()
            .is_empty()
    );
    // Same inputs, same bytes; another cup, another latent.
    let mut other = stage();
    other.process(&visual(1_200_000_000, 0.07), &clock).unwrap();
    let out2 = other
        .process(&Msg::Background(background()), &clock)
        .unwrap();
    let mut again = stage();
    again.process(&visual(1_200_000_000, 0.09), &clock).unwrap();
    let out3 = again
        .process(&Msg::Background(background()), &clock)
        .unwrap();
    assert_eq!(out, out3);
    assert_ne!(out, out2);
}

#[test]
fn a_camera_value_that_is_not_a_measurement_is_a_clear_error() {
    let clock = ManualClock::new(Stamp(1_500_000_000));
    let mut st = stage();
    st.process(&visual(1_200_000_000, f64::NAN), &clock)
        .unwrap();
    let e = st
        .process(&Msg::Background(background()), &clock)
        .unwrap_err()
        .to_string();
    assert!(e.contains("cup_width_m is NaN"), "{e}");
}
