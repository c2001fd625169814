//! The physical model of the world: the cup wall, the gel on each finger, the gripper, and the
//! static equilibrium between them.
//!
//! # Model (per side; the two fingers are symmetric)
//! Units: SI (m, N, s, kg).
//! - finger position `p` \[m], closing positive, 0 = the gel surface touches the undeformed wall.
//!   The gripper moves it kinematically: toward a position target at no more than its speed
//!   limit, or (force command) at a speed proportional to the force error, also limited; it stalls
//!   at its force limit.
//! - wall deformation `x` \[m] (inward) and velocity `v`: `m x'' = F_gel - (k x + k3 x^3 + c v)`.
//! - gel penetration `d = p - x`; the gel pushes with `F_gel = kg d^1.5 + cg d'` while `d > 0`
//!   (Hertz-like elastomer with a little viscosity), never pulls.
//!
//! Cup deformation (ground truth) is the loss of diameter, `2 x`.

use serde::Serialize;

use crate::object::Object;

/// A cup: size and wall (one side's lateral spring-damper).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Cup {
    pub label: String,
    pub diameter_m: f64,
    /// Linear wall stiffness per side [N/m].
    pub k_n_per_m: f64,
    /// Cubic stiffening [N/m^3] (a wall stiffens as it flattens).
    pub k3_n_per_m3: f64,
    /// Damping ratio of the wall's own mode at its linear stiffness.
    pub damping_ratio: f64,
    /// Moving mass of one wall side \[kg].
    pub wall_mass_kg: f64,
}

/// Radius of the gel's dome \[m]: the cup wall (curved one way) on the domed gel looks to the
/// renderer like a sphere of radius 1 / (1/R_cup + 1/R_dome).
pub const GEL_DOME_M: f64 = 0.017;

/// The length over which the cubic term of a wall adds its linear force again \[m] (5 mm): the
/// cubic stiffness is `k / CUBIC_LENGTH_M^2`.
pub const CUBIC_LENGTH_M: f64 = 0.005;

impl Cup {
    /// A cup with this wall stiffness; the cubic term adds the linear force again at 5 mm
    /// ([`CUBIC_LENGTH_M`]), damping ratio 0.05, 5 g of moving wall.
    pub fn new(label: &str, diameter_m: f64, k_n_per_m: f64) -> Self {
        Self {
            label: label.into(),
            diameter_m,
            k_n_per_m,
            k3_n_per_m3: k_n_per_m / (CUBIC_LENGTH_M * CUBIC_LENGTH_M),
            damping_ratio: 0.05,
            wall_mass_kg: 0.005,
        }
    }
    /// A paper cup of this diameter: a ring's lateral stiffness scales as 1/R^3, 300 N/m at
    /// 80 mm.
    pub fn paper(diameter_m: f64) -> Self {
        let d = diameter_m.max(0.010);
        Self::new("cup", d, 300.0 * (0.080 / d).powi(3))
    }
    /// The report's three cups: soft paper (50 N/m), stiff plastic (5 kN/m), near-rigid
    /// (500 kN/m): four orders of magnitude.
    pub fn soft() -> Self {
        Self::new("soft", 0.080, 50.0)
    }
    pub fn stiff() -> Self {
        Self::new("stiff", 0.080, 5e3)
    }
    pub fn extreme() -> Self {
        Self::new("extreme", 0.080, 5e5)
    }
    /// Moving mass of one wall side \[kg].
    pub fn mass(&self) -> f64 {
        self.wall_mass_kg
    }
    /// Viscous coefficient of the wall [N s/m].
    pub fn damping(&self) -> f64 {
        2.0 * self.damping_ratio * (self.k_n_per_m * self.mass()).sqrt()
    }
    /// Wall spring force \[N] at deformation x \[m] and its derivative [N/m].
    pub fn spring(&self, x: f64) -> (f64, f64) {
        (
            self.k_n_per_m * x + self.k3_n_per_m3 * x * x * x,
            self.k_n_per_m + 3.0 * self.k3_n_per_m3 * x * x,
        )
    }
    /// Potential energy of the wall spring \[J].
    pub fn spring_energy(&self, x: f64) -> f64 {
        0.5 * self.k_n_per_m * x * x + 0.25 * self.k3_n_per_m3 * x.powi(4)
    }
    /// What the gel sees of the cup (a smooth sphere of the combined curvature).
    pub fn object(&self) -> Object {
        let r_m = 1.0 / (2.0 / self.diameter_m.max(0.001) + 1.0 / GEL_DOME_M);
        Object::new(&self.label, r_m * 1e3, 0.005, 2.0)
    }
}

/// The elastomer on each finger.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Gel {
    /// Hertz-like stiffness: F = kg d^1.5 [N/m^1.5].
    pub k_n_per_m15: f64,
    /// Viscosity while in contact [N s/m].
    pub c_n_s_per_m: f64,
}

impl Default for Gel {
    fn default() -> Self {
        Self {
            // 4 N/mm^1.5 and 0.002 N s/mm.
            k_n_per_m15: 126_491.106_406_735_2,
            c_n_s_per_m: 2.0,
        }
    }
}

impl Gel {
    /// Elastic force \[N] and tangent stiffness [N/m] at penetration d \[m].
    pub fn elastic(&self, d: f64) -> (f64, f64) {
        if d <= 0.0 {
            return (0.0, 0.0);
        }
        let s = d.sqrt();
        (self.k_n_per_m15 * d * s, 1.5 * self.k_n_per_m15 * s)
    }
    /// Force on the wall \[N] at penetration d and penetration rate dd [m/s]; never pulls.
    pub fn force(&self, d: f64, dd: f64) -> f64 {
        if d <= 0.0 {
            return 0.0;
        }
        (self.elastic(d).0 + self.c_n_s_per_m * dd).max(0.0)
    }
    /// Stored elastic energy \[J].
    pub fn energy(&self, d: f64) -> f64 {
        if d <= 0.0 {
            0.0
        } else {
            self.k_n_per_m15 * d.powf(2.5) / 2.5
        }
    }
}

/// The 1-DOF parallel gripper.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Gripper {
    /// Speed limit per finger [m/s].
    pub speed_m_s: f64,
    /// Force limit per finger \[N]: closing stalls above it.
    pub max_force_n: f64,
    /// Force-command admittance: closing speed per newton of force error [m/s/N].
    pub force_gain: f64,
}

impl Default for Gripper {
    fn default() -> Self {
        Self {
            speed_m_s: 0.004,
            max_force_n: 20.0,
            force_gain: 0.002,
        }
    }
}

/// Static equilibrium: wall deformation x \[m] with the finger held at p (gel force = wall
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

/// Finger position \[m] at which the static deformation (2 x) reaches `target_m`, or the gel
/// force reaches `max_force_n`, whichever comes first.
pub fn static_finger_for(cup: &Cup, gel: &Gel, target_m: f64, max_force_n: f64) -> f64 {
    let x_target = 0.5 * target_m;
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
    x + (f / gel.k_n_per_m15.max(1e-12)).powf(2.0 / 3.0)
}
