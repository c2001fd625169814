//! `unitac-lab report sampler` and `unitac-lab bench sampler`: error against run time of the flow
//! sampler (Euler / midpoint / Heun x steps x guidance) on two velocity models: the reference
//! bundle's analytic Gaussian (error against the exact solution) and the trained touch projector
//! (the touch bundle's, error against a 1024-step Heun reference) on an unseen cup's condition
//! (its camera values in the task world, the sensor prior of a mock GelSight Mini), with guards off
//! so failures show as errors; the guard verdict is reported beside each row. The bench also times
//! the two guidance branches as one batch-2 call against two calls, on the projector and on the
//! reference bundle's random-weight transformer (a timing fixture of the paper's DiT shape),
//! interleaved over several rounds, with the spread of the ratio.

use anyhow::Context;
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Instant;
use unitac_infer::flow::{
    Guards, OnnxVelocity, SampleConfig, Solver, exact_gaussian, noise, sample,
};
use unitac_infer::{Bundle, RuntimeConfig};
use unitac_plot::{self as plot, Axis, Chart, Figure, LegendEntry, Marker, PALETTE, Series};

pub const STEPS: [u32; 6] = [4, 8, 16, 32, 50, 64];
pub const GUIDANCE: [f64; 6] = [0.0, 1.0, 1.5, 3.0, 7.5, 20.0];
/// The trained case's name in rows and plots.
pub const PROJECTOR: &str = "projector";
const SEED: u64 = 17;
/// Target sigma of the Gaussian case (>= the models' declared sigma_min of 0.1).
const SIGMA_C: f64 = 0.2;

#[derive(Debug, Clone, Serialize)]
pub struct Row {
    pub model: String,
    pub solver: Solver,
    pub steps: u32,
    pub guidance: f64,
    pub model_calls: u32,
    /// Median wall time per sample \[s], batched guidance, one thread.
    pub time_s: f64,
    /// RMS error of the sample against the exact (Gaussian) or fine-step (projector) answer.
    pub error: f64,
    /// What the guards would say: "ok", or the start of their report.
    pub guard: String,
}

struct Case {
    name: &'static str,
    v: OnnxVelocity,
    prior: Vec<f32>,
    cond: Vec<f32>,
    mu: Vec<f32>,
}

fn models_dir() -> anyhow::Result<PathBuf> {
    std::env::var_os("UNITAC_MODELS")
        .map(PathBuf::from)
        .context("UNITAC_MODELS is not set (use scripts/unitac)")
}

fn bundle_dir() -> anyhow::Result<PathBuf> {
    Ok(models_dir()?.join("reference"))
}

/// The Gaussian case: prior N(0, 1), conditional N(mu, SIGMA_C^2).
fn gaussian_case() -> anyhow::Result<Case> {
    let b = Bundle::open(&bundle_dir()?)?;
    let g = b
        .load(&["velocity_gaussian"], &RuntimeConfig::default())?
        .into_iter()
        .next()
        .context("velocity_gaussian missing")?;
    let g = OnnxVelocity::new(g)?;
    use unitac_infer::flow::Velocity;
    let d = g.dim();
    let mu: Vec<f32> = noise(SEED + 1, d).iter().map(|v| 0.8 * v).collect();
    let gp = vec![0.0; d + 1];
    let gc: Vec<f32> = mu.iter().copied().chain([SIGMA_C.ln() as f32]).collect();
    Ok(Case {
        name: "gaussian",
        v: g,
        prior: gp,
        cond: gc,
        mu,
    })
}

/// The trained projector on an unseen cup: the cup the camera sees in the unseen split's first
/// trial, the sensor prior of a mock GelSight Mini's background.
fn projector_case() -> anyhow::Result<Case> {
    use unitac_core::SensorKind;
    let dir = models_dir()?.join("touch");
    let b = Bundle::open(&dir)?;
    let mut ms = b
        .load(&["encoder", "velocity"], &RuntimeConfig::default())?
        .into_iter();
    let (Some(enc), Some(v)) = (ms.next(), ms.next()) else {
        anyhow::bail!("{}: models missing", dir.display())
    };
    let v = OnnxVelocity::new(v)?;
    let mut prior = unitac_infer::prior::SensorPrior::new(b.manifest.preprocess.clone(), enc);
    let kind = SensorKind::GELSIGHT_MINI;
    let idle = unitac_sim::MockSensor::new(
        unitac_sim::MockConfig::new(kind, 3),
        unitac_sim::Scenario::idle(1.0),
    );
    let bg = crate::touch_dataset::background_of(idle, kind)?;
    let z_sen = prior.of(&bg)?;
    use unitac_sim::task::{Split, TaskConfig, TaskWorld, trial_rng};
    let world = TaskWorld::reset(&TaskConfig::cup(Split::Unseen), 101, 0);
    let visual =
        unitac_trials::bridge::visual_message(&world.observe_visual(&mut trial_rng(101, 0)));
    let (cond, prior) =
        unitac_infer::predict::conditions(v.spec(), v.cond_dims(), "cup", &z_sen, &visual)
            .map_err(|e| anyhow::anyhow!("{e}"))?;
    Ok(Case {
        name: PROJECTOR,
        v,
        prior,
        cond,
        mu: Vec::new(),
    })
}

/// The reference bundle's random-weight transformer, for timing only (SPSS layout: prior =
/// sensor only, conditional = object + sensor).
fn timing_fixture_case() -> anyhow::Result<Case> {
    let b = Bundle::open(&bundle_dir()?)?;
    let t = b
        .load(&["velocity_timing_fixture"], &RuntimeConfig::default())?
        .into_iter()
        .next()
        .context("velocity_timing_fixture missing")?;
    let t = OnnxVelocity::new(t)?;
    use unitac_infer::flow::Velocity;
    let c = t.cond_dim();
    let half = (c - 1) / 2;
    let sen = noise(SEED + 2, half);
    let obj = noise(SEED + 3, half);
    let prior: Vec<f32> = vec![0.0; half]
        .into_iter()
        .chain(sen.iter().copied())
        .chain([0.0])
        .collect();
    let cond: Vec<f32> = obj.into_iter().chain(sen).chain([1.0]).collect();
    Ok(Case {
        name: "timing fixture",
        v: t,
        prior,
        cond,
        mu: Vec::new(),
    })
}

fn cases() -> anyhow::Result<Vec<Case>> {
    Ok(vec![gaussian_case()?, projector_case()?])
}

fn rms(a: &[f32], b: &[f64]) -> f64 {
    let s: f64 = a
        .iter()
        .zip(b)
        .map(|(x, y)| (f64::from(*x) - y).powi(2))
        .sum();
    let e = (s / a.len().max(1) as f64).sqrt();
    if a.iter().all(|v| v.is_finite()) {
        e
    } else {
        f64::INFINITY
    }
}

fn off() -> Guards {
    Guards {
        enabled: false,
        sigma_min: 0.1,
        growth: 4.0,
    }
}

/// Timed sample: (median time \[us], outcome of the last run).
fn timed(
    case: &mut Case,
    cfg: &SampleConfig,
    reps: usize,
) -> anyhow::Result<(f64, unitac_infer::flow::Outcome)> {
    let mut times = Vec::with_capacity(reps);
    let mut last = None;
    for _ in 0..reps {
        let t0 = Instant::now();
        let out = sample(&mut case.v, cfg, &off(), &case.prior, &case.cond)?;
        times.push(t0.elapsed().as_secs_f64());
        last = Some(out);
    }
    Ok((unitac_core::timing(times).median_s, last.context("no run")?))
}

fn truth(case: &mut Case, s: f64) -> anyhow::Result<Vec<f64>> {
    if case.name == "gaussian" {
        let z = noise(SEED, case.mu.len());
        return Ok(z
            .iter()
            .zip(&case.mu)
            .map(|(&z, &m)| exact_gaussian(f64::from(z), 0.0, 1.0, f64::from(m), SIGMA_C, s))
            .collect());
    }
    let cfg = SampleConfig {
        solver: Solver::Heun,
        steps: 1024,
        guidance: s,
        seed: SEED,
        batched: true,
    };
    let out = sample(&mut case.v, &cfg, &off(), &case.prior, &case.cond)?;
    Ok(out.x.iter().map(|&v| f64::from(v)).collect())
}

pub fn table(reps: usize) -> anyhow::Result<Vec<Row>> {
    let mut rows = Vec::new();
    let cases = cases()?;
    let bar = crate::progress::bar(
        (cases.len() * GUIDANCE.len() * Solver::ALL.len() * STEPS.len()) as u64,
        "sampler table",
    );
    for mut case in cases {
        for s in GUIDANCE {
            let exact = truth(&mut case, s)?;
            for solver in Solver::ALL {
                for steps in STEPS {
                    let cfg = SampleConfig {
                        solver,
                        steps,
                        guidance: s,
                        seed: SEED,
                        batched: true,
                    };
                    let (time_s, out) = timed(&mut case, &cfg, reps)?;
                    let g = Guards::new(case.v.sigma_min);
                    let guarded = sample(&mut case.v, &cfg, &g, &case.prior, &case.cond)?;
                    let guard = if guarded.valid {
                        "ok".to_string()
                    } else {
                        guarded.report.split(':').next().unwrap_or("").to_string()
                    };
                    rows.push(Row {
                        model: case.name.into(),
                        solver,
                        steps,
                        guidance: s,
                        model_calls: out.model_calls,
                        time_s,
                        error: rms(&out.x, &exact),
                        guard,
                    });
                    bar.inc(1);
                }
            }
        }
    }
    bar.finish_and_clear();
    Ok(rows)
}

/// Per solver, per guidance scale: (steps, stable) cells.
pub type StabilityMap = Vec<(Solver, Vec<(f64, Vec<(u32, bool)>)>)>;

#[derive(Debug, Serialize)]
pub struct Report {
    pub rows: Vec<Row>,
    /// Per model (Gaussian, projector): solver -> guidance -> steps -> stable (finite, error
    /// < 0.5 against its reference).
    pub stability: Vec<(String, StabilityMap)>,
    pub plots: Vec<PathBuf>,
}

pub const STAB_S: [f64; 6] = [1.0, 1.5, 3.0, 7.5, 20.0, 50.0];
pub const STAB_N: [u32; 7] = [2, 4, 8, 16, 32, 64, 128];

/// Stable cells of `case` (finite, rms error < 0.5 against its reference).
fn stability(case: &mut Case) -> anyhow::Result<StabilityMap> {
    let mut out = Vec::new();
    for solver in Solver::ALL {
        let mut by_s = Vec::new();
        for s in STAB_S {
            let exact = truth(case, s)?;
            let mut row = Vec::new();
            for n in STAB_N {
                let cfg = SampleConfig {
                    solver,
                    steps: n,
                    guidance: s,
                    seed: SEED,
                    batched: true,
                };
                let o = sample(&mut case.v, &cfg, &off(), &case.prior, &case.cond)?;
                row.push((n, rms(&o.x, &exact) < 0.5));
            }
            by_s.push((s, row));
        }
        out.push((solver, by_s));
    }
    Ok(out)
}

pub fn report(out_dir: &Path, reps: usize) -> anyhow::Result<Report> {
    std::fs::create_dir_all(out_dir).with_context(|| out_dir.display().to_string())?;
    let rows = table(reps)?;
    let p1 = out_dir.join("sampler_error_vs_time.png");
    error_vs_time(&rows).save(&p1)?;
    let mut plots = vec![p1];
    let mut stab = Vec::new();
    for mut case in cases()? {
        let map = stability(&mut case)?;
        let p = out_dir.join(format!("sampler_stability_{}.png", case.name));
        stability_map(case.name, &map).save(&p)?;
        plots.push(p);
        stab.push((case.name.to_string(), map));
    }
    Ok(Report {
        rows,
        stability: stab,
        plots,
    })
}

const SOLVER_MARKERS: [Marker; 3] = [Marker::Circle, Marker::Square, Marker::Triangle];

/// Error against time: one panel per model x guidance, one line per solver; non-finite errors
/// (the sample blew up) as crosses on the panel's overflow strip.
fn error_vs_time(rows: &[Row]) -> Figure {
    let mut fig = Figure::new(1720, 820)
        .columns(GUIDANCE.len())
        .title("flow sampler: rms error against time per sample (guards off)");
    for model in ["gaussian", PROJECTOR] {
        for s in GUIDANCE {
            let what = if model == "gaussian" {
                "vs exact"
            } else {
                "vs Heun-1024"
            };
            let mut chart = Chart::new(
                format!("{model} {what}, s = {s}"),
                Axis::log("time per sample [s]"),
                Axis::log("rms error"),
            )
            .overflow("diverged");
            for (k, solver) in Solver::ALL.iter().enumerate() {
                let points = rows
                    .iter()
                    .filter(|r| r.model == model && r.guidance == s && r.solver == *solver)
                    .map(|r| (r.time_s, r.error))
                    .collect();
                chart = chart.series(
                    Series::new(PALETTE[k], points)
                        .label(solver.as_str())
                        .marker(SOLVER_MARKERS[k]),
                );
            }
            fig = fig.panel(chart);
        }
    }
    fig.legend_from_series().note(format!(
        "steps {STEPS:?} along each line; guidance s per column"
    ))
}

/// Stability map: one grid per solver, guidance (rows) x steps (columns).
fn stability_map(model: &str, stab: &StabilityMap) -> Figure {
    const STABLE: plot::Rgb = [120, 200, 120];
    const UNSTABLE: plot::Rgb = [230, 110, 110];
    let cols: Vec<String> = STAB_N.iter().map(|n| n.to_string()).collect();
    let rows: Vec<String> = STAB_S.iter().map(|s| s.to_string()).collect();
    let mut fig = Figure::new(1500, 480)
        .columns(Solver::ALL.len())
        .title(format!(
            "flow sampler on the {model} case: stable (finite, rms error < 0.5)"
        ));
    for (solver, by_s) in stab {
        let cells: Vec<Vec<(plot::Rgb, Option<String>)>> = by_s
            .iter()
            .map(|(_, r)| {
                r.iter()
                    .map(|(_, ok)| (if *ok { STABLE } else { UNSTABLE }, None))
                    .collect()
            })
            .collect();
        fig = fig.panel(Chart::heatmap(
            solver.as_str(),
            ("steps", &cols),
            ("guidance s", &rows),
            &cells,
        ));
    }
    fig.legend(LegendEntry::fill("stable", STABLE))
        .legend(LegendEntry::fill("unstable", UNSTABLE))
}

impl Report {
    pub fn text(&self) -> String {
        let mut s = String::from(
            "flow sampler: error against run time (guards off; 'guard' = what the guards would do)\n",
        );
        for model in ["gaussian", PROJECTOR] {
            s += &format!(
                "\n{model} ({})\n  s     solver    steps calls   time [us]     error   guard\n",
                if model == "gaussian" {
                    "error vs the exact solution"
                } else {
                    "error vs Heun-1024"
                }
            );
            for r in self.rows.iter().filter(|r| r.model == model) {
                s += &format!(
                    "  {:<5} {:<9} {:>5} {:>5} {:>11.1} {:>9.2e}   {}\n",
                    r.guidance,
                    r.solver.as_str(),
                    r.steps,
                    r.model_calls,
                    r.time_s * 1e6,
                    r.error,
                    r.guard
                );
            }
        }
        for (model, map) in &self.stability {
            s += &format!(
                "\nstability map ({model}; S = finite and rms error < 0.5 against its reference, U = not)\n"
            );
            for (solver, by_s) in map {
                s += &format!(
                    "  {:<9} steps {}\n",
                    solver.as_str(),
                    STAB_N.iter().map(|n| format!("{n:>4}")).collect::<String>()
                );
                for (g, row) in by_s {
                    s += &format!(
                        "  {:<9} s={g:<4}{}\n",
                        "",
                        row.iter()
                            .map(|(_, ok)| if *ok { "   S" } else { "   U" })
                            .collect::<String>()
                    );
                }
            }
        }
        for p in &self.plots {
            s += &format!("plot: {}\n", p.display());
        }
        s
    }
}

/// The paper's Euler-50 against the cheapest (solver, steps) that is at least as accurate, on one
/// velocity model at s = 1.5.
#[derive(Debug, Serialize)]
pub struct VersusEuler50 {
    pub model: String,
    pub euler50_error: f64,
    pub euler50_s: f64,
    pub best: Option<Row>,
    pub best_time_ratio: Option<f64>,
}

/// Both guidance branches in one batch-2 call against two calls, Heun-16 at s = 1.5 on one
/// model: medians of `rounds` interleaved rounds and the ratio's range over the rounds.
#[derive(Debug, Serialize)]
pub struct Batching {
    pub model: String,
    pub rounds: usize,
    pub batched_s: f64,
    pub two_calls_s: f64,
    /// two calls / one batch-2 call: median and range over the rounds.
    pub speedup: f64,
    pub speedup_min: f64,
    pub speedup_max: f64,
}

#[derive(Debug, Serialize)]
pub struct Bench {
    pub versus_euler50: Vec<VersusEuler50>,
    pub batching: Vec<Batching>,
    pub encoder_properties_s: f64,
}

/// Rounds of the batching comparison (each times both forms `reps` times, alternating).
pub const BATCH_ROUNDS: usize = 7;

fn batching(case: &mut Case, reps: usize) -> anyhow::Result<Batching> {
    let heun16 = SampleConfig {
        solver: Solver::Heun,
        steps: 16,
        guidance: 1.5,
        seed: SEED,
        batched: true,
    };
    let two = SampleConfig {
        batched: false,
        ..heun16.clone()
    };
    let (mut b, mut t, mut ratio) = (Vec::new(), Vec::new(), Vec::new());
    for _ in 0..BATCH_ROUNDS {
        let (tb, _) = timed(case, &heun16, reps)?;
        let (tt, _) = timed(case, &two, reps)?;
        b.push(tb);
        t.push(tt);
        ratio.push(tt / tb);
    }
    let med = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let (lo, hi) = ratio
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(l, h), &r| (l.min(r), h.max(r)));
    Ok(Batching {
        model: case.name.into(),
        rounds: BATCH_ROUNDS,
        batched_s: med(&mut b),
        two_calls_s: med(&mut t),
        speedup: med(&mut ratio),
        speedup_min: lo,
        speedup_max: hi,
    })
}

pub fn bench(reps: usize) -> anyhow::Result<Bench> {
    let s = 1.5;
    let mut versus = Vec::new();
    let mut all = cases()?;
    for case in all.iter_mut() {
        let exact = truth(case, s)?;
        let mut rows = Vec::new();
        for solver in Solver::ALL {
            for steps in [2, 3, 4, 5, 6, 8, 10, 12, 16, 20, 24, 32, 50] {
                let cfg = SampleConfig {
                    solver,
                    steps,
                    guidance: s,
                    seed: SEED,
                    batched: true,
                };
                let (t, out) = timed(case, &cfg, reps)?;
                rows.push(Row {
                    model: case.name.into(),
                    solver,
                    steps,
                    guidance: s,
                    model_calls: out.model_calls,
                    time_s: t,
                    error: rms(&out.x, &exact),
                    guard: String::new(),
                });
            }
        }
        let e50 = rows
            .iter()
            .find(|r| r.solver == Solver::Euler && r.steps == 50)
            .context("euler 50")?
            .clone();
        let best = rows
            .iter()
            .filter(|r| r.error <= e50.error && !(r.solver == Solver::Euler && r.steps == 50))
            .min_by(|a, b| a.time_s.total_cmp(&b.time_s))
            .cloned();
        versus.push(VersusEuler50 {
            model: case.name.into(),
            euler50_error: e50.error,
            euler50_s: e50.time_s,
            best_time_ratio: best.as_ref().map(|b| b.time_s / e50.time_s),
            best,
        });
    }
    let mut batch = Vec::new();
    let projector = all.get_mut(1).context("projector case")?;
    batch.push(batching(projector, reps * 2)?);
    batch.push(batching(&mut timing_fixture_case()?, reps * 2)?);
    Ok(Bench {
        versus_euler50: versus,
        batching: batch,
        encoder_properties_s: encoder_latency(reps * 4)?,
    })
}

/// Median encoder + property head time per episode clip, on a mock fabric press.
fn encoder_latency(reps: usize) -> anyhow::Result<f64> {
    use unitac_core::SensorKind;
    let mut enc =
        unitac_infer::encoder::EncoderStage::new(&bundle_dir()?, &RuntimeConfig::default())?;
    let pre = unitac_infer::preprocess::Preprocess::reference();
    let obj = unitac_sim::Scenario::fabric("bench", 0.04, 0.9);
    let sensor = unitac_sim::MockSensor::new(
        unitac_sim::MockConfig::new(SensorKind::GELSIGHT_MINI, 3),
        crate::dataset::press(&obj, 0.5),
    );
    let clip = crate::dataset::first_clip(sensor, pre.clip_frames * 2)?;

    let mut t = Vec::new();
    for _ in 0..reps {
        let t0 = Instant::now();
        enc.encode(&clip).map_err(|e| anyhow::anyhow!("{e}"))?;
        t.push(t0.elapsed().as_secs_f64());
    }
    Ok(unitac_core::timing(t).median_s)
}

impl Bench {
    pub fn text(&self) -> String {
        let mut s = String::from(
            "flow sampler at s = 1.5 (the paper's setting), one thread, batched guidance\n",
        );
        for v in &self.versus_euler50 {
            s += &format!(
                "  {} ({}): paper's Euler-50 error {:.2e} in {:.0} us\n",
                v.model,
                if v.model == "gaussian" {
                    "error vs the exact solution"
                } else {
                    "trained, unseen cup, error vs Heun-1024"
                },
                v.euler50_error,
                v.euler50_s * 1e6
            );
            if let (Some(b), Some(r)) = (&v.best, v.best_time_ratio) {
                s += &format!(
                    "    cheapest at least as accurate: {} {} ({} calls), error {:.2e} in {:.0} us = {:.0} % of Euler-50's time\n",
                    b.solver.as_str(),
                    b.steps,
                    b.model_calls,
                    b.error,
                    b.time_s * 1e6,
                    100.0 * r
                );
            }
        }
        for b in &self.batching {
            s += &format!(
                "  guidance branches (Heun-16, {}): one batch-2 call {:.0} us, two calls {:.0} us: {:.2}x (median of {} rounds, range {:.2}-{:.2}x)\n",
                b.model,
                b.batched_s * 1e6,
                b.two_calls_s * 1e6,
                b.speedup,
                b.rounds,
                b.speedup_min,
                b.speedup_max
            );
        }
        s += &format!(
            "  encoder + property head per episode: {:.0} us\n",
            self.encoder_properties_s * 1e6
        );
        s
    }
}
