//! The held object's vertical motion: Coulomb friction between the two gels and the object.
//!
//! One axis (up). The object (height `z` above where it rests, velocity `v`) is loaded by
//! `down(z, v)` (weight, drag) and has mass `m(z)`; the table holds it at `z = 0`. The fingers
//! (the arm's vertical speed `va` and acceleration `aa`) press it with the grip force `N` per
//! finger, so friction can carry at most `2 mu_s N` while it sticks and gives `2 mu_k N` against
//! the relative motion while it slips:
//! - stick: the object moves with the fingers while the force that takes,
//!   `m aa + down`, is within `2 mu_s N`;
//! - slip: `m v' = +-2 mu_k N - down` (semi-implicit Euler), until the relative velocity changes
//!   sign and the force to stick is within the static bound again;
//! - no grip (`N = 0`): the object falls to the table.
//!
//! The gel surface takes the tangential force as a spring (shear stiffness per finger): its
//! displacement is the force share over that stiffness (quasi-static), and slip is the relative
//! motion of object and fingers.

use serde::Serialize;

/// Standard gravity \[m/s^2].
pub const G: f64 = 9.81;

/// The object's vertical load at height `z` and velocity `v`: (mass \[kg], downward force \[N]).
pub(crate) type Load<'a> = &'a dyn Fn(f64, f64) -> (f64, f64);

/// Vertical state of the object between the fingers (or resting).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Default)]
pub struct Hold {
    /// Height of the object above where it rests \[m].
    pub z_m: f64,
    pub v_m_s: f64,
    /// Moving with the fingers (no relative motion).
    pub stuck: bool,
    /// Tangential (vertical) force friction gives the object, both fingers \[N], up positive.
    pub friction_n: f64,
    /// Relative motion of fingers over object since the grasp, signed (fingers up positive) \[m].
    pub slip_net_m: f64,
    /// Relative motion since the grasp, summed unsigned \[m].
    pub slip_total_m: f64,
}

impl Hold {
    /// A new grasp: slip counters start at zero.
    pub fn regrasp(&mut self) {
        self.stuck = true;
        self.slip_net_m = 0.0;
        self.slip_total_m = 0.0;
    }

    /// Advance by `h` \[s]; returns the slip in this step \[m] (relative motion, signed, fingers
    /// up positive).
    pub fn step(
        &mut self,
        h: f64,
        va: f64,
        aa: f64,
        grip_n: f64,
        mu: (f64, f64),
        load: Load<'_>,
    ) -> f64 {
        if grip_n <= 0.0 {
            self.stuck = false;
            self.friction_n = 0.0;
            if self.z_m > 0.0 || self.v_m_s > 0.0 {
                self.v_m_s -= G * h;
                self.z_m += self.v_m_s * h;
            }
            if self.z_m <= 0.0 {
                self.z_m = 0.0;
                self.v_m_s = 0.0;
            }
            return 0.0;
        }
        let (lim_s, lim_k) = (2.0 * mu.0 * grip_n, 2.0 * mu.1 * grip_n);
        // Resting on the table while the fingers do not lift: the table carries the load; fingers
        // that move down rub along the object.
        if self.z_m <= 0.0 && va <= 0.0 {
            self.z_m = 0.0;
            self.v_m_s = 0.0;
            self.stuck = va == 0.0;
            self.friction_n = if va < 0.0 { -lim_k } else { 0.0 };
            return self.slipped(va * h);
        }
        let (m, down) = load(self.z_m, va);
        let m = m.max(1e-6);
        let need = m * aa + down;
        if self.stuck && need.abs() <= lim_s {
            self.v_m_s = va;
            self.z_m = (self.z_m + va * h).max(0.0);
            self.friction_n = need;
            return 0.0;
        }
        let (_, down) = load(self.z_m, self.v_m_s);
        let rel = va - self.v_m_s;
        let dir = if rel != 0.0 {
            rel.signum()
        } else {
            need.signum()
        };
        let f = dir * lim_k;
        let v1 = self.v_m_s + h * (f - down) / m;
        let rel1 = va - v1;
        if rel1 * rel <= 0.0 && need.abs() <= lim_s {
            // The relative velocity crossed zero and static friction can hold: stick again.
            self.stuck = true;
            self.v_m_s = va;
        } else {
            self.stuck = false;
            self.v_m_s = v1;
        }
        self.z_m += self.v_m_s * h;
        if self.z_m <= 0.0 {
            self.z_m = 0.0;
            self.v_m_s = self.v_m_s.max(0.0);
        }
        self.friction_n = f;
        self.slipped((va - self.v_m_s) * h)
    }

    fn slipped(&mut self, ds: f64) -> f64 {
        self.slip_net_m += ds;
        self.slip_total_m += ds.abs();
        ds
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Lift a 100 g object at 0.1 m/s after a 2 m/s^2 ramp; returns (final height, total slip).
    fn lift(grip_n: f64, mu: f64) -> (f64, f64) {
        let load = |_: f64, _: f64| (0.1, 0.1 * G);
        let mut h = Hold::default();
        h.regrasp();
        let dt = 1e-3;
        for k in 0..1000 {
            let t = k as f64 * dt;
            let (va, aa) = if t < 0.05 { (2.0 * t, 2.0) } else { (0.1, 0.0) };
            h.step(dt, va, aa, grip_n, (mu, 0.8 * mu), &load);
        }
        (h.z_m, h.slip_total_m)
    }

    #[test]
    fn an_object_lifts_above_the_friction_bound_and_stays_below_it() {
        // Bound: 2 mu N >= m (g + a) = 0.1 x 11.81 = 1.181 N; with mu = 0.5, N >= 1.181 N.
        let (z, slip) = lift(1.3, 0.5);
        assert!(z > 0.09 && slip < 1e-9, "{z} {slip}");
        let (z, slip) = lift(1.0, 0.5);
        assert!(z < 0.01 && slip > 0.05, "{z} {slip}");
    }

    #[test]
    fn without_grip_a_lifted_object_falls_to_the_table() {
        let load = |_: f64, _: f64| (0.1, 0.1 * G);
        let mut h = Hold {
            z_m: 0.05,
            ..Hold::default()
        };
        for _ in 0..200 {
            h.step(1e-3, 0.0, 0.0, 0.0, (0.5, 0.4), &load);
        }
        assert_eq!((h.z_m, h.v_m_s), (0.0, 0.0));
    }
}
