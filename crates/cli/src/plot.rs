//! A very small PNG line plotter (log-log axes, coloured series, tick labels from a built-in
//! 3x5 pixel font), enough for error-vs-time figures without a font or plotting dependency.

use image::{Rgb, RgbImage};

pub const COLOURS: [[u8; 3]; 6] = [
    [214, 39, 40],
    [44, 160, 44],
    [31, 119, 180],
    [148, 103, 189],
    [255, 127, 14],
    [23, 190, 207],
];

/// 3x5 glyphs, one u16 per glyph (row-major, top row in the high bits); upper case is drawn
/// as lower case.
fn glyph(c: char) -> Option<u16> {
    Some(match c.to_ascii_lowercase() {
        '0' => 0b111_101_101_101_111,
        '1' => 0b010_110_010_010_111,
        '2' => 0b111_001_111_100_111,
        '3' => 0b111_001_111_001_111,
        '4' => 0b101_101_111_001_001,
        '5' => 0b111_100_111_001_111,
        '6' => 0b111_100_111_101_111,
        '7' => 0b111_001_010_010_010,
        '8' => 0b111_101_111_101_111,
        '9' => 0b111_101_111_001_111,
        '.' => 0b000_000_000_000_010,
        '-' => 0b000_000_111_000_000,
        '=' => 0b000_111_000_111_000,
        '+' => 0b000_010_111_010_000,
        '(' => 0b010_100_100_100_010,
        ')' => 0b010_001_001_001_010,
        ',' => 0b000_000_000_010_100,
        '/' => 0b001_001_010_100_100,
        ':' => 0b000_010_000_010_000,
        '_' => 0b000_000_000_000_111,
        'a' => 0b010_101_111_101_101,
        'b' => 0b110_101_110_101_110,
        'c' => 0b011_100_100_100_011,
        'd' => 0b110_101_101_101_110,
        'e' => 0b111_100_110_100_111,
        'f' => 0b111_100_110_100_100,
        'g' => 0b011_100_101_101_011,
        'h' => 0b101_101_111_101_101,
        'i' => 0b111_010_010_010_111,
        'j' => 0b001_001_001_101_010,
        'k' => 0b101_110_100_110_101,
        'l' => 0b100_100_100_100_111,
        'm' => 0b101_111_111_101_101,
        'n' => 0b110_101_101_101_101,
        'o' => 0b010_101_101_101_010,
        'p' => 0b110_101_110_100_100,
        'q' => 0b010_101_101_110_011,
        'r' => 0b110_101_110_101_101,
        's' => 0b011_100_010_001_110,
        't' => 0b111_010_010_010_010,
        'u' => 0b101_101_101_101_111,
        'v' => 0b101_101_101_101_010,
        'w' => 0b101_101_111_111_101,
        'x' => 0b101_101_010_101_101,
        'y' => 0b101_101_010_010_010,
        'z' => 0b111_001_010_100_111,
        ' ' => 0b000_000_000_000_000,
        _ => return None,
    })
}

pub fn text(img: &mut RgbImage, x: i64, y: i64, s: &str, scale: i64, colour: [u8; 3]) {
    for (k, c) in s.chars().enumerate() {
        let Some(g) = glyph(c) else { continue };
        for row in 0..5 {
            for col in 0..3 {
                if g >> (14 - (row * 3 + col)) & 1 == 1 {
                    for dy in 0..scale {
                        for dx in 0..scale {
                            put(
                                img,
                                x + (k as i64 * 4 + col) * scale + dx,
                                y + row * scale + dy,
                                colour,
                            );
                        }
                    }
                }
            }
        }
    }
}

fn put(img: &mut RgbImage, x: i64, y: i64, c: [u8; 3]) {
    if x >= 0 && y >= 0 && (x as u32) < img.width() && (y as u32) < img.height() {
        img.put_pixel(x as u32, y as u32, Rgb(c));
    }
}

fn line(img: &mut RgbImage, (x0, y0): (f64, f64), (x1, y1): (f64, f64), c: [u8; 3], width: i64) {
    let n = ((x1 - x0).abs().max((y1 - y0).abs()).ceil() as i64).max(1);
    for i in 0..=n {
        let t = i as f64 / n as f64;
        let (x, y) = (
            (x0 + t * (x1 - x0)).round() as i64,
            (y0 + t * (y1 - y0)).round() as i64,
        );
        for dy in -(width / 2)..=(width / 2) {
            for dx in -(width / 2)..=(width / 2) {
                put(img, x + dx, y + dy, c);
            }
        }
    }
}

#[derive(Debug, Clone)]
pub struct Series {
    pub colour: [u8; 3],
    /// (x, y) points, both > 0 (log axes); non-finite or non-positive points are skipped.
    pub points: Vec<(f64, f64)>,
}

/// One log-log panel into `img` at (ox, oy) of size (w, h).
pub fn loglog(
    img: &mut RgbImage,
    (ox, oy, w, h): (i64, i64, i64, i64),
    series: &[Series],
    title: &str,
) {
    let ok = |(x, y): &(f64, f64)| x.is_finite() && y.is_finite() && *x > 0.0 && *y > 0.0;
    let pts: Vec<(f64, f64)> = series
        .iter()
        .flat_map(|s| s.points.iter().copied())
        .filter(ok)
        .collect();
    if pts.is_empty() {
        return;
    }
    let lo = |v: f64| v.log10().floor();
    let hi = |v: f64| v.log10().ceil();
    let (x0, x1) = (
        pts.iter().map(|p| lo(p.0)).fold(f64::MAX, f64::min),
        pts.iter().map(|p| hi(p.0)).fold(f64::MIN, f64::max),
    );
    let (y0, y1) = (
        pts.iter().map(|p| lo(p.1)).fold(f64::MAX, f64::min),
        pts.iter().map(|p| hi(p.1)).fold(f64::MIN, f64::max),
    );
    let (x1, y1) = (x1.max(x0 + 1.0), y1.max(y0 + 1.0));
    let (pl, pt, pw, ph) = (ox + 50, oy + 24, w - 64, h - 54);
    let map = |(x, y): (f64, f64)| {
        (
            pl as f64 + (x.log10() - x0) / (x1 - x0) * pw as f64,
            (pt + ph) as f64 - (y.log10() - y0) / (y1 - y0) * ph as f64,
        )
    };
    let grey = [200, 200, 200];
    for d in (x0 as i64)..=(x1 as i64) {
        let (x, _) = map((10f64.powi(d as i32), 10f64.powf(y0)));
        line(img, (x, pt as f64), (x, (pt + ph) as f64), grey, 1);
        text(
            img,
            x as i64 - 8,
            pt + ph + 6,
            &format!("1e{d}"),
            2,
            [0, 0, 0],
        );
    }
    for d in (y0 as i64)..=(y1 as i64) {
        let (_, y) = map((10f64.powf(x0), 10f64.powi(d as i32)));
        line(img, (pl as f64, y), ((pl + pw) as f64, y), grey, 1);
        text(img, ox + 2, y as i64 - 5, &format!("1e{d}"), 2, [0, 0, 0]);
    }
    line(
        img,
        (pl as f64, (pt + ph) as f64),
        ((pl + pw) as f64, (pt + ph) as f64),
        [0, 0, 0],
        1,
    );
    line(
        img,
        (pl as f64, pt as f64),
        (pl as f64, (pt + ph) as f64),
        [0, 0, 0],
        1,
    );
    text(img, pl, oy + 4, title, 2, [0, 0, 0]);
    for s in series {
        let p: Vec<(f64, f64)> = s.points.iter().copied().filter(ok).map(map).collect();
        for w in p.windows(2) {
            line(img, w[0], w[1], s.colour, 3);
        }
        for &(x, y) in &p {
            for dy in -3..=3 {
                for dx in -3..=3 {
                    put(img, x as i64 + dx, y as i64 + dy, s.colour);
                }
            }
        }
    }
}

/// A grid of coloured cells (stability maps): rows x cols, true = green.
pub fn grid(
    img: &mut RgbImage,
    (ox, oy, cell): (i64, i64, i64),
    cells: &[Vec<bool>],
    row_labels: &[String],
    col_labels: &[String],
    title: &str,
) {
    text(img, ox, oy, title, 2, [0, 0, 0]);
    let (gx, gy) = (ox + 70, oy + 20);
    for (r, row) in cells.iter().enumerate() {
        if let Some(l) = row_labels.get(r) {
            text(
                img,
                ox,
                gy + r as i64 * cell + cell / 2 - 5,
                l,
                2,
                [0, 0, 0],
            );
        }
        for (c, &v) in row.iter().enumerate() {
            let colour = if v { [120, 200, 120] } else { [230, 110, 110] };
            for y in 1..cell {
                for x in 1..cell {
                    put(
                        img,
                        gx + c as i64 * cell + x,
                        gy + r as i64 * cell + y,
                        colour,
                    );
                }
            }
        }
    }
    for (c, l) in col_labels.iter().enumerate() {
        text(
            img,
            gx + c as i64 * cell + 4,
            gy + cells.len() as i64 * cell + 6,
            l,
            2,
            [0, 0, 0],
        );
    }
}
