//! `unitac-lab`: the lab's tools of the UniTac robot stack: evaluations against the mock
//! sensor's truth, benchmarks beside the Python baselines, reports with plots, training sets,
//! demonstrations and closed-loop grasp trials. The robot's commands are `unitac`'s
//! (crates/cli), whose library this binary shares (the grammar's parse, the exit codes, stdout).
//!
//! Exit codes (the table in crates/cli/README.md): 0 success; 1 the work failed or produced
//! errors (stdout closed or full, a trial where the policy never acted); 2 bad usage or
//! configuration (unknown scene, bad value, a directory that cannot be made). The reason is one
//! line on stderr, `unitac-lab: <reason>`.

mod bench;
mod dataset;
mod decode_bench;
mod demos;
mod depth;
mod eval;
mod policy_bench;
mod progress;
mod render_bench;
mod report_sim;
mod sampler;
mod scratch;
mod sim_charts;
mod slip_eval;
mod touch_dataset;
mod trials;

use clap::{Parser, Subcommand};
use std::path::PathBuf;
use std::process::ExitCode;
use unitac_cli::{args, emit, emit_report};

#[derive(Parser, Debug)]
#[command(
    name = "unitac-lab",
    version,
    about = "UniTac lab tools: evaluations, benchmarks, reports, datasets, demonstrations, trials"
)]
struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand, Debug)]
enum Cmd {
    /// Measure quality against ground truth (mock sensor): `eval contact`, `eval slip`,
    /// `eval depth`.
    Eval {
        /// What to evaluate.
        what: EvalTarget,
        /// Print the report as one JSON object instead of tables.
        #[arg(long)]
        json: bool,
        /// `eval depth`: directory for PNGs of frame, estimated and true depth.
        #[arg(long)]
        out: Option<PathBuf>,
        /// `eval contact`: minutes of simulated idle time for the false-episode count.
        #[arg(long, default_value_t = 10.0, value_parser = args::f64_in(0.0, 600.0))]
        idle_minutes: f64,
    },
    /// Benchmarks, side by side with the Python a user would otherwise run where there is one:
    /// `bench contact`, `bench replay`, `bench sampler`, `bench render` (mock sensor frames),
    /// `bench decode` (camera JPEG and YUYV decoding), `bench depth` (depth from one image),
    /// `bench policy` (the policy's control tick and a paced loop's period, per scene and mode).
    Bench {
        /// What to time.
        what: BenchTarget,
        /// Print the timings as one JSON object instead of text.
        #[arg(long)]
        json: bool,
        /// Distinct frames (`bench decode`: the first 8 of them, generated JPEGs; `bench depth`:
        /// the first 200, ball presses).
        #[arg(long, default_value_t = 140, value_parser = args::int_in(1usize, 10_000))]
        frames: usize,
        /// Passes over the frames (`bench policy`: episodes per scene and mode).
        #[arg(long, default_value_t = 5, value_parser = args::int_in(1usize, 1000))]
        repeat: usize,
        /// Skip the Python baseline.
        #[arg(long)]
        no_python: bool,
        /// `bench policy`: ticks of the real-time paced loop per scene (0: none).
        #[arg(long, default_value_t = 300)]
        ticks: usize,
        /// `bench policy`: an ONNX policy directory (default: the test MLP, generated).
        #[arg(long)]
        policy: Option<PathBuf>,
    },
    /// Error against run time, with tables and PNG plots: `report sampler` (flow sampler),
    /// `report sim` (the simulator's integrators on soft, stiff and extreme cups, stability map).
    Report {
        /// What to report on.
        what: ReportTarget,
        /// Print the report as one JSON object instead of tables.
        #[arg(long)]
        json: bool,
        /// Directory for the PNG plots (default: $UNITAC_ROOT/.build/report or ./report).
        #[arg(long)]
        out: Option<PathBuf>,
        /// `report sampler`: timed repetitions per configuration (median).
        #[arg(long, default_value_t = 5, value_parser = args::int_in(1usize, 1000))]
        repeat: usize,
    },
    /// Write a training set: `dataset fabrics --out DIR` (mock presses on fabrics with known
    /// properties, for the property head: --train, --test, --seed) or `dataset touch --split S
    /// --seeds 1,2 --trials N --sensor K --out DIR` (the camera's values and the sensor prior of
    /// cups and fabrics before contact, with the encoder's latent of their touch, for the touch
    /// projector).
    Dataset {
        /// Which training set.
        what: DatasetTarget,
        /// Directory to write the set into (created if missing).
        #[arg(long)]
        out: PathBuf,
        /// `dataset fabrics`: training samples (train + test: 1 to 100000).
        #[arg(long, default_value_t = 240, value_parser = args::int_in(0usize, dataset::MAX_SAMPLES))]
        train: usize,
        /// `dataset fabrics`: test samples, drawn after the training ones.
        #[arg(long, default_value_t = 120, value_parser = args::int_in(0usize, dataset::MAX_SAMPLES))]
        test: usize,
        /// `dataset fabrics`: seed of the fabric draws and the mock sensor's noise.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        #[command(flatten)]
        set: TrialSet,
        /// `dataset touch`: sensor kind: a profile of sensors/ (gelsight-mini, digit, generic, ...) or of $UNITAC_SENSORS.
        #[arg(long, default_value = "gelsight-mini")]
        sensor: unitac_core::SensorKind,
    },
    /// Demonstrations of the scripted expert with what a policy of every mode could observe,
    /// through each scene's tactile stages (scenes of one task, comma-separated):
    /// `demos --scene S[,S2] --split train --seeds 1,2,3 --trials 10 --out DIR`.
    Demos {
        /// Scenes of one task, comma separated (the first one's contact state drives the cup's
        /// probe, its safety bounds are recorded).
        #[arg(long, value_delimiter = ',', required = true)]
        scene: Vec<String>,
        #[command(flatten)]
        set: TrialSet,
        /// Directory for demos.json (created if missing).
        #[arg(long)]
        out: PathBuf,
        /// DAgger: a learned scene of the same task drives the world (its stages, as in a
        /// trial), each tick labelled with the expert's command there.
        #[arg(long)]
        drive: Option<String>,
        /// The policy bundle (its manifest.json) the driving scene runs instead of the one it
        /// names.
        #[arg(long, requires = "drive")]
        drive_model: Option<PathBuf>,
        /// Whose demonstrations: vla | vtla_real | vtla_pred (the expert decides from what that
        /// mode observes: vtla_real probes the cup and chooses the fabric by touch, vla and
        /// vtla_pred do neither). Default: the first scene's mode.
        #[arg(long)]
        mode: Option<String>,
    },
    /// Closed-loop grasp trials in the sim world: each mode's scene
    /// (`<scene>_<mode>.yaml`) N times, the success table beside the paper's (`--json`, `--plot DIR`).
    Trials(trials::TrialsArgs),
}

#[derive(clap::ValueEnum, Clone, Copy, Debug)]
enum EvalTarget {
    /// The contact detector against the mock sensor's truth: a press-depth sweep, false
    /// episodes over idle minutes, the contact area on ball presses.
    Contact,
    /// The slip stage's shear, rotation and slip flag against the renderer's tangential truth.
    Slip,
    /// Depth from one image on mock ball presses against their exact depth: RMSE, penetration
    /// error, contact area against the Hertz and geometric discs, at several depths, noise and
    /// shading levels.
    Depth,
}

/// Which trials of the task worlds: the split's objects, seeds and trials per seed.
#[derive(clap::Args, Debug)]
struct TrialSet {
    /// Which objects of objects/split.yaml the trials draw.
    #[arg(long, value_enum, default_value = "train")]
    split: DemoSplit,
    /// Seeds of the trial draws, comma separated.
    #[arg(long, value_delimiter = ',', default_value = "1")]
    seeds: Vec<u64>,
    /// Trials per seed.
    #[arg(long, default_value_t = 10, value_parser = args::int_in(1u32, 100_000))]
    trials: u32,
}

#[derive(clap::ValueEnum, Clone, Copy, Debug)]
enum DemoSplit {
    /// The training objects of objects/split.yaml.
    Train,
    /// The unseen objects of objects/split.yaml.
    Unseen,
}

impl From<DemoSplit> for unitac_sim::task::Split {
    fn from(s: DemoSplit) -> Self {
        match s {
            DemoSplit::Train => unitac_sim::task::Split::Train,
            DemoSplit::Unseen => unitac_sim::task::Split::Unseen,
        }
    }
}

#[derive(clap::ValueEnum, Clone, Copy, Debug)]
enum DatasetTarget {
    /// Mock presses on fabrics with known properties, for the property head.
    Fabrics,
    /// The camera's values and the sensor prior before contact, with the encoder's latent of
    /// the touch, for the touch projector.
    Touch,
}

#[derive(clap::ValueEnum, Clone, Copy, Debug)]
enum BenchTarget {
    /// The contact detector per frame vs Python (numpy + OpenCV, as in the GelSight SDK).
    Contact,
    /// A bag's images read and through the contact stage, vs Python.
    Replay,
    /// The flow sampler's models per call and batched.
    Sampler,
    /// The mock sensor's renderer per frame.
    Render,
    /// GelSight Mini MJPEG 3280x2464 -> 320x240 and YUYV 320x240 -> RGB, vs OpenCV.
    Decode,
    /// The policy tick per scene and mode (--repeat episodes each), with an ONNX policy's act,
    /// and a loop paced at the control rate (--ticks), vs Python onnxruntime.
    Policy,
    /// Depth from one image per frame (320x240, 640x480) vs gs_sdk's path a GelSight user
    /// runs (numpy + scipy), the read-pass floor, and the share of one core at 25 fps.
    Depth,
}

#[derive(clap::ValueEnum, Clone, Copy, Debug)]
enum ReportTarget {
    /// The flow sampler: error against run time per step count.
    Sampler,
    /// The simulator's integrators: error, stability map (tables and PNG plots).
    Sim,
}

/// The command line's grammar: [`Cli`] ([`unitac_cli::command`]).
fn command() -> clap::Command {
    unitac_cli::command::<Cli>()
}

fn main() -> ExitCode {
    unitac_cli::init_logging();
    let cli: Cli = match unitac_cli::parse(command()) {
        Ok(c) => c,
        Err(code) => return code,
    };
    unitac_cli::exit_code(dispatch(cli.cmd), 1)
}

/// One command: Ok(false) when it ran but something in it failed (exit 1).
fn dispatch(cmd: Cmd) -> anyhow::Result<bool> {
    match cmd {
        Cmd::Eval {
            what,
            json,
            out,
            idle_minutes,
        } => cmd_eval(what, json, out, idle_minutes),
        Cmd::Report {
            what,
            json,
            out,
            repeat,
        } => {
            let out = out.unwrap_or_else(|| match std::env::var_os("UNITAC_ROOT") {
                Some(r) => PathBuf::from(r).join(".build/report"),
                None => PathBuf::from("report"),
            });
            match what {
                ReportTarget::Sampler => {
                    emit_report(sampler::report(&out, repeat), json, |r| r.text())
                }
                ReportTarget::Sim => report_sim::report_sim(json, &out),
            }
        }
        Cmd::Bench {
            what,
            json,
            frames,
            repeat,
            no_python,
            ticks,
            policy,
        } => cmd_bench(
            what,
            json,
            BenchSize {
                frames,
                repeat,
                python: !no_python,
                ticks,
                policy,
            },
        ),
        Cmd::Dataset {
            what: DatasetTarget::Fabrics,
            out,
            train,
            test,
            seed,
            ..
        } => dataset::fabrics(&out, train, test, seed).map(|()| true),
        Cmd::Dataset {
            what: DatasetTarget::Touch,
            out,
            set,
            sensor,
            ..
        } => touch_dataset::touch(set.split.into(), &set.seeds, set.trials, sensor, &out)
            .and_then(emit)
            .map(|()| true),
        Cmd::Demos {
            scene,
            set,
            out,
            drive,
            drive_model,
            mode,
        } => {
            let driver = drive.map(|scene| demos::Driver {
                scene,
                model: drive_model,
            });
            demos::demos(
                &scene,
                set.split.into(),
                &set.seeds,
                set.trials,
                &out,
                driver,
                mode.as_deref(),
            )
            .and_then(emit)
            .map(|()| true)
        }
        Cmd::Trials(args) => trials::run(args),
    }
}

/// `unitac-lab eval contact | depth | slip`.
fn cmd_eval(
    what: EvalTarget,
    json: bool,
    out: Option<PathBuf>,
    idle_minutes: f64,
) -> anyhow::Result<bool> {
    match what {
        EvalTarget::Contact => {
            emit_report(eval::eval_contact(idle_minutes * 60.0), json, |r| r.text())
        }
        EvalTarget::Depth => emit_report(depth::eval_depth(out.as_deref()), json, |r| r.text()),
        EvalTarget::Slip => emit_report(slip_eval::eval_slip(), json, |r| r.text()),
    }
}

/// How much `unitac-lab bench` measures.
struct BenchSize {
    frames: usize,
    repeat: usize,
    python: bool,
    ticks: usize,
    policy: Option<PathBuf>,
}

/// `unitac-lab bench ...`: each target beside its baseline, its JSON or its table.
fn cmd_bench(what: BenchTarget, json: bool, n: BenchSize) -> anyhow::Result<bool> {
    fn both<R: serde::Serialize>(
        r: anyhow::Result<R>,
        text: impl FnOnce(&R) -> String,
    ) -> anyhow::Result<(String, String)> {
        let r = r?;
        Ok((serde_json::to_string(&r)?, text(&r)))
    }
    let spinner = progress::spinner(&format!("bench {what:?}").to_lowercase());
    let (frames, repeat, python) = (n.frames, n.repeat, n.python);
    let text = match what {
        BenchTarget::Contact => both(bench::bench_contact(frames, repeat, python), |r| r.text()),
        BenchTarget::Depth => both(depth::bench_depth(frames, repeat, python), |r| r.text()),
        BenchTarget::Replay => both(bench::bench_replay(frames, repeat, python), |r| r.text()),
        BenchTarget::Sampler => both(sampler::bench(repeat), |r| r.text()),
        BenchTarget::Decode => both(decode_bench::bench_decode(frames, repeat, python), |r| {
            r.text()
        }),
        BenchTarget::Render => both(
            render_bench::render_bench(repeat).map_err(anyhow::Error::from),
            |r| r.text(),
        ),
        BenchTarget::Policy => both(
            policy_bench::bench_policy(&policy_bench::Options {
                episodes: repeat,
                paced_ticks: n.ticks,
                python,
                policy: n.policy,
            }),
            |r| r.text(),
        ),
    };
    spinner.finish_and_clear();
    let (j, t) = text?;
    if json {
        emit(format_args!("{j}\n"))?;
    } else {
        emit(t)?;
    }
    Ok(true)
}

#[cfg(test)]
mod tests {
    use super::*;
    use unitac_cli::grammar;

    /// Every subcommand, option and positional of every `--help` page has a description, and so
    /// has every value of a subcommand's target (`eval contact|slip|depth`, ...).
    #[test]
    fn every_command_and_argument_has_a_description() {
        let cli = command();
        assert!(
            grammar::count(&cli) > 6,
            "{} commands",
            grammar::count(&cli)
        );
        let missing = grammar::undescribed(&cli);
        assert!(missing.is_empty(), "no description: {missing:#?}");
    }

    /// A command whose target is a positional (`bench contact`, ...) names each target in its
    /// summary, as `<command> <target>`.
    #[test]
    fn summaries_name_every_target() {
        let missing = grammar::targets_not_in_summaries(&command());
        assert!(missing.is_empty(), "not in the summary: {missing:?}");
    }

    /// Help texts are plain text: no markdown escapes (`\[mm]`) printed literally.
    #[test]
    fn help_texts_have_no_escapes() {
        let found = grammar::escaped_texts(&command());
        assert!(found.is_empty(), "{found:#?}");
    }
}
