//! A figure: an optional title, panels in a grid, a legend and notes below them; rendered into
//! an RGB buffer and encoded as PNG with the workspace's `image` crate.

use crate::chart::{Chart, Marker, Scale, Series, Stroke};
use crate::draw::{self, Area, TEXT_PX, TITLE_PX, colour, text_left};
use crate::font::ensure_font;
use crate::{BLACK, GREY, PlotError, Rgb};
use image::ImageEncoder;
use plotters::element::DashedPathElement;
use plotters::prelude::*;
use std::path::Path;

/// Figure sides are bounded (pixels).
pub const MIN_SIDE: u32 = 64;
pub const MAX_SIDE: u32 = 8192;
/// At most this many panels, and columns.
pub const MAX_PANELS: usize = 64;

/// What a legend entry shows beside its label.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Key {
    /// A line, with a marker on it if given.
    Line {
        stroke: Stroke,
        marker: Option<Marker>,
    },
    Marker(Marker),
    /// A filled square (cell colours, bands).
    Fill,
}

#[derive(Debug, Clone, PartialEq)]
pub struct LegendEntry {
    pub label: String,
    pub colour: Rgb,
    pub key: Key,
}

impl LegendEntry {
    pub fn line(label: impl Into<String>, colour: Rgb) -> Self {
        Self {
            label: label.into(),
            colour,
            key: Key::Line {
                stroke: Stroke::Solid,
                marker: None,
            },
        }
    }

    pub fn marker(label: impl Into<String>, colour: Rgb, marker: Marker) -> Self {
        Self {
            label: label.into(),
            colour,
            key: Key::Marker(marker),
        }
    }

    pub fn fill(label: impl Into<String>, colour: Rgb) -> Self {
        Self {
            label: label.into(),
            colour,
            key: Key::Fill,
        }
    }

    /// The entry of a labelled series, drawn as the series is.
    pub fn of(series: &Series) -> Option<Self> {
        let label = series.label.clone()?;
        let key = match (series.stroke, series.marker) {
            (Stroke::None, Some(m)) => Key::Marker(m),
            (stroke, marker) => Key::Line { stroke, marker },
        };
        Some(Self {
            label,
            colour: series.colour,
            key,
        })
    }
}

/// A whole PNG: panels left to right, top to bottom, `columns` per row, then the legend (wrapped
/// to the width) and notes (one line each, grey).
#[derive(Debug, Clone, PartialEq)]
pub struct Figure {
    pub width: u32,
    pub height: u32,
    pub title: Option<String>,
    pub columns: usize,
    pub panels: Vec<Chart>,
    pub legend: Vec<LegendEntry>,
    pub notes: Vec<String>,
}

/// Where a panel's plot area landed, to map data to pixels (tests, overlays).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PanelGeometry {
    /// Plot area in pixels (right and bottom exclusive).
    pub left: i32,
    pub right: i32,
    pub top: i32,
    pub bottom: i32,
    /// Shown ranges in plot units (log10 of the value on a log axis), overflow strip included.
    pub x: (f64, f64),
    pub y: (f64, f64),
    pub x_scale: Scale,
    pub y_scale: Scale,
}

impl PanelGeometry {
    /// The pixel of the data point (x, y); `None` if an axis cannot show it.
    pub fn pixel(&self, x: f64, y: f64) -> Option<(f64, f64)> {
        let t = |v: f64, s: Scale| match s {
            _ if !v.is_finite() => None,
            Scale::Linear => Some(v),
            Scale::Log => (v > 0.0).then(|| v.log10()),
        };
        let (tx, ty) = (t(x, self.x_scale)?, t(y, self.y_scale)?);
        let u = (tx - self.x.0) / (self.x.1 - self.x.0);
        let v = (ty - self.y.0) / (self.y.1 - self.y.0);
        Some((
            f64::from(self.left) + u * f64::from(self.right - self.left - 1),
            f64::from(self.bottom - 1) - v * f64::from(self.bottom - self.top - 1),
        ))
    }
}

/// A rendered figure.
#[derive(Debug, Clone)]
pub struct Rendered {
    pub image: image::RgbImage,
    pub panels: Vec<PanelGeometry>,
}

const LEGEND_ROW: i32 = 28;
const NOTE_ROW: i32 = 24;
const MARGIN: i32 = 20;
const TITLE_H: u32 = 40;

impl Figure {
    pub fn new(width: u32, height: u32) -> Self {
        Self {
            width,
            height,
            title: None,
            columns: 1,
            panels: Vec::new(),
            legend: Vec::new(),
            notes: Vec::new(),
        }
    }

    pub fn title(mut self, title: impl Into<String>) -> Self {
        self.title = Some(title.into());
        self
    }

    pub fn columns(mut self, columns: usize) -> Self {
        self.columns = columns;
        self
    }

    pub fn panel(mut self, chart: Chart) -> Self {
        self.panels.push(chart);
        self
    }

    pub fn legend(mut self, entry: LegendEntry) -> Self {
        self.legend.push(entry);
        self
    }

    pub fn note(mut self, note: impl Into<String>) -> Self {
        self.notes.push(note.into());
        self
    }

    /// Add a legend entry for every labelled series, once per label, in panel order.
    pub fn legend_from_series(mut self) -> Self {
        let mut seen: Vec<String> = self.legend.iter().map(|e| e.label.clone()).collect();
        let mut add = Vec::new();
        for s in self.panels.iter().flat_map(|p| &p.series) {
            if let Some(e) = LegendEntry::of(s) {
                if !seen.contains(&e.label) {
                    seen.push(e.label.clone());
                    add.push(e);
                }
            }
        }
        self.legend.extend(add);
        self
    }

    fn check(&self) -> Result<(), PlotError> {
        let side = MIN_SIDE..=MAX_SIDE;
        if !side.contains(&self.width) || !side.contains(&self.height) {
            return Err(PlotError::Size {
                width: self.width,
                height: self.height,
            });
        }
        if self.panels.len() > MAX_PANELS || !(1..=MAX_PANELS).contains(&self.columns) {
            return Err(PlotError::Panels {
                panels: self.panels.len(),
                columns: self.columns,
            });
        }
        Ok(())
    }

    /// Draw the figure into an RGB image.
    pub fn render(&self) -> Result<Rendered, PlotError> {
        self.check()?;
        ensure_font()?;
        let (w, h) = (self.width, self.height);
        let mut buf = vec![255u8; w as usize * h as usize * 3];
        let panels = {
            let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
            let panels = self.draw(&root)?;
            root.present()?;
            panels
        };
        let image = image::RgbImage::from_raw(w, h, buf).ok_or(PlotError::Size {
            width: w,
            height: h,
        })?;
        Ok(Rendered { image, panels })
    }

    fn draw(&self, root: &Area) -> Result<Vec<PanelGeometry>, PlotError> {
        let (w, h) = (self.width as i32, self.height as i32);
        let mut top = 0;
        if let Some(title) = &self.title {
            root.draw(&Text::new(
                title.clone(),
                (w / 2, TITLE_H as i32 / 2),
                draw::text_centre(TITLE_PX + 2.0, BLACK),
            ))?;
            top = TITLE_H as i32;
        }
        // Legend rows: entries wrap at the figure's width.
        let font = text_left(TEXT_PX, BLACK);
        let mut placed = Vec::new();
        let (mut x, mut row) = (MARGIN, 0);
        for e in &self.legend {
            let tw = i32::try_from(root.estimate_text_size(&e.label, &font)?.0).unwrap_or(w);
            let ew = 40 + tw + 30;
            if x > MARGIN && x + ew > w - MARGIN {
                x = MARGIN;
                row += 1;
            }
            placed.push((x, row, e));
            x += ew;
        }
        let rows = if placed.is_empty() { 0 } else { row + 1 };
        let below = rows * LEGEND_ROW + self.notes.len() as i32 * NOTE_ROW;
        let below = if below > 0 { below + 12 } else { 0 };
        let panel_h = (h - top - below).max(1);
        let legend_top = top + panel_h + 6;
        for (x, row, e) in placed {
            let y = legend_top + row * LEGEND_ROW + LEGEND_ROW / 2;
            legend_key(root, (x, y), e)?;
            root.draw(&Text::new(e.label.clone(), (x + 40, y), font.clone()))?;
        }
        let notes_top = legend_top + rows * LEGEND_ROW;
        for (i, n) in self.notes.iter().enumerate() {
            let y = notes_top + i as i32 * NOTE_ROW + NOTE_ROW / 2;
            root.draw(&Text::new(
                n.clone(),
                (MARGIN, y),
                text_left(TEXT_PX - 1.0, GREY),
            ))?;
        }
        if self.panels.is_empty() {
            return Ok(Vec::new());
        }
        let grid = root.clone().shrink((0, top), (w as u32, panel_h as u32));
        let cols = self.columns.min(self.panels.len());
        let rows = self.panels.len().div_ceil(cols);
        let cells = grid.split_evenly((rows, cols));
        let mut out = Vec::new();
        for (chart, area) in self.panels.iter().zip(&cells) {
            out.push(draw::chart(root, area, chart)?);
        }
        Ok(out)
    }

    /// The figure as PNG bytes (the same bytes for the same figure).
    pub fn png(&self) -> Result<Vec<u8>, PlotError> {
        let r = self.render()?;
        let mut out = Vec::new();
        image::codecs::png::PngEncoder::new(&mut out).write_image(
            r.image.as_raw(),
            r.image.width(),
            r.image.height(),
            image::ExtendedColorType::Rgb8,
        )?;
        Ok(out)
    }

    /// Write the figure as a PNG file.
    pub fn save(&self, path: &Path) -> Result<(), PlotError> {
        let bytes = self.png()?;
        std::fs::write(path, bytes).map_err(|source| PlotError::Write {
            path: path.to_path_buf(),
            source,
        })
    }
}

fn legend_key(root: &Area, (x, y): (i32, i32), e: &LegendEntry) -> Result<(), PlotError> {
    let c = colour(e.colour);
    match e.key {
        Key::Line { stroke, marker } => {
            let path = vec![(x, y), (x + 30, y)];
            match stroke {
                Stroke::Solid => root.draw(&PathElement::new(path, c.stroke_width(3)))?,
                Stroke::Dashed => {
                    root.draw(&DashedPathElement::new(path, 8, 5, c.stroke_width(3)))?
                }
                Stroke::None => {}
            }
            if let Some(m) = marker {
                draw::marker(root, (x + 15, y), m, e.colour)?;
            }
        }
        Key::Marker(m) => draw::marker(root, (x + 15, y), m, e.colour)?,
        Key::Fill => root.draw(&Rectangle::new(
            [(x + 4, y - 8), (x + 26, y + 8)],
            c.filled(),
        ))?,
    }
    Ok(())
}
