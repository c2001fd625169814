//! Sans-I/O register protocols of the two families: which request to send next, given what the
//! user wants, and how a reply updates the state. The driver thread ([`crate::driver`]) only
//! moves bytes; the tests drive these state machines through the real client and a simulated
//! device.
//!
//! Start-up rule (both families): the first request only reads the status. An active gripper is
//! left exactly as it is (nothing is written until a new command), so a restarted driver never
//! drops what the gripper holds. Robotiq's rACT = 0 is written only to clear a major fault, when
//! asked to.

use crate::frame::{Request, Response};
use crate::gripper::{Activation, Fault, GripperSetpoint, GripperState, Linear, Motion};
use crate::model::{Calibration, Family, Model};

/// What the user asked for; the protocol consumes the one-shot requests when it has acted on them.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Wants {
    /// Latest motion command and its sequence number (increases with every command).
    pub command: Option<(u64, GripperSetpoint)>,
    pub activate: bool,
    pub clear_fault: bool,
}

/// Robotiq 2F registers.
pub mod robotiq {
    pub const CMD: u16 = 0x03E8;
    pub const STATUS: u16 = 0x07D0;
    pub const ACT: u8 = 0x01;
    pub const GTO: u8 = 0x08;
    pub const FAULT_NO_COMM: u8 = 0x09;
    pub const FAULT_OVERCURRENT: u8 = 0x0E;

    /// The six status bytes (three registers, big-endian).
    #[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
    pub struct Status {
        pub act: bool,
        pub gto: bool,
        /// gSTA: 0 reset, 1 activating, 3 activated.
        pub sta: u8,
        /// gOBJ: 0 moving, 1 stopped on an object opening, 2 closing, 3 at the position.
        pub obj: u8,
        /// gFLT (low nibble of the fault byte).
        pub flt: u8,
        /// gPR, gPO, gCU.
        pub pr: u8,
        pub po: u8,
        pub cu: u8,
    }

    impl Status {
        pub fn from_regs(r: &[u16]) -> Option<Status> {
            let (&r0, &r1, &r2) = (r.first()?, r.get(1)?, r.get(2)?);
            let b0 = (r0 >> 8) as u8;
            Some(Status {
                act: b0 & 0x01 != 0,
                gto: b0 & 0x08 != 0,
                sta: (b0 >> 4) & 0x03,
                obj: (b0 >> 6) & 0x03,
                flt: ((r1 >> 8) as u8) & 0x0F,
                pr: r1 as u8,
                po: (r2 >> 8) as u8,
                cu: r2 as u8,
            })
        }
        pub fn to_regs(&self) -> [u16; 3] {
            let b0 = u8::from(self.act)
                | (u8::from(self.gto) << 3)
                | ((self.sta & 3) << 4)
                | ((self.obj & 3) << 6);
            [
                u16::from(b0) << 8,
                (u16::from(self.flt) << 8) | u16::from(self.pr),
                (u16::from(self.po) << 8) | u16::from(self.cu),
            ]
        }
    }

    /// The three command registers: action byte, reserved, reserved, rPR, rSP, rFR.
    pub fn command_regs(action: u8, pr: u8, sp: u8, fr: u8) -> Vec<u16> {
        vec![
            u16::from(action) << 8,
            u16::from(pr),
            (u16::from(sp) << 8) | u16::from(fr),
        ]
    }

    pub fn fault_text(code: u8) -> &'static str {
        match code {
            0x05 => "action delayed: activation must complete first",
            0x07 => "the activation bit must be set before an action",
            0x08 => "maximum operating temperature exceeded, wait for cool-down",
            0x09 => "no communication for at least 1 s",
            0x0A => "under minimum operating voltage",
            0x0B => "automatic release in progress",
            0x0C => "internal fault",
            0x0D => "activation fault: check for interference",
            0x0E => "overcurrent triggered",
            0x0F => "automatic release completed",
            _ => "unknown fault",
        }
    }
}

/// DH Robotics AG/PGE registers.
pub mod dh {
    pub const INIT: u16 = 0x0100;
    pub const FORCE: u16 = 0x0101;
    pub const POSITION: u16 = 0x0103;
    pub const SPEED: u16 = 0x0104;
    pub const INIT_STATE: u16 = 0x0200;
    pub const GRIP_STATE: u16 = 0x0201;
    pub const POSITION_NOW: u16 = 0x0202;
    /// Value written to INIT to (re)initialise.
    pub const INIT_FULL: u16 = 0xA5;
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Phase {
    /// Read the status before anything else.
    Probe,
    /// Normal cycles.
    Run,
    /// Robotiq fault reset: rACT = 0 was written; rACT = 1 comes next.
    ResetLow,
}

/// One family's protocol state.
#[derive(Debug, Clone)]
pub struct Session {
    model: Model,
    cal: Calibration,
    phase: Phase,
    /// Sequence number of the command the device has acknowledged, and of the one in flight.
    written: Option<u64>,
    in_flight: Option<u64>,
    /// DH: a write went out last cycle, read the status now.
    read_next: bool,
    /// DH: raw values acknowledged (force, speed, position).
    dh_written: [Option<u16>; 3],
    /// The device was seen holding an object, for "dropped".
    was_caught: bool,
    activating: bool,
}

impl Session {
    pub fn new(model: Model) -> Self {
        Self::with_calibration(model, model.calibration())
    }

    /// A session with a unit's own calibration (see the README's checklist).
    pub fn with_calibration(model: Model, cal: Calibration) -> Self {
        Self {
            model,
            cal,
            phase: Phase::Probe,
            written: None,
            in_flight: None,
            read_next: false,
            dh_written: [None; 3],
            was_caught: false,
            activating: false,
        }
    }

    pub fn model(&self) -> Model {
        self.model
    }

    /// Start over with a status read (after the port was re-opened).
    pub fn reset(&mut self) {
        *self = Session::with_calibration(self.model, self.cal);
    }

    /// The next request.
    pub fn next_request(&mut self, wants: &Wants, state: &GripperState) -> Request {
        match self.model.family() {
            Family::Robotiq => self.robotiq_next(wants, state),
            Family::Dh => self.dh_next(wants, state),
        }
    }

    fn status_read(&self) -> Request {
        match self.model.family() {
            Family::Robotiq => Request::ReadInput {
                addr: robotiq::STATUS,
                qty: 3,
            },
            Family::Dh => Request::ReadHolding {
                addr: dh::INIT_STATE,
                qty: 3,
            },
        }
    }

    fn robotiq_next(&mut self, wants: &Wants, state: &GripperState) -> Request {
        let rw = |values| Request::ReadWrite {
            read_addr: robotiq::STATUS,
            read_qty: 3,
            write_addr: robotiq::CMD,
            values,
        };
        match self.phase {
            Phase::Probe => self.status_read(),
            Phase::ResetLow => rw(robotiq::command_regs(robotiq::ACT, 0, 0, 0)),
            Phase::Run => {
                let major = matches!(state.fault, Some(Fault::Major { .. }));
                if major && wants.clear_fault {
                    // The only rACT = 0 this driver ever writes: a major fault needs a rising edge.
                    return rw(robotiq::command_regs(0, 0, 0, 0));
                }
                match state.activation {
                    Activation::Inactive if wants.activate || wants.clear_fault => {
                        rw(robotiq::command_regs(robotiq::ACT, 0, 0, 0))
                    }
                    Activation::Active if !major => match wants.command {
                        Some((seq, cmd)) if self.written != Some(seq) => {
                            self.in_flight = Some(seq);
                            let c = &self.cal;
                            rw(robotiq::command_regs(
                                robotiq::ACT | robotiq::GTO,
                                c.position.to_raw(cmd.opening_m) as u8,
                                c.speed.to_raw(cmd.speed_m_s) as u8,
                                c.force.to_raw(cmd.force_n) as u8,
                            ))
                        }
                        _ => self.status_read(),
                    },
                    _ => self.status_read(),
                }
            }
        }
    }

    fn dh_next(&mut self, wants: &Wants, state: &GripperState) -> Request {
        if self.phase == Phase::Probe {
            return self.status_read();
        }
        match state.activation {
            Activation::Inactive if (wants.activate || wants.clear_fault) && !self.activating => {
                Request::WriteSingle {
                    addr: dh::INIT,
                    value: dh::INIT_FULL,
                }
            }
            Activation::Active => {
                // One write per cycle (force, speed, then position), a status read between.
                let Some((_, cmd)) = wants.command else {
                    return self.status_read();
                };
                if self.read_next {
                    self.read_next = false;
                    return self.status_read();
                }
                let c = &self.cal;
                let raw = [
                    (dh::FORCE, c.force.to_raw(cmd.force_n)),
                    (dh::SPEED, c.speed.to_raw(cmd.speed_m_s)),
                    (dh::POSITION, c.position.to_raw(cmd.opening_m)),
                ];
                for (i, (addr, value)) in raw.into_iter().enumerate() {
                    if self.dh_written[i] != Some(value) {
                        return Request::WriteSingle { addr, value };
                    }
                }
                self.status_read()
            }
            _ => self.status_read(),
        }
    }

    /// Take the reply to `req`; clears the one-shot wants it fulfilled.
    pub fn on_reply(
        &mut self,
        req: &Request,
        resp: &Response,
        wants: &mut Wants,
        state: &mut GripperState,
    ) {
        match self.model.family() {
            Family::Robotiq => self.robotiq_reply(req, resp, wants, state),
            Family::Dh => self.dh_reply(req, resp, wants, state),
        }
    }

    fn robotiq_reply(
        &mut self,
        req: &Request,
        resp: &Response,
        wants: &mut Wants,
        state: &mut GripperState,
    ) {
        if let Request::ReadWrite { values, .. } = req {
            let action = values.first().map_or(0, |v| (v >> 8) as u8);
            if action & robotiq::ACT == 0 {
                self.phase = Phase::ResetLow;
            } else if self.phase == Phase::ResetLow || action & robotiq::GTO == 0 {
                // rACT rising edge written: activation under way.
                self.phase = Phase::Run;
                wants.activate = false;
                wants.clear_fault = false;
                self.written = None;
                self.activating = true;
            } else {
                self.written = self.in_flight;
                self.was_caught = false;
            }
        }
        let Response::Registers(r) = resp else {
            return;
        };
        let Some(s) = robotiq::Status::from_regs(r) else {
            return;
        };
        if self.phase == Phase::Probe {
            self.phase = Phase::Run;
        }
        let c = &self.cal;
        state.activation = match (s.act, s.sta) {
            (false, _) if !self.activating => Activation::Inactive,
            (_, 3) => Activation::Active,
            _ => Activation::Activating,
        };
        if s.sta == 3 {
            self.activating = false;
        }
        state.motion = match (s.gto, s.obj) {
            (false, _) => Motion::Idle,
            (true, 0) => Motion::Moving,
            (true, 1) => Motion::CaughtOpening,
            (true, 2) => Motion::Caught,
            _ if self.was_caught => Motion::Dropped,
            _ => Motion::Reached,
        };
        self.was_caught = match state.motion {
            Motion::Caught | Motion::CaughtOpening | Motion::Dropped => true,
            Motion::Moving | Motion::Idle => false,
            _ => self.was_caught,
        };
        let (opening, po_out) = c.position.to_si_clamped(f64::from(s.po));
        let (target, pr_out) = c.position.to_si_clamped(f64::from(s.pr));
        state.opening_m = Some(opening);
        state.raw_position = Some(u16::from(s.po));
        state.target_m = Some(target);
        state.out_of_range = out_of_range(
            &c.position,
            &[("gPO", s.po.into(), po_out), ("gPR", s.pr.into(), pr_out)],
        );
        state.current_a = Some(f64::from(s.cu) * 0.01);
        state.force_n = None;
        state.fault = match s.flt {
            0 => None,
            code @ 0x0A.. => Some(Fault::Major {
                code,
                what: robotiq::fault_text(code).into(),
            }),
            code => Some(Fault::Minor {
                code,
                what: robotiq::fault_text(code).into(),
            }),
        };
        if state.fault.is_none() && state.activation == Activation::Active {
            wants.clear_fault = false;
        }
    }

    fn dh_reply(
        &mut self,
        req: &Request,
        resp: &Response,
        wants: &mut Wants,
        state: &mut GripperState,
    ) {
        match (req, resp) {
            (Request::WriteSingle { addr, value }, Response::WriteSingle { .. }) => {
                match *addr {
                    dh::INIT => {
                        wants.activate = false;
                        wants.clear_fault = false;
                        self.activating = true;
                        self.dh_written = [None; 3];
                        state.activation = Activation::Activating;
                    }
                    dh::FORCE => self.dh_written[0] = Some(*value),
                    dh::SPEED => self.dh_written[1] = Some(*value),
                    dh::POSITION => self.dh_written[2] = Some(*value),
                    _ => {}
                }
                self.read_next = true;
            }
            (Request::ReadHolding { .. }, Response::Registers(r)) if r.len() >= 3 => {
                self.phase = Phase::Run;
                let (init, grip, pos) = (r[0], r[1], r[2]);
                state.activation = match init {
                    1 => {
                        self.activating = false;
                        Activation::Active
                    }
                    _ if self.activating => Activation::Activating,
                    _ => Activation::Inactive,
                };
                state.motion = match grip {
                    0 => Motion::Moving,
                    1 => Motion::Reached,
                    2 => Motion::Caught,
                    3 => Motion::Dropped,
                    _ => Motion::Unknown,
                };
                let (opening, out) = self.cal.position.to_si_clamped(f64::from(pos));
                state.opening_m = Some(opening);
                state.raw_position = Some(pos);
                state.target_m = self.dh_written[2].map(|v| self.cal.position.to_si(f64::from(v)));
                state.out_of_range = out_of_range(&self.cal.position, &[("position", pos, out)]);
                state.fault = None;
            }
            _ => {}
        }
    }
}

/// The note for raw positions outside the calibration (`(what, raw, outside)`), None if none is.
fn out_of_range(cal: &Linear, raws: &[(&str, u16, bool)]) -> Option<String> {
    let (lo, hi) = (cal.raw_a.min(cal.raw_b), cal.raw_a.max(cal.raw_b));
    let bad: Vec<String> = raws
        .iter()
        .filter(|(_, _, out)| *out)
        .map(|(what, raw, _)| format!("{what} {raw}"))
        .collect();
    (!bad.is_empty()).then(|| {
        format!(
            "{} outside the calibrated raw range {lo}..{hi}, read as the nearest end of the stroke: \
             check the calibration's raw ends (README, hardware checklist)",
            bad.join(", ")
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn robotiq_status_bytes_roundtrip() {
        let s = robotiq::Status {
            act: true,
            gto: true,
            sta: 3,
            obj: 2,
            flt: 0x0E,
            pr: 200,
            po: 150,
            cu: 33,
        };
        assert_eq!(robotiq::Status::from_regs(&s.to_regs()), Some(s));
        // gACT=1, gGTO=1, gSTA=3, gOBJ=3 is 0xF9 in the first byte (Robotiq manual example).
        let done = robotiq::Status {
            obj: 3,
            flt: 0,
            ..s
        };
        assert_eq!(done.to_regs()[0] >> 8, 0xF9);
    }

    #[test]
    fn a_raw_position_beyond_the_calibration_is_clamped_and_flagged() {
        // gPO 230 with fully closed calibrated at 227 read as an opening of -1.12 mm.
        let mut s = Session::new(Model::named("robotiq_2f85").unwrap());
        let mut wants = Wants::default();
        let mut st = GripperState::default();
        let r = s.next_request(&wants, &st);
        let past = robotiq::Status {
            act: true,
            gto: true,
            sta: 3,
            obj: 3,
            pr: 255,
            po: 230,
            ..Default::default()
        };
        s.on_reply(
            &r,
            &Response::Registers(past.to_regs().to_vec()),
            &mut wants,
            &mut st,
        );
        assert_eq!(st.opening_m, Some(0.0));
        assert_eq!(st.target_m, Some(0.0));
        assert_eq!(st.raw_position, Some(230));
        let note = st.out_of_range.clone().unwrap();
        assert!(note.starts_with("gPO 230, gPR 255 outside"), "{note}");
        // Back in range: the flag goes.
        let ok = robotiq::Status {
            pr: 200,
            po: 100,
            ..past
        };
        s.on_reply(
            &r,
            &Response::Registers(ok.to_regs().to_vec()),
            &mut wants,
            &mut st,
        );
        assert!(
            st.opening_m.unwrap() > 0.0 && st.out_of_range.is_none(),
            "{st:?}"
        );
    }

    #[test]
    fn start_reads_first_and_writes_nothing_to_an_active_gripper() {
        let mut s = Session::new(Model::named("robotiq_2f85").unwrap());
        let mut wants = Wants {
            activate: true,
            ..Wants::default()
        };
        let mut st = GripperState::default();
        let r = s.next_request(&wants, &st);
        assert!(matches!(r, Request::ReadInput { .. }));
        let active = robotiq::Status {
            act: true,
            gto: true,
            sta: 3,
            obj: 2,
            pr: 227,
            po: 120,
            ..Default::default()
        };
        s.on_reply(
            &r,
            &Response::Registers(active.to_regs().to_vec()),
            &mut wants,
            &mut st,
        );
        assert_eq!(st.activation, Activation::Active);
        assert_eq!(st.motion, Motion::Caught);
        // Activation was asked for but the gripper is active: still only reads.
        for _ in 0..3 {
            assert!(matches!(
                s.next_request(&wants, &st),
                Request::ReadInput { .. }
            ));
        }
    }
}
