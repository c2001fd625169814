//! Integration of the wall: the methods, their stability bounds, sub-stepping, and the step.
//!
//! # Stability bounds
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

use super::World;

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

    /// Largest stable step \[s] for a linear oscillator of mass `m` \[kg], stiffness `k`
    /// [N/m] and damping `c` [N s/m] (see the module docs). `f64::INFINITY` when any step is
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

/// A method name that is none of [`Method::ALL`].
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[error("unknown method '{0}' (explicit_euler, semi_implicit_euler, backward_euler)")]
pub struct UnknownMethod(pub String);

impl std::str::FromStr for Method {
    type Err = UnknownMethod;
    fn from_str(s: &str) -> Result<Self, UnknownMethod> {
        Method::ALL
            .into_iter()
            .find(|m| m.as_str() == s)
            .ok_or_else(|| UnknownMethod(s.to_string()))
    }
}

/// How a step is split.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub enum Substep {
    /// One integrator step per world step.
    Off,
    /// Sub-steps no longer than `safety` x the method's stability bound at the current state.
    Stability { safety: f64 },
}

/// Iterations and relative tolerance of the Newton solve: a step ends when it moves the wall by
/// less than `NEWTON_TOL` x (`NEWTON_SCALE_M` + |x|).
const NEWTON_ITERS: u32 = 60;
const NEWTON_TOL: f64 = 1e-13;
/// Length scale of the Newton tolerance and of the bracket's first step \[m] (1 mm).
const NEWTON_SCALE_M: f64 = 1e-3;

impl World {
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

    /// The method's stability bound \[s] linearised at the current state.
    pub fn stable_step(&self) -> f64 {
        let (k, c) = self.tangent(self.x, self.p);
        self.cfg.method.stable_step(self.cfg.cup.mass(), k, c)
    }

    /// Tangent stiffness and damping of the wall at (x, p).
    fn tangent(&self, x: f64, p: f64) -> (f64, f64) {
        let cup = &self.cfg.cup;
        let (_, ks) = cup.spring(x);
        let (_, kg) = self.cfg.gel.elastic(p - x);
        let cg = if p > x { self.cfg.gel.c_n_s_per_m } else { 0.0 };
        (ks + kg, cup.damping() + cg)
    }

    /// Net force on the wall [N] and the gel force, with the finger at p moving at pv.
    fn forces(&self, x: f64, v: f64, p: f64, pv: f64) -> (f64, f64) {
        let cup = &self.cfg.cup;
        let fg = self.cfg.gel.force(p - x, pv - v);
        (fg - cup.spring(x).0 - cup.damping() * v, fg)
    }

    /// One integrator step of length h, finger moving from self.p to p1.
    pub(super) fn integrate(&mut self, h: f64, p1: f64) {
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
        let mut step = (NEWTON_SCALE_M * 1e-3).max((h * v0).abs());
        let (mut lo, mut hi) = (guess, guess);
        let mut k = 0;
        while r(lo) > 0.0 && k < 200 {
            lo -= step;
            step *= 2.0;
            k += 1;
        }
        step = (NEWTON_SCALE_M * 1e-3).max((h * v0).abs());
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
            if dx <= NEWTON_TOL * (NEWTON_SCALE_M + x.abs())
                || hi - lo <= NEWTON_TOL * NEWTON_SCALE_M
            {
                return (xn, it);
            }
            x = xn;
        }
        (x, NEWTON_ITERS)
    }
}
