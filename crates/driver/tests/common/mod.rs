//! A fake V4L2 world for the stream tests: a device that can vanish and come back, a clock that
//! moves only when told (or when the stream sleeps), control registers, open-handle counting.
#![allow(dead_code)]

use std::collections::BTreeMap;
use std::sync::{Arc, Mutex};
use std::time::Duration;
use unitac_core::Stamp;
use unitac_driver::capture::{CaptureDevice, DeviceError, Mode, RawBuffer};
use unitac_driver::decode::PixelFormat;
use unitac_driver::stream::{Backend, DriverClock, OpenedDevice};

/// Shared fake time: monotonic nanoseconds and the realtime - monotonic offset.
#[derive(Debug, Clone)]
pub struct FakeClock(pub Arc<Mutex<ClockState>>);

#[derive(Debug)]
pub struct ClockState {
    pub mono: Duration,
    pub real_offset_ns: i64,
    pub sleeps: Vec<Duration>,
}

impl FakeClock {
    pub fn new() -> Self {
        FakeClock(Arc::new(Mutex::new(ClockState {
            mono: Duration::from_secs(1000),
            real_offset_ns: 1_700_000_000_000_000_000,
            sleeps: Vec::new(),
        })))
    }
    pub fn advance(&self, d: Duration) {
        self.0.lock().unwrap().mono += d;
    }
    pub fn mono(&self) -> Duration {
        self.0.lock().unwrap().mono
    }
    pub fn offset(&self) -> i64 {
        self.0.lock().unwrap().real_offset_ns
    }
}

impl DriverClock for FakeClock {
    fn monotonic(&self) -> Duration {
        self.0.lock().unwrap().mono
    }
    fn realtime(&self) -> Stamp {
        let s = self.0.lock().unwrap();
        Stamp(s.mono.as_nanos() as i64 + s.real_offset_ns)
    }
    fn sleep(&self, d: Duration) {
        let mut s = self.0.lock().unwrap();
        s.mono += d;
        s.sleeps.push(d);
    }
}

/// What the next buffer looks like.
#[derive(Debug, Clone)]
pub enum Next {
    /// A good buffer captured `age` before it is read.
    Good {
        age: Duration,
    },
    /// A buffer captured before the stream started (left in the queue).
    Stale,
    /// Skip this many sequence numbers first (frames the driver lost).
    Skip(u32),
    /// These bytes instead of the image.
    Bytes(Vec<u8>),
    Timeout,
    /// A buffer with no timestamp.
    NoTimestamp,
}

#[derive(Debug)]
pub struct World {
    pub serial: String,
    pub firmware: Option<String>,
    pub present: bool,
    pub modes: Vec<Mode>,
    /// The image every good buffer carries.
    pub image: Vec<u8>,
    pub script: std::collections::VecDeque<Next>,
    pub opens: u64,
    pub open_attempts: Vec<Duration>,
    pub open_handles: i64,
    /// Control registers; reset to `defaults` on every plug (power cycle).
    pub controls: BTreeMap<u32, i64>,
    pub defaults: BTreeMap<u32, i64>,
    /// Control id -> value the device clamps writes to.
    pub clamp: BTreeMap<u32, i64>,
    pub control_writes: u64,
    pub frame_interval: Duration,
    /// Hold a real file descriptor per open device (to check the process's fd count).
    pub hold_fd: bool,
    /// The fake USB layer: a stalled device is present but its node delivers no buffers
    /// (every wait times out) until a USB reset.
    pub stalled: bool,
    /// USB resets asked for, and those asked while a node was still open (must stay 0).
    pub usb_resets: u64,
    pub resets_with_open_node: u64,
    /// Whether the backend can reset (a backend without USB access cannot).
    pub can_reset: bool,
    /// After a reset the device re-enumerates: this many open attempts find it gone.
    pub reenumerate_opens: u32,
    pub reenumerating: u32,
    /// Hotplug events: `None` = the backend has none (polling); else the queued arrivals.
    pub hotplug: Option<std::collections::VecDeque<()>>,
    pub hotplug_waits: u64,
}

impl World {
    pub fn new(serial: &str, mode: Mode, image: Vec<u8>) -> Arc<Mutex<World>> {
        Arc::new(Mutex::new(World {
            serial: serial.into(),
            firmware: Some("0200".into()),
            present: true,
            modes: vec![mode],
            image,
            script: Default::default(),
            opens: 0,
            open_attempts: Vec::new(),
            open_handles: 0,
            controls: BTreeMap::new(),
            defaults: BTreeMap::new(),
            clamp: BTreeMap::new(),
            control_writes: 0,
            frame_interval: Duration::from_millis(40),
            hold_fd: false,
            stalled: false,
            usb_resets: 0,
            resets_with_open_node: 0,
            can_reset: true,
            reenumerate_opens: 1,
            reenumerating: 0,
            hotplug: None,
            hotplug_waits: 0,
        }))
    }
}

pub struct FakeBackend {
    pub world: Arc<Mutex<World>>,
    pub clock: FakeClock,
}

impl Backend for FakeBackend {
    fn open(&mut self, serial: &str) -> Result<OpenedDevice, DeviceError> {
        let mut w = self.world.lock().unwrap();
        w.open_attempts.push(self.clock.mono());
        if !w.present || w.serial != serial {
            return Err(DeviceError::Gone(format!("no sensor {serial}")));
        }
        if w.reenumerating > 0 {
            w.reenumerating -= 1;
            if w.reenumerating == 0
                && let Some(q) = w.hotplug.as_mut()
            {
                q.push_back(());
            }
            return Err(DeviceError::Gone(format!("{serial} re-enumerating")));
        }
        w.opens += 1;
        w.open_handles += 1;
        w.controls = w.defaults.clone();
        let fd = if w.hold_fd {
            Some(std::fs::File::open("/dev/null").unwrap())
        } else {
            None
        };
        Ok(OpenedDevice {
            device: Box::new(FakeDevice {
                world: self.world.clone(),
                clock: self.clock.clone(),
                seq: 0,
                started_at: None,
                buf: Vec::new(),
                _fd: fd,
            }),
            firmware: w.firmware.clone(),
        })
    }

    fn reset_usb(&mut self, serial: &str) -> Result<(), DeviceError> {
        let mut w = self.world.lock().unwrap();
        if !w.can_reset {
            return Err(DeviceError::Unsupported("no USB access".into()));
        }
        if !w.present || w.serial != serial {
            return Err(DeviceError::Gone(format!("no sensor {serial}")));
        }
        if w.open_handles != 0 {
            w.resets_with_open_node += 1;
        }
        w.usb_resets += 1;
        // The software replug: the stall is gone, the device drops off the bus and comes back
        // power-cycled (controls at defaults).
        w.stalled = false;
        w.reenumerating = w.reenumerate_opens;
        w.controls = w.defaults.clone();
        Ok(())
    }

    fn wait_usb_event(&mut self, max: Duration) -> Option<bool> {
        let mut w = self.world.lock().unwrap();
        w.hotplug_waits += 1;
        let q = w.hotplug.as_mut()?;
        if q.pop_front().is_some() {
            drop(w);
            self.clock.advance(Duration::from_millis(1));
            return Some(true);
        }
        drop(w);
        self.clock.advance(max);
        Some(false)
    }
}

pub struct FakeDevice {
    world: Arc<Mutex<World>>,
    clock: FakeClock,
    seq: u32,
    started_at: Option<Duration>,
    buf: Vec<u8>,
    _fd: Option<std::fs::File>,
}

impl Drop for FakeDevice {
    fn drop(&mut self) {
        if let Ok(mut w) = self.world.lock() {
            w.open_handles -= 1;
        }
    }
}

impl CaptureDevice for FakeDevice {
    fn modes(&mut self) -> Result<Vec<Mode>, DeviceError> {
        Ok(self.world.lock().unwrap().modes.clone())
    }
    fn set_mode(&mut self, mode: &Mode) -> Result<Mode, DeviceError> {
        Ok(*mode)
    }
    fn start(&mut self) -> Result<(), DeviceError> {
        self.started_at = Some(self.clock.mono());
        Ok(())
    }
    fn next_buffer(&mut self, timeout: Duration) -> Result<RawBuffer<'_>, DeviceError> {
        let mut w = self.world.lock().unwrap();
        if !w.present {
            return Err(DeviceError::Gone("ENODEV".into()));
        }
        let started = self
            .started_at
            .ok_or(DeviceError::Io("not started".into()))?;
        if w.stalled {
            drop(w);
            self.clock.advance(timeout);
            return Err(DeviceError::Timeout(timeout));
        }
        let mut next = w.script.pop_front().unwrap_or(Next::Good {
            age: Duration::from_millis(5),
        });
        if let Next::Skip(n) = next {
            self.seq = self.seq.wrapping_add(n);
            next = Next::Good {
                age: Duration::from_millis(5),
            };
        }
        let interval = w.frame_interval;
        drop(w);
        self.clock.advance(interval);
        let now = self.clock.mono();
        let (data, ts) = match next {
            Next::Good { age } => (self.world.lock().unwrap().image.clone(), now - age),
            Next::Stale => (
                self.world.lock().unwrap().image.clone(),
                started - Duration::from_millis(500),
            ),
            Next::Bytes(b) => (b, now - Duration::from_millis(5)),
            Next::NoTimestamp => (self.world.lock().unwrap().image.clone(), Duration::ZERO),
            Next::Timeout => {
                self.clock.advance(timeout);
                return Err(DeviceError::Timeout(timeout));
            }
            Next::Skip(_) => unreachable!(),
        };
        self.buf = data;
        let seq = self.seq;
        self.seq = self.seq.wrapping_add(1);
        Ok(RawBuffer {
            data: &self.buf,
            sequence: seq,
            timestamp: ts,
        })
    }
    fn queue_len(&self) -> u32 {
        4
    }
    fn set_control(&mut self, id: u32, value: i64) -> Result<(), DeviceError> {
        let mut w = self.world.lock().unwrap();
        if !w.present {
            return Err(DeviceError::Gone("ENODEV".into()));
        }
        w.control_writes += 1;
        let v = w.clamp.get(&id).copied().unwrap_or(value);
        w.controls.insert(id, v);
        Ok(())
    }
    fn control(&mut self, id: u32) -> Result<i64, DeviceError> {
        let w = self.world.lock().unwrap();
        w.controls
            .get(&id)
            .copied()
            .ok_or_else(|| DeviceError::Unsupported(format!("no control {id:#x}")))
    }
}

/// A YUYV image of a gradient (so resize and rotation are visible), `width` even.
pub fn yuyv_gradient(width: u32, height: u32) -> Vec<u8> {
    let mut v = Vec::with_capacity((width * height * 2) as usize);
    for y in 0..height {
        for x in (0..width).step_by(2) {
            let l = (16 + (x * 200 / width) as u8).min(235);
            v.extend_from_slice(&[l, 128 + (y % 16) as u8, l, 128]);
        }
    }
    v
}

pub fn qvga_yuyv() -> Mode {
    Mode {
        format: PixelFormat::Yuyv,
        width: 320,
        height: 240,
        fps: 60.0,
    }
}
