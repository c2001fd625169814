//! The learned policies setup trains (scripts/learned_policies.sh: unitac_tools.train_policy on
//! the LeRobot datasets of the expert's demonstrations): every policy of the 3 modes x 2 tasks
//! loads through the manifest checks, and the Rust runtime agrees with the Python onnxruntime
//! oracle (tests/policy/policy_oracle.py). The trainer's own checks (its gradient, ONNX Runtime
//! against its numpy forward) are python/tests/test_train_policy.py's.
//! The policies are looked up in `$UNITAC_LEARNED`, else `$UNITAC_MODELS/learned`, else
//! `.build/models/learned`.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;
use std::path::PathBuf;
use unitac_policy::onnx::NamedInputs;

const TASKS: [&str; 2] = ["cup_deformation", "fabric_selection"];
const MODES: [&str; 3] = ["vla", "vtla_real", "vtla_pred"];
/// Largest difference between the Rust runtime and the oracle, as a fraction of each action's
/// bound range: the same float32 graph and normalisation on both sides.
const TOLERANCE: f64 = 1e-6;

fn learned() -> PathBuf {
    if let Some(d) = std::env::var_os("UNITAC_LEARNED") {
        return PathBuf::from(d);
    }
    std::env::var_os("UNITAC_MODELS")
        .map(PathBuf::from)
        .unwrap_or_else(|| common::root().join(".build/models"))
        .join("learned")
}

#[test]
fn every_learned_policy_loads_and_the_rust_runtime_matches_the_oracle() {
    let work = common::tmpdir("learned");
    for seed in ["seed0", "seed1", "seed2"] {
        for task in TASKS {
            for mode in MODES {
                let dir = learned().join(seed).join(format!("{task}_{mode}"));
                let mut p = common::load(&dir);
                let m = p.manifest().clone();
                // The gripper's interface and the arm first, then one score per arm target.
                let names = p.action_names().to_vec();
                assert_eq!(
                    names[..3],
                    ["gripper.position_m", "gripper.speed_m_s", "gripper.force_n"]
                );
                assert_eq!(names[7], "arm.target.home", "{names:?}");
                // One architecture: the modes differ only in their inputs.
                let inputs: Vec<String> = m.inputs.iter().map(|i| i.name.clone()).collect();
                assert_eq!(
                    inputs.contains(&"observation.tactile_latent_real".to_string()),
                    mode == "vtla_real"
                );
                assert_eq!(
                    inputs.contains(&"observation.tactile_latent_pred".to_string()),
                    mode == "vtla_pred"
                );
                assert_eq!(
                    inputs.contains(&"observation.contact".to_string()),
                    mode == "vtla_real"
                );
                if seed != "seed0" {
                    continue;
                }
                // Inputs of the right widths, around the training statistics.
                let values: Vec<Vec<f32>> = m
                    .inputs
                    .iter()
                    .enumerate()
                    .map(|(k, i)| {
                        let n = i.normalization.as_ref().unwrap();
                        let (mean, std) = (n.mean.clone().unwrap(), n.std.clone().unwrap());
                        unitac_infer::flow::noise(k as u64 + 1, mean.len())
                            .iter()
                            .zip(mean.iter().zip(&std))
                            .map(|(z, (mu, sd))| (*mu + f64::from(*z) * sd) as f32)
                            .collect()
                    })
                    .collect();
                let stamps = common::stamps(4);
                let mut ours = Vec::new();
                let mut ticks = Vec::new();
                for t in &stamps {
                    let mut named = NamedInputs::new();
                    let mut json = serde_json::Map::new();
                    for (i, v) in m.inputs.iter().zip(&values) {
                        named = named.with(&i.name, v);
                        json.insert(i.name.clone(), serde_json::json!(v));
                    }
                    let c = p.act(&named, *t).unwrap();
                    ours.push(c.row(0).unwrap().to_vec());
                    ticks.push(serde_json::json!({"t": t.0, "inputs": json}));
                }
                let v = common::run_oracle(&dir, ticks, &work);
                let plans: Vec<Vec<Vec<f64>>> = serde_json::from_value(v["plans"].clone()).unwrap();
                let mut worst = 0f64;
                for (a, plan) in ours.iter().zip(&plans) {
                    for (j, (x, y)) in a.iter().zip(&plan[0]).enumerate() {
                        let range = m.output.actions[j].max - m.output.actions[j].min;
                        worst = worst.max((f64::from(*x) - f64::from(*y as f32)).abs() / range);
                    }
                }
                println!("{task}_{mode}: Rust vs oracle {worst:.3e} of the bound range");
                assert!(worst <= TOLERANCE, "{task}_{mode}: {worst}");
            }
        }
    }
    std::fs::remove_dir_all(&work).ok();
}

/// The commands of a learned policy never leave the bounds its dataset records, whatever the
/// inputs: the network ends in a clip, so inputs 1000 standard deviations out put no command
/// beyond a bound in the runtime; and training keeps the network inside them before that clip (train.json: at
/// most 5 % of the demonstration frames, and of the DAgger states where there are some, per
/// command, by more than 2 % of the range).
#[test]
fn learned_commands_stay_inside_their_bounds() {
    for seed in ["seed0", "seed1", "seed2"] {
        let report: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(learned().join(seed).join("train.json")).unwrap(),
        )
        .unwrap();
        for p in report["policies"].as_array().unwrap() {
            for key in ["beyond_share_demos", "beyond_share_dagger"] {
                // The DAgger states: only where the policies were trained on them.
                let Some(shares) = p[key].as_object() else {
                    assert!(key == "beyond_share_dagger" && p["dagger"] == false, "{p}");
                    continue;
                };
                for (action, share) in shares {
                    let share = share.as_f64().unwrap();
                    assert!(
                        share <= 0.05,
                        "{seed} {} {key} {action}: {share}",
                        p["policy"]
                    );
                }
            }
        }
    }
    for task in TASKS {
        for mode in MODES {
            let dir = learned().join("seed0").join(format!("{task}_{mode}"));
            let mut p = common::load(&dir);
            let m = p.manifest().clone();
            for (k, sign) in [1.0f64, -1.0].into_iter().enumerate() {
                let values: Vec<Vec<f32>> = m
                    .inputs
                    .iter()
                    .map(|i| {
                        let n = i.normalization.as_ref().unwrap();
                        let (mean, std) = (n.mean.clone().unwrap(), n.std.clone().unwrap());
                        mean.iter()
                            .zip(&std)
                            .enumerate()
                            .map(|(j, (mu, sd))| {
                                let s = if j % 2 == 0 { sign } else { -sign };
                                (mu + 1000.0 * s * sd) as f32
                            })
                            .collect()
                    })
                    .collect();
                let mut named = NamedInputs::new();
                for (i, v) in m.inputs.iter().zip(&values) {
                    named = named.with(&i.name, v);
                }
                let c = p.act(&named, common::stamps(2)[k]).unwrap();
                // The runtime clamps what lies beyond the manifest's bounds and names what lay
                // beyond by more than 2 %: no command (the first 7 actions; scores are not
                // clipped, the runtime takes the largest).
                assert!(
                    c.beyond.iter().all(|&j| j >= 7),
                    "{task}_{mode}: {:?}",
                    c.beyond
                );
            }
        }
    }
}
