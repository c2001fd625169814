//! Round trips per second against a gripper, against the limit the wire sets.
//!
//! A benchmark reads status only ([`Cycle::StatusOnly`]): a device on a bench may be inactive,
//! holding something or have a hand near its fingers, and a benchmark must not move it. The
//! command cycle ([`Cycle::Motion`]) writes the command registers every cycle and is for a gripper
//! that may move (`unitac gripper ... bench --allow-motion`).
//!
//! Wire limit of one cycle at `baud` (8N1: 10 bits a character): the request and reply bytes plus
//! a 3.5-character silence after each frame. Status only, Robotiq and DH alike: one read of three
//! registers (FC 0x04 / 0x03, 8-byte request, 11-byte reply) = 26 character times = 2.257 ms at
//! 115200 baud, 443.1 cycles/s. Motion: Robotiq one 0x17 exchange (19-byte request writing three
//! registers and reading three, 11-byte reply) = 37 character times = 3.212 ms, 311.4 cycles/s;
//! DH a 0x06 write (8 + 8 bytes) and a 0x03 read of three registers (8 + 11 bytes) = 49 character
//! times, 235.1 cycles/s.

use crate::client::{Link, ModbusError, RtuClient};
use crate::frame::{Request, Response};
use crate::model::{Family, Model};
use crate::protocol::{dh, robotiq};
use serde::Serialize;
use std::time::{Duration, Instant};

/// What one benchmark cycle does.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Cycle {
    /// Read the status registers; nothing is written.
    StatusOnly,
    /// Write a command and read the status: Robotiq rACT | rGTO, rPR = 0 (open), rSP = 255, which
    /// activates an inactive gripper and opens it at full speed; DH position 1000 (open).
    Motion,
}

impl Cycle {
    /// One line for the user: what the cycle does to the gripper.
    pub fn describe(self, model: Model) -> &'static str {
        match (self, model.family()) {
            (Cycle::StatusOnly, Family::Robotiq) => {
                "status reads only (FC 0x04, 3 registers at 0x07D0): nothing is written, the \
                 gripper does not move; --allow-motion benchmarks command writes instead"
            }
            (Cycle::StatusOnly, Family::Dh) => {
                "status reads only (FC 0x03, 3 registers at 0x0200): nothing is written, the \
                 gripper does not move; --allow-motion benchmarks command writes instead"
            }
            (Cycle::Motion, Family::Robotiq) => {
                "with --allow-motion: every cycle writes rACT | rGTO, rPR = 0, rSP = 255 (FC 0x17): \
                 an inactive gripper is activated and the fingers open at full speed"
            }
            (Cycle::Motion, Family::Dh) => {
                "with --allow-motion: every cycle writes position 1000 (FC 0x06, the fingers \
                 open) and reads the status (FC 0x03)"
            }
        }
    }
}

/// The requests of one benchmark cycle of `model`.
pub fn cycle(model: Model, kind: Cycle) -> Vec<Request> {
    match (kind, model.family()) {
        (Cycle::StatusOnly, Family::Robotiq) => vec![Request::ReadInput {
            addr: robotiq::STATUS,
            qty: 3,
        }],
        (Cycle::StatusOnly, Family::Dh) => vec![Request::ReadHolding {
            addr: dh::INIT_STATE,
            qty: 3,
        }],
        (Cycle::Motion, Family::Robotiq) => vec![Request::ReadWrite {
            read_addr: robotiq::STATUS,
            read_qty: 3,
            write_addr: robotiq::CMD,
            values: robotiq::command_regs(robotiq::ACT | robotiq::GTO, 0, 255, 0),
        }],
        (Cycle::Motion, Family::Dh) => vec![
            Request::WriteSingle {
                addr: dh::POSITION,
                value: 1000,
            },
            Request::ReadHolding {
                addr: dh::INIT_STATE,
                qty: 3,
            },
        ],
    }
}

/// Bytes of the reply to `req`.
pub fn reply_len(req: &Request) -> usize {
    match req {
        Request::ReadHolding { qty, .. }
        | Request::ReadInput { qty, .. }
        | Request::ReadWrite { read_qty: qty, .. } => 5 + 2 * usize::from(*qty),
        Request::WriteSingle { .. } | Request::WriteMultiple { .. } => 8,
    }
}

/// Seconds one cycle takes on the wire at `baud`.
pub fn wire_time(cycle: &[Request], baud: u32) -> f64 {
    let chars: f64 = cycle
        .iter()
        .map(|r| {
            let req = r.encode(0).map_or(0, |b| b.len());
            (req + reply_len(r)) as f64 + 2.0 * 3.5
        })
        .sum();
    chars * 10.0 / f64::from(baud.max(1))
}

#[derive(Debug, Clone, Serialize)]
pub struct BenchResult {
    pub label: String,
    /// What each cycle did (status reads only, or command writes that move the gripper).
    pub cycle: Cycle,
    pub cycles: u64,
    pub failures: u64,
    pub seconds: f64,
    pub rate_hz: f64,
    pub wire_limit_hz: f64,
    /// rate / wire limit.
    pub ratio: f64,
    /// Round trip of one request and its reply \[s], median and 99th percentile.
    pub rtt_p50_s: Option<f64>,
    pub rtt_p99_s: Option<f64>,
}

/// Run the `kind` cycle of `model` back to back for `duration` over `client`.
pub fn run<L: Link>(
    label: &str,
    client: &mut RtuClient<L>,
    model: Model,
    kind: Cycle,
    duration: Duration,
) -> Result<BenchResult, ModbusError> {
    let baud = client.config().baud;
    let cycle = &cycle(model, kind)[..];
    // One cycle first: a device that does not answer is an error, not a rate of zero.
    for r in cycle {
        client.call(r)?;
    }
    let t0 = Instant::now();
    let (mut cycles, mut failures) = (0u64, 0u64);
    while t0.elapsed() < duration {
        let mut ok = true;
        for r in cycle {
            match client.call(r) {
                Ok(Response::Exception { .. }) | Err(_) => ok = false,
                Ok(_) => {}
            }
        }
        if ok {
            cycles += 1;
        } else {
            failures += 1;
        }
    }
    let seconds = t0.elapsed().as_secs_f64();
    let rate = cycles as f64 / seconds;
    let limit = 1.0 / wire_time(cycle, baud);
    let s = client.stats();
    Ok(BenchResult {
        label: label.into(),
        cycle: kind,
        cycles,
        failures,
        seconds,
        rate_hz: rate,
        wire_limit_hz: limit,
        ratio: rate / limit,
        rtt_p50_s: s.rtt_percentile(0.5),
        rtt_p99_s: s.rtt_percentile(0.99),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wire_limits_from_frame_sizes() {
        let r = cycle(Model::named("robotiq_2f85").unwrap(), Cycle::Motion);
        assert_eq!(r[0].encode(9).unwrap().len(), 19);
        assert_eq!(reply_len(&r[0]), 11);
        let hz = 1.0 / wire_time(&r, 115_200);
        assert!((hz - 115_200.0 / 370.0).abs() < 1e-9, "{hz}");
        let d = 1.0
            / wire_time(
                &cycle(Model::named("dh_ag95").unwrap(), Cycle::Motion),
                115_200,
            );
        assert!((d - 115_200.0 / 490.0).abs() < 1e-9, "{d}");
        for m in [
            Model::named("robotiq_2f85").unwrap(),
            Model::named("dh_ag95").unwrap(),
        ] {
            let r = cycle(m, Cycle::StatusOnly);
            assert_eq!(r[0].encode(9).unwrap().len(), 8);
            let hz = 1.0 / wire_time(&r, 115_200);
            assert!((hz - 115_200.0 / 260.0).abs() < 1e-9, "{hz}");
        }
    }

    #[test]
    fn a_status_only_cycle_writes_nothing() {
        for m in Model::all() {
            assert!(
                cycle(m, Cycle::StatusOnly)
                    .iter()
                    .all(|r| matches!(r, Request::ReadInput { .. } | Request::ReadHolding { .. })),
                "{m}"
            );
        }
    }
}
