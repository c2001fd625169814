//! Time: a nanosecond stamp on the ROS time line and the injected clocks.
//!
//! Stages never read the wall clock. The runtime passes a [`SystemClock`] when it runs live
//! sensors and a [`ManualClock`] set to each message's capture stamp when it replays (bag, mock
//! sensor), which is what makes replay byte-for-byte deterministic.

use serde::{Deserialize, Serialize};
use std::sync::atomic::{AtomicI64, Ordering};

/// Nanoseconds since the Unix epoch (ROS time: `sec`, `nanosec` split on output).
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default, Serialize, Deserialize,
)]
#[serde(transparent)]
pub struct Stamp(pub i64);

impl Stamp {
    pub const ZERO: Stamp = Stamp(0);

    pub fn from_secs_f64(s: f64) -> Stamp {
        Stamp((s * 1e9).round() as i64)
    }
    pub fn as_secs_f64(self) -> f64 {
        self.0 as f64 * 1e-9
    }
    /// ROS `builtin_interfaces/Time` split. Negative stamps clamp to zero (ROS time is unsigned).
    pub fn to_sec_nanosec(self) -> (i32, u32) {
        let ns = self.0.max(0);
        let sec = (ns / 1_000_000_000).min(i64::from(i32::MAX)) as i32;
        (sec, (ns % 1_000_000_000) as u32)
    }
    pub fn from_sec_nanosec(sec: i32, nanosec: u32) -> Stamp {
        Stamp(i64::from(sec) * 1_000_000_000 + i64::from(nanosec.min(999_999_999)))
    }
    pub fn saturating_add_nanos(self, ns: i64) -> Stamp {
        Stamp(self.0.saturating_add(ns))
    }
    /// Seconds from `earlier` to `self` (negative if `earlier` is later).
    pub fn secs_since(self, earlier: Stamp) -> f64 {
        self.0.saturating_sub(earlier.0) as f64 * 1e-9
    }
}

/// The one way a stage learns the time.
pub trait Clock: Send + Sync {
    fn now(&self) -> Stamp;
}

/// Wall clock (system realtime). Only for live sensors.
#[derive(Debug, Default, Clone, Copy)]
pub struct SystemClock;

impl Clock for SystemClock {
    fn now(&self) -> Stamp {
        let d = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .unwrap_or_default();
        Stamp(i64::try_from(d.as_nanos()).unwrap_or(i64::MAX))
    }
}

/// A clock that only moves when told: tests, replay, the mock sensor's simulated time.
#[derive(Debug, Default)]
pub struct ManualClock {
    nanos: AtomicI64,
}

impl ManualClock {
    pub fn new(start: Stamp) -> Self {
        Self {
            nanos: AtomicI64::new(start.0),
        }
    }
    pub fn set(&self, t: Stamp) {
        self.nanos.store(t.0, Ordering::SeqCst);
    }
    pub fn advance_nanos(&self, ns: i64) {
        self.nanos.fetch_add(ns, Ordering::SeqCst);
    }
}

impl Clock for ManualClock {
    fn now(&self) -> Stamp {
        Stamp(self.nanos.load(Ordering::SeqCst))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sec_nanosec_round_trip() {
        let t = Stamp(1_700_000_000_123_456_789);
        let (s, ns) = t.to_sec_nanosec();
        assert_eq!((s, ns), (1_700_000_000, 123_456_789));
        assert_eq!(Stamp::from_sec_nanosec(s, ns), t);
        assert_eq!(Stamp(-5).to_sec_nanosec(), (0, 0));
    }

    #[test]
    fn manual_clock_moves_only_when_told() {
        let c = ManualClock::new(Stamp(10));
        assert_eq!(c.now(), Stamp(10));
        c.advance_nanos(5);
        assert_eq!(c.now(), Stamp(15));
        c.set(Stamp(3));
        assert_eq!(c.now(), Stamp(3));
    }

    #[test]
    fn system_clock_is_after_2020() {
        assert!(SystemClock.now() > Stamp::from_secs_f64(1.577e9));
    }
}
