//! A gripper's state as `unitac_msgs/GripperStatus`, the message the policy ticks on: the one
//! conversion the gripper node (crates/ros) and the serial trial gripper (crates/trials) share.
//!
//! Unknowns are NaN (as the message says); `object_detected` is the device's own object
//! detection (Robotiq gOBJ, DH "caught"); `fault` is empty when there is none, else its kind,
//! code and text (a link fault too: the policy's watchdog treats a gripper fault as invalid).

use crate::gripper::{Activation, Fault, GripperState, Motion};
use unitac_core::Stamp;
use unitac_core::msg::{GripperStatus, Header};

fn activation(a: Activation) -> &'static str {
    match a {
        Activation::Unknown => "unknown",
        Activation::Inactive => "reset",
        Activation::Activating => "activating",
        Activation::Active => "active",
    }
}

fn motion(m: Motion) -> &'static str {
    match m {
        Motion::Unknown => "unknown",
        Motion::Idle => "idle",
        Motion::Moving => "moving",
        Motion::Reached => "reached",
        Motion::CaughtOpening => "caught_opening",
        Motion::Caught => "caught",
        Motion::Dropped => "dropped",
    }
}

fn fault(f: &Option<Fault>) -> String {
    match f {
        None => String::new(),
        Some(Fault::Minor { code, what }) => format!("minor 0x{code:02X}: {what}"),
        Some(Fault::Major { code, what }) => format!("major 0x{code:02X}: {what}"),
        Some(Fault::Link { what }) => format!("link: {what}"),
    }
}

/// The state read at `stamp` as a GripperStatus in `frame_id`.
pub fn status(s: &GripperState, stamp: Stamp, frame_id: &str) -> GripperStatus {
    let nan = |v: Option<f64>| v.unwrap_or(f64::NAN);
    GripperStatus {
        header: Header::new(stamp, frame_id),
        opening_m: nan(s.opening_m),
        target_m: nan(s.target_m),
        force_n: nan(s.force_n),
        current_a: nan(s.current_a),
        object_detected: s.motion.holds_object(),
        activation: activation(s.activation).into(),
        motion: motion(s.motion).into(),
        fault: fault(&s.fault),
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn unknowns_are_nan_and_a_catch_is_a_detected_object() {
        let s = GripperState::default();
        let m = status(&s, Stamp(5), "gripper_base");
        assert!(m.opening_m.is_nan() && m.target_m.is_nan() && m.force_n.is_nan());
        assert_eq!(
            (m.activation.as_str(), m.motion.as_str()),
            ("unknown", "unknown")
        );
        assert!(!m.object_detected && m.fault.is_empty());
        let s = GripperState {
            activation: Activation::Active,
            motion: Motion::Caught,
            opening_m: Some(0.042),
            force_n: Some(20.0),
            fault: Some(Fault::Major {
                code: 0x0B,
                what: "overcurrent".into(),
            }),
            ..GripperState::default()
        };
        let m = status(&s, Stamp(5), "gripper_base");
        assert_eq!((m.opening_m, m.force_n), (0.042, 20.0));
        assert!(m.object_detected);
        assert_eq!(m.fault, "major 0x0B: overcurrent");
        assert_eq!(m.header.frame_id, "gripper_base");
    }
}
