//! `unitac trials`: the paper's closed-loop grasp trials in the sim world, one scene file per mode
//! (`<scene>_<mode>.yaml`), N trials each, the success table beside the paper's.
//!
//! The loop is unitac-trials' (`run_trial_on`, with the gripper `--gripper` names); here: arguments, the stages built fresh per trial
//! from the scene (unitac-pipeline), the progress bar, the table, JSON and the plots.

use crate::ConfigError;
use crate::progress;
use anyhow::{Context, Result};
use serde::Serialize;
use std::path::{Path, PathBuf};
use unitac_gripper::Model;
use unitac_plot::{Axis, Band, Chart, Figure, PALETTE, Series, Stroke};
use unitac_sim::task::{Split, TaskConfig, TaskKind, TaskOutcome};
use unitac_trials::serial::SerialReport;
use unitac_trials::table::{self, Row};
use unitac_trials::{TrialGripper, TrialOptions, TrialRecord, run_trial_on};

/// Most trials per mode.
pub const MAX_TRIALS: u32 = 1000;
/// Trials per mode drawn in the plots.
const PLOTTED: usize = 3;

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum TrialScene {
    /// Squeeze the unseen 90 mm cup by 1 cm and lift it.
    #[value(name = "cup_deformation")]
    CupDeformation,
    /// Touch two fabrics, grasp the smoother one, lift it.
    #[value(name = "fabric_selection")]
    FabricSelection,
}

impl TrialScene {
    fn name(self) -> &'static str {
        match self {
            TrialScene::CupDeformation => "cup_deformation",
            TrialScene::FabricSelection => "fabric_selection",
        }
    }
}

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum TrialMode {
    #[value(name = "vla")]
    Vla,
    #[value(name = "vtla_real")]
    VtlaReal,
    #[value(name = "vtla_pred")]
    VtlaPred,
}

impl TrialMode {
    fn name(self) -> &'static str {
        match self {
            TrialMode::Vla => "vla",
            TrialMode::VtlaReal => "vtla_real",
            TrialMode::VtlaPred => "vtla_pred",
        }
    }
}

/// The gripper a trial drives.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum TrialGripperArg {
    /// The task world's gripper, in process.
    #[value(name = "sim")]
    Sim,
    /// The serial driver and a simulated Robotiq 2F-140 on a pty, fingers = the world's gripper.
    #[value(name = "robotiq_2f140")]
    Robotiq2F140,
    /// The same with a simulated DH AG-95 (95 mm stroke: too narrow for the unseen 90 mm cup
    /// between 2 x 3 mm gel pads).
    #[value(name = "dh_ag95")]
    DhAg95,
}

impl TrialGripperArg {
    fn gripper(self) -> TrialGripper {
        match self {
            TrialGripperArg::Sim => TrialGripper::InProcess,
            TrialGripperArg::Robotiq2F140 => TrialGripper::Serial(Model::Robotiq2F140),
            TrialGripperArg::DhAg95 => TrialGripper::Serial(Model::DhAg95),
        }
    }
}

#[derive(clap::Args, Debug)]
pub struct TrialsArgs {
    /// Task: cup_deformation | fabric_selection (runs `launch/scenes/<scene>_<mode>.yaml`).
    #[arg(long)]
    pub scene: TrialScene,
    /// Modes, comma separated: vla, vtla_real, vtla_pred.
    #[arg(long, value_delimiter = ',', default_value = "vla,vtla_real,vtla_pred")]
    pub modes: Vec<TrialMode>,
    /// Trials per mode (1..=1000).
    #[arg(long, default_value_t = 20)]
    pub trials: u32,
    /// Seed of the trial draws (objects, placement, camera, sensor noise).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Cup task: draw the training cups (60 / 65 / 70 mm) instead of the unseen 90 mm one.
    #[arg(long)]
    pub train: bool,
    /// The gripper: sim (the world's own, in process) or a serial model (the Modbus driver
    /// talking to a simulated device on a pty whose fingers are the world's gripper).
    #[arg(long, value_enum, default_value = "sim")]
    pub gripper: TrialGripperArg,
    /// Print the table and every trial's outcome as one JSON object.
    #[arg(long)]
    pub json: bool,
    /// Write one PNG per task into this directory (cup: deformation over time; fabric: grip
    /// force and slip over time; a few trials per mode).
    #[arg(long, value_name = "DIR")]
    pub plot: Option<PathBuf>,
    /// Extra directory to look for scenes in (searched first).
    #[arg(long)]
    pub scene_dir: Option<PathBuf>,
}

/// One trial in the JSON output (the trace is left out: `--plot` draws it).
#[derive(Debug, Serialize)]
struct TrialLine<'a> {
    trial: u32,
    objects: &'a str,
    end_phase: &'a str,
    end_reason: &'a str,
    phases: &'a [String],
    duration_s: f64,
    frames: u64,
    rejected: u64,
    outcome: &'a TaskOutcome,
    /// What went over the wire (serial grippers).
    #[serde(skip_serializing_if = "Option::is_none")]
    serial: Option<&'a SerialReport>,
}

#[derive(Debug, Serialize)]
struct ModeReport<'a> {
    mode: &'a str,
    scene: &'a str,
    trials: Vec<TrialLine<'a>>,
}

#[derive(Debug, Serialize)]
struct Report<'a> {
    task: &'a str,
    split: Split,
    seed: u64,
    trials: u32,
    gripper: &'a str,
    table: &'a [Row],
    modes: Vec<ModeReport<'a>>,
}

fn config(msg: String) -> anyhow::Error {
    anyhow::Error::new(ConfigError(msg))
}

/// Run every mode's trials; Ok(true) when every trial ran to its end (successful or not).
pub fn run(a: TrialsArgs) -> Result<bool> {
    if !(1..=MAX_TRIALS).contains(&a.trials) {
        return Err(config(format!(
            "--trials {} is outside 1..={MAX_TRIALS}",
            a.trials
        )));
    }
    let mut modes = a.modes.clone();
    modes.dedup();
    if modes.is_empty() {
        return Err(config("--modes names no mode".into()));
    }
    let kind = match a.scene {
        TrialScene::CupDeformation => TaskKind::Cup,
        TrialScene::FabricSelection => TaskKind::Fabric,
    };
    let task = match kind {
        TaskKind::Cup => TaskConfig::cup(if a.train { Split::Train } else { Split::Unseen }),
        TaskKind::Fabric => TaskConfig::fabric(),
    };
    // Every scene loads (and its stages build once) before any trial runs.
    let mut scenes = Vec::new();
    for m in &modes {
        let name = format!("{}_{}", a.scene.name(), m.name());
        let scene = unitac_pipeline::load_scene(&name, a.scene_dir.clone())
            .map_err(|e| config(e.to_string()))?;
        unitac_pipeline::build_stages(&scene).map_err(|e| config(e.to_string()))?;
        unitac_trials::run::policy_params(&scene).map_err(|e| config(e.to_string()))?;
        scenes.push((*m, scene));
    }
    let opts = TrialOptions::for_task(kind);
    let gripper = a.gripper.gripper();
    let total = u64::from(a.trials) * modes.len() as u64;
    let bar = progress::bar(total, &format!("trials {}", a.scene.name()));
    let mut records: Vec<(TrialMode, Vec<TrialRecord>)> = Vec::new();
    for (m, scene) in &scenes {
        bar.set_message(format!("trials {} {}", a.scene.name(), m.name()));
        let mut rs = Vec::new();
        for trial in 0..a.trials {
            let stages = unitac_pipeline::build_stages(scene).map_err(|e| config(e.to_string()))?;
            let r = run_trial_on(scene, stages, &task, a.seed, trial, &opts, gripper)
                .with_context(|| format!("{} trial {trial}", scene.name))?;
            rs.push(r);
            bar.inc(1);
        }
        records.push((*m, rs));
    }
    bar.finish_and_clear();
    let outcomes: Vec<(String, Vec<TaskOutcome>)> = records
        .iter()
        .map(|(m, rs)| {
            (
                m.name().to_string(),
                rs.iter().map(|r| r.outcome.clone()).collect(),
            )
        })
        .collect();
    let rows = table::table(kind, &outcomes);
    if let Some(dir) = &a.plot {
        plot(dir, a.scene, &records)?;
    }
    if a.json {
        let report = Report {
            task: a.scene.name(),
            split: task.split,
            seed: a.seed,
            trials: a.trials,
            gripper: gripper.name(),
            table: &rows,
            modes: records
                .iter()
                .map(|(m, rs)| ModeReport {
                    mode: m.name(),
                    scene: rs.first().map_or("", |r| r.scene.as_str()),
                    trials: rs
                        .iter()
                        .map(|r| TrialLine {
                            trial: r.trial,
                            objects: &r.objects,
                            end_phase: &r.end_phase,
                            end_reason: &r.end_reason,
                            phases: &r.phases,
                            duration_s: r.duration_s,
                            frames: r.frames,
                            rejected: r.rejected,
                            outcome: &r.outcome,
                            serial: r.serial.as_ref(),
                        })
                        .collect(),
                })
                .collect(),
        };
        crate::emit(format_args!("{}\n", serde_json::to_string(&report)?))?;
    } else {
        let what = match (kind, task.split) {
            (TaskKind::Cup, Split::Unseen) => "unseen cup (90 mm)",
            (TaskKind::Cup, Split::Train) => "training cups (60 / 65 / 70 mm)",
            (TaskKind::Fabric, _) => "fabric selection",
        };
        let mut text = format!(
            "{what}, seed {}, {} trial(s) per mode, gripper {gripper}: ours (paper, real robot)\n",
            a.seed, a.trials
        );
        text.push_str(&table::render(&rows));
        for (m, rs) in &records {
            let failed: Vec<String> = rs
                .iter()
                .filter(|r| !r.outcome.overall())
                .map(|r| format!("{} ({})", r.trial, r.end_phase))
                .collect();
            if !failed.is_empty() {
                text.push_str(&format!(
                    "{}: not overall: trials {}\n",
                    m.name(),
                    failed.join(", ")
                ));
            }
        }
        crate::emit(text)?;
    }
    Ok(true)
}

/// Points of one trace value over time.
fn series(r: &TrialRecord, f: impl Fn(&unitac_trials::TraceRow) -> f64) -> Vec<(f64, f64)> {
    r.trace.iter().map(|row| (row.t_s, f(row))).collect()
}

/// One PNG per task: cup, deformation over time per mode (the target band); fabric, grip force
/// and slip since the grasp over time per mode. The first few trials of each mode.
fn plot(dir: &Path, scene: TrialScene, records: &[(TrialMode, Vec<TrialRecord>)]) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("--plot {}", dir.display()))?;
    let strokes = [Stroke::Solid, Stroke::Dashed, Stroke::Solid];
    let mut figure;
    match scene {
        TrialScene::CupDeformation => {
            let mut chart = Chart::new(
                "cup deformation (loss of diameter)",
                Axis::linear("t [s]"),
                Axis::linear("deformation [mm]"),
            )
            .band(Band {
                y: (8.0, 12.0),
                colour: [150, 150, 150],
                label: Some("target 10 +- 2 mm".into()),
            });
            for (i, (m, rs)) in records.iter().enumerate() {
                for (j, r) in rs.iter().take(PLOTTED).enumerate() {
                    let mut s = Series::new(
                        PALETTE[i % PALETTE.len()],
                        series(r, |row| row.deformation_m * 1e3),
                    )
                    .stroke(strokes[j % strokes.len()]);
                    if j == 0 {
                        s = s.label(m.name());
                    }
                    chart = chart.series(s);
                }
            }
            figure = Figure::new(1000, 560).panel(chart);
        }
        TrialScene::FabricSelection => {
            let mut force = Chart::new(
                "grip force",
                Axis::linear("t [s]"),
                Axis::linear("force per finger [N]"),
            );
            let mut slip = Chart::new(
                "slip since the grasp",
                Axis::linear("t [s]"),
                Axis::linear("slip [mm]"),
            );
            for (i, (m, rs)) in records.iter().enumerate() {
                for (j, r) in rs.iter().take(PLOTTED).enumerate() {
                    let colour = PALETTE[i % PALETTE.len()];
                    let stroke = strokes[j % strokes.len()];
                    let mut f = Series::new(colour, series(r, |row| row.force_n)).stroke(stroke);
                    let s = Series::new(colour, series(r, |row| row.slip_m * 1e3)).stroke(stroke);
                    if j == 0 {
                        f = f.label(m.name());
                    }
                    force = force.series(f);
                    slip = slip.series(s);
                }
            }
            figure = Figure::new(1000, 820).columns(1).panel(force).panel(slip);
        }
    }
    figure = figure
        .title(format!(
            "{}: the first {PLOTTED} trials per mode (solid, dashed, solid)",
            scene.name()
        ))
        .legend_from_series();
    let path = dir.join(format!("{}.png", scene.name()));
    figure
        .save(&path)
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}
