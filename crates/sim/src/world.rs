//! A small simulated world: a 1-DOF parallel gripper with a gel sensor on each finger squeezing a
//! cup, whose wall is a nonlinear spring-damper.
//!
//! - [`model`]: the physical model (cup wall, gel, gripper) and its static equilibrium.
//! - [`integrate`]: the integration methods of the wall, their stability bounds and sub-stepping.
//! - this module: the world's state, one step under a gripper command, and the closed-loop grip.

use serde::Serialize;
use thiserror::Error;

pub mod integrate;
pub mod model;

pub use integrate::{Method, Substep, UnknownMethod};
pub use model::{Cup, GEL_DOME_M, Gel, Gripper, static_finger_for, static_wall};

/// What the gripper is told to do.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub enum Command {
    /// Finger position \[m] (closing, 0 = touching the undeformed cup).
    Position(f64),
    /// Grip force per finger \[N].
    Force(f64),
}

#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct WorldConfig {
    pub cup: Cup,
    pub gel: Gel,
    pub gripper: Gripper,
    pub method: Method,
    pub substep: Substep,
    /// Sub-steps allowed per step before the world reports that it cannot keep the bound.
    pub max_substeps: u32,
    /// Finger position at t = 0 \[m] (negative: open, not touching).
    pub start_m: f64,
}

impl WorldConfig {
    /// Semi-implicit Euler with sub-stepping at half the stability bound.
    pub fn new(cup: Cup) -> Self {
        Self {
            cup,
            gel: Gel::default(),
            gripper: Gripper::default(),
            method: Method::SemiImplicitEuler,
            substep: Substep::Stability { safety: 0.5 },
            max_substeps: 100_000,
            start_m: -0.0004,
        }
    }
    pub fn with_method(mut self, method: Method, substep: Substep) -> Self {
        self.method = method;
        self.substep = substep;
        self
    }
}

#[derive(Debug, Clone, PartialEq, Error)]
pub enum WorldError {
    #[error("the {method} integration diverged at t = {t_s:.6} s (step {step_s:e} s): {what}")]
    Diverged {
        method: Method,
        t_s: f64,
        step_s: f64,
        what: String,
    },
    #[error("bad step {0} s (must be finite and > 0)")]
    BadStep(f64),
    /// A task command (or run setting) outside its domain: nothing was changed.
    #[error("bad command: {field} = {value} ({why})")]
    BadCommand {
        field: &'static str,
        value: f64,
        why: &'static str,
    },
    /// An arm target that is neither "home" nor an object of this task (name cut to 64 chars).
    #[error("unknown arm target '{name}' (home or one of: {known})")]
    UnknownTarget { name: String, known: String },
}

/// Ground truth after a step.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Default)]
pub struct WorldTruth {
    pub t_s: f64,
    /// Finger position \[m] (closing, 0 = touching the undeformed cup).
    pub finger_m: f64,
    /// Gripper opening \[m]: cup diameter - 2 x finger position.
    pub width_m: f64,
    /// Force between gel and cup \[N] per finger.
    pub force_n: f64,
    /// Loss of cup diameter \[m] (2 x wall deformation).
    pub deformation_m: f64,
    /// Gel penetration \[m]; negative is the gap to the wall.
    pub penetration_m: f64,
    /// Wall velocity [m/s].
    pub wall_velocity_m_s: f64,
    /// Integrator steps this world step took.
    pub substeps: u32,
    /// Largest force at the end of any of those sub-steps \[N] (a peak inside the step).
    pub step_peak_force_n: f64,
}

/// What one [`World::drive`] step did.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct DriveStep {
    pub truth: WorldTruth,
    /// The target asked the finger to close.
    pub closing: bool,
    /// Closing was held back by the commanded force bound.
    pub stalled: bool,
}

/// The world: state and integrator.
#[derive(Debug, Clone)]
pub struct World {
    cfg: WorldConfig,
    t: f64,
    p: f64,
    x: f64,
    v: f64,
    force: f64,
    newton_max_iters: u32,
}

impl World {
    pub fn new(cfg: WorldConfig) -> Self {
        let p = cfg.start_m;
        Self {
            cfg,
            t: 0.0,
            p,
            x: 0.0,
            v: 0.0,
            force: 0.0,
            newton_max_iters: 0,
        }
    }
    pub fn config(&self) -> &WorldConfig {
        &self.cfg
    }
    /// Set the wall state directly (free-oscillation studies).
    pub fn set_wall(&mut self, x_m: f64, v_m_s: f64) {
        self.x = x_m;
        self.v = v_m_s;
    }
    pub fn time(&self) -> f64 {
        self.t
    }
    /// Most Newton iterations any backward-Euler step needed so far.
    pub fn newton_max_iters(&self) -> u32 {
        self.newton_max_iters
    }

    /// Total mechanical energy of wall and gels \[J].
    pub fn energy(&self) -> f64 {
        0.5 * self.cfg.cup.mass() * self.v * self.v
            + self.cfg.cup.spring_energy(self.x)
            + self.cfg.gel.energy(self.p - self.x)
    }

    pub fn truth(&self, substeps: u32) -> WorldTruth {
        WorldTruth {
            t_s: self.t,
            finger_m: self.p,
            width_m: self.cfg.cup.diameter_m - 2.0 * self.p,
            force_n: self.force,
            deformation_m: 2.0 * self.x,
            penetration_m: self.p - self.x,
            wall_velocity_m_s: self.v,
            substeps,
            step_peak_force_n: self.force,
        }
    }

    /// Advance by `h` seconds under a gripper command.
    pub fn step(&mut self, h: f64, cmd: Command) -> Result<WorldTruth, WorldError> {
        if !(h.is_finite() && h > 0.0) {
            return Err(WorldError::BadStep(h));
        }
        let g = self.cfg.gripper;
        let vmax = g.speed_m_s.max(0.0) * h;
        let dp = match cmd {
            Command::Position(target) => (target - self.p).clamp(-vmax, vmax),
            Command::Force(target) => (g.force_gain * (target - self.force) * h).clamp(-vmax, vmax),
        };
        // Stall at the force limit (never close harder than the gripper can).
        let dp = if dp > 0.0 && self.force >= g.max_force_n {
            0.0
        } else {
            dp
        };
        let p1 = self.p + dp;
        self.step_finger(h, p1)
    }

    /// Advance by `h` seconds as a gripper drive does: the finger moves toward `target_m` at no
    /// more than `speed_m_s`, and does not close further while the force is at or above
    /// `force_n` (the commanded force bound; the world's own limits still hold).
    pub fn drive(
        &mut self,
        h: f64,
        target_m: f64,
        speed_m_s: f64,
        force_n: f64,
    ) -> Result<DriveStep, WorldError> {
        let v = speed_m_s.max(0.0) * h;
        let next = self.p + (target_m - self.p).clamp(-v, v);
        let closing = next > self.p;
        let stalled = closing && self.force >= force_n;
        let to = if stalled { self.p } else { next };
        let truth = self.step(h, Command::Position(to))?;
        Ok(DriveStep {
            truth,
            closing,
            stalled,
        })
    }

    /// Advance by `h` seconds while the finger moves linearly to `p1` \[m] (a prescribed motion,
    /// as the numerics report uses so every method sees the same input).
    pub fn step_finger(&mut self, h: f64, p1: f64) -> Result<WorldTruth, WorldError> {
        if !(h.is_finite() && h > 0.0) {
            return Err(WorldError::BadStep(h));
        }
        let n = self.substeps(h);
        let hs = h / f64::from(n);
        let p0 = self.p;
        let mut peak: f64 = 0.0;
        for i in 1..=n {
            let pe = p0 + (p1 - p0) * f64::from(i) / f64::from(n);
            self.integrate(hs, pe);
            self.t += hs;
            peak = peak.max(self.force);
            if let Some(what) = self.broken() {
                return Err(WorldError::Diverged {
                    method: self.cfg.method,
                    t_s: self.t,
                    step_s: hs,
                    what,
                });
            }
        }
        let mut t = self.truth(n);
        t.step_peak_force_n = peak;
        Ok(t)
    }
    /// Why the state is no longer physical, if it is not.
    fn broken(&self) -> Option<String> {
        if !(self.x.is_finite() && self.v.is_finite() && self.force.is_finite()) {
            return Some("non-finite state".into());
        }
        let r = 0.5 * self.cfg.cup.diameter_m;
        if self.x.abs() > r {
            return Some(format!(
                "wall moved {:.4} m, more than the cup's radius",
                self.x
            ));
        }
        None
    }
}

/// One sample of a grip for the renderer and the ground truth.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Default)]
pub struct GripSample {
    pub t_s: f64,
    pub penetration_m: f64,
    pub force_n: f64,
    pub deformation_m: f64,
}

/// What a closed-loop grip did.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct GripRun {
    pub samples: Vec<GripSample>,
    /// Time the target deformation (or the force limit) was reached \[s], and the hold's end.
    pub closed_s: f64,
    pub hold_end_s: f64,
    pub final_deformation_m: f64,
    pub peak_force_n: f64,
}

/// The paper's cup task, closed loop: close at the speed limit until the cup is compressed by
/// `target_m` (ground-truth deformation) or the force limit is hit, hold for `hold_s`, open
/// back to the start. Control period `dt` \[s]; one sample per control period.
pub fn grip_cup(
    cfg: WorldConfig,
    target_m: f64,
    hold_s: f64,
    dt: f64,
) -> Result<GripRun, WorldError> {
    let mut w = World::new(cfg);
    let start = w.cfg.start_m;
    let far = w.cfg.cup.diameter_m * 0.5;
    let mut samples = Vec::new();
    let mut peak: f64 = 0.0;
    let sample = |t: WorldTruth| GripSample {
        t_s: t.t_s,
        penetration_m: t.penetration_m,
        force_n: t.force_n,
        deformation_m: t.deformation_m,
    };
    samples.push(sample(w.truth(0)));
    // Close.
    let max_steps = (60.0 / dt).ceil() as u64;
    let mut k = 0;
    let mut last = w.truth(0);
    while last.deformation_m < target_m && k < max_steps {
        last = w.step(dt, Command::Position(far))?;
        peak = peak.max(last.step_peak_force_n);
        samples.push(sample(last));
        k += 1;
        if last.force_n >= w.cfg.gripper.max_force_n {
            break;
        }
    }
    let closed_s = w.t;
    let hold = Command::Position(w.p);
    let n_hold = (hold_s / dt).round() as u64;
    for _ in 0..n_hold {
        last = w.step(dt, hold)?;
        peak = peak.max(last.step_peak_force_n);
        samples.push(sample(last));
    }
    let hold_end_s = w.t;
    let final_deformation_m = last.deformation_m;
    // Open until the gel has left the wall and the finger is back at the start.
    k = 0;
    while (w.p > start + 1e-12 || last.penetration_m > start * 0.25) && k < max_steps {
        last = w.step(dt, Command::Position(start))?;
        samples.push(sample(last));
        k += 1;
    }
    Ok(GripRun {
        samples,
        closed_s,
        hold_end_s,
        final_deformation_m,
        peak_force_n: peak,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn method_names_parse_back_and_an_unknown_one_is_a_typed_error() {
        for m in Method::ALL {
            assert_eq!(m.as_str().parse::<Method>(), Ok(m));
        }
        assert_eq!("rk4".parse::<Method>(), Err(UnknownMethod("rk4".into())));
    }

    fn free(method: Method, cup: Cup, h: f64, steps: usize) -> (f64, Vec<f64>) {
        let mut cfg = WorldConfig::new(cup).with_method(method, Substep::Off);
        cfg.start_m = -0.030; // fingers far away: a free wall
        let mut w = World::new(cfg);
        w.set_wall(0.001, 0.0);
        let e0 = w.energy();
        let mut es = Vec::with_capacity(steps);
        for _ in 0..steps {
            match w.step_finger(h, -0.030) {
                Ok(_) => es.push(w.energy()),
                Err(_) => {
                    es.push(f64::INFINITY);
                    break;
                }
            }
        }
        (e0, es)
    }

    fn undamped(k: f64) -> Cup {
        let mut c = Cup::new("free", 0.080, k);
        c.damping_ratio = 0.0;
        c
    }

    #[test]
    fn energy_does_not_grow_in_a_free_oscillation() {
        for cup in [undamped(50.0), undamped(5e3), undamped(5e5)] {
            let w = (cup.k_n_per_m / cup.mass()).sqrt();
            let h = 0.2 / w; // 31 steps per period
            let steps = 100 * 32; // 100 periods
            // Semi-implicit: energy oscillates within O(w h) of E0 and does not drift.
            let (e0, es) = free(Method::SemiImplicitEuler, cup.clone(), h, steps);
            let max = es.iter().cloned().fold(0.0, f64::max);
            assert!(max <= e0 * 1.15, "{}: {max} vs {e0}", cup.k_n_per_m);
            let tail = es[es.len() - 64..].iter().cloned().fold(0.0, f64::max);
            let head = es[..64].iter().cloned().fold(0.0, f64::max);
            // (The maxima of two windows differ a little with the sampling phase.)
            assert!(tail <= head * (1.0 + 1e-3), "drift {head} -> {tail}");
            // Backward Euler: energy never increases, step by step (convex spring potential).
            let (e0, es) = free(Method::BackwardEuler, cup.clone(), h, steps);
            let mut prev = e0;
            for &e in &es {
                // (Floor: the Newton tolerance, once the energy has decayed by 12 decades.)
                assert!(e <= prev * (1.0 + 1e-9) + 1e-12 * e0, "{e} > {prev}");
                prev = e;
            }
            // Explicit Euler without damping gains energy every step.
            let (e0, es) = free(Method::ExplicitEuler, cup.clone(), h, 200);
            assert!(es.last().copied().unwrap_or(0.0) > e0 * 2.0);
        }
    }

    #[test]
    fn explicit_euler_is_unstable_beyond_its_bound_and_stable_within() {
        // A linear wall (the bound is derived for the linearisation), damping ratio 0.05.
        let mut cup = Cup::stiff();
        cup.k3_n_per_m3 = 0.0;
        let (m, k, c) = (cup.mass(), cup.k_n_per_m, cup.damping());
        let bound = Method::ExplicitEuler.stable_step(m, k, c);
        let w = (k / m).sqrt();
        assert!((bound - 2.0 * 0.05 / w).abs() < 1e-12 * bound.max(1.0));
        let grows = |h: f64| {
            let (e0, es) = free(Method::ExplicitEuler, cup.clone(), h, 4000);
            es.last().copied().unwrap_or(f64::INFINITY) > e0
        };
        assert!(!grows(0.8 * bound));
        assert!(grows(1.2 * bound));
        // Semi-implicit: stable up to its own bound (~2/w), far beyond the explicit one.
        let sb = Method::SemiImplicitEuler.stable_step(m, k, c);
        assert!(sb > 10.0 * bound);
        let (e0, es) = free(Method::SemiImplicitEuler, cup.clone(), 0.95 * sb, 4000);
        assert!(es.last().copied().unwrap_or(f64::INFINITY) < e0);
        let (e0, es) = free(Method::SemiImplicitEuler, cup.clone(), 1.05 * sb, 4000);
        assert!(es.last().copied().unwrap_or(f64::INFINITY) > e0);
    }

    #[test]
    fn force_rises_monotonically_with_indentation() {
        for cup in [Cup::soft(), Cup::paper(0.080), Cup::stiff(), Cup::extreme()] {
            // Static: force at the gel vs finger position.
            let gel = Gel::default();
            let mut prev = -1.0;
            for i in 1..200 {
                let p = i as f64 * 5e-5;
                let x = static_wall(&cup, &gel, p);
                let f = gel.elastic(p - x).0;
                assert!(f > prev, "{}: {f} <= {prev} at {p}", cup.label);
                assert!((f - cup.spring(x).0).abs() < 1e-6 * f.max(1.0));
                prev = f;
            }
            // Dynamic: a slow close (1 mm/s) with the implicit method. The gel's viscous part
            // (at most cg x finger speed = 0.002 N) may relax while the wall starts to move.
            let tol = Gel::default().c_n_s_per_m * 1e-3;
            let cfg =
                WorldConfig::new(cup.clone()).with_method(Method::BackwardEuler, Substep::Off);
            let mut w = World::new(cfg);
            let mut prev = 0.0;
            let mut pen_prev = f64::NEG_INFINITY;
            for i in 1..2000 {
                let t = w.step_finger(1e-3, -0.0004 + i as f64 * 1e-6).unwrap();
                if t.penetration_m > 0.0 {
                    assert!(t.penetration_m > pen_prev, "{}", cup.label);
                    assert!(
                        t.force_n >= prev - tol,
                        "{}: {} < {prev}",
                        cup.label,
                        t.force_n
                    );
                }
                pen_prev = t.penetration_m;
                prev = t.force_n;
            }
            assert!(prev > 0.0);
        }
    }

    #[test]
    fn grip_reaches_the_target_deformation_and_reports_truth() {
        let cfg = WorldConfig::new(Cup::paper(0.080));
        let run = grip_cup(cfg, 0.010, 0.5, 1e-3).unwrap();
        assert!((run.final_deformation_m - 0.010).abs() < 1e-4, "{run:?}");
        assert!(run.peak_force_n > 1.0 && run.peak_force_n < 5.0);
        let last = run.samples.last().unwrap();
        assert!(last.penetration_m < 0.0 && last.force_n == 0.0);
        // A near-rigid cup: the gripper stalls at its force limit, deformation stays small.
        let cfg = WorldConfig::new(Cup::extreme());
        let run = grip_cup(cfg, 0.010, 0.2, 1e-3).unwrap();
        assert!(run.final_deformation_m < 2e-4);
        assert!(
            run.peak_force_n >= 20.0 && run.peak_force_n < 22.0,
            "{}",
            run.peak_force_n
        );
    }

    #[test]
    fn force_command_settles_at_the_target_force() {
        let cfg = WorldConfig::new(Cup::stiff());
        let mut w = World::new(cfg);
        let mut t = w.truth(0);
        for _ in 0..5000 {
            t = w.step(1e-3, Command::Force(5.0)).unwrap();
        }
        assert!((t.force_n - 5.0).abs() < 0.05, "{t:?}");
    }

    #[test]
    fn divergence_is_reported_not_hidden() {
        let cfg = WorldConfig::new(Cup::extreme()).with_method(Method::ExplicitEuler, Substep::Off);
        let mut w = World::new(cfg);
        let mut err = None;
        for i in 0..5000 {
            if let Err(e) = w.step_finger(1e-3, -0.0004 + i as f64 * 4e-6) {
                err = Some(e);
                break;
            }
        }
        assert!(matches!(err, Some(WorldError::Diverged { .. })), "{err:?}");
    }
}
