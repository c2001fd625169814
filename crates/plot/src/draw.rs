//! Drawing one [`Chart`] into a region of the figure with plotters: the axes, grid and labels
//! come from plotters' mesh; cells, bands, lines and markers are plotters elements placed at
//! pixel positions that plotters' own coordinate mapping gives, cut to the plot area here.

use crate::axes::AxisLayout;
use crate::chart::{Chart, Marker, Stroke};
use crate::font::FAMILY;
use crate::{GREY, PanelGeometry, PlotError, Rgb};
use plotters::coord::Shift;
use plotters::coord::ranged1d::{DefaultFormatting, KeyPointHint, Ranged};
use plotters::element::DashedPathElement;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use std::ops::Range;

pub(crate) type Area<'a> = DrawingArea<BitMapBackend<'a>, Shift>;

/// Font sizes \[px\].
pub(crate) const TITLE_PX: f64 = 20.0;
pub(crate) const LABEL_PX: f64 = 15.0;
pub(crate) const TEXT_PX: f64 = 16.0;
/// Marker radius \[px\].
const MARKER_PX: i32 = 5;

pub(crate) fn colour(c: Rgb) -> RGBColor {
    RGBColor(c[0], c[1], c[2])
}

/// Text anchored at its left end, vertically centred on `y`.
pub(crate) fn text_left<'a>(size: f64, c: Rgb) -> TextStyle<'a> {
    (FAMILY, size)
        .into_font()
        .color(&colour(c))
        .pos(Pos::new(HPos::Left, VPos::Center))
}

/// Text centred on a point.
pub(crate) fn text_centre<'a>(size: f64, c: Rgb) -> TextStyle<'a> {
    (FAMILY, size)
        .into_font()
        .color(&colour(c))
        .pos(Pos::new(HPos::Center, VPos::Center))
}

/// An axis for plotters: linear in plot units, its tick and grid positions from the layout.
struct Coord(AxisLayout);

impl Ranged for Coord {
    type FormatOption = DefaultFormatting;
    type ValueType = f64;

    fn map(&self, v: &f64, limit: (i32, i32)) -> i32 {
        let u = (v - self.0.lo) / (self.0.end - self.0.lo);
        limit.0 + (f64::from(limit.1 - limit.0) * u).round() as i32
    }

    fn key_points<H: KeyPointHint>(&self, hint: H) -> Vec<f64> {
        if hint.weight().allow_light_points() {
            self.0.light.clone()
        } else {
            self.0.tick_positions()
        }
    }

    fn range(&self) -> Range<f64> {
        self.0.lo..self.0.end
    }
}

/// Plot-unit positions of everything in `chart`, per axis.
fn extents(chart: &Chart) -> (Vec<f64>, Vec<f64>) {
    let (mut xs, mut ys) = (Vec::new(), Vec::new());
    for s in &chart.series {
        for &(x, y) in &s.points {
            match (chart.x.to_plot(x), chart.y.to_plot(y)) {
                (Some(a), Some(b)) => {
                    xs.push(a);
                    ys.push(b);
                }
                (Some(a), None) if chart.overflow.is_some() && !y.is_finite() => xs.push(a),
                _ => {}
            }
        }
    }
    for c in &chart.cells {
        xs.extend([c.x.0, c.x.1].iter().filter_map(|v| chart.x.to_plot(*v)));
        ys.extend([c.y.0, c.y.1].iter().filter_map(|v| chart.y.to_plot(*v)));
    }
    for b in &chart.bands {
        ys.extend([b.y.0, b.y.1].iter().filter_map(|v| chart.y.to_plot(*v)));
    }
    (xs, ys)
}

/// Cut the segment a-b (plot units) to the box; `None` when none of it is inside.
fn clip(
    a: (f64, f64),
    b: (f64, f64),
    (x0, x1): (f64, f64),
    (y0, y1): (f64, f64),
) -> Option<((f64, f64), (f64, f64))> {
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for (p, q) in [
        (-dx, a.0 - x0),
        (dx, x1 - a.0),
        (-dy, a.1 - y0),
        (dy, y1 - a.1),
    ] {
        if p == 0.0 {
            if q < 0.0 {
                return None;
            }
        } else {
            let r = q / p;
            if p < 0.0 {
                t0 = t0.max(r);
            } else {
                t1 = t1.min(r);
            }
        }
    }
    (t0 <= t1).then_some((
        (a.0 + t0 * dx, a.1 + t0 * dy),
        (a.0 + t1 * dx, a.1 + t1 * dy),
    ))
}

/// The chart's cells (a stability map's), each filled inside its corners with a pixel of white
/// between neighbours, and its mark at the centre; `x` and `y` are the axes' drawable ranges.
fn draw_cells(
    root: &Area,
    chart: &Chart,
    x: (f64, f64),
    y: (f64, f64),
    to_px: &dyn Fn((f64, f64)) -> (i32, i32),
) -> Result<(), PlotError> {
    for c in &chart.cells {
        let corners = (
            chart.x.to_plot(c.x.0),
            chart.x.to_plot(c.x.1),
            chart.y.to_plot(c.y.0),
            chart.y.to_plot(c.y.1),
        );
        let (Some(x0), Some(x1), Some(y0), Some(y1)) = corners else {
            continue;
        };
        let (x0, x1) = (x0.min(x1).max(x.0), x0.max(x1).min(x.1));
        let (y0, y1) = (y0.min(y1).max(y.0), y0.max(y1).min(y.1));
        if x0 >= x1 || y0 >= y1 {
            continue;
        }
        let (a, b) = (to_px((x0, y1)), to_px((x1, y0)));
        // One pixel of white between neighbouring cells.
        root.draw(&Rectangle::new(
            [(a.0 + 1, a.1 + 1), (b.0 - 1, b.1 - 1)],
            colour(c.colour).filled(),
        ))?;
        if let Some(mark) = &c.mark {
            let m = to_px((0.5 * (x0 + x1), 0.5 * (y0 + y1)));
            root.draw(&Text::new(
                mark.clone(),
                m,
                text_centre(TEXT_PX + 4.0, crate::BLACK),
            ))?;
        }
    }
    Ok(())
}

/// The chart's horizontal bands: a light fill between dashed edges, and the label at the right.
fn draw_bands(
    root: &Area,
    chart: &Chart,
    x: (f64, f64),
    y: (f64, f64),
    to_px: &dyn Fn((f64, f64)) -> (i32, i32),
) -> Result<(), PlotError> {
    for b in &chart.bands {
        let (Some(y0), Some(y1)) = (chart.y.to_plot(b.y.0), chart.y.to_plot(b.y.1)) else {
            continue;
        };
        let (y0, y1) = (y0.min(y1).max(y.0), y0.max(y1).min(y.1));
        if y0 > y1 {
            continue;
        }
        let (a, z) = (to_px((x.0, y1)), to_px((x.1, y0)));
        let col = colour(b.colour);
        root.draw(&Rectangle::new([a, z], col.mix(0.15).filled()))?;
        for y in [a.1, z.1] {
            root.draw(&DashedPathElement::new(
                vec![(a.0, y), (z.0, y)],
                8,
                6,
                col.stroke_width(2),
            ))?;
        }
        if let Some(label) = &b.label {
            root.draw(&Text::new(
                label.clone(),
                (z.0 - 6, a.1 + 12),
                (FAMILY, LABEL_PX)
                    .into_font()
                    .color(&col)
                    .pos(Pos::new(HPos::Right, VPos::Center)),
            ))?;
        }
    }
    Ok(())
}

/// The runs of a series cut at the data box, as pixel polylines: a run that leaves and comes
/// back becomes two.
fn polylines(
    runs: &[Vec<(f64, f64)>],
    data_box: ((f64, f64), (f64, f64)),
    to_px: &dyn Fn((f64, f64)) -> (i32, i32),
) -> Vec<Vec<(i32, i32)>> {
    let mut lines: Vec<Vec<(i32, i32)>> = Vec::new();
    for run in runs {
        let mut open = false;
        for w in run.windows(2) {
            let Some((a, b)) = clip(w[0], w[1], data_box.0, data_box.1) else {
                open = false;
                continue;
            };
            match lines.last_mut() {
                Some(line) if open && a == w[0] => line.push(to_px(b)),
                _ => lines.push(vec![to_px(a), to_px(b)]),
            }
            open = b == w[1];
        }
    }
    lines
}

/// The strip above the y axis's top (`hi`) where values beyond it are marked (at `strip_y`): a
/// dashed edge and its label, right-aligned with a cross before it.
fn overflow_strip(
    root: &Area,
    label: &str,
    x: (f64, f64),
    (hi, strip_y): (f64, f64),
    to_px: &dyn Fn((f64, f64)) -> (i32, i32),
) -> Result<(), PlotError> {
    let (a, z) = (to_px((x.0, hi)), to_px((x.1, hi)));
    root.draw(&DashedPathElement::new(
        vec![a, z],
        5,
        4,
        colour(GREY).stroke_width(1),
    ))?;
    let s = to_px((x.1, strip_y));
    let text = text_left(LABEL_PX, GREY);
    let w = i32::try_from(root.estimate_text_size(label, &text)?.0).unwrap_or(0);
    let at = (s.0 - w - 10, s.1);
    marker(root, (at.0 - 12, at.1), Marker::Cross, GREY)?;
    root.draw(&Text::new(label.to_string(), at, text))?;
    Ok(())
}

/// Draw `chart` into `area`; pixel-placed elements go onto `root` (absolute coordinates).
pub(crate) fn chart(root: &Area, area: &Area, chart: &Chart) -> Result<PanelGeometry, PlotError> {
    let (xs, ys) = extents(chart);
    let xl = AxisLayout::new(&chart.x, &xs, false, 8, &chart.title, "x")?;
    let yl = AxisLayout::new(
        &chart.y,
        &ys,
        chart.overflow.is_some(),
        12,
        &chart.title,
        "y",
    )?;
    let label_font = TextStyle::from((FAMILY, LABEL_PX).into_font());
    let mut y_label_w = 0u32;
    for (_, l) in &yl.ticks {
        y_label_w = y_label_w.max(area.estimate_text_size(l, &label_font)?.0);
    }
    let mut cc = ChartBuilder::on(area)
        .caption(&chart.title, (FAMILY, TITLE_PX))
        .margin(8)
        .margin_right(20)
        .x_label_area_size(50)
        .y_label_area_size(y_label_w + 40)
        .build_cartesian_2d(Coord(xl.clone()), Coord(yl.clone()))?;
    cc.configure_mesh()
        .x_desc(chart.x.label.as_str())
        .y_desc(chart.y.label.as_str())
        .x_label_formatter(&|v| xl.label_at(*v))
        .y_label_formatter(&|v| yl.label_at(*v))
        .bold_line_style(RGBColor(200, 200, 200))
        .light_line_style(RGBColor(235, 235, 235))
        .axis_style(BLACK)
        .label_style(label_font.clone())
        .axis_desc_style((FAMILY, TEXT_PX))
        .draw()?;
    let (px, py) = cc.plotting_area().get_pixel_range();
    let geometry = PanelGeometry {
        left: px.start,
        right: px.end,
        top: py.start,
        bottom: py.end,
        x: (xl.lo, xl.end),
        y: (yl.lo, yl.end),
        x_scale: chart.x.scale,
        y_scale: chart.y.scale,
    };
    root.draw(&Rectangle::new(
        [(px.start, py.start), (px.end - 1, py.end - 1)],
        BLACK.stroke_width(1),
    ))?;
    let data_box = ((xl.lo, xl.end), (yl.lo, yl.hi));
    let to_px = |t: (f64, f64)| cc.backend_coord(&t);

    draw_cells(root, chart, (xl.lo, xl.end), (yl.lo, yl.hi), &to_px)?;
    draw_bands(root, chart, (xl.lo, xl.end), (yl.lo, yl.hi), &to_px)?;

    let strip_y = 0.5 * (yl.hi + yl.end);
    if let Some(label) = &chart.overflow {
        overflow_strip(root, label, (xl.lo, xl.end), (yl.hi, strip_y), &to_px)?;
    }

    for s in &chart.series {
        let col = colour(s.colour);
        let style = col.stroke_width(s.width.max(1));
        // Runs of drawable points; a point the axes cannot show ends a run.
        let mut runs: Vec<Vec<(f64, f64)>> = vec![Vec::new()];
        let mut markers = Vec::new();
        let mut overflow = Vec::new();
        for &(x, y) in &s.points {
            match (chart.x.to_plot(x), chart.y.to_plot(y)) {
                (Some(tx), Some(ty)) => {
                    if let Some(run) = runs.last_mut() {
                        run.push((tx, ty));
                    }
                    if xl.lo <= tx && tx <= xl.end && yl.lo <= ty && ty <= yl.hi {
                        markers.push(to_px((tx, ty)));
                    }
                }
                (tx, _) => {
                    if let Some(tx) = tx.filter(|t| xl.lo <= *t && *t <= xl.end) {
                        if chart.overflow.is_some() && !y.is_finite() {
                            overflow.push(to_px((tx, strip_y)));
                        }
                    }
                    runs.push(Vec::new());
                }
            }
        }
        if s.stroke != Stroke::None {
            // Polylines inside the plot area: a run cut at the edges, drawn whole so that
            // dashes run on across its points.
            let lines = polylines(&runs, data_box, &to_px);
            for line in lines {
                if s.stroke == Stroke::Dashed {
                    root.draw(&DashedPathElement::new(line, 10, 6, style))?;
                } else {
                    root.draw(&PathElement::new(line, style))?;
                }
            }
        }
        if let Some(m) = s.marker {
            for p in markers {
                marker(root, p, m, s.colour)?;
            }
        }
        for p in overflow {
            marker(root, p, Marker::Cross, s.colour)?;
        }
    }

    for n in &chart.notes {
        let x = px.start + ((px.end - px.start) as f64 * n.at.0) as i32;
        let y = py.start + ((py.end - py.start) as f64 * n.at.1) as i32;
        root.draw(&Text::new(
            n.text.clone(),
            (x, y),
            text_left(TEXT_PX, n.colour),
        ))?;
    }
    Ok(geometry)
}

/// One marker centred on the pixel `p`.
pub(crate) fn marker(root: &Area, p: (i32, i32), m: Marker, c: Rgb) -> Result<(), PlotError> {
    let (x, y) = p;
    let r = MARKER_PX;
    let fill = colour(c).filled();
    match m {
        Marker::Circle => root.draw(&Circle::new(p, r, fill))?,
        Marker::Square => root.draw(&Rectangle::new(
            [(x - r + 1, y - r + 1), (x + r - 1, y + r - 1)],
            fill,
        ))?,
        Marker::Triangle => root.draw(&Polygon::new(
            vec![
                (x, y - r - 1),
                (x + r + 1, y + r - 1),
                (x - r - 1, y + r - 1),
            ],
            fill,
        ))?,
        Marker::Diamond => root.draw(&Polygon::new(
            vec![
                (x, y - r - 1),
                (x + r + 1, y),
                (x, y + r + 1),
                (x - r - 1, y),
            ],
            fill,
        ))?,
        Marker::Cross => {
            let style = colour(c).stroke_width(2);
            root.draw(&PathElement::new(
                vec![(x - r, y - r), (x + r, y + r)],
                style,
            ))?;
            root.draw(&PathElement::new(
                vec![(x - r, y + r), (x + r, y - r)],
                style,
            ))?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clip_cuts_segments_at_the_box() {
        let b = ((0.0, 1.0), (0.0, 1.0));
        assert_eq!(
            clip((0.5, 0.5), (1.5, 0.5), b.0, b.1),
            Some(((0.5, 0.5), (1.0, 0.5)))
        );
        assert_eq!(clip((2.0, 2.0), (3.0, 3.0), b.0, b.1), None);
        assert_eq!(
            clip((-1.0, 0.5), (2.0, 0.5), b.0, b.1),
            Some(((0.0, 0.5), (1.0, 0.5)))
        );
    }
}
