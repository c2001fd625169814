//! The one summary every benchmark reports: order statistics of timed samples.
//!
//! Benchmarks time their own loops (they know what is warm-up and what is measured) and hand the
//! samples here, so `unitac-lab bench ...` and `unitac-lab report ...` state the same statistics
//! under the same names. Nothing here reads a clock.

use serde::Serialize;

/// Summary of timed samples, in seconds (reports print them in us or ms). All 0 when there
/// were no samples.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Timing {
    /// Fastest sample (least disturbed by other load on the machine).
    pub min_s: f64,
    /// Middle sample (the upper one of the two for an even count).
    pub median_s: f64,
    pub mean_s: f64,
    /// 90th percentile (nearest rank below).
    pub p90_s: f64,
}

/// Summarise samples \[s]; NaN samples sort last (`f64::total_cmp`).
pub fn timing(mut samples_s: Vec<f64>) -> Timing {
    samples_s.sort_by(f64::total_cmp);
    let n = samples_s.len();
    let at = |i: usize| samples_s.get(i).copied().unwrap_or(0.0);
    Timing {
        min_s: at(0),
        median_s: at(n / 2),
        mean_s: samples_s.iter().sum::<f64>() / n.max(1) as f64,
        p90_s: at(n * 9 / 10),
    }
}

/// Tail of latency-type samples (control ticks, message latencies), in seconds: what a
/// control loop's deadline is judged by. Nearest-rank percentiles; all 0 when there were none.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Tail {
    pub n: usize,
    pub p50_s: f64,
    pub p99_s: f64,
    pub max_s: f64,
}

/// The nearest-rank `q` quantile (0 < q <= 1) of sorted samples: the smallest sample with at
/// least a fraction `q` of the samples at or below it.
fn nearest_rank(sorted: &[f64], q: f64) -> f64 {
    let n = sorted.len();
    let rank = ((q * n as f64).ceil() as usize).clamp(1, n.max(1));
    sorted.get(rank - 1).copied().unwrap_or(0.0)
}

/// Summarise latency samples \[s] (NaN sorts last).
pub fn tail(mut samples_s: Vec<f64>) -> Tail {
    samples_s.sort_by(f64::total_cmp);
    Tail {
        n: samples_s.len(),
        p50_s: nearest_rank(&samples_s, 0.5),
        p99_s: nearest_rank(&samples_s, 0.99),
        max_s: samples_s.last().copied().unwrap_or(0.0),
    }
}

/// How regularly a paced loop ran: the achieved periods (between consecutive iteration starts)
/// against the period it was paced at, in seconds.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PeriodJitter {
    pub target_s: f64,
    pub periods: usize,
    pub p50_s: f64,
    pub p99_s: f64,
    /// Largest |period - target|.
    pub max_dev_s: f64,
}

/// Achieved periods from iteration start times \[s, any origin, increasing] of a loop paced
/// at `target_s`.
pub fn period_jitter(starts_s: &[f64], target_s: f64) -> PeriodJitter {
    let mut periods: Vec<f64> = starts_s.windows(2).map(|w| w[1] - w[0]).collect();
    let max_dev_s = periods
        .iter()
        .map(|p| (p - target_s).abs())
        .fold(0.0, f64::max);
    periods.sort_by(f64::total_cmp);
    PeriodJitter {
        target_s,
        periods: periods.len(),
        p50_s: nearest_rank(&periods, 0.5),
        p99_s: nearest_rank(&periods, 0.99),
        max_dev_s,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn order_statistics_of_unsorted_samples() {
        let t = timing(vec![9.0, 1.0, 5.0, 3.0, 7.0, 2.0, 4.0, 6.0, 8.0, 10.0]);
        assert_eq!((t.min_s, t.median_s, t.p90_s), (1.0, 6.0, 10.0));
        assert!((t.mean_s - 5.5).abs() < 1e-12);
        let one = timing(vec![3.0]);
        assert_eq!(
            (one.min_s, one.median_s, one.mean_s, one.p90_s),
            (3.0, 3.0, 3.0, 3.0)
        );
    }

    #[test]
    fn no_samples_is_all_zero() {
        let t = timing(Vec::new());
        assert_eq!(
            (t.min_s, t.median_s, t.mean_s, t.p90_s),
            (0.0, 0.0, 0.0, 0.0)
        );
    }

    #[test]
    fn tail_ses_nearest_ranks() {
        // 1..=200: p50 is the 100th sample, p99 the 198th.
        let t = tail((1..=200).rev().map(f64::from).collect());
        assert_eq!((t.n, t.p50_s, t.p99_s, t.max_s), (200, 100.0, 198.0, 200.0));
        let one = tail(vec![7.0]);
        assert_eq!((one.p50_s, one.p99_s, one.max_s), (7.0, 7.0, 7.0));
        assert_eq!(tail(Vec::new()).max_s, 0.0);
    }

    #[test]
    fn period_jitter_of_start_times() {
        // Periods 30, 40, 30 ms against 33 ms: the largest deviation is 7 ms.
        let j = period_jitter(&[1.0, 1.03, 1.07, 1.10], 0.033);
        assert_eq!(j.periods, 3);
        assert!((j.p50_s - 0.030).abs() < 1e-12, "{j:?}");
        assert!((j.p99_s - 0.040).abs() < 1e-12, "{j:?}");
        assert!((j.max_dev_s - 0.007).abs() < 1e-12, "{j:?}");
        let none = period_jitter(&[1.0], 0.033);
        assert_eq!((none.periods, none.max_dev_s), (0, 0.0));
    }
}
