//! Predicted touch knows the object through what the camera sees, and nothing else: in the
//! cup_deformation_vtla_pred scene's trials (the sampler stage on the trained touch projector,
//! the stiffness readout of its scene), the stiffness read from the predicted latent
//! - falls as the cup the camera sees gets wider (unseen cups, several trials);
//! - changes with the object's category (the same scene's sampler asked for a fabric);
//! - is byte-identical for two cups that differ only in their hidden stiffness;
//!
//! and the latent names its condition's sources and their ages.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use unitac_core::Chain;
use unitac_core::msg::{LatentSource, Msg, TactileLatent};
use unitac_pipeline::{StageConfig, build_stage, stage_configs};
use unitac_policy::PolicyParams;
use unitac_policy::readout::Readout;
use unitac_sim::task::{Hidden, Split, TaskConfig, TaskKind};
use unitac_trials::{TrialOptions, run_trial};

const SCENE: &str = "cup_deformation_vtla_pred";

/// The predicted latent of trial `n` (unseen cups) and the camera's cup diameter then.
fn predicted(n: u32, hidden: Option<Hidden>) -> (TactileLatent, f64) {
    let scene = unitac_pipeline::load_scene(SCENE, None).unwrap();
    let task = TaskConfig::new(TaskKind::CUP, Split::Unseen);
    let opts = TrialOptions {
        max_s: 2.5,
        hidden,
        keep_messages: true,
        ..TrialOptions::for_task(task.kind)
    };
    let r = run_trial(&scene, &task, 5, n, &opts).unwrap();
    let mut diameter = None;
    for m in &r.messages {
        match &m.msg {
            Msg::VisualObservation(v) if diameter.is_none() => {
                let i = v.names.iter().position(|n| n == "cup_width_m").unwrap();
                diameter = Some(v.values[i]);
            }
            Msg::TactileLatent(l) if l.source == LatentSource::Predicted => {
                return (l.clone(), diameter.unwrap());
            }
            _ => {}
        }
    }
    panic!("trial {n}: no predicted latent");
}

/// The scene's stiffness readout and its policy params.
fn readout() -> (Readout, PolicyParams) {
    let scene = unitac_pipeline::load_scene(SCENE, None).unwrap();
    let (p, model) = stage_configs(&scene)
        .unwrap()
        .into_iter()
        .find_map(|c| match c {
            StageConfig::Policy { params, model, .. } => Some((*params, model.unwrap())),
            _ => None,
        })
        .unwrap();
    (Readout::load(&model, p.latent_len).unwrap(), p)
}

fn stiffness(r: &mut Readout, p: &PolicyParams, l: &TactileLatent) -> f64 {
    r.stiffness(p, l, l.header.stamp).unwrap().0
}

#[test]
fn predicted_stiffness_follows_the_camera_and_ignores_hidden_stiffness() {
    let (mut r, p) = readout();
    let mut seen: Vec<(f64, f64)> = (0..6)
        .map(|n| {
            let (l, d) = predicted(n, None);
            assert!(l.valid, "{}", l.guard_report);
            assert_eq!(l.object, "cup");
            assert_eq!(l.condition_sources, ["visual_observation", "background"]);
            assert!(l.condition_age_s.iter().all(|a| (0.0..5.0).contains(a)));
            (d, stiffness(&mut r, &p, &l))
        })
        .collect();
    seen.sort_by(|a, b| a.0.total_cmp(&b.0));
    eprintln!("camera diameter [m], predicted stiffness [N/m]: {seen:?}");
    // Wider cup, softer wall: the narrowest and the widest seen cups in that order, by a margin.
    let (narrow, wide) = (seen[0], seen[seen.len() - 1]);
    assert!(wide.0 - narrow.0 > 0.004, "{seen:?}");
    assert!(narrow.1 > 1.1 * wide.1, "{seen:?}");

    // The same trial with the cup twice as stiff: the same latent, to the byte.
    let (a, _) = predicted(2, None);
    let (b, _) = predicted(2, Some(Hidden::Stiffness(2.0)));
    assert_eq!(a, b);
}

#[test]
fn the_category_is_part_of_the_condition() {
    let scene = unitac_pipeline::load_scene(SCENE, None).unwrap();
    let (mut r, p) = readout();
    let (cup, _) = predicted(1, None);
    // The scene's sampler, asked for the same values as a fabric's.
    let cfg = stage_configs(&scene)
        .unwrap()
        .into_iter()
        .find_map(|c| match c {
            StageConfig::Sampler { mut params, bundle } => {
                params.objects = vec!["fabric_a".into()];
                Some(StageConfig::Sampler { params, bundle })
            }
            _ => None,
        })
        .unwrap();
    let mut chain = Chain::new(vec![build_stage(&scene, cfg).unwrap()]);
    let trial = {
        let task = TaskConfig::new(TaskKind::CUP, Split::Unseen);
        let opts = TrialOptions {
            max_s: 2.5,
            keep_messages: true,
            ..TrialOptions::for_task(task.kind)
        };
        run_trial(&scene, &task, 5, 1, &opts).unwrap()
    };
    // The trial's camera inputs (the cup's values under the fabric's names) and the background
    // the contact stage made, in their order.
    let mut fabric = None;
    for m in &trial.messages {
        let msg = match &m.msg {
            Msg::VisualObservation(v) if m.input => {
                let mut v = v.clone();
                v.names = v
                    .names
                    .iter()
                    .map(|n| n.replace("cup_", "fabric_a_"))
                    .collect();
                Msg::VisualObservation(v)
            }
            Msg::Background(_) if !m.input => m.msg.clone(),
            _ => continue,
        };
        for out in chain.run(msg).produced {
            if let Msg::TactileLatent(l) = out {
                fabric.get_or_insert(l);
            }
        }
    }
    let fabric = fabric.expect("a latent for the fabric");
    assert_eq!(fabric.object, "fabric_a");
    let (kc, kf) = (
        stiffness(&mut r, &p, &cup),
        stiffness(
            &mut r,
            &p,
            &TactileLatent {
                header: cup.header.clone(),
                ..fabric
            },
        ),
    );
    assert!((kc - kf).abs() > 0.1 * kc, "cup {kc} N/m, fabric {kf} N/m");
}
