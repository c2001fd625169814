//! The `Gripper` trait: what a policy sees of any gripper, in SI units.
//!
//! Every method returns at once: a serial gripper's I/O runs on its own thread (see
//! [`crate::driver`]), so activation and fault recovery never block the caller's control cycle;
//! they are requested here and their progress shows in [`Gripper::state`].

use serde::Serialize;
use thiserror::Error;
pub use unitac_core::GripperSetpoint;

/// Activation of the gripper's controller.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Activation {
    /// Not read from the device yet.
    #[default]
    Unknown,
    /// Not activated (a Robotiq in reset, a DH gripper not initialised).
    Inactive,
    /// Activation (homing) in progress.
    Activating,
    Active,
}

/// What the fingers are doing, as the device reports it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Motion {
    #[default]
    Unknown,
    /// No motion requested (a Robotiq with rGTO = 0).
    Idle,
    Moving,
    /// At the requested opening, no object.
    Reached,
    /// Stopped on an object while opening.
    CaughtOpening,
    /// Stopped on an object while closing (gOBJ = 2, DH "caught").
    Caught,
    /// The object was lost after a catch (DH "dropped").
    Dropped,
}

impl Motion {
    pub fn holds_object(self) -> bool {
        matches!(self, Motion::Caught | Motion::CaughtOpening)
    }
}

/// A fault the device reports, or a link fault.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Fault {
    /// Clears by itself or with the next command (e.g. Robotiq 0x05, 0x07, 0x08, 0x09).
    Minor { code: u8, what: String },
    /// Needs [`Gripper::clear_fault`] (a Robotiq rACT rising edge; gFLT >= 0x0A).
    Major { code: u8, what: String },
    /// The device does not answer or the port is gone; the driver keeps trying.
    Link { what: String },
}

/// The latest state, always available without waiting.
#[derive(Debug, Clone, PartialEq, Serialize, Default)]
pub struct GripperState {
    pub activation: Activation,
    pub motion: Motion,
    /// Fingertip distance \[m] (None until read).
    pub opening_m: Option<f64>,
    /// The position register as the device reports it (Robotiq gPO 0-255, DH 0-1000), for
    /// calibration.
    pub raw_position: Option<u16>,
    /// The device's echo of the requested opening \[m].
    pub target_m: Option<f64>,
    /// A raw position or target outside the calibrated range, read as the nearest end of the
    /// stroke (the opening never leaves [0, stroke]): what came and what to do (None: in range).
    pub out_of_range: Option<String>,
    /// Grip force estimate \[N] (Robotiq: from the motor current, a rough figure; sim: exact).
    pub force_n: Option<f64>,
    /// Motor current \[A] where the device reports one.
    pub current_a: Option<f64>,
    pub fault: Option<Fault>,
    /// Successful exchanges since start.
    pub updates: u64,
    /// Time of the last good update [s since the driver's start].
    pub stamp_s: f64,
}

/// Range and resolution of one model, for bounds and display.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Limits {
    pub max_opening_m: f64,
    pub min_speed_m_s: f64,
    pub max_speed_m_s: f64,
    pub min_force_n: f64,
    pub max_force_n: f64,
}

#[derive(Debug, Clone, PartialEq, Error)]
pub enum GripperError {
    #[error("bad command: {0}")]
    BadCommand(String),
    #[error("the gripper driver has stopped: {0}")]
    Stopped(String),
    /// The weakest grip the gripper can make is above a force bound its user promised to keep.
    #[error(
        "its weakest grip, {min_force_n} N, is above the force bound of {bound_n} N: every \
         grip would be raised to at least {min_force_n} N, past the bound"
    )]
    ForceFloorAboveBound { min_force_n: f64, bound_n: f64 },
}

/// Any gripper, driven the same way by a policy.
pub trait Gripper: Send {
    /// Model name (e.g. "robotiq_2f85").
    fn model(&self) -> &str;
    fn limits(&self) -> Limits;
    /// Request activation; a gripper that is already active stays as it is (nothing is written).
    fn activate(&mut self) -> Result<(), GripperError>;
    /// Request a motion. Values outside the model's range are clamped to it; non-finite values are
    /// refused.
    fn command(&mut self, cmd: GripperSetpoint) -> Result<(), GripperError>;
    /// The latest state (never waits for the device).
    fn state(&self) -> GripperState;
    /// Request recovery from a major fault (re-activation). Does nothing without one.
    fn clear_fault(&mut self) -> Result<(), GripperError>;
}

/// What [`Limits::clamp`] changed in a command, field by field (none: it was within range).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct Clamped {
    pub opening: bool,
    pub speed: bool,
    pub force: bool,
}

impl Clamped {
    pub fn any(&self) -> bool {
        self.opening || self.speed || self.force
    }
}

impl Limits {
    /// Which fields of a finite `asked` command [`Limits::clamp`] changes into `done`.
    pub fn clamped(asked: &GripperSetpoint, done: &GripperSetpoint) -> Clamped {
        Clamped {
            opening: asked.opening_m != done.opening_m,
            speed: asked.speed_m_s != done.speed_m_s,
            force: asked.force_n != done.force_n,
        }
    }

    /// Whether a caller bounded to `max_force_n` (a policy's force cap) can drive this gripper
    /// within that bound: refused when even the weakest grip is stronger (a DH AG-95's 45 N
    /// under a 40 N bound), since [`Limits::clamp`] would raise every force past it.
    pub fn check_force_bound(&self, max_force_n: f64) -> Result<(), GripperError> {
        if max_force_n.is_nan() || self.min_force_n > max_force_n {
            return Err(GripperError::ForceFloorAboveBound {
                min_force_n: self.min_force_n,
                bound_n: max_force_n,
            });
        }
        Ok(())
    }

    /// Check `cmd` is finite and clamp it to the limits.
    pub fn clamp(&self, cmd: GripperSetpoint) -> Result<GripperSetpoint, GripperError> {
        if !(cmd.opening_m.is_finite() && cmd.speed_m_s.is_finite() && cmd.force_n.is_finite()) {
            return Err(GripperError::BadCommand(format!(
                "non-finite value in {cmd:?}"
            )));
        }
        Ok(GripperSetpoint {
            opening_m: cmd.opening_m.clamp(0.0, self.max_opening_m),
            speed_m_s: cmd.speed_m_s.clamp(self.min_speed_m_s, self.max_speed_m_s),
            force_n: cmd.force_n.clamp(self.min_force_n, self.max_force_n),
        })
    }
}

/// A linear map between a raw register range and an SI range.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Linear {
    pub raw_a: f64,
    pub si_a: f64,
    pub raw_b: f64,
    pub si_b: f64,
}

impl Linear {
    pub const fn new(raw_a: f64, si_a: f64, raw_b: f64, si_b: f64) -> Self {
        Self {
            raw_a,
            si_a,
            raw_b,
            si_b,
        }
    }
    pub fn to_si(&self, raw: f64) -> f64 {
        self.si_a + (raw - self.raw_a) * (self.si_b - self.si_a) / (self.raw_b - self.raw_a)
    }
    /// The SI value of `raw` clamped to the raw range first, and whether it was outside it (a
    /// device reporting past its calibrated end: the SI value stays within the SI range).
    pub fn to_si_clamped(&self, raw: f64) -> (f64, bool) {
        let (lo, hi) = (self.raw_a.min(self.raw_b), self.raw_a.max(self.raw_b));
        let r = raw.clamp(lo, hi);
        (self.to_si(r), r != raw)
    }
    /// Nearest raw value, clamped to the raw range.
    pub fn to_raw(&self, si: f64) -> u16 {
        let r = self.raw_a + (si - self.si_a) * (self.raw_b - self.raw_a) / (self.si_b - self.si_a);
        let (lo, hi) = (self.raw_a.min(self.raw_b), self.raw_a.max(self.raw_b));
        r.round().clamp(lo, hi) as u16
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn linear_maps_both_ways_and_clamps() {
        let pos = Linear::new(0.0, 0.085, 227.0, 0.0);
        assert_eq!(pos.to_raw(0.085), 0);
        assert_eq!(pos.to_raw(0.0), 227);
        assert_eq!(pos.to_raw(-1.0), 227);
        assert!((pos.to_si(f64::from(pos.to_raw(0.04))) - 0.04).abs() < 0.5 * 0.085 / 227.0);
        let l = Limits {
            max_opening_m: 0.085,
            min_speed_m_s: 0.02,
            max_speed_m_s: 0.15,
            min_force_n: 20.0,
            max_force_n: 235.0,
        };
        let c = l
            .clamp(GripperSetpoint {
                opening_m: 1.0,
                speed_m_s: 0.0,
                force_n: 1e9,
            })
            .unwrap();
        assert_eq!((c.opening_m, c.speed_m_s, c.force_n), (0.085, 0.02, 235.0));
        let asked = GripperSetpoint {
            opening_m: 0.05,
            speed_m_s: 0.01,
            force_n: 50.0,
        };
        let done = l.clamp(asked).unwrap();
        let what = Limits::clamped(&asked, &done);
        assert_eq!(
            what,
            Clamped {
                opening: false,
                speed: true,
                force: false
            }
        );
        assert!(what.any());
        assert!(!Limits::clamped(&done, &done).any());
        assert!(
            l.clamp(GripperSetpoint {
                opening_m: f64::NAN,
                speed_m_s: 0.1,
                force_n: 50.0
            })
            .is_err()
        );
    }

    #[test]
    fn a_force_bound_below_the_weakest_grip_is_refused() {
        let ag95 = crate::Model::named("dh_ag95").unwrap().calibration().limits;
        let e = ag95.check_force_bound(40.0).unwrap_err();
        assert_eq!(
            e,
            GripperError::ForceFloorAboveBound {
                min_force_n: 45.0,
                bound_n: 40.0
            }
        );
        assert!(e.to_string().contains("45 N"), "{e}");
        assert!(e.to_string().contains("40 N"), "{e}");
        assert!(ag95.check_force_bound(45.0).is_ok());
        assert!(ag95.check_force_bound(f64::NAN).is_err());
        let f140 = crate::Model::named("robotiq_2f140")
            .unwrap()
            .calibration()
            .limits;
        assert!(f140.check_force_bound(40.0).is_ok());
    }
}
