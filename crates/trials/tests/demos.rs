//! The demonstration recorder through the shipped cup scenes' own tactile stages: deterministic
//! (same seed and trial, same bytes), and it records what it says (the probe touch's real
//! latent, the predicted latent before any touch, the labels of the cup drawn).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use unitac_core::Stage;
use unitac_pipeline::{StageConfig, build_stage, load_scene_without_policy_models, stage_configs};
use unitac_sim::MockConfig;
use unitac_sim::task::Split;
use unitac_trials::demos::{Demo, DemoConfig, record};

fn demo(scene: &str, split: Split, seed: u64, trial: u32) -> Demo {
    let s = load_scene_without_policy_models(scene, None).unwrap();
    let stages: Vec<Box<dyn Stage>> = stage_configs(&s)
        .unwrap()
        .into_iter()
        .filter(|c| !matches!(c, StageConfig::Policy { .. }))
        .map(|c| build_stage(&s, c).unwrap())
        .collect();
    let sensor = MockConfig::new(s.source.sensor, s.source.seed);
    record(split, seed, trial, &sensor, stages, &DemoConfig::default()).unwrap()
}

#[test]
fn the_recorder_is_deterministic_and_records_the_probe_touch() {
    let a = demo("cup_deformation_vtla_real", Split::Train, 5, 1);
    let b = demo("cup_deformation_vtla_real", Split::Train, 5, 1);
    let (ja, jb) = (
        serde_json::to_string(&a).unwrap(),
        serde_json::to_string(&b).unwrap(),
    );
    assert_eq!(ja, jb);
    // The first latent is the probe touch's, from the encoder, after the contact began.
    let l = &a.latents[0];
    assert_eq!((l.source.as_str(), l.touch), ("real", 1), "{:?}", a.latents);
    assert_eq!(l.shape, [64, 48]);
    assert!(l.data.iter().all(|v| v.is_finite()));
    // The contact was found near the cup's width (fingers = diameter + two 3 mm pads).
    let train = unitac_sim::task::split::SPLIT.cups.train_diameter_mm;
    assert!(
        (train.0..=train.1).contains(&(a.diameter_m * 1e3)),
        "{}",
        a.diameter_m
    );
    assert!(
        (a.contact_opening_m - (a.diameter_m + 0.006)).abs() < 0.003,
        "{a:?}"
    );
    // Labels: the paper-cup law (0.3 N/mm at 80 mm, ~1/d^3, x 0.8..1.2, cubic stiffening).
    let nominal = 300.0 * (0.08 / a.diameter_m).powi(3);
    assert!(
        a.stiffness_n_per_m > 0.75 * nominal && a.stiffness_n_per_m < 1.25 * nominal,
        "{} vs {nominal}",
        a.stiffness_n_per_m
    );
    assert!(
        a.success,
        "the expert reaches the target after the probe: {a:?}"
    );
    // Another trial is another cup or another draw.
    let c = demo("cup_deformation_vtla_real", Split::Train, 5, 2);
    assert_ne!(serde_json::to_string(&c).unwrap(), ja);
}

#[test]
fn the_predicted_latent_comes_before_any_touch_and_unseen_is_an_unseen_size() {
    let d = demo("cup_deformation_vtla_pred", Split::Unseen, 7, 0);
    let unseen = unitac_sim::task::split::SPLIT.cups.unseen_diameter_mm;
    assert!(
        (unseen.0..=unseen.1).contains(&(d.diameter_m * 1e3)),
        "{}",
        d.diameter_m
    );
    let l = &d.latents[0];
    assert_eq!((l.source.as_str(), l.touch), ("predicted", 0));
    assert_eq!(l.shape, [2, 48]);
}
