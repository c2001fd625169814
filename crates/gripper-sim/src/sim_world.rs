//! The sim world's gripper ([`unitac_sim::World`]) behind the same interfaces as the
//! serial grippers: as a [`Gripper`] stepped in-process by the caller's clock
//! ([`SimWorldGripper::advance`]), and as [`Physics`] for a simulated serial device, so a trial
//! can swap the in-process gripper for the serial one over a pty without changing the policy side.
//!
//! Uses only the world's public API: `World::step` with a per-step position target (the commanded
//! speed and force limit are applied here; the world's own speed limit still holds).
//! Opening = the world's `width_m` (cup diameter - 2 x finger position).

use crate::device::physics::{Drive, Fingers, Physics};
use unitac_gripper::gripper::{
    Activation, Gripper, GripperError, GripperSetpoint, GripperState, Limits, Motion,
};
use unitac_sim::{Command, World, WorldError, WorldTruth};

/// The world's fingers as [`Physics`].
#[derive(Debug, Clone)]
pub struct WorldFingers {
    world: World,
    max_opening_m: f64,
    truth: WorldTruth,
    fingers: Fingers,
    error: Option<WorldError>,
}

impl WorldFingers {
    /// `max_opening_m`: the opening the fingers start from is clamped to it.
    pub fn new(world: World, max_opening_m: f64) -> Self {
        let truth = world.truth(0);
        let mut s = Self {
            world,
            max_opening_m,
            truth,
            fingers: Fingers::default(),
            error: None,
        };
        s.fingers = s.read(false, false);
        s
    }
    pub fn world(&self) -> &World {
        &self.world
    }
    pub fn truth(&self) -> &WorldTruth {
        &self.truth
    }
    /// The integration error that stopped the world, if any.
    pub fn error(&self) -> Option<&WorldError> {
        self.error.as_ref()
    }
    fn diameter_m(&self) -> f64 {
        self.world.config().cup.diameter_m
    }
    fn read(&self, stalled: bool, closing: bool) -> Fingers {
        Fingers {
            opening_m: self.truth.width_m.min(self.max_opening_m),
            force_n: self.truth.force_n,
            stalled,
            closing,
        }
    }
}

impl Physics for WorldFingers {
    fn step(&mut self, dt: f64, d: Drive) -> Fingers {
        if !(dt.is_finite() && dt > 0.0) || self.error.is_some() {
            return self.fingers;
        }
        let p = self.truth.finger_m;
        let step = if d.enabled {
            let target = (self.diameter_m() - d.target_m.clamp(0.0, self.max_opening_m)) / 2.0;
            // Opening speed is split over two fingers.
            self.world
                .drive(dt, target, d.speed_m_s / 2.0, d.force_n)
                .map(|s| (s.truth, s.closing, s.stalled))
        } else {
            // Motor off: the cup pushes the fingers back to touching.
            self.world
                .step(dt, Command::Position(p.min(0.0)))
                .map(|t| (t, false, false))
        };
        let (closing, stalled) = match step {
            Ok((t, closing, stalled)) => {
                self.truth = t;
                (closing, stalled)
            }
            Err(e) => {
                self.error = Some(e);
                (false, false)
            }
        };
        self.fingers = self.read(stalled, closing);
        self.fingers
    }
    fn fingers(&self) -> Fingers {
        self.fingers
    }
}

/// The world's gripper as an in-process [`Gripper`], activated from the start.
#[derive(Debug, Clone)]
pub struct SimWorldGripper {
    fingers: WorldFingers,
    limits: Limits,
    cmd: Option<GripperSetpoint>,
    state: GripperState,
    t: f64,
}

impl SimWorldGripper {
    pub fn new(world: World, limits: Limits) -> Self {
        let fingers = WorldFingers::new(world, limits.max_opening_m);
        let f = fingers.fingers();
        Self {
            state: GripperState {
                activation: Activation::Active,
                motion: Motion::Idle,
                opening_m: Some(f.opening_m),
                force_n: Some(f.force_n),
                ..GripperState::default()
            },
            fingers,
            limits,
            cmd: None,
            t: 0.0,
        }
    }
    pub fn fingers(&self) -> &WorldFingers {
        &self.fingers
    }
    /// Advance the world by `dt` seconds under the current command.
    pub fn advance(&mut self, dt: f64) -> Result<(), WorldError> {
        let f = self.fingers.fingers();
        let drive = match self.cmd {
            Some(c) => Drive {
                enabled: true,
                target_m: c.opening_m,
                speed_m_s: c.speed_m_s,
                force_n: c.force_n,
            },
            None => Drive {
                enabled: true,
                target_m: f.opening_m,
                speed_m_s: 0.0,
                force_n: self.limits.min_force_n,
            },
        };
        let f = self.fingers.step(dt, drive);
        if let Some(e) = self.fingers.error() {
            return Err(e.clone());
        }
        self.t += dt;
        let s = &mut self.state;
        s.opening_m = Some(f.opening_m);
        s.force_n = Some(f.force_n);
        s.target_m = self.cmd.map(|c| c.opening_m);
        s.updates += 1;
        s.stamp_s = self.t;
        // Caught stays caught for this command while the force hovers at its limit.
        let latched = s.motion.holds_object();
        s.motion = match self.cmd {
            None => Motion::Idle,
            Some(_) if f.stalled || latched => {
                if f.closing {
                    Motion::Caught
                } else {
                    Motion::CaughtOpening
                }
            }
            Some(c) if (f.opening_m - c.opening_m).abs() < 1e-4 => Motion::Reached,
            Some(_) => Motion::Moving,
        };
        Ok(())
    }
}

impl Gripper for SimWorldGripper {
    fn model(&self) -> &str {
        "sim"
    }
    fn limits(&self) -> Limits {
        self.limits
    }
    fn activate(&mut self) -> Result<(), GripperError> {
        Ok(())
    }
    fn command(&mut self, cmd: GripperSetpoint) -> Result<(), GripperError> {
        let cmd = self.limits.clamp(cmd)?;
        if self.cmd != Some(cmd) {
            self.state.motion = Motion::Moving;
        }
        self.cmd = Some(cmd);
        Ok(())
    }
    fn state(&self) -> GripperState {
        self.state.clone()
    }
    fn clear_fault(&mut self) -> Result<(), GripperError> {
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use unitac_gripper::model::Model;
    use unitac_sim::{Cup, WorldConfig};

    #[test]
    fn squeezes_the_cup_to_the_force_limit_and_reports_caught_public_world_api_only() {
        let cup = Cup::paper(0.060);
        let world = World::new(WorldConfig::new(cup));
        let limits = Limits {
            min_force_n: 1.0,
            ..Model::named("robotiq_2f85").unwrap().calibration().limits
        };
        let mut g = SimWorldGripper::new(world, limits);
        let start = g.state().opening_m.unwrap();
        assert!(start > 0.060, "starts open: {start}");
        g.command(GripperSetpoint {
            opening_m: 0.0,
            speed_m_s: 0.02,
            force_n: 5.0,
        })
        .unwrap();
        for _ in 0..3000 {
            g.advance(0.002).unwrap();
            if g.state().motion == Motion::Caught {
                break;
            }
        }
        assert_eq!(g.state().motion, Motion::Caught, "{:?}", g.state());
        // Contact rings (a light wall, 5 % damping); held for 3 s the force settles at the limit.
        for _ in 0..1500 {
            g.advance(0.002).unwrap();
        }
        let s = g.state();
        assert_eq!(s.motion, Motion::Caught, "{s:?}");
        let f = s.force_n.unwrap();
        assert!((4.5..5.5).contains(&f), "force {f}");
        assert!(s.opening_m.unwrap() < 0.060, "cup compressed: {s:?}");
        assert!(g.fingers().truth().deformation_m > 0.0);
    }
}
