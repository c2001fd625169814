//! The one lock-step world stepper: a task world ([`unitac_sim::task::TaskWorld`]) advanced one
//! control period at a time, with what a robot would see of it and the one way a command moves
//! it. The embedded trials ([`crate::run`]), the demonstrations ([`crate::demos`]), the ROS sim
//! node and the policy bench all step their world here.
//!
//! Per control period: [`WorldStepper::frames`] (the tactile frames due up to now, rendered from
//! the world's sensor view), [`WorldStepper::visual`] (the camera's estimate, its own noise
//! stream), [`WorldStepper::status`] (the gripper's status as its driver reads it), then
//! [`WorldStepper::step`] with the period's command (None: the last one again, counted in
//! [`WorldStepper::repeated`]). A message command becomes a world command by
//! [`WorldStepper::command`] (the bridge's conversion). The gripper is one seam
//! ([`crate::gripper`]): the world's own fingers in process, or the serial driver and a simulated
//! device on a pty.
//!
//! [`SimSpec`] names a trial the way the ROS sim node's parameters do; [`WorldStepper::observe`]
//! gives one period's view as messages. Same world, seed, trial and commands: the same frames
//! and statuses, bit for bit.

use crate::bridge::{self, BridgeError, GripperGauge, SensorRig};
use crate::gripper::{GripperSide, TrialGripper};
use crate::serial::{SerialError, SerialReport};
use std::fmt;
use thiserror::Error;
use unitac_core::msg::{ArmCommand, GripperCommand, GripperStatus, VisualObservation};
use unitac_core::{Frame, GripperSetpoint, SensorKind, Stamp};
use unitac_sim::task::{
    self, ArmSetpoint, ArmTarget, Split, TaskCommand, TaskConfig, TaskKind, TaskOutcome, TaskTruth,
    TaskWorld, UnknownTask, trial_rng,
};
use unitac_sim::{GroundTruth, MockConfig, MockSensor, Scenario, SplitMix64, WorldError};

/// Salt of the camera noise stream of a [`SimSpec`] trial (apart from the trial's own draw).
const SIM_CAMERA_SALT: u64 = 0x524f_5356_4953_0001;

/// Why the world cannot take a step, or a trial cannot be set up.
#[derive(Debug, Error)]
pub enum StepError {
    #[error(transparent)]
    Task(#[from] UnknownTask),
    #[error("split must be train or unseen, got '{0}'")]
    Split(String),
    #[error("control rate {0} Hz is not in [1, 1000]")]
    Rate(f64),
    #[error("duration {0} s is not in (0, 600]")]
    Duration(f64),
    #[error("command: {0}")]
    Command(#[from] BridgeError),
    #[error("gripper: {0}")]
    Gripper(#[from] SerialError),
    #[error("world refused the step: {0}")]
    World(#[from] WorldError),
}

/// Which trial, at which rate, for how long, seen by which sensor (the ROS sim node's
/// parameters).
#[derive(Debug, Clone, PartialEq)]
pub struct SimSpec {
    /// The task's name (`cup_deformation`, `fabric_selection`).
    pub task: String,
    /// train | unseen (the fabric task has one set and ignores it)
    pub split: String,
    pub seed: u64,
    pub trial: u32,
    /// Steps per sim second.
    pub rate_hz: f64,
    /// Sim time of the trial \[s].
    pub duration_s: f64,
    /// The mock tactile sensor and its id.
    pub sensor: SensorKind,
    pub sensor_id: String,
}

/// What the robot sees at one world time, as messages.
#[derive(Debug, Clone)]
pub struct Observed {
    pub stamp: Stamp,
    /// The tactile frames captured since the last observation, up to now.
    pub frames: Vec<Frame>,
    pub gripper: GripperStatus,
    pub visual: VisualObservation,
}

/// One trial's world, stepped at the control period.
pub struct WorldStepper {
    world: TaskWorld,
    rig: SensorRig,
    camera: SplitMix64,
    side: Box<dyn GripperSide>,
    gripper: TrialGripper,
    dt_s: f64,
    /// End of the trial \[s] (world time).
    duration_s: f64,
    last: TaskCommand,
    repeated: u64,
}

impl fmt::Debug for WorldStepper {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("WorldStepper")
            .field("t_s", &self.world.time())
            .field("gripper", &self.gripper)
            .field("dt_s", &self.dt_s)
            .field("repeated", &self.repeated)
            .finish_non_exhaustive()
    }
}

impl WorldStepper {
    /// Step `world` (reset to trial `trial` of `seed`) every `dt_s`, seen by `sensor`, the
    /// camera's noise from `camera`, its gripper `gripper`. Until the first command the fingers
    /// stay where they are (a stop with the gripper's maximum force) and the arm at home.
    pub fn new(
        world: TaskWorld,
        sensor: MockSensor,
        camera: SplitMix64,
        gripper: TrialGripper,
        (seed, trial): (u64, u32),
        dt_s: f64,
    ) -> Result<Self, StepError> {
        let truth = world.truth();
        let limits = world.config().gripper;
        let side = gripper.start(&truth, GripperGauge::for_trial(&world, seed, trial))?;
        let stay = TaskCommand {
            gripper: GripperSetpoint {
                opening_m: truth.gripper.opening_m,
                speed_m_s: limits.max_speed_m_s,
                force_n: limits.max_force_n,
            },
            arm: ArmSetpoint {
                target: ArmTarget::Home,
                xy_m: [0.0, 0.0],
                z_m: 0.0,
                lift_m: 0.0,
            },
        };
        Ok(Self {
            world,
            rig: SensorRig::new(sensor),
            camera,
            side,
            gripper,
            dt_s,
            duration_s: f64::INFINITY,
            last: stay,
            repeated: 0,
        })
    }

    /// The trial `spec` names, in process, the camera on the sim node's noise stream.
    pub fn for_spec(spec: &SimSpec) -> Result<Self, StepError> {
        let split = match spec.split.as_str() {
            "train" => Split::Train,
            "unseen" => Split::Unseen,
            other => return Err(StepError::Split(other.into())),
        };
        let cfg = TaskConfig::new(TaskKind::named(&spec.task, &[])?, split);
        let (rate_hz, duration_s, seed, trial) =
            (spec.rate_hz, spec.duration_s, spec.seed, spec.trial);
        if !(rate_hz.is_finite() && (1.0..=1000.0).contains(&rate_hz)) {
            return Err(StepError::Rate(rate_hz));
        }
        if !(duration_s.is_finite() && duration_s > 0.0 && duration_s <= 600.0) {
            return Err(StepError::Duration(duration_s));
        }
        let mut mock = MockConfig::new(spec.sensor, seed);
        mock.sensor_id = spec.sensor_id.clone();
        let mut s = Self::new(
            TaskWorld::reset(&cfg, seed, trial),
            MockSensor::new(mock, Scenario::idle(duration_s)),
            trial_rng(seed ^ SIM_CAMERA_SALT, trial),
            TrialGripper::InProcess,
            (seed, trial),
            1.0 / rate_hz,
        )?;
        s.duration_s = duration_s;
        Ok(s)
    }

    pub fn world(&self) -> &TaskWorld {
        &self.world
    }
    /// The world itself, for what a trial does to it between steps (hidden perturbations, the
    /// fabric decision).
    pub fn world_mut(&mut self) -> &mut TaskWorld {
        &mut self.world
    }
    /// World time now \[s].
    pub fn time(&self) -> f64 {
        self.world.time()
    }
    /// The stamp of world time now.
    pub fn stamp(&self) -> Stamp {
        bridge::stamp_at(self.world.time())
    }
    /// The control period \[s].
    pub fn dt_s(&self) -> f64 {
        self.dt_s
    }
    /// Whether a [`SimSpec`] trial's duration is over (never for [`WorldStepper::new`]).
    pub fn done(&self) -> bool {
        self.world.time() >= self.duration_s - 1e-9
    }
    /// Steps taken with the previous command because none came for the step's time.
    pub fn repeated(&self) -> u64 {
        self.repeated
    }
    /// The task's outcome now, judged by the world.
    pub fn outcome(&self) -> TaskOutcome {
        self.world.outcome()
    }
    /// What went over the wire (None in process).
    pub fn report(&self) -> Option<SerialReport> {
        self.side.report()
    }

    /// The tactile frames captured up to now and not given before, each with its ground truth
    /// (for measuring, never for a policy).
    pub fn frames(&mut self) -> Vec<(Frame, GroundTruth)> {
        self.rig.frames_until(&self.world, self.world.time())
    }
    /// The camera's estimate now (one draw of its noise).
    pub fn visual(&mut self) -> task::VisualObservation {
        self.world.observe_visual(&mut self.camera)
    }
    /// The gripper's status now, as its driver reads it.
    pub fn status(&mut self) -> Result<GripperStatus, StepError> {
        Ok(self.side.status(&self.world.truth())?)
    }

    /// Frames, status and camera now, as messages (frames already given are not given again).
    pub fn observe(&mut self) -> Result<Observed, StepError> {
        let frames = self.frames().into_iter().map(|(f, _truth)| f).collect();
        Ok(Observed {
            stamp: self.stamp(),
            frames,
            gripper: self.status()?,
            visual: bridge::visual_message(&self.visual()),
        })
    }

    /// The policy's two commands as the world command (a stop holds the opening now).
    pub fn command(&self, g: &GripperCommand, a: &ArmCommand) -> Result<TaskCommand, StepError> {
        let opening = self.world.truth().gripper.opening_m;
        Ok(bridge::task_command(g, a, Some(opening))?)
    }

    /// One control period under `cmd` (None: none came; the last command is kept and counted).
    /// The gripper side takes the setpoint first (a serial gripper drives the world with what its
    /// registers hold). Returns the world's state after the step.
    pub fn step(&mut self, cmd: Option<TaskCommand>) -> Result<TaskTruth, StepError> {
        match cmd {
            Some(mut c) => {
                c.gripper = self.side.command(c.gripper)?;
                self.last = c;
            }
            None => self.repeated += 1,
        }
        let next = self.world.step(&self.last, self.dt_s)?;
        self.side.stepped(&next)?;
        Ok(next)
    }

    /// [`WorldStepper::command`] then [`WorldStepper::step`], for a transport that has the two
    /// messages (or none).
    pub fn step_commands(
        &mut self,
        cmd: Option<(&GripperCommand, &ArmCommand)>,
    ) -> Result<TaskTruth, StepError> {
        let c = cmd.map(|(g, a)| self.command(g, a)).transpose()?;
        self.step(c)
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use unitac_core::msg::{GripperMode, Header};

    fn spec(task: &str, split: &str, rate_hz: f64, duration_s: f64) -> SimSpec {
        SimSpec {
            task: task.into(),
            split: split.into(),
            seed: 3,
            trial: 0,
            rate_hz,
            duration_s,
            sensor: SensorKind::GELSIGHT_MINI,
            sensor_id: "gsmini".into(),
        }
    }

    fn sim() -> WorldStepper {
        WorldStepper::for_spec(&spec("cup_deformation", "train", 30.0, 1.0)).unwrap()
    }

    #[test]
    fn bad_parameters_are_named() {
        let e = |task, split, rate, dur| {
            WorldStepper::for_spec(&spec(task, split, rate, dur))
                .unwrap_err()
                .to_string()
        };
        assert!(e("mug", "train", 30.0, 1.0).contains("'mug'"));
        assert!(e("cup", "train", 30.0, 1.0).contains("no task 'cup'"));
        assert!(e("cup_deformation", "test", 30.0, 1.0).contains("'test'"));
        assert!(e("cup_deformation", "train", 0.0, 1.0).contains("control rate"));
        assert!(e("cup_deformation", "train", 30.0, f64::NAN).contains("duration"));
    }

    #[test]
    fn frames_and_status_at_each_step_are_stamped_on_world_time() {
        let mut s = sim();
        let o = s.observe().unwrap();
        assert_eq!(o.stamp, bridge::stamp_at(0.0));
        assert_eq!(o.gripper.header.stamp, o.stamp);
        assert_eq!(o.visual.header.stamp, o.stamp);
        assert_eq!(o.frames.len(), 1);
        assert_eq!(o.frames[0].stamp, o.stamp);
        assert_eq!(o.frames[0].sensor_id, "gsmini");
        // Without a command the world goes on under the last one, counted.
        s.step(None).unwrap();
        assert_eq!(s.repeated(), 1);
        assert!((s.time() - 1.0 / 30.0).abs() < 1e-12);
        let o = s.observe().unwrap();
        assert_eq!(o.gripper.header.stamp, bridge::stamp_at(s.time()));
        // 25 fps: the frame at 0.04 s is not due at 0.033 s.
        assert!(o.frames.is_empty());
    }

    #[test]
    fn the_same_commands_give_the_same_world() {
        let run = || {
            let mut s = sim();
            let g = GripperCommand {
                header: Header::new(Stamp::ZERO, "g"),
                mode: GripperMode::Position,
                position_m: 0.05,
                speed_m_s: 0.05,
                force_n: 10.0,
                reason: String::new(),
            };
            let a = ArmCommand {
                header: Header::new(Stamp::ZERO, "g"),
                target: "cup".into(),
                x_m: 0.45,
                y_m: 0.0,
                z_m: 0.04,
                lift_m: 0.0,
                reason: String::new(),
            };
            let mut trace = Vec::new();
            while !s.done() {
                let o = s.observe().unwrap();
                trace.push((o.gripper.opening_m.to_bits(), o.frames.len()));
                s.step_commands(Some((&g, &a))).unwrap();
            }
            (trace, format!("{:?}", s.outcome()))
        };
        assert_eq!(run(), run());
    }
}
