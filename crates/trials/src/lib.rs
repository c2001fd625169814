//! Closed-loop trials of the paper's two tasks: a sim task world
//! ([`unitac_sim::task::TaskWorld`]) driven by the scene's stages and policy through messages.
//!
//! - [`bridge`]: the one conversion between the world and the messages (GripperStatus,
//!   VisualObservation and the mock sensor's frames out of the world; GripperCommand +
//!   ArmCommand into it), used by the embedded trial loop and by the ROS sim node alike;
//! - [`gripper`]: the gripper side of a trial, in process or [`serial`] (the Modbus driver and a
//!   simulated device on a pty whose fingers are the world's gripper);
//! - [`run`]: one closed-loop trial (the world as the scene's source, the scene's stages driven
//!   by `unitac_core::chain`, a per-tick trace and the world's outcome);
//! - [`scene`]: the sim task a scene's policy stage names;
//! - [`stepper`]: the one lock-step world stepper (frames, camera, gripper status out; one
//!   command per control period in), used by the trials, the demonstrations, the ROS sim node
//!   and the policy bench;
//! - [`table`]: the paper-style success table, our counts beside the paper's;
//! - [`demos`]: the scripted expert's cup demonstrations recorded with what a policy could
//!   observe (the scene's tactile stages' latents, the camera, the gripper) and its labels.

pub mod bridge;
pub mod demos;
pub mod gripper;
pub mod run;
pub mod scene;
pub mod serial;
pub mod stepper;
pub mod table;

pub use gripper::{TrialGripper, UnknownTrialGripper};
pub use run::{
    ChainMessage, StiffnessReading, TouchSwap, TraceRow, TrialError, TrialOptions, TrialRecord,
    run_trial, run_trial_on, run_trial_swapped,
};
