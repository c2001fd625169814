//! The demonstration recorder through the shipped scenes' own tactile stages: deterministic
//! (same seed and trial, same bytes), and it records what it says (the probe touch's real
//! latent, the predicted latent before any touch, the labels of the cup drawn), each mode's
//! expert deciding from what that mode observes (vtla_real: the probe and the fabric comparison;
//! vla and vtla_pred: neither, the camera's roughness guesses).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use unitac_core::Stage;
use unitac_pipeline::{StageConfig, build_stage, load_scene_without_policy_models, stage_configs};
use unitac_policy::Mode;
use unitac_sim::MockConfig;
use unitac_sim::task::{Split, TaskKind};
use unitac_trials::demos::{Demo, DemoConfig, record, record_chains, record_driven};

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
    let train = unitac_sim::task::split::SPLIT.cups.train_diameter_m;
    assert!(
        (train.0..=train.1).contains(&a.diameter_m),
        "{}",
        a.diameter_m
    );
    assert!(
        (a.contact_opening_m - (a.diameter_m + 0.006)).abs() < 0.003,
        "{a:?}"
    );
    // Labels: the paper-cup law (300 N/m at 80 mm, ~1/d^3, x 0.8..1.2, cubic stiffening).
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
    let unseen = unitac_sim::task::split::SPLIT.cups.unseen_diameter_m;
    assert!(
        (unseen.0..=unseen.1).contains(&d.diameter_m),
        "{}",
        d.diameter_m
    );
    let l = &d.latents[0];
    assert_eq!((l.source.as_str(), l.touch), ("predicted", 0));
    assert_eq!(l.shape, [2, 48]);
}

fn chain(scene: &str) -> Vec<Box<dyn Stage>> {
    let s = load_scene_without_policy_models(scene, None).unwrap();
    stage_configs(&s)
        .unwrap()
        .into_iter()
        .filter(|c| !matches!(c, StageConfig::Policy { .. }))
        .map(|c| build_stage(&s, c).unwrap())
        .collect()
}

#[test]
fn a_fabric_demonstration_records_every_modes_observations_tick_by_tick() {
    let record = || {
        let s = load_scene_without_policy_models("fabric_selection_vtla_real", None).unwrap();
        let sensor = MockConfig::new(s.source.sensor, s.source.seed);
        let cfg = DemoConfig {
            task: TaskKind::FABRIC,
            ..DemoConfig::default()
        };
        let chains = vec![
            chain("fabric_selection_vtla_real"),
            chain("fabric_selection_vtla_pred"),
        ];
        record_chains(Split::Train, 4, 0, &sensor, chains, &cfg).unwrap()
    };
    let d = record();
    assert_eq!(
        serde_json::to_string(&d).unwrap(),
        serde_json::to_string(&record()).unwrap()
    );
    assert_eq!(d.objects, ["fabric_a", "fabric_b"]);
    // It decided from the comparison, and grasped and lifted what it chose.
    assert!(d.objects.contains(&d.chosen), "{:?}", d.chosen);
    let decision = d.ticks.iter().find(|t| t.t_s >= d.decided_s).unwrap();
    assert_eq!(decision.comparison[..3].iter().sum::<f32>(), 1.0);
    let first = &d.ticks[0];
    let last = d.ticks.last().unwrap();
    // Fixed widths: 8 gripper values, the 10 camera values, per fabric 96 pooled values + known.
    for t in &d.ticks {
        assert_eq!(t.state.len(), 8);
        assert_eq!(t.visual.len(), d.visual_names.len());
        assert_eq!(t.contact.len(), 3);
        assert_eq!((t.latent_real.len(), t.latent_pred.len()), (194, 194));
        assert_eq!((t.comparison.len(), t.action.len()), (5, 7));
        assert!(t.action.iter().chain(&t.latent_real).all(|v| v.is_finite()));
    }
    // Nothing is known at the start; at the end both touches' live latents, both predictions
    // and the comparison are.
    let known = |v: &[f32]| [v[96], v[193]];
    assert_eq!(known(&first.latent_real), [0.0, 0.0]);
    assert_eq!(known(&first.latent_pred), [0.0, 0.0]);
    assert_eq!(first.comparison, [0.0; 5]);
    assert_eq!(known(&last.latent_real), [1.0, 1.0]);
    assert_eq!(known(&last.latent_pred), [1.0, 1.0]);
    assert_eq!(last.comparison[..3].iter().sum::<f32>(), 1.0);
    // The two live latents are of two fabrics: they differ.
    assert_ne!(last.latent_real[..96], last.latent_real[97..193]);
    // The arm visits both fabrics; the action is the command (force within the gripper's bound).
    let targets: std::collections::BTreeSet<u32> = d.ticks.iter().map(|t| t.arm_target).collect();
    assert!(targets.contains(&1) && targets.contains(&2), "{targets:?}");
    assert!(d.ticks.iter().all(|t| (0.0..=200.0).contains(&t.action[2])));
}

#[test]
fn the_cup_ticks_hold_the_probe_latent_after_the_probe_and_the_prediction_before_it() {
    let s = load_scene_without_policy_models("cup_deformation_vtla_real", None).unwrap();
    let sensor = MockConfig::new(s.source.sensor, s.source.seed);
    let chains = vec![
        chain("cup_deformation_vtla_real"),
        chain("cup_deformation_vtla_pred"),
    ];
    let d = record_chains(Split::Train, 5, 1, &sensor, chains, &DemoConfig::default()).unwrap();
    // The same labels and probe as with the vtla_real chain alone.
    let alone = demo("cup_deformation_vtla_real", Split::Train, 5, 1);
    assert_eq!(d.contact_opening_m, alone.contact_opening_m);
    assert_eq!(d.stiffness_n_per_m, alone.stiffness_n_per_m);
    let real_at = d
        .ticks
        .iter()
        .position(|t| t.latent_real[96] == 1.0)
        .unwrap();
    let pred_at = d
        .ticks
        .iter()
        .position(|t| t.latent_pred[96] == 1.0)
        .unwrap();
    assert!(pred_at < real_at, "{pred_at} {real_at}");
    // The probe's latent, pooled, is what the ticks carry after it arrived.
    let probe = alone
        .latents
        .iter()
        .find(|l| l.source == "real" && l.touch == 1)
        .unwrap();
    let p = unitac_trials::demos::pooled(&probe.data, 48);
    assert_eq!(d.ticks[real_at].latent_real[..96], p[..]);
    assert!(d.success);
}

/// A driver that keeps the arm home with the fingers at `opening_m`: it answers each gripper
/// status with both commands, as a policy stage does.
struct StayHome {
    opening_m: f64,
}

impl Stage for StayHome {
    fn name(&self) -> &str {
        "policy"
    }

    fn process(
        &mut self,
        input: &unitac_core::Msg,
        _clock: &dyn unitac_core::clock::Clock,
    ) -> Result<Vec<unitac_core::Msg>, unitac_core::StageError> {
        use unitac_core::msg::{ArmCommand, GripperCommand, GripperMode, samples};
        let unitac_core::Msg::GripperStatus(s) = input else {
            return Ok(Vec::new());
        };
        let header = s.header.clone();
        Ok(vec![
            unitac_core::Msg::GripperCommand(GripperCommand {
                header: header.clone(),
                mode: GripperMode::Position,
                position_m: self.opening_m,
                speed_m_s: 0.05,
                force_n: 5.0,
                reason: "stay".into(),
            }),
            unitac_core::Msg::ArmCommand(ArmCommand {
                header,
                target: "home".into(),
                x_m: 0.0,
                y_m: 0.0,
                z_m: 0.2,
                lift_m: 0.0,
                reason: "stay".into(),
            }),
            unitac_core::Msg::PolicyStatus(samples::policy_status()),
        ])
    }
}

#[test]
fn a_driven_demonstration_moves_the_world_by_the_driver_and_labels_it_with_the_expert() {
    let s = load_scene_without_policy_models("fabric_selection_vtla_real", None).unwrap();
    let sensor = MockConfig::new(s.source.sensor, s.source.seed);
    let cfg = DemoConfig {
        task: TaskKind::FABRIC,
        run_s: Some(3.0),
        ..DemoConfig::default()
    };
    let driver: Vec<Box<dyn Stage>> = vec![Box::new(StayHome { opening_m: 0.03 })];
    let chains = vec![chain("fabric_selection_vtla_real")];
    let d = record_driven(Split::Train, 4, 0, &sensor, chains, driver, &cfg).unwrap();
    let expert = record_chains(
        Split::Train,
        4,
        0,
        &sensor,
        vec![chain("fabric_selection_vtla_real")],
        &cfg,
    )
    .unwrap();
    assert_eq!(d.ticks.len(), expert.ticks.len());
    // The first state is the draw's, so the first label is the expert's first command.
    assert_eq!(d.ticks[0].state, expert.ticks[0].state);
    assert_eq!(d.ticks[0].action, expert.ticks[0].action);
    // The world followed the driver: the fingers went to its 30 mm (state[0]: the opening) and
    // no fabric was touched; the expert's own run closed on fabric A.
    let last = d.ticks.last().unwrap();
    assert!((last.state[0] - 0.03).abs() < 1e-3, "{:?}", last.state);
    assert_eq!(last.contact[0], 0.0);
    assert!(expert.ticks.iter().any(|t| t.contact[0] > 0.0));
    // Every label is the expert's for the states the driver made: go to fabric A (target 1),
    // never home, where the driver kept the arm.
    assert!(
        d.ticks.iter().all(|t| t.arm_target == 1),
        "{:?}",
        d.ticks.last()
    );
    assert!(!d.success);
}

#[test]
fn a_driven_cup_demonstration_that_never_reaches_the_cup_ends_at_the_timeout_with_its_ticks() {
    let s = load_scene_without_policy_models("cup_deformation_vtla_real", None).unwrap();
    let sensor = MockConfig::new(s.source.sensor, s.source.seed);
    let cfg = DemoConfig {
        timeout_s: 2.0,
        ..DemoConfig::default()
    };
    let driver: Vec<Box<dyn Stage>> = vec![Box::new(StayHome { opening_m: 0.1 })];
    let d = record_driven(
        Split::Train,
        5,
        1,
        &sensor,
        vec![chain("cup_deformation_vtla_real")],
        driver,
        &cfg,
    )
    .unwrap();
    // The approach's timeout (2 s at 30 Hz), the arm never arriving at the cup it is told to go to.
    let n = d.ticks.len();
    assert!((59..=63).contains(&n), "{n} ticks");
    assert!(d.ticks.iter().all(|t| t.arm_target == 1));
    assert!(d.latents.iter().all(|l| l.touch == 0), "no probe touch");
}

/// A fabric demonstration of `mode`, seed 1, trial `trial`, both scenes' stages watching.
fn fabric_demo(mode: Mode, trial: u32) -> Demo {
    let s = load_scene_without_policy_models("fabric_selection_vtla_real", None).unwrap();
    let sensor = MockConfig::new(s.source.sensor, s.source.seed);
    let cfg = DemoConfig {
        task: TaskKind::FABRIC,
        mode,
        ..DemoConfig::default()
    };
    let chains = vec![
        chain("fabric_selection_vtla_real"),
        chain("fabric_selection_vtla_pred"),
    ];
    record_chains(Split::Train, 1, trial, &sensor, chains, &cfg).unwrap()
}

#[test]
fn each_modes_fabric_expert_touches_both_then_decides_from_what_that_mode_observes() {
    let mut by_touch = Vec::new();
    for trial in 0..4 {
        let real = fabric_demo(Mode::VtlaReal, trial);
        let vla = fabric_demo(Mode::Vla, trial);
        for d in [&real, &vla] {
            let at = d.ticks.iter().position(|t| t.t_s >= d.decided_s).unwrap();
            // Both touches ended (each live latent encoded) before the decision, and no tick
            // before it lifted anything.
            let t = &d.ticks[at];
            assert_eq!(
                [t.latent_real[96], t.latent_real[193]],
                [1.0, 1.0],
                "trial {trial}"
            );
            assert!(d.ticks[..at].iter().all(|t| t.action[6] == 0.0));
            // After it, the arm goes to the chosen fabric and lifts it.
            let k = d.objects.iter().position(|o| *o == d.chosen).unwrap() as u32 + 1;
            let last = d.ticks.last().unwrap();
            assert_eq!(last.arm_target, k, "trial {trial}");
            assert!(last.action[6] > 0.0, "trial {trial}: {last:?}");
            assert!(
                last.state[3] > 0.0,
                "trial {trial}: holding: {:?}",
                last.state
            );
        }
        // vtla_real: the comparison it holds at the decision ([A rougher, B rougher, tie, ..])
        // names the smoother one.
        let at = real.ticks.iter().find(|t| t.t_s >= real.decided_s).unwrap();
        let by_comparison = if at.comparison[0] == 1.0 {
            "fabric_b"
        } else {
            assert_eq!(at.comparison[1], 1.0, "trial {trial}: {:?}", at.comparison);
            "fabric_a"
        };
        assert_eq!(real.chosen, by_comparison, "trial {trial}");
        // vla: the lower of the camera's mean roughness guesses at the decision.
        let at = vla.ticks.iter().find(|t| t.t_s >= vla.decided_s).unwrap();
        let r = |name: &str| {
            let i = vla.visual_names.iter().position(|n| n == name).unwrap();
            at.visual[i]
        };
        let by_camera = if r("fabric_b_roughness") < r("fabric_a_roughness") {
            "fabric_b"
        } else {
            "fabric_a"
        };
        assert_eq!(vla.chosen, by_camera, "trial {trial}");
        by_touch.push(real.chosen.clone());
    }
    // The comparison names either fabric over these draws.
    assert!(by_touch.iter().any(|c| c == "fabric_a") && by_touch.iter().any(|c| c == "fabric_b"));
}

#[test]
fn only_vtla_reals_cup_demonstration_probes_before_the_squeeze() {
    let s = load_scene_without_policy_models("cup_deformation_vtla_real", None).unwrap();
    let sensor = MockConfig::new(s.source.sensor, s.source.seed);
    let record = |mode| {
        let cfg = DemoConfig {
            mode,
            ..DemoConfig::default()
        };
        let chains = vec![
            chain("cup_deformation_vtla_real"),
            chain("cup_deformation_vtla_pred"),
        ];
        record_chains(Split::Train, 5, 1, &sensor, chains, &cfg).unwrap()
    };
    let real = record(Mode::VtlaReal);
    for mode in [Mode::Vla, Mode::VtlaPred] {
        let d = record(mode);
        // No probe: one contact episode (the squeeze), no tick at the probe's closing speed.
        let cfg = DemoConfig::default();
        let probing = |d: &Demo| {
            d.ticks
                .iter()
                .filter(|t| {
                    (f64::from(t.action[1]) - cfg.touch_speed_m_s).abs() < 1e-9
                        && (f64::from(t.action[2]) - cfg.touch_force_n).abs() < 1e-6
                })
                .count()
        };
        assert_eq!(probing(&d), 0, "{mode:?}");
        assert!(probing(&real) > 0);
        assert!(d.latents.iter().all(|l| l.touch <= 1), "{mode:?}");
        assert!(real.latents.iter().any(|l| l.touch == 2));
        // The same cup, the same squeeze and outcome, sooner.
        assert_eq!(d.stiffness_n_per_m, real.stiffness_n_per_m);
        assert_eq!(d.expert_opening_m, real.expert_opening_m);
        assert!(d.success && real.success);
        assert!(d.ticks.len() < real.ticks.len());
        assert!(
            d.contact_opening_m.is_nan(),
            "no probe contact: {}",
            d.contact_opening_m
        );
    }
}

/// A demonstration tick's fields are the schema's dataset features (schema/policy.json: each
/// feature's id is the tick's field the dataset writer reads), plus its time, command and arm
/// target: a feature added to the schema without its field, or the other way round, fails here.
#[test]
fn a_tick_holds_the_schemas_dataset_features() {
    let d = demo("cup_deformation_vtla_real", Split::Train, 5, 1);
    let tick = serde_json::to_value(&d.ticks[0]).unwrap();
    let mut fields: Vec<&str> = tick
        .as_object()
        .unwrap()
        .keys()
        .map(String::as_str)
        .collect();
    let mut want: Vec<&str> = unitac_policy::schema::DATASET_FEATURES
        .iter()
        .map(|(id, _)| *id)
        .chain(["t_s", "action", "arm_target"])
        .collect();
    fields.sort_unstable();
    want.sort_unstable();
    assert_eq!(fields, want);
    assert_eq!(
        tick["action"].as_array().unwrap().len(),
        unitac_policy::schema::COMMANDS.len()
    );
}
