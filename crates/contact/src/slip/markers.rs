//! The gel's marker dots in one frame: dark blobs against the local brightness, with sub-pixel
//! centroids.
//!
//! On the luminance `r + g + b` (the three coloured lights of a GelSight-style sensor come from
//! directions 120 degrees apart, so the slope shading of a press largely cancels in the sum and
//! the dots stay the darkest thing on the gel), a pixel is part of a dot when it is darker than
//! `dot_ratio` times the mean of the box around it. The 8-connected regions of such pixels with
//! an area in `[min_area_px, max_area_px]` are dots; each dot's centroid is weighted by how much
//! darker than its surroundings each pixel is, which places it to a fraction of a pixel.

use unitac_core::Frame;

/// Most dots a frame may hold (a GelSight Mini has about a hundred); more is not a marker gel.
pub const MAX_DOTS: usize = 4096;

/// How dots are found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DotParams {
    /// Half-width of the box the local mean is taken over \[px].
    pub box_radius_px: u32,
    /// A pixel darker than this fraction of its local mean belongs to a dot.
    pub dot_ratio: f64,
    /// Dot area bounds \[px].
    pub min_area_px: u32,
    pub max_area_px: u32,
}

/// One dot: centroid \[px] (x, y) and area \[px].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Dot {
    pub centre: [f64; 2],
    pub area_px: u32,
}

/// Why a frame's dots could not be listed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum DotError {
    #[error("more than {MAX_DOTS} dark dots: not a marker pattern")]
    TooMany,
}

/// The dots of `frame`, in raster order of their first pixel.
pub fn find_dots(frame: &Frame, p: &DotParams) -> Result<Vec<Dot>, DotError> {
    let (w, h) = (frame.width as usize, frame.height as usize);
    if w == 0 || h == 0 {
        return Ok(Vec::new());
    }
    let lum: Vec<u32> = frame
        .data()
        .chunks_exact(3)
        .map(|c| u32::from(c[0]) + u32::from(c[1]) + u32::from(c[2]))
        .collect();
    // Integral image, (w + 1) x (h + 1).
    let iw = w + 1;
    let mut integral = vec![0u64; iw * (h + 1)];
    for y in 0..h {
        let mut row = 0u64;
        for x in 0..w {
            row += u64::from(lum[y * w + x]);
            integral[(y + 1) * iw + x + 1] = integral[y * iw + x + 1] + row;
        }
    }
    let r = p.box_radius_px as usize;
    // Darkness below the local mean of each dot pixel (0: not a dot pixel).
    let mut dark = vec![0f64; w * h];
    for y in 0..h {
        let (y0, y1) = (y.saturating_sub(r), (y + r + 1).min(h));
        for x in 0..w {
            let (x0, x1) = (x.saturating_sub(r), (x + r + 1).min(w));
            let sum = integral[y1 * iw + x1] + integral[y0 * iw + x0]
                - integral[y0 * iw + x1]
                - integral[y1 * iw + x0];
            let mean = sum as f64 / ((x1 - x0) * (y1 - y0)) as f64;
            let l = f64::from(lum[y * w + x]);
            if l < p.dot_ratio * mean {
                dark[y * w + x] = mean - l;
            }
        }
    }
    // 8-connected regions of dot pixels, by an explicit stack.
    let mut seen = vec![false; w * h];
    let mut dots = Vec::new();
    let mut stack = Vec::new();
    for start in 0..w * h {
        if seen[start] || dark[start] <= 0.0 {
            continue;
        }
        seen[start] = true;
        stack.push(start);
        let (mut sw, mut sx, mut sy, mut area) = (0.0, 0.0, 0.0, 0u32);
        while let Some(i) = stack.pop() {
            let (x, y) = (i % w, i / w);
            let d = dark[i];
            sw += d;
            sx += d * x as f64;
            sy += d * y as f64;
            area += 1;
            for ny in y.saturating_sub(1)..(y + 2).min(h) {
                for nx in x.saturating_sub(1)..(x + 2).min(w) {
                    let j = ny * w + nx;
                    if !seen[j] && dark[j] > 0.0 {
                        seen[j] = true;
                        stack.push(j);
                    }
                }
            }
        }
        if area >= p.min_area_px && area <= p.max_area_px && sw > 0.0 {
            if dots.len() == MAX_DOTS {
                return Err(DotError::TooMany);
            }
            dots.push(Dot {
                centre: [sx / sw, sy / sw],
                area_px: area,
            });
        }
    }
    Ok(dots)
}

#[cfg(test)]
mod tests {
    use super::*;
    use unitac_core::{SensorKind, Stamp};

    pub(crate) fn params() -> DotParams {
        DotParams {
            box_radius_px: 7,
            dot_ratio: 0.7,
            min_area_px: 4,
            max_area_px: 200,
        }
    }

    /// A grey frame with soft dark dots at `centres`.
    fn frame_with(centres: &[[f64; 2]]) -> Frame {
        let (w, h) = (64u32, 48u32);
        let mut data = vec![0u8; (w * h * 3) as usize];
        for y in 0..h {
            for x in 0..w {
                let mut v = 150.0;
                for c in centres {
                    let d = ((x as f64 - c[0]).powi(2) + (y as f64 - c[1]).powi(2)).sqrt();
                    let edge = (3.6 - d).clamp(0.0, 1.0);
                    v *= 1.0 - 0.65 * edge;
                }
                let i = ((y * w + x) * 3) as usize;
                data[i..i + 3].fill(v.round() as u8);
            }
        }
        Frame::new("t", 0, Stamp(0), w, h, data).unwrap()
    }

    #[test]
    fn dots_are_found_to_a_fraction_of_a_pixel() {
        let centres = [[12.3, 10.6], [40.0, 30.25], [50.7, 12.0]];
        let dots = find_dots(&frame_with(&centres), &params()).unwrap();
        assert_eq!(dots.len(), 3, "{dots:?}");
        for c in centres {
            let best = dots
                .iter()
                .map(|d| (d.centre[0] - c[0]).hypot(d.centre[1] - c[1]))
                .fold(f64::INFINITY, f64::min);
            assert!(best < 0.15, "{c:?}: {best} px off");
        }
    }

    #[test]
    fn a_gel_without_dots_has_none() {
        let f = Frame::black_of(SensorKind::DIGIT, "d");
        assert!(find_dots(&f, &params()).unwrap().is_empty());
        assert!(find_dots(&frame_with(&[]), &params()).unwrap().is_empty());
    }
}
