//! The arm, kinematic: the fingertip centre moves toward its target with a speed and an
//! acceleration bound per axis (a trapezoidal profile that brakes to stop on the target). No
//! dynamics, no joints: what a position-controlled arm with a Cartesian planner does.

use serde::Serialize;

/// Speed and acceleration bounds of the arm and its home pose.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ArmLimits {
    /// Per-axis speed bound \[m/s].
    pub max_speed_m_s: f64,
    /// Per-axis acceleration bound \[m/s^2].
    pub max_accel_m_s2: f64,
    /// Fingertip centre at home, table frame (x forward, y left, z up) \[m].
    pub home_m: [f64; 3],
}

impl Default for ArmLimits {
    fn default() -> Self {
        Self {
            max_speed_m_s: 0.25,
            max_accel_m_s2: 2.0,
            home_m: [0.30, 0.0, 0.25],
        }
    }
}

/// Within this distance of the target on every axis, and this slow, the arm has arrived.
const ARRIVED_M: f64 = 5e-4;
const ARRIVED_M_S: f64 = 2e-3;

/// The arm's state (table frame, SI).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Default)]
pub struct ArmState {
    pub position_m: [f64; 3],
    pub velocity_m_s: [f64; 3],
    /// Acceleration over the last sub-step \[m/s^2].
    pub accel_m_s2: [f64; 3],
    pub target_m: [f64; 3],
    /// At the target and (nearly) still.
    pub arrived: bool,
    /// The last sub-step's move was refused (the closed fingers met an object).
    pub blocked: bool,
}

impl ArmState {
    pub fn at(position_m: [f64; 3]) -> Self {
        Self {
            position_m,
            target_m: position_m,
            arrived: true,
            ..Self::default()
        }
    }

    /// The state after `h` seconds toward `target` (not applied: the caller may refuse it).
    pub fn advanced(&self, lim: &ArmLimits, target: [f64; 3], h: f64) -> ArmState {
        let (vmax, amax) = (lim.max_speed_m_s.max(0.0), lim.max_accel_m_s2.max(0.0));
        let mut next = *self;
        next.target_m = target;
        next.blocked = false;
        for (i, &goal) in target.iter().enumerate() {
            let e = goal - self.position_m[i];
            // Fastest speed that still stops on the target, and no overshoot within this step.
            let reach = vmax.min((2.0 * amax * e.abs()).sqrt()).min(e.abs() / h);
            let v_des = reach.copysign(e);
            let v = self.velocity_m_s[i];
            let v1 = v + (v_des - v).clamp(-amax * h, amax * h);
            next.velocity_m_s[i] = v1;
            next.accel_m_s2[i] = (v1 - v) / h;
            // The table is the floor: fingertips never go below it.
            next.position_m[i] = self.position_m[i] + v1 * h;
        }
        if next.position_m[2] < 0.0 {
            next.position_m[2] = 0.0;
            next.velocity_m_s[2] = 0.0;
        }
        next.arrived = (0..3).all(|i| {
            (target[i] - next.position_m[i]).abs() <= ARRIVED_M
                && next.velocity_m_s[i].abs() <= ARRIVED_M_S
        });
        next
    }

    /// This state, stopped where it is (a refused move).
    pub fn blocked(&self, target: [f64; 3]) -> ArmState {
        ArmState {
            velocity_m_s: [0.0; 3],
            accel_m_s2: [0.0; 3],
            target_m: target,
            arrived: false,
            blocked: true,
            ..*self
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_arm_reaches_its_target_within_its_bounds() {
        let lim = ArmLimits::default();
        let mut a = ArmState::at(lim.home_m);
        let target = [0.45, 0.1, 0.05];
        let h = 1e-3;
        let mut t = 0.0;
        loop {
            let n = a.advanced(&lim, target, h);
            for i in 0..3 {
                assert!(n.velocity_m_s[i].abs() <= lim.max_speed_m_s + 1e-12);
                assert!(n.accel_m_s2[i].abs() <= lim.max_accel_m_s2 + 1e-9);
            }
            a = n;
            t += h;
            if a.arrived || t > 10.0 {
                break;
            }
        }
        assert!(a.arrived, "{a:?}");
        for (p, goal) in a.position_m.iter().zip(target) {
            assert!((p - goal).abs() <= ARRIVED_M);
        }
        // 0.2 m in z at 0.25 m/s and 2 m/s^2: at least 0.2/0.25 + 0.25/2 = 0.925 s.
        assert!(t > 0.9 && t < 1.5, "{t}");
    }
}
