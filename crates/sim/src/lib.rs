//! Mock tactile sensor: deterministic RGB frames of presses on objects, with ground truth, and
//! the small simulated world (gripper, gel, cup) that drives some of its scenarios.
//!
//! - [`mock`]: the mock sensor as a frame source (scenario, frame rate, stamps, ground truth).
//! - `render`: the photometric model of a gel sensor that draws each frame.
//! - [`tangential`]: the gel's sideways displacement under a pulled or twisted object (markers),
//!   the truth a slip detector is measured against.
//! - [`world`]: the gripper / gel / cup model and its integrators.
//! - [`task`]: the closed-loop task worlds (cup deformation, fabric selection) and the scripted
//!   expert.
//! - [`numerics`]: the integrator study (its tables; the charts and the renderer benchmark are
//!   `unitac-lab`'s).

pub mod ballpress;
pub mod degrade;
pub mod mock;
pub mod numerics;
mod object;
mod render;
mod rng;
mod scenario;
pub mod tangential;
pub mod task;
pub mod world;

pub use mock::{Drift, EPOCH, GroundTruth, MockConfig, MockSensor};
pub use object::{BUMP_ASPECT, FLAT_FILLET, FoldEdge, MM_PER_M, Object, Shape};
pub use rng::{GaussianTable, NoiseStream, SplitMix64, normal_quantile, quantise_f32};
pub use scenario::{Phase, Scenario, ScenarioError};
pub use tangential::{MarkerTruth, Tangential};
pub use world::{
    Command, Cup, DriveStep, Gel, GripSample, Gripper, Method, Substep, World, WorldConfig,
    WorldError, WorldTruth,
};
