//! The one pacer: when a recorded or simulated message is due on the wall clock.
//!
//! The embedded runtime (mock and bag sources in real time), `unitac replay --rate`, and the ROS
//! sensor node (mock and bag sources) all pace through [`Pacer`]: message `k` with stamp `t_k` is
//! due `(t_k - t_0) / rate` after the first one was released. Pacing only decides *when* a
//! message is handed on, never what it contains, so it cannot change any output.
//!
//! Waiting is done by the caller's `idle` function (sleep in a thread, spin a ROS node), called
//! with slices of at most [`MAX_IDLE_SLICE`], so a stop request is seen promptly.

use crate::clock::Stamp;
use std::time::{Duration, Instant};

/// The longest single wait handed to `idle`.
pub const MAX_IDLE_SLICE: Duration = Duration::from_millis(50);
/// Rates accepted by [`Pacer::new`] (stream seconds per wall second).
pub const RATE_RANGE: (f64, f64) = (1e-3, 1e3);

/// A pacing rate outside [`RATE_RANGE`] (or not finite).
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[error("rate must be in [{lo}, {hi}], got {rate}", lo = RATE_RANGE.0, hi = RATE_RANGE.1, rate = .0)]
pub struct RateError(pub f64);

#[derive(Debug, Clone)]
pub struct Pacer {
    rate: Option<f64>,
    start: Option<(Instant, Stamp)>,
}

impl Pacer {
    /// `rate` = stream seconds per wall second (1.0 = real time); `None` = as fast as possible.
    /// A rate outside [`RATE_RANGE`] (or not finite) is an error naming the range.
    pub fn new(rate: Option<f64>) -> Result<Self, RateError> {
        if let Some(r) = rate {
            if !(r.is_finite() && (RATE_RANGE.0..=RATE_RANGE.1).contains(&r)) {
                return Err(RateError(r));
            }
        }
        Ok(Self { rate, start: None })
    }

    /// As fast as possible: every message is due at once.
    pub fn fast() -> Self {
        Self {
            rate: None,
            start: None,
        }
    }
    /// Real time (rate 1).
    pub fn real_time() -> Self {
        Self {
            rate: Some(1.0),
            start: None,
        }
    }

    /// Start over: the next message is due at once (a new pass of a looped source).
    pub fn restart(&mut self) {
        self.start = None;
    }

    /// How long after `now` the message stamped `stamp` is due (zero: now or overdue).
    pub fn due_in(&mut self, stamp: Stamp, now: Instant) -> Duration {
        let Some(rate) = self.rate else {
            return Duration::ZERO;
        };
        let (t0, s0) = *self.start.get_or_insert((now, stamp));
        let stream_s = stamp.secs_since(s0).max(0.0) / rate;
        let due = t0 + Duration::from_secs_f64(stream_s.min(1e7));
        due.saturating_duration_since(now)
    }

    /// Wait until `stamp` is due, calling `idle(slice)` until then; `idle` returns false to stop
    /// waiting (a stop request). Returns false if it was stopped.
    pub fn wait(&mut self, stamp: Stamp, mut idle: impl FnMut(Duration) -> bool) -> bool {
        loop {
            let left = self.due_in(stamp, Instant::now());
            if left.is_zero() {
                return true;
            }
            if !idle(left.min(MAX_IDLE_SLICE)) {
                return false;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    const MS: i64 = 1_000_000;

    #[test]
    fn messages_are_due_at_their_stamp_offset_divided_by_the_rate() {
        let t0 = Instant::now();
        let mut p = Pacer::new(Some(2.0)).unwrap();
        assert_eq!(p.due_in(Stamp(1000 * MS), t0), Duration::ZERO);
        // 100 ms of stream at 2x: 50 ms after the first.
        assert_eq!(p.due_in(Stamp(1100 * MS), t0), Duration::from_millis(50));
        assert_eq!(
            p.due_in(Stamp(1100 * MS), t0 + Duration::from_millis(20)),
            Duration::from_millis(30)
        );
        // Overdue and older stamps are due at once.
        assert_eq!(
            p.due_in(Stamp(1100 * MS), t0 + Duration::from_secs(1)),
            Duration::ZERO
        );
        assert_eq!(p.due_in(Stamp(900 * MS), t0), Duration::ZERO);
    }

    #[test]
    fn fast_is_never_due_later_and_restart_starts_over() {
        let t0 = Instant::now();
        let mut fast = Pacer::new(None).unwrap();
        assert_eq!(fast.due_in(Stamp(i64::MAX), t0), Duration::ZERO);
        let mut p = Pacer::new(Some(1.0)).unwrap();
        p.due_in(Stamp(0), t0);
        assert_eq!(p.due_in(Stamp(10 * MS), t0), Duration::from_millis(10));
        p.restart();
        assert_eq!(p.due_in(Stamp(10 * MS), t0), Duration::ZERO);
    }

    #[test]
    fn wait_idles_in_slices_and_stops_when_told() {
        let mut p = Pacer::new(Some(1.0)).unwrap();
        assert!(p.wait(Stamp(0), |_| true));
        let mut slices = Vec::new();
        let stopped = !p.wait(Stamp(10_000 * MS), |d| {
            slices.push(d);
            slices.len() < 3
        });
        assert!(stopped);
        assert_eq!(slices.len(), 3);
        assert!(slices.iter().all(|d| *d <= MAX_IDLE_SLICE));
    }

    #[test]
    fn bad_rates_are_refused() {
        for r in [0.0, -1.0, f64::NAN, f64::INFINITY, 1e6] {
            assert!(Pacer::new(Some(r)).is_err(), "{r}");
        }
    }
}
