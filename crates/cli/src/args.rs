//! Argument checks shared by every subcommand, and the forms of the stderr lines.
//!
//! Numbers: each numeric flag takes one of the value parsers here (`#[arg(value_parser =
//! args::f64_in(0.0, 600.0))]`), so clap refuses a value outside the range before any work (exit
//! 2, one line), and the message names the flag (clap adds it) and the inclusive range the check
//! applies, from the same two bounds: the message and the check cannot disagree.
//!
//! Lines on stderr: an error is `unitac: <what>` (the run ends with it, exit 1 or 2); a warning
//! on a run that goes on is `unitac: warning: <what>` ([`warn`]); `unitac-lab: ...` from the
//! lab's binary ([`crate::program`]).

use std::fmt::Display;
use std::str::FromStr;

/// Why `value` is refused: it is not within `lo` to `hi` inclusive.
fn outside(value: impl Display, lo: impl Display, hi: impl Display) -> String {
    format!("{value} is outside {lo} to {hi} (inclusive)")
}

/// `v` if it is finite and within `lo..=hi`, else the message of [`f64_in`].
pub fn check_f64(v: f64, lo: f64, hi: f64) -> Result<f64, String> {
    if v.is_finite() && v >= lo && v <= hi {
        Ok(v)
    } else {
        Err(outside(v, lo, hi))
    }
}

/// A clap value parser: a finite number within `lo` to `hi`, both inclusive (NaN, infinities and
/// anything outside are refused, the range in the message).
pub fn f64_in(lo: f64, hi: f64) -> impl Fn(&str) -> Result<f64, String> + Clone + Send + Sync {
    move |s: &str| {
        let v: f64 = s
            .trim()
            .parse()
            .map_err(|_| format!("not a number; a number from {lo} to {hi} (inclusive)"))?;
        check_f64(v, lo, hi)
    }
}

/// A clap value parser: a finite number above `lo` (excluded) and at most `hi` (a duration that
/// must be positive, ...).
pub fn f64_above(lo: f64, hi: f64) -> impl Fn(&str) -> Result<f64, String> + Clone + Send + Sync {
    move |s: &str| {
        let range = format!("above {lo}, at most {hi}");
        let v: f64 = s
            .trim()
            .parse()
            .map_err(|_| format!("not a number; a number {range}"))?;
        if v.is_finite() && v > lo && v <= hi {
            Ok(v)
        } else {
            Err(format!("{v} is outside the range: a number {range}"))
        }
    }
}

/// A clap value parser: an integer within `lo` to `hi`, both inclusive.
pub fn int_in<T>(lo: T, hi: T) -> impl Fn(&str) -> Result<T, String> + Clone + Send + Sync
where
    T: FromStr + PartialOrd + Display + Copy + Send + Sync,
{
    move |s: &str| {
        let v: T = s
            .trim()
            .parse()
            .map_err(|_| format!("not a whole number; one from {lo} to {hi} (inclusive)"))?;
        if v >= lo && v <= hi {
            Ok(v)
        } else {
            Err(outside(v, lo, hi))
        }
    }
}

/// A warning on a run that goes on: one line, `unitac: warning: <what>`, distinct from the
/// error line `unitac: <what>` that ends a run.
pub fn warn(what: impl Display) {
    eprintln!("{}: warning: {what}", crate::program());
}

/// An error that ends the run with exit 2 (bad usage or configuration, found before any work).
pub fn usage(what: impl Into<String>) -> anyhow::Error {
    anyhow::Error::new(crate::ConfigError(what.into()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bounds_are_inclusive_and_in_the_message() {
        let p = f64_in(0.1, 100.0);
        assert_eq!(p("0.1"), Ok(0.1));
        assert_eq!(p("100"), Ok(100.0));
        for bad in [
            "NaN",
            "nan",
            "inf",
            "-inf",
            "0",
            "1e9",
            "100.000001",
            "0.0999",
        ] {
            let e = p(bad).unwrap_err();
            assert!(e.contains("0.1 to 100 (inclusive)"), "{bad}: {e}");
        }
        assert!(p("x").unwrap_err().contains("0.1 to 100"));
        let n = int_in(1usize, 500);
        assert_eq!(n("1"), Ok(1));
        assert_eq!(n("500"), Ok(500));
        assert_eq!(n("0").unwrap_err(), "0 is outside 1 to 500 (inclusive)");
        assert!(n("-1").unwrap_err().contains("1 to 500"));
        assert!(n("501").is_err());
        let d = f64_above(0.0, 3600.0);
        assert_eq!(d("3600"), Ok(3600.0));
        assert_eq!(d("1e-3"), Ok(1e-3));
        for bad in ["0", "-1", "NaN", "inf", "3600.5"] {
            assert!(
                d(bad).unwrap_err().contains("above 0, at most 3600"),
                "{bad}"
            );
        }
    }
}
