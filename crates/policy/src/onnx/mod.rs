//! ONNX policies: a policy exported to ONNX (LeRobot-style flat inputs, an action chunk out),
//! described by a manifest next to the `.onnx` file, checked against the model at load, and run
//! per control tick with chunking and ACT temporal ensembling.
//!
//! - [`manifest`]: the `manifest.json` format (LeRobot names: `observation.state`,
//!   `observation.images.<camera>`, `observation.<name>`, `action`; `chunk_size`,
//!   `n_action_steps`, `temporal_ensemble_coeff`).
//! - [`validate`]: every mismatch between manifest and model, collected into one error.
//! - [`OnnxPolicy`]: load once, then `act(&NamedInputs, Stamp) -> ActionChunk` on every tick.
//!
//! The model runs through unitac-infer's runtime (the process's one ONNX Runtime environment
//! and its session settings); no ort type appears in this module's API.

mod chunk;
mod io;
pub mod manifest;
mod normalize;
mod policy;
pub mod validate;

pub use chunk::TimeWentBack;
pub use io::{ActionChunk, NamedInputs};
pub use manifest::PolicyManifest;
pub use policy::{FAR_FRACTION, LoadError, Mismatches, OnnxPolicy, RunError};
pub use unitac_infer::RuntimeConfig;
pub use validate::Mismatch;
