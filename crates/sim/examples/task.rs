//! Run the scripted expert on task trials and print each outcome:
//! `cargo run -p unitac-sim --example task -- cup_deformation|fabric_selection [--seed N]
//! [--trials N] [--unseen] [--fixed-opening M]` (training objects unless `--unseen`;
//! `--fixed-opening`: the size-blind cup grip closing to M metres instead of the expert).

use std::error::Error;
use std::io::Write;

use unitac_sim::task::{
    Split, TaskConfig, TaskKind, TaskOutcome, fixed_opening_command, run_expert, run_policy,
};

fn main() -> Result<(), Box<dyn Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let value = |flag: &str| -> Option<&String> {
        let i = args.iter().position(|a| a == flag)?;
        args.get(i + 1)
    };
    let seed: u64 = value("--seed").map_or(Ok(1), |s| s.parse())?;
    let trials: u32 = value("--trials").map_or(Ok(10), |s| s.parse())?;
    let fixed: Option<f64> = value("--fixed-opening").map(|s| s.parse()).transpose()?;
    let split = if args.iter().any(|a| a == "--unseen") {
        Split::Unseen
    } else {
        Split::Train
    };
    let usage = "usage: task cup_deformation|fabric_selection [--seed N] [--trials N] [--unseen]";
    let kind = TaskKind::named(args.first().ok_or(usage)?, &[])?;
    let cfg = TaskConfig::new(kind, split);
    let (dt, duration) = cfg.kind.expert_run();
    let mut out = std::io::stdout().lock();
    let mut ok = 0;
    for trial in 0..trials.min(1000) {
        let demo = match fixed {
            Some(m) => run_policy(&cfg, seed, trial, dt, duration, |t, spec| {
                fixed_opening_command(t, spec, &cfg, m)
            })?,
            None => run_expert(&cfg, seed, trial, dt, duration)?,
        };
        ok += u32::from(demo.outcome.overall());
        match &demo.outcome {
            TaskOutcome::Cup(c) => {
                let cup = demo.spec.cup().ok_or("no cup")?;
                writeln!(
                    out,
                    "trial {trial:3} cup {:2.0} mm k {:.0} N/m m {:3.0} g mu {:.2}: \
                     lift {} ({:.1} mm) deformation {} ({:.2} mm, peak {:.2}) overall {}",
                    cup.diameter_m * 1e3,
                    cup.wall.k_n_per_m,
                    cup.mass_kg * 1e3,
                    cup.friction_static,
                    c.lift,
                    c.lift_height_m * 1e3,
                    c.deformation,
                    c.deformation_m * 1e3,
                    c.peak_deformation_m * 1e3,
                    c.overall
                )?;
            }
            TaskOutcome::Fabric(f) => {
                let name = |n: &str| demo.spec.fabric(n).map_or("?", |s| s.fabric.name);
                writeln!(
                    out,
                    "trial {trial:3} a {:10} b {:10} smoother {}: chose {} selection {} \
                     layers {} lift {:.1} mm slip {:.2} mm grasp {} overall {}",
                    name("fabric_a"),
                    name("fabric_b"),
                    f.smoother,
                    if f.chosen.is_empty() { "-" } else { &f.chosen },
                    f.selection,
                    f.layers,
                    f.lift_height_m * 1e3,
                    f.slip_m * 1e3,
                    f.grasp,
                    f.overall
                )?;
            }
            TaskOutcome::Criteria(c) => writeln!(out, "trial {trial:3}: {:?}", c.met)?,
        }
    }
    let who = if fixed.is_some() {
        "fixed-opening grip"
    } else {
        "expert"
    };
    writeln!(out, "{who} overall success: {ok}/{}", trials.min(1000))?;
    Ok(())
}
