//! The serial gripper: a [`Gripper`] whose Modbus I/O runs on its own thread at a fixed rate.
//!
//! The caller's methods only touch shared state under short locks, so a slow, silent or unplugged
//! device never blocks a control cycle. The thread opens the port by its stable name, probes the
//! status first ([`crate::protocol`]), and on a dead link (I/O error, or many failed exchanges in
//! a row) closes the port and re-opens it with a back-off until the adapter returns.

use crate::client::{ClientConfig, LinkStats, RtuClient};
use crate::gripper::{Fault, Gripper, GripperError, GripperSetpoint, GripperState, Limits};
use crate::model::{Calibration, Model};
use crate::port::{self, BY_ID};
use crate::protocol::{Session, Wants};
use serde::Serialize;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// Settings of a serial gripper.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DriverConfig {
    pub port: PathBuf,
    pub model: Model,
    pub slave: u8,
    pub baud: u32,
    /// Exchanges per second (Robotiq's manual: at most 200, >= 5 ms apart).
    pub rate_hz: f64,
    pub timeout: Duration,
    pub retries: u8,
    /// Failed exchanges in a row after which the port is closed and re-opened.
    pub reopen_after: u32,
    /// Directory of stable device names.
    pub by_id_dir: PathBuf,
    /// Raw <-> SI maps and limits (default: the model's; a unit's own after calibration).
    pub calibration: Calibration,
}

impl DriverConfig {
    pub fn new(port: impl Into<PathBuf>, model: Model) -> Self {
        Self {
            port: port.into(),
            model,
            slave: model.default_slave(),
            baud: model.default_baud(),
            rate_hz: 100.0,
            timeout: Duration::from_millis(30),
            retries: 1,
            reopen_after: 20,
            by_id_dir: PathBuf::from(BY_ID),
            calibration: model.calibration(),
        }
    }
}

/// Link health, for diagnostics.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct DriverStats {
    /// The port the driver opens (the stable name when there is one).
    pub port: PathBuf,
    pub connected: bool,
    pub opens: u64,
    pub cycles: u64,
    pub consecutive_failures: u32,
    pub last_error: Option<String>,
    pub link: LinkStats,
    /// Exchange rate over the last second \[Hz].
    pub rate_hz: f64,
    pub rtt_p50_s: Option<f64>,
    pub rtt_p99_s: Option<f64>,
    /// Commands that asked for more than the model can do (or less: a speed or force below its
    /// minimum) and were clamped to its limits, and the last such change.
    pub clamped_commands: u64,
    pub last_clamp: Option<String>,
}

#[derive(Debug, Default)]
struct Shared {
    wants: Mutex<Wants>,
    state: Mutex<GripperState>,
    stats: Mutex<DriverStats>,
    stop: AtomicBool,
    seq: Mutex<u64>,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    // A panic elsewhere cannot leave these plain values half-written; keep going.
    m.lock().unwrap_or_else(|p| p.into_inner())
}

/// A serial gripper (Robotiq 2F, DH AG/PGE) driven by a background thread.
#[derive(Debug)]
pub struct SerialGripper {
    cfg: DriverConfig,
    shared: Arc<Shared>,
    thread: Option<JoinHandle<()>>,
}

impl SerialGripper {
    /// Start the driver thread. Opening the port happens there (and is retried), so this never
    /// fails on a missing device; see [`SerialGripper::stats`].
    pub fn start(cfg: DriverConfig) -> std::io::Result<Self> {
        let shared = Arc::new(Shared::default());
        let port = port::stable_path(&cfg.port, &cfg.by_id_dir);
        lock(&shared.stats).port = port.clone();
        let (c, s) = (cfg.clone(), shared.clone());
        let thread = std::thread::Builder::new()
            .name(format!("gripper-{}", cfg.model))
            .spawn(move || run(c, port, s))?;
        Ok(Self {
            cfg,
            shared,
            thread: Some(thread),
        })
    }

    pub fn config(&self) -> &DriverConfig {
        &self.cfg
    }

    pub fn stats(&self) -> DriverStats {
        lock(&self.shared.stats).clone()
    }

    /// Stop the thread (also done on drop). The gripper keeps its last command.
    pub fn stop(&mut self) {
        self.shared.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl Drop for SerialGripper {
    fn drop(&mut self) {
        self.stop();
    }
}

impl Gripper for SerialGripper {
    fn model(&self) -> &str {
        self.cfg.model.name()
    }
    fn limits(&self) -> Limits {
        self.cfg.calibration.limits
    }
    fn activate(&mut self) -> Result<(), GripperError> {
        self.alive()?;
        lock(&self.shared.wants).activate = true;
        Ok(())
    }
    fn command(&mut self, cmd: GripperSetpoint) -> Result<(), GripperError> {
        self.alive()?;
        let limits = self.limits();
        let asked = cmd;
        let cmd = limits.clamp(cmd)?;
        let what = Limits::clamped(&asked, &cmd);
        if what.any() {
            let said = clamp_text(&asked, &cmd, what);
            let mut st = lock(&self.shared.stats);
            // Said once per kind of change, then counted (a policy repeats its command).
            if st.last_clamp.as_deref() != Some(said.as_str()) {
                tracing::warn!(
                    "{}: command clamped to the model's limits: {said}",
                    self.cfg.model
                );
            }
            st.clamped_commands += 1;
            st.last_clamp = Some(said);
        }
        let seq = {
            let mut s = lock(&self.shared.seq);
            *s += 1;
            *s
        };
        lock(&self.shared.wants).command = Some((seq, cmd));
        Ok(())
    }
    fn state(&self) -> GripperState {
        lock(&self.shared.state).clone()
    }
    fn clear_fault(&mut self) -> Result<(), GripperError> {
        self.alive()?;
        if matches!(self.state().fault, Some(Fault::Major { .. })) {
            lock(&self.shared.wants).clear_fault = true;
        }
        Ok(())
    }
}

/// "speed 0.010 -> 0.030 m/s, ..." for the fields `what` names.
fn clamp_text(
    asked: &GripperSetpoint,
    done: &GripperSetpoint,
    what: crate::gripper::Clamped,
) -> String {
    let mut parts = Vec::new();
    if what.opening {
        parts.push(format!(
            "opening {:.4} -> {:.4} m",
            asked.opening_m, done.opening_m
        ));
    }
    if what.speed {
        parts.push(format!(
            "speed {:.3} -> {:.3} m/s",
            asked.speed_m_s, done.speed_m_s
        ));
    }
    if what.force {
        parts.push(format!(
            "force {:.1} -> {:.1} N",
            asked.force_n, done.force_n
        ));
    }
    parts.join(", ")
}

impl SerialGripper {
    fn alive(&self) -> Result<(), GripperError> {
        match &self.thread {
            Some(t) if !t.is_finished() => Ok(()),
            _ => Err(GripperError::Stopped(
                lock(&self.shared.stats)
                    .last_error
                    .clone()
                    .unwrap_or_else(|| "driver thread ended".into()),
            )),
        }
    }
}

/// Sleep until `until` unless asked to stop; false when asked to stop.
fn nap(shared: &Shared, until: Instant) -> bool {
    loop {
        if shared.stop.load(Ordering::Relaxed) {
            return false;
        }
        let now = Instant::now();
        if now >= until {
            return true;
        }
        std::thread::sleep((until - now).min(Duration::from_millis(20)));
    }
}

fn set_link_fault(shared: &Shared, what: String) {
    let mut st = lock(&shared.state);
    if !matches!(st.fault, Some(Fault::Major { .. })) {
        st.fault = Some(Fault::Link { what: what.clone() });
    }
    drop(st);
    lock(&shared.stats).last_error = Some(what);
}

fn run(cfg: DriverConfig, port: PathBuf, shared: Arc<Shared>) {
    let t_start = Instant::now();
    let ccfg = ClientConfig {
        slave: cfg.slave,
        timeout: cfg.timeout,
        retries: cfg.retries,
        baud: cfg.baud,
    };
    let period = if cfg.rate_hz > 0.0 && cfg.rate_hz.is_finite() {
        Duration::from_secs_f64(1.0 / cfg.rate_hz)
    } else {
        Duration::ZERO
    };
    let mut session = Session::with_calibration(cfg.model, cfg.calibration);
    let mut client: Option<RtuClient<Box<dyn serialport::SerialPort>>> = None;
    let mut backoff = Duration::from_millis(50);
    let mut next = Instant::now();
    let mut window: (Instant, u64) = (Instant::now(), 0);
    while !shared.stop.load(Ordering::Relaxed) {
        if client.is_none() {
            match port::open(&port, cfg.baud) {
                Ok(p) => {
                    client = Some(RtuClient::new(p, ccfg));
                    session.reset();
                    backoff = Duration::from_millis(50);
                    let mut s = lock(&shared.stats);
                    s.connected = true;
                    s.opens += 1;
                }
                Err(e) => {
                    set_link_fault(&shared, e.to_string());
                    lock(&shared.stats).connected = false;
                    if !nap(&shared, Instant::now() + backoff) {
                        break;
                    }
                    backoff = (backoff * 2).min(Duration::from_secs(1));
                }
            }
            continue;
        }
        let Some(c) = client.as_mut() else {
            continue;
        };
        let req = {
            let wants = lock(&shared.wants);
            let st = lock(&shared.state);
            session.next_request(&wants, &st)
        };
        let result = c.call(&req);
        let failed = match result {
            Ok(resp) => {
                let mut wants = lock(&shared.wants);
                let mut st = lock(&shared.state);
                if matches!(st.fault, Some(Fault::Link { .. })) {
                    st.fault = None;
                }
                session.on_reply(&req, &resp, &mut wants, &mut st);
                st.updates += 1;
                st.stamp_s = t_start.elapsed().as_secs_f64();
                None
            }
            Err(e) => Some(e),
        };
        {
            let mut s = lock(&shared.stats);
            s.cycles += 1;
            s.link = c.stats().clone();
            s.rtt_p50_s = s.link.rtt_percentile(0.5);
            s.rtt_p99_s = s.link.rtt_percentile(0.99);
            window.1 += 1;
            let dt = window.0.elapsed().as_secs_f64();
            if dt >= 1.0 {
                s.rate_hz = window.1 as f64 / dt;
                window = (Instant::now(), 0);
            }
            if failed.is_none() {
                s.consecutive_failures = 0;
            }
        }
        if let Some(e) = failed {
            let n = {
                let mut s = lock(&shared.stats);
                s.consecutive_failures += 1;
                s.consecutive_failures
            };
            let dead = e.is_link() || n >= cfg.reopen_after;
            tracing::debug!(error = %e, failures = n, "gripper exchange failed");
            set_link_fault(&shared, e.to_string());
            if dead {
                client = None;
                lock(&shared.stats).connected = false;
                if !nap(&shared, Instant::now() + backoff) {
                    break;
                }
                continue;
            }
        }
        next += period;
        let now = Instant::now();
        if next <= now {
            next = now;
        } else if !nap(&shared, next) {
            break;
        }
    }
}
