//! Where an axis starts and ends and where its ticks go, in plot units (log10 of the value on a
//! log axis): whole decades labelled 10^n on log axes, 1/2/5 steps on linear ones.

use crate::PlotError;
use crate::chart::{Axis, Scale};

/// An axis as drawn, in plot units.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct AxisLayout {
    pub lo: f64,
    /// Top of the data range.
    pub hi: f64,
    /// Top of the drawn range: `hi`, plus the overflow strip when there is one.
    pub end: f64,
    /// Labelled ticks (bold grid lines).
    pub ticks: Vec<(f64, String)>,
    /// Unlabelled grid lines (other decades, 2..9 within a decade).
    pub light: Vec<f64>,
}

/// Share of the data range the overflow strip adds on top.
const STRIP: f64 = 0.1;

impl AxisLayout {
    /// `data`: the positions (plot units) of everything drawn on this axis. At most
    /// `max_labels` ticks are labelled. `strip`: add the overflow strip.
    pub fn new(
        axis: &Axis,
        data: &[f64],
        strip: bool,
        max_labels: usize,
        chart: &str,
        name: &'static str,
    ) -> Result<Self, PlotError> {
        let bad = |lo: f64, hi: f64| PlotError::Range {
            chart: chart.to_string(),
            axis: name,
            lo,
            hi,
        };
        let (lo, hi) = match axis.range {
            Some((a, b)) => match (axis.to_plot(a), axis.to_plot(b)) {
                (Some(lo), Some(hi)) if lo < hi => (lo, hi),
                _ => return Err(bad(a, b)),
            },
            None => auto_range(axis.scale, data, max_labels),
        };
        let (ticks, light) = match &axis.ticks {
            Some(given) => (
                given
                    .iter()
                    .filter_map(|(v, l)| axis.to_plot(*v).map(|t| (t, l.clone())))
                    .filter(|(t, _)| inside(*t, lo, hi))
                    .collect(),
                Vec::new(),
            ),
            None => match axis.scale {
                Scale::Log => decade_ticks(lo, hi, max_labels),
                Scale::Linear => linear_ticks(lo, hi, max_labels),
            },
        };
        let end = if strip { hi + STRIP * (hi - lo) } else { hi };
        Ok(Self {
            lo,
            hi,
            end,
            ticks,
            light,
        })
    }

    pub fn tick_positions(&self) -> Vec<f64> {
        self.ticks.iter().map(|(t, _)| *t).collect()
    }

    /// The label of the tick at `t`, or nothing.
    pub fn label_at(&self, t: f64) -> String {
        self.ticks
            .iter()
            .find(|(p, _)| (p - t).abs() <= 1e-9 * (1.0 + t.abs()))
            .map(|(_, l)| l.clone())
            .unwrap_or_default()
    }
}

fn inside(t: f64, lo: f64, hi: f64) -> bool {
    let eps = 1e-9 * (hi - lo);
    t >= lo - eps && t <= hi + eps
}

fn min_max(data: &[f64]) -> Option<(f64, f64)> {
    let lo = data.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = data.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    (lo.is_finite() && hi.is_finite()).then_some((lo, hi))
}

fn auto_range(scale: Scale, data: &[f64], max_labels: usize) -> (f64, f64) {
    let Some((lo, hi)) = min_max(data) else {
        return (0.0, 1.0);
    };
    match scale {
        Scale::Log => {
            let (lo, hi) = (lo.floor(), hi.ceil());
            (lo, hi.max(lo + 1.0))
        }
        Scale::Linear => {
            let (lo, hi) = if hi - lo > 1e-12 * (1.0 + lo.abs().max(hi.abs())) {
                (lo, hi)
            } else {
                let pad = 0.5 * lo.abs().max(1.0);
                (lo - pad, hi + pad)
            };
            let step = nice_step(hi - lo, max_labels);
            ((lo / step).floor() * step, (hi / step).ceil() * step)
        }
    }
}

/// 1, 2 or 5 times a power of ten, giving at most about `max_labels` steps over `span`.
fn nice_step(span: f64, max_labels: usize) -> f64 {
    let raw = span / max_labels.max(2) as f64;
    let mag = 10f64.powf(raw.log10().floor());
    [1.0, 2.0, 5.0, 10.0]
        .iter()
        .map(|m| m * mag)
        .find(|s| *s >= raw)
        .unwrap_or(10.0 * mag)
}

fn linear_ticks(lo: f64, hi: f64, max_labels: usize) -> (Vec<(f64, String)>, Vec<f64>) {
    let step = nice_step(hi - lo, max_labels);
    let decimals = (-step.log10().floor()).max(0.0) as usize;
    let first = (lo / step).ceil() as i64;
    let last = (hi / step).floor() as i64;
    let ticks = (first..=last)
        .map(|k| {
            let v = k as f64 * step;
            (v, format!("{:.*}", decimals, if k == 0 { 0.0 } else { v }))
        })
        .collect();
    (ticks, Vec::new())
}

fn decade_ticks(lo: f64, hi: f64, max_labels: usize) -> (Vec<(f64, String)>, Vec<f64>) {
    let (first, last) = (lo.ceil() as i64, hi.floor() as i64);
    let count = (last - first + 1).max(1) as usize;
    // Label every k-th decade (multiples of k, so 1 stays labelled) so that the labels fit;
    // grid lines at every decade.
    let every = count.div_ceil(max_labels.max(1)).max(1) as i64;
    let mut ticks = Vec::new();
    let mut light = Vec::new();
    for d in first..=last {
        if d.rem_euclid(every) == 0 {
            ticks.push((d as f64, decade_label(d)));
        } else {
            light.push(d as f64);
        }
    }
    // Minor lines at 2..9 when there are few decades.
    if hi - lo <= 3.0 {
        for d in (lo.floor() as i64)..=(hi.ceil() as i64) {
            for m in 2..10 {
                let t = d as f64 + f64::from(m).log10();
                if inside(t, lo, hi) {
                    light.push(t);
                }
            }
        }
    }
    (ticks, light)
}

/// "1", "10", "10⁻³": a power of ten with a superscript exponent.
pub(crate) fn decade_label(d: i64) -> String {
    match d {
        0 => "1".into(),
        1 => "10".into(),
        _ => {
            let sup: String = d
                .to_string()
                .chars()
                .map(|c| match c {
                    '-' => '⁻',
                    '0' => '⁰',
                    '1' => '¹',
                    '2' => '²',
                    '3' => '³',
                    '4' => '⁴',
                    '5' => '⁵',
                    '6' => '⁶',
                    '7' => '⁷',
                    '8' => '⁸',
                    _ => '⁹',
                })
                .collect();
            format!("10{sup}")
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn log_axis_spans_whole_decades_with_superscript_labels() {
        let axis = Axis::log("t");
        let l = AxisLayout::new(&axis, &[-2.2, -0.4], false, 10, "c", "x").unwrap();
        assert_eq!((l.lo, l.hi, l.end), (-3.0, 0.0, 0.0));
        let labels: Vec<&str> = l.ticks.iter().map(|(_, s)| s.as_str()).collect();
        assert_eq!(labels, ["10⁻³", "10⁻²", "10⁻¹", "1"]);
        // Minor lines at 2..9 inside the range.
        assert!(
            l.light
                .iter()
                .any(|t| (t - (-3.0 + 2f64.log10())).abs() < 1e-12)
        );
        assert_eq!(decade_label(12), "10¹²");
        assert_eq!(l.label_at(-2.0), "10⁻²");
        assert_eq!(l.label_at(-2.5), "");
    }

    #[test]
    fn many_decades_label_every_kth_and_strip_adds_room() {
        let l = AxisLayout::new(&Axis::log("e"), &[-16.0, 0.0], true, 8, "c", "y").unwrap();
        // 17 decades, at most 8 labels: every third decade, 1 among them.
        let labelled: Vec<f64> = l.ticks.iter().map(|t| t.0).collect();
        assert_eq!(labelled, [-15.0, -12.0, -9.0, -6.0, -3.0, 0.0]);
        assert!(l.light.contains(&-16.0) && l.light.contains(&-1.0));
        assert!((l.end - 1.6).abs() < 1e-12);
    }

    #[test]
    fn linear_axis_rounds_to_steps_and_bad_ranges_are_errors() {
        let l = AxisLayout::new(&Axis::linear("f"), &[0.3, 9.6], false, 6, "c", "y").unwrap();
        assert_eq!((l.lo, l.hi), (0.0, 10.0));
        assert_eq!(l.ticks.first().map(|t| t.1.as_str()), Some("0"));
        assert_eq!(l.ticks.last().map(|t| t.1.as_str()), Some("10"));
        let flat = AxisLayout::new(&Axis::linear("f"), &[2.0, 2.0], false, 6, "c", "y").unwrap();
        assert!(flat.lo < 2.0 && flat.hi > 2.0);
        for axis in [
            Axis::log("e").range(0.0, 1.0),
            Axis::linear("f").range(3.0, 3.0),
        ] {
            let e = AxisLayout::new(&axis, &[], false, 6, "panel", "x").unwrap_err();
            assert!(e.to_string().contains("panel"), "{e}");
        }
    }
}
