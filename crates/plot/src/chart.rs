//! What a chart shows, as plain data: axes, series, filled cells, bands, notes. Drawing lives in
//! `draw.rs`; nothing here knows about pixels.

use crate::Rgb;

/// How an axis maps values to positions.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Scale {
    Linear,
    /// Base 10; values <= 0 cannot be shown and are skipped.
    Log,
}

/// One axis of a chart.
#[derive(Debug, Clone, PartialEq)]
pub struct Axis {
    /// Axis title, e.g. "run time \[s\]".
    pub label: String,
    pub scale: Scale,
    /// Shown range; `None`: from the data (whole decades on a log axis, round steps on a
    /// linear one).
    pub range: Option<(f64, f64)>,
    /// Tick positions (in data units) and their labels; `None`: every decade (log) or round
    /// steps (linear).
    pub ticks: Option<Vec<(f64, String)>>,
}

impl Axis {
    pub fn linear(label: impl Into<String>) -> Self {
        Self {
            label: label.into(),
            scale: Scale::Linear,
            range: None,
            ticks: None,
        }
    }

    pub fn log(label: impl Into<String>) -> Self {
        Self {
            scale: Scale::Log,
            ..Self::linear(label)
        }
    }

    /// Show exactly `lo..hi` (data units); points outside are left out, lines are cut at the edge.
    pub fn range(mut self, lo: f64, hi: f64) -> Self {
        self.range = Some((lo, hi));
        self
    }

    /// Ticks at these positions with these labels instead of the automatic ones.
    pub fn ticks(mut self, ticks: Vec<(f64, String)>) -> Self {
        self.ticks = Some(ticks);
        self
    }

    /// Position of `v` along the axis in plot units (log10 on a log axis); `None` for values the
    /// axis cannot show (non-finite, or <= 0 on a log axis).
    pub(crate) fn to_plot(&self, v: f64) -> Option<f64> {
        match self.scale {
            _ if !v.is_finite() => None,
            Scale::Linear => Some(v),
            Scale::Log if v > 0.0 => Some(v.log10()),
            Scale::Log => None,
        }
    }
}

/// Point marker shapes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Marker {
    Circle,
    Square,
    Triangle,
    Diamond,
    Cross,
}

/// How a series' points are joined.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stroke {
    Solid,
    Dashed,
    /// Markers only.
    None,
}

/// A line and/or markers through points, in the order given.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    /// Name for the legend ([`crate::Figure::legend_from_series`]); `None`: not listed.
    pub label: Option<String>,
    pub colour: Rgb,
    /// (x, y) in data units. A point the axes cannot show (non-finite, <= 0 on a log axis) is
    /// skipped and breaks the line, except that a finite x with a non-finite y goes to the
    /// chart's overflow strip when it has one ([`Chart::overflow`]).
    pub points: Vec<(f64, f64)>,
    pub marker: Option<Marker>,
    pub stroke: Stroke,
    /// Line width in pixels.
    pub width: u32,
}

impl Series {
    /// A solid 2 px line without markers.
    pub fn new(colour: Rgb, points: Vec<(f64, f64)>) -> Self {
        Self {
            label: None,
            colour,
            points,
            marker: None,
            stroke: Stroke::Solid,
            width: 2,
        }
    }

    pub fn label(mut self, label: impl Into<String>) -> Self {
        self.label = Some(label.into());
        self
    }

    pub fn marker(mut self, marker: Marker) -> Self {
        self.marker = Some(marker);
        self
    }

    pub fn stroke(mut self, stroke: Stroke) -> Self {
        self.stroke = stroke;
        self
    }

    pub fn width(mut self, width: u32) -> Self {
        self.width = width;
        self
    }
}

/// A filled rectangle in data units (maps, heatmaps), with an optional centred mark ("*").
#[derive(Debug, Clone, PartialEq)]
pub struct Cell {
    pub x: (f64, f64),
    pub y: (f64, f64),
    pub colour: Rgb,
    pub mark: Option<String>,
}

/// A horizontal band between two y values (a target range): light fill, dashed edges.
#[derive(Debug, Clone, PartialEq)]
pub struct Band {
    pub y: (f64, f64),
    pub colour: Rgb,
    /// Written at the band's right end.
    pub label: Option<String>,
}

/// Text inside the plot area, placed by fractions of its width and height from the top left.
#[derive(Debug, Clone, PartialEq)]
pub struct Note {
    pub at: (f64, f64),
    pub text: String,
    pub colour: Rgb,
}

/// One panel: axes, a title, and what is drawn in it (cells first, then bands, lines,
/// markers, notes).
#[derive(Debug, Clone, PartialEq)]
pub struct Chart {
    pub title: String,
    pub x: Axis,
    pub y: Axis,
    pub cells: Vec<Cell>,
    pub bands: Vec<Band>,
    pub series: Vec<Series>,
    pub notes: Vec<Note>,
    /// A strip above the y range for points whose y is not finite (diverged runs), drawn as
    /// crosses in their series' colour with this label; `None`: such points are skipped.
    pub overflow: Option<String>,
}

impl Chart {
    pub fn new(title: impl Into<String>, x: Axis, y: Axis) -> Self {
        Self {
            title: title.into(),
            x,
            y,
            cells: Vec::new(),
            bands: Vec::new(),
            series: Vec::new(),
            notes: Vec::new(),
            overflow: None,
        }
    }

    /// A grid of coloured cells with labelled columns and rows (`cells[row][col]`, row 0 at the
    /// bottom), e.g. a stability map over categorical settings.
    pub fn heatmap(
        title: impl Into<String>,
        x: (&str, &[String]),
        y: (&str, &[String]),
        cells: &[Vec<(Rgb, Option<String>)>],
    ) -> Self {
        let ticks = |labels: &[String]| -> Vec<(f64, String)> {
            labels
                .iter()
                .enumerate()
                .map(|(i, l)| (i as f64 + 0.5, l.clone()))
                .collect()
        };
        let axis = |(label, labels): (&str, &[String])| {
            Axis::linear(label)
                .range(0.0, labels.len().max(1) as f64)
                .ticks(ticks(labels))
        };
        let mut chart = Self::new(title, axis(x), axis(y));
        for (r, row) in cells.iter().enumerate() {
            for (c, (colour, mark)) in row.iter().enumerate() {
                chart.cells.push(Cell {
                    x: (c as f64, c as f64 + 1.0),
                    y: (r as f64, r as f64 + 1.0),
                    colour: *colour,
                    mark: mark.clone(),
                });
            }
        }
        chart
    }

    pub fn series(mut self, series: Series) -> Self {
        self.series.push(series);
        self
    }

    pub fn cell(mut self, cell: Cell) -> Self {
        self.cells.push(cell);
        self
    }

    pub fn band(mut self, band: Band) -> Self {
        self.bands.push(band);
        self
    }

    pub fn note(mut self, at: (f64, f64), text: impl Into<String>, colour: Rgb) -> Self {
        self.notes.push(Note {
            at,
            text: text.into(),
            colour,
        });
        self
    }

    pub fn overflow(mut self, label: impl Into<String>) -> Self {
        self.overflow = Some(label.into());
        self
    }
}
