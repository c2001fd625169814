//! Register maps of the simulated devices: what a Robotiq 2F or a DH AG/PGE controller does with
//! each request, on top of a [`Physics`] model of the fingers.
//!
//! Behaviour taken from the manuals: Robotiq's action/status bytes, activation (gSTA 1 -> 3),
//! gOBJ, major faults cleared only by an rACT rising edge, no exception replies; DH's init,
//! force/speed/position registers and grip states. Sim-model assumptions (not from a manual): the
//! activation takes `activation_s` and leaves the fingers open; fault 0x09 (no communication for
//! 1 s) is reported by reads and cleared by the next command write; the motor is off under a major
//! fault; the current reads 5 mA per newton.

use super::physics::{Drive, Fingers, Physics};
use crate::frame::{Request, Response};
use crate::model::{Calibration, Model};
use crate::protocol::{dh, robotiq};

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
        crate::model::Family::Robotiq => {
            Box::new(RobotiqRegs::new(model, physics, activation_s, start_active))
        }
        crate::model::Family::Dh => {
            Box::new(DhRegs::new(model, physics, activation_s, start_active))
        }
    }
}

struct RobotiqRegs {
    cal: Calibration,
    phys: Box<dyn Physics>,
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
        Self {
            cal,
            act: active,
            gto: false,
            pr: cal.position.to_raw(f.opening_m) as u8,
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

    fn write(&mut self, values: &[u16]) {
        let action = values.first().map_or(0, |v| (v >> 8) as u8);
        let act = action & robotiq::ACT != 0;
        if act && !self.act {
            // Rising edge: clears faults and (re)activates.
            self.flt = 0;
            self.sta = 1;
            self.activating_left = self.activation_s;
            self.snap.activations += 1;
        }
        if !act {
            self.snap.deactivations += 1;
            self.sta = 0;
            self.flt = 0;
        }
        self.act = act;
        self.gto = action & robotiq::GTO != 0;
        if let (Some(&r1), Some(&r2)) = (values.get(1), values.get(2)) {
            self.pr = r1 as u8;
            self.sp = (r2 >> 8) as u8;
            self.fr = r2 as u8;
        }
        if self.flt == robotiq::FAULT_NO_COMM {
            self.flt = 0;
        }
        if self.gto && !act {
            self.flt = 0x07;
        }
        if self.gto {
            self.obj = 0;
        }
    }
}

impl Registers for RobotiqRegs {
    fn handle(&mut self, req: &Request) -> Option<Response> {
        self.snap.requests += 1;
        let status = |s: &Self, qty: u16| {
            let r = s.status().to_regs();
            Response::Registers(r[..usize::from(qty).min(3)].to_vec())
        };
        let resp = match req {
            Request::ReadInput { addr, qty } | Request::ReadHolding { addr, qty }
                if *addr == robotiq::STATUS && *qty <= 3 =>
            {
                status(self, *qty)
            }
            Request::WriteMultiple { addr, values }
                if *addr == robotiq::CMD && values.len() <= 3 =>
            {
                self.write(values);
                Response::WriteMultiple {
                    addr: *addr,
                    qty: values.len() as u16,
                }
            }
            Request::ReadWrite {
                read_addr,
                read_qty,
                write_addr,
                values,
            } if *read_addr == robotiq::STATUS
                && *read_qty <= 3
                && *write_addr == robotiq::CMD
                && values.len() <= 3 =>
            {
                self.write(values);
                status(self, *read_qty)
            }
            // The Robotiq controller sends no exception responses.
            _ => return None,
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
            }
        }
        if self.act && self.sta == 3 && self.gto && !major {
            let target = c.position.to_si(f64::from(self.pr));
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
