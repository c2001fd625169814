//! A small simulated world: a 1-DOF parallel gripper with a gel sensor on each finger squeezing a
//! cup, whose wall is a nonlinear spring-damper.
//!
//! # Model (per side; the two fingers are symmetric)
//! Units: mm, N, s; masses are given in kg and used as N s^2/mm (x 1e-3).
//! - finger position `p` [mm], closing positive, 0 = the gel surface touches the undeformed wall.
//!   The gripper moves it kinematically: toward a position target at no more than its speed
//!   limit, or (force command) at a speed proportional to the force error, also limited; it stalls
//!   at its force limit.
//! - wall deformation `x` [mm] (inward) and velocity `v`: `m x'' = F_gel - (k x + k3 x^3 + c v)`.
//! - gel penetration `d = p - x`; the gel pushes with `F_gel = kg d^1.5 + cg d'` while `d > 0`
//!   (Hertz-like elastomer with a little viscosity), never pulls.
//!
//! Cup deformation (ground truth) is the loss of diameter, `2 x`.
//!
//! # Integrators and their stability bounds
//! Linearised about the current state the wall is `m x'' + C x' + K x = input` with tangent
//! stiffness `K = k + 3 k3 x^2 + 1.5 kg d^0.5` and damping `C = c + cg` (in contact), so
//! `w = sqrt(K/m)` and `z = C / (2 sqrt(K m))`. With `h` the step:
//! - explicit Euler: the amplification of the mode `-z w +- i w sqrt(1-z^2)` is
//!   `|1 + h l|^2 = 1 - 2 z w h + w^2 h^2`, below 1 only for `h < 2 z / w = C / K` (z <= 1;
//!   `h < 2 / (w (z + sqrt(z^2 - 1)))` when overdamped). Without damping no step is stable.
//! - semi-implicit (symplectic) Euler, `v+ = v + h a(x, v)`, `x+ = x + h v+`: the step matrix has
//!   trace `2 - w^2 h^2 - 2 z w h` and determinant `1 - 2 z w h`; the Jury conditions give
//!   `h < 2 (sqrt(1 + z^2) - z) / w` (= 2 / w undamped, where energy stays bounded).
//! - backward Euler with Newton on the nonlinear spring: A-stable, and for a convex spring
//!   potential it never increases the energy (see the tests); no stability bound.
//!
//! Sub-stepping: a step `h` is split into `n = ceil(h / (s h_max))` equal sub-steps, with `h_max`
//! the method's bound at the current state and safety `s` (0.5 by default, for the stiffness
//! change within a step and the moving finger).

use serde::Serialize;
use thiserror::Error;

use crate::object::Object;

/// Integration method of the wall.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    ExplicitEuler,
    SemiImplicitEuler,
    BackwardEuler,
}

impl Method {
    pub const ALL: [Method; 3] = [
        Method::ExplicitEuler,
        Method::SemiImplicitEuler,
        Method::BackwardEuler,
    ];
    pub fn as_str(self) -> &'static str {
        match self {
            Method::ExplicitEuler => "explicit_euler",
            Method::SemiImplicitEuler => "semi_implicit_euler",
            Method::BackwardEuler => "backward_euler",
        }
    }

    /// Largest stable step [s] for a linear oscillator of mass `m` [N s^2/mm], stiffness `k`
    /// [N/mm] and damping `c` [N s/mm] (see the module docs). `f64::INFINITY` when any step is
    /// stable, 0 when none is.
    pub fn stable_step(self, m: f64, k: f64, c: f64) -> f64 {
        if k.is_nan() || m.is_nan() || k <= 0.0 || m <= 0.0 {
            return f64::INFINITY;
        }
        let w = (k / m).sqrt();
        let z = c.max(0.0) / (2.0 * (k * m).sqrt());
        match self {
            Method::ExplicitEuler => {
                if z <= 1.0 {
                    2.0 * z / w
                } else {
                    2.0 / (w * (z + (z * z - 1.0).sqrt()))
                }
            }
            Method::SemiImplicitEuler => 2.0 * ((1.0 + z * z).sqrt() - z) / w,
            Method::BackwardEuler => f64::INFINITY,
        }
    }
}

impl std::fmt::Display for Method {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

impl std::str::FromStr for Method {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Method::ALL
            .into_iter()
            .find(|m| m.as_str() == s)
            .ok_or_else(|| format!("unknown method '{s}'"))
    }
}

/// A cup: size and wall (one side's lateral spring-damper).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Cup {
    pub label: String,
    pub diameter_mm: f64,
    /// Linear wall stiffness per side [N/mm].
    pub k_n_per_mm: f64,
    /// Cubic stiffening [N/mm^3] (a wall stiffens as it flattens).
    pub k3_n_per_mm3: f64,
    /// Damping ratio of the wall's own mode at its linear stiffness.
    pub damping_ratio: f64,
    /// Moving mass of one wall side [kg].
    pub wall_mass_kg: f64,
}

/// Radius of the gel's dome [mm]: the cup wall (curved one way) on the domed gel looks to the
/// renderer like a sphere of radius 1 / (1/R_cup + 1/R_dome).
pub const GEL_DOME_MM: f64 = 17.0;

impl Cup {
    /// A cup with this wall stiffness; the cubic term is 4 % of `k` per mm^2 (at 5 mm it adds
    /// the linear force again), damping ratio 0.05, 5 g of moving wall.
    pub fn new(label: &str, diameter_mm: f64, k_n_per_mm: f64) -> Self {
        Self {
            label: label.into(),
            diameter_mm,
            k_n_per_mm,
            k3_n_per_mm3: 0.04 * k_n_per_mm,
            damping_ratio: 0.05,
            wall_mass_kg: 0.005,
        }
    }
    /// A paper cup of this diameter: a ring's lateral stiffness scales as 1/R^3, 0.3 N/mm at
    /// 80 mm.
    pub fn paper(diameter_mm: f64) -> Self {
        let d = diameter_mm.max(10.0);
        Self::new("cup", d, 0.3 * (80.0 / d).powi(3))
    }
    /// The report's three cups: soft paper (0.05 N/mm), stiff plastic (5 N/mm), near-rigid
    /// (500 N/mm): four orders of magnitude.
    pub fn soft() -> Self {
        Self::new("soft", 80.0, 0.05)
    }
    pub fn stiff() -> Self {
        Self::new("stiff", 80.0, 5.0)
    }
    pub fn extreme() -> Self {
        Self::new("extreme", 80.0, 500.0)
    }
    /// Mass in N s^2/mm.
    pub fn mass(&self) -> f64 {
        self.wall_mass_kg * 1e-3
    }
    /// Viscous coefficient of the wall [N s/mm].
    pub fn damping(&self) -> f64 {
        2.0 * self.damping_ratio * (self.k_n_per_mm * self.mass()).sqrt()
    }
    /// Wall spring force at deformation x [mm] and its derivative.
    pub fn spring(&self, x: f64) -> (f64, f64) {
        (
            self.k_n_per_mm * x + self.k3_n_per_mm3 * x * x * x,
            self.k_n_per_mm + 3.0 * self.k3_n_per_mm3 * x * x,
        )
    }
    /// Potential energy of the wall spring [N mm = mJ].
    pub fn spring_energy(&self, x: f64) -> f64 {
        0.5 * self.k_n_per_mm * x * x + 0.25 * self.k3_n_per_mm3 * x.powi(4)
    }
    /// What the gel sees of the cup (a smooth sphere of the combined curvature).
    pub fn object(&self) -> Object {
        let r = 1.0 / (2.0 / self.diameter_mm.max(1.0) + 1.0 / GEL_DOME_MM);
        Object::new(&self.label, r, 0.005, 2.0)
    }
}

/// The elastomer on each finger.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Gel {
    /// Hertz-like stiffness: F = kg d^1.5 [N/mm^1.5].
    pub k_n_per_mm15: f64,
    /// Viscosity while in contact [N s/mm].
    pub c_n_s_per_mm: f64,
}

impl Default for Gel {
    fn default() -> Self {
        Self {
            k_n_per_mm15: 4.0,
            c_n_s_per_mm: 0.002,
        }
    }
}

impl Gel {
    /// Elastic force [N] and tangent stiffness [N/mm] at penetration d [mm].
    pub fn elastic(&self, d: f64) -> (f64, f64) {
        if d <= 0.0 {
            return (0.0, 0.0);
        }
        let s = d.sqrt();
        (self.k_n_per_mm15 * d * s, 1.5 * self.k_n_per_mm15 * s)
    }
    /// Force on the wall [N] at penetration d and penetration rate dd [mm/s]; never pulls.
    pub fn force(&self, d: f64, dd: f64) -> f64 {
        if d <= 0.0 {
            return 0.0;
        }
        (self.elastic(d).0 + self.c_n_s_per_mm * dd).max(0.0)
    }
    /// Stored elastic energy [mJ].
    pub fn energy(&self, d: f64) -> f64 {
        if d <= 0.0 {
            0.0
        } else {
            self.k_n_per_mm15 * d.powf(2.5) / 2.5
        }
    }
}

/// The 1-DOF parallel gripper.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Gripper {
    /// Speed limit per finger [mm/s].
    pub speed_mm_s: f64,
    /// Force limit per finger [N]: closing stalls above it.
    pub max_force_n: f64,
    /// Force-command admittance: closing speed per newton of force error [mm/s/N].
    pub force_gain: f64,
}

impl Default for Gripper {
    fn default() -> Self {
        Self {
            speed_mm_s: 4.0,
            max_force_n: 20.0,
            force_gain: 2.0,
        }
    }
}

/// What the gripper is told to do.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub enum Command {
    /// Finger position [mm] (closing, 0 = touching the undeformed cup).
    Position(f64),
    /// Grip force per finger [N].
    Force(f64),
}

/// How a step is split.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub enum Substep {
    /// One integrator step per world step.
    Off,
    /// Sub-steps no longer than `safety` x the method's stability bound at the current state.
    Stability { safety: f64 },
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
    /// Finger position at t = 0 [mm] (negative: open, not touching).
    pub start_mm: f64,
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
            start_mm: -0.4,
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
}

/// Ground truth after a step.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Default)]
pub struct WorldTruth {
    pub t_s: f64,
    /// Finger position [mm] (closing, 0 = touching the undeformed cup).
    pub finger_mm: f64,
    /// Gripper opening [mm]: cup diameter - 2 x finger position.
    pub width_mm: f64,
    /// Force between gel and cup [N] per finger.
    pub force_n: f64,
    /// Loss of cup diameter [mm] (2 x wall deformation).
    pub deformation_mm: f64,
    /// Gel penetration [mm]; negative is the gap to the wall.
    pub penetration_mm: f64,
    /// Wall velocity [mm/s].
    pub wall_velocity_mm_s: f64,
    /// Integrator steps this world step took.
    pub substeps: u32,
    /// Largest force at the end of any of those sub-steps [N] (a peak inside the step).
    pub step_peak_force_n: f64,
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

/// Iterations and tolerance of the Newton solve [mm] (relative to 1 + |x|).
const NEWTON_ITERS: u32 = 60;
const NEWTON_TOL_MM: f64 = 1e-13;

impl World {
    pub fn new(cfg: WorldConfig) -> Self {
        let p = cfg.start_mm;
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
    pub fn set_wall(&mut self, x_mm: f64, v_mm_s: f64) {
        self.x = x_mm;
        self.v = v_mm_s;
    }
    pub fn time(&self) -> f64 {
        self.t
    }
    /// Most Newton iterations any backward-Euler step needed so far.
    pub fn newton_max_iters(&self) -> u32 {
        self.newton_max_iters
    }

    /// Total mechanical energy of wall and gels [mJ].
    pub fn energy(&self) -> f64 {
        0.5 * self.cfg.cup.mass() * self.v * self.v
            + self.cfg.cup.spring_energy(self.x)
            + self.cfg.gel.energy(self.p - self.x)
    }

    pub fn truth(&self, substeps: u32) -> WorldTruth {
        WorldTruth {
            t_s: self.t,
            finger_mm: self.p,
            width_mm: self.cfg.cup.diameter_mm - 2.0 * self.p,
            force_n: self.force,
            deformation_mm: 2.0 * self.x,
            penetration_mm: self.p - self.x,
            wall_velocity_mm_s: self.v,
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
        let vmax = g.speed_mm_s.max(0.0) * h;
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

    /// Advance by `h` seconds while the finger moves linearly to `p1` [mm] (a prescribed motion,
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

    /// Number of sub-steps for a step of `h` from the current state.
    pub fn substeps(&self, h: f64) -> u32 {
        let Substep::Stability { safety } = self.cfg.substep else {
            return 1;
        };
        let bound = self.stable_step();
        if bound.is_infinite() {
            return 1;
        }
        let cap = self.cfg.max_substeps.max(1);
        if bound <= 0.0 {
            return cap;
        }
        let n = (h / (safety.clamp(1e-3, 1.0) * bound)).ceil();
        if n.is_finite() {
            (n.max(1.0) as u64).min(u64::from(cap)) as u32
        } else {
            cap
        }
    }

    /// The method's stability bound [s] linearised at the current state.
    pub fn stable_step(&self) -> f64 {
        let (k, c) = self.tangent(self.x, self.p);
        self.cfg.method.stable_step(self.cfg.cup.mass(), k, c)
    }

    /// Tangent stiffness and damping of the wall at (x, p).
    fn tangent(&self, x: f64, p: f64) -> (f64, f64) {
        let cup = &self.cfg.cup;
        let (_, ks) = cup.spring(x);
        let (_, kg) = self.cfg.gel.elastic(p - x);
        let cg = if p > x {
            self.cfg.gel.c_n_s_per_mm
        } else {
            0.0
        };
        (ks + kg, cup.damping() + cg)
    }

    /// Net force on the wall [N] and the gel force, with the finger at p moving at pv.
    fn forces(&self, x: f64, v: f64, p: f64, pv: f64) -> (f64, f64) {
        let cup = &self.cfg.cup;
        let fg = self.cfg.gel.force(p - x, pv - v);
        (fg - cup.spring(x).0 - cup.damping() * v, fg)
    }

    /// One integrator step of length h, finger moving from self.p to p1.
    fn integrate(&mut self, h: f64, p1: f64) {
        let m = self.cfg.cup.mass();
        let pv = (p1 - self.p) / h;
        match self.cfg.method {
            Method::ExplicitEuler => {
                let (f, _) = self.forces(self.x, self.v, self.p, pv);
                self.x += h * self.v;
                self.v += h * f / m;
            }
            Method::SemiImplicitEuler => {
                let (f, _) = self.forces(self.x, self.v, self.p, pv);
                self.v += h * f / m;
                self.x += h * self.v;
            }
            Method::BackwardEuler => {
                let (x1, iters) = self.solve_backward_euler(h, p1, pv);
                self.newton_max_iters = self.newton_max_iters.max(iters);
                self.v = (x1 - self.x) / h;
                self.x = x1;
            }
        }
        self.p = p1;
        self.force = self.forces(self.x, self.v, self.p, pv).1;
    }

    /// Backward Euler: find x1 with m (v1 - v0) = h F(x1, v1), v1 = (x1 - x0) / h.
    /// The residual r(x1) = m (x1 - x0 - h v0) - h^2 F(x1, (x1 - x0)/h) is increasing in x1
    /// (spring and gel forces are monotone, damping positive), so the root is unique; Newton's
    /// method is safeguarded by a bracket and bisection. Returns (x1, iterations).
    fn solve_backward_euler(&self, h: f64, p1: f64, pv: f64) -> (f64, u32) {
        let m = self.cfg.cup.mass();
        let (x0, v0) = (self.x, self.v);
        let r = |x1: f64| -> f64 {
            let v1 = (x1 - x0) / h;
            m * (x1 - x0 - h * v0) - h * h * self.forces(x1, v1, p1, pv).0
        };
        let dr = |x1: f64| -> f64 {
            let (k, c) = self.tangent(x1, p1);
            m + h * c + h * h * k
        };
        // Bracket the root around the explicit guess.
        let guess = x0 + h * v0;
        let mut step = 1e-3_f64.max((h * v0).abs());
        let (mut lo, mut hi) = (guess, guess);
        let mut k = 0;
        while r(lo) > 0.0 && k < 200 {
            lo -= step;
            step *= 2.0;
            k += 1;
        }
        step = 1e-3_f64.max((h * v0).abs());
        k = 0;
        while r(hi) < 0.0 && k < 200 {
            hi += step;
            step *= 2.0;
            k += 1;
        }
        let mut x = guess.clamp(lo, hi);
        for it in 1..=NEWTON_ITERS {
            let rx = r(x);
            if rx > 0.0 {
                hi = x;
            } else {
                lo = x;
            }
            let mut xn = x - rx / dr(x);
            if !(xn >= lo && xn <= hi) {
                xn = 0.5 * (lo + hi);
            }
            let dx = (xn - x).abs();
            if dx <= NEWTON_TOL_MM * (1.0 + x.abs()) || hi - lo <= NEWTON_TOL_MM {
                return (xn, it);
            }
            x = xn;
        }
        (x, NEWTON_ITERS)
    }

    /// Why the state is no longer physical, if it is not.
    fn broken(&self) -> Option<String> {
        if !(self.x.is_finite() && self.v.is_finite() && self.force.is_finite()) {
            return Some("non-finite state".into());
        }
        let r = 0.5 * self.cfg.cup.diameter_mm;
        if self.x.abs() > r {
            return Some(format!(
                "wall moved {:.1} mm, more than the cup's radius",
                self.x
            ));
        }
        None
    }
}

/// Static equilibrium: wall deformation x [mm] with the finger held at p (gel force = wall
/// spring force), by bisection (both sides are monotone in x).
pub fn static_wall(cup: &Cup, gel: &Gel, p: f64) -> f64 {
    if p <= 0.0 {
        return 0.0;
    }
    let f = |x: f64| gel.elastic(p - x).0 - cup.spring(x).0;
    let (mut lo, mut hi) = (0.0, p);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if f(mid) > 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// Finger position [mm] at which the static deformation (2 x) reaches `target_mm`, or the gel
/// force reaches `max_force_n`, whichever comes first.
pub fn static_finger_for(cup: &Cup, gel: &Gel, target_mm: f64, max_force_n: f64) -> f64 {
    let x_target = 0.5 * target_mm;
    let f_target = cup.spring(x_target).0;
    let f = f_target.min(max_force_n);
    let x = if f < f_target {
        // Force-limited: find x with spring(x) = f.
        let (mut lo, mut hi) = (0.0, x_target);
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if cup.spring(mid).0 < f {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        0.5 * (lo + hi)
    } else {
        x_target
    };
    // Gel penetration carrying f.
    x + (f / gel.k_n_per_mm15.max(1e-12)).powf(2.0 / 3.0)
}

/// One sample of a grip for the renderer and the ground truth.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Default)]
pub struct GripSample {
    pub t_s: f64,
    pub penetration_mm: f64,
    pub force_n: f64,
    pub deformation_mm: f64,
}

/// What a closed-loop grip did.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct GripRun {
    pub samples: Vec<GripSample>,
    /// Time the target deformation (or the force limit) was reached [s], and the hold's end.
    pub closed_s: f64,
    pub hold_end_s: f64,
    pub final_deformation_mm: f64,
    pub peak_force_n: f64,
}

/// The paper's cup task, closed loop: close at the speed limit until the cup is compressed by
/// `target_mm` (ground-truth deformation) or the force limit is hit, hold for `hold_s`, open
/// back to the start. Control period `dt` [s]; one sample per control period.
pub fn grip_cup(
    cfg: WorldConfig,
    target_mm: f64,
    hold_s: f64,
    dt: f64,
) -> Result<GripRun, WorldError> {
    let mut w = World::new(cfg);
    let start = w.cfg.start_mm;
    let far = w.cfg.cup.diameter_mm * 0.5;
    let mut samples = Vec::new();
    let mut peak: f64 = 0.0;
    let sample = |t: WorldTruth| GripSample {
        t_s: t.t_s,
        penetration_mm: t.penetration_mm,
        force_n: t.force_n,
        deformation_mm: t.deformation_mm,
    };
    samples.push(sample(w.truth(0)));
    // Close.
    let max_steps = (60.0 / dt).ceil() as u64;
    let mut k = 0;
    let mut last = w.truth(0);
    while last.deformation_mm < target_mm && k < max_steps {
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
    let final_deformation_mm = last.deformation_mm;
    // Open until the gel has left the wall and the finger is back at the start.
    k = 0;
    while (w.p > start + 1e-9 || last.penetration_mm > start * 0.25) && k < max_steps {
        last = w.step(dt, Command::Position(start))?;
        samples.push(sample(last));
        k += 1;
    }
    Ok(GripRun {
        samples,
        closed_s,
        hold_end_s,
        final_deformation_mm,
        peak_force_n: peak,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn free(method: Method, cup: Cup, h: f64, steps: usize) -> (f64, Vec<f64>) {
        let mut cfg = WorldConfig::new(cup).with_method(method, Substep::Off);
        cfg.start_mm = -30.0; // fingers far away: a free wall
        let mut w = World::new(cfg);
        w.set_wall(1.0, 0.0);
        let e0 = w.energy();
        let mut es = Vec::with_capacity(steps);
        for _ in 0..steps {
            match w.step_finger(h, -30.0) {
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
        let mut c = Cup::new("free", 80.0, k);
        c.damping_ratio = 0.0;
        c
    }

    #[test]
    fn energy_does_not_grow_in_a_free_oscillation() {
        for cup in [undamped(0.05), undamped(5.0), undamped(500.0)] {
            let w = (cup.k_n_per_mm / cup.mass()).sqrt();
            let h = 0.2 / w; // 31 steps per period
            let steps = 100 * 32; // 100 periods
            // Semi-implicit: energy oscillates within O(w h) of E0 and does not drift.
            let (e0, es) = free(Method::SemiImplicitEuler, cup.clone(), h, steps);
            let max = es.iter().cloned().fold(0.0, f64::max);
            assert!(max <= e0 * 1.15, "{}: {max} vs {e0}", cup.k_n_per_mm);
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
        cup.k3_n_per_mm3 = 0.0;
        let (m, k, c) = (cup.mass(), cup.k_n_per_mm, cup.damping());
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
        for cup in [Cup::soft(), Cup::paper(80.0), Cup::stiff(), Cup::extreme()] {
            // Static: force at the gel vs finger position.
            let gel = Gel::default();
            let mut prev = -1.0;
            for i in 1..200 {
                let p = i as f64 * 0.05;
                let x = static_wall(&cup, &gel, p);
                let f = gel.elastic(p - x).0;
                assert!(f > prev, "{}: {f} <= {prev} at {p}", cup.label);
                assert!((f - cup.spring(x).0).abs() < 1e-6 * f.max(1.0));
                prev = f;
            }
            // Dynamic: a slow close (1 mm/s) with the implicit method. The gel's viscous part
            // (at most cg x finger speed = 0.002 N) may relax while the wall starts to move.
            let tol = Gel::default().c_n_s_per_mm * 1.0;
            let cfg =
                WorldConfig::new(cup.clone()).with_method(Method::BackwardEuler, Substep::Off);
            let mut w = World::new(cfg);
            let mut prev = 0.0;
            let mut pen_prev = f64::NEG_INFINITY;
            for i in 1..2000 {
                let t = w.step_finger(1e-3, -0.4 + i as f64 * 1e-3).unwrap();
                if t.penetration_mm > 0.0 {
                    assert!(t.penetration_mm > pen_prev, "{}", cup.label);
                    assert!(
                        t.force_n >= prev - tol,
                        "{}: {} < {prev}",
                        cup.label,
                        t.force_n
                    );
                }
                pen_prev = t.penetration_mm;
                prev = t.force_n;
            }
            assert!(prev > 0.0);
        }
    }

    #[test]
    fn grip_reaches_the_target_deformation_and_reports_truth() {
        let cfg = WorldConfig::new(Cup::paper(80.0));
        let run = grip_cup(cfg, 10.0, 0.5, 1e-3).unwrap();
        assert!((run.final_deformation_mm - 10.0).abs() < 0.1, "{run:?}");
        assert!(run.peak_force_n > 1.0 && run.peak_force_n < 5.0);
        let last = run.samples.last().unwrap();
        assert!(last.penetration_mm < 0.0 && last.force_n == 0.0);
        // A near-rigid cup: the gripper stalls at its force limit, deformation stays small.
        let cfg = WorldConfig::new(Cup::extreme());
        let run = grip_cup(cfg, 10.0, 0.2, 1e-3).unwrap();
        assert!(run.final_deformation_mm < 0.2);
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
            if let Err(e) = w.step_finger(1e-3, -0.4 + i as f64 * 4e-3) {
                err = Some(e);
                break;
            }
        }
        assert!(matches!(err, Some(WorldError::Diverged { .. })), "{err:?}");
    }
}
