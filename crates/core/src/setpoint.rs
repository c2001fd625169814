//! The one gripper setpoint: what every gripper (a serial Robotiq or DH, a ros2_control
//! controller, the sim world's fingers) is asked to do, in SI units, and the one place a
//! `GripperCommand` message becomes it.

use serde::Serialize;

use crate::msg::{GripperCommand, GripperMode};

/// A motion: go to `opening_m` at no more than `speed_m_s`, squeezing with at most `force_n`
/// (the fingers stop on an object when the grip force reaches it).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct GripperSetpoint {
    /// Distance between the fingertips \[m].
    pub opening_m: f64,
    /// Bound on the opening rate \[m/s].
    pub speed_m_s: f64,
    /// Grip force bound per finger \[N].
    pub force_n: f64,
}

impl GripperSetpoint {
    /// The motion a `unitac_msgs/GripperCommand` asks for, as the message defines it:
    /// - POSITION goes to `position_m` with `force_n` as the force limit;
    /// - FORCE closes (target 0) until the grip force reaches `force_n`;
    /// - STOP holds the measured opening `opening_now` with `force_n`, None without a measured
    ///   opening (nothing to hold yet).
    ///
    /// The speed is the command's in every mode. Values are not checked here: a gripper clamps
    /// or refuses what is outside its range, and callers check finiteness.
    pub fn from_command(c: &GripperCommand, opening_now: Option<f64>) -> Option<Self> {
        let opening_m = match c.mode {
            GripperMode::Position => c.position_m,
            GripperMode::Force => 0.0,
            GripperMode::Stop => opening_now?,
        };
        Some(Self {
            opening_m,
            speed_m_s: c.speed_m_s,
            force_n: c.force_n,
        })
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use crate::clock::Stamp;
    use crate::msg::Header;

    fn cmd(mode: GripperMode, position_m: f64, force_n: f64) -> GripperCommand {
        GripperCommand {
            header: Header::new(Stamp::ZERO, "gripper"),
            mode,
            position_m,
            speed_m_s: 0.05,
            force_n,
            reason: String::new(),
        }
    }

    #[test]
    fn each_mode_has_the_meaning_the_message_gives_it() {
        let p = GripperSetpoint::from_command(&cmd(GripperMode::Position, 0.04, 20.0), Some(0.07));
        assert_eq!(
            p,
            Some(GripperSetpoint {
                opening_m: 0.04,
                speed_m_s: 0.05,
                force_n: 20.0
            })
        );
        let f = GripperSetpoint::from_command(&cmd(GripperMode::Force, 0.04, 15.0), Some(0.07));
        assert_eq!(f.unwrap().opening_m, 0.0);
        assert_eq!(f.unwrap().force_n, 15.0);
        // STOP holds the measured opening with the command's force, whatever position_m says.
        let s = GripperSetpoint::from_command(&cmd(GripperMode::Stop, f64::NAN, 5.0), Some(0.07));
        assert_eq!(
            s,
            Some(GripperSetpoint {
                opening_m: 0.07,
                speed_m_s: 0.05,
                force_n: 5.0
            })
        );
        assert_eq!(
            GripperSetpoint::from_command(&cmd(GripperMode::Stop, 0.02, 5.0), None),
            None
        );
    }
}
