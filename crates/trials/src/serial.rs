//! The serial gripper side of a trial: the real driver ([`SerialGripper`], the code the gripper
//! node and `unitac gripper` run) talks Modbus RTU over a pseudo-terminal to a simulated device
//! ([`SimDevice`]) whose fingers are the task world's gripper.
//!
//! The world stays integrated by the trial loop in sim time. The device's physics is a
//! [`relay`]: each device tick records the drive its controller decoded from the registers the
//! driver wrote (target, speed and force as raw register values: quantized to the model's
//! ranges, and clamped to them by the driver) and reports the fingers this side last published
//! from the world's truth. Per control tick:
//!
//! 1. `status`: wait until two exchanges completed after the last publish (the
//!    second one's request left after it, so the device ticked on the new fingers before
//!    answering it: gPO/gOBJ, or DH's position and grip state, describe the world after the
//!    previous step), then the driver's state as the GripperStatus message
//!    ([`unitac_gripper::status::status`], the gripper node's conversion);
//! 2. `command`: hand the policy's setpoint to the driver, wait until the device's
//!    drive is that command as the registers hold it and the driver's state echoes its target
//!    (the write was answered and the device ticked after it), and step the world with that
//!    drive. A command whose raw values equal the last one's is not sent again (nothing would
//!    change in the registers), so no write is ever in flight while the world steps;
//! 3. `stepped`: publish the world's new fingers (opening, force, stalled, and
//!    closing = the drive's target below the opening before the step).
//!
//! Wall time in the device and the driver, and why none of it reaches the outcome:
//! - the device steps its physics by wall-clock intervals: the relay ignores the interval;
//! - activation (Robotiq gSTA 1 -> 3, DH init) counts down in wall time: it runs through the
//!   driver's real activation sequence in `SerialSide::start`, before the trial's first tick,
//!   and the loop starts only once the driver reports the gripper active;
//! - the 1 s no-communication fault (Robotiq 0x09) cannot fire while the driver polls at
//!   [`RATE_HZ`]; if a stall of the process made it fire anyway, the status would carry the
//!   fault and `status` ends the trial with an error instead of a different outcome;
//! - a failed exchange (no reply within [`TIMEOUT`]) is counted in [`SerialReport::link_errors`]:
//!   a lost reply to a write makes the driver write again, which resets the device's object
//!   detection at a moment wall time decides, so a serial trial repeats byte for byte when it
//!   has none (tests/serial_gripper.rs asserts 0);
//! - waits are bounded by [`WAIT`] of wall time, then an error.
//!
//! The world's force bound is per finger, the Robotiq's and DH's a grip force: the number is
//! passed through as it is (one force, as the in-process gripper takes it).

use crate::bridge::{GRIPPER_FRAME, stamp_at};
use crate::gripper::GripperSide;
use serde::Serialize;
use std::time::{Duration, Instant};
use thiserror::Error;
use unitac_core::msg::GripperStatus;
use unitac_gripper::gripper::Linear;
use unitac_gripper::model::Calibration;
use unitac_gripper::{
    Activation, DriverConfig, Fault, Gripper, GripperError, GripperSetpoint, GripperState, Model,
    SerialGripper,
};
use unitac_gripper_sim::device::physics::{Drive, Fingers};
use unitac_gripper_sim::device::relay::{RelayHandle, relay};
use unitac_gripper_sim::device::{DeviceConfig, SimDevice};
use unitac_sim::task::TaskTruth;

/// Driver exchanges per second (the device is unpaced: a pty exchange takes well under 1 ms).
pub const RATE_HZ: f64 = 1000.0;
/// Per-request timeout of the driver: generous, a late reply is a link error (see above).
pub const TIMEOUT: Duration = Duration::from_millis(250);
/// Longest wait for the device or the driver at one step (wall time).
pub const WAIT: Duration = Duration::from_secs(10);

/// The serial side failed: the trial cannot go on with this gripper.
#[derive(Debug, Error)]
pub enum SerialError {
    #[error("cannot start the simulated serial gripper: {0}")]
    Spawn(#[from] std::io::Error),
    #[error("the serial gripper refused the command: {0}")]
    Command(#[from] GripperError),
    #[error("no {what} within {} s of wall time (driver state {state:?})", WAIT.as_secs())]
    Timeout {
        what: &'static str,
        state: Box<GripperState>,
    },
    #[error("the serial gripper reports a fault: {0}")]
    Fault(String),
    #[error("the device's motor is off (drive {0:?}): not active, or under a major fault")]
    MotorOff(Drive),
}

/// What went over the wire in one serial trial.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SerialReport {
    pub model: String,
    /// Requests the simulated device received and answered.
    pub device_requests: u64,
    pub device_replies: u64,
    /// Activations and rACT = 0 writes (Robotiq) / init writes (DH) the device saw.
    pub device_activations: u64,
    pub device_deactivations: u64,
    /// Motion commands handed to the driver (ticks whose raw command equals the last one's
    /// send none).
    pub commands: u64,
    /// The driver's successful exchanges, and its failed ones (no reply, incomplete, garbled,
    /// wrong slave) with their retries.
    pub exchanges: u64,
    pub link_errors: u64,
    pub retries: u64,
    /// The driver's last state: the raw position register and the opening it maps to \[m].
    pub last_raw_position: Option<u16>,
    pub last_opening_m: Option<f64>,
    /// One count of the position register \[m] (the model's calibration: stroke / raw range).
    pub position_step_m: f64,
}

/// The serial gripper of one trial. Field order is drop order: the driver stops before the
/// device.
pub(crate) struct SerialSide {
    driver: SerialGripper,
    device: SimDevice,
    relay: RelayHandle,
    model: Model,
    cal: Calibration,
    /// The last command as the device's drive (None before the first).
    sent: Option<Drive>,
    commands: u64,
    /// The fingers last published, and the driver's update count then.
    fingers: Fingers,
    published_at: u64,
}

/// `si` as the register holds it: to raw (rounded, clamped to the raw range) and back.
fn quantized(map: &Linear, si: f64) -> f64 {
    map.to_si(f64::from(map.to_raw(si)))
}

impl SerialSide {
    /// Spawn the device with the world's fingers at reset, start the driver and activate the
    /// gripper through the driver's activation sequence.
    pub fn start(model: Model, truth: &TaskTruth) -> Result<Self, SerialError> {
        let g = truth.gripper;
        let fingers = Fingers {
            opening_m: g.opening_m,
            force_n: g.force_n,
            stalled: g.stalled,
            closing: false,
        };
        let (physics, relay) = relay(fingers);
        let mut dcfg = DeviceConfig::new(model);
        dcfg.paced = false;
        let device = SimDevice::spawn_with(dcfg, Box::new(physics))?;
        let mut cfg = DriverConfig::new(device.path(), model);
        cfg.rate_hz = RATE_HZ;
        cfg.timeout = TIMEOUT;
        let cal = cfg.calibration;
        let driver = SerialGripper::start(cfg)?;
        let mut side = Self {
            driver,
            device,
            relay,
            model,
            cal,
            sent: None,
            commands: 0,
            fingers,
            published_at: 0,
        };
        side.driver.activate()?;
        let s = side.wait("activation", |s, _| s.activation == Activation::Active)?;
        side.published_at = s.updates;
        Ok(side)
    }

    /// Poll the driver's state (and the relay) until `ok`, at most [`WAIT`].
    fn wait(
        &self,
        what: &'static str,
        mut ok: impl FnMut(&GripperState, Option<Drive>) -> bool,
    ) -> Result<GripperState, SerialError> {
        let t0 = Instant::now();
        loop {
            let s = self.driver.state();
            if ok(&s, self.relay.drive()) {
                return Ok(s);
            }
            if t0.elapsed() >= WAIT {
                return Err(SerialError::Timeout {
                    what,
                    state: Box::new(s),
                });
            }
            std::thread::sleep(Duration::from_micros(100));
        }
    }
}

impl GripperSide for SerialSide {
    fn status(&mut self, truth: &TaskTruth) -> Result<GripperStatus, SerialError> {
        let need = self.published_at + 2;
        // A link fault clears with the next good exchange; wait for it.
        let s = self.wait("status read after the world's step", |s, _| {
            s.updates >= need && !matches!(s.fault, Some(Fault::Link { .. }))
        })?;
        if let Some(f) = &s.fault {
            return Err(SerialError::Fault(format!("{f:?}")));
        }
        Ok(unitac_gripper::status::status(
            &s,
            stamp_at(truth.t_s),
            GRIPPER_FRAME,
        ))
    }

    fn command(&mut self, want: GripperSetpoint) -> Result<GripperSetpoint, SerialError> {
        let cmd = GripperSetpoint {
            opening_m: want.opening_m,
            speed_m_s: want.speed_m_s,
            force_n: want.force_n,
        };
        // The driver clamps the same way before it converts to raw values.
        let c = self.cal.limits.clamp(cmd)?;
        let expected = Drive {
            enabled: true,
            target_m: quantized(&self.cal.position, c.opening_m),
            speed_m_s: quantized(&self.cal.speed, c.speed_m_s),
            force_n: quantized(&self.cal.force, c.force_n),
        };
        if self.sent != Some(expected) {
            self.driver.command(cmd)?;
            self.commands += 1;
            self.wait("device drive for the command", |s, d| {
                d == Some(expected) && s.target_m == Some(expected.target_m)
            })?;
            self.sent = Some(expected);
        }
        match self.relay.drive() {
            Some(d) if d.enabled => Ok(GripperSetpoint {
                opening_m: d.target_m,
                speed_m_s: d.speed_m_s,
                force_n: d.force_n,
            }),
            Some(d) => Err(SerialError::MotorOff(d)),
            None => Err(SerialError::Timeout {
                what: "first device tick",
                state: Box::new(self.driver.state()),
            }),
        }
    }

    fn stepped(&mut self, truth: &TaskTruth) -> Result<(), SerialError> {
        let g = truth.gripper;
        let before = self.fingers.opening_m;
        let closing = match self.sent {
            Some(d) if d.target_m < before => true,
            Some(d) if d.target_m > before => false,
            _ => self.fingers.closing,
        };
        self.fingers = Fingers {
            opening_m: g.opening_m,
            force_n: g.force_n,
            stalled: g.stalled,
            closing,
        };
        self.relay.publish(self.fingers);
        self.published_at = self.driver.state().updates;
        Ok(())
    }

    fn report(&self) -> Option<SerialReport> {
        // The driver's side first: every exchange it completed was counted by the device
        // before its reply left, so the device's counts read after are at least these.
        let state = self.driver.state();
        let stats = self.driver.stats();
        let snap = self.device.snapshot();
        let l = &stats.link;
        let p = &self.cal.position;
        Some(SerialReport {
            model: self.model.name().to_string(),
            device_requests: snap.requests,
            device_replies: snap.replies,
            device_activations: snap.activations,
            device_deactivations: snap.deactivations,
            commands: self.commands,
            exchanges: state.updates,
            link_errors: l.no_reply + l.incomplete + l.garbled + l.wrong_slave,
            retries: l.retries,
            last_raw_position: state.raw_position,
            last_opening_m: state.opening_m,
            position_step_m: (p.si_b - p.si_a).abs() / (p.raw_b - p.raw_a).abs(),
        })
    }
}
