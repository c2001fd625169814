//! PNG charts for the UniTac reports, on [plotters] with DejaVu Sans through ab_glyph.
//!
//! A [`Figure`] holds [`Chart`] panels in a grid, a legend and notes. A chart has two [`Axis`]
//! (linear or log10, automatic or fixed ranges and ticks) and draws, in order: [`Cell`]s (maps,
//! heatmaps: [`Chart::heatmap`]), [`Band`]s (target ranges), [`Series`] (lines, solid or
//! dashed, with [`Marker`]s), notes. Points an axis cannot show are skipped and break the line;
//! with [`Chart::overflow`] a non-finite y (a diverged run) is drawn as a cross on a strip above
//! the data instead. The same figure always gives the same PNG bytes.
//!
//! ```no_run
//! use unitac_plot::{Axis, Chart, Figure, Marker, PALETTE, Series};
//! let chart = Chart::new("error", Axis::log("time [s]"), Axis::log("rms error")).series(
//!     Series::new(PALETTE[0], vec![(1e-3, 0.1), (1e-2, 0.01)]).label("heun").marker(Marker::Circle),
//! );
//! Figure::new(640, 480).panel(chart).legend_from_series().save("error.png".as_ref())?;
//! # Ok::<(), unitac_plot::PlotError>(())
//! ```

mod axes;
mod chart;
mod draw;
mod figure;
mod font;

pub use chart::{Axis, Band, Cell, Chart, Marker, Note, Scale, Series, Stroke};
pub use figure::{
    Figure, Key, LegendEntry, MAX_PANELS, MAX_SIDE, MIN_SIDE, PanelGeometry, Rendered,
};
pub use font::{DEFAULT_FONT, FONT_PACKAGE, load_font};

use std::path::PathBuf;
use thiserror::Error;

/// An sRGB colour.
pub type Rgb = [u8; 3];

pub const BLACK: Rgb = [0, 0, 0];
pub const GREY: Rgb = [110, 110, 110];
/// Distinct series colours (matplotlib's first six).
pub const PALETTE: [Rgb; 6] = [
    [214, 39, 40],
    [44, 160, 44],
    [31, 119, 180],
    [148, 103, 189],
    [255, 127, 14],
    [23, 190, 207],
];

#[derive(Debug, Error)]
pub enum PlotError {
    #[error("font {path}: {source} (install the Debian package {package})")]
    FontMissing {
        path: PathBuf,
        package: &'static str,
        source: std::io::Error,
    },
    #[error("font {path} is not a TrueType/OpenType font of at most 32 MiB")]
    FontInvalid { path: PathBuf },
    #[error("figure size {width}x{height} px is outside {MIN_SIDE}..={MAX_SIDE} px on a side")]
    Size { width: u32, height: u32 },
    #[error("figure with {panels} panels in {columns} columns (1..={MAX_PANELS} each)")]
    Panels { panels: usize, columns: usize },
    #[error("chart '{chart}': {axis} range {lo}..{hi} is empty or cannot be shown on its axis")]
    Range {
        chart: String,
        axis: &'static str,
        lo: f64,
        hi: f64,
    },
    #[error("drawing: {0}")]
    Draw(#[from] plotters::drawing::DrawingAreaErrorKind<plotters_bitmap::BitMapBackendError>),
    #[error("encoding PNG: {0}")]
    Encode(#[from] image::ImageError),
    #[error("writing {path}: {source}")]
    Write {
        path: PathBuf,
        source: std::io::Error,
    },
}
