//! Closed-loop trials through the scene's real stages (built by unitac-pipeline, as the CLI does).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use unitac_sim::task::{Split, TaskConfig, TaskOutcome};
use unitac_trials::run::trace_jsonl;
use unitac_trials::{TrialOptions, TrialRecord, run_trial};

fn trial(scene: &str, task: &TaskConfig, seed: u64, trial: u32, max_s: f64) -> TrialRecord {
    let scene = unitac_pipeline::load_scene(scene, None).unwrap();
    let stages = unitac_pipeline::build_stages(&scene).unwrap();
    let opts = TrialOptions {
        max_s,
        ..TrialOptions::for_task(task.kind)
    };
    run_trial(&scene, stages, task, seed, trial, &opts).unwrap()
}

#[test]
fn explore() {
    let scene = std::env::var("SCENE").unwrap_or("cup_deformation_vtla_real".into());
    let task = if scene.starts_with("cup") {
        TaskConfig::cup(Split::Unseen)
    } else {
        TaskConfig::fabric()
    };
    let r = trial(&scene, &task, 1, 0, 60.0);
    let mut last = String::new();
    for row in &r.trace {
        let line = format!("{} {} {}", row.phase, row.safety_ok, row.reason);
        if line != last {
            println!(
                "{:7.3} op {:.4} F {:6.2} def {:.4} slip {:.4} lift {:.3} | {line}",
                row.t_s, row.opening_m, row.force_n, row.deformation_m, row.slip_m, row.lift_m
            );
            last = line;
        }
    }
    println!(
        "{} {} frames {} {:?} rej {} {:?}",
        r.objects, r.end_phase, r.frames, r.outcome, r.rejected, r.rejections
    );
    let _ = trace_jsonl(&r);
    let _ = matches!(r.outcome, TaskOutcome::Cup(_));
}
