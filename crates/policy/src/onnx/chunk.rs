//! Chunk bookkeeping: which control tick a stamp is, when the next inference is due, and the
//! action plan from the current tick on, with ACT's temporal ensembling when configured.
//!
//! Time is counted in control ticks from the first stamp seen, `tick = round((t - t0) * rate)`,
//! so a missed tick skips a row instead of shifting the plan (the chunk is a plan in time, not a
//! queue). An inference at tick `s` predicts ticks `s .. s + H`; the next one is due at
//! `s + n_action_steps`, or as soon as the plan has no row for the current tick.
//!
//! Temporal ensembling (Zhao et al., ACT): every stored chunk that predicts tick `tau` contributes,
//! oldest first, with weight `w_i = exp(-m * i)` (i = 0 the oldest), normalised to sum 1. Without
//! it only the newest chunk is used. Pure and deterministic (f64 accumulation, fixed order).

use std::collections::VecDeque;
use unitac_core::Stamp;

/// Why a stamp cannot be placed on the tick grid.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error(
    "stamp {now} ns is before the previous control tick's {last} ns (call reset for a new episode)"
)]
pub struct TimeWentBack {
    pub last: i64,
    pub now: i64,
}

#[derive(Debug, Clone)]
struct Stored {
    start: i64,
    /// H rows of A values.
    rows: Vec<f32>,
}

#[derive(Debug, Clone)]
pub(crate) struct Schedule {
    horizon: usize,
    actions: usize,
    execute: usize,
    ensemble: Option<f64>,
    period_ns: i64,
    origin: Option<Stamp>,
    last_tick: Option<i64>,
    last_inference: Option<i64>,
    /// Oldest first; without ensembling at most one.
    chunks: VecDeque<Stored>,
}

impl Schedule {
    /// `period_ns` > 0, 1 <= `execute` <= `horizon` (the manifest's validation guarantees them).
    pub(crate) fn new(
        horizon: usize,
        actions: usize,
        execute: usize,
        ensemble: Option<f64>,
        period_ns: i64,
    ) -> Schedule {
        Schedule {
            horizon,
            actions,
            execute,
            ensemble,
            period_ns: period_ns.max(1),
            origin: None,
            last_tick: None,
            last_inference: None,
            chunks: VecDeque::new(),
        }
    }

    /// Forget every chunk and the time origin (a new episode).
    pub(crate) fn reset(&mut self) {
        self.origin = None;
        self.last_tick = None;
        self.last_inference = None;
        self.chunks.clear();
    }

    pub(crate) fn period_ns(&self) -> i64 {
        self.period_ns
    }

    /// The tick of `t` (the first stamp is tick 0), checked not to go back. Does not commit:
    /// [`Schedule::advance`] does, once the plan for the tick exists.
    pub(crate) fn tick_of(&self, t: Stamp) -> Result<i64, TimeWentBack> {
        let Some(origin) = self.origin else {
            return Ok(0);
        };
        let d = i128::from(t.0) - i128::from(origin.0);
        let p = i128::from(self.period_ns);
        // Round half away from zero.
        let tick = if d >= 0 {
            (2 * d + p) / (2 * p)
        } else {
            -((-2 * d + p) / (2 * p))
        };
        let tick = i64::try_from(tick).unwrap_or(i64::MAX);
        match self.last_tick {
            Some(last) if tick < last => Err(TimeWentBack {
                last: origin.0.saturating_add(last.saturating_mul(self.period_ns)),
                now: t.0,
            }),
            _ => Ok(tick),
        }
    }

    /// Whether tick `tick` needs a new inference.
    pub(crate) fn due(&self, tick: i64) -> bool {
        match (self.last_inference, self.chunks.back()) {
            (Some(last), Some(newest)) => {
                tick >= last.saturating_add(self.execute as i64)
                    || tick >= newest.start.saturating_add(self.horizon as i64)
            }
            _ => true,
        }
    }

    /// Commit tick `tick` of stamp `t` (and the origin on the first call); `chunk` is the
    /// inference made for it, if one was.
    pub(crate) fn advance(&mut self, t: Stamp, tick: i64, chunk: Option<Vec<f32>>) {
        if self.origin.is_none() {
            self.origin = Some(t);
        }
        self.last_tick = Some(tick);
        if let Some(rows) = chunk {
            self.last_inference = Some(tick);
            if self.ensemble.is_none() {
                self.chunks.clear();
            }
            self.chunks.push_back(Stored { start: tick, rows });
        }
        let h = self.horizon as i64;
        while self
            .chunks
            .front()
            .is_some_and(|c| c.start.saturating_add(h) <= tick)
        {
            self.chunks.pop_front();
        }
    }

    /// The plan from `tick` on: one row per tick up to the end of the newest chunk (row 0 is the
    /// action for `tick`). Empty when no chunk covers `tick`.
    pub(crate) fn plan(&self, tick: i64) -> Vec<f32> {
        let Some(newest) = self.chunks.back() else {
            return Vec::new();
        };
        let end = newest.start.saturating_add(self.horizon as i64);
        let rows = usize::try_from(end.saturating_sub(tick)).unwrap_or(0);
        let a = self.actions;
        let mut out = Vec::with_capacity(rows * a);
        let mut acc = vec![0f64; a];
        for r in 0..rows as i64 {
            let tau = tick + r;
            acc.iter_mut().for_each(|v| *v = 0.0);
            let mut wsum = 0f64;
            let covering = self
                .chunks
                .iter()
                .filter(|c| c.start <= tau && tau < c.start.saturating_add(self.horizon as i64));
            // Without ensembling only the newest chunk is stored.
            for (i, c) in covering.enumerate() {
                let w = self.ensemble.map_or(1.0, |m| (-m * i as f64).exp());
                let off = (tau - c.start) as usize * a;
                for (s, &v) in acc.iter_mut().zip(&c.rows[off..off + a]) {
                    *s += w * f64::from(v);
                }
                wsum += w;
            }
            out.extend(acc.iter().map(|s| (s / wsum) as f32));
        }
        out
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
    use super::*;

    const P: i64 = 1_000_000; // 1 kHz

    /// A chunk whose row r is `base + r` in every action.
    fn chunk(base: f32, h: usize, a: usize) -> Vec<f32> {
        (0..h)
            .flat_map(|r| std::iter::repeat_n(base + r as f32, a))
            .collect()
    }

    #[test]
    fn plain_chunks_execute_k_rows_then_infer_again() {
        let mut s = Schedule::new(4, 1, 2, None, P);
        let mut inferred = Vec::new();
        let mut first = Vec::new();
        for i in 0..6 {
            let t = Stamp(5_000 + i * P);
            let tick = s.tick_of(t).unwrap();
            let due = s.due(tick);
            inferred.push(due);
            s.advance(t, tick, due.then(|| chunk(100.0 * i as f32, 4, 1)));
            first.push(s.plan(tick)[0]);
        }
        assert_eq!(inferred, [true, false, true, false, true, false]);
        assert_eq!(first, [0.0, 1.0, 200.0, 201.0, 400.0, 401.0]);
        assert_eq!(s.plan(5), vec![401.0, 402.0, 403.0]);
    }

    #[test]
    fn a_missed_tick_skips_a_row_and_a_late_stamp_rounds_to_its_tick() {
        let mut s = Schedule::new(8, 1, 8, None, P);
        s.advance(Stamp(0), 0, Some(chunk(0.0, 8, 1)));
        // 2.4 periods later is tick 2; 2.6 would be tick 3.
        assert_eq!(s.tick_of(Stamp(2 * P + 400_000)).unwrap(), 2);
        assert_eq!(s.tick_of(Stamp(2 * P + 600_000)).unwrap(), 3);
        s.advance(Stamp(3 * P), 3, None);
        assert_eq!(s.plan(3)[0], 3.0);
        assert!(s.tick_of(Stamp(P)).is_err());
        // k = H = 8: the next inference is due when the chunk's rows are used up.
        assert!(s.due(8));
        assert!(!s.due(7));
    }

    #[test]
    fn ensembling_weights_the_oldest_prediction_most() {
        let m = 0.5;
        let mut s = Schedule::new(3, 1, 1, Some(m), P);
        s.advance(Stamp(0), 0, Some(chunk(0.0, 3, 1))); // predicts 0, 1, 2 for ticks 0..3
        s.advance(Stamp(P), 1, Some(chunk(10.0, 3, 1))); // 10, 11, 12 for ticks 1..4
        s.advance(Stamp(2 * P), 2, Some(chunk(20.0, 3, 1))); // 20, 21, 22 for ticks 2..5
        let w = [1.0, (-m).exp(), (-2.0 * m).exp()];
        let at2 = (2.0 * w[0] + 11.0 * w[1] + 20.0 * w[2]) / (w[0] + w[1] + w[2]);
        let at3 = (12.0 * w[0] + 21.0 * w[1]) / (w[0] + w[1]);
        let plan = s.plan(2);
        assert_eq!(plan.len(), 3);
        assert!((f64::from(plan[0]) - at2).abs() < 1e-5, "{plan:?}");
        assert!((f64::from(plan[1]) - at3).abs() < 1e-5, "{plan:?}");
        assert_eq!(plan[2], 22.0);
        // m = 0 is the plain average.
        let mut s = Schedule::new(2, 1, 1, Some(0.0), P);
        s.advance(Stamp(0), 0, Some(vec![1.0, 3.0]));
        s.advance(Stamp(P), 1, Some(vec![5.0, 7.0]));
        assert_eq!(s.plan(1), vec![4.0, 7.0]);
    }

    #[test]
    fn old_chunks_are_dropped_once_they_predict_nothing_current() {
        let mut s = Schedule::new(2, 1, 1, Some(0.1), P);
        for i in 0..50 {
            s.advance(Stamp(i * P), i, Some(chunk(i as f32, 2, 1)));
            assert!(s.chunks.len() <= 2);
        }
        s.reset();
        assert!(s.plan(0).is_empty());
        assert!(s.due(0));
        assert_eq!(s.tick_of(Stamp(-7)).unwrap(), 0);
    }
}
