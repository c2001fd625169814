//! Register maps of the simulated devices: what a Robotiq 2F or a DH AG/PGE controller does with
//! each request, on top of a [`Physics`] model of the fingers.
//!
//! Behaviour taken from the manuals: Robotiq's register map (the command block 0x03E8-0x03EA and
//! the status block 0x07D0-0x07D2, each readable and writable at any start and count inside it:
//! FC 0x03 / 0x04 reads, FC 0x06 / 0x10 writes, FC 0x17 both), its action/status bytes,
//! activation (gSTA 1 -> 3), gOBJ, major faults cleared only by an rACT rising edge; DH's init,
//! force/speed/position registers and grip states. Both answer a request they cannot serve with a
//! Modbus exception (0x01 illegal function, 0x02 illegal data address, 0x03 illegal data value),
//! as the Modbus specification has a slave do. Sim-model assumptions (not from a manual): the
//! activation takes `activation_s` and leaves the fingers open; gOBJ is 0 from a reset or an rACT
//! rising edge until the next motion ends; fault 0x09 (no communication for 1 s) is reported by
//! reads and cleared by the next command write; the motor is off under a major fault; the
//! current reads 5 mA per newton of grip force (0 with no object held).

use super::physics::{Drive, Fingers, Physics};
use unitac_gripper::frame::{Request, Response};
use unitac_gripper::model::{Calibration, Model};
use unitac_gripper::protocol::{dh, robotiq};

/// What a test can see of a simulated device.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Snapshot {
    pub active: bool,
    pub activating: bool,
    pub fingers: Fingers,
    /// Robotiq gFLT (0 for DH).
    pub fault: u8,
    /// Robotiq gOBJ, or DH grip state (0 moving, 1 arrived, 2 caught, 3 dropped).
    pub object: u8,
    /// Writes of rACT = 0 (Robotiq) or of the init register (DH) since start.
    pub deactivations: u64,
    pub activations: u64,
    pub requests: u64,
    pub replies: u64,
}

/// A device's registers and controller.
pub trait Registers: Send {
    /// Answer a request (None: the device stays silent).
    fn handle(&mut self, req: &Request) -> Option<Response>;
    /// Advance the controller and the fingers by `dt`; `since_rx` is the time since the last
    /// request addressed to this device.
    fn tick(&mut self, dt: f64, since_rx: f64);
    fn snapshot(&self) -> Snapshot;
    /// Trip the overcurrent protection (where the model has one).
    fn overcurrent(&mut self);
}

/// Build the registers of `model` over `physics`.
pub fn for_model(
    model: Model,
    physics: Box<dyn Physics>,
    activation_s: f64,
    start_active: bool,
) -> Box<dyn Registers> {
    match model.family() {
        unitac_gripper::model::Family::Robotiq => {
            Box::new(RobotiqRegs::new(model, physics, activation_s, start_active))
        }
        unitac_gripper::model::Family::Dh => {
            Box::new(DhRegs::new(model, physics, activation_s, start_active))
        }
    }
}

struct RobotiqRegs {
    cal: Calibration,
    phys: Box<dyn Physics>,
    /// The command block as last written (0x03E8: action byte, reserved; 0x03E9: reserved, rPR;
    /// 0x03EA: rSP, rFR).
    cmd: [u16; 3],
    act: bool,
    gto: bool,
    pr: u8,
    sp: u8,
    fr: u8,
    sta: u8,
    obj: u8,
    flt: u8,
    activation_s: f64,
    activating_left: f64,
    snap: Snapshot,
}

impl RobotiqRegs {
    fn new(model: Model, phys: Box<dyn Physics>, activation_s: f64, active: bool) -> Self {
        let cal = model.calibration();
        let f = phys.fingers();
        let pr = cal.position.to_raw(f.opening_m) as u8;
        Self {
            cal,
            cmd: [
                if active {
                    u16::from(robotiq::ACT) << 8
                } else {
                    0
                },
                u16::from(pr),
                (255 << 8) | 128,
            ],
            act: active,
            gto: false,
            pr,
            sp: 255,
            fr: 128,
            sta: if active { 3 } else { 0 },
            obj: 0,
            flt: 0,
            activation_s,
            activating_left: 0.0,
            snap: Snapshot::default(),
            phys,
        }
    }

    fn status(&self) -> robotiq::Status {
        let f = self.phys.fingers();
        robotiq::Status {
            act: self.act,
            gto: self.gto,
            sta: self.sta,
            obj: self.obj,
            flt: self.flt,
            pr: self.pr,
            po: self.cal.position.to_raw(f.opening_m).min(255) as u8,
            cu: (f.force_n * 0.5).round().clamp(0.0, 255.0) as u8,
        }
    }

    /// Write `values` into the command block from register `offset` (checked by the caller).
    fn write(&mut self, offset: usize, values: &[u16]) {
        for (r, v) in self.cmd.iter_mut().skip(offset).zip(values) {
            *r = *v;
        }
        if offset == 0 {
            let action = (self.cmd[0] >> 8) as u8;
            let act = action & robotiq::ACT != 0;
            if act && !self.act {
                // Rising edge: clears faults and (re)activates.
                self.flt = 0;
                self.sta = 1;
                self.obj = 0;
                self.activating_left = self.activation_s;
                self.snap.activations += 1;
            }
            if !act {
                self.snap.deactivations += 1;
                self.sta = 0;
                self.flt = 0;
                self.obj = 0;
            }
            self.act = act;
            self.gto = action & robotiq::GTO != 0;
        }
        self.pr = self.cmd[1] as u8;
        self.sp = (self.cmd[2] >> 8) as u8;
        self.fr = self.cmd[2] as u8;
        if self.flt == robotiq::FAULT_NO_COMM {
            self.flt = 0;
        }
        if self.gto && !self.act {
            self.flt = 0x07;
        }
        if self.gto {
            // A new motion: gOBJ says "moving" until it ends.
            self.obj = 0;
        }
    }

    /// Registers `addr .. addr + qty` of the status or the command block.
    fn read(&self, addr: u16, qty: u16) -> Result<Vec<u16>, u8> {
        if let Some(o) = in_block(robotiq::STATUS, addr, qty) {
            return Ok(self.status().to_regs()[o..o + usize::from(qty)].to_vec());
        }
        if let Some(o) = in_block(robotiq::CMD, addr, qty) {
            return Ok(self.cmd[o..o + usize::from(qty)].to_vec());
        }
        Err(ILLEGAL_ADDRESS)
    }
}

/// Registers in a Robotiq block.
const ROBOTIQ_BLOCK: u16 = 3;

/// The offset of `addr .. addr + qty` in the block starting at `start`, when it lies inside it.
fn in_block(start: u16, addr: u16, qty: u16) -> Option<usize> {
    let end = u32::from(addr) + u32::from(qty);
    (qty > 0 && addr >= start && end <= u32::from(start) + u32::from(ROBOTIQ_BLOCK))
        .then(|| usize::from(addr - start))
}

impl Registers for RobotiqRegs {
    fn handle(&mut self, req: &Request) -> Option<Response> {
        self.snap.requests += 1;
        let exc = |code| Response::Exception {
            function: req.function(),
            code,
        };
        let cmd_offset = |addr: u16, n: usize| {
            u16::try_from(n)
                .ok()
                .and_then(|n| in_block(robotiq::CMD, addr, n))
                .ok_or(ILLEGAL_ADDRESS)
        };
        let resp = match req {
            Request::ReadInput { addr, qty } | Request::ReadHolding { addr, qty } => {
                self.read(*addr, *qty).map_or_else(exc, Response::Registers)
            }
            Request::WriteSingle { addr, value } => match cmd_offset(*addr, 1) {
                Ok(o) => {
                    self.write(o, &[*value]);
                    Response::WriteSingle {
                        addr: *addr,
                        value: *value,
                    }
                }
                Err(code) => exc(code),
            },
            Request::WriteMultiple { addr, values } => match cmd_offset(*addr, values.len()) {
                Ok(o) => {
                    self.write(o, values);
                    Response::WriteMultiple {
                        addr: *addr,
                        qty: values.len() as u16,
                    }
                }
                Err(code) => exc(code),
            },
            Request::ReadWrite {
                read_addr,
                read_qty,
                write_addr,
                values,
            } => {
                // Both ranges are checked before anything is written.
                match (
                    cmd_offset(*write_addr, values.len()),
                    self.read(*read_addr, *read_qty),
                ) {
                    (Ok(o), Ok(_)) => {
                        self.write(o, values);
                        self.read(*read_addr, *read_qty)
                            .map_or_else(exc, Response::Registers)
                    }
                    (Err(code), _) | (_, Err(code)) => exc(code),
                }
            }
        };
        self.snap.replies += 1;
        Some(resp)
    }

    fn tick(&mut self, dt: f64, since_rx: f64) {
        let c = &self.cal;
        let major = self.flt >= 0x0A;
        let f = self.phys.fingers();
        let drive = if self.act && self.sta == 1 {
            Drive {
                enabled: true,
                target_m: c.limits.max_opening_m,
                speed_m_s: c.limits.max_speed_m_s,
                force_n: c.limits.min_force_n,
            }
        } else if self.act && self.sta == 3 && !major && self.gto {
            Drive {
                enabled: true,
                target_m: c.position.to_si(f64::from(self.pr)),
                speed_m_s: c.speed.to_si(f64::from(self.sp)),
                force_n: c.force.to_si(f64::from(self.fr)),
            }
        } else if self.act && self.sta == 3 && !major {
            Drive {
                enabled: true,
                target_m: f.opening_m,
                speed_m_s: 0.0,
                force_n: f.force_n.max(c.limits.min_force_n),
            }
        } else {
            Drive {
                enabled: false,
                target_m: f.opening_m,
                speed_m_s: 0.0,
                force_n: 0.0,
            }
        };
        let f = self.phys.step(dt, drive);
        if self.sta == 1 {
            self.activating_left -= dt;
            if self.activating_left <= 0.0 {
                self.sta = 3;
                self.pr = c.position.to_raw(f.opening_m) as u8;
                self.cmd[1] = (self.cmd[1] & 0xFF00) | u16::from(self.pr);
            }
        }
        if self.act && self.sta == 3 && self.gto && !major {
            // A request past the end of the stroke (rPR 255 on a 2F-85) is reached at the stop.
            let target = c
                .position
                .to_si(f64::from(self.pr))
                .clamp(0.0, c.limits.max_opening_m);
            let count = c.limits.max_opening_m / 255.0;
            // An object once detected stays detected until the next command (the force may
            // dip under the limit while the grip settles).
            self.obj = if f.stalled {
                if f.closing { 2 } else { 1 }
            } else if self.obj == 1 || self.obj == 2 {
                self.obj
            } else if (f.opening_m - target).abs() <= count {
                3
            } else {
                0
            };
        }
        if self.act && self.sta == 3 && self.flt == 0 && since_rx >= 1.0 {
            self.flt = robotiq::FAULT_NO_COMM;
        }
        self.snap.active = self.act && self.sta == 3;
        self.snap.activating = self.act && self.sta == 1;
        self.snap.fingers = f;
        self.snap.fault = self.flt;
        self.snap.object = self.obj;
    }

    fn snapshot(&self) -> Snapshot {
        self.snap
    }

    fn overcurrent(&mut self) {
        self.flt = robotiq::FAULT_OVERCURRENT;
    }
}

struct DhRegs {
    cal: Calibration,
    phys: Box<dyn Physics>,
    initialised: bool,
    init_left: Option<f64>,
    force_pct: u16,
    speed_pct: u16,
    position: u16,
    grip: u16,
    activation_s: f64,
    snap: Snapshot,
}

impl DhRegs {
    fn new(model: Model, phys: Box<dyn Physics>, activation_s: f64, active: bool) -> Self {
        let cal = model.calibration();
        let f = phys.fingers();
        Self {
            cal,
            initialised: active,
            init_left: None,
            force_pct: 30,
            speed_pct: 50,
            position: cal.position.to_raw(f.opening_m),
            grip: 1,
            activation_s,
            snap: Snapshot::default(),
            phys,
        }
    }

    fn read(&self, addr: u16) -> Option<u16> {
        let f = self.phys.fingers();
        Some(match addr {
            dh::INIT => 0,
            dh::FORCE => self.force_pct,
            0x0102 => 0,
            dh::POSITION => self.position,
            dh::SPEED => self.speed_pct,
            dh::INIT_STATE => u16::from(self.initialised),
            dh::GRIP_STATE => self.grip,
            dh::POSITION_NOW => self.cal.position.to_raw(f.opening_m),
            _ => return None,
        })
    }
}

/// Modbus exception codes.
const ILLEGAL_FUNCTION: u8 = 0x01;
const ILLEGAL_ADDRESS: u8 = 0x02;
const ILLEGAL_VALUE: u8 = 0x03;

impl Registers for DhRegs {
    fn handle(&mut self, req: &Request) -> Option<Response> {
        self.snap.requests += 1;
        let exc = |code| Response::Exception {
            function: req.function(),
            code,
        };
        let resp = match *req {
            Request::ReadHolding { addr, qty } => (0..qty)
                .map(|i| addr.checked_add(i).and_then(|a| self.read(a)))
                .collect::<Option<Vec<u16>>>()
                .map_or(exc(ILLEGAL_ADDRESS), Response::Registers),
            Request::WriteSingle { addr, value } => {
                let ok = match addr {
                    dh::INIT if value == 1 || value == dh::INIT_FULL => {
                        self.init_left = Some(self.activation_s);
                        self.initialised = false;
                        self.snap.deactivations += 1;
                        self.snap.activations += 1;
                        true
                    }
                    dh::FORCE if (20..=100).contains(&value) => {
                        self.force_pct = value;
                        true
                    }
                    dh::SPEED if (1..=100).contains(&value) => {
                        self.speed_pct = value;
                        true
                    }
                    dh::POSITION if value <= 1000 => {
                        self.position = value;
                        if self.initialised {
                            self.grip = 0;
                        }
                        true
                    }
                    dh::INIT | dh::FORCE | dh::SPEED | dh::POSITION => false,
                    _ => {
                        self.snap.replies += 1;
                        return Some(exc(ILLEGAL_ADDRESS));
                    }
                };
                if ok {
                    Response::WriteSingle { addr, value }
                } else {
                    exc(ILLEGAL_VALUE)
                }
            }
            _ => exc(ILLEGAL_FUNCTION),
        };
        self.snap.replies += 1;
        Some(resp)
    }

    fn tick(&mut self, dt: f64, _since_rx: f64) {
        let c = &self.cal;
        let f = self.phys.fingers();
        let drive = if self.init_left.is_some() {
            Drive {
                enabled: true,
                target_m: c.limits.max_opening_m,
                speed_m_s: c.limits.max_speed_m_s,
                force_n: c.limits.min_force_n,
            }
        } else if self.initialised {
            Drive {
                enabled: true,
                target_m: c.position.to_si(f64::from(self.position)),
                speed_m_s: c.speed.to_si(f64::from(self.speed_pct)),
                force_n: c.force.to_si(f64::from(self.force_pct)),
            }
        } else {
            Drive {
                enabled: false,
                target_m: f.opening_m,
                speed_m_s: 0.0,
                force_n: 0.0,
            }
        };
        let f = self.phys.step(dt, drive);
        if let Some(left) = self.init_left {
            let left = left - dt;
            if left <= 0.0 {
                self.init_left = None;
                self.initialised = true;
                self.position = c.position.to_raw(f.opening_m);
                self.grip = 1;
            } else {
                self.init_left = Some(left);
            }
        } else if self.initialised {
            let target = c.position.to_si(f64::from(self.position));
            self.grip = if f.stalled && f.closing {
                2
            } else if self.grip == 2 && !f.stalled {
                3
            } else if (f.opening_m - target).abs() <= c.limits.max_opening_m / 1000.0 {
                if self.grip == 3 { 3 } else { 1 }
            } else if self.grip == 3 {
                3
            } else {
                0
            };
        }
        self.snap.active = self.initialised;
        self.snap.activating = self.init_left.is_some();
        self.snap.fingers = f;
        self.snap.object = self.grip as u8;
    }

    fn snapshot(&self) -> Snapshot {
        self.snap
    }

    fn overcurrent(&mut self) {}
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::panic)]
    use super::*;
    use crate::device::physics::Kinematic;

    fn robotiq() -> Box<dyn Registers> {
        let m = Model::named("robotiq_2f85").unwrap();
        let max = m.calibration().limits.max_opening_m;
        for_model(m, Box::new(Kinematic::new(max, None)), 0.05, false)
    }

    fn run(r: &mut dyn Registers, seconds: f64) {
        for _ in 0..(seconds / 0.001) as usize {
            r.tick(0.001, 0.0);
        }
    }

    fn regs(resp: Option<Response>) -> Vec<u16> {
        match resp {
            Some(Response::Registers(v)) => v,
            other => panic!("{other:?}"),
        }
    }

    fn exception(resp: Option<Response>) -> u8 {
        match resp {
            Some(Response::Exception { code, .. }) => code,
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn robotiq_blocks_answer_any_start_and_count_inside_them() {
        let mut r = robotiq();
        // Activate with one FC 0x06 write of the action register.
        let w = r.handle(&Request::WriteSingle {
            addr: 0x03E8,
            value: 0x0900,
        });
        assert_eq!(
            w,
            Some(Response::WriteSingle {
                addr: 0x03E8,
                value: 0x0900
            })
        );
        run(r.as_mut(), 0.2);
        // Position, speed and force from 0x03E9 (FC 0x10, two registers), as pyRobotiqGripper
        // writes them.
        let w = r.handle(&Request::WriteMultiple {
            addr: 0x03E9,
            values: vec![0x00E6, 0xFF00],
        });
        assert_eq!(
            w,
            Some(Response::WriteMultiple {
                addr: 0x03E9,
                qty: 2
            })
        );
        // Every start and count inside the status block, by FC 0x03 and 0x04.
        let all = regs(r.handle(&Request::ReadInput {
            addr: 0x07D0,
            qty: 3,
        }));
        for addr in 0x07D0..0x07D3u16 {
            for qty in 1..=(0x07D3 - addr) {
                for req in [
                    Request::ReadInput { addr, qty },
                    Request::ReadHolding { addr, qty },
                ] {
                    let o = usize::from(addr - 0x07D0);
                    assert_eq!(
                        regs(r.handle(&req)),
                        all[o..o + usize::from(qty)],
                        "{req:?}"
                    );
                }
            }
        }
        // gPR echoes the request written at 0x03E9.
        assert_eq!(all[1] & 0xFF, 0xE6);
        // The command block reads back as written.
        assert_eq!(
            regs(r.handle(&Request::ReadHolding {
                addr: 0x03E9,
                qty: 2
            })),
            [0x00E6, 0xFF00]
        );
        // FC 0x17 writing at 0x03EA and reading from 0x07D1.
        let rw = regs(r.handle(&Request::ReadWrite {
            read_addr: 0x07D1,
            read_qty: 2,
            write_addr: 0x03EA,
            values: vec![0x8010],
        }));
        assert_eq!(rw.len(), 2);
        assert_eq!(
            regs(r.handle(&Request::ReadHolding {
                addr: 0x03EA,
                qty: 1
            })),
            [0x8010]
        );
    }

    #[test]
    fn robotiq_refuses_what_lies_outside_the_blocks_with_exceptions() {
        let mut r = robotiq();
        let bad_reads = [
            (0x07D2, 2),
            (0x07CF, 1),
            (0x03EA, 2),
            (0x0000, 3),
            (0xFFFF, 1),
        ];
        for (addr, qty) in bad_reads {
            assert_eq!(
                exception(r.handle(&Request::ReadInput { addr, qty })),
                ILLEGAL_ADDRESS
            );
        }
        assert_eq!(
            exception(r.handle(&Request::WriteMultiple {
                addr: 0x03E9,
                values: vec![1, 2, 3]
            })),
            ILLEGAL_ADDRESS
        );
        assert_eq!(
            exception(r.handle(&Request::WriteSingle {
                addr: 0x07D0,
                value: 1
            })),
            ILLEGAL_ADDRESS
        );
        // An FC 0x17 with a bad read range writes nothing.
        assert_eq!(
            exception(r.handle(&Request::ReadWrite {
                read_addr: 0x07D3,
                read_qty: 1,
                write_addr: 0x03E8,
                values: vec![0x0100],
            })),
            ILLEGAL_ADDRESS
        );
        run(r.as_mut(), 0.2);
        assert!(!r.snapshot().active && !r.snapshot().activating);
        assert_eq!(r.snapshot().activations, 0);
    }

    #[test]
    fn robotiq_reactivation_clears_the_object_and_a_full_close_is_reached_at_the_stop() {
        let m = Model::named("robotiq_2f85").unwrap();
        let obj = crate::device::physics::SimObject {
            width_m: 0.04,
            stiffness_n_per_m: 20_000.0,
        };
        let mut r = for_model(m, Box::new(Kinematic::new(0.085, Some(obj))), 0.05, false);
        let write = |r: &mut Box<dyn Registers>, v: Vec<u16>| {
            r.handle(&Request::WriteMultiple {
                addr: 0x03E8,
                values: v,
            })
        };
        write(&mut r, vec![0x0900, 0, 0xFF00]);
        run(r.as_mut(), 0.1);
        write(&mut r, vec![0x0900, 255, 0xFF00]);
        run(r.as_mut(), 1.0);
        assert_eq!(r.snapshot().object, 2, "{:?}", r.snapshot());
        // Reset, then rACT again: no catch reported from before.
        write(&mut r, vec![0, 0, 0]);
        run(r.as_mut(), 0.001);
        assert_eq!(r.snapshot().object, 0);
        write(&mut r, vec![0x0900, 0, 0]);
        run(r.as_mut(), 1.0);
        assert_eq!(r.snapshot().object, 3, "{:?}", r.snapshot());
        // Nothing between the fingers: rPR 255 ends at the stop, reached (gOBJ 3).
        let mut r = robotiq();
        write(&mut r, vec![0x0900, 0, 0xFF00]);
        run(r.as_mut(), 0.1);
        write(&mut r, vec![0x0900, 255, 0xFF00]);
        run(r.as_mut(), 1.0);
        let st = regs(r.handle(&Request::ReadInput {
            addr: 0x07D0,
            qty: 3,
        }));
        assert_eq!(st[0] >> 14, 3, "gOBJ: {st:04X?}");
        assert_eq!(st[2] >> 8, 227, "gPO at the stop: {st:04X?}");
        assert_eq!(st[2] & 0xFF, 0, "no current without an object: {st:04X?}");
    }
}
