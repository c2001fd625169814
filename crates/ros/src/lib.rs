//! ROS 2 side of the UniTac robot stack (r2r). The only crate that links ROS.
//!
//! Nodes here are thin: they convert between ROS messages and the `unitac-core` types and drive
//! the same stages as the embedded runtime. [`convert`] holds the field-by-field conversions.

pub mod convert;

use std::time::{Duration, Instant};

/// Spin `node` until `done()` holds or `timeout` passes; returns whether `done()` held.
/// The spin wait is short (10 ms) so delivery is not capped the way a 100 ms spin would cap it.
pub fn spin_until(node: &mut r2r::Node, timeout: Duration, mut done: impl FnMut() -> bool) -> bool {
    let t0 = Instant::now();
    while t0.elapsed() < timeout {
        if done() {
            return true;
        }
        node.spin_once(Duration::from_millis(10));
    }
    done()
}

/// A list parameter: comma-separated, items trimmed, empty items dropped (r2r's derived
/// parameters have no arrays).
pub fn list_param(s: &str) -> Vec<String> {
    s.split(',')
        .map(str::trim)
        .filter(|x| !x.is_empty())
        .map(str::to_string)
        .collect()
}

pub mod chain;
pub mod diagnostics;
pub mod drops;
pub mod image;
pub mod node;
