//! Serial grippers for the UniTac robot stack.
//!
//! - [`gripper::Gripper`]: the one trait a policy drives (SI units, non-blocking).
//! - [`driver::SerialGripper`]: Robotiq 2F-85/2F-140 and DH AG-95/PGE over Modbus RTU
//!   ([`client`], [`frame`], [`protocol`]) on a serial port ([`port`]).
//! - [`status::status`]: a gripper's state as the `GripperStatus` message (the gripper node and
//!   the serial trial gripper both use it).
//! - [`action::ActionLink`]: a ros2_control gripper action's goals from our commands.
//! - [`mod@bench`]: round trips per second against a gripper, against the wire's limit.
//!
//! Simulated devices (a pty Robotiq or DH, the sim world's gripper) live in unitac-gripper-sim.

pub mod action;
pub mod bench;
pub mod client;
pub mod crc;
pub mod driver;
pub mod frame;
pub mod gripper;
pub mod model;
pub mod port;
pub mod protocol;
pub mod status;

pub use driver::{DriverConfig, DriverStats, SerialGripper};
pub use gripper::{
    Activation, Fault, Gripper, GripperError, GripperSetpoint, GripperState, Motion,
};
pub use model::{Model, UnknownModel};
