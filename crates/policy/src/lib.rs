//! VTLA policy stages (issue 13): observation assembly with freshness budgets, scene controllers,
//! ONNX policies, and the safety layer between any policy and any gripper.
//!
//! Every stage here implements `unitac_core::Stage` with an injected clock, like the contact and
//! inference stages, so the embedded runtime, bag replay and the ROS policy node drive the same
//! code.

pub mod onnx;
