//! The simulator's numerics report: accuracy against run time of each integrator on soft, stiff
//! and extreme cups, and a stability map (wall stiffness x step size).
//!
//! The task is the paper's cup squeeze with a prescribed finger motion (so every method sees the
//! same input): from 0.4 mm open the finger closes at 40 mm/s to the position where the static
//! deformation is 1 cm (or the gel force reaches the gripper's 20 N limit, for walls too stiff to
//! dent), then holds 0.3 s. Measured: final deformation and peak grip force, against a reference
//! run with semi-implicit Euler at 1e-7 s (whose own error is estimated from a run at 2e-7 s).
//!
//! The report is data and text; its two PNG figures are drawn by `unitac-lab report sim`
//! (crates/lab/src/sim_charts.rs), so the simulator carries no plotting.

use serde::Serialize;
use std::time::Instant;

use crate::world::{Cup, Gel, Method, Substep, World, WorldConfig, static_finger_for, static_wall};

/// Target deformation \[m] and force limit \[N] of the task.
pub const TARGET_M: f64 = 0.010;
pub const MAX_FORCE_N: f64 = 20.0;
/// Closing speed [m/s], hold \[s], start \[m].
pub const SPEED_M_S: f64 = 0.040;
pub const HOLD_S: f64 = 0.3;
pub const START_M: f64 = -0.0004;
/// Reference step \[s].
pub const REF_STEP_S: f64 = 1e-7;
/// Step sizes of the accuracy runs \[s].
pub const STEPS_S: [f64; 9] = [1e-2, 3e-3, 1e-3, 3e-4, 1e-4, 3e-5, 1e-5, 3e-6, 1e-6];
/// The world's default control step \[s] (sub-stepped inside).
pub const DEFAULT_STEP_S: f64 = 1e-3;

/// The prescribed task for one cup.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Task {
    /// Final finger position \[m].
    pub finger_m: f64,
    /// End of the closing ramp and of the run \[s].
    pub close_s: f64,
    pub end_s: f64,
}

impl Task {
    pub fn for_cup(cup: &Cup) -> Self {
        let finger_m = static_finger_for(cup, &Gel::default(), TARGET_M, MAX_FORCE_N);
        let close_s = (finger_m - START_M) / SPEED_M_S;
        Self {
            finger_m,
            close_s,
            end_s: close_s + HOLD_S,
        }
    }
    /// Finger position at time t.
    pub fn finger_at(&self, t: f64) -> f64 {
        if t >= self.close_s {
            self.finger_m
        } else {
            START_M + SPEED_M_S * t.max(0.0)
        }
    }
}

/// Result of one run of the task.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Outcome {
    pub final_deformation_m: f64,
    /// Deformation the moment the finger stops (the end of the closing ramp) \[m]: still
    /// dynamic, unlike the final one, which the hold lets settle to the static equilibrium.
    pub stop_deformation_m: f64,
    pub peak_force_n: f64,
    /// Integrator steps taken (sub-steps included).
    pub steps: u64,
    /// Largest |x - x_static| in the first and the second half of the hold \[m] (a growing
    /// oscillation = unstable).
    pub hold_swing_first_m: f64,
    pub hold_swing_second_m: f64,
    /// Why the run stopped early, if it did.
    pub diverged: Option<String>,
}

impl Outcome {
    /// Bounded: no divergence and the hold's oscillation does not grow.
    pub fn stable(&self) -> bool {
        self.diverged.is_none()
            && self.final_deformation_m.is_finite()
            && !(self.hold_swing_second_m > self.hold_swing_first_m
                && self.hold_swing_second_m > 1e-12)
    }
}

/// Run the task on `cup` with `method` at step `h` \[s].
pub fn run_task(cup: &Cup, method: Method, substep: Substep, h: f64) -> Outcome {
    let task = Task::for_cup(cup);
    let mut cfg = WorldConfig::new(cup.clone()).with_method(method, substep);
    cfg.start_m = START_M;
    let x_static = static_wall(cup, &cfg.gel, task.finger_m);
    let mut w = World::new(cfg);
    // Steps that land exactly on the end of the closing ramp (no input kink inside a step).
    let n_close = (task.close_s / h).round().max(1.0) as u64;
    let h = task.close_s / n_close as f64;
    let n = n_close + ((task.end_s - task.close_s) / h).round().max(2.0) as u64;
    let hold_mid = task.close_s + 0.5 * (n - n_close) as f64 * h;
    let mut out = Outcome {
        final_deformation_m: f64::NAN,
        stop_deformation_m: f64::NAN,
        peak_force_n: 0.0,
        steps: 0,
        hold_swing_first_m: 0.0,
        hold_swing_second_m: 0.0,
        diverged: None,
    };
    for i in 1..=n {
        let t = i as f64 * h;
        match w.step_finger(h, task.finger_at(t)) {
            Ok(s) => {
                out.steps += u64::from(s.substeps);
                out.peak_force_n = out.peak_force_n.max(s.step_peak_force_n);
                out.final_deformation_m = s.deformation_m;
                if i == n_close {
                    out.stop_deformation_m = s.deformation_m;
                }
                let swing = (0.5 * s.deformation_m - x_static).abs();
                if i > n_close && t > hold_mid {
                    out.hold_swing_second_m = out.hold_swing_second_m.max(swing);
                } else if i > n_close {
                    out.hold_swing_first_m = out.hold_swing_first_m.max(swing);
                }
            }
            Err(e) => {
                out.diverged = Some(e.to_string());
                out.final_deformation_m = f64::NAN;
                out.stop_deformation_m = f64::NAN;
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
    pub final_deformation_m: f64,
    pub stop_deformation_m: f64,
    pub peak_force_n: f64,
    /// |final deformation - reference| \[m] (NaN when diverged).
    pub err_deformation_m: f64,
    /// |deformation when the finger stops - reference| \[m].
    pub err_stop_deformation_m: f64,
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
    pub final_deformation_m: f64,
    pub stop_deformation_m: f64,
    pub peak_force_n: f64,
    /// Difference to a run at twice the reference step (an estimate of its own error).
    pub self_err_deformation_m: f64,
    pub self_err_stop_deformation_m: f64,
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
    pub k_n_per_m: f64,
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
    pub map_stiffness_n_per_m: Vec<f64>,
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
            // 10 N/m .. 1 MN/m: five decades.
            map_stiffness: (0..11).map(|i| 10f64.powf(1.0 + 0.5 * i as f64)).collect(),
            map_steps: STEPS_S.iter().rev().copied().collect(),
        }
    }
}

/// Bounds of each explicit method at the task's end state (static equilibrium, finger held).
pub fn end_state_bounds(cup: &Cup) -> (f64, f64) {
    let task = Task::for_cup(cup);
    let gel = Gel::default();
    let x = static_wall(cup, &gel, task.finger_m);
    let d = task.finger_m - x;
    let k = cup.spring(x).1 + gel.elastic(d).1;
    let c = cup.damping() + if d > 0.0 { gel.c_n_s_per_m } else { 0.0 };
    (
        Method::ExplicitEuler.stable_step(cup.mass(), k, c),
        Method::SemiImplicitEuler.stable_step(cup.mass(), k, c),
    )
}

/// Relative error of `a` against `b` (`b` at least 1e-12 in size).
pub fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs().max(1e-12)
}

/// The name of a method's runs in the tables (and the plots' legends): `substeps` for the
/// sub-stepped semi-implicit runs.
pub fn series_name(m: Method, substeps: bool) -> &'static str {
    match (m, substeps) {
        (_, true) => "semi-implicit + sub-steps",
        (Method::ExplicitEuler, _) => "explicit Euler",
        (Method::SemiImplicitEuler, _) => "semi-implicit Euler",
        (Method::BackwardEuler, _) => "backward Euler (Newton)",
    }
}

pub fn report(opts: &NumericsOptions) -> NumericsReport {
    report_with_progress(opts, &mut |_, _| {})
}

/// Units of work [`report_with_progress`] reports: one per cup, one per stability-map column.
pub fn report_steps(opts: &NumericsOptions) -> u64 {
    (opts.cups.len() + Method::ALL.len() * opts.map_stiffness.len()) as u64
}

/// The reference run of `cup` (semi-implicit Euler at the reference step) and its
/// self-consistency against twice that step.
fn reference_for(cup: &Cup, opts: &NumericsOptions) -> Reference {
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
    Reference {
        cup: cup.clone(),
        task: Task::for_cup(cup),
        final_deformation_m: r.final_deformation_m,
        stop_deformation_m: r.stop_deformation_m,
        peak_force_n: r.peak_force_n,
        self_err_deformation_m: (r.final_deformation_m - r2.final_deformation_m).abs(),
        self_err_stop_deformation_m: (r.stop_deformation_m - r2.stop_deformation_m).abs(),
        self_err_force_n: (r.peak_force_n - r2.peak_force_n).abs(),
        bound_explicit_s: be,
        bound_semi_implicit_s: bs,
        wall_s,
    }
}

/// Every method at every step of `opts` on `cup` (and the world's default, sub-stepped), each
/// against `reference`, timed best of three.
fn accuracy_rows(cup: &Cup, opts: &NumericsOptions, reference: &Reference) -> Vec<AccuracyRow> {
    let mut rows = Vec::new();
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
        let ed = (o.final_deformation_m - reference.final_deformation_m).abs();
        let ef = (o.peak_force_n - reference.peak_force_n).abs();
        rows.push(AccuracyRow {
            cup: cup.label.clone(),
            method: m,
            substeps: matches!(sub, Substep::Stability { .. }),
            step_s: h,
            final_deformation_m: o.final_deformation_m,
            stop_deformation_m: o.stop_deformation_m,
            peak_force_n: o.peak_force_n,
            err_deformation_m: ed,
            err_stop_deformation_m: (o.stop_deformation_m - reference.stop_deformation_m).abs(),
            err_force_n: ef,
            rel_err: rel(o.final_deformation_m, reference.final_deformation_m)
                .max(rel(o.stop_deformation_m, reference.stop_deformation_m))
                .max(rel(o.peak_force_n, reference.peak_force_n)),
            steps: o.steps,
            wall_s,
            stable: o.stable(),
            diverged: o.diverged.clone(),
        });
    }
    rows
}

/// One column of the stability map: method `m` on a cup of stiffness `k` at each step, the
/// bound's prediction beside what the run did.
fn stability_column(m: Method, k: f64, steps: &[f64]) -> Vec<StabilityCell> {
    let mut cells = Vec::new();
    let cup = Cup::new("map", 0.080, k);
    let (be, bs) = end_state_bounds(&cup);
    for &h in steps {
        let o = run_task(&cup, m, Substep::Off, h);
        let predicted_stable = match m {
            Method::ExplicitEuler => h < be,
            Method::SemiImplicitEuler => h < bs,
            Method::BackwardEuler => true,
        };
        cells.push(StabilityCell {
            method: m,
            k_n_per_m: k,
            step_s: h,
            predicted_stable,
            observed_stable: o.stable(),
        });
    }
    cells
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
        let reference = reference_for(cup, opts);
        accuracy.extend(accuracy_rows(cup, opts, &reference));
        references.push(reference);
        done += 1;
        progress(done, total);
    }
    let mut stability = Vec::new();
    for m in Method::ALL {
        for &k in &opts.map_stiffness {
            stability.extend(stability_column(m, k, &opts.map_steps));
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
            "close at {SPEED_M_S} m/s from {START_M} m to a static deformation of \
             {TARGET_M} m (or {MAX_FORCE_N} N), hold {HOLD_S} s; reference: semi-implicit \
             Euler at {:e} s",
            opts.ref_step_s
        ),
        references,
        accuracy,
        map_stiffness_n_per_m: opts.map_stiffness.clone(),
        map_steps_s: opts.map_steps.clone(),
        stability,
        map_disagreements,
    }
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
            "  cup        k [N/m]  finger [m]  final defo. [m]  at stop [m]  peak force [N]  self-error [m / m / N]          bound expl. [s]  bound semi [s]"
        );
        for r in &self.references {
            let _ = writeln!(
                s,
                "  {:<8} {:>10.1}  {:>10.3e}  {:>15.6e}  {:>11.6e}  {:>14.6}  {:>7.1e} / {:>7.1e} / {:>7.1e}  {:>15.2e}  {:>14.2e}",
                r.cup.label,
                r.cup.k_n_per_m,
                r.task.finger_m,
                r.final_deformation_m,
                r.stop_deformation_m,
                r.peak_force_n,
                r.self_err_deformation_m,
                r.self_err_stop_deformation_m,
                r.self_err_force_n,
                r.bound_explicit_s,
                r.bound_semi_implicit_s
            );
        }
        let _ = writeln!(s, "\naccuracy against run time (one core, best of 3)");
        let _ = writeln!(
            s,
            "  cup      method                     step [s]   steps      time [ms]  err final [m]   err stop [m]   err peak [N]  rel. err"
        );
        for a in &self.accuracy {
            let name = series_name(a.method, a.substeps);
            let errs = if a.diverged.is_some() {
                format!("{:>14}  {:>13}  {:>12}  {:>8}", "diverged", "-", "-", "-")
            } else {
                format!(
                    "{:>14.2e}  {:>13.2e}  {:>12.2e}  {:>8.1e}{}",
                    a.err_deformation_m,
                    a.err_stop_deformation_m,
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
            let mut hdr = String::from("     k [N/m] \\ h [s]");
            for h in &self.map_steps_s {
                let _ = write!(hdr, " {:>6.0e}", h);
            }
            let _ = writeln!(s, "{hdr}");
            for &k in &self.map_stiffness_n_per_m {
                let mut row = format!("    {:>17.1}", k);
                for &h in &self.map_steps_s {
                    if let Some(c) = self
                        .stability
                        .iter()
                        .find(|c| c.method == m && c.k_n_per_m == k && c.step_s == h)
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
        assert!(o.stable() && o.final_deformation_m.is_finite(), "{o:?}");
        assert!(
            rel(o.final_deformation_m, r.final_deformation_m) < 5e-3,
            "{} vs {}",
            o.final_deformation_m,
            r.final_deformation_m
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
        assert!(b.stable() && rel(b.final_deformation_m, r.final_deformation_m) < 0.05);
    }

    #[test]
    fn explicit_euler_is_flagged_unstable_where_the_bound_says() {
        for k in [100.0, 1e4, 1e6] {
            let cup = Cup::new("k", 0.080, k);
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
    fn small_report_has_tables() {
        let opts = NumericsOptions {
            cups: vec![Cup::stiff()],
            steps_s: vec![1e-3, 1e-4],
            ref_step_s: 1e-6,
            map_stiffness: vec![100.0, 1e4],
            map_steps: vec![1e-4, 1e-3],
        };
        let r = report(&opts);
        assert_eq!(r.accuracy.len(), 3 * 2 + 1);
        assert_eq!(r.stability.len(), 3 * 2 * 2);
        let t = r.text();
        assert!(t.contains("backward_euler") && t.contains("stiff"), "{t}");
    }
}
