//! A task added as one module: `lift_cup` (below) and its scene file (toy/lift_cup_vla.yaml),
//! with no other edit. Its expert solves it, a scene naming it runs a closed-loop trial through
//! the scene's real stages, and the success table has its rows.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use unitac_sim::task::{Split, TaskConfig, TaskOutcome, run_expert};
use unitac_trials::{TrialOptions, run_trial, scene::scene_task_in, table};

/// The toy task: one training-size cup; lift it 3 cm without a collision, however hard it is
/// squeezed. One module: its draw, camera values, criteria, judge and expert.
mod lift_cup {
    use unitac_sim::SplitMix64;
    use unitac_sim::task::cup_deformation::{cup_visual_names, draw_cup};
    use unitac_sim::task::{
        ArmSetpoint, ArmTarget, CriteriaOutcome, GripperSetpoint, Judged, Split, Task, TaskCommand,
        TaskConfig, TaskKind, TaskObject, TaskOutcome, TaskTruth, TrialSpec,
    };

    pub struct LiftCup;
    pub const LIFT_CUP: TaskKind = TaskKind::new(&LiftCup);
    const LIFT_M: f64 = 0.03;

    impl Task for LiftCup {
        fn name(&self) -> &'static str {
            "lift_cup"
        }
        fn objects(&self) -> &'static str {
            "cups"
        }
        fn describe(&self, split: Split) -> String {
            format!("lift a cup ({split:?})")
        }
        fn draw(&self, cfg: &TaskConfig, rng: &mut SplitMix64) -> Vec<TaskObject> {
            vec![draw_cup(cfg, rng)]
        }
        fn visual_names(&self) -> Vec<String> {
            cup_visual_names()
        }
        fn criteria(&self) -> &'static [&'static str] {
            &["lift", "overall"]
        }
        fn judge(&self, _cfg: &TaskConfig, j: &Judged) -> TaskOutcome {
            let lift = j.held.is_some() && j.lift_m >= LIFT_M - 0.002 && !j.truth.collision;
            let mut o = CriteriaOutcome::default();
            o.met.insert("lift".into(), lift);
            o.met.insert("overall".into(), lift);
            o.values.insert("lift_m".into(), j.lift_m);
            TaskOutcome::Criteria(o)
        }
        /// Open wide at half the cup's height, close with 5 N, lift 4 cm once gripped.
        fn expert(
            &self,
            t: &TaskTruth,
            spec: &TrialSpec,
            cfg: &TaskConfig,
            _choice: Option<&str>,
        ) -> TaskCommand {
            let (Some(cup), Some(o)) = (spec.cup(), spec.object("cup")) else {
                panic!("the toy task draws a cup");
            };
            let z = 0.5 * cup.height_m;
            let around = t.contact.object == "cup" && (t.arm.arrived || t.gripper.force_n > 0.0);
            let gripped = around && t.gripper.force_n >= 4.5;
            let g = cfg.gripper;
            TaskCommand {
                gripper: GripperSetpoint {
                    opening_m: if around { 0.0 } else { g.max_opening_m },
                    speed_m_s: 0.02,
                    force_n: 5.0,
                },
                arm: ArmSetpoint {
                    target: ArmTarget::named("cup"),
                    xy_m: o.placed_m,
                    z_m: z,
                    lift_m: if gripped { 0.04 } else { 0.0 },
                },
            }
        }
        fn expert_run(&self) -> (f64, f64) {
            (1.0 / 30.0, 8.0)
        }
        fn trial_s(&self) -> f64 {
            30.0
        }
    }
}

use lift_cup::LIFT_CUP;

const SCENE: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/toy/lift_cup_vla.yaml");

#[test]
fn a_toy_task_is_one_module_and_a_scene_file() {
    // The scene names it; the loader finds it beside the shipped tasks, and not without it.
    let scene = unitac_pipeline::load_scene(SCENE, None).unwrap();
    let (_, kind) = scene_task_in(&scene, &[LIFT_CUP]).unwrap();
    assert_eq!(kind, LIFT_CUP);
    let e = unitac_trials::scene::scene_task(&scene)
        .unwrap_err()
        .to_string();
    assert!(e.contains("no task 'lift_cup'"), "{e}");

    // Its expert solves it.
    let cfg = TaskConfig::new(kind, Split::Train);
    let (dt, dur) = kind.expert_run();
    for trial in 0..3 {
        let demo = run_expert(&cfg, 1, trial, dt, dur).unwrap();
        assert!(demo.outcome.overall(), "trial {trial}: {:?}", demo.outcome);
        assert_eq!(demo.spec.kind, LIFT_CUP);
    }

    // A closed-loop trial of the scene's scripted policy in the toy task's world, judged by it.
    let opts = TrialOptions::for_task(kind);
    assert_eq!(opts.max_s, 30.0);
    let outcomes: Vec<TaskOutcome> = (0..2)
        .map(|trial| {
            let r = run_trial(&scene, &cfg, 1, trial, &opts).unwrap();
            assert!(!r.trace.is_empty());
            let TaskOutcome::Criteria(c) = &r.outcome else {
                panic!("{:?}", r.outcome)
            };
            assert!(c.values["lift_m"].is_finite());
            r.outcome
        })
        .collect();
    let rows = table::table(kind, &[("vla".into(), outcomes.clone())]);
    let names: Vec<&str> = rows.iter().map(|r| r.criterion.as_str()).collect();
    assert_eq!(names, ["lift", "overall"]);
    let lifted = outcomes.iter().filter(|o| o.meets("lift")).count() as u32;
    assert_eq!(rows[0].cells[0].ours, lifted);
    assert_eq!(rows[0].cells[0].paper, None);
    eprintln!("lift_cup_vla: {lifted} of 2 lifted");
    // The scripted controller squeezes and lifts: a training cup comes up.
    assert!(lifted >= 1, "{outcomes:?}");
}
