//! The driver's benchmark cycle (`unitac_gripper::bench`) against a simulated device on a pty:
//! the figure a user compares a real gripper's with.

use crate::device::{DeviceConfig, SimDevice};
use std::time::Duration;
use thiserror::Error;
use unitac_gripper::bench::{self, BenchResult, Cycle};
use unitac_gripper::client::{ClientConfig, ModbusError, RtuClient};
use unitac_gripper::model::Model;
use unitac_gripper::port::{self, PortError};

/// Why the simulated benchmark could not run.
#[derive(Debug, Error)]
pub enum SimBenchError {
    #[error("sim device: {0}")]
    Device(#[from] std::io::Error),
    #[error(transparent)]
    Port(#[from] PortError),
    #[error(transparent)]
    Modbus(#[from] ModbusError),
}

/// The benchmark cycle `kind` against a simulated `model` on a pty, paced at `baud` or not.
pub fn run_sim(
    model: Model,
    kind: Cycle,
    baud: u32,
    paced: bool,
    duration: Duration,
) -> Result<BenchResult, SimBenchError> {
    let mut cfg = DeviceConfig::new(model);
    cfg.baud = baud;
    cfg.paced = paced;
    cfg.spin = paced;
    cfg.start_active = true;
    let dev = SimDevice::spawn(cfg)?;
    let p = port::open(&dev.path(), baud)?;
    let mut client = RtuClient::new(
        p,
        ClientConfig {
            timeout: Duration::from_millis(100),
            retries: 0,
            ..ClientConfig::new(model.default_slave(), baud)
        },
    );
    let label = format!(
        "sim {} on a pty, {}",
        model,
        if paced {
            format!("paced at {baud} baud")
        } else {
            "unpaced".into()
        }
    );
    Ok(bench::run(&label, &mut client, model, kind, duration)?)
}
