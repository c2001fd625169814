//! Helpers shared by the lab's command-line tests: running `unitac-lab` (with a time limit), and
//! [`shared`], what the tests of `unitac` (crates/cli/tests) do as well. Each test file uses some
//! of them.
#![allow(dead_code)]

#[path = "../../../cli/tests/common/shared.rs"]
pub mod shared;

use std::process::{Command, Output};
use std::time::Duration;

/// The binary under test.
pub const EXE: &str = env!("CARGO_BIN_EXE_unitac-lab");

/// `unitac-lab args`, logging at warn.
pub fn unitac_lab(args: &[&str]) -> Output {
    Command::new(EXE)
        .args(args)
        .env("RUST_LOG", "warn")
        .output()
        .unwrap()
}

/// `unitac-lab args` with the environment variables `env` set, killed after `limit` (a hang is
/// a failure, not a stuck test).
pub fn unitac_lab_within(args: &[&str], env: &[(&str, &str)], limit: Duration) -> Output {
    shared::run_within(EXE, args, env, limit)
}
