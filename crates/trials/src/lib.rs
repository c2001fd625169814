//! Closed-loop trials of the paper's two tasks (issue 13): a sim task world
//! ([`unitac_sim::task::TaskWorld`]) driven by the scene's stages and policy through messages.
//!
//! - [`bridge`]: the one conversion between the world and the messages (GripperStatus,
//!   VisualObservation and the mock sensor's frames out of the world; GripperCommand +
//!   ArmCommand into it), used by the embedded trial loop and by the ROS sim node alike.
//! - [`demos`]: the scripted expert's cup demonstrations recorded with what a policy could
//!   observe (the scene's tactile stages' latents, the camera, the gripper) and its labels.

pub mod bridge;
pub mod demos;
