//! Finger physics behind a simulated device: the fingers move toward a target at the commanded
//! speed and stop on an object when the grip force reaches the commanded force.

/// What the device's controller asks of the fingers.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Drive {
    /// Motor on (off: no grip force, an elastic object pushes the fingers back open).
    pub enabled: bool,
    pub target_m: f64,
    pub speed_m_s: f64,
    pub force_n: f64,
}

/// Finger state after a step.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Fingers {
    pub opening_m: f64,
    pub force_n: f64,
    /// Stopped by the force limit on an object.
    pub stalled: bool,
    /// Closing (true) or opening (false) when last moving.
    pub closing: bool,
}

/// Something the fingers can close on.
pub trait Physics: Send {
    /// Advance `dt` seconds under `drive`.
    fn step(&mut self, dt: f64, drive: Drive) -> Fingers;
    fn fingers(&self) -> Fingers;
}

/// An elastic object of a given width between the fingers (or none).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimObject {
    pub width_m: f64,
    /// Contact stiffness [N/m].
    pub stiffness_n_per_m: f64,
}

/// Kinematic fingers and an optional linear-elastic object.
#[derive(Debug, Clone)]
pub struct Kinematic {
    pub object: Option<SimObject>,
    pub max_opening_m: f64,
    f: Fingers,
}

impl Kinematic {
    pub fn new(max_opening_m: f64, object: Option<SimObject>) -> Self {
        Self {
            object,
            max_opening_m,
            f: Fingers {
                opening_m: max_opening_m,
                ..Fingers::default()
            },
        }
    }
    fn contact_force(&self, opening: f64) -> f64 {
        self.object.map_or(0.0, |o| {
            (o.stiffness_n_per_m * (o.width_m - opening)).max(0.0)
        })
    }
}

impl Physics for Kinematic {
    fn step(&mut self, dt: f64, d: Drive) -> Fingers {
        let dt = if dt.is_finite() { dt.max(0.0) } else { 0.0 };
        let o = self.f.opening_m;
        if !d.enabled {
            // Motor off: the object springs the fingers back to its width.
            let w = self.object.map_or(o, |ob| ob.width_m.max(o));
            self.f = Fingers {
                opening_m: w.min(self.max_opening_m),
                force_n: 0.0,
                stalled: false,
                closing: self.f.closing,
            };
            return self.f;
        }
        let target = d.target_m.clamp(0.0, self.max_opening_m);
        let step = (d.speed_m_s.max(0.0) * dt).max(0.0);
        let mut next = o + (target - o).clamp(-step, step);
        let closing = target < o || (self.f.closing && target <= o);
        let mut stalled = false;
        if let Some(ob) = self.object {
            // Where the grip force equals the force limit.
            let hold = ob.width_m - d.force_n.max(0.0) / ob.stiffness_n_per_m.max(1e-9);
            if next < hold && target < hold {
                next = hold.max(next).min(o.max(hold));
                stalled = true;
            }
        }
        self.f = Fingers {
            opening_m: next,
            force_n: self.contact_force(next),
            stalled,
            closing,
        };
        self.f
    }
    fn fingers(&self) -> Fingers {
        self.f
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn closes_at_speed_and_stalls_at_the_force_limit() {
        let obj = SimObject {
            width_m: 0.05,
            stiffness_n_per_m: 20_000.0,
        };
        let mut k = Kinematic::new(0.085, Some(obj));
        let d = Drive {
            enabled: true,
            target_m: 0.0,
            speed_m_s: 0.1,
            force_n: 100.0,
        };
        let f = k.step(0.1, d);
        assert!((f.opening_m - 0.075).abs() < 1e-12 && !f.stalled);
        for _ in 0..20 {
            k.step(0.1, d);
        }
        let f = k.fingers();
        // 100 N at 20 N/mm: 5 mm squeeze.
        assert!((f.opening_m - 0.045).abs() < 1e-9, "{f:?}");
        assert!((f.force_n - 100.0).abs() < 1e-6 && f.stalled && f.closing);
        // Motor off: the object pushes back to its width, no force.
        let f = k.step(
            0.01,
            Drive {
                enabled: false,
                ..d
            },
        );
        assert_eq!((f.opening_m, f.force_n), (0.05, 0.0));
    }
}
