//! A small bitmap plotter (no fonts, no plotting crate): RGB canvas, lines, markers, a 5x7
//! pixel font, log-log axes; PNG through the `image` crate. Enough for the report's figures.

use std::path::Path;
use thiserror::Error;

#[derive(Debug, Error)]
pub enum PlotError {
    #[error("writing {path}: {source}")]
    Write {
        path: String,
        source: image::ImageError,
    },
}

pub type Rgb = [u8; 3];
pub const WHITE: Rgb = [255, 255, 255];
pub const BLACK: Rgb = [0, 0, 0];
pub const GREY: Rgb = [120, 120, 120];
pub const LIGHT: Rgb = [225, 225, 225];

/// Marker shapes for series.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Marker {
    Circle,
    Square,
    Triangle,
    Cross,
    Diamond,
}

/// An RGB image to draw on.
#[derive(Debug, Clone)]
pub struct Canvas {
    pub width: u32,
    pub height: u32,
    data: Vec<u8>,
}

/// Glyph width and height of the font, in font pixels (plus one column of spacing).
const GW: i64 = 5;
const GH: i64 = 7;

#[rustfmt::skip]
const FONT: &[(char, [u8; 7])] = &[
    (' ', [0b00000, 0b00000, 0b00000, 0b00000, 0b00000, 0b00000, 0b00000]),
    ('0', [0b01110, 0b10001, 0b10011, 0b10101, 0b11001, 0b10001, 0b01110]),
    ('1', [0b00100, 0b01100, 0b00100, 0b00100, 0b00100, 0b00100, 0b01110]),
    ('2', [0b01110, 0b10001, 0b00001, 0b00010, 0b00100, 0b01000, 0b11111]),
    ('3', [0b11111, 0b00010, 0b00100, 0b00010, 0b00001, 0b10001, 0b01110]),
    ('4', [0b00010, 0b00110, 0b01010, 0b10010, 0b11111, 0b00010, 0b00010]),
    ('5', [0b11111, 0b10000, 0b11110, 0b00001, 0b00001, 0b10001, 0b01110]),
    ('6', [0b00110, 0b01000, 0b10000, 0b11110, 0b10001, 0b10001, 0b01110]),
    ('7', [0b11111, 0b00001, 0b00010, 0b00100, 0b01000, 0b01000, 0b01000]),
    ('8', [0b01110, 0b10001, 0b10001, 0b01110, 0b10001, 0b10001, 0b01110]),
    ('9', [0b01110, 0b10001, 0b10001, 0b01111, 0b00001, 0b00010, 0b01100]),
    ('a', [0b00000, 0b00000, 0b01110, 0b00001, 0b01111, 0b10001, 0b01111]),
    ('b', [0b10000, 0b10000, 0b10110, 0b11001, 0b10001, 0b10001, 0b11110]),
    ('c', [0b00000, 0b00000, 0b01110, 0b10000, 0b10000, 0b10001, 0b01110]),
    ('d', [0b00001, 0b00001, 0b01101, 0b10011, 0b10001, 0b10001, 0b01111]),
    ('e', [0b00000, 0b00000, 0b01110, 0b10001, 0b11111, 0b10000, 0b01110]),
    ('f', [0b00110, 0b01001, 0b01000, 0b11100, 0b01000, 0b01000, 0b01000]),
    ('g', [0b01111, 0b10001, 0b10001, 0b10001, 0b01111, 0b00001, 0b01110]),
    ('h', [0b10000, 0b10000, 0b10110, 0b11001, 0b10001, 0b10001, 0b10001]),
    ('i', [0b00100, 0b00000, 0b01100, 0b00100, 0b00100, 0b00100, 0b01110]),
    ('j', [0b00010, 0b00000, 0b00110, 0b00010, 0b00010, 0b10010, 0b01100]),
    ('k', [0b10000, 0b10000, 0b10010, 0b10100, 0b11000, 0b10100, 0b10010]),
    ('l', [0b01100, 0b00100, 0b00100, 0b00100, 0b00100, 0b00100, 0b01110]),
    ('m', [0b00000, 0b00000, 0b11010, 0b10101, 0b10101, 0b10001, 0b10001]),
    ('n', [0b00000, 0b00000, 0b10110, 0b11001, 0b10001, 0b10001, 0b10001]),
    ('o', [0b00000, 0b00000, 0b01110, 0b10001, 0b10001, 0b10001, 0b01110]),
    ('p', [0b11110, 0b10001, 0b10001, 0b10001, 0b11110, 0b10000, 0b10000]),
    ('q', [0b01111, 0b10001, 0b10001, 0b10001, 0b01111, 0b00001, 0b00001]),
    ('r', [0b00000, 0b00000, 0b10110, 0b11001, 0b10000, 0b10000, 0b10000]),
    ('s', [0b00000, 0b00000, 0b01110, 0b10000, 0b01110, 0b00001, 0b11110]),
    ('t', [0b01000, 0b01000, 0b11100, 0b01000, 0b01000, 0b01001, 0b00110]),
    ('u', [0b00000, 0b00000, 0b10001, 0b10001, 0b10001, 0b10011, 0b01101]),
    ('v', [0b00000, 0b00000, 0b10001, 0b10001, 0b10001, 0b01010, 0b00100]),
    ('w', [0b00000, 0b00000, 0b10001, 0b10001, 0b10101, 0b10101, 0b01010]),
    ('x', [0b00000, 0b00000, 0b10001, 0b01010, 0b00100, 0b01010, 0b10001]),
    ('y', [0b10001, 0b10001, 0b10001, 0b10011, 0b01101, 0b00001, 0b01110]),
    ('z', [0b00000, 0b00000, 0b11111, 0b00010, 0b00100, 0b01000, 0b11111]),
    ('A', [0b01110, 0b10001, 0b10001, 0b11111, 0b10001, 0b10001, 0b10001]),
    ('B', [0b11110, 0b10001, 0b10001, 0b11110, 0b10001, 0b10001, 0b11110]),
    ('C', [0b01110, 0b10001, 0b10000, 0b10000, 0b10000, 0b10001, 0b01110]),
    ('D', [0b11100, 0b10010, 0b10001, 0b10001, 0b10001, 0b10010, 0b11100]),
    ('E', [0b11111, 0b10000, 0b10000, 0b11110, 0b10000, 0b10000, 0b11111]),
    ('F', [0b11111, 0b10000, 0b10000, 0b11110, 0b10000, 0b10000, 0b10000]),
    ('G', [0b01110, 0b10001, 0b10000, 0b10111, 0b10001, 0b10001, 0b01111]),
    ('H', [0b10001, 0b10001, 0b10001, 0b11111, 0b10001, 0b10001, 0b10001]),
    ('I', [0b01110, 0b00100, 0b00100, 0b00100, 0b00100, 0b00100, 0b01110]),
    ('J', [0b00111, 0b00010, 0b00010, 0b00010, 0b00010, 0b10010, 0b01100]),
    ('K', [0b10001, 0b10010, 0b10100, 0b11000, 0b10100, 0b10010, 0b10001]),
    ('L', [0b10000, 0b10000, 0b10000, 0b10000, 0b10000, 0b10000, 0b11111]),
    ('M', [0b10001, 0b11011, 0b10101, 0b10101, 0b10001, 0b10001, 0b10001]),
    ('N', [0b10001, 0b10001, 0b11001, 0b10101, 0b10011, 0b10001, 0b10001]),
    ('O', [0b01110, 0b10001, 0b10001, 0b10001, 0b10001, 0b10001, 0b01110]),
    ('P', [0b11110, 0b10001, 0b10001, 0b11110, 0b10000, 0b10000, 0b10000]),
    ('Q', [0b01110, 0b10001, 0b10001, 0b10001, 0b10101, 0b10010, 0b01101]),
    ('R', [0b11110, 0b10001, 0b10001, 0b11110, 0b10100, 0b10010, 0b10001]),
    ('S', [0b01111, 0b10000, 0b10000, 0b01110, 0b00001, 0b00001, 0b11110]),
    ('T', [0b11111, 0b00100, 0b00100, 0b00100, 0b00100, 0b00100, 0b00100]),
    ('U', [0b10001, 0b10001, 0b10001, 0b10001, 0b10001, 0b10001, 0b01110]),
    ('V', [0b10001, 0b10001, 0b10001, 0b10001, 0b10001, 0b01010, 0b00100]),
    ('W', [0b10001, 0b10001, 0b10001, 0b10101, 0b10101, 0b10101, 0b01010]),
    ('X', [0b10001, 0b10001, 0b01010, 0b00100, 0b01010, 0b10001, 0b10001]),
    ('Y', [0b10001, 0b10001, 0b10001, 0b01010, 0b00100, 0b00100, 0b00100]),
    ('Z', [0b11111, 0b00001, 0b00010, 0b00100, 0b01000, 0b10000, 0b11111]),
    ('.', [0b00000, 0b00000, 0b00000, 0b00000, 0b00000, 0b01100, 0b01100]),
    (',', [0b00000, 0b00000, 0b00000, 0b00000, 0b01100, 0b00100, 0b01000]),
    ('-', [0b00000, 0b00000, 0b00000, 0b11111, 0b00000, 0b00000, 0b00000]),
    ('+', [0b00000, 0b00100, 0b00100, 0b11111, 0b00100, 0b00100, 0b00000]),
    ('=', [0b00000, 0b00000, 0b11111, 0b00000, 0b11111, 0b00000, 0b00000]),
    ('(', [0b00010, 0b00100, 0b01000, 0b01000, 0b01000, 0b00100, 0b00010]),
    (')', [0b01000, 0b00100, 0b00010, 0b00010, 0b00010, 0b00100, 0b01000]),
    ('[', [0b01110, 0b01000, 0b01000, 0b01000, 0b01000, 0b01000, 0b01110]),
    (']', [0b01110, 0b00010, 0b00010, 0b00010, 0b00010, 0b00010, 0b01110]),
    ('/', [0b00000, 0b00001, 0b00010, 0b00100, 0b01000, 0b10000, 0b00000]),
    (';', [0b00000, 0b01100, 0b01100, 0b00000, 0b01100, 0b00100, 0b01000]),
    (':', [0b00000, 0b01100, 0b01100, 0b00000, 0b01100, 0b01100, 0b00000]),
    ('%', [0b11000, 0b11001, 0b00010, 0b00100, 0b01000, 0b10011, 0b00011]),
    ('_', [0b00000, 0b00000, 0b00000, 0b00000, 0b00000, 0b00000, 0b11111]),
    ('<', [0b00010, 0b00100, 0b01000, 0b10000, 0b01000, 0b00100, 0b00010]),
    ('>', [0b01000, 0b00100, 0b00010, 0b00001, 0b00010, 0b00100, 0b01000]),
    ('\'', [0b01100, 0b00100, 0b01000, 0b00000, 0b00000, 0b00000, 0b00000]),
    ('*', [0b00000, 0b00100, 0b10101, 0b01110, 0b10101, 0b00100, 0b00000]),
    ('^', [0b00100, 0b01010, 0b10001, 0b00000, 0b00000, 0b00000, 0b00000]),
    ('|', [0b00100, 0b00100, 0b00100, 0b00100, 0b00100, 0b00100, 0b00100]),
    ('~', [0b00000, 0b00000, 0b01000, 0b10101, 0b00010, 0b00000, 0b00000]),
];

/// Glyphs with a descender: drawn two font pixels lower (their bitmaps start at x-height).
const DESCENDERS: &str = "gpqy";

fn glyph(c: char) -> Option<&'static [u8; 7]> {
    FONT.iter().find(|(g, _)| *g == c).map(|(_, b)| b)
}

impl Canvas {
    pub fn new(width: u32, height: u32) -> Self {
        Self {
            width,
            height,
            data: vec![255; width as usize * height as usize * 3],
        }
    }
    pub fn data(&self) -> &[u8] {
        &self.data
    }
    pub fn put(&mut self, x: i64, y: i64, c: Rgb) {
        if x < 0 || y < 0 || x >= i64::from(self.width) || y >= i64::from(self.height) {
            return;
        }
        let i = (y as usize * self.width as usize + x as usize) * 3;
        self.data[i..i + 3].copy_from_slice(&c);
    }
    /// Blend `c` over the pixel with opacity `a` in [0, 1].
    pub fn blend(&mut self, x: i64, y: i64, c: Rgb, a: f64) {
        if x < 0 || y < 0 || x >= i64::from(self.width) || y >= i64::from(self.height) {
            return;
        }
        let a = a.clamp(0.0, 1.0);
        let i = (y as usize * self.width as usize + x as usize) * 3;
        for (d, &ck) in self.data[i..i + 3].iter_mut().zip(&c) {
            let v = f64::from(*d) * (1.0 - a) + f64::from(ck) * a;
            *d = v.round() as u8;
        }
    }
    pub fn fill_rect(&mut self, x0: i64, y0: i64, x1: i64, y1: i64, c: Rgb) {
        for y in y0.min(y1)..=y0.max(y1) {
            for x in x0.min(x1)..=x0.max(x1) {
                self.put(x, y, c);
            }
        }
    }
    pub fn rect(&mut self, x0: i64, y0: i64, x1: i64, y1: i64, c: Rgb) {
        for x in x0..=x1 {
            self.put(x, y0, c);
            self.put(x, y1, c);
        }
        for y in y0..=y1 {
            self.put(x0, y, c);
            self.put(x1, y, c);
        }
    }
    /// Anti-aliased line of width `w` px (distance-to-segment coverage).
    pub fn line(&mut self, x0: f64, y0: f64, x1: f64, y1: f64, c: Rgb, w: f64) {
        if ![x0, y0, x1, y1].iter().all(|v| v.is_finite()) {
            return;
        }
        let r = 0.5 * w;
        let (minx, maxx) = (
            (x0.min(x1) - r - 1.0).floor(),
            (x0.max(x1) + r + 1.0).ceil(),
        );
        let (miny, maxy) = (
            (y0.min(y1) - r - 1.0).floor(),
            (y0.max(y1) + r + 1.0).ceil(),
        );
        let (dx, dy) = (x1 - x0, y1 - y0);
        let len2 = dx * dx + dy * dy;
        for y in miny as i64..=maxy as i64 {
            for x in minx as i64..=maxx as i64 {
                let (px, py) = (x as f64, y as f64);
                let t = if len2 > 0.0 {
                    (((px - x0) * dx + (py - y0) * dy) / len2).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                let (qx, qy) = (x0 + t * dx - px, y0 + t * dy - py);
                let d = (qx * qx + qy * qy).sqrt();
                let a = (r + 0.5 - d).clamp(0.0, 1.0);
                if a > 0.0 {
                    self.blend(x, y, c, a);
                }
            }
        }
    }
    /// Dashed line (dash and gap lengths in px).
    pub fn dashed(&mut self, from: (f64, f64), to: (f64, f64), c: Rgb, w: f64, dash: f64) {
        let ((x0, y0), (x1, y1)) = (from, to);
        let len = ((x1 - x0).powi(2) + (y1 - y0).powi(2)).sqrt();
        if !(len.is_finite() && len > 0.0 && dash > 0.0) {
            return;
        }
        let n = (len / (2.0 * dash)).ceil() as i64;
        for k in 0..n {
            let a = (2 * k) as f64 * dash / len;
            let b = ((2 * k + 1) as f64 * dash / len).min(1.0);
            self.line(
                x0 + a * (x1 - x0),
                y0 + a * (y1 - y0),
                x0 + b * (x1 - x0),
                y0 + b * (y1 - y0),
                c,
                w,
            );
        }
    }
    pub fn marker(&mut self, x: f64, y: f64, m: Marker, c: Rgb, size: f64) {
        if !(x.is_finite() && y.is_finite()) {
            return;
        }
        let s = size;
        match m {
            Marker::Circle | Marker::Square | Marker::Diamond => {
                let r = s.ceil() as i64 + 1;
                let (xi, yi) = (x.round() as i64, y.round() as i64);
                for py in yi - r..=yi + r {
                    for px in xi - r..=xi + r {
                        let (ux, uy) = (px as f64 - x, py as f64 - y);
                        let d = match m {
                            Marker::Circle => (ux * ux + uy * uy).sqrt(),
                            Marker::Square => ux.abs().max(uy.abs()) * 1.1,
                            _ => (ux.abs() + uy.abs()) * 0.8,
                        };
                        let a = (s + 0.5 - d).clamp(0.0, 1.0);
                        if a > 0.0 {
                            self.blend(px, py, c, a);
                        }
                    }
                }
            }
            Marker::Triangle => {
                let h = s * 1.2;
                self.line(x - h, y + h * 0.8, x + h, y + h * 0.8, c, 2.0);
                self.line(x - h, y + h * 0.8, x, y - h, c, 2.0);
                self.line(x + h, y + h * 0.8, x, y - h, c, 2.0);
            }
            Marker::Cross => {
                self.line(x - s, y - s, x + s, y + s, c, 2.0);
                self.line(x - s, y + s, x + s, y - s, c, 2.0);
            }
        }
    }
    /// Width in px of `s` drawn at `scale`.
    pub fn text_width(s: &str, scale: i64) -> i64 {
        s.chars().count() as i64 * (GW + 1) * scale
    }
    pub fn text_height(scale: i64) -> i64 {
        GH * scale
    }
    /// Text with its top-left corner at (x, y); unknown characters draw as blanks.
    pub fn text(&mut self, x: i64, y: i64, s: &str, c: Rgb, scale: i64) {
        let mut cx = x;
        for ch in s.chars() {
            let drop = if DESCENDERS.contains(ch) { 2 } else { 0 };
            if let Some(g) = glyph(ch) {
                for (row, bits) in g.iter().enumerate() {
                    for col in 0..GW {
                        if bits >> (GW - 1 - col) & 1 == 1 {
                            let py = y + (row as i64 + drop) * scale;
                            let px = cx + col * scale;
                            self.fill_rect(px, py, px + scale - 1, py + scale - 1, c);
                        }
                    }
                }
            }
            cx += (GW + 1) * scale;
        }
    }
    /// Text rotated 90 degrees counter-clockwise, reading bottom to top, with its bottom-left
    /// corner at (x, y).
    pub fn text_up(&mut self, x: i64, y: i64, s: &str, c: Rgb, scale: i64) {
        let mut cy = y;
        for ch in s.chars() {
            let drop = if DESCENDERS.contains(ch) { 2 } else { 0 };
            if let Some(g) = glyph(ch) {
                for (row, bits) in g.iter().enumerate() {
                    for col in 0..GW {
                        if bits >> (GW - 1 - col) & 1 == 1 {
                            let px = x + (row as i64 + drop) * scale;
                            let py = cy - (col + 1) * scale;
                            self.fill_rect(px, py, px + scale - 1, py + scale - 1, c);
                        }
                    }
                }
            }
            cy -= (GW + 1) * scale;
        }
    }
    pub fn save_png(&self, path: &Path) -> Result<(), PlotError> {
        image::save_buffer(
            path,
            &self.data,
            self.width,
            self.height,
            image::ColorType::Rgb8,
        )
        .map_err(|source| PlotError::Write {
            path: path.display().to_string(),
            source,
        })
    }
}

/// A log-log plot area inside a canvas.
#[derive(Debug, Clone, Copy)]
pub struct LogAxes {
    /// Pixel box of the plot area.
    pub left: f64,
    pub top: f64,
    pub width: f64,
    pub height: f64,
    /// Decades shown: [10^x0, 10^x1] x [10^y0, 10^y1].
    pub x0: f64,
    pub x1: f64,
    pub y0: f64,
    pub y1: f64,
}

/// "1e-3" style label of a decade.
pub fn decade_label(e: i64) -> String {
    match e {
        0 => "1".into(),
        1 => "10".into(),
        _ => format!("1e{e}"),
    }
}

impl LogAxes {
    pub fn px(&self, x: f64, y: f64) -> (f64, f64) {
        let u = (x.log10() - self.x0) / (self.x1 - self.x0);
        let v = (y.log10() - self.y0) / (self.y1 - self.y0);
        (
            self.left + u * self.width,
            self.top + (1.0 - v) * self.height,
        )
    }
    /// Frame, decade grid, tick labels and axis titles.
    pub fn draw(&self, c: &mut Canvas, xlabel: &str, ylabel: &str, title: &str) {
        let (l, t, r, b) = (
            self.left,
            self.top,
            self.left + self.width,
            self.top + self.height,
        );
        let sc = 2;
        for e in self.x0.ceil() as i64..=self.x1.floor() as i64 {
            let (x, _) = self.px(10f64.powi(e as i32), 1.0);
            c.line(x, t, x, b, LIGHT, 1.0);
            let s = decade_label(e);
            let w = Canvas::text_width(&s, sc);
            c.text(x.round() as i64 - w / 2, b as i64 + 8, &s, BLACK, sc);
        }
        for e in self.y0.ceil() as i64..=self.y1.floor() as i64 {
            let (_, y) = self.px(1.0, 10f64.powi(e as i32));
            c.line(l, y, r, y, LIGHT, 1.0);
            let s = decade_label(e);
            let w = Canvas::text_width(&s, sc);
            c.text(l as i64 - w - 8, y.round() as i64 - 7, &s, BLACK, sc);
        }
        c.rect(l as i64, t as i64, r as i64, b as i64, BLACK);
        let w = Canvas::text_width(xlabel, sc);
        c.text(
            ((l + r) * 0.5) as i64 - w / 2,
            b as i64 + 32,
            xlabel,
            BLACK,
            sc,
        );
        let w = Canvas::text_width(ylabel, sc);
        c.text_up(
            l as i64 - 90,
            ((t + b) * 0.5) as i64 + w / 2,
            ylabel,
            BLACK,
            sc,
        );
        let w = Canvas::text_width(title, sc);
        c.text(
            ((l + r) * 0.5) as i64 - w / 2,
            t as i64 - 24,
            title,
            BLACK,
            sc,
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn text_and_lines_draw_pixels() {
        let mut c = Canvas::new(100, 40);
        c.text(2, 2, "1e-3 ok", BLACK, 1);
        c.line(0.0, 30.0, 99.0, 30.0, [255, 0, 0], 2.0);
        let dark = c.data().chunks(3).filter(|p| p[0] < 50).count();
        assert!(dark > 20);
        assert!(c.data().chunks(3).any(|p| p == [255, 0, 0]));
        assert!(Canvas::text_width("abc", 2) == 36);
        assert!(glyph('x').is_some() && glyph('Q').is_some());
    }
}
