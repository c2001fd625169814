//! Serial grippers for the UniTac robot stack.
//!
//! - [`gripper::Gripper`]: the one trait a policy drives (SI units, non-blocking).
//! - [`driver::SerialGripper`]: Robotiq 2F-85/2F-140 and DH AG-95/PGE over Modbus RTU
//!   ([`client`], [`frame`], [`protocol`]) on a serial port ([`port`]).
//! - [`sim_world::SimWorldGripper`]: the sim world's gripper behind the same trait.
//! - [`status::status`]: a gripper's state as the `GripperStatus` message (the gripper node and
//!   the serial trial gripper both use it).
//! - [`device::SimDevice`]: simulated serial grippers on a pseudo-terminal, with fault injection,
//!   for tests and benchmarks without hardware.

pub mod action;
pub mod bench;
pub mod client;
pub mod crc;
pub mod device;
pub mod driver;
pub mod frame;
pub mod gripper;
pub mod model;
pub mod port;
pub mod protocol;
pub mod sim_world;
pub mod status;

pub use driver::{DriverConfig, DriverStats, SerialGripper};
pub use gripper::{Activation, Fault, GripCommand, Gripper, GripperError, GripperState, Motion};
pub use model::{Model, UnknownModel};
