//! The world <-> message bridge: what a task world publishes (the gripper's state, the camera's
//! estimate, the tactile sensor's frames) and how the policy's commands become a world command.
//!
//! Times: world time `t_s` (seconds since the trial's reset) maps to the stamp
//! [`EPOCH`] + `t_s`, the same epoch the mock sensor stamps its frames with, so a frame captured
//! at world time t and a gripper status read at t carry the same stamp.
//!
//! What the gripper reports is what a real gripper can ([`GripperGauge`], the world's gripper
//! measurement model `unitac_sim::task::GripperSensing`): the opening (encoder resolution), the
//! motor current, the force estimated from that current (with this gripper's gain error), object
//! detection (it stopped on something short of the target, drawing current); never the world's
//! contact force, the object's deformation or slip.

use thiserror::Error;
use unitac_core::Frame;
use unitac_core::clock::Stamp;
use unitac_core::msg::{
    ArmCommand, GripperCommand, GripperMode, GripperStatus, Header, VisualObservation,
};
use unitac_sim::task::{
    self, ArmSetpoint, ArmTarget, GripperSensing, GripperSetpoint, TaskCommand, TaskTruth,
    TaskWorld, trial_rng,
};
use unitac_sim::{EPOCH, GroundTruth, MockSensor, SplitMix64};

/// The frame id of the gripper's status (REP 105 style: the gripper's base link).
pub const GRIPPER_FRAME: &str = "gripper_base_link";
/// The frame id of the camera's observation.
pub const CAMERA_FRAME: &str = "scene_camera_optical_frame";

/// Opening within this of the target counts as arrived \[m] (a real gripper's position deadband).
const ARRIVED_M: f64 = 1e-4;

/// A command the bridge cannot turn into a world command.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum BridgeError {
    #[error("gripper command {field} = {value} is not finite")]
    NotFinite { field: &'static str, value: f64 },
    #[error("arm command target is empty")]
    EmptyTarget,
    #[error("gripper STOP before the first measured opening: nothing to hold")]
    NothingToHold,
}

/// World time -> stamp.
pub fn stamp_at(t_s: f64) -> Stamp {
    EPOCH.saturating_add_nanos((t_s * 1e9).round() as i64)
}

/// Stamp -> world time (the inverse of [`stamp_at`]).
pub fn time_of(stamp: Stamp) -> f64 {
    stamp.secs_since(EPOCH)
}

/// Salt of the gripper's measurement noise stream (apart from the trial's draw and the camera).
const GRIPPER_SALT: u64 = 0x4752_4950_5045_0001;

/// The world's gripper as its driver reads it: the trial's measurement model, its gain (drawn
/// with the trial) and its own noise stream from (seed, trial).
#[derive(Debug, Clone)]
pub struct GripperGauge {
    sensing: GripperSensing,
    gain: f64,
    rng: SplitMix64,
}

impl GripperGauge {
    /// The gauge of the trial `world` was reset to (`seed`, `trial`).
    pub fn for_trial(world: &TaskWorld, seed: u64, trial: u32) -> Self {
        Self {
            sensing: world.config().sensing,
            gain: world.spec().gripper_gain,
            rng: trial_rng(seed ^ GRIPPER_SALT, trial),
        }
    }

    /// The gripper's state as its driver would publish it. `target_m` is the opening the last
    /// command asked for (NaN before the first).
    pub fn status(&mut self, truth: &TaskTruth, target_m: f64) -> GripperStatus {
        let r = self.sensing.read(&truth.gripper, self.gain, &mut self.rng);
        let arrived = target_m.is_finite() && (r.opening_m - target_m).abs() < ARRIVED_M;
        GripperStatus {
            header: Header::new(stamp_at(truth.t_s), GRIPPER_FRAME),
            opening_m: r.opening_m,
            target_m,
            force_n: r.force_n,
            current_a: r.current_a,
            object_detected: r.object_detected,
            activation: "active".into(),
            motion: if arrived || r.stalled {
                "stopped"
            } else {
                "moving"
            }
            .into(),
            fault: String::new(),
        }
    }
}

/// The message name of a camera value: the world's `<object>.<field>` as `<object>_<field>`,
/// with the cup's diameter called its width (`cup_width_m`, what the camera measures across the
/// rim and the name the policy reads) and a fabric's Ra called its roughness
/// (`fabric_a_roughness`, the property name the policy picks by; the value stays Ra in m).
pub fn visual_name(world_name: &str) -> String {
    let name = world_name.replacen('.', "_", 1);
    if let Some(object) = name.strip_suffix("_diameter_m") {
        format!("{object}_width_m")
    } else if let Some(object) = name.strip_suffix("_roughness_ra_m") {
        format!("{object}_roughness")
    } else {
        name
    }
}

/// The camera's estimate as a message (names by [`visual_name`]).
pub fn visual_message(v: &task::VisualObservation) -> VisualObservation {
    VisualObservation {
        header: Header::new(stamp_at(v.t_s), CAMERA_FRAME),
        names: v.names.iter().map(|n| visual_name(n)).collect(),
        values: v.values.clone(),
    }
}

fn finite(field: &'static str, value: f64) -> Result<f64, BridgeError> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(BridgeError::NotFinite { field, value })
    }
}

/// The policy's two commands as one world command. The gripper part is the one setpoint every
/// gripper takes ([`GripperSetpoint::from_command`], the message's meaning of each mode; a stop
/// holds `opening_now`, the measured opening, with the command's force). Values beyond the
/// gripper's range are left for the world to clamp or refuse, as a gripper does; NaN or inf is
/// an error here.
pub fn task_command(
    g: &GripperCommand,
    a: &ArmCommand,
    opening_now: Option<f64>,
) -> Result<TaskCommand, BridgeError> {
    finite("speed_m_s", g.speed_m_s)?;
    finite("force_n", g.force_n)?;
    if g.mode == GripperMode::Position {
        finite("position_m", g.position_m)?;
    }
    let gripper =
        GripperSetpoint::from_command(g, opening_now).ok_or(BridgeError::NothingToHold)?;
    finite("opening_m", gripper.opening_m)?;
    if a.target.is_empty() {
        return Err(BridgeError::EmptyTarget);
    }
    Ok(TaskCommand {
        gripper,
        arm: ArmSetpoint {
            target: ArmTarget::named(&a.target),
            xy_m: [finite("x_m", a.x_m)?, finite("y_m", a.y_m)?],
            z_m: finite("z_m", a.z_m)?,
            lift_m: finite("lift_m", a.lift_m)?,
        },
    })
}

/// The tactile sensor on the finger: renders the world's sensor view at the sensor's own frame
/// times. Frame `i` is captured at world time `i / fps`; [`SensorRig::frames_until`] renders every
/// frame due up to a world time from the world as it is then (the control step is the sim's
/// resolution: frames within one step see the state at its end).
#[derive(Debug)]
pub struct SensorRig {
    sensor: MockSensor,
    next: u64,
}

impl SensorRig {
    pub fn new(sensor: MockSensor) -> Self {
        Self { sensor, next: 0 }
    }
    pub fn sensor(&self) -> &MockSensor {
        &self.sensor
    }
    /// World time of frame `index` \[s].
    pub fn frame_time(&self, index: u64) -> f64 {
        index as f64 / self.sensor.config().fps
    }
    /// Every frame captured at or before world time `t_s`, rendered from `world`'s sensor view,
    /// with its ground truth (for measuring, never for the policy).
    pub fn frames_until(&mut self, world: &task::TaskWorld, t_s: f64) -> Vec<(Frame, GroundTruth)> {
        let view = world.sensor_view();
        let mut out = Vec::new();
        // A tolerance of 1 ns keeps frames whose time equals t_s up to rounding.
        while self.frame_time(self.next) <= t_s + 1e-9 {
            out.push(view.render(&self.sensor, self.next));
            self.next += 1;
        }
        out
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)]
    use super::*;
    use unitac_core::SensorKind;
    use unitac_sim::task::{GripperLimits, Split, TaskConfig, TaskWorld};
    use unitac_sim::{MockConfig, Scenario};

    fn cmd(mode: GripperMode, position_m: f64) -> GripperCommand {
        GripperCommand {
            header: Header::new(EPOCH, GRIPPER_FRAME),
            mode,
            position_m,
            speed_m_s: 0.05,
            force_n: 12.0,
            reason: String::new(),
        }
    }
    fn arm(target: &str) -> ArmCommand {
        ArmCommand {
            header: Header::new(EPOCH, GRIPPER_FRAME),
            target: target.into(),
            x_m: 0.45,
            y_m: 0.01,
            z_m: 0.05,
            lift_m: 0.0,
            reason: String::new(),
        }
    }

    #[test]
    fn stamps_round_trip_world_time() {
        for t in [0.0, 1.0 / 30.0, 2.5, 600.0] {
            assert!((time_of(stamp_at(t)) - t).abs() < 1e-9);
        }
        assert_eq!(stamp_at(0.0), EPOCH);
    }

    #[test]
    fn modes_become_world_setpoints() {
        let p = task_command(&cmd(GripperMode::Position, 0.05), &arm("cup"), Some(0.08)).unwrap();
        assert_eq!(p.gripper.opening_m, 0.05);
        assert_eq!(p.gripper.force_n, 12.0);
        assert_eq!(p.arm.target, ArmTarget::Object("cup".into()));
        assert_eq!(p.arm.xy_m, [0.45, 0.01]);
        let f = task_command(&cmd(GripperMode::Force, 0.05), &arm("home"), Some(0.08)).unwrap();
        assert_eq!((f.gripper.opening_m, f.gripper.force_n), (0.0, 12.0));
        assert_eq!(f.arm.target, ArmTarget::Home);
        let s = task_command(&cmd(GripperMode::Stop, f64::NAN), &arm("cup"), Some(0.08)).unwrap();
        assert_eq!((s.gripper.opening_m, s.gripper.force_n), (0.08, 12.0));
        assert_eq!(
            task_command(&cmd(GripperMode::Stop, 0.05), &arm("cup"), None),
            Err(BridgeError::NothingToHold)
        );
    }

    /// The gripper node on the robot turns a command into a motion with
    /// `GripperSetpoint::from_command` and the gripper's measured opening; the sim (trials, the
    /// ROS sim node) through this bridge. Both give the same setpoint for every mode, and a STOP
    /// holds with the command's force, never the gripper's maximum.
    #[test]
    fn the_robot_and_the_sim_turn_a_command_into_the_same_setpoint() {
        let lim = GripperLimits::default();
        for mode in [GripperMode::Position, GripperMode::Force, GripperMode::Stop] {
            for (position_m, force_n, opening) in [(0.05, 12.0, 0.08), (0.0, 3.5, 0.031)] {
                let mut c = cmd(mode, position_m);
                c.force_n = force_n;
                let robot = GripperSetpoint::from_command(&c, Some(opening)).unwrap();
                let sim = task_command(&c, &arm("cup"), Some(opening))
                    .unwrap()
                    .gripper;
                assert_eq!(robot, sim, "{mode:?}");
                assert_eq!(sim.force_n, force_n);
                assert!(sim.force_n < lim.max_force_n);
            }
        }
    }

    #[test]
    fn non_finite_commands_are_errors_naming_the_field() {
        let e = task_command(
            &cmd(GripperMode::Position, f64::NAN),
            &arm("cup"),
            Some(0.08),
        );
        assert!(matches!(
            e,
            Err(BridgeError::NotFinite {
                field: "position_m",
                ..
            })
        ));
        let mut a = arm("cup");
        a.lift_m = f64::INFINITY;
        let e = task_command(&cmd(GripperMode::Position, 0.05), &a, Some(0.08));
        assert!(matches!(
            e,
            Err(BridgeError::NotFinite {
                field: "lift_m",
                ..
            })
        ));
        let e = task_command(&cmd(GripperMode::Position, 0.05), &arm(""), Some(0.08));
        assert_eq!(e, Err(BridgeError::EmptyTarget));
    }

    #[test]
    fn camera_values_keep_their_order_under_the_message_names() {
        let w = TaskWorld::reset(&TaskConfig::cup(Split::Unseen), 3, 0);
        let v = w.observe_visual(&mut unitac_sim::SplitMix64::new(1));
        let m = visual_message(&v);
        assert_eq!(
            m.names,
            [
                "cup_x_m",
                "cup_y_m",
                "cup_z_m",
                "cup_width_m",
                "cup_height_m"
            ]
        );
        assert_eq!(m.values, v.values);
        assert_eq!(m.header.stamp, stamp_at(v.t_s));
        assert_eq!(m.get("cup_width_m"), v.get("cup.diameter_m"));
        assert_eq!(
            visual_name("fabric_b.edge_height_m"),
            "fabric_b_edge_height_m"
        );
        let w = TaskWorld::reset(&TaskConfig::fabric(Split::Train), 3, 0);
        let v = w.observe_visual(&mut unitac_sim::SplitMix64::new(1));
        let m = visual_message(&v);
        for o in ["fabric_a", "fabric_b"] {
            let ra = m.get(&format!("{o}_roughness"));
            assert!(ra.is_some(), "{:?}", m.names);
            assert_eq!(ra, v.get(&format!("{o}.roughness_ra_m")));
            assert!(m.get(&format!("{o}_edge_height_m")).is_some());
        }
    }

    #[test]
    fn status_reports_what_a_gripper_can_measure() {
        let w = TaskWorld::reset(&TaskConfig::cup(Split::Train), 3, 0);
        let mut gauge = GripperGauge::for_trial(&w, 3, 0);
        let t = w.truth();
        let s = gauge.status(&t, f64::NAN);
        assert_eq!(s.header.stamp, stamp_at(t.t_s));
        assert!((s.opening_m - t.gripper.opening_m).abs() <= 0.5e-4);
        assert!(s.target_m.is_nan() && s.current_a.is_finite());
        assert!(!s.object_detected);
        assert_eq!(s.motion, "moving");
        let s = gauge.status(&t, s.opening_m);
        assert_eq!(s.motion, "stopped");
        // A grip: the force is the current's estimate with this gripper's gain, not the world's.
        let mut held = t.clone();
        held.gripper.force_n = 10.0;
        held.gripper.stalled = true;
        let n = 400;
        let mean = (0..n)
            .map(|_| gauge.status(&held, 0.0).force_n)
            .sum::<f64>()
            / f64::from(n);
        let want = 10.0 / w.spec().gripper_gain;
        assert!((mean - want).abs() < 0.3, "{mean} vs {want}");
        assert!(gauge.status(&held, 0.0).object_detected);
    }

    #[test]
    fn rig_renders_each_frame_once_at_its_own_time() {
        let cfg = MockConfig::new(SensorKind::GELSIGHT_MINI, 5);
        let sensor = MockSensor::new(cfg, Scenario::idle(1.0));
        let mut rig = SensorRig::new(sensor);
        let w = TaskWorld::reset(&TaskConfig::cup(Split::Train), 3, 0);
        let first = rig.frames_until(&w, 0.1);
        // 25 fps: frames at 0, 0.04, 0.08.
        assert_eq!(first.len(), 3);
        assert_eq!(first[0].0.stamp, stamp_at(0.0));
        assert_eq!(first[2].0.stamp, stamp_at(0.08));
        assert!(rig.frames_until(&w, 0.1).is_empty());
        let next = rig.frames_until(&w, 0.125);
        assert_eq!(next.len(), 1);
        assert_eq!(next[0].0.seq, 3);
    }
}
