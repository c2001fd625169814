//! The simulator's numerics report: accuracy against run time of each integrator on soft, stiff
//! and extreme cups, and a stability map (wall stiffness x step size).
//!
//! The task is the paper's cup squeeze with a prescribed finger motion (so every method sees the
//! same input): from 0.4 mm open the finger closes at 4 mm/s to the position where the static
//! deformation is 1 cm (or the gel force reaches the gripper's 20 N limit, for walls too stiff to
//! dent), then holds 0.3 s. Measured: final deformation and peak grip force, against a reference
//! run with semi-implicit Euler at 1e-7 s (whose own error is estimated from a run at 2e-7 s).

use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::plot::{BLACK, Canvas, GREY, LogAxes, Marker, PlotError, Rgb};
use crate::world::{Cup, Gel, Method, Substep, World, WorldConfig, static_finger_for, static_wall};

/// Target deformation \[mm] and force limit \[N] of the task.
pub const TARGET_MM: f64 = 10.0;
pub const MAX_FORCE_N: f64 = 20.0;
/// Closing speed [mm/s], hold \[s], start \[mm].
pub const SPEED_MM_S: f64 = 40.0;
pub const HOLD_S: f64 = 0.3;
pub const START_MM: f64 = -0.4;
/// Reference step \[s].
pub const REF_STEP_S: f64 = 1e-7;
/// Step sizes of the accuracy runs \[s].
pub const STEPS_S: [f64; 9] = [1e-2, 3e-3, 1e-3, 3e-4, 1e-4, 3e-5, 1e-5, 3e-6, 1e-6];
/// The world's default control step \[s] (sub-stepped inside).
pub const DEFAULT_STEP_S: f64 = 1e-3;

/// The prescribed task for one cup.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Task {
    /// Final finger position \[mm].
    pub finger_mm: f64,
    /// End of the closing ramp and of the run \[s].
    pub close_s: f64,
    pub end_s: f64,
}

impl Task {
    pub fn for_cup(cup: &Cup) -> Self {
        let finger_mm = static_finger_for(cup, &Gel::default(), TARGET_MM, MAX_FORCE_N);
        let close_s = (finger_mm - START_MM) / SPEED_MM_S;
        Self {
            finger_mm,
            close_s,
            end_s: close_s + HOLD_S,
        }
    }
    /// Finger position at time t.
    pub fn finger_at(&self, t: f64) -> f64 {
        if t >= self.close_s {
            self.finger_mm
        } else {
            START_MM + SPEED_MM_S * t.max(0.0)
        }
    }
}

/// Result of one run of the task.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Outcome {
    pub final_deformation_mm: f64,
    /// Deformation the moment the finger stops (the end of the closing ramp) \[mm]: still
    /// dynamic, unlike the final one, which the hold lets settle to the static equilibrium.
    pub stop_deformation_mm: f64,
    pub peak_force_n: f64,
    /// Integrator steps taken (sub-steps included).
    pub steps: u64,
    /// Largest |x - x_static| in the first and the second half of the hold \[mm] (a growing
    /// oscillation = unstable).
    pub hold_swing_first_mm: f64,
    pub hold_swing_second_mm: f64,
    /// Why the run stopped early, if it did.
    pub diverged: Option<String>,
}

impl Outcome {
    /// Bounded: no divergence and the hold's oscillation does not grow.
    pub fn stable(&self) -> bool {
        self.diverged.is_none()
            && self.final_deformation_mm.is_finite()
            && !(self.hold_swing_second_mm > self.hold_swing_first_mm
                && self.hold_swing_second_mm > 1e-9)
    }
}

/// Run the task on `cup` with `method` at step `h` \[s].
pub fn run_task(cup: &Cup, method: Method, substep: Substep, h: f64) -> Outcome {
    let task = Task::for_cup(cup);
    let mut cfg = WorldConfig::new(cup.clone()).with_method(method, substep);
    cfg.start_mm = START_MM;
    let x_static = static_wall(cup, &cfg.gel, task.finger_mm);
    let mut w = World::new(cfg);
    // Steps that land exactly on the end of the closing ramp (no input kink inside a step).
    let n_close = (task.close_s / h).round().max(1.0) as u64;
    let h = task.close_s / n_close as f64;
    let n = n_close + ((task.end_s - task.close_s) / h).round().max(2.0) as u64;
    let hold_mid = task.close_s + 0.5 * (n - n_close) as f64 * h;
    let mut out = Outcome {
        final_deformation_mm: f64::NAN,
        stop_deformation_mm: f64::NAN,
        peak_force_n: 0.0,
        steps: 0,
        hold_swing_first_mm: 0.0,
        hold_swing_second_mm: 0.0,
        diverged: None,
    };
    for i in 1..=n {
        let t = i as f64 * h;
        match w.step_finger(h, task.finger_at(t)) {
            Ok(s) => {
                out.steps += u64::from(s.substeps);
                out.peak_force_n = out.peak_force_n.max(s.step_peak_force_n);
                out.final_deformation_mm = s.deformation_mm;
                if i == n_close {
                    out.stop_deformation_mm = s.deformation_mm;
                }
                let swing = (0.5 * s.deformation_mm - x_static).abs();
                if i > n_close && t > hold_mid {
                    out.hold_swing_second_mm = out.hold_swing_second_mm.max(swing);
                } else if i > n_close {
                    out.hold_swing_first_mm = out.hold_swing_first_mm.max(swing);
                }
            }
            Err(e) => {
                out.diverged = Some(e.to_string());
                out.final_deformation_mm = f64::NAN;
                out.stop_deformation_mm = f64::NAN;
                out.peak_force_n = f64::NAN;
                break;
            }
        }
    }
    out
}

/// One row of the accuracy table.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AccuracyRow {
    pub cup: String,
    pub method: Method,
    pub substeps: bool,
    pub step_s: f64,
    pub final_deformation_mm: f64,
    pub stop_deformation_mm: f64,
    pub peak_force_n: f64,
    /// |final deformation - reference| \[mm] (NaN when diverged).
    pub err_deformation_mm: f64,
    /// |deformation when the finger stops - reference| \[mm].
    pub err_stop_deformation_mm: f64,
    /// |peak force - reference| \[N].
    pub err_force_n: f64,
    /// Largest of the three relative errors.
    pub rel_err: f64,
    pub steps: u64,
    pub wall_s: f64,
    pub stable: bool,
    pub diverged: Option<String>,
}

#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Reference {
    pub cup: Cup,
    pub task: Task,
    pub final_deformation_mm: f64,
    pub stop_deformation_mm: f64,
    pub peak_force_n: f64,
    /// Difference to a run at twice the reference step (an estimate of its own error).
    pub self_err_deformation_mm: f64,
    pub self_err_stop_deformation_mm: f64,
    pub self_err_force_n: f64,
    /// Stability bounds at the end state \[s].
    pub bound_explicit_s: f64,
    pub bound_semi_implicit_s: f64,
    pub wall_s: f64,
}

/// One cell of the stability map.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StabilityCell {
    pub method: Method,
    pub k_n_per_mm: f64,
    pub step_s: f64,
    /// The bound (module docs of `world`) at the task's end state says stable.
    pub predicted_stable: bool,
    pub observed_stable: bool,
}

#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct NumericsReport {
    pub task: String,
    pub references: Vec<Reference>,
    pub accuracy: Vec<AccuracyRow>,
    pub map_stiffness_n_per_mm: Vec<f64>,
    pub map_steps_s: Vec<f64>,
    pub stability: Vec<StabilityCell>,
    /// Cells where prediction and observation disagree.
    pub map_disagreements: usize,
}

/// Options of the report (the fast variant is for tests).
#[derive(Debug, Clone, PartialEq)]
pub struct NumericsOptions {
    pub cups: Vec<Cup>,
    pub steps_s: Vec<f64>,
    pub ref_step_s: f64,
    pub map_stiffness: Vec<f64>,
    pub map_steps: Vec<f64>,
}

impl Default for NumericsOptions {
    fn default() -> Self {
        Self {
            cups: vec![Cup::soft(), Cup::stiff(), Cup::extreme()],
            steps_s: STEPS_S.to_vec(),
            ref_step_s: REF_STEP_S,
            // 0.01 .. 1000 N/mm: five decades.
            map_stiffness: (0..11).map(|i| 10f64.powf(-2.0 + 0.5 * i as f64)).collect(),
            map_steps: STEPS_S.iter().rev().copied().collect(),
        }
    }
}

/// Bounds of each explicit method at the task's end state (static equilibrium, finger held).
pub fn end_state_bounds(cup: &Cup) -> (f64, f64) {
    let task = Task::for_cup(cup);
    let gel = Gel::default();
    let x = static_wall(cup, &gel, task.finger_mm);
    let d = task.finger_mm - x;
    let k = cup.spring(x).1 + gel.elastic(d).1;
    let c = cup.damping() + if d > 0.0 { gel.c_n_s_per_mm } else { 0.0 };
    (
        Method::ExplicitEuler.stable_step(cup.mass(), k, c),
        Method::SemiImplicitEuler.stable_step(cup.mass(), k, c),
    )
}

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs().max(1e-12)
}

pub fn report(opts: &NumericsOptions) -> NumericsReport {
    report_with_progress(opts, &mut |_, _| {})
}

/// Units of work [`report_with_progress`] reports: one per cup, one per stability-map column.
pub fn report_steps(opts: &NumericsOptions) -> u64 {
    (opts.cups.len() + Method::ALL.len() * opts.map_stiffness.len()) as u64
}

/// [`report`], calling `progress(done, total)` after each unit of [`report_steps`].
pub fn report_with_progress(
    opts: &NumericsOptions,
    progress: &mut dyn FnMut(u64, u64),
) -> NumericsReport {
    let total = report_steps(opts);
    let mut done = 0;
    let mut references = Vec::new();
    let mut accuracy = Vec::new();
    for cup in &opts.cups {
        let t0 = Instant::now();
        let r = run_task(
            cup,
            Method::SemiImplicitEuler,
            Substep::Off,
            opts.ref_step_s,
        );
        let wall_s = t0.elapsed().as_secs_f64();
        let r2 = run_task(
            cup,
            Method::SemiImplicitEuler,
            Substep::Off,
            2.0 * opts.ref_step_s,
        );
        let (be, bs) = end_state_bounds(cup);
        let reference = Reference {
            cup: cup.clone(),
            task: Task::for_cup(cup),
            final_deformation_mm: r.final_deformation_mm,
            stop_deformation_mm: r.stop_deformation_mm,
            peak_force_n: r.peak_force_n,
            self_err_deformation_mm: (r.final_deformation_mm - r2.final_deformation_mm).abs(),
            self_err_stop_deformation_mm: (r.stop_deformation_mm - r2.stop_deformation_mm).abs(),
            self_err_force_n: (r.peak_force_n - r2.peak_force_n).abs(),
            bound_explicit_s: be,
            bound_semi_implicit_s: bs,
            wall_s,
        };
        let mut runs: Vec<(Method, Substep, f64)> = Vec::new();
        for m in Method::ALL {
            for &h in &opts.steps_s {
                runs.push((m, Substep::Off, h));
            }
        }
        // The world's default: semi-implicit Euler, sub-stepped at half its bound.
        for &h in &opts.steps_s {
            if h >= DEFAULT_STEP_S {
                runs.push((
                    Method::SemiImplicitEuler,
                    Substep::Stability { safety: 0.5 },
                    h,
                ));
            }
        }
        for (m, sub, h) in runs {
            // Best of three timings (the machine is shared); the outcome is deterministic.
            let t0 = Instant::now();
            let o = run_task(cup, m, sub, h);
            let mut wall_s = t0.elapsed().as_secs_f64();
            for _ in 0..2 {
                let t0 = Instant::now();
                std::hint::black_box(run_task(cup, m, sub, h));
                wall_s = wall_s.min(t0.elapsed().as_secs_f64());
            }
            let ed = (o.final_deformation_mm - reference.final_deformation_mm).abs();
            let ef = (o.peak_force_n - reference.peak_force_n).abs();
            accuracy.push(AccuracyRow {
                cup: cup.label.clone(),
                method: m,
                substeps: matches!(sub, Substep::Stability { .. }),
                step_s: h,
                final_deformation_mm: o.final_deformation_mm,
                stop_deformation_mm: o.stop_deformation_mm,
                peak_force_n: o.peak_force_n,
                err_deformation_mm: ed,
                err_stop_deformation_mm: (o.stop_deformation_mm - reference.stop_deformation_mm)
                    .abs(),
                err_force_n: ef,
                rel_err: rel(o.final_deformation_mm, reference.final_deformation_mm)
                    .max(rel(o.stop_deformation_mm, reference.stop_deformation_mm))
                    .max(rel(o.peak_force_n, reference.peak_force_n)),
                steps: o.steps,
                wall_s,
                stable: o.stable(),
                diverged: o.diverged.clone(),
            });
        }
        references.push(reference);
        done += 1;
        progress(done, total);
    }
    let mut stability = Vec::new();
    for m in Method::ALL {
        for &k in &opts.map_stiffness {
            let cup = Cup::new("map", 80.0, k);
            let (be, bs) = end_state_bounds(&cup);
            for &h in &opts.map_steps {
                let o = run_task(&cup, m, Substep::Off, h);
                let predicted_stable = match m {
                    Method::ExplicitEuler => h < be,
                    Method::SemiImplicitEuler => h < bs,
                    Method::BackwardEuler => true,
                };
                stability.push(StabilityCell {
                    method: m,
                    k_n_per_mm: k,
                    step_s: h,
                    predicted_stable,
                    observed_stable: o.stable(),
                });
            }
            done += 1;
            progress(done, total);
        }
    }
    let map_disagreements = stability
        .iter()
        .filter(|c| c.predicted_stable != c.observed_stable)
        .count();
    NumericsReport {
        task: format!(
            "close at {SPEED_MM_S} mm/s from {START_MM} mm to a static deformation of \
             {TARGET_MM} mm (or {MAX_FORCE_N} N), hold {HOLD_S} s; reference: semi-implicit \
             Euler at {:e} s",
            opts.ref_step_s
        ),
        references,
        accuracy,
        map_stiffness_n_per_mm: opts.map_stiffness.clone(),
        map_steps_s: opts.map_steps.clone(),
        stability,
        map_disagreements,
    }
}

const METHOD_COLOURS: [Rgb; 4] = [
    [214, 39, 40],
    [31, 119, 180],
    [44, 160, 44],
    [148, 103, 189],
];

fn series_style(m: Method, substeps: bool) -> (Rgb, &'static str) {
    match (m, substeps) {
        (_, true) => (METHOD_COLOURS[3], "semi-implicit + sub-steps"),
        (Method::ExplicitEuler, _) => (METHOD_COLOURS[0], "explicit Euler"),
        (Method::SemiImplicitEuler, _) => (METHOD_COLOURS[1], "semi-implicit Euler"),
        (Method::BackwardEuler, _) => (METHOD_COLOURS[2], "backward Euler (Newton)"),
    }
}

fn cup_marker(i: usize) -> Marker {
    [
        Marker::Circle,
        Marker::Square,
        Marker::Triangle,
        Marker::Diamond,
    ][i % 4]
}

impl NumericsReport {
    pub fn text(&self) -> String {
        use std::fmt::Write;
        let mut s = String::new();
        let _ = writeln!(s, "simulator numerics: {}", self.task);
        let _ = writeln!(
            s,
            "\nreferences (bounds at the end state: explicit Euler h < C/K, semi-implicit h < 2(sqrt(1+z^2)-z)/w)"
        );
        let _ = writeln!(
            s,
            "  cup      k [N/mm]  finger [mm]  final defo. [mm]  at stop [mm]  peak force [N]  self-error [mm / mm / N]        bound expl. [s]  bound semi [s]"
        );
        for r in &self.references {
            let _ = writeln!(
                s,
                "  {:<8} {:>8.3}  {:>11.3}  {:>16.6}  {:>12.6}  {:>14.6}  {:>7.1e} / {:>7.1e} / {:>7.1e}  {:>15.2e}  {:>14.2e}",
                r.cup.label,
                r.cup.k_n_per_mm,
                r.task.finger_mm,
                r.final_deformation_mm,
                r.stop_deformation_mm,
                r.peak_force_n,
                r.self_err_deformation_mm,
                r.self_err_stop_deformation_mm,
                r.self_err_force_n,
                r.bound_explicit_s,
                r.bound_semi_implicit_s
            );
        }
        let _ = writeln!(s, "\naccuracy against run time (one core, best of 3)");
        let _ = writeln!(
            s,
            "  cup      method                     step [s]   steps      time [ms]  err final [mm]  err stop [mm]  err peak [N]  rel. err"
        );
        for a in &self.accuracy {
            let (_, name) = series_style(a.method, a.substeps);
            let errs = if a.diverged.is_some() {
                format!("{:>14}  {:>13}  {:>12}  {:>8}", "diverged", "-", "-", "-")
            } else {
                format!(
                    "{:>14.2e}  {:>13.2e}  {:>12.2e}  {:>8.1e}{}",
                    a.err_deformation_mm,
                    a.err_stop_deformation_mm,
                    a.err_force_n,
                    a.rel_err,
                    if a.stable {
                        ""
                    } else {
                        "  (oscillation grows)"
                    }
                )
            };
            let _ = writeln!(
                s,
                "  {:<8} {:<26} {:>8.0e}  {:>9}  {:>9.2}  {}",
                a.cup,
                name,
                a.step_s,
                a.steps,
                a.wall_s * 1e3,
                errs
            );
        }
        let _ = writeln!(
            s,
            "\nstability map (S stable, U unstable: diverged or a growing oscillation; * = the bound predicted otherwise)"
        );
        for m in Method::ALL {
            let _ = writeln!(s, "  {m}");
            let mut hdr = String::from("    k [N/mm] \\ h [s]");
            for h in &self.map_steps_s {
                let _ = write!(hdr, " {:>6.0e}", h);
            }
            let _ = writeln!(s, "{hdr}");
            for &k in &self.map_stiffness_n_per_mm {
                let mut row = format!("    {:>17.3}", k);
                for &h in &self.map_steps_s {
                    if let Some(c) = self
                        .stability
                        .iter()
                        .find(|c| c.method == m && c.k_n_per_mm == k && c.step_s == h)
                    {
                        let mark = if c.observed_stable { "S" } else { "U" };
                        let flag = if c.predicted_stable == c.observed_stable {
                            " "
                        } else {
                            "*"
                        };
                        let _ = write!(row, " {:>5}{}", mark, flag);
                    }
                }
                let _ = writeln!(s, "{row}");
            }
        }
        let _ = writeln!(
            s,
            "  prediction and observation disagree in {} of {} cells",
            self.map_disagreements,
            self.stability.len()
        );
        s
    }

    /// Write `sim_accuracy.png` and `sim_stability.png` into `dir`.
    pub fn write_plots(&self, dir: &Path) -> Result<Vec<PathBuf>, PlotError> {
        let a = dir.join("sim_accuracy.png");
        self.accuracy_plot().save_png(&a)?;
        let b = dir.join("sim_stability.png");
        self.stability_plot().save_png(&b)?;
        Ok(vec![a, b])
    }

    /// Relative error against run time, log-log, one panel per measure; diverged runs as
    /// crosses on a band at the top.
    pub fn accuracy_plot(&self) -> Canvas {
        let (w, h) = (1640u32, 680u32);
        let mut c = Canvas::new(w, h);
        let ok: Vec<&AccuracyRow> = self.accuracy.iter().collect();
        let times: Vec<f64> = ok.iter().map(|a| a.wall_s.max(1e-6)).collect();
        let tmin = times.iter().cloned().fold(f64::INFINITY, f64::min);
        let tmax = times.iter().cloned().fold(0.0, f64::max);
        let x0 = tmin.log10().floor();
        let x1 = tmax.log10().ceil().max(x0 + 1.0);
        type Measure = fn(&AccuracyRow, &Reference) -> f64;
        let panels: [(&str, Measure); 3] = [
            ("final deformation", |a, r| {
                rel(a.final_deformation_mm, r.final_deformation_mm)
            }),
            ("deformation when the finger stops", |a, r| {
                rel(a.stop_deformation_mm, r.stop_deformation_mm)
            }),
            ("peak grip force", |a, r| {
                rel(a.peak_force_n, r.peak_force_n)
            }),
        ];
        for (pi, (name, measure)) in panels.iter().enumerate() {
            // Points of this panel, and the decades they span (floor 1e-16).
            let mut pts: Vec<(usize, Method, bool, f64, Option<f64>)> = Vec::new();
            for (ci, r) in self.references.iter().enumerate() {
                for a in self.accuracy.iter().filter(|a| a.cup == r.cup.label) {
                    let e = if a.diverged.is_some() || !a.stable {
                        None
                    } else {
                        Some(measure(a, r).max(1e-16))
                    };
                    pts.push((ci, a.method, a.substeps, a.wall_s.max(1e-6), e));
                }
            }
            let es: Vec<f64> = pts.iter().filter_map(|p| p.4).collect();
            let emin = es.iter().cloned().fold(1.0, f64::min);
            let emax = es.iter().cloned().fold(1e-16, f64::max);
            let y0 = emin.log10().floor();
            // One decade of headroom for the band of diverged runs.
            let y1 = emax.log10().ceil().max(y0 + 2.0) + 1.0;
            let ax = LogAxes {
                left: 130.0 + pi as f64 * 520.0,
                top: 60.0,
                width: 400.0,
                height: 420.0,
                x0,
                x1,
                y0,
                y1,
            };
            ax.draw(&mut c, "run time [s]", "relative error", name);
            let band_y = ax.px(1.0, 10f64.powf(y1 - 0.5)).1;
            let sep = ax.px(1.0, 10f64.powf(y1 - 1.0)).1;
            c.dashed((ax.left, sep), (ax.left + ax.width, sep), GREY, 1.0, 4.0);
            c.text(
                (ax.left + ax.width - 150.0) as i64,
                band_y as i64 - 7,
                "x diverged",
                GREY,
                2,
            );
            for (ci, _) in self.references.iter().enumerate() {
                for m in Method::ALL {
                    for sub in [false, true] {
                        let (col, _) = series_style(m, sub);
                        let mut line: Vec<(f64, f64)> = Vec::new();
                        for p in pts.iter().filter(|p| p.0 == ci && p.1 == m && p.2 == sub) {
                            match p.4 {
                                Some(e) => line.push(ax.px(p.3, e)),
                                None => {
                                    let (px, _) = ax.px(p.3, 1.0);
                                    c.marker(px, band_y, Marker::Cross, col, 5.0);
                                }
                            }
                        }
                        for q in line.windows(2) {
                            c.line(q[0].0, q[0].1, q[1].0, q[1].1, col, 1.5);
                        }
                        for q in &line {
                            c.marker(q.0, q.1, cup_marker(ci), col, 5.0);
                        }
                    }
                }
            }
        }
        // Legend: methods (colours), then cups (markers); wraps at the canvas edge.
        let mut items: Vec<(Option<Rgb>, Option<Marker>, String)> = Vec::new();
        for (m, sub) in [
            (Method::ExplicitEuler, false),
            (Method::SemiImplicitEuler, false),
            (Method::BackwardEuler, false),
            (Method::SemiImplicitEuler, true),
        ] {
            let (col, name) = series_style(m, sub);
            items.push((Some(col), None, name.to_string()));
        }
        for (ci, r) in self.references.iter().enumerate() {
            items.push((
                None,
                Some(cup_marker(ci)),
                format!("{} cup, {} N/mm", r.cup.label, r.cup.k_n_per_mm),
            ));
        }
        let (mut lx, mut ly) = (130i64, 565i64);
        for (col, mk, name) in items {
            let wd = 38 + Canvas::text_width(&name, 2) + 36;
            if lx + wd > i64::from(w) - 20 {
                lx = 130;
                ly += 32;
            }
            if let Some(col) = col {
                c.line(
                    lx as f64,
                    ly as f64 + 7.0,
                    lx as f64 + 30.0,
                    ly as f64 + 7.0,
                    col,
                    3.0,
                );
            }
            if let Some(mk) = mk {
                c.marker(lx as f64 + 15.0, ly as f64 + 7.0, mk, BLACK, 5.0);
            }
            c.text(lx + 38, ly, &name, BLACK, 2);
            lx += wd;
        }
        c.text(
            130,
            ly + 40,
            "points along a line: steps 1e-2 .. 1e-6 s (sub-stepped: outer steps 1e-2 .. 1e-3 s); reference: semi-implicit at 1e-7 s",
            GREY,
            2,
        );
        c
    }

    /// Stability map per method: cells green (stable) or red (unstable), the derived bound as
    /// a dashed line.
    pub fn stability_plot(&self) -> Canvas {
        let (w, h) = (1400u32, 560u32);
        let mut c = Canvas::new(w, h);
        let ks = &self.map_stiffness_n_per_mm;
        let hs = &self.map_steps_s;
        if ks.is_empty() || hs.is_empty() {
            return c;
        }
        let lg = |v: &[f64]| -> (f64, f64) {
            let lo = v.iter().cloned().fold(f64::INFINITY, f64::min).log10();
            let hi = v.iter().cloned().fold(0.0, f64::max).log10();
            // Half a cell beyond the first and last sample.
            let d = if v.len() > 1 {
                0.5 * (hi - lo) / (v.len() - 1) as f64
            } else {
                0.5
            };
            (lo - d, hi + d)
        };
        let (kx0, kx1) = lg(ks);
        let (hy0, hy1) = lg(hs);
        for (mi, m) in Method::ALL.iter().enumerate() {
            let ax = LogAxes {
                left: 130.0 + mi as f64 * 440.0,
                top: 60.0,
                width: 340.0,
                height: 340.0,
                x0: kx0,
                x1: kx1,
                y0: hy0,
                y1: hy1,
            };
            let (cw, ch) = (ax.width / ks.len() as f64, ax.height / hs.len() as f64);
            for cell in self.stability.iter().filter(|c| c.method == *m) {
                let (px, py) = ax.px(cell.k_n_per_mm, cell.step_s);
                let col: Rgb = if cell.observed_stable {
                    [150, 215, 150]
                } else {
                    [240, 150, 140]
                };
                c.fill_rect(
                    (px - cw / 2.0 + 1.0) as i64,
                    (py - ch / 2.0 + 1.0) as i64,
                    (px + cw / 2.0 - 1.0) as i64,
                    (py + ch / 2.0 - 1.0) as i64,
                    col,
                );
                if cell.predicted_stable != cell.observed_stable {
                    c.text(px as i64 - 5, py as i64 - 7, "*", BLACK, 2);
                }
            }
            ax.draw(
                &mut c,
                "wall stiffness k [N/mm]",
                "step h [s]",
                series_style(*m, false).1,
            );
            // The derived bound as a curve over k.
            if *m != Method::BackwardEuler {
                let mut prev: Option<(f64, f64)> = None;
                for i in 0..=200 {
                    let lk = kx0 + (kx1 - kx0) * i as f64 / 200.0;
                    let cup = Cup::new("map", 80.0, 10f64.powf(lk));
                    let (be, bs) = end_state_bounds(&cup);
                    let b = if *m == Method::ExplicitEuler { be } else { bs };
                    let lb = b.log10().clamp(hy0, hy1);
                    let p = ax.px(10f64.powf(lk), 10f64.powf(lb));
                    if let Some(q) = prev {
                        c.line(q.0, q.1, p.0, p.1, BLACK, 2.5);
                    }
                    prev = Some(p);
                }
            } else {
                c.text(
                    (ax.left + 20.0) as i64,
                    (ax.top + 20.0) as i64,
                    "no bound (A-stable)",
                    BLACK,
                    2,
                );
            }
        }
        let ly = 490i64;
        c.fill_rect(130, ly, 152, ly + 14, [150, 215, 150]);
        c.text(160, ly, "stable", BLACK, 2);
        c.fill_rect(260, ly, 282, ly + 14, [240, 150, 140]);
        c.text(290, ly, "unstable (diverged or growing)", BLACK, 2);
        c.line(690.0, ly as f64 + 7.0, 720.0, ly as f64 + 7.0, BLACK, 2.5);
        c.text(728, ly, "derived bound", BLACK, 2);
        c.text(910, ly, "* bound predicted otherwise", BLACK, 2);
        c.text(
            130,
            ly + 30,
            "task: close to 1 cm deformation (or 20 N), hold 0.3 s; no sub-steps",
            GREY,
            2,
        );
        c
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stiffest_cup_at_the_default_step_matches_the_reference() {
        // Stated accuracy of the default world (semi-implicit Euler, sub-stepped at half its
        // bound, 1 ms control step) on the near-rigid cup: within 0.5 % of a 1e-7 s reference
        // in final deformation and peak force, and finite.
        let cup = Cup::extreme();
        let r = run_task(&cup, Method::SemiImplicitEuler, Substep::Off, 1e-7);
        let o = run_task(
            &cup,
            Method::SemiImplicitEuler,
            Substep::Stability { safety: 0.5 },
            DEFAULT_STEP_S,
        );
        assert!(o.stable() && o.final_deformation_mm.is_finite(), "{o:?}");
        assert!(
            rel(o.final_deformation_mm, r.final_deformation_mm) < 5e-3,
            "{} vs {}",
            o.final_deformation_mm,
            r.final_deformation_mm
        );
        assert!(
            rel(o.peak_force_n, r.peak_force_n) < 5e-3,
            "{} vs {}",
            o.peak_force_n,
            r.peak_force_n
        );
        // Without sub-steps the same step is far beyond both explicit bounds: flagged.
        let (be, bs) = end_state_bounds(&cup);
        assert!(DEFAULT_STEP_S > bs && bs > be);
        assert!(!run_task(&cup, Method::ExplicitEuler, Substep::Off, DEFAULT_STEP_S).stable());
        assert!(
            !run_task(
                &cup,
                Method::SemiImplicitEuler,
                Substep::Off,
                DEFAULT_STEP_S
            )
            .stable()
        );
        // Backward Euler at the same step stays finite and bounded.
        let b = run_task(&cup, Method::BackwardEuler, Substep::Off, DEFAULT_STEP_S);
        assert!(b.stable() && rel(b.final_deformation_mm, r.final_deformation_mm) < 0.05);
    }

    #[test]
    fn explicit_euler_is_flagged_unstable_where_the_bound_says() {
        for k in [0.1, 10.0, 1000.0] {
            let cup = Cup::new("k", 80.0, k);
            let (be, _) = end_state_bounds(&cup);
            assert!(
                run_task(&cup, Method::ExplicitEuler, Substep::Off, 0.5 * be).stable(),
                "k {k}: half the bound"
            );
            assert!(
                !run_task(&cup, Method::ExplicitEuler, Substep::Off, 2.0 * be).stable(),
                "k {k}: twice the bound"
            );
        }
    }

    #[test]
    fn small_report_has_tables_and_plots() {
        let opts = NumericsOptions {
            cups: vec![Cup::stiff()],
            steps_s: vec![1e-3, 1e-4],
            ref_step_s: 1e-6,
            map_stiffness: vec![0.1, 10.0],
            map_steps: vec![1e-4, 1e-3],
        };
        let r = report(&opts);
        assert_eq!(r.accuracy.len(), 3 * 2 + 1);
        assert_eq!(r.stability.len(), 3 * 2 * 2);
        let t = r.text();
        assert!(t.contains("backward_euler") && t.contains("stiff"), "{t}");
        let dir = std::env::temp_dir().join(format!("unitac-numerics-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let files = r.write_plots(&dir).unwrap();
        for f in &files {
            assert!(std::fs::metadata(f).unwrap().len() > 1000);
        }
        std::fs::remove_dir_all(&dir).ok();
    }
}
