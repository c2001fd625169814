//! Closed-loop trials through the scene's real stages (built by unitac-pipeline, as the CLI
//! does): determinism, a vtla_real unseen-cup trial to its end, bad scenes as errors.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use unitac_sim::task::{Split, TaskConfig, TaskOutcome};
use unitac_trials::run::trace_jsonl;
use unitac_trials::{TrialError, TrialOptions, TrialRecord, run_trial};

fn opts(task: &TaskConfig, max_s: f64) -> TrialOptions {
    TrialOptions {
        max_s,
        ..TrialOptions::for_task(task.kind)
    }
}

fn trial(scene: &str, task: &TaskConfig, seed: u64, n: u32, max_s: f64) -> TrialRecord {
    let scene = unitac_pipeline::load_scene(scene, None).unwrap();
    run_trial(&scene, task, seed, n, &opts(task, max_s)).unwrap()
}

#[test]
fn a_short_trial_of_each_task_gives_the_same_trace_bytes_twice() {
    for (scene, task) in [
        ("cup_deformation_vtla_real", TaskConfig::cup(Split::Unseen)),
        (
            "fabric_selection_vtla_real",
            TaskConfig::fabric(Split::Unseen),
        ),
    ] {
        let a = trial(scene, &task, 5, 1, 4.0);
        let b = trial(scene, &task, 5, 1, 4.0);
        assert_eq!(a.trace.len(), 120, "{scene}: 4 s at 30 Hz");
        assert!(a.frames >= 100, "{scene}: {} frames", a.frames);
        // The policy got past its first phase on what the stages told it.
        assert!(
            a.trace.iter().any(|r| r.phase != a.trace[0].phase),
            "{scene}"
        );
        assert_eq!(
            trace_jsonl(&a).unwrap(),
            trace_jsonl(&b).unwrap(),
            "{scene}"
        );
        assert_eq!(a, b);
        // Another trial draws another world: the bytes differ.
        let c = trial(scene, &task, 5, 2, 4.0);
        assert_ne!(
            trace_jsonl(&a).unwrap(),
            trace_jsonl(&c).unwrap(),
            "{scene}"
        );
    }
}

#[test]
fn a_vtla_real_unseen_cup_trial_ends_with_the_outcome_the_world_measures() {
    let task = TaskConfig::cup(Split::Unseen);
    let r = trial("cup_deformation_vtla_real", &task, 1, 0, 40.0);
    let TaskOutcome::Cup(c) = &r.outcome else {
        panic!("{:?}", r.outcome)
    };
    // An unseen cup: 84-96 mm (objects/split.yaml).
    let d: f64 = r.objects[4..6].parse().unwrap();
    assert!(
        r.objects.starts_with("cup ") && (84.0..=96.0).contains(&d),
        "{}",
        r.objects
    );
    assert_eq!(r.end_phase, "done");
    // The phases a live-touch squeeze goes through, in order, with the safety layer quiet.
    let mut phases: Vec<&str> = r.trace.iter().map(|t| t.phase.as_str()).collect();
    phases.dedup();
    assert_eq!(
        phases,
        [
            "approach",
            "close",
            "probe",
            "await_latent",
            "squeeze",
            "hold",
            "lift",
            "done"
        ]
    );
    assert!(
        r.trace.iter().all(|t| t.safety_ok),
        "{:?}",
        r.trace.iter().find(|t| !t.safety_ok)
    );
    // The outcome is the world's state at the last tick of the trace.
    let last = r.trace.last().unwrap();
    assert_eq!(c.deformation_m, last.deformation_m);
    assert_eq!(c.lift_height_m, last.lift_m);
    let peak = r.trace.iter().map(|t| t.deformation_m).fold(0.0, f64::max);
    assert!(c.peak_deformation_m >= peak);
    // The world's criteria: 1 cm +- 2 mm, never over, lifted 3 cm.
    let k = &task.cup_criteria;
    assert_eq!(
        c.deformation,
        (c.deformation_m - k.target_deformation_m).abs() <= k.tolerance_m && !c.over_compressed
    );
    assert!(c.overall, "{c:?}");
    assert_eq!(r.rejected, 0, "{:?}", r.rejections);
}

fn scene_file(name: &str, body: &str) -> unitac_core::Scene {
    let dir = std::env::temp_dir().join(format!("unitac-trials-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(format!("{name}.yaml"));
    std::fs::write(&path, body).unwrap();
    unitac_pipeline::load_scene(path.to_str().unwrap(), None).unwrap()
}

#[test]
fn a_scene_that_cannot_drive_the_world_is_an_error() {
    let task = TaskConfig::cup(Split::Unseen);
    // No policy stage: nothing would command the gripper.
    let s = scene_file(
        "no_policy",
        "scene: no_policy\nsource: {kind: mock, sensor: gelsight-mini}\nstages:\n  - kind: contact\n",
    );
    let e = run_trial(&s, &task, 1, 0, &opts(&task, 2.0)).unwrap_err();
    assert!(matches!(e, TrialError::Scene { .. }), "{e}");
    assert!(e.to_string().contains("no policy stage"), "{e}");
    // The cup scene on the fabric world: its object is not there.
    let cup = unitac_pipeline::load_scene("cup_deformation_vla", None).unwrap();
    let fabric = TaskConfig::fabric(Split::Unseen);
    let e = run_trial(&cup, &fabric, 1, 0, &opts(&fabric, 2.0)).unwrap_err();
    assert!(
        e.to_string().contains(
            "policy objects [\"cup\"] are not in the fabric_selection task's world (fabric_a, fabric_b)"
        ),
        "{e}"
    );
    // Time limits outside their range.
    for bad in [0.0, -1.0, f64::NAN, 1e9] {
        let e = run_trial(&cup, &task, 1, 0, &opts(&task, bad)).unwrap_err();
        assert!(matches!(e, TrialError::Options(_)), "{bad}: {e}");
    }
}

#[test]
fn a_millimetre_of_arm_height_noise_does_not_turn_a_scripted_cup_grasp_into_a_collision() {
    // The scripted VLA cup controller holds its arm height exactly; the same controller with up to
    // +-1 mm of noise on every command's height (a learned policy's arm does not hold still)
    // must grasp the same: the world's fingers stay around a cup while they are below its rim.
    let task = TaskConfig::cup(Split::Train);
    let scene = unitac_pipeline::load_scene("cup_deformation_vla", None).unwrap();
    for n in 0..3 {
        let still = run_trial(&scene, &task, 4242, n, &opts(&task, 40.0)).unwrap();
        let noisy_opts = TrialOptions {
            arm_z_noise_m: 1e-3,
            ..opts(&task, 40.0)
        };
        let noisy = run_trial(&scene, &task, 4242, n, &noisy_opts).unwrap();
        let (TaskOutcome::Cup(s), TaskOutcome::Cup(c)) = (&still.outcome, &noisy.outcome) else {
            panic!("{:?}", noisy.outcome)
        };
        assert!(!c.collision, "trial {n}: {c:?}");
        assert_eq!((c.lift, c.collision), (s.lift, s.collision), "trial {n}");
        assert!(
            (c.deformation_m - s.deformation_m).abs() < 1e-3,
            "trial {n}: {c:?} vs {s:?}"
        );
        // The noise reached the world: the two trials' traces differ.
        assert_ne!(still.trace, noisy.trace, "trial {n}");
    }
    // Out of range: refused before the trial.
    let bad = TrialOptions {
        arm_z_noise_m: f64::NAN,
        ..opts(&task, 40.0)
    };
    assert!(matches!(
        run_trial(&scene, &task, 4242, 0, &bad),
        Err(TrialError::Options(_))
    ));
}

#[test]
fn the_probe_reads_an_unseen_cups_stiffness_in_the_closed_loop_without_clipping() {
    // Unseen cups are 2-3x softer than the training cups the readout was fitted on: the probe's
    // press must show the sensor the wall, in the closed loop as in the demonstrations.
    let task = TaskConfig::cup(Split::Unseen);
    let scene = unitac_pipeline::load_scene("cup_deformation_vtla_real", None).unwrap();
    let mut errors = Vec::new();
    let mut clipped = 0;
    for n in 0..8 {
        let r = run_trial(&scene, &task, 2, n, &opts(&task, 12.0)).unwrap();
        let Some(s) = &r.stiffness else {
            // No reading: the trial never touched the cup (a collision of the camera's place).
            let TaskOutcome::Cup(c) = &r.outcome else {
                panic!("{:?}", r.outcome)
            };
            assert!(c.collision, "trial {n} read no stiffness: {:?}", r.phases);
            continue;
        };
        assert!(s.true_n_per_m > 100.0 && s.true_n_per_m < 400.0, "{s:?}");
        clipped += usize::from(s.clipped_ticks > 0);
        errors.push((s.read_n_per_m - s.true_n_per_m).abs() / s.true_n_per_m);
    }
    assert!(errors.len() >= 6, "{errors:?}");
    // No reading at a bound of the readout's range (at most 5 % of trials: none of these).
    assert_eq!(clipped, 0);
    errors.sort_by(f64::total_cmp);
    let median = errors[errors.len() / 2];
    assert!(median < 0.3, "median relative error {median}: {errors:?}");
}
