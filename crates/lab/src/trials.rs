//! `unitac-lab trials`: the paper's closed-loop grasp trials in the sim world, one scene file per mode
//! (`<scene>_<mode>.yaml`), N trials each, the success table beside the paper's.
//!
//! The loop is unitac-trials' (`run_trial_on`, with the gripper `--gripper` names); here: arguments, the stages built fresh per trial
//! from the scene (unitac-pipeline), the progress bar, the table, JSON and the plots.

use crate::progress;
use anyhow::{Context, Result};
use clap::builder::{PossibleValuesParser, TypedValueParser};
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicU32, Ordering};
use unitac_cli::ConfigError;
use unitac_plot::{Axis, Band, Chart, Figure, PALETTE, Series, Stroke};
use unitac_policy::{Mode, TickCounts};
use unitac_sim::task::{PlotKind, Split, Sweep, TaskConfig, TaskKind, TaskOutcome};
use unitac_trials::serial::SerialReport;
use unitac_trials::table::{self, Row};
use unitac_trials::{TouchSwap, TrialGripper, TrialOptions, TrialRecord, run_trial_swapped};

/// Most trials per mode.
pub const MAX_TRIALS: u32 = 1000;
/// Trials per mode drawn in the plots.
const PLOTTED: usize = 3;

/// `--modes`: the library's modes ([`Mode::ALL`]) by name.
fn mode_parser() -> impl TypedValueParser<Value = Mode> {
    PossibleValuesParser::new(Mode::names()).try_map(|s| s.parse::<Mode>())
}

/// `--gripper`: the grippers a trial can drive ([`TrialGripper::offered`]) by name.
fn gripper_parser() -> impl TypedValueParser<Value = TrialGripper> {
    PossibleValuesParser::new(TrialGripper::offered().into_iter().map(|g| g.name()))
        .try_map(|s| s.parse::<TrialGripper>())
}

#[derive(clap::Args, Debug)]
pub struct TrialsArgs {
    /// Task: a scene name with a `<scene>_<mode>.yaml` per mode in the scene directories
    /// (`unitac scenes`; e.g. cup_deformation runs `launch/scenes/cup_deformation_<mode>.yaml`).
    #[arg(long)]
    pub scene: String,
    /// Modes, comma separated (default: every mode the task has a scene for).
    #[arg(long, value_delimiter = ',', value_parser = mode_parser())]
    pub modes: Vec<Mode>,
    /// Trials per mode (1..=1000).
    #[arg(long, default_value_t = 20)]
    pub trials: u32,
    /// Seed of the trial draws (objects, placement, camera, sensor noise).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Draw the training objects instead of the unseen ones (objects/split.yaml: cups by
    /// diameter range, fabrics by type).
    #[arg(long)]
    pub train: bool,
    /// Also run every mode with the world varied: camera noise x0.5 / x2, and for the cup
    /// stiffness x0.5 / x2 and size -10 / +10 mm; a table per variation.
    #[arg(long)]
    pub sweep: bool,
    /// Cup VLA on the training cups: print the rule's offset (vla_offset_m) that centres its
    /// deformation on the target, for the scene file.
    #[arg(long)]
    pub calibrate_vla: bool,
    /// The gripper: sim (the world's own, in process) or a serial model (the Modbus driver
    /// talking to a simulated device on a pty whose fingers are the world's gripper); the models
    /// whose stroke opens around an unseen cup with its gel pads.
    #[arg(long, value_parser = gripper_parser(), default_value = "sim")]
    pub gripper: TrialGripper,
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
    /// The policy: scripted (each mode's scene controller, `<task>_<mode>.yaml`) or learned
    /// (the ONNX policy trained on demonstrations, `<task>_learned_<mode>.yaml`).
    #[arg(long, value_parser = ["scripted", "learned"], default_value = "scripted")]
    pub policy: String,
    /// The touch ablation: run every touch mode again with each trial's latents and
    /// comparisons replaced by the next trial's (trial i gets trial i + 1's, the last the
    /// first's), each message keeping its own stamp; a second table.
    #[arg(long)]
    pub permute_touch: bool,
    /// Learned policies: the training seed whose policies run (scripts/learned_policies.sh
    /// trains seeds 0, 1, 2 into `<learned>/seed<K>/<task>_<mode>`); the scene's bundle path
    /// must follow that layout. Without it, each scene's own bundle runs.
    #[arg(long, value_parser = clap::value_parser!(u32).range(0..1000))]
    pub training_seed: Option<u32>,
    /// Add uniform noise of up to this many metres to the arm height of every command the policy
    /// sends, drawn per tick from the trial's own stream: a policy whose arm does not hold its
    /// height still (the world's grasp geometry must not turn it into a collision).
    #[arg(long, value_name = "M", default_value_t = 0.0,
          value_parser = unitac_cli::args::f64_in(0.0, unitac_trials::run::MAX_ARM_Z_NOISE_M))]
    pub arm_z_noise_m: f64,
}

/// The training seed of a bundle path `<root>/seed<K>/<name>/manifest.json`, and its root and
/// name; None when the path does not follow that layout.
fn seed_layout(path: &Path) -> Option<(u32, &Path, &std::ffi::OsStr)> {
    let bundle = path.parent()?;
    let seed_dir = bundle.parent()?;
    let k = seed_dir.file_name()?.to_str()?.strip_prefix("seed")?;
    if k.is_empty() || !k.bytes().all(|b| b.is_ascii_digit()) || k.len() > 3 {
        return None;
    }
    Some((k.parse().ok()?, seed_dir.parent()?, bundle.file_name()?))
}

/// The training seed the scene's policy bundle path names (`.../seed<K>/<name>/...`).
fn scene_training_seed(scene: &unitac_core::Scene) -> Option<u32> {
    scene
        .models
        .get("policy")
        .and_then(|p| seed_layout(p))
        .map(|(k, ..)| k)
}

/// The scene's `policy` model moved to training seed `seed`: the bundle of the same name under
/// `seed<K>` beside the one the scene names (`<root>/seed<J>/<name>/manifest.json`). A bundle
/// path of another layout is refused (exit 2), never rewritten.
fn with_training_seed(scene: &mut unitac_core::Scene, seed: u32) -> Result<()> {
    let Some(path) = scene.models.get_mut("policy") else {
        return Err(config(format!("{}: names no policy model", scene.name)));
    };
    let Some((_, root, name)) = seed_layout(path) else {
        return Err(config(format!(
            "{}: --training-seed {seed}: the policy bundle {} is not at \
             <root>/seed<K>/<name>/manifest.json, so it has no training seed to change; \
             leave --training-seed out to run it as the scene names it",
            scene.name,
            path.display()
        )));
    };
    let moved = root
        .join(format!("seed{seed}"))
        .join(name)
        .join("manifest.json");
    if !moved.is_file() {
        return Err(config(format!(
            "{}: no policy of training seed {seed} ({})",
            scene.name,
            moved.display()
        )));
    }
    *path = moved;
    Ok(())
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
    /// Ticks per value its proposal had beyond a bound by more than 2 % of the range.
    clamped: &'a BTreeMap<String, u64>,
    /// Ticks per kind the tactile reflex acted on.
    reflex: &'a BTreeMap<String, u64>,
    /// Every tick by what it sent: the policy's action, or the safe action and why.
    policy_ticks: &'a TickCounts,
    /// What went over the wire (serial grippers).
    #[serde(skip_serializing_if = "Option::is_none")]
    serial: Option<&'a SerialReport>,
    /// The cup's stiffness as the policy read it and as it is (cup modes that read one).
    #[serde(skip_serializing_if = "Option::is_none")]
    stiffness: Option<&'a unitac_trials::StiffnessReading>,
}

/// A mode's stiffness readings over its trials.
#[derive(Debug, Serialize)]
struct StiffnessSummary {
    /// Trials whose policy read a stiffness, and those in which its readout clipped a reading
    /// to its range (a reading at a bound).
    read: usize,
    clipped: usize,
    /// Median of |read - true| / true over the trials read.
    median_relative_error: f64,
}

fn stiffness_summary(rs: &[TrialRecord]) -> Option<StiffnessSummary> {
    let read: Vec<&unitac_trials::StiffnessReading> =
        rs.iter().filter_map(|r| r.stiffness.as_ref()).collect();
    if read.is_empty() {
        return None;
    }
    let mut errs: Vec<f64> = read
        .iter()
        .map(|s| (s.read_n_per_m - s.true_n_per_m).abs() / s.true_n_per_m)
        .collect();
    errs.sort_by(f64::total_cmp);
    let n = errs.len();
    let median = if n % 2 == 1 {
        errs[n / 2]
    } else {
        0.5 * (errs[n / 2 - 1] + errs[n / 2])
    };
    Some(StiffnessSummary {
        read: n,
        clipped: read.iter().filter(|s| s.clipped_ticks > 0).count(),
        median_relative_error: median,
    })
}

#[derive(Debug, Serialize)]
struct ModeReport<'a> {
    mode: &'a str,
    scene: &'a str,
    clamps: Clamps,
    /// Every tick of the mode's trials by what it sent (summed), and the trials whose policy
    /// never acted (every tick sent the safe action).
    policy_ticks: TickCounts,
    never_acted: Vec<u32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    stiffness: Option<StiffnessSummary>,
    trials: Vec<TrialLine<'a>>,
}

#[derive(Debug, Serialize)]
struct Report<'a> {
    task: &'a str,
    /// scripted | learned, and the learned policies' training seed.
    policy: &'a str,
    #[serde(skip_serializing_if = "Option::is_none")]
    training_seed: Option<u32>,
    split: Split,
    seed: u64,
    trials: u32,
    gripper: &'a str,
    /// Arm height noise added to every command (`--arm-z-noise-m`) \[m].
    arm_z_noise_m: f64,
    table: &'a [Row],
    /// The touch modes with each trial's touch values from the next trial (`--permute-touch`).
    #[serde(skip_serializing_if = "<[Row]>::is_empty")]
    touch_permuted: &'a [Row],
    sweep: &'a [SweepRow],
    /// Every noise and measurement figure of the world with its source.
    noise_figures: Vec<unitac_sim::task::NoiseFigure>,
    modes: Vec<ModeReport<'a>>,
}

fn config(msg: String) -> anyhow::Error {
    anyhow::Error::new(ConfigError(msg))
}

/// The trials of one scene, run in parallel on every core (`workers` threads; one for a serial
/// gripper, whose pty timing wants a core of its own), each trial's stages built fresh from the
/// scene; in trial order, each a pure function of (scene, task, seed, trial).
fn run_trials(
    scene: &unitac_core::Scene,
    task: &TaskConfig,
    (seed, trials): (u64, u32),
    opts: &TrialOptions,
    gripper: TrialGripper,
    bar: &indicatif::ProgressBar,
    donors: Option<&[Vec<unitac_core::msg::Msg>]>,
) -> Result<Vec<TrialRecord>> {
    let workers = match gripper {
        TrialGripper::InProcess => std::thread::available_parallelism().map_or(1, |n| n.get()),
        TrialGripper::Serial(_) => 1,
    }
    .min(trials as usize)
    .max(1);
    let next = AtomicU32::new(0);
    let results: Mutex<Vec<Option<Result<TrialRecord>>>> =
        Mutex::new((0..trials).map(|_| None).collect());
    std::thread::scope(|s| {
        for _ in 0..workers {
            s.spawn(|| {
                loop {
                    let trial = next.fetch_add(1, Ordering::Relaxed);
                    if trial >= trials {
                        break;
                    }
                    let swap = donors
                        .and_then(|d| d.get(trial as usize))
                        .map_or_else(TouchSwap::default, |d| TouchSwap::new(d.clone()));
                    let r = run_trial_swapped(scene, task, seed, trial, opts, gripper, swap)
                        .with_context(|| format!("{} trial {trial}", scene.name));
                    bar.inc(1);
                    let failed = r.is_err();
                    if let Ok(mut all) = results.lock()
                        && let Some(slot) = all.get_mut(trial as usize)
                    {
                        *slot = Some(r);
                    }
                    if failed {
                        // Stop handing out trials: the first error ends the run.
                        next.store(trials, Ordering::Relaxed);
                    }
                }
            });
        }
    });
    let all = results
        .into_inner()
        .map_err(|_| anyhow::anyhow!("a trial thread panicked"))?;
    let mut out = Vec::with_capacity(all.len());
    for r in all {
        match r {
            Some(r) => out.push(r?),
            None => anyhow::bail!("a trial did not run (an earlier one failed)"),
        }
    }
    Ok(out)
}

/// One variation of the world for `--sweep` (the task's [`unitac_sim::task::Task::sweep`]).
#[derive(Debug, Clone, Serialize)]
struct Variant {
    name: String,
    camera_noise: f64,
    cup_stiffness: f64,
    cup_size_mm: f64,
    #[serde(skip)]
    sweep: Sweep,
}

impl Variant {
    fn of(sweep: Sweep) -> Variant {
        let (mut camera_noise, mut cup_stiffness, mut cup_size_mm) = (1.0, 1.0, 0.0);
        match sweep {
            Sweep::CameraNoise(f) => camera_noise = f,
            Sweep::CupStiffness(f) => cup_stiffness = f,
            Sweep::CupSize(d) => cup_size_mm = d * 1e3,
        }
        Variant {
            name: sweep.name(),
            camera_noise,
            cup_stiffness,
            cup_size_mm,
            sweep,
        }
    }
    fn apply(&self, task: &TaskConfig) -> TaskConfig {
        self.sweep.apply(task)
    }
}

/// Per mode: ticks, per value the ticks it was reported clamped, and per kind the ticks the
/// tactile reflex acted on (summed over the trials).
#[derive(Debug, Default, Serialize)]
struct Clamps {
    ticks: u64,
    clamped: BTreeMap<String, u64>,
    reflex: BTreeMap<String, u64>,
    /// The largest share of ticks any one value was clamped in.
    worst_share: f64,
}

fn clamps(rs: &[TrialRecord]) -> Clamps {
    let mut c = Clamps::default();
    for r in rs {
        c.ticks += r.ticks;
        for (k, n) in &r.clamped {
            *c.clamped.entry(k.clone()).or_default() += n;
        }
        for (k, n) in &r.reflex {
            *c.reflex.entry(k.clone()).or_default() += n;
        }
    }
    c.worst_share = c
        .clamped
        .values()
        .map(|&n| n as f64 / c.ticks.max(1) as f64)
        .fold(0.0, f64::max);
    c
}

/// Every tick of `rs` by what it sent, summed.
fn policy_ticks(rs: &[TrialRecord]) -> TickCounts {
    let mut c = TickCounts::default();
    for r in rs {
        c.add(&r.policy_ticks);
    }
    c
}

/// The trials of `rs` whose policy never acted.
fn never_acted(rs: &[TrialRecord]) -> Vec<u32> {
    rs.iter()
        .filter(|r| r.policy_ticks.never_acted())
        .map(|r| r.trial)
        .collect()
}

/// What the policy's failures say about one run of a mode (`what`: the mode, and the sweep
/// variant or the touch ablation): a warning when it failed on any tick, and an error line when
/// a trial's policy never acted.
fn failure_lines(what: &str, rs: &[TrialRecord]) -> (Option<String>, Option<String>) {
    let c = policy_ticks(rs);
    let warning = (c.failed() > 0).then(|| {
        format!(
            "warning: {what}: the policy gave no usable action on {} in {} trial(s); first: {}",
            c.failures_text(),
            rs.len(),
            c.first_failure.as_deref().unwrap_or("-")
        )
    });
    let never = never_acted(rs);
    let error = (!never.is_empty()).then(|| {
        let list: Vec<String> = never.iter().map(u32::to_string).collect();
        format!(
            "{what}: the policy never acted in trial(s) {} (every tick sent the safe action)",
            list.join(", ")
        )
    });
    (warning, error)
}

/// One variant's table (sweep output).
#[derive(Debug, Serialize)]
struct SweepRow {
    variant: Variant,
    table: Vec<Row>,
}

/// One column of the tables: a mode's scene, or a variant of it (`vla_force`: the cup VLA
/// scene with its force rule, the strongest camera-only baseline beside the position rule).
#[derive(Debug, Clone)]
struct Column {
    mode: Mode,
    name: String,
}

impl Column {
    fn of(mode: Mode) -> Self {
        Self {
            mode,
            name: mode.as_str().to_string(),
        }
    }
    fn as_str(&self) -> &str {
        &self.name
    }
}

/// The cup VLA rule that is not the scene's own, as a column of its own.
const VLA_FORCE: &str = "vla_force";

type Records = Vec<(Column, Vec<TrialRecord>)>;

fn outcomes(records: &Records) -> Vec<(String, Vec<TaskOutcome>)> {
    records
        .iter()
        .map(|(m, rs)| {
            (
                m.as_str().to_string(),
                rs.iter().map(|r| r.outcome.clone()).collect(),
            )
        })
        .collect()
}

fn calibrate_usage() -> String {
    "--calibrate-vla fits the cup VLA rule on the training cups: give --scene \
     cup_deformation --modes vla --train"
        .into()
}

/// Run every mode's trials; Ok(true) when every trial ran to its end (successful or not),
/// Ok(false) when in some trial the policy never acted (every tick sent the safe action).
pub fn run(a: TrialsArgs) -> Result<bool> {
    if !(1..=MAX_TRIALS).contains(&a.trials) {
        return Err(config(format!(
            "--trials {} is outside 1..={MAX_TRIALS}",
            a.trials
        )));
    }
    let task_name = match a.policy.as_str() {
        "learned" => format!("{}_learned", a.scene),
        _ => a.scene.clone(),
    };
    let tasks = unitac_pipeline::tasks(a.scene_dir.clone());
    let Some(task_modes) = tasks.get(&task_name) else {
        let known: Vec<&str> = tasks.keys().map(String::as_str).collect();
        return Err(config(format!(
            "--scene {}: no scene <task>_<mode> (mode: {}) has that task in the scene \
             directories (tasks: {})",
            a.scene,
            Mode::names().join(", "),
            if known.is_empty() {
                "none".into()
            } else {
                known.join(", ")
            }
        )));
    };
    let mut modes = if a.modes.is_empty() {
        task_modes.clone()
    } else {
        a.modes.clone()
    };
    modes.dedup();
    if a.calibrate_vla && (!a.train || modes != [Mode::Vla]) {
        return Err(config(calibrate_usage()));
    }
    let (kind, scenes, squeeze_vla) = load_scenes(&a, &task_name, &modes)?;
    if a.calibrate_vla && !squeeze_vla {
        return Err(config(calibrate_usage()));
    }
    let split = if a.train { Split::Train } else { Split::Unseen };
    let task = TaskConfig::new(kind, split);
    let opts = TrialOptions {
        arm_z_noise_m: a.arm_z_noise_m,
        ..TrialOptions::for_task(kind)
    };
    let gripper = a.gripper;
    let Runs {
        records,
        sweep,
        permuted_records,
        failures,
    } = run_all(&a, &scenes, kind, &task, &opts, &modes)?;
    let rows = table::table(kind, &outcomes(&records));
    let permuted = if a.permute_touch {
        table::table(kind, &outcomes(&permuted_records))
    } else {
        Vec::new()
    };
    if a.calibrate_vla {
        return calibrate_vla(&a, &task, &records);
    }
    if let Some(dir) = &a.plot {
        plot(dir, &a.scene, kind, &records)?;
    }
    if a.json {
        json_report(&a, &task, &scenes, (&rows, &permuted), &sweep, &records)?;
    } else {
        let training_seed = a
            .training_seed
            .or_else(|| scenes.first().and_then(|(_, s)| scene_training_seed(s)));
        unitac_cli::emit(text_report(
            (&a, training_seed),
            kind,
            split,
            gripper,
            (&rows, &permuted),
            &records,
            &sweep,
        ))?;
    }
    for line in failures.0.iter().chain(&failures.1) {
        eprintln!("{}: {line}", unitac_cli::program());
    }
    // A policy that never acted ran no trial: the table above counts nothing it did.
    Ok(failures.1.is_empty())
}

/// Each table column's scene.
type ModeScenes = Vec<(Column, unitac_core::Scene)>;

/// The scenes of each mode, loaded with their stages built once before any trial runs; the sim
/// task their policy stages name (the same for every mode); and whether it is a squeeze with a
/// VLA mode, whose force rule then runs beside its position rule (scripted scenes).
fn load_scenes(
    a: &TrialsArgs,
    task_name: &str,
    modes: &[Mode],
) -> Result<(TaskKind, ModeScenes, bool)> {
    // Every scene loads (and its stages build once) before any trial runs; the sim task is the
    // one their policy stages name, the same for every mode.
    let mut scenes = Vec::new();
    let mut kinds = Vec::new();
    let mut squeeze_vla = false;
    for m in modes {
        let name = unitac_pipeline::mode_scene(task_name, *m);
        let mut scene = unitac_pipeline::load_scene(&name, a.scene_dir.clone())
            .map_err(|e| config(e.to_string()))?;
        if a.policy == "learned"
            && let Some(k) = a.training_seed
        {
            with_training_seed(&mut scene, k)?;
        }
        unitac_pipeline::build_stages(&scene).map_err(|e| config(e.to_string()))?;
        let (params, kind) =
            unitac_trials::scene::scene_task(&scene).map_err(|e| config(e.to_string()))?;
        // A serial gripper whose weakest grip is above the scene's force cap would break it.
        if let TrialGripper::Serial(model) = a.gripper {
            let limits = model.calibration().limits;
            limits
                .check_force_bound(params.limits.max_force_n)
                .map_err(|e| {
                    config(format!(
                        "--gripper {model} with scene {} (policy max_force_n = {} N): {e}; choose \
                     a gripper whose force range reaches below the cap, or a scene whose \
                     max_force_n is at least {} N",
                        scene.name, params.limits.max_force_n, limits.min_force_n
                    ))
                })?;
        }
        kinds.push(format!("{} ({})", scene.name, kind.name()));
        // The squeeze controller's VLA has two camera-only rules (vla_rule), and a fitted one.
        if *m == Mode::Vla {
            squeeze_vla = matches!(
                unitac_policy::task::Task::parse(&params.task),
                Ok(unitac_policy::task::Task::Squeeze { .. })
            );
        }
        scenes.push((*m, kind, scene));
    }
    let kind = match scenes.as_slice() {
        [(_, k, _), rest @ ..] if rest.iter().all(|(_, r, _)| r == k) => *k,
        _ => {
            return Err(config(format!(
                "--scene {}: its mode scenes name different tasks: {}",
                a.scene,
                kinds.join(", ")
            )));
        }
    };
    let mut scenes: ModeScenes = scenes
        .into_iter()
        .map(|(m, _, s)| (Column::of(m), s))
        .collect();
    // The squeeze controller: VLA's force rule beside its position rule (scripted scenes; a
    // learned VLA has one).
    if squeeze_vla && a.policy != "learned" {
        let force = scenes
            .iter()
            .find(|(c, _)| c.mode == Mode::Vla)
            .map(|(_, s)| unitac_trials::scene::with_vla_rule(s, unitac_policy::VlaRule::Force));
        if let Some(s) = force {
            unitac_pipeline::build_stages(&s).map_err(|e| config(e.to_string()))?;
            let at = scenes
                .iter()
                .position(|(c, _)| c.mode == Mode::Vla)
                .map_or(0, |i| i + 1);
            scenes.insert(
                at,
                (
                    Column {
                        mode: Mode::Vla,
                        name: VLA_FORCE.into(),
                    },
                    s,
                ),
            );
        }
    }
    Ok((kind, scenes, squeeze_vla))
}

/// Everything the trials ran: each mode's records, the sweep's tables, the touch-permuted
/// records, and the policy's failures (warnings; runs where it never acted).
struct Runs {
    records: Records,
    sweep: Vec<SweepRow>,
    permuted_records: Records,
    failures: (Vec<String>, Vec<String>),
}

/// The trials of every mode, then the sweep's variants, then the touch ablation (each touch mode
/// again, trial i with trial i + 1's touch values), behind one progress bar.
fn run_all(
    a: &TrialsArgs,
    scenes: &[(Column, unitac_core::Scene)],
    kind: TaskKind,
    task: &TaskConfig,
    opts: &TrialOptions,
    modes: &[Mode],
) -> Result<Runs> {
    let gripper = a.gripper;
    let variants = if a.sweep {
        kind.sweep().into_iter().map(Variant::of).collect()
    } else {
        Vec::new()
    };
    let touch_modes = modes.iter().filter(|m| **m != Mode::Vla).count();
    let total = u64::from(a.trials)
        * (scenes.len() * (1 + variants.len()) + if a.permute_touch { touch_modes } else { 0 })
            as u64;
    let bar = progress::bar(total, &format!("trials {}", a.scene));
    let mut records: Records = Vec::new();
    for (m, scene) in scenes {
        bar.set_message(format!("trials {} {}", a.scene, m.as_str()));
        let rs = run_trials(scene, task, (a.seed, a.trials), opts, gripper, &bar, None)?;
        records.push((m.clone(), rs));
    }
    // The policy's failures of every run: warnings, and runs where it never acted.
    let mut failures: (Vec<String>, Vec<String>) = (Vec::new(), Vec::new());
    let mut note = |what: String, rs: &[TrialRecord]| {
        let (w, e) = failure_lines(&what, rs);
        failures.0.extend(w);
        failures.1.extend(e);
    };
    for (m, rs) in &records {
        note(m.as_str().to_string(), rs);
    }
    let mut sweep = Vec::new();
    for v in &variants {
        let t = v.apply(task);
        let mut rs_all = Vec::new();
        for (m, scene) in scenes {
            bar.set_message(format!("sweep {} {}", v.name, m.as_str()));
            rs_all.push((
                m.clone(),
                run_trials(scene, &t, (a.seed, a.trials), opts, gripper, &bar, None)?,
            ));
        }
        for (m, rs) in &rs_all {
            note(format!("{} ({})", m.as_str(), v.name), rs);
        }
        sweep.push(SweepRow {
            variant: v.clone(),
            table: table::table(kind, &outcomes(&rs_all)),
        });
    }
    // The touch ablation: each touch mode again, trial i with trial i + 1's touch values.
    let mut permuted_records: Records = Vec::new();
    if a.permute_touch {
        for ((m, scene), (_, own)) in scenes.iter().zip(&records) {
            if m.mode == Mode::Vla {
                continue;
            }
            let n = own.len();
            let donors: Vec<Vec<unitac_core::msg::Msg>> =
                (0..n).map(|i| own[(i + 1) % n].touch.clone()).collect();
            bar.set_message(format!("touch permuted {}", m.as_str()));
            permuted_records.push((
                m.clone(),
                run_trials(
                    scene,
                    task,
                    (a.seed, a.trials),
                    opts,
                    gripper,
                    &bar,
                    Some(&donors),
                )?,
            ));
        }
    }
    for (m, rs) in &permuted_records {
        note(format!("{} (touch permuted)", m.as_str()), rs);
    }
    bar.finish_and_clear();
    Ok(Runs {
        records,
        sweep,
        permuted_records,
        failures,
    })
}

/// `--json`: the report on one line.
fn json_report(
    a: &TrialsArgs,
    task: &TaskConfig,
    scenes: &[(Column, unitac_core::Scene)],
    (rows, permuted): (&[Row], &[Row]),
    sweep: &[SweepRow],
    records: &Records,
) -> Result<()> {
    let report = Report {
        task: &a.scene,
        policy: &a.policy,
        training_seed: (a.policy == "learned")
            .then(|| {
                a.training_seed
                    .or_else(|| scenes.first().and_then(|(_, s)| scene_training_seed(s)))
            })
            .flatten(),
        split: task.split,
        seed: a.seed,
        trials: a.trials,
        gripper: a.gripper.name(),
        arm_z_noise_m: a.arm_z_noise_m,
        table: rows,
        touch_permuted: permuted,
        sweep,
        noise_figures: task.noise_figures(),
        modes: records
            .iter()
            .map(|(m, rs)| ModeReport {
                mode: m.as_str(),
                scene: rs.first().map_or("", |r| r.scene.as_str()),
                clamps: clamps(rs),
                policy_ticks: policy_ticks(rs),
                never_acted: never_acted(rs),
                stiffness: stiffness_summary(rs),
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
                        clamped: &r.clamped,
                        reflex: &r.reflex,
                        policy_ticks: &r.policy_ticks,
                        serial: r.serial.as_ref(),
                        stiffness: r.stiffness.as_ref(),
                    })
                    .collect(),
            })
            .collect(),
    };
    unitac_cli::emit(format_args!("{}\n", serde_json::to_string(&report)?))?;
    Ok(())
}

/// The tables as text: the main one, which trials failed, the clamps, the sweep's.
fn text_report(
    (a, training_seed): (&TrialsArgs, Option<u32>),
    kind: TaskKind,
    split: Split,
    gripper: TrialGripper,
    (rows, permuted): (&[Row], &[Row]),
    records: &Records,
    sweep: &[SweepRow],
) -> String {
    let what = kind.describe(split);
    let policy = match (a.policy.as_str(), training_seed) {
        ("learned", Some(k)) => format!("learned policies (training seed {k})"),
        ("learned", None) => "learned policies (the scenes' bundles)".to_string(),
        (p, _) => format!("{p} policies"),
    };
    let mut text = format!(
        "{what}, seed {}, {} trial(s) per mode, gripper {gripper}, {policy}: ours (paper, real robot)\n",
        a.seed, a.trials
    );
    text.push_str(&table::render(rows));
    for (m, rs) in records {
        let failed: Vec<String> = rs
            .iter()
            .filter(|r| !r.outcome.overall())
            .map(|r| format!("{} ({})", r.trial, r.end_phase))
            .collect();
        if !failed.is_empty() {
            text.push_str(&format!(
                "{}: not overall: trials {}\n",
                m.as_str(),
                failed.join(", ")
            ));
        }
        let t = policy_ticks(rs);
        if t.failed() > 0 {
            text.push_str(&format!(
                "{}: the policy gave no usable action on {}\n",
                m.as_str(),
                t.failures_text()
            ));
        }
        if let Some(k) = stiffness_summary(rs) {
            text.push_str(&format!(
                "{}: stiffness read in {} trial(s), clipped to the readout's range in {}, median error {:.0} %\n",
                m.as_str(),
                k.read,
                k.clipped,
                100.0 * k.median_relative_error
            ));
        }
        let c = clamps(rs);
        for (what, counts) in [
            ("tactile reflex acted", &c.reflex),
            ("proposals beyond a bound by > 2 % of its range", &c.clamped),
        ] {
            if !counts.is_empty() {
                let list: Vec<String> = counts.iter().map(|(k, n)| format!("{k} {n}")).collect();
                text.push_str(&format!(
                    "{}: {what}, ticks of {}: {}\n",
                    m.as_str(),
                    c.ticks,
                    list.join(", ")
                ));
            }
        }
    }
    if !permuted.is_empty() {
        text.push_str("\ntouch permuted across trials (trial i reads trial i + 1's latents, comparisons and contact geometry)\n");
        text.push_str(&table::render(permuted));
    }
    for row in sweep {
        text.push_str(&format!("\nsweep: {}\n", row.variant.name));
        text.push_str(&table::render(&row.table));
    }
    text
}

/// `--calibrate-vla`: the offset that centres the VLA rule's deformation on the target, from the
/// training cups' trials just run (with the scene's own offset): new = old - mean(achieved -
/// target) over the trials whose cup was gripped (a larger offset closes further).
fn calibrate_vla(a: &TrialsArgs, task: &TaskConfig, records: &Records) -> Result<bool> {
    let Some((_, rs)) = records.iter().find(|(c, _)| c.name == Mode::Vla.as_str()) else {
        anyhow::bail!("no trials");
    };
    let scene = rs.first().map_or("", |r| r.scene.as_str());
    let old = unitac_pipeline::load_scene(scene, a.scene_dir.clone())
        .map_err(|e| config(e.to_string()))
        .and_then(|s| unitac_trials::run::policy_params(&s).map_err(|e| config(e.to_string())))?
        .vla_offset_m;
    let target = task.cup_criteria.target_deformation_m;
    let errs: Vec<f64> = rs
        .iter()
        .filter_map(|r| match &r.outcome {
            TaskOutcome::Cup(c) if c.held => Some(c.deformation_m - target),
            _ => None,
        })
        .collect();
    if errs.is_empty() {
        anyhow::bail!("no training cup was gripped: nothing to calibrate on");
    }
    let mean = errs.iter().sum::<f64>() / errs.len() as f64;
    let sd = (errs.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / errs.len() as f64).sqrt();
    let new = old - mean;
    unitac_cli::emit(format!(
        "{} of {} training cups gripped: deformation error mean {mean:+.5} m, sd {sd:.5} m with \
         vla_offset_m {old:.5}\nvla_offset_m: {new:.5}\n",
        errs.len(),
        rs.len(),
    ))?;
    if let Some((_, rs)) = records.iter().find(|(c, _)| c.name == VLA_FORCE) {
        unitac_cli::emit(calibrate_force_law(rs)?)?;
    }
    Ok(true)
}

/// The force rule's stiffness law from the training cups: least squares of ln k on ln(D / 80
/// mm) over the trials, k and D the cups' true stiffness and diameter: a calibration against
/// reference values, as the touch readouts are fitted on true labels (fitted on the camera's
/// noisy widths instead, the slope flattens, -2.1 for -3, and the law under-reads wider cups'
/// softness).
fn calibrate_force_law(rs: &[TrialRecord]) -> Result<String> {
    let pts: Vec<(f64, f64)> = rs
        .iter()
        .filter_map(|r| r.stiffness.as_ref())
        .map(|s| ((s.true_diameter_m / 0.08).ln(), s.true_n_per_m.ln()))
        .filter(|(x, y)| x.is_finite() && y.is_finite())
        .collect();
    if pts.len() < 3 {
        anyhow::bail!("fewer than 3 training cups read by the force rule: nothing to fit");
    }
    let n = pts.len() as f64;
    let (mx, my) = (
        pts.iter().map(|p| p.0).sum::<f64>() / n,
        pts.iter().map(|p| p.1).sum::<f64>() / n,
    );
    let sxx: f64 = pts.iter().map(|p| (p.0 - mx).powi(2)).sum();
    let sxy: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    if sxx <= 0.0 {
        anyhow::bail!("the training cups' camera widths do not vary: nothing to fit");
    }
    let e = sxy / sxx;
    let k80 = (my - e * mx).exp();
    let resid = (pts
        .iter()
        .map(|p| (p.1 - (my + e * (p.0 - mx))).powi(2))
        .sum::<f64>()
        / n)
        .sqrt();
    Ok(format!(
        "{} training cups for the force rule: ln k residual {resid:.3} (rms)\n\
         vla_stiffness_at_80mm_n_per_m: {k80:.1}\nvla_stiffness_exponent: {e:.3}\n",
        pts.len()
    ))
}

/// Points of one trace value over time.
fn series(r: &TrialRecord, f: impl Fn(&unitac_trials::TraceRow) -> f64) -> Vec<(f64, f64)> {
    r.trace.iter().map(|row| (row.t_s, f(row))).collect()
}

/// One PNG per task: cup, deformation over time per mode (the target band); fabric, grip force
/// and slip since the grasp over time per mode. The first few trials of each mode.
fn plot(dir: &Path, scene: &str, kind: TaskKind, records: &Records) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("--plot {}", dir.display()))?;
    let strokes = [Stroke::Solid, Stroke::Dashed, Stroke::Solid];
    let mut figure;
    match kind.plot() {
        PlotKind::Deformation => {
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
                        s = s.label(m.as_str());
                    }
                    chart = chart.series(s);
                }
            }
            figure = Figure::new(1000, 560).panel(chart);
        }
        PlotKind::ForceAndSlip => {
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
                        f = f.label(m.as_str());
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
            scene
        ))
        .legend_from_series();
    let path = dir.join(format!("{}.png", scene));
    figure
        .save(&path)
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}
