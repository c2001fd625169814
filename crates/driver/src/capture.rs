//! Capture behind a trait, and the pure pieces every capture needs.
//!
//! [`CaptureDevice`] is what a V4L2 node (crates/driver/src/v4l_backend.rs) and the test fakes
//! implement. The logic around it is pure and tested without a device:
//! - [`choose_mode`]: format and mode negotiation against what the device lists;
//! - [`TimeMapper`]: the buffer's CLOCK_MONOTONIC capture time mapped to system (ROS) time with an
//!   offset taken at start and re-checked; a frame never carries the time it was read;
//! - [`SequenceTracker`]: drops counted from gaps in the driver's sequence numbers;
//! - [`StaleFlush`]: buffers captured before the stream (re)started are thrown away.

use crate::decode::PixelFormat;
use serde::{Deserialize, Serialize};
use std::time::Duration;
use thiserror::Error;
use unitac_core::Stamp;

#[derive(Debug, Error, Clone, PartialEq, Eq)]
pub enum DeviceError {
    /// The device went away (unplugged, USB reset): reconnect.
    #[error("device gone: {0}")]
    Gone(String),
    /// No buffer within the timeout.
    #[error("no frame within {0:?}")]
    Timeout(Duration),
    /// The device cannot do what was asked (format, mode, control).
    #[error("unsupported: {0}")]
    Unsupported(String),
    /// Any other I/O error; the device may still be usable.
    #[error("{0}")]
    Io(String),
}

/// One stream mode a device offers.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Mode {
    pub format: PixelFormat,
    pub width: u32,
    pub height: u32,
    pub fps: f64,
}

impl std::fmt::Display for Mode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let cc = self.format.fourcc();
        write!(
            f,
            "{}{}{}{} {}x{}@{}",
            cc[0] as char,
            cc[1] as char,
            cc[2] as char,
            cc[3] as char,
            self.width,
            self.height,
            self.fps
        )
    }
}

/// What the driver asks for: formats in order of preference, size and rate.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ModeRequest {
    pub formats: Vec<PixelFormat>,
    pub width: u32,
    pub height: u32,
    pub fps: f64,
}

/// Pick the mode to ask the device for. Exact size in the most preferred format first, with the
/// closest frame rate not above the request (else the slowest above it); if no format has the
/// size, the largest size of the most preferred format. `None` if no offered format is wanted.
pub fn choose_mode(offered: &[Mode], req: &ModeRequest) -> Option<Mode> {
    let rate = |cands: Vec<Mode>| -> Option<Mode> {
        let below = cands
            .iter()
            .filter(|m| m.fps <= req.fps + 1e-6)
            .max_by(|a, b| a.fps.total_cmp(&b.fps));
        below
            .or_else(|| cands.iter().min_by(|a, b| a.fps.total_cmp(&b.fps)))
            .copied()
    };
    for f in &req.formats {
        let exact: Vec<Mode> = offered
            .iter()
            .filter(|m| m.format == *f && m.width == req.width && m.height == req.height)
            .copied()
            .collect();
        if let Some(m) = rate(exact) {
            return Some(m);
        }
    }
    for f in &req.formats {
        let area = |m: &Mode| u64::from(m.width) * u64::from(m.height);
        let Some(largest) = offered.iter().filter(|m| m.format == *f).map(area).max() else {
            continue;
        };
        let cands: Vec<Mode> = offered
            .iter()
            .filter(|m| m.format == *f && area(m) == largest)
            .copied()
            .collect();
        if let Some(m) = rate(cands) {
            return Some(m);
        }
    }
    None
}

/// One dequeued buffer: the bytes the driver filled and its metadata.
#[derive(Debug, Clone, Copy)]
pub struct RawBuffer<'a> {
    pub data: &'a [u8],
    /// Driver sequence number (wraps at u32).
    pub sequence: u32,
    /// Capture time on CLOCK_MONOTONIC (V4L2 buffer timestamp); zero if the driver gave none.
    pub timestamp: Duration,
}

/// A capture device: one open V4L2 node, or a fake in tests.
pub trait CaptureDevice: Send {
    /// Modes the device lists (format x size x rate).
    fn modes(&mut self) -> Result<Vec<Mode>, DeviceError>;
    /// Ask for a mode; returns what the device actually set (it may differ).
    fn set_mode(&mut self, mode: &Mode) -> Result<Mode, DeviceError>;
    /// Map buffers and start streaming.
    fn start(&mut self) -> Result<(), DeviceError>;
    /// The next filled buffer, waiting at most `timeout`.
    fn next_buffer(&mut self, timeout: Duration) -> Result<RawBuffer<'_>, DeviceError>;
    /// Number of buffers in the driver's queue (the most that can be stale at start).
    fn queue_len(&self) -> u32;
    fn set_control(&mut self, id: u32, value: i64) -> Result<(), DeviceError>;
    fn control(&mut self, id: u32) -> Result<i64, DeviceError>;
}

/// Monotonic capture time -> system time: `stamp = mono + offset`, offset = realtime - monotonic
/// sampled back to back. Re-checked every `recheck_every`; a difference above `step_threshold`
/// (the system clock was stepped, e.g. by NTP or PTP) adopts the new offset and is counted.
#[derive(Debug, Clone)]
pub struct TimeMapper {
    offset_ns: Option<i64>,
    last_check: Duration,
    pub recheck_every: Duration,
    pub step_threshold_ns: i64,
    pub resyncs: u64,
}

impl Default for TimeMapper {
    fn default() -> Self {
        Self {
            offset_ns: None,
            last_check: Duration::ZERO,
            recheck_every: Duration::from_secs(1),
            step_threshold_ns: 2_000_000,
            resyncs: 0,
        }
    }
}

fn nanos(d: Duration) -> i64 {
    i64::try_from(d.as_nanos()).unwrap_or(i64::MAX)
}

impl TimeMapper {
    /// Take the offset from a (realtime, monotonic) pair read back to back.
    pub fn start(&mut self, real: Stamp, mono: Duration) {
        self.offset_ns = Some(real.0.saturating_sub(nanos(mono)));
        self.last_check = mono;
    }
    /// Feed a new pair; re-checks if due. Returns true when the offset changed.
    pub fn recheck(&mut self, real: Stamp, mono: Duration) -> bool {
        let Some(old) = self.offset_ns else {
            self.start(real, mono);
            return true;
        };
        if mono.saturating_sub(self.last_check) < self.recheck_every {
            return false;
        }
        self.last_check = mono;
        let new = real.0.saturating_sub(nanos(mono));
        if new.saturating_sub(old).abs() > self.step_threshold_ns {
            self.offset_ns = Some(new);
            self.resyncs += 1;
            true
        } else {
            false
        }
    }
    pub fn is_due(&self, mono: Duration) -> bool {
        self.offset_ns.is_none() || mono.saturating_sub(self.last_check) >= self.recheck_every
    }
    /// System time of a buffer captured at monotonic time `buffer`; `None` before `start` or for a
    /// buffer without a timestamp.
    pub fn map(&self, buffer: Duration) -> Option<Stamp> {
        if buffer.is_zero() {
            return None;
        }
        self.offset_ns
            .map(|o| Stamp(nanos(buffer).saturating_add(o)))
    }
}

/// Result of feeding one sequence number.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SeqEvent {
    First,
    InOrder,
    /// `n` frames were lost before this one.
    Gap(u64),
    /// The counter went backwards or jumped absurdly (stream restart): not counted as drops.
    Reset,
}

/// Turns the driver's u32 sequence into a published u64 that never goes backwards (also across
/// reconnects) and counts the frames lost in between.
#[derive(Debug, Clone, Default)]
pub struct SequenceTracker {
    last: Option<u32>,
    next_out: u64,
    pub dropped: u64,
    pub resets: u64,
}

/// A jump larger than this is a restart, not a loss (about 4.6 h at 60 fps).
const MAX_GAP: u32 = 1_000_000;

impl SequenceTracker {
    /// Feed the next buffer's sequence; returns the published sequence and what happened.
    pub fn feed(&mut self, seq: u32) -> (u64, SeqEvent) {
        let ev = match self.last {
            None => SeqEvent::First,
            Some(last) => {
                let d = seq.wrapping_sub(last);
                if d == 1 {
                    SeqEvent::InOrder
                } else if d == 0 || d > MAX_GAP {
                    SeqEvent::Reset
                } else {
                    SeqEvent::Gap(u64::from(d - 1))
                }
            }
        };
        match ev {
            SeqEvent::Gap(n) => {
                self.dropped += n;
                self.next_out += n;
            }
            SeqEvent::Reset => self.resets += 1,
            SeqEvent::First | SeqEvent::InOrder => {}
        }
        self.last = Some(seq);
        let out = self.next_out;
        self.next_out += 1;
        (out, ev)
    }
    /// The device was re-opened: its counter starts again; published numbers go on.
    pub fn restart(&mut self) {
        self.last = None;
    }
}

/// Throws away buffers captured before the stream started (frames that sat in the queue while
/// nobody read, or from before a reconnect). At most `queue_len + 1` buffers are thrown away, so
/// a device with odd timestamps cannot stall the stream.
#[derive(Debug, Clone, Default)]
pub struct StaleFlush {
    started: Duration,
    budget: u32,
    pub flushed: u64,
}

impl StaleFlush {
    pub fn start(&mut self, started_mono: Duration, queue_len: u32) {
        self.started = started_mono;
        self.budget = queue_len.saturating_add(1);
    }
    /// True if this buffer is stale and must be dropped.
    pub fn is_stale(&mut self, timestamp: Duration) -> bool {
        if self.budget == 0 {
            return false;
        }
        if !timestamp.is_zero() && timestamp < self.started {
            self.budget -= 1;
            self.flushed += 1;
            true
        } else {
            // The first fresh buffer ends the flush.
            self.budget = 0;
            false
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
    use super::*;

    fn m(format: PixelFormat, width: u32, height: u32, fps: f64) -> Mode {
        Mode {
            format,
            width,
            height,
            fps,
        }
    }

    fn digit_modes() -> Vec<Mode> {
        use PixelFormat::*;
        vec![
            m(Mjpg, 640, 480, 30.0),
            m(Mjpg, 640, 480, 15.0),
            m(Mjpg, 320, 240, 60.0),
            m(Mjpg, 320, 240, 30.0),
            m(Yuyv, 640, 480, 30.0),
            m(Yuyv, 640, 480, 15.0),
            m(Yuyv, 320, 240, 60.0),
            m(Yuyv, 320, 240, 30.0),
        ]
    }

    #[test]
    fn negotiation_prefers_format_then_size_then_rate() {
        use PixelFormat::*;
        let req = |formats: Vec<PixelFormat>, w, h, fps| ModeRequest {
            formats,
            width: w,
            height: h,
            fps,
        };
        let d = digit_modes();
        assert_eq!(
            choose_mode(&d, &req(vec![Yuyv, Mjpg], 320, 240, 60.0)),
            Some(m(Yuyv, 320, 240, 60.0))
        );
        assert_eq!(
            choose_mode(&d, &req(vec![Mjpg], 320, 240, 45.0)),
            Some(m(Mjpg, 320, 240, 30.0))
        );
        assert_eq!(
            choose_mode(&d, &req(vec![Mjpg], 640, 480, 10.0)),
            Some(m(Mjpg, 640, 480, 15.0))
        );
        // GelSight Mini: 320x240 is not offered; the only mode is taken.
        let g = [m(Mjpg, 3280, 2464, 25.0)];
        assert_eq!(
            choose_mode(&g, &req(vec![Yuyv, Mjpg], 320, 240, 25.0)),
            Some(g[0])
        );
        assert_eq!(choose_mode(&g, &req(vec![Yuyv], 320, 240, 25.0)), None);
        assert_eq!(choose_mode(&[], &req(vec![Yuyv], 320, 240, 25.0)), None);
    }

    #[test]
    fn time_mapping_uses_buffer_time_and_follows_clock_steps() {
        let mut t = TimeMapper::default();
        assert_eq!(t.map(Duration::from_secs(5)), None);
        let real0 = Stamp(1_700_000_000_000_000_000);
        t.start(real0, Duration::from_secs(100));
        // A buffer captured 20 ms before the offset was taken maps 20 ms earlier.
        assert_eq!(
            t.map(Duration::from_millis(99_980)),
            Some(Stamp(real0.0 - 20_000_000))
        );
        assert_eq!(t.map(Duration::ZERO), None);
        // Small jitter between the two clock reads is ignored.
        assert!(!t.recheck(
            Stamp(real0.0 + 2_000_000_000 + 500_000),
            Duration::from_secs(102)
        ));
        // Not due yet: nothing happens even with a large step.
        assert!(!t.recheck(
            Stamp(real0.0 + 10_000_000_000),
            Duration::from_millis(102_500)
        ));
        // The system clock was stepped 1 s forward.
        assert!(t.recheck(Stamp(real0.0 + 4_000_000_000), Duration::from_secs(103)));
        assert_eq!(t.resyncs, 1);
        assert_eq!(
            t.map(Duration::from_secs(103)),
            Some(Stamp(real0.0 + 4_000_000_000))
        );
    }

    #[test]
    fn sequence_gaps_wraps_and_resets() {
        let mut s = SequenceTracker::default();
        assert_eq!(s.feed(10), (0, SeqEvent::First));
        assert_eq!(s.feed(11), (1, SeqEvent::InOrder));
        assert_eq!(s.feed(14), (4, SeqEvent::Gap(2)));
        assert_eq!(s.dropped, 2);
        // Wrap-around of the u32 counter is not a reset.
        let mut w = SequenceTracker::default();
        w.feed(u32::MAX - 1);
        w.feed(u32::MAX);
        assert_eq!(w.feed(0).1, SeqEvent::InOrder);
        assert_eq!(w.feed(2).1, SeqEvent::Gap(1));
        // Going backwards is a reset, published numbers still go up.
        assert_eq!(s.feed(3), (5, SeqEvent::Reset));
        assert_eq!(s.resets, 1);
        s.restart();
        assert_eq!(s.feed(0), (6, SeqEvent::First));
        assert_eq!(s.dropped, 2);
    }

    #[test]
    fn stale_buffers_are_flushed_at_start_only() {
        let mut f = StaleFlush::default();
        f.start(Duration::from_secs(10), 4);
        assert!(f.is_stale(Duration::from_secs(8)));
        assert!(f.is_stale(Duration::from_secs(9)));
        assert!(!f.is_stale(Duration::from_millis(10_010)));
        // After the first fresh buffer nothing more is flushed.
        assert!(!f.is_stale(Duration::from_secs(9)));
        assert_eq!(f.flushed, 2);
        // Bounded: a device whose clock is stuck in the past is flushed at most queue + 1 times.
        let mut f = StaleFlush::default();
        f.start(Duration::from_secs(10), 2);
        let n = (0..10)
            .filter(|_| f.is_stale(Duration::from_secs(1)))
            .count();
        assert_eq!(n, 3);
    }
}
