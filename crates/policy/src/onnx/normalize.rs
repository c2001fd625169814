//! Feature normalisation as LeRobot defines it (see [`super::manifest::NormSpec`]), resolved
//! from a manifest entry once at load and applied in float32 on every inference.
//!
//! The operations are written out in the order LeRobot (and the numpy oracle in
//! tests/policy/policy_oracle.py) applies them, so the float32 results are the same bits.

use super::manifest::NormSpec;
use super::validate::Mismatch;

/// Statistics of one feature in float32, one value per element or per channel.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Norm {
    Identity,
    MeanStd {
        mean: Vec<f32>,
        std: Vec<f32>,
        /// Elements sharing one statistic (1: per element; the channel's size: per channel).
        inner: usize,
    },
    MinMax {
        min: Vec<f32>,
        /// max - min in float32, > 0.
        range: Vec<f32>,
        inner: usize,
    },
}

/// The normalisation mode of a manifest spelling, LeRobot's upper-case names included.
fn mode(s: &str) -> Option<&'static str> {
    match s {
        "mean_std" | "MEAN_STD" => Some("mean_std"),
        "min_max" | "MIN_MAX" => Some("min_max"),
        "identity" | "IDENTITY" => Some("identity"),
        _ => None,
    }
}

/// A statistic converted to float32; every value must stay finite.
fn stat(
    tensor: &str,
    name: &'static str,
    mode: &'static str,
    values: Option<&Vec<f64>>,
    lens: (usize, usize),
    problems: &mut Vec<Mismatch>,
) -> Option<Vec<f32>> {
    let Some(values) = values else {
        problems.push(Mismatch::MissingStat {
            tensor: tensor.to_string(),
            mode,
            stat: name,
        });
        return None;
    };
    let (numel, channels) = lens;
    if values.len() != numel && values.len() != channels {
        let expected = if numel == channels {
            numel.to_string()
        } else {
            format!("{numel} (per element) or {channels} (per channel)")
        };
        problems.push(Mismatch::StatLength {
            tensor: tensor.to_string(),
            stat: name,
            len: values.len(),
            expected,
        });
        return None;
    }
    let mut ok = true;
    let out: Vec<f32> = values.iter().map(|&v| v as f32).collect();
    for (index, (&v, &f)) in values.iter().zip(&out).enumerate() {
        if !f.is_finite() {
            problems.push(Mismatch::NonFiniteStat {
                tensor: tensor.to_string(),
                stat: name,
                index,
                value: v,
            });
            ok = false;
        }
    }
    ok.then_some(out)
}

impl Norm {
    /// Resolve `spec` for a feature of `numel` elements whose first (channel) dimension is
    /// `channels`; problems are appended to `problems` (all of them), and None comes back when
    /// there was any.
    pub(crate) fn resolve(
        tensor: &str,
        spec: Option<&NormSpec>,
        numel: usize,
        channels: usize,
        problems: &mut Vec<Mismatch>,
    ) -> Option<Norm> {
        let Some(spec) = spec else {
            problems.push(Mismatch::MissingNormalization {
                tensor: tensor.to_string(),
            });
            return None;
        };
        let Some(m) = mode(&spec.mode) else {
            problems.push(Mismatch::UnknownMode {
                tensor: tensor.to_string(),
                mode: spec.mode.clone(),
            });
            return None;
        };
        let inner_of = |len: usize| {
            if len == numel {
                1
            } else {
                numel / channels.max(1)
            }
        };
        let lens = (numel, channels);
        let start = problems.len();
        let same_len = |a: &[f32], b: &[f32], stat: &'static str, of: &str, p: &mut Vec<_>| {
            if a.len() != b.len() {
                p.push(Mismatch::StatLength {
                    tensor: tensor.to_string(),
                    stat,
                    len: b.len(),
                    expected: format!("{} (as many as {of})", a.len()),
                });
            }
        };
        match m {
            "mean_std" => {
                let mean = stat(tensor, "mean", m, spec.mean.as_ref(), lens, problems);
                let std = stat(tensor, "std", m, spec.std.as_ref(), lens, problems);
                for (index, &s) in std.iter().flatten().enumerate() {
                    if s.is_nan() || s < super::validate::MIN_SCALE {
                        problems.push(Mismatch::StdNotPositive {
                            tensor: tensor.to_string(),
                            index,
                            value: f64::from(s),
                        });
                    }
                }
                let (Some(mean), Some(std)) = (mean, std) else {
                    return None;
                };
                same_len(&mean, &std, "std", "mean", problems);
                (problems.len() == start).then(|| Norm::MeanStd {
                    inner: inner_of(mean.len()),
                    mean,
                    std,
                })
            }
            "min_max" => {
                let min = stat(tensor, "min", m, spec.min.as_ref(), lens, problems);
                let max = stat(tensor, "max", m, spec.max.as_ref(), lens, problems);
                let (Some(min), Some(max)) = (min, max) else {
                    return None;
                };
                same_len(&min, &max, "max", "min", problems);
                let range: Vec<f32> = min.iter().zip(&max).map(|(lo, hi)| hi - lo).collect();
                for (index, ((&lo, &hi), &r)) in min.iter().zip(&max).zip(&range).enumerate() {
                    if !(r >= super::validate::MIN_SCALE && r.is_finite()) {
                        problems.push(Mismatch::EmptyRange {
                            tensor: tensor.to_string(),
                            index,
                            min: f64::from(lo),
                            max: f64::from(hi),
                        });
                    }
                }
                (problems.len() == start).then(|| Norm::MinMax {
                    inner: inner_of(min.len()),
                    min,
                    range,
                })
            }
            _ => Some(Norm::Identity),
        }
    }

    /// Raw feature values -> model input, into `out` (same length as `x`).
    pub(crate) fn forward(&self, x: &[f32], out: &mut Vec<f32>) {
        out.clear();
        match self {
            Norm::Identity => out.extend_from_slice(x),
            Norm::MeanStd { mean, std, inner } => {
                out.extend(x.iter().enumerate().map(|(i, &v)| {
                    let c = i / inner;
                    (v - mean[c]) / std[c]
                }));
            }
            Norm::MinMax { min, range, inner } => {
                out.extend(x.iter().enumerate().map(|(i, &v)| {
                    let c = i / inner;
                    (v - min[c]) / range[c] * 2.0 - 1.0
                }));
            }
        }
    }

    /// Model output -> SI values, in place; `x` is rows of `width` values, statistic `j` applies
    /// to column `j` (output statistics are per action).
    pub(crate) fn inverse_rows(&self, x: &mut [f32], width: usize) {
        let col = |i: usize| i % width.max(1);
        match self {
            Norm::Identity => {}
            Norm::MeanStd { mean, std, .. } => {
                for (i, v) in x.iter_mut().enumerate() {
                    let c = col(i);
                    *v = *v * std[c] + mean[c];
                }
            }
            Norm::MinMax { min, range, .. } => {
                for (i, v) in x.iter_mut().enumerate() {
                    let c = col(i);
                    *v = (*v + 1.0) / 2.0 * range[c] + min[c];
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
    use super::*;

    fn spec(mode: &str) -> NormSpec {
        NormSpec {
            mode: mode.into(),
            mean: None,
            std: None,
            min: None,
            max: None,
        }
    }

    #[test]
    fn mean_std_per_channel_broadcasts_over_the_rest() {
        let mut s = spec("MEAN_STD");
        s.mean = Some(vec![1.0, -1.0]);
        s.std = Some(vec![2.0, 0.5]);
        let mut p = Vec::new();
        let n = Norm::resolve("img", Some(&s), 4, 2, &mut p).unwrap();
        assert!(p.is_empty());
        let mut out = Vec::new();
        n.forward(&[3.0, 5.0, 0.0, -2.0], &mut out);
        assert_eq!(out, vec![1.0, 2.0, 2.0, -2.0]);
    }

    #[test]
    fn min_max_maps_the_range_to_minus_one_one_and_back() {
        let mut s = spec("min_max");
        s.min = Some(vec![0.0, 10.0]);
        s.max = Some(vec![4.0, 20.0]);
        let mut p = Vec::new();
        let n = Norm::resolve("a", Some(&s), 2, 2, &mut p).unwrap();
        let mut out = Vec::new();
        n.forward(&[0.0, 20.0], &mut out);
        assert_eq!(out, vec![-1.0, 1.0]);
        let mut back = vec![0.0, 0.0, 1.0, -1.0];
        n.inverse_rows(&mut back, 2);
        assert_eq!(back, vec![2.0, 15.0, 4.0, 10.0]);
    }

    #[test]
    fn every_bad_statistic_is_listed() {
        let mut s = spec("mean_std");
        s.mean = Some(vec![0.0, 1e39, 0.0]);
        s.std = Some(vec![1.0, 0.0, -2.0]);
        let mut p = Vec::new();
        assert!(Norm::resolve("x", Some(&s), 3, 3, &mut p).is_none());
        assert!(
            matches!(
                p.as_slice(),
                [
                    Mismatch::NonFiniteStat { index: 1, .. },
                    Mismatch::StdNotPositive { index: 1, .. },
                    Mismatch::StdNotPositive { index: 2, .. }
                ]
            ),
            "{p:?}"
        );
        let mut s = spec("min_max");
        s.min = Some(vec![0.0, 1.0]);
        s.max = Some(vec![1.0, 1.0]);
        p.clear();
        assert!(Norm::resolve("y", Some(&s), 2, 2, &mut p).is_none());
        assert!(
            matches!(p.as_slice(), [Mismatch::EmptyRange { index: 1, .. }]),
            "{p:?}"
        );
        p.clear();
        assert!(Norm::resolve("z", None, 2, 2, &mut p).is_none());
        assert!(Norm::resolve("z", Some(&spec("zscore")), 2, 2, &mut p).is_none());
        assert!(Norm::resolve("z", Some(&spec("mean_std")), 2, 2, &mut p).is_none());
        assert!(
            matches!(
                p.as_slice(),
                [
                    Mismatch::MissingNormalization { .. },
                    Mismatch::UnknownMode { .. },
                    Mismatch::MissingStat { stat: "mean", .. },
                    Mismatch::MissingStat { stat: "std", .. }
                ]
            ),
            "{p:?}"
        );
    }
}
