//! The lock-step sim of the sim node, without ROS: a task world
//! ([`unitac_sim::task::TaskWorld`]) stepped one control period at a time, everything it shows
//! and takes converted by crates/trials' bridge (the one world <-> message conversion).
//!
//! Each step: [`LockStep::observe`] gives what the robot sees at world time t (the tactile
//! frames due up to t, the gripper's status, the camera's estimate), all stamped on the mock
//! sensor's epoch ([`unitac_trials::bridge::stamp_at`]); [`LockStep::step`] takes the policy's
//! GripperCommand + ArmCommand for t (or none: the last command again, counted) and advances the
//! world by one period. Same task, seed, trial and commands: the same frames and statuses, bit
//! for bit.

use thiserror::Error;
use unitac_core::msg::{
    ArmCommand, GripperCommand, GripperMode, GripperStatus, Header, VisualObservation,
};
use unitac_core::{Frame, SensorKind, Stamp};
use unitac_sim::task::{Split, TaskCommand, TaskConfig, TaskOutcome, TaskWorld, trial_rng};
use unitac_sim::{MockConfig, MockSensor, Scenario, SplitMix64};
use unitac_trials::bridge::{self, BridgeError, SensorRig};

/// Salt of the camera noise stream of the sim node (separate from the trial's draw).
const VISION_SALT: u64 = 0x524f_5356_4953_0001;

/// Why the sim cannot go on.
#[derive(Debug, Error)]
pub enum SimError {
    #[error("task must be cup or fabric, got '{0}'")]
    Task(String),
    #[error("split must be train or unseen, got '{0}'")]
    Split(String),
    #[error("control rate {0} Hz is not in [1, 1000]")]
    Rate(f64),
    #[error("duration {0} s is not in (0, 600]")]
    Duration(f64),
    #[error("command: {0}")]
    Command(#[from] BridgeError),
    #[error("world refused the step: {0}")]
    World(String),
}

/// Which trial, at which rate, for how long, seen by which sensor.
#[derive(Debug, Clone, PartialEq)]
pub struct SimSpec {
    /// cup | fabric
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

/// What the robot sees at one world time.
#[derive(Debug, Clone)]
pub struct Observed {
    pub stamp: Stamp,
    /// The tactile frames captured since the last observation, up to now.
    pub frames: Vec<Frame>,
    pub gripper: GripperStatus,
    pub visual: VisualObservation,
}

/// One trial of a task world, stepped at the control rate.
#[derive(Debug)]
pub struct LockStep {
    world: TaskWorld,
    rig: SensorRig,
    rng: SplitMix64,
    /// The world's gripper as its driver reads it.
    gauge: bridge::GripperGauge,
    dt_s: f64,
    duration_s: f64,
    /// The opening the last command asked for (NaN before the first).
    target_m: f64,
    last: TaskCommand,
    /// Steps taken with the previous command because none came for the step's time.
    pub repeated: u64,
}

impl LockStep {
    /// The trial `spec` names.
    pub fn new(spec: &SimSpec) -> Result<Self, SimError> {
        let split = match spec.split.as_str() {
            "train" => Split::Train,
            "unseen" => Split::Unseen,
            other => return Err(SimError::Split(other.into())),
        };
        let cfg = match spec.task.as_str() {
            "cup" => TaskConfig::cup(split),
            "fabric" => TaskConfig::fabric(split),
            other => return Err(SimError::Task(other.into())),
        };
        let (rate_hz, duration_s, seed, trial) =
            (spec.rate_hz, spec.duration_s, spec.seed, spec.trial);
        if !(rate_hz.is_finite() && (1.0..=1000.0).contains(&rate_hz)) {
            return Err(SimError::Rate(rate_hz));
        }
        if !(duration_s.is_finite() && duration_s > 0.0 && duration_s <= 600.0) {
            return Err(SimError::Duration(duration_s));
        }
        let world = TaskWorld::reset(&cfg, seed, trial);
        let mut mock = MockConfig::new(spec.sensor, seed);
        mock.sensor_id = spec.sensor_id.clone();
        let rig = SensorRig::new(MockSensor::new(mock, Scenario::idle(duration_s)));
        // Before the policy's first command: stay (fingers where they are, arm home).
        let stay = bridge::task_command(
            &GripperCommand {
                header: Header::new(bridge::stamp_at(0.0), bridge::GRIPPER_FRAME),
                mode: GripperMode::Stop,
                position_m: f64::NAN,
                speed_m_s: cfg.gripper.max_speed_m_s,
                force_n: cfg.gripper.max_force_n,
                reason: String::new(),
            },
            &ArmCommand {
                header: Header::new(bridge::stamp_at(0.0), bridge::GRIPPER_FRAME),
                target: "home".into(),
                x_m: 0.0,
                y_m: 0.0,
                z_m: 0.0,
                lift_m: 0.0,
                reason: String::new(),
            },
            Some(world.truth().gripper.opening_m),
        )?;
        Ok(Self {
            gauge: bridge::GripperGauge::for_trial(&world, seed, trial),
            world,
            rig,
            rng: trial_rng(seed ^ VISION_SALT, trial),
            dt_s: 1.0 / rate_hz,
            duration_s,
            target_m: f64::NAN,
            last: stay,
            repeated: 0,
        })
    }

    /// World time now \[s].
    pub fn time(&self) -> f64 {
        self.world.time()
    }
    /// The stamp of world time now.
    pub fn stamp(&self) -> Stamp {
        bridge::stamp_at(self.world.time())
    }
    /// Whether the trial's duration is over.
    pub fn done(&self) -> bool {
        self.world.time() >= self.duration_s - 1e-9
    }
    pub fn world(&self) -> &TaskWorld {
        &self.world
    }

    /// What the robot sees now; frames already given are not given again.
    pub fn observe(&mut self) -> Observed {
        let t = self.world.time();
        let frames = self
            .rig
            .frames_until(&self.world, t)
            .into_iter()
            .map(|(f, _truth)| f)
            .collect();
        let truth = self.world.truth();
        Observed {
            stamp: bridge::stamp_at(t),
            frames,
            gripper: self.gauge.status(&truth, self.target_m),
            visual: bridge::visual_message(&self.world.observe_visual(&mut self.rng)),
        }
    }

    /// One control period under the policy's commands for now (`None`: none came; the last
    /// command is kept and counted in `repeated`). A command the bridge refuses (NaN) is an
    /// error and nothing moves.
    pub fn step(&mut self, cmd: Option<(&GripperCommand, &ArmCommand)>) -> Result<(), SimError> {
        match cmd {
            Some((g, a)) => {
                let opening = self.world.truth().gripper.opening_m;
                let c = bridge::task_command(g, a, Some(opening))?;
                self.target_m = c.gripper.opening_m;
                self.last = c;
            }
            None => self.repeated += 1,
        }
        self.world
            .step(&self.last, self.dt_s)
            .map_err(|e| SimError::World(e.to_string()))?;
        Ok(())
    }

    /// The task's outcome now, judged by the world (its success criteria with their values).
    pub fn outcome(&self) -> TaskOutcome {
        self.world.outcome()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec(task: &str, split: &str, rate_hz: f64, duration_s: f64) -> SimSpec {
        SimSpec {
            task: task.into(),
            split: split.into(),
            seed: 3,
            trial: 0,
            rate_hz,
            duration_s,
            sensor: SensorKind::GelsightMini,
            sensor_id: "gsmini".into(),
        }
    }

    fn sim() -> LockStep {
        LockStep::new(&spec("cup", "train", 30.0, 1.0)).unwrap()
    }

    #[test]
    fn bad_parameters_are_named() {
        let e = |task, split, rate, dur| {
            LockStep::new(&spec(task, split, rate, dur))
                .unwrap_err()
                .to_string()
        };
        assert!(e("mug", "train", 30.0, 1.0).contains("'mug'"));
        assert!(e("cup", "test", 30.0, 1.0).contains("'test'"));
        assert!(e("cup", "train", 0.0, 1.0).contains("control rate"));
        assert!(e("cup", "train", 30.0, f64::NAN).contains("duration"));
    }

    #[test]
    fn frames_and_status_at_each_step_are_stamped_on_world_time() {
        let mut s = sim();
        let o = s.observe();
        assert_eq!(o.stamp, bridge::stamp_at(0.0));
        assert_eq!(o.gripper.header.stamp, o.stamp);
        assert_eq!(o.visual.header.stamp, o.stamp);
        assert_eq!(o.frames.len(), 1);
        assert_eq!(o.frames[0].stamp, o.stamp);
        assert_eq!(o.frames[0].sensor_id, "gsmini");
        // Without a command the world goes on under the last one, counted.
        s.step(None).unwrap();
        assert_eq!(s.repeated, 1);
        assert!((s.time() - 1.0 / 30.0).abs() < 1e-12);
        let o = s.observe();
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
                let o = s.observe();
                trace.push((o.gripper.opening_m.to_bits(), o.frames.len()));
                s.step(Some((&g, &a))).unwrap();
            }
            (trace, format!("{:?}", s.outcome()))
        };
        assert_eq!(run(), run());
    }
}
