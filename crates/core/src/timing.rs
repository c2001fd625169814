//! The one summary every benchmark reports: order statistics of timed samples.
//!
//! Benchmarks time their own loops (they know what is warm-up and what is measured) and hand the
//! samples here, so `unitac bench ...` and `unitac report ...` state the same statistics under
//! the same names. Nothing here reads a clock.

use serde::Serialize;

/// Summary of timed samples, in microseconds. All 0 when there were no samples.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Timing {
    /// Fastest sample (least disturbed by other load on the machine).
    pub min_us: f64,
    /// Middle sample (the upper one of the two for an even count).
    pub median_us: f64,
    pub mean_us: f64,
    /// 90th percentile (nearest rank below).
    pub p90_us: f64,
}

/// Summarise samples \[us]; NaN samples sort last (`f64::total_cmp`).
pub fn timing(mut samples_us: Vec<f64>) -> Timing {
    samples_us.sort_by(f64::total_cmp);
    let n = samples_us.len();
    let at = |i: usize| samples_us.get(i).copied().unwrap_or(0.0);
    Timing {
        min_us: at(0),
        median_us: at(n / 2),
        mean_us: samples_us.iter().sum::<f64>() / n.max(1) as f64,
        p90_us: at(n * 9 / 10),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn order_statistics_of_unsorted_samples() {
        let t = timing(vec![9.0, 1.0, 5.0, 3.0, 7.0, 2.0, 4.0, 6.0, 8.0, 10.0]);
        assert_eq!((t.min_us, t.median_us, t.p90_us), (1.0, 6.0, 10.0));
        assert!((t.mean_us - 5.5).abs() < 1e-12);
        let one = timing(vec![3.0]);
        assert_eq!(
            (one.min_us, one.median_us, one.mean_us, one.p90_us),
            (3.0, 3.0, 3.0, 3.0)
        );
    }

    #[test]
    fn no_samples_is_all_zero() {
        let t = timing(Vec::new());
        assert_eq!(
            (t.min_us, t.median_us, t.mean_us, t.p90_us),
            (0.0, 0.0, 0.0, 0.0)
        );
    }
}
