//! A sensor stream: open by serial, negotiate, set controls, capture, decode, and reconnect.
//!
//! [`SensorStream`] is the runtime's [`Source`] for a live sensor. It is written against two
//! traits so the whole state machine runs in tests without hardware: a [`Backend`] that opens a
//! [`CaptureDevice`] by serial, and a [`DriverClock`] (monotonic time, system time, sleep).
//!
//! States: `Opening` -> `Streaming` -> (device gone) `Lost` -> retry with exponential backoff ->
//! `Streaming` again, with the same sensor id, settings written again and the published sequence
//! going on. While the device is away, `next_frame` returns `SourceError::Unavailable` once per
//! `report_every` so the caller can log it and see its stop flag.
//!
//! A stalled stream (device present, no frame for `stall_after`: the GelSight Mini failure users
//! fix by pulling the cable) is recovered in software: the node is closed, the backend resets
//! the USB device (the software replug; [`Backend::reset_usb`]), and the stream re-opens it by
//! serial and writes the settings again, counted in `stalls` / `usb_resets` / `stall_recoveries`.
//! While lost, a backend with USB hotplug events ([`Backend::wait_usb_event`]) wakes the retry
//! as soon as a device arrives instead of waiting out the backoff.

use crate::calib::Calibration;
use crate::capture::{
    CaptureDevice, DeviceError, Mode, ModeRequest, SequenceTracker, StaleFlush, TimeMapper,
    choose_mode,
};
use crate::controls::{ControlMismatch, apply_and_verify, firmware_number};
use crate::decode::{DecodeError, FrameDecoder, PixelFormat};
use serde::Serialize;
use std::time::Duration;
use unitac_core::{Frame, Source, SourceError, Stamp};

/// The stream's own faults: the [`SourceError`] causes that the device's [`DeviceError`] and
/// the decoder's [`DecodeError`] do not name by themselves.
#[derive(Debug, thiserror::Error)]
pub enum StreamError {
    #[error("calibration: {0}")]
    Calibration(DecodeError),
    /// The device went away or stalled; the stream reconnects.
    #[error("{name}: {why}")]
    Lost { name: String, why: String },
    #[error("{name}: still away after {attempts} attempts: {last}")]
    StillAway {
        name: String,
        attempts: u32,
        last: DeviceError,
    },
    #[error("streaming without a mode")]
    NoMode,
    #[error("buffer without a capture timestamp")]
    NoTimestamp,
    #[error("seq {seq}: {error}")]
    Decode { seq: u64, error: DecodeError },
    #[error("no fresh buffer after {0} tries")]
    NoFreshBuffer(u32),
}

/// Opens devices by serial: the real one (V4L2 through sysfs discovery) or a fake.
pub trait Backend: Send {
    /// Open the capture node of the sensor with this serial. `DeviceError::Gone` if it is not
    /// on the bus (the stream keeps retrying).
    fn open(&mut self, serial: &str) -> Result<OpenedDevice, DeviceError>;

    /// Reset the USB device of the sensor with this serial (the software replug: it drops off
    /// the bus and enumerates again). Called with the capture node closed. Default: not
    /// supported (the stream then only re-opens the node).
    fn reset_usb(&mut self, serial: &str) -> Result<(), DeviceError> {
        Err(DeviceError::Unsupported(format!(
            "USB reset of {serial}: no USB access in this backend"
        )))
    }

    /// Wait at most `max` for a USB arrival or removal event. `Some(true)`: an event came (try
    /// to open now), `Some(false)`: none within `max`, `None`: no hotplug events here (the
    /// caller sleeps and polls).
    fn wait_usb_event(&mut self, max: Duration) -> Option<bool> {
        let _ = max;
        None
    }
}

/// What `Backend::open` returns.
pub struct OpenedDevice {
    pub device: Box<dyn CaptureDevice>,
    /// bcdDevice string (DIGIT LED encoding depends on it).
    pub firmware: Option<String>,
}

impl std::fmt::Debug for OpenedDevice {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("OpenedDevice")
            .field("firmware", &self.firmware)
            .finish_non_exhaustive()
    }
}

/// The clocks a stream needs. The real one reads CLOCK_MONOTONIC (the clock V4L2 stamps buffers
/// with) and CLOCK_REALTIME, and sleeps; tests move a fake one by hand.
pub trait DriverClock: Send {
    fn monotonic(&self) -> Duration;
    fn realtime(&self) -> Stamp;
    fn sleep(&self, d: Duration);
}

/// CLOCK_MONOTONIC / CLOCK_REALTIME through rustix (no unsafe here), `std::thread::sleep`.
#[derive(Debug, Default, Clone, Copy)]
pub struct SystemDriverClock;

impl DriverClock for SystemDriverClock {
    fn monotonic(&self) -> Duration {
        let t = rustix::time::clock_gettime(rustix::time::ClockId::Monotonic);
        Duration::new(
            u64::try_from(t.tv_sec).unwrap_or(0),
            u32::try_from(t.tv_nsec).unwrap_or(0),
        )
    }
    fn realtime(&self) -> Stamp {
        let t = rustix::time::clock_gettime(rustix::time::ClockId::Realtime);
        Stamp(
            t.tv_sec
                .saturating_mul(1_000_000_000)
                .saturating_add(t.tv_nsec),
        )
    }
    fn sleep(&self, d: Duration) {
        std::thread::sleep(d);
    }
}

/// Link state, for status reports.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum LinkState {
    Opening,
    Streaming,
    Lost,
}

/// Counters of one stream (they survive reconnects).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct StreamCounters {
    pub frames: u64,
    pub decode_errors: u64,
    /// Frames lost according to gaps in the driver's sequence numbers.
    pub dropped: u64,
    pub sequence_resets: u64,
    /// Stale buffers thrown away at (re)start.
    pub flushed: u64,
    /// Buffers without a capture timestamp (dropped: no read-time stamps).
    pub no_timestamp: u64,
    pub timeouts: u64,
    pub disconnects: u64,
    pub reconnects: u64,
    pub open_failures: u64,
    pub control_mismatches: u64,
    pub clock_resyncs: u64,
    /// Times the device was open but sent no frame for `stall_after`.
    pub stalls: u64,
    /// USB resets done for stalls (0 where the backend cannot reset).
    pub usb_resets: u64,
    pub usb_reset_failures: u64,
    /// Stalls after which the device streamed again.
    pub stall_recoveries: u64,
    /// USB hotplug events that woke a reconnect.
    pub hotplug_events: u64,
}

/// Settings of a stream.
#[derive(Debug, Clone)]
pub struct StreamConfig {
    pub serial: String,
    pub calibration: Calibration,
    /// Formats in order of preference, size and rate asked of the device.
    pub request: ModeRequest,
    /// Wait for one buffer.
    pub frame_timeout: Duration,
    /// Consecutive timeouts after which the device is closed and re-opened.
    pub timeouts_before_reopen: u32,
    /// No frame for this long with the device open = a stall: close, USB reset, re-open.
    pub stall_after: Duration,
    pub backoff_initial: Duration,
    pub backoff_max: Duration,
    /// While the device is away, how often `next_frame` returns `Unavailable`.
    pub report_every: Duration,
}

impl StreamConfig {
    pub fn new(serial: &str, calibration: Calibration) -> Self {
        let spec = calibration.kind.spec();
        // MJPEG first for both models: a third of the USB bandwidth of YUYV ("Not enough
        // bandwidth" with several cameras on one root port); GelSight Mini offers only MJPEG.
        let formats = vec![PixelFormat::Mjpg, PixelFormat::Yuyv, PixelFormat::Uyvy];
        Self {
            serial: serial.to_string(),
            request: ModeRequest {
                formats,
                width: spec.native_width,
                height: spec.native_height,
                fps: spec.fps,
            },
            calibration,
            frame_timeout: Duration::from_secs(1),
            timeouts_before_reopen: 3,
            stall_after: Duration::from_secs(3),
            backoff_initial: Duration::from_millis(100),
            backoff_max: Duration::from_secs(2),
            report_every: Duration::from_secs(2),
        }
    }
}

enum State {
    Streaming(Box<dyn CaptureDevice>),
    Lost { attempt: u32, next_try: Duration },
}

/// A live sensor as a [`Source`].
pub struct SensorStream<B: Backend, C: DriverClock> {
    cfg: StreamConfig,
    backend: B,
    clock: C,
    state: State,
    name: String,
    mode: Option<Mode>,
    /// Firmware revision as a number (0 if unknown).
    firmware: u32,
    decoder: FrameDecoder,
    time: TimeMapper,
    seq: SequenceTracker,
    flush: StaleFlush,
    timeouts_in_a_row: u32,
    /// Monotonic time of the last buffer (or of the start).
    last_buffer_at: Duration,
    /// A stall reset is waiting for the device to stream again.
    recovering_stall: bool,
    counters: StreamCounters,
    last_mismatches: Vec<ControlMismatch>,
    lost_reported_at: Option<Duration>,
}

impl<B: Backend, C: DriverClock> std::fmt::Debug for SensorStream<B, C> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SensorStream")
            .field("serial", &self.cfg.serial)
            .field("state", &self.state())
            .field("counters", &self.counters)
            .finish_non_exhaustive()
    }
}

impl<B: Backend, C: DriverClock> SensorStream<B, C> {
    /// Opens the device now; a sensor that is not there is an error (a typo in a serial should
    /// not look like a loose cable). Later disappearances are reconnected.
    pub fn open(cfg: StreamConfig, backend: B, clock: C) -> Result<Self, SourceError> {
        let decoder = FrameDecoder::new(cfg.calibration.decode_config())
            .map_err(|e| SourceError::fatal(StreamError::Calibration(e)))?;
        let mut s = Self {
            name: format!("v4l:{}", cfg.serial),
            cfg,
            backend,
            clock,
            state: State::Lost {
                attempt: 0,
                next_try: Duration::ZERO,
            },
            mode: None,
            firmware: 0,
            decoder,
            time: TimeMapper::default(),
            seq: SequenceTracker::default(),
            flush: StaleFlush::default(),
            timeouts_in_a_row: 0,
            last_buffer_at: Duration::ZERO,
            recovering_stall: false,
            counters: StreamCounters::default(),
            last_mismatches: Vec::new(),
            lost_reported_at: None,
        };
        let dev = s.connect().map_err(|e| match e {
            e @ DeviceError::Gone(_) => SourceError::unavailable(e),
            other => SourceError::fatal(other),
        })?;
        s.state = State::Streaming(dev);
        Ok(s)
    }

    pub fn state(&self) -> LinkState {
        match self.state {
            State::Streaming(_) => LinkState::Streaming,
            State::Lost { .. } => LinkState::Lost,
        }
    }
    pub fn counters(&self) -> StreamCounters {
        let mut c = self.counters;
        c.decode_errors = self.decoder.counters.errors;
        c.dropped = self.seq.dropped;
        c.sequence_resets = self.seq.resets;
        c.flushed = self.flush.flushed;
        c.clock_resyncs = self.time.resyncs;
        c
    }
    /// The mode the device streams in (after negotiation).
    pub fn mode(&self) -> Option<Mode> {
        self.mode
    }
    /// Controls the device did not take at the last (re)open.
    pub fn control_mismatches(&self) -> &[ControlMismatch] {
        &self.last_mismatches
    }
    pub fn backend(&self) -> &B {
        &self.backend
    }

    /// Change the camera settings: written now (if streaming) and after every reconnect.
    pub fn set_camera_settings(
        &mut self,
        settings: crate::controls::CameraSettings,
    ) -> Result<Vec<ControlMismatch>, SourceError> {
        settings.validate().map_err(SourceError::fatal)?;
        self.cfg.calibration.camera = settings;
        if let State::Streaming(dev) = &mut self.state {
            let plan = settings.plan(self.cfg.calibration.kind, self.firmware);
            let bad = apply_and_verify(dev.as_mut(), &plan).map_err(SourceError::unavailable)?;
            self.counters.control_mismatches += bad.len() as u64;
            self.last_mismatches = bad.clone();
            return Ok(bad);
        }
        Ok(Vec::new())
    }

    /// Open, negotiate, write settings, start streaming, reset the pure trackers.
    fn connect(&mut self) -> Result<Box<dyn CaptureDevice>, DeviceError> {
        let opened = self.backend.open(&self.cfg.serial)?;
        self.firmware = opened
            .firmware
            .as_deref()
            .and_then(firmware_number)
            .unwrap_or(0);
        let mut dev = opened.device;
        let offered = dev.modes()?;
        let want = choose_mode(&offered, &self.cfg.request).ok_or_else(|| {
            DeviceError::Unsupported(format!(
                "none of {:?} offered (device lists {})",
                self.cfg.request.formats,
                offered
                    .iter()
                    .map(ToString::to_string)
                    .collect::<Vec<_>>()
                    .join(", ")
            ))
        })?;
        let got = dev.set_mode(&want)?;
        if got != want {
            tracing::warn!("{}: asked for {want}, device set {got}", self.name);
        }
        self.mode = Some(got);
        let plan = self
            .cfg
            .calibration
            .camera
            .plan(self.cfg.calibration.kind, self.firmware);
        let bad = apply_and_verify(dev.as_mut(), &plan)?;
        for m in &bad {
            tracing::warn!("{}: control {} not taken: {m:?}", self.name, m.name);
        }
        self.counters.control_mismatches += bad.len() as u64;
        self.last_mismatches = bad;
        let started = self.clock.monotonic();
        dev.start()?;
        self.flush.start(started, dev.queue_len());
        self.time
            .start(self.clock.realtime(), self.clock.monotonic());
        self.seq.restart();
        self.timeouts_in_a_row = 0;
        self.last_buffer_at = self.clock.monotonic();
        Ok(dev)
    }

    fn backoff(&self, attempt: u32) -> Duration {
        let f = 1u32.checked_shl(attempt.min(16)).unwrap_or(u32::MAX);
        self.cfg
            .backoff_initial
            .saturating_mul(f)
            .min(self.cfg.backoff_max)
    }

    fn lose(&mut self, why: &str) -> SourceError {
        // Dropping the device closes it (and unmaps its buffers).
        self.state = State::Lost {
            attempt: 0,
            next_try: self.clock.monotonic(),
        };
        self.counters.disconnects += 1;
        self.lost_reported_at = Some(self.clock.monotonic());
        tracing::warn!("{}: {why}; reconnecting", self.name);
        SourceError::unavailable(StreamError::Lost {
            name: self.name.clone(),
            why: why.to_string(),
        })
    }

    /// The device is open but silent: close it, reset its USB device, re-open by serial.
    fn stall(&mut self, why: &str) -> SourceError {
        self.counters.stalls += 1;
        // Close the node first (dropping the device unmaps its buffers and closes it).
        self.state = State::Lost {
            attempt: 0,
            next_try: self.clock.monotonic(),
        };
        match self.backend.reset_usb(&self.cfg.serial) {
            Ok(()) => {
                self.counters.usb_resets += 1;
                tracing::warn!("{}: {why}; USB device reset, re-opening", self.name);
            }
            Err(DeviceError::Unsupported(m)) => {
                tracing::warn!("{}: {why}; re-opening ({m})", self.name);
            }
            Err(e) => {
                self.counters.usb_reset_failures += 1;
                tracing::warn!("{}: {why}; USB reset failed ({e}), re-opening", self.name);
            }
        }
        self.recovering_stall = true;
        self.counters.disconnects += 1;
        self.lost_reported_at = Some(self.clock.monotonic());
        SourceError::unavailable(StreamError::Lost {
            name: self.name.clone(),
            why: why.to_string(),
        })
    }

    /// One step while lost: wait for the next try (bounded by `report_every`), try to open.
    fn try_reconnect(&mut self) -> Result<(), SourceError> {
        let State::Lost { attempt, next_try } = self.state else {
            return Ok(());
        };
        let now = self.clock.monotonic();
        if next_try > now {
            match self.backend.wait_usb_event(next_try - now) {
                Some(true) => self.counters.hotplug_events += 1,
                Some(false) => {}
                None => self.clock.sleep(next_try - now),
            }
        }
        match self.connect() {
            Ok(dev) => {
                self.state = State::Streaming(dev);
                self.counters.reconnects += 1;
                self.lost_reported_at = None;
                tracing::info!("{}: reconnected", self.name);
                Ok(())
            }
            Err(e) => {
                self.counters.open_failures += 1;
                let now = self.clock.monotonic();
                self.state = State::Lost {
                    attempt: attempt.saturating_add(1),
                    next_try: now + self.backoff(attempt),
                };
                let due = self
                    .lost_reported_at
                    .is_none_or(|t| now.saturating_sub(t) >= self.cfg.report_every);
                if due {
                    self.lost_reported_at = Some(now);
                    Err(SourceError::unavailable(StreamError::StillAway {
                        name: self.name.clone(),
                        attempts: attempt.saturating_add(1),
                        last: e,
                    }))
                } else {
                    Ok(())
                }
            }
        }
    }

    fn capture_one(&mut self) -> Result<Option<Frame>, SourceError> {
        let State::Streaming(dev) = &mut self.state else {
            return Ok(None);
        };
        let Some(mode) = self.mode else {
            return Err(SourceError::fatal(StreamError::NoMode));
        };
        // Re-check the clock offset before dequeuing (cheap: two clock reads once a second).
        let mono = self.clock.monotonic();
        if self.time.is_due(mono) {
            let real = self.clock.realtime();
            self.time.recheck(real, self.clock.monotonic());
        }
        let buf = match dev.next_buffer(self.cfg.frame_timeout) {
            Ok(b) => b,
            Err(DeviceError::Gone(m)) => return Err(self.lose(&m)),
            Err(DeviceError::Timeout(d)) => {
                self.counters.timeouts += 1;
                self.timeouts_in_a_row += 1;
                let silent = self.clock.monotonic().saturating_sub(self.last_buffer_at);
                if silent >= self.cfg.stall_after
                    || self.timeouts_in_a_row >= self.cfg.timeouts_before_reopen
                {
                    return Err(self.stall(&format!(
                        "no frame for {silent:?} ({} timeouts of {d:?} in a row)",
                        self.timeouts_in_a_row
                    )));
                }
                return Err(SourceError::frame(DeviceError::Timeout(d)));
            }
            Err(e) => return Err(SourceError::frame(e)),
        };
        self.timeouts_in_a_row = 0;
        self.last_buffer_at = self.clock.monotonic();
        if self.recovering_stall {
            self.recovering_stall = false;
            self.counters.stall_recoveries += 1;
        }
        if self.flush.is_stale(buf.timestamp) {
            return Ok(None);
        }
        let (seq, _) = self.seq.feed(buf.sequence);
        let Some(stamp) = self.time.map(buf.timestamp) else {
            self.counters.no_timestamp += 1;
            return Err(SourceError::frame(StreamError::NoTimestamp));
        };
        let rgb = self
            .decoder
            .decode(mode.format, mode.width, mode.height, buf.data)
            .map_err(|error| SourceError::frame(StreamError::Decode { seq, error }))?;
        let frame = Frame::new(
            self.cfg.serial.clone(),
            seq,
            stamp,
            rgb.width,
            rgb.height,
            rgb.data,
        )
        .map_err(SourceError::frame)?;
        self.counters.frames += 1;
        Ok(Some(frame))
    }
}

impl<B: Backend, C: DriverClock> Source for SensorStream<B, C> {
    fn name(&self) -> &str {
        &self.name
    }
    fn is_replay(&self) -> bool {
        false
    }
    fn next_frame(&mut self) -> Result<Option<Frame>, SourceError> {
        // Bounded: stale buffers are at most queue_len + 1 per start.
        const TRIES: u32 = 64;
        for _ in 0..TRIES {
            match self.state {
                State::Lost { .. } => self.try_reconnect()?,
                State::Streaming(_) => {
                    if let Some(f) = self.capture_one()? {
                        return Ok(Some(f));
                    }
                }
            }
        }
        Err(SourceError::frame(StreamError::NoFreshBuffer(TRIES)))
    }
}
