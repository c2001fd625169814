//! UniTac inference through ONNX Runtime.
//!
//! - [`runtime`]: the one ONNX Runtime environment of the process (ort, load-dynamic) and sessions.
//! - [`bundle`]: a model bundle (manifest + .onnx files), every declared input/output checked
//!   against the file on load, only the models a scene uses loaded.
//! - [`preprocess`]: clip frames -> encoder tensors, as the manifest says.
//! - [`encoder`]: touch encoder + property head on contact-episode clips.
//! - [`compare`]: Property Comparison between touched objects.
//! - [`prior`]: the sensor-level condition (the encoder's sensor tokens of the background).
//! - [`condition`]: the object-level condition (category and camera values of one object).
//! - [`predict`]: the sampler stage: a predicted tactile latent per object before contact.
//! - [`flow`]: rectified-flow sampling with sensor-prior guidance (SPSS), guards, exact Gaussian
//!   oracle.
//!
//! Time convention of the sampler: tau in [0, 1], tau = 0 is noise, tau = 1 is data, N steps of
//! h = 1/N ending exactly at tau = 1. A model trained the other way is adapted by the manifest's
//! `time_convention` (see ../shared notes on the flow sampler).

pub mod bundle;
pub mod compare;
pub mod condition;
pub mod encoder;
pub mod flow;
pub mod predict;
pub mod preprocess;
pub mod prior;
pub mod runtime;

pub use bundle::{Bundle, Manifest, ModelSpec};
pub use runtime::{ExecutionProvider, InferError, RuntimeConfig};
