//! The simulator's numerics report's two figures (`unitac-lab report sim`; the report is
//! unitac_sim::numerics): relative error against run time per measure (diverged runs as crosses
//! on a strip above the data), and the stability map per method with the derived bound.

use std::path::{Path, PathBuf};
use unitac_plot::{Axis, BLACK, Cell, Chart, Figure, LegendEntry, Marker, PlotError, Rgb, Series};
use unitac_sim::numerics::{
    AccuracyRow, NumericsReport, Reference, end_state_bounds, rel, series_name,
};
use unitac_sim::world::{Cup, Method};

const METHOD_COLOURS: [Rgb; 4] = [
    [214, 39, 40],
    [31, 119, 180],
    [44, 160, 44],
    [148, 103, 189],
];
const STABLE: Rgb = [150, 215, 150];
const UNSTABLE: Rgb = [240, 150, 140];

/// A method's runs' colour and name (the tables' name, [`series_name`]).
fn series_style(m: Method, substeps: bool) -> (Rgb, &'static str) {
    let colour = match (m, substeps) {
        (_, true) => METHOD_COLOURS[3],
        (Method::ExplicitEuler, _) => METHOD_COLOURS[0],
        (Method::SemiImplicitEuler, _) => METHOD_COLOURS[1],
        (Method::BackwardEuler, _) => METHOD_COLOURS[2],
    };
    (colour, series_name(m, substeps))
}

fn cup_marker(i: usize) -> Marker {
    [
        Marker::Circle,
        Marker::Square,
        Marker::Triangle,
        Marker::Diamond,
    ][i % 4]
}

/// Decades covering `v` (at least one), as a range in data units.
fn decades(v: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = v.fold((f64::INFINITY, 0.0f64), |(lo, hi), t| {
        (lo.min(t), hi.max(t))
    });
    if !(lo.is_finite() && lo > 0.0) {
        return (1e-6, 1.0);
    }
    let (a, b) = (lo.log10().floor(), hi.log10().ceil());
    (10f64.powf(a), 10f64.powf(b.max(a + 1.0)))
}

/// Write the report's `sim_accuracy.png` and `sim_stability.png` into `dir`.
pub fn write_plots(report: &NumericsReport, dir: &Path) -> Result<Vec<PathBuf>, PlotError> {
    let a = dir.join("sim_accuracy.png");
    accuracy_plot(report).save(&a)?;
    let b = dir.join("sim_stability.png");
    stability_plot(report).save(&b)?;
    Ok(vec![a, b])
}

/// Relative error against run time, log-log, one panel per measure, one line per cup and
/// method; runs that diverged or grew are crosses on the strip above the data.
fn accuracy_plot(report: &NumericsReport) -> Figure {
    let (t0, t1) = decades(report.accuracy.iter().map(|a| a.wall_s.max(1e-6)));
    type Measure = fn(&AccuracyRow, &Reference) -> f64;
    let panels: [(&str, Measure); 3] = [
        ("final deformation", |a, r| {
            rel(a.final_deformation_m, r.final_deformation_m)
        }),
        ("deformation when the finger stops", |a, r| {
            rel(a.stop_deformation_m, r.stop_deformation_m)
        }),
        ("peak grip force", |a, r| {
            rel(a.peak_force_n, r.peak_force_n)
        }),
    ];
    let mut fig = Figure::new(1640, 700).columns(3);
    for (name, measure) in panels {
        let mut chart = Chart::new(
            name,
            Axis::log("run time [s]").range(t0, t1),
            Axis::log("relative error"),
        )
        .overflow("diverged");
        for (ci, r) in report.references.iter().enumerate() {
            for m in Method::ALL {
                for sub in [false, true] {
                    let points: Vec<(f64, f64)> = report
                        .accuracy
                        .iter()
                        .filter(|a| a.cup == r.cup.label && a.method == m && a.substeps == sub)
                        .map(|a| {
                            let e = if a.diverged.is_some() || !a.stable {
                                f64::INFINITY
                            } else {
                                // Exact agreement is drawn at 1e-16.
                                measure(a, r).max(1e-16)
                            };
                            (a.wall_s.max(1e-6), e)
                        })
                        .collect();
                    if points.is_empty() {
                        continue;
                    }
                    let (colour, _) = series_style(m, sub);
                    chart = chart.series(Series::new(colour, points).marker(cup_marker(ci)));
                }
            }
        }
        fig = fig.panel(chart);
    }
    for (m, sub) in [
        (Method::ExplicitEuler, false),
        (Method::SemiImplicitEuler, false),
        (Method::BackwardEuler, false),
        (Method::SemiImplicitEuler, true),
    ] {
        let (colour, name) = series_style(m, sub);
        fig = fig.legend(LegendEntry::line(name, colour));
    }
    for (ci, r) in report.references.iter().enumerate() {
        fig = fig.legend(LegendEntry::marker(
            format!("{} cup, {} N/m", r.cup.label, r.cup.k_n_per_m),
            BLACK,
            cup_marker(ci),
        ));
    }
    fig.note(
        "points along a line: steps 1e-2 .. 1e-6 s (sub-stepped: outer steps 1e-2 .. 1e-3 s); reference: semi-implicit Euler at 1e-7 s",
    )
}

/// Stability map per method: cells green (stable) or red (unstable), '*' where the derived
/// bound predicts otherwise, the bound as a black line.
fn stability_plot(report: &NumericsReport) -> Figure {
    let ks = &report.map_stiffness_n_per_m;
    let hs = &report.map_steps_s;
    // Log range half a cell beyond the first and last sample, and the half cell.
    let span = |v: &[f64]| -> (f64, f64, f64) {
        let lo = v.iter().cloned().fold(f64::INFINITY, f64::min).log10();
        let hi = v.iter().cloned().fold(0.0, f64::max).log10();
        let d = if v.len() > 1 {
            0.5 * (hi - lo) / (v.len() - 1) as f64
        } else {
            0.5
        };
        (lo - d, hi + d, d)
    };
    let mut fig = Figure::new(1400, 580).columns(3);
    if !ks.is_empty() && !hs.is_empty() {
        let (kx0, kx1, dk) = span(ks);
        let (hy0, hy1, dh) = span(hs);
        let p = |l: f64| 10f64.powf(l);
        for m in Method::ALL {
            let mut chart = Chart::new(
                series_style(m, false).1,
                Axis::log("wall stiffness k [N/m]").range(p(kx0), p(kx1)),
                Axis::log("step h [s]").range(p(hy0), p(hy1)),
            );
            for c in report.stability.iter().filter(|c| c.method == m) {
                let (lk, lh) = (c.k_n_per_m.log10(), c.step_s.log10());
                chart = chart.cell(Cell {
                    x: (p(lk - dk), p(lk + dk)),
                    y: (p(lh - dh), p(lh + dh)),
                    colour: if c.observed_stable { STABLE } else { UNSTABLE },
                    mark: (c.predicted_stable != c.observed_stable).then(|| "*".into()),
                });
            }
            if m == Method::BackwardEuler {
                chart = chart.note((0.05, 0.07), "no bound (A-stable)", BLACK);
            } else {
                let bound: Vec<(f64, f64)> = (0..=80)
                    .map(|i| {
                        let k = p(kx0 + (kx1 - kx0) * f64::from(i) / 80.0);
                        let (be, bs) = end_state_bounds(&Cup::new("map", 0.080, k));
                        (k, if m == Method::ExplicitEuler { be } else { bs })
                    })
                    .collect();
                chart = chart.series(Series::new(BLACK, bound));
            }
            fig = fig.panel(chart);
        }
    }
    fig.legend(LegendEntry::fill("stable", STABLE))
        .legend(LegendEntry::fill(
            "unstable (diverged or growing)",
            UNSTABLE,
        ))
        .legend(LegendEntry::line("derived bound", BLACK))
        .note("* the bound predicts otherwise")
        .note("task: close to 1 cm deformation (or 20 N), hold 0.3 s; no sub-steps")
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use unitac_sim::numerics::{NumericsOptions, report};

    #[test]
    fn a_small_report_has_both_plots() {
        let opts = NumericsOptions {
            cups: vec![Cup::stiff()],
            steps_s: vec![1e-3, 1e-4],
            ref_step_s: 1e-6,
            map_stiffness: vec![100.0, 1e4],
            map_steps: vec![1e-4, 1e-3],
        };
        let r = report(&opts);
        let dir = std::env::temp_dir().join(format!("unitac-numerics-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let files = write_plots(&r, &dir).unwrap();
        assert_eq!(files.len(), 2);
        for f in &files {
            assert!(std::fs::metadata(f).unwrap().len() > 1000);
        }
        std::fs::remove_dir_all(&dir).ok();
    }
}
