//! The command a task world takes each control tick (SI), and what it refuses.

use serde::Serialize;

use crate::world::WorldError;

/// The gripper part of a command: the one setpoint every gripper takes (see
/// [`unitac_core::GripperSetpoint`]).
pub use unitac_core::GripperSetpoint;

/// Where the arm goes.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ArmTarget {
    Home,
    /// An object of the task by name ("cup", "fabric_a", "fabric_b").
    Object(String),
}

impl ArmTarget {
    /// "home" or an object name (checked against the task at the step).
    pub fn named(name: &str) -> ArmTarget {
        if name == "home" {
            ArmTarget::Home
        } else {
            ArmTarget::Object(name.to_string())
        }
    }
    pub fn name(&self) -> &str {
        match self {
            ArmTarget::Home => "home",
            ArmTarget::Object(n) => n,
        }
    }
}

/// The arm part of a command: the target, where over the table the fingertip centre goes (the
/// commander's estimate of the object's position: a policy's from the camera, the expert's the
/// truth), its height above the table at the grasp, and how far to lift from there \[m] (home
/// ignores all three). The world goes where `xy_m` says, never to the object's true place.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ArmSetpoint {
    pub target: ArmTarget,
    pub xy_m: [f64; 2],
    pub z_m: f64,
    pub lift_m: f64,
}

/// One control tick's command.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TaskCommand {
    pub gripper: GripperSetpoint,
    pub arm: ArmSetpoint,
}

/// Bounds of a command's fields (beyond them the command is refused, nothing changes).
const MAX_Z_M: f64 = 1.0;
const MAX_LIFT_M: f64 = 0.5;
/// The workspace's horizontal reach from the table frame's origin \[m].
const MAX_XY_M: f64 = 2.0;
/// Longest control step accepted \[s].
pub const MAX_STEP_S: f64 = 1.0;

fn check(field: &'static str, v: f64, lo: f64, hi: f64) -> Result<(), WorldError> {
    if !v.is_finite() {
        return Err(WorldError::BadCommand {
            field,
            value: v,
            why: "not finite",
        });
    }
    if v < lo || v > hi {
        return Err(WorldError::BadCommand {
            field,
            value: v,
            why: if v < lo {
                "below its range"
            } else {
                "above its range"
            },
        });
    }
    Ok(())
}

impl TaskCommand {
    /// Refuse NaN / inf, negative opening, speed, force, height or lift, and heights beyond the
    /// workspace. An opening, speed or force beyond the gripper's bounds is clamped to them (as
    /// the gripper does), not refused.
    pub fn validate(&self) -> Result<(), WorldError> {
        let g = &self.gripper;
        check("gripper.opening_m", g.opening_m, 0.0, f64::MAX)?;
        check("gripper.speed_m_s", g.speed_m_s, 0.0, f64::MAX)?;
        check("gripper.force_n", g.force_n, 0.0, f64::MAX)?;
        check("arm.x_m", self.arm.xy_m[0], -MAX_XY_M, MAX_XY_M)?;
        check("arm.y_m", self.arm.xy_m[1], -MAX_XY_M, MAX_XY_M)?;
        check("arm.z_m", self.arm.z_m, 0.0, MAX_Z_M)?;
        check("arm.lift_m", self.arm.lift_m, 0.0, MAX_LIFT_M)?;
        Ok(())
    }
}
