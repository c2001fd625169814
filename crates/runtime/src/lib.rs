//! The embedded runtime: runs the stages a scene file names, with no ROS.
//!
//! One thread per stage (plus one for the source) and a bounded [`edge::Edge`] between
//! neighbours. Each stage sees every message from upstream; the runtime forwards each input
//! downstream after the stage's own outputs, so a chain `source -> contact -> infer -> policy`
//! works without stages knowing about each other. Threads rather than async tasks: stages are
//! CPU-bound and few, live sources block on the device, and ordering per edge is what makes replay
//! deterministic.
//!
//! Edge policy is explicit: frames are dropped oldest-first (and counted) when a consumer falls
//! behind a live or real-time source; events are never dropped (the producer waits). With `--fast`
//! replay, frames are lossless too, so a replay's output depends only on its input.

pub mod edge;
pub mod report;
pub mod run;

pub use edge::{Edge, FramePolicy};
pub use report::{RunReport, StageReport};
pub use run::{RunOptions, run};
