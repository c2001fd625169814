//! Rendered charts checked by their pixels: points land where the axes put them, unshowable
//! points are skipped or go to the overflow strip, lines break at gaps, text is drawn, and the
//! same figure gives the same bytes.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use unitac_plot::{Axis, Chart, Figure, LegendEntry, Marker, PlotError, Rendered, Series, Stroke};

/// A colour nothing else in a figure uses (text and grid are grey levels).
const PROBE: [u8; 3] = [255, 0, 255];

fn probe_pixels(r: &Rendered) -> Vec<(f64, f64)> {
    r.image
        .enumerate_pixels()
        .filter(|(_, _, p)| p.0 == PROBE)
        .map(|(x, y, _)| (f64::from(x), f64::from(y)))
        .collect()
}

/// Centroid of the probe pixels within `radius` of `c`.
fn centroid_near(px: &[(f64, f64)], c: (f64, f64), radius: f64) -> Option<(f64, f64)> {
    let near: Vec<&(f64, f64)> = px
        .iter()
        .filter(|p| (p.0 - c.0).abs() <= radius && (p.1 - c.1).abs() <= radius)
        .collect();
    (!near.is_empty()).then(|| {
        let n = near.len() as f64;
        (
            near.iter().map(|p| p.0).sum::<f64>() / n,
            near.iter().map(|p| p.1).sum::<f64>() / n,
        )
    })
}

fn one_panel(chart: Chart) -> Figure {
    Figure::new(640, 480).panel(chart)
}

#[test]
fn log_log_points_land_a_decade_apart() {
    let pts = vec![(3.0, 2.0), (30.0, 20.0), (300.0, 200.0)];
    let chart = Chart::new(
        "probe",
        Axis::log("x").range(1.0, 1000.0),
        Axis::log("y").range(1.0, 1000.0),
    )
    .series(
        Series::new(PROBE, pts.clone())
            .stroke(Stroke::None)
            .marker(Marker::Square),
    );
    let r = one_panel(chart).render().unwrap();
    let g = r.panels[0];
    let px = probe_pixels(&r);
    let mut found = Vec::new();
    for &(x, y) in &pts {
        let want = g.pixel(x, y).unwrap();
        let got = centroid_near(&px, want, 10.0).unwrap_or_else(|| panic!("no marker at {want:?}"));
        assert!(
            (got.0 - want.0).abs() <= 1.5 && (got.1 - want.1).abs() <= 1.5,
            "marker of {x},{y} at {got:?}, expected {want:?}"
        );
        found.push(got);
    }
    // Equal decades are equal distances, up and to the right, a third of the plot area apart.
    let (d1, d2) = (
        (found[1].0 - found[0].0, found[0].1 - found[1].1),
        (found[2].0 - found[1].0, found[1].1 - found[2].1),
    );
    assert!(
        (d1.0 - d2.0).abs() <= 1.0 && (d1.1 - d2.1).abs() <= 1.0,
        "{d1:?} {d2:?}"
    );
    let third = f64::from(g.right - g.left) / 3.0;
    assert!((d1.0 - third).abs() <= 2.0, "{d1:?} vs {third}");
    assert!(d1.1 > 0.0);
    // Nothing else in the probe colour.
    assert!(px.iter().all(|p| {
        found
            .iter()
            .any(|f| (p.0 - f.0).abs() <= 7.0 && (p.1 - f.1).abs() <= 7.0)
    }));
}

#[test]
fn unshowable_points_are_skipped_and_diverged_ones_go_to_the_strip() {
    let pts = vec![
        (1e-3, 1e-2),
        (f64::NAN, 1e-3),
        (1e-2, 0.0),
        (-1.0, 1e-3),
        (1e-1, f64::INFINITY),
        (1.0, f64::NAN),
        (10.0, 1e-4),
    ];
    let base = Chart::new("skip", Axis::log("t"), Axis::log("e")).series(
        Series::new(PROBE, pts)
            .stroke(Stroke::None)
            .marker(Marker::Circle),
    );
    // Without a strip: only the two showable points are drawn.
    let r = one_panel(base.clone()).render().unwrap();
    let g = r.panels[0];
    let px = probe_pixels(&r);
    let a = g.pixel(1e-3, 1e-2).unwrap();
    let b = g.pixel(10.0, 1e-4).unwrap();
    assert!(centroid_near(&px, a, 8.0).is_some() && centroid_near(&px, b, 8.0).is_some());
    assert!(
        px.iter().all(|p| [a, b]
            .iter()
            .any(|c| (p.0 - c.0).abs() <= 7.0 && (p.1 - c.1).abs() <= 7.0)),
        "probe pixels away from the two valid points"
    );
    // With a strip: the two non-finite y values are crosses above the data, at their x.
    let r = one_panel(base.overflow("diverged")).render().unwrap();
    let g = r.panels[0];
    let px = probe_pixels(&r);
    let top = g.pixel(1.0, 1e-2).unwrap().1; // 1e-2 is the top decade of the data
    for x in [1e-1, 1.0] {
        let col = g.pixel(x, 1e-2).unwrap().0;
        let strip: Vec<&(f64, f64)> = px
            .iter()
            .filter(|p| (p.0 - col).abs() <= 6.0 && p.1 < top - 2.0)
            .collect();
        assert!(strip.len() >= 8, "no cross at x={x}: {} px", strip.len());
    }
}

#[test]
fn a_line_breaks_where_a_point_is_missing() {
    let chart = |mid: f64| {
        Chart::new(
            "gap",
            Axis::log("x").range(1.0, 100.0),
            Axis::log("y").range(1.0, 100.0),
        )
        .series(Series::new(PROBE, vec![(1.5, 1.5), (10.0, mid), (70.0, 70.0)]).width(3))
    };
    let probe_at = |r: &Rendered, at: (f64, f64)| centroid_near(&probe_pixels(r), at, 3.0);
    let whole = one_panel(chart(10.0)).render().unwrap();
    let g = whole.panels[0];
    let quarter = g.pixel(10f64.powf(0.6), 10f64.powf(0.6)).unwrap();
    assert!(
        probe_at(&whole, quarter).is_some(),
        "the unbroken line passes there"
    );
    let broken = one_panel(chart(f64::NAN)).render().unwrap();
    assert!(
        probe_at(&broken, quarter).is_none(),
        "a NaN point must break the line"
    );
}

#[test]
fn dashed_lines_have_gaps_and_bands_are_filled() {
    let chart = Chart::new(
        "time series",
        Axis::linear("t [s]").range(0.0, 10.0),
        Axis::linear("force [N]").range(0.0, 10.0),
    )
    .series(Series::new(PROBE, vec![(0.0, 5.0), (10.0, 5.0)]).stroke(Stroke::Dashed))
    .band(unitac_plot::Band {
        y: (7.0, 9.0),
        colour: [0, 0, 255],
        label: Some("target".into()),
    });
    let r = one_panel(chart).render().unwrap();
    let g = r.panels[0];
    let (x0, y) = g.pixel(0.0, 5.0).unwrap();
    let (x1, _) = g.pixel(10.0, 5.0).unwrap();
    let on = (x0 as u32..x1 as u32)
        .filter(|&x| r.image.get_pixel(x, y.round() as u32).0 == PROBE)
        .count() as f64;
    let share = on / (x1 - x0);
    assert!(share > 0.4 && share < 0.8, "dashed coverage {share}");
    // Inside the band: a light blue tint, not white.
    let (bx, by) = g.pixel(3.3, 8.0).unwrap();
    let p = r.image.get_pixel(bx as u32, by as u32).0;
    assert!(p[2] > p[0] + 20 && p[0] > 150, "band fill {p:?}");
}

#[test]
fn heatmap_cells_and_marks_sit_in_their_rows_and_columns() {
    let (g_, r_) = ([120, 200, 120], [230, 110, 110]);
    let cells = vec![
        vec![(g_, None), (r_, None), (r_, Some("*".to_string()))],
        vec![(g_, None), (g_, None), (r_, None)],
    ];
    let cols: Vec<String> = ["2", "4", "8"].iter().map(|s| s.to_string()).collect();
    let rows: Vec<String> = ["s=1", "s=3"].iter().map(|s| s.to_string()).collect();
    let chart = Chart::heatmap("map", ("steps", &cols), ("guidance", &rows), &cells);
    let r = one_panel(chart).render().unwrap();
    let g = r.panels[0];
    for (ri, row) in cells.iter().enumerate() {
        for (ci, (colour, _)) in row.iter().enumerate() {
            // A quarter into the cell (the centre may hold a mark).
            let (x, y) = g.pixel(ci as f64 + 0.25, ri as f64 + 0.25).unwrap();
            assert_eq!(
                &r.image.get_pixel(x as u32, y as u32).0,
                colour,
                "cell {ri},{ci}"
            );
        }
    }
    let (cx, cy) = g.pixel(2.5, 0.5).unwrap();
    let dark = (-8..=8)
        .flat_map(|dy| (-8..=8).map(move |dx| (dx, dy)))
        .filter(|(dx, dy)| {
            let p = r
                .image
                .get_pixel((cx as i32 + dx) as u32, (cy as i32 + dy) as u32)
                .0;
            p.iter().all(|v| *v < 100)
        })
        .count();
    assert!(dark >= 4, "mark '*' missing: {dark} dark px");
}

#[test]
fn text_is_drawn_and_the_same_figure_gives_the_same_bytes() {
    let fig = |title: &str| {
        Figure::new(500, 400)
            .panel(
                Chart::new(
                    title,
                    Axis::log("run time [s]"),
                    Axis::log("relative error"),
                )
                .series(
                    Series::new([31, 119, 180], vec![(1e-4, 1e-1), (1e-2, 1e-6)])
                        .label("heun")
                        .marker(Marker::Diamond),
                ),
            )
            .legend_from_series()
            .legend(LegendEntry::marker("soft cup", [0, 0, 0], Marker::Triangle))
            .note("reference: semi-implicit at 1e-7 s")
    };
    let a = fig("accuracy").png().unwrap();
    assert_eq!(a, fig("accuracy").png().unwrap());
    assert_ne!(a, fig("accuracy!").png().unwrap());
    let r = fig("accuracy").render().unwrap();
    let g = r.panels[0];
    // Title above the plot area, tick labels below it, legend and note under the panel.
    let dark = |x0: u32, y0: u32, x1: u32, y1: u32| {
        (y0..y1)
            .flat_map(|y| (x0..x1).map(move |x| (x, y)))
            .filter(|&(x, y)| r.image.get_pixel(x, y).0.iter().all(|v| *v < 90))
            .count()
    };
    let (l, rt, t, b) = (g.left as u32, g.right as u32, g.top as u32, g.bottom as u32);
    assert!(dark(l, 0, rt, t.saturating_sub(2)) > 50, "title");
    assert!(dark(l, b + 3, rt, b + 25) > 50, "x tick labels");
    assert!(dark(0, b + 60, 500, 400) > 100, "legend and note");
}

#[test]
fn bad_figures_are_errors_not_panics() {
    let e = Figure::new(10, 100_000).render().unwrap_err();
    assert!(matches!(e, PlotError::Size { .. }), "{e}");
    let e = Figure::new(300, 300).columns(0).render().unwrap_err();
    assert!(matches!(e, PlotError::Panels { .. }), "{e}");
    let bad = Chart::new("neg", Axis::log("x").range(-1.0, 10.0), Axis::linear("y"));
    let e = one_panel(bad).render().unwrap_err();
    assert!(e.to_string().contains("'neg'"), "{e}");
    // Empty charts and series render (nothing to show is not an error).
    let empty =
        Chart::new("empty", Axis::log("x"), Axis::linear("y")).series(Series::new(PROBE, vec![]));
    assert!(one_panel(empty).render().is_ok());
}
