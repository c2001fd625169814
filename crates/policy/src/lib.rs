//! VTLA policy stages: observation assembly with freshness budgets, scene controllers,
//! ONNX policies, and the safety layer between any policy and any gripper.
//!
//! Every stage here implements `unitac_core::Stage` with an injected clock, like the contact and
//! inference stages, so the embedded runtime, bag replay and the ROS policy node drive the same
//! code. See the crate README for the observation layout, the safety rules and the modes.

pub mod bench;
pub mod controller;
pub mod error;
pub mod learned;
pub mod mode;
pub mod observation;
pub mod onnx;
pub mod params;
pub mod policy;
pub mod readout;
pub mod reflex;
pub mod safety;
pub mod schema;
pub mod stage;
pub mod task;
pub mod ticks;

pub use error::{FeatureError, InputError, PolicyLoadError, Problems, SceneStagesError};
pub use learned::LearnedPolicy;
pub use mode::{Mode, UnknownMode};
pub use params::{PolicyKind, PolicyParams, VlaRule};
pub use policy::{Action, ArmAction, GripperAction, Policy, PolicyError};
pub use reflex::ReflexCounters;
pub use stage::{PolicyStage, check_scene};
pub use ticks::{TickCounts, TickKind};
