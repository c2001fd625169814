//! Simulated serial grippers: a Robotiq 2F or DH AG/PGE controller speaking Modbus RTU on the
//! master side of a pseudo-terminal pair, so the real driver opens the slave side by its path
//! exactly as it opens /dev/ttyUSB0.
//!
//! A pty moves bytes instantly; the device paces itself at the configured baud rate (8N1, 10 bits
//! a character): a request counts as received one request-length after it arrived (no earlier
//! than 3.5 characters after the previous reply ended), the reply starts 3.5 characters later and
//! is released in two pieces, each when its last byte would have been on the wire. Faults are
//! injected per reply.

pub mod link;
pub mod physics;
pub mod registers;
pub mod relay;

use physics::{Kinematic, Physics, SimObject};
use registers::{Registers, Snapshot};
use serialport::{SerialPort, TTYPort};
use std::io::{self, Read, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};
use unitac_gripper::frame::{Decoder, Direction, FrameError, Request, Response};
use unitac_gripper::model::Model;

/// Settings of a simulated device.
#[derive(Debug, Clone, PartialEq)]
pub struct DeviceConfig {
    pub model: Model,
    pub slave: u8,
    pub baud: u32,
    /// Pace replies at `baud` (false: as fast as the pty goes).
    pub paced: bool,
    /// Busy-wait the last stretch of each pacing deadline (precise; costs a core: benchmarks).
    pub spin: bool,
    pub activation_s: f64,
    /// Start activated (a gripper that was running before the driver started).
    pub start_active: bool,
    pub object: Option<SimObject>,
    /// A symlink to (re)point at the pty (a stand-in for a /dev/serial/by-id name). Placed only
    /// where nothing is, or over a stale simulator link ([`link`]); removed when the device stops.
    pub link: Option<PathBuf>,
}

impl DeviceConfig {
    pub fn new(model: Model) -> Self {
        Self {
            model,
            slave: model.default_slave(),
            baud: model.default_baud(),
            paced: true,
            spin: false,
            activation_s: 0.3,
            start_active: false,
            object: None,
            link: None,
        }
    }
}

/// Faults injected into the next replies (counters go down as they are used).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Faults {
    /// Stay silent for the next n requests.
    pub no_reply: u32,
    /// Send only the first half of the next n replies.
    pub half_frame: u32,
    /// Flip the CRC of the next n replies.
    pub corrupt_crc: u32,
    /// Answer the next n requests with another slave id.
    pub wrong_slave: u32,
    /// Garbage bytes sent before each of the next n replies.
    pub garbage_before: u32,
    /// Extra latency before every reply (a slow device).
    pub delay: Duration,
    /// Answer nothing at all until cleared.
    pub mute: bool,
}

#[derive(Debug, Default)]
struct Shared {
    faults: Mutex<Faults>,
    snap: Mutex<Snapshot>,
    overcurrent: AtomicBool,
    overcurrent_persists: AtomicBool,
    unplugged: AtomicBool,
    stop: AtomicBool,
    path: Mutex<PathBuf>,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

/// A running simulated device.
#[derive(Debug)]
pub struct SimDevice {
    shared: Arc<Shared>,
    link: Option<PathBuf>,
    thread: Option<JoinHandle<()>>,
}

impl SimDevice {
    /// Start a device with the built-in kinematic finger model.
    pub fn spawn(cfg: DeviceConfig) -> io::Result<Self> {
        let max = cfg.model.calibration().limits.max_opening_m;
        let phys = Box::new(Kinematic::new(max, cfg.object));
        Self::spawn_with(cfg, phys)
    }

    /// Start a device whose fingers are `physics` (e.g. the sim world's gripper).
    pub fn spawn_with(cfg: DeviceConfig, physics: Box<dyn Physics>) -> io::Result<Self> {
        let regs = registers::for_model(cfg.model, physics, cfg.activation_s, cfg.start_active);
        let shared = Arc::new(Shared::default());
        let pty = Pty::open(&cfg.link)?;
        *lock(&shared.path) = pty.path.clone();
        let link = cfg.link.clone();
        let s = shared.clone();
        let pty_path = pty.path.clone();
        let thread = match std::thread::Builder::new()
            .name("sim-gripper".into())
            .spawn(move || serve(cfg, regs, pty, s))
        {
            Ok(t) => t,
            Err(e) => {
                // A failed start leaves nothing behind.
                if let Some(l) = &link {
                    link::remove(l, &pty_path);
                }
                return Err(e);
            }
        };
        Ok(Self {
            shared,
            link,
            thread: Some(thread),
        })
    }

    /// The path the driver opens: the link when there is one, else the pty's slave path.
    pub fn path(&self) -> PathBuf {
        self.link
            .clone()
            .unwrap_or_else(|| lock(&self.shared.path).clone())
    }

    pub fn snapshot(&self) -> Snapshot {
        *lock(&self.shared.snap)
    }

    /// Change the injected faults.
    pub fn faults(&self, f: impl FnOnce(&mut Faults)) {
        f(&mut lock(&self.shared.faults));
    }

    /// Trip the overcurrent protection (Robotiq: major fault 0x0E).
    pub fn overcurrent(&self) {
        self.shared.overcurrent.store(true, Ordering::Relaxed);
    }

    /// A persistent overcurrent (a finger blocked, a motor fault): while `on`, the device trips
    /// Robotiq's major fault 0x0E again as soon as it is active without a fault, so every
    /// re-activation ends in the fault.
    pub fn overcurrent_persists(&self, on: bool) {
        self.shared
            .overcurrent_persists
            .store(on, Ordering::Relaxed);
    }

    /// Pull the USB adapter: the pty closes (the driver's port hangs up) and the link goes.
    pub fn unplug(&self) {
        self.shared.unplugged.store(true, Ordering::Relaxed);
    }

    /// Plug it back: a new pty (another /dev/pts/N), the link re-pointed at it.
    pub fn replug(&self) {
        self.shared.unplugged.store(false, Ordering::Relaxed);
    }

    /// Stop serving and remove the link (if it is still the one this device placed).
    pub fn stop(&mut self) {
        self.shared.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
            if let Some(l) = &self.link {
                link::remove(l, &lock(&self.shared.path));
            }
        }
    }
}

impl Drop for SimDevice {
    fn drop(&mut self) {
        self.stop();
    }
}

/// Both ends of a pseudo-terminal: the device talks on the master; it keeps its own slave handle
/// open so the pty stays up between driver opens.
struct Pty {
    master: TTYPort,
    _slave: TTYPort,
    path: PathBuf,
}

impl Pty {
    fn open(at: &Option<PathBuf>) -> io::Result<Pty> {
        let (mut master, slave) = TTYPort::pair().map_err(io::Error::other)?;
        master
            .set_timeout(Duration::from_millis(1))
            .map_err(io::Error::other)?;
        let path = slave
            .name()
            .map(PathBuf::from)
            .ok_or_else(|| io::Error::other("pty without a name"))?;
        if let Some(l) = at {
            link::place(l, &path)?;
        }
        Ok(Pty {
            master,
            _slave: slave,
            path,
        })
    }
}

/// Sleep until `t`; with `spin`, busy-wait the last 200 us for precision.
fn sleep_until(t: Instant, spin: bool) {
    let margin = if spin {
        Duration::from_micros(200)
    } else {
        Duration::ZERO
    };
    loop {
        let now = Instant::now();
        if now >= t {
            return;
        }
        let left = t - now;
        if left > margin {
            std::thread::sleep(left - margin);
        } else {
            std::hint::spin_loop();
        }
    }
}

/// Write `bytes` so that they are complete when the wire would have carried them: the first half
/// at `start + len/2 x char_time`, the rest at `start + len x char_time` (two writes, so the driver
/// sees a frame arrive in pieces, as from a USB adapter, without a wake-up per byte).
fn send_paced(
    w: &mut impl Write,
    bytes: &[u8],
    start: Instant,
    char_time: Duration,
    spin: bool,
) -> io::Result<Instant> {
    let mut sent = 0usize;
    for end in [bytes.len() / 2, bytes.len()] {
        if end <= sent {
            continue;
        }
        sleep_until(start + char_time * end as u32, spin);
        w.write_all(&bytes[sent..end])?;
        sent = end;
    }
    Ok(start + char_time * bytes.len() as u32)
}

/// `reply` to `slave` as the injected faults make it, each one-shot fault used up (None: no
/// reply at all), and the delay before it.
fn faulted_reply(
    faults: &mut Faults,
    reply: &Response,
    slave: u8,
    function: u8,
) -> Option<(Vec<u8>, Duration)> {
    if faults.mute {
        return None;
    }
    if faults.no_reply > 0 {
        faults.no_reply -= 1;
        return None;
    }
    let mut to = slave;
    if faults.wrong_slave > 0 {
        faults.wrong_slave -= 1;
        to = slave.wrapping_add(1);
    }
    let mut bytes = reply.encode(to, function);
    if faults.corrupt_crc > 0 {
        faults.corrupt_crc -= 1;
        if let Some(b) = bytes.last_mut() {
            *b ^= 0xA5;
        }
    }
    if faults.half_frame > 0 {
        faults.half_frame -= 1;
        bytes.truncate(bytes.len() / 2);
    }
    if faults.garbage_before > 0 {
        faults.garbage_before -= 1;
        let mut g = vec![0xFF, 0x00, 0x17, slave, 0x99, 0x42, slave, 0x04];
        g.append(&mut bytes);
        bytes = g;
    }
    Some((bytes, faults.delay))
}

fn serve(cfg: DeviceConfig, mut regs: Box<dyn Registers>, pty: Pty, shared: Arc<Shared>) {
    let char_time = Duration::from_secs_f64(10.0 / f64::from(cfg.baud.max(1)));
    let silence = char_time.mul_f64(3.5);
    let mut pty = Some(pty);
    let mut dec = Decoder::new(Direction::Requests);
    let mut buf = [0u8; 512];
    let t0 = Instant::now();
    let mut last_tick = t0;
    let mut last_rx = t0;
    let mut last_tx_end = t0;
    let mut replug_at = t0;
    while !shared.stop.load(Ordering::Relaxed) {
        // Plug state.
        let unplugged = shared.unplugged.load(Ordering::Relaxed);
        if unplugged && pty.is_some() {
            pty = None;
            if let Some(l) = &cfg.link {
                link::remove(l, &lock(&shared.path));
            }
        } else if !unplugged && pty.is_none() && Instant::now() >= replug_at {
            match Pty::open(&cfg.link) {
                Ok(p) => {
                    *lock(&shared.path) = p.path.clone();
                    pty = Some(p);
                    dec.clear();
                }
                Err(e) => {
                    tracing::warn!("sim gripper: cannot re-create the pty: {e}");
                    replug_at = Instant::now() + Duration::from_millis(500);
                }
            }
        }
        let n = match pty.as_mut().map(|p| p.master.read(&mut buf)) {
            Some(Ok(n)) => n,
            Some(Err(e)) if e.kind() == io::ErrorKind::TimedOut => 0,
            // No driver has the slave open, or no pty: idle a little.
            _ => {
                std::thread::sleep(Duration::from_millis(1));
                0
            }
        };
        dec.push(&buf[..n]);
        let now = Instant::now();
        // Requests already waiting count as received now, before the communication watchdog is
        // checked: a real controller's watchdog runs on its own MCU, while this thread can be
        // starved on a loaded host with the driver's requests queued in the pty (a driver that
        // really went quiet sends nothing, and the fault comes as it should).
        let frames: Vec<_> = std::iter::from_fn(|| dec.next_frame()).collect();
        if frames.iter().any(|f| f.slave == cfg.slave) {
            last_rx = now;
        }
        if shared.overcurrent.swap(false, Ordering::Relaxed) {
            regs.overcurrent();
        }
        regs.tick(
            (now - last_tick).as_secs_f64(),
            (now - last_rx).as_secs_f64(),
        );
        if shared.overcurrent_persists.load(Ordering::Relaxed) {
            let s = regs.snapshot();
            if s.active && s.fault == 0 {
                regs.overcurrent();
            }
        }
        last_tick = now;
        for frame in frames {
            if frame.slave != cfg.slave {
                continue;
            }
            let adu_len = frame.data.len() + 4;
            last_rx = now;
            let (reply, function) = match Request::decode(&frame) {
                Ok(req) => (regs.handle(&req), req.function()),
                // A function no gripper serves, or a quantity out of range: the exception reply
                // a Modbus slave gives (illegal function, illegal data value).
                Err(e) => {
                    let code = match e {
                        FrameError::Function(_) => 0x01,
                        _ => 0x03,
                    };
                    let f = frame.function;
                    (Some(Response::Exception { function: f, code }), f)
                }
            };
            // Counted before the reply leaves: a driver that has the reply sees it counted.
            *lock(&shared.snap) = regs.snapshot();
            let Some(reply) = reply else { continue };
            let faulted = faulted_reply(&mut lock(&shared.faults), &reply, cfg.slave, function);
            let Some((bytes, delay)) = faulted else {
                continue;
            };
            let start = if cfg.paced {
                let rx_start = now.max(last_tx_end + silence);
                rx_start + char_time * adu_len as u32 + silence + delay
            } else {
                now + delay
            };
            let Some(p) = pty.as_mut() else { break };
            let sent = if cfg.paced {
                send_paced(&mut p.master, &bytes, start, char_time, cfg.spin)
            } else {
                sleep_until(start, cfg.spin);
                p.master.write_all(&bytes).map(|()| Instant::now())
            };
            match sent {
                Ok(end) => last_tx_end = end,
                Err(e) => tracing::debug!("sim gripper: write failed: {e}"),
            }
        }
        *lock(&shared.snap) = regs.snapshot();
    }
}

/// The path a device's pty currently has (for messages).
pub fn describe(path: &Path) -> String {
    match std::fs::read_link(path) {
        Ok(t) => format!("{} -> {}", path.display(), t.display()),
        Err(_) => path.display().to_string(),
    }
}
