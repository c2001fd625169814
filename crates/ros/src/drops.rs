//! Frames lost before a subscriber saw them, counted from gaps in their capture stamps.
//!
//! sensor_msgs/Image has no sequence number, and neither DDS (best-effort, keep-last) nor r2r's
//! subscription buffer says when it throws a sample away. A frame source has a steady period, so
//! a gap of k periods between two capture stamps means k - 1 frames were lost on the way. The
//! period is the median of recent regular intervals; gaps do not enter that estimate, so a
//! subscriber that keeps losing every other frame still counts one drop per gap.

use std::collections::VecDeque;

/// Intervals kept for the period estimate.
const WINDOW: usize = 15;
/// Regular intervals needed before gaps are counted.
const MIN_INTERVALS: usize = 4;
/// An interval longer than this many periods is a gap.
const GAP_FACTOR: f64 = 1.5;
/// After this many gaps in a row the source is taken to have changed its rate: start again.
const MAX_GAPS_IN_A_ROW: u32 = 30;

#[derive(Debug, Default, Clone)]
pub struct DropCounter {
    last_ns: Option<i64>,
    intervals: VecDeque<i64>,
    gaps_in_a_row: u32,
    /// Frames that arrived since the last stamp seen but had no usable stamp (rejected): they
    /// fill part of the next gap, so they are not counted as lost as well.
    arrived_unstamped: u64,
    /// Frames counted as lost so far.
    pub dropped: u64,
}

impl DropCounter {
    /// The current period estimate \[ns], once there are enough regular intervals.
    pub fn period_ns(&self) -> Option<i64> {
        if self.intervals.len() < MIN_INTERVALS {
            return None;
        }
        let mut v: Vec<i64> = self.intervals.iter().copied().collect();
        v.sort_unstable();
        Some(v[v.len() / 2])
    }

    /// A frame arrived whose stamp cannot be used (it was rejected and counted as an error): it
    /// is not lost, so the next gap is that much shorter.
    pub fn arrived_without_stamp(&mut self) {
        self.arrived_unstamped = self.arrived_unstamped.saturating_add(1);
    }

    /// Account for a frame captured at `stamp_ns`; returns how many frames were lost just before
    /// it. A stamp that goes backwards (a replay looping, a restarted source) starts afresh.
    pub fn observe(&mut self, stamp_ns: i64) -> u64 {
        let unstamped = std::mem::take(&mut self.arrived_unstamped);
        let Some(last) = self.last_ns.replace(stamp_ns) else {
            return 0;
        };
        let dt = stamp_ns.saturating_sub(last);
        if dt <= 0 {
            if dt < 0 {
                self.intervals.clear();
                self.gaps_in_a_row = 0;
            }
            return 0;
        }
        let lost = match self.period_ns() {
            Some(p) if dt as f64 > GAP_FACTOR * p as f64 => {
                self.gaps_in_a_row += 1;
                if self.gaps_in_a_row > MAX_GAPS_IN_A_ROW {
                    self.intervals.clear();
                    self.gaps_in_a_row = 0;
                }
                let periods = (dt as f64 / p as f64).round();
                // Bounded: a stamp jump of hours is not billions of lost frames.
                ((periods - 1.0).clamp(0.0, 1e6) as u64).saturating_sub(unstamped)
            }
            _ => {
                self.gaps_in_a_row = 0;
                if self.intervals.len() == WINDOW {
                    self.intervals.pop_front();
                }
                self.intervals.push_back(dt);
                0
            }
        };
        self.dropped += lost;
        lost
    }
}

#[cfg(test)]
mod unstamped_tests {
    use super::*;

    #[test]
    fn a_frame_rejected_for_its_stamp_is_not_counted_as_lost_too() {
        let mut d = DropCounter::default();
        for k in 0..10 {
            assert_eq!(d.observe(k * 40), 0);
        }
        // Frames 10 and 11 arrived with unusable stamps; 12 is fine: no loss.
        d.arrived_without_stamp();
        d.arrived_without_stamp();
        assert_eq!(d.observe(12 * 40), 0);
        // A real loss is still counted: 13 and 14 missing.
        assert_eq!(d.observe(15 * 40), 2);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const P: i64 = 40_000_000; // 25 fps

    #[test]
    fn a_steady_stream_loses_nothing() {
        let mut d = DropCounter::default();
        for k in 0..1000 {
            assert_eq!(d.observe(k * P + (k % 3) * 300_000), 0);
        }
        assert_eq!(d.dropped, 0);
        assert!((d.period_ns().unwrap() - P).abs() < 1_000_000);
    }

    #[test]
    fn gaps_count_the_frames_missing() {
        let mut d = DropCounter::default();
        let mut t = 0;
        for _ in 0..10 {
            t += P;
            d.observe(t);
        }
        t += 4 * P; // three frames missing
        assert_eq!(d.observe(t), 3);
        t += P;
        assert_eq!(d.observe(t), 0);
        t += 2 * P;
        assert_eq!(d.observe(t), 1);
        assert_eq!(d.dropped, 4);
    }

    #[test]
    fn losing_every_other_frame_keeps_counting() {
        let mut d = DropCounter::default();
        let mut t = 0;
        for _ in 0..10 {
            t += P;
            d.observe(t);
        }
        for _ in 0..20 {
            t += 2 * P;
            d.observe(t);
        }
        assert_eq!(d.dropped, 20);
        assert_eq!(d.period_ns(), Some(P));
    }

    #[test]
    fn nothing_is_counted_before_the_period_is_known_or_after_a_restart() {
        let mut d = DropCounter::default();
        assert_eq!(d.observe(0), 0);
        assert_eq!(d.observe(10 * P), 0, "no period yet");
        for k in 11..20 {
            d.observe(k * P);
        }
        // The source starts again from an earlier stamp (a looping replay): no drops, re-learn.
        assert_eq!(d.observe(0), 0);
        assert_eq!(d.period_ns(), None);
        assert_eq!(d.observe(i64::MAX), 0);
        assert_eq!(d.dropped, 0);
    }

    #[test]
    fn a_huge_stamp_jump_is_bounded() {
        let mut d = DropCounter::default();
        for k in 0..10 {
            d.observe(k * P);
        }
        assert_eq!(d.observe(i64::MAX), 1_000_000);
    }
}
