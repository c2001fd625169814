//! Simulated grippers for tests, trials and benchmarks without hardware, behind the same
//! interfaces as the real ones (crates/gripper):
//!
//! - [`device::SimDevice`]: simulated Robotiq 2F and DH controllers speaking Modbus RTU on a
//!   pseudo-terminal, with fault injection; the real driver opens them by path like a port.
//! - [`device::relay`]: a device whose fingers the caller integrates in its own clock (the
//!   closed-loop trials' serial gripper).
//! - [`sim_world::SimWorldGripper`]: the sim world's gripper behind the `Gripper` trait, and
//!   [`sim_world::WorldFingers`], the same world as a simulated device's fingers.
//! - [`bench::run_sim`]: the driver's benchmark cycle against a simulated device.

pub mod bench;
pub mod device;
pub mod sim_world;
