//! Scenarios: timed phases of pressing objects into the gel.

use crate::object::MM_PER_M;
pub use crate::object::Object;
use crate::world::{Cup, GripSample, WorldConfig, grip_cup};
use thiserror::Error;

#[derive(Debug, Error, PartialEq, Eq)]
pub enum ScenarioError {
    #[error(
        "unknown mock scenario '{0}' (known: fabric_selection, cup_deformation, indenters, idle)"
    )]
    Unknown(String),
}

/// One phase: the indenter depth ramps linearly from `from_mm` to `to_mm` over `duration_s`.
#[derive(Debug, Clone, PartialEq)]
pub struct Phase {
    pub duration_s: f64,
    pub object: Option<Object>,
    pub from_mm: f64,
    pub to_mm: f64,
}

#[derive(Debug, Clone, PartialEq)]
pub struct Scenario {
    pub name: String,
    pub phases: Vec<Phase>,
    /// World samples (grip force, cup deformation) when the world drives the scenario, one per
    /// control period, time-sorted; empty otherwise.
    pub grip: Vec<GripSample>,
}

fn free(d: f64) -> Phase {
    Phase {
        duration_s: d,
        object: None,
        from_mm: 0.0,
        to_mm: 0.0,
    }
}

/// Approach, hold and release on one object.
fn press(o: &Object, depth: f64, hold_s: f64) -> [Phase; 3] {
    [
        Phase {
            duration_s: 0.4,
            object: Some(o.clone()),
            from_mm: -0.1,
            to_mm: depth,
        },
        Phase {
            duration_s: hold_s,
            object: Some(o.clone()),
            from_mm: depth,
            to_mm: depth,
        },
        Phase {
            duration_s: 0.3,
            object: Some(o.clone()),
            from_mm: depth,
            to_mm: -0.1,
        },
    ]
}

fn start_pen(samples: &[GripSample]) -> f64 {
    samples.first().map_or(0.0, |s| s.penetration_m * MM_PER_M)
}

impl Scenario {
    pub fn by_name(name: &str) -> Result<Scenario, ScenarioError> {
        match name {
            "fabric_selection" => Ok(Self::fabric_selection()),
            "cup_deformation" => Ok(Self::cup_deformation()),
            "indenters" => Ok(Self::indenters()),
            "idle" => Ok(Scenario {
                name: "idle".into(),
                phases: vec![free(5.0)],
                grip: Vec::new(),
            }),
            other => Err(ScenarioError::Unknown(other.to_string())),
        }
    }

    /// Touch fabric A (rougher), release, touch fabric B (smoother), release.
    pub fn fabric_selection() -> Scenario {
        let a = Object::new("fabric_a", 6.0, 0.06, 0.9);
        let b = Object::new("fabric_b", 6.0, 0.015, 0.6);
        let mut phases = vec![free(1.0)];
        phases.extend(press(&a, 0.6, 0.8));
        phases.push(free(0.8));
        phases.extend(press(&b, 0.6, 0.8));
        phases.push(free(0.8));
        Scenario {
            name: "fabric_selection".into(),
            phases,
            grip: Vec::new(),
        }
    }

    /// One press each with a sphere, a flat punch, an edge, and a soft bumpy fabric (terry towel
    /// over the sphere): the object models side by side.
    pub fn indenters() -> Scenario {
        let objects = [
            Object::sphere("sphere", 4.0),
            Object::flat("flat", 2.5),
            Object::edge("edge", 1.0),
            Object::new("towel", 6.0, 0.01, 0.7)
                .with_hardness(0.5)
                .with_bumps(0.35, 1.2),
        ];
        let mut phases = vec![free(1.0)];
        for o in &objects {
            phases.extend(press(o, 0.6, 0.8));
            phases.push(free(0.6));
        }
        Scenario {
            name: "indenters".into(),
            phases,
            grip: Vec::new(),
        }
    }

    /// No contact at all for `duration_s`.
    pub fn idle(duration_s: f64) -> Scenario {
        Scenario {
            name: "idle".into(),
            phases: vec![free(duration_s)],
            grip: Vec::new(),
        }
    }

    /// One press per depth \[mm] on `object`: free 0.8 s, press 0.4 s, hold 0.8 s, release 0.3 s.
    pub fn press_sweep(object: &Object, depths: &[f64]) -> Scenario {
        let mut phases = vec![free(1.0)];
        for &d in depths {
            phases.extend(press(object, d, 0.8));
            phases.push(free(0.8));
        }
        Scenario {
            name: "press_sweep".into(),
            phases,
            grip: Vec::new(),
        }
    }

    /// A contact held for `hold_s` (minutes, for background-absorption tests).
    pub fn held(object: &Object, depth: f64, hold_s: f64) -> Scenario {
        let mut phases = vec![free(2.0)];
        phases.extend(press(object, depth, hold_s));
        phases.push(free(2.0));
        Scenario {
            name: "held".into(),
            phases,
            grip: Vec::new(),
        }
    }

    /// The fabrics of the fabric scenario (A rougher than B).
    pub fn fabric(label: &str, roughness_mm: f64, period_mm: f64) -> Object {
        Object::new(label, 6.0, roughness_mm, period_mm)
    }

    /// The paper's cup task on a paper cup (80 mm): the world's gripper closes at its speed
    /// limit until the cup is compressed by 1 cm (ground truth), holds 1 s, opens. The gel
    /// penetration the world computes drives the renderer; force and deformation are ground truth.
    pub fn cup_deformation() -> Scenario {
        Self::cup_grip(&Cup::paper(0.080), 0.010)
    }

    /// Grip `cup` until it is compressed by `target_m` \[m] (or the gripper's force limit), hold
    /// 1 s, open (world-driven; semi-implicit Euler with sub-stepping, 1 ms control period). The
    /// world's penetration becomes the phases' gel depth in mm.
    pub fn cup_grip(cup: &Cup, target_m: f64) -> Scenario {
        let object = cup.object();
        let mut phases = vec![free(1.0)];
        let mut grip = Vec::new();
        match grip_cup(WorldConfig::new(cup.clone()), target_m, 1.0, 1e-3) {
            Ok(run) => {
                // One phase per 10 ms of the grip, linear between world samples; the settled part
                // of the hold (0.1 s after closing until opening) is one constant phase.
                let settle = run.closed_s + 0.1;
                let (mut t_prev, mut pen_prev) = (0.0, start_pen(&run.samples));
                let mut hold_open = false;
                for s in run.samples.iter().step_by(10).skip(1) {
                    let dt = s.t_s - t_prev;
                    let hold = s.t_s > settle && s.t_s <= run.hold_end_s + 1e-9;
                    match (hold, hold_open, phases.last_mut()) {
                        (true, true, Some(last)) => last.duration_s += dt,
                        (true, _, _) => {
                            phases.push(Phase {
                                duration_s: dt,
                                object: Some(object.clone()),
                                from_mm: pen_prev,
                                to_mm: pen_prev,
                            });
                            hold_open = true;
                        }
                        (false, _, _) => {
                            phases.push(Phase {
                                duration_s: dt,
                                object: Some(object.clone()),
                                from_mm: pen_prev,
                                to_mm: s.penetration_m * MM_PER_M,
                            });
                            pen_prev = s.penetration_m * MM_PER_M;
                            hold_open = false;
                        }
                    }
                    t_prev = s.t_s;
                }
                grip = run
                    .samples
                    .iter()
                    .map(|s| GripSample {
                        t_s: s.t_s + 1.0,
                        ..*s
                    })
                    .collect();
            }
            Err(_) => {
                // The default world never diverges (sub-stepped); keep a press as a fallback.
                phases.extend(press(&object, 0.6, 1.0));
            }
        }
        phases.push(free(0.6));
        Scenario {
            name: "cup_deformation".into(),
            phases,
            grip,
        }
    }

    /// World sample at time t (None outside a world-driven grip).
    pub fn grip_at(&self, t: f64) -> Option<GripSample> {
        let (first, last) = (self.grip.first()?, self.grip.last()?);
        if t < first.t_s || t > last.t_s {
            return None;
        }
        let i = self.grip.partition_point(|s| s.t_s <= t);
        self.grip.get(i.saturating_sub(1)).copied()
    }

    pub fn duration_s(&self) -> f64 {
        self.phases.iter().map(|p| p.duration_s).sum()
    }

    /// Indenter depth \[mm] (negative = above the gel) and object at time t.
    pub fn at(&self, t: f64) -> (f64, Option<&Object>) {
        let mut t0 = 0.0;
        for p in &self.phases {
            if t < t0 + p.duration_s {
                let a = ((t - t0) / p.duration_s).clamp(0.0, 1.0);
                return (p.from_mm + a * (p.to_mm - p.from_mm), p.object.as_ref());
            }
            t0 += p.duration_s;
        }
        (0.0, None)
    }

    /// Middle of the first hold phase on the object with this label (for tests and demos).
    pub fn first_hold_time(&self, label: &str) -> Option<f64> {
        let mut t0 = 0.0;
        for p in &self.phases {
            let is_hold = p.from_mm == p.to_mm && p.from_mm > 0.0;
            if is_hold && p.object.as_ref().is_some_and(|o| o.label == label) {
                return Some(t0 + p.duration_s / 2.0);
            }
            t0 += p.duration_s;
        }
        None
    }

    /// Number of distinct presses (phases sequences on an object separated by free time).
    pub fn press_count(&self) -> usize {
        let mut n = 0;
        let mut prev: Option<&str> = None;
        for p in &self.phases {
            let cur = p.object.as_ref().map(|o| o.label.as_str());
            if cur.is_some() && cur != prev {
                n += 1;
            }
            prev = cur;
        }
        n
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_scenarios() {
        assert_eq!(
            Scenario::by_name("fabric_selection").unwrap().press_count(),
            2
        );
        assert_eq!(
            Scenario::by_name("cup_deformation").unwrap().press_count(),
            1
        );
        assert_eq!(Scenario::by_name("idle").unwrap().press_count(), 0);
        assert_eq!(Scenario::by_name("indenters").unwrap().press_count(), 4);
        assert!(Scenario::by_name("juggling").is_err());
    }

    #[test]
    fn cup_deformation_is_driven_by_the_world() {
        let s = Scenario::cup_deformation();
        let t = s.first_hold_time("cup").unwrap();
        let (d, o) = s.at(t);
        assert_eq!(o.unwrap().label, "cup");
        let g = s.grip_at(t).unwrap();
        assert!((g.deformation_m - 0.010).abs() < 1e-4, "{g:?}");
        assert!(
            (g.penetration_m * MM_PER_M - d).abs() < 1e-3,
            "{g:?} vs {d}"
        );
        assert!(d > 0.4 && d < 1.0, "{d}");
        assert!(g.force_n > 1.0);
        // Phases are continuous and the scenario ends free.
        let mut t0 = 0.0;
        for w in s.phases.windows(2) {
            t0 += w[0].duration_s;
            if w[0].object.is_some() && w[1].object.is_some() {
                assert!((w[0].to_mm - w[1].from_mm).abs() < 1e-3, "at {t0}");
            }
        }
        assert_eq!(s.at(s.duration_s() - 0.1), (0.0, None));
        assert!(
            s.duration_s() > 4.0 && s.duration_s() < 8.0,
            "{}",
            s.duration_s()
        );
    }

    #[test]
    fn depth_follows_phases() {
        let s = Scenario::fabric_selection();
        assert_eq!(s.at(0.5).0, 0.0);
        let t = s.first_hold_time("fabric_b").unwrap();
        let (d, o) = s.at(t);
        assert!((d - 0.6).abs() < 1e-12);
        assert_eq!(o.unwrap().label, "fabric_b");
        assert_eq!(s.at(s.duration_s() + 1.0), (0.0, None));
    }
}
