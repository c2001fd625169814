//! The picture a person checks the contact stage with: the frame with the contact region's
//! outline (red) and centroid (a yellow cross), marker displacement arrows (green) where given,
//! and, with depth, beside it the depth colour map (0 to 1 mm; grey where the depth is unknown)
//! with the depth's contact outline (white). One implementation for `unitac contact --overlay`
//! (PNG files) and the contact stage's `overlay` param (the `contact_overlay` topic).

use unitac_core::{Frame, FrameError};

/// Colour of the contact outline on the frame.
pub const OUTLINE: [u8; 3] = [255, 0, 0];
/// Colour of the centroid cross.
pub const CENTROID: [u8; 3] = [255, 255, 0];
/// Colour of the depth's contact outline on the depth panel.
pub const DEPTH_OUTLINE: [u8; 3] = [255, 255, 255];
/// Colour of the marker displacement arrows.
pub const ARROW: [u8; 3] = [0, 255, 0];
/// Colour of pixels of unknown depth on the depth panel.
pub const UNKNOWN: [u8; 3] = [128, 128, 128];
/// Depth at the top of the colour map \[m].
pub const DEPTH_SCALE_M: f32 = 1e-3;

/// The depth panel: depth per pixel \[m, NaN = unknown] and its contact region, row-major at
/// the frame's size.
#[derive(Debug, Clone, Copy)]
pub struct DepthPanel<'a> {
    pub depth_m: &'a [f32],
    pub mask: &'a [bool],
}

/// What is drawn on one frame.
#[derive(Debug, Clone, Copy, Default)]
pub struct Overlay<'a> {
    /// The contact region in the frame's pixels (row-major; empty: none).
    pub contact: &'a [bool],
    /// Centroid \[px] (x, y); None: no cross.
    pub centroid: Option<[f32; 2]>,
    /// Marker displacements: (from, to) \[px].
    pub arrows: &'a [([f32; 2], [f32; 2])],
    /// The depth panel, beside the frame.
    pub depth: Option<DepthPanel<'a>>,
}

/// Viridis-like colour of t in 0..=1.
pub fn ramp(t: f32) -> [u8; 3] {
    let t = if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let stops = [
        [48.0, 18.0, 59.0],
        [33.0, 145.0, 140.0],
        [122.0, 209.0, 81.0],
        [253.0, 231.0, 37.0],
    ];
    let x = t * 3.0;
    let i = (x.floor() as usize).min(2);
    let f = x - i as f32;
    let mut o = [0u8; 3];
    for (c, v) in o.iter_mut().enumerate() {
        *v = (stops[i][c] * (1.0 - f) + stops[i + 1][c] * f) as u8;
    }
    o
}

/// Whether pixel (x, y) is on the edge of region `m` (w x h, row-major).
fn edge(m: &[bool], w: usize, h: usize, x: usize, y: usize) -> bool {
    let at = |x: usize, y: usize| m.get(y * w + x).copied().unwrap_or(false);
    at(x, y)
        && (x == 0
            || y == 0
            || x + 1 == w
            || y + 1 == h
            || !at(x - 1, y)
            || !at(x + 1, y)
            || !at(x, y - 1)
            || !at(x, y + 1))
}

/// The overlay of `frame`: as wide as the frame (twice with a depth panel), as high, RGB8, the
/// frame's sensor id, sequence and stamp. Regions of another size than the frame's draw nothing
/// beyond their ends (they are read with bounds checks).
pub fn draw(frame: &Frame, o: &Overlay<'_>) -> Result<Frame, FrameError> {
    let (w, h) = (frame.width as usize, frame.height as usize);
    let panels = if o.depth.is_some() { 2 } else { 1 };
    let ow = w * panels;
    let mut img = vec![0u8; ow * h * 3];
    let mut put = |x: usize, y: usize, c: [u8; 3]| {
        if let Some(p) = img.get_mut((y * ow + x) * 3..(y * ow + x) * 3 + 3) {
            p.copy_from_slice(&c);
        }
    };
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            let p = frame.data().get(i * 3..i * 3 + 3).unwrap_or(&[0, 0, 0]);
            let c = if edge(o.contact, w, h, x, y) {
                OUTLINE
            } else {
                [p[0], p[1], p[2]]
            };
            put(x, y, c);
            if let Some(d) = o.depth {
                let v = d.depth_m.get(i).copied().unwrap_or(f32::NAN);
                let c = if edge(d.mask, w, h, x, y) {
                    DEPTH_OUTLINE
                } else if v.is_finite() {
                    ramp(v / DEPTH_SCALE_M)
                } else {
                    UNKNOWN
                };
                put(w + x, y, c);
            }
        }
    }
    // Arrows: a line from the marker's rest position to where it is, a small head at its end.
    let mut line = |a: [f32; 2], b: [f32; 2]| {
        let n = ((b[0] - a[0]).abs().max((b[1] - a[1]).abs()).ceil() as usize).min(4 * (w + h));
        for k in 0..=n {
            let t = if n == 0 { 0.0 } else { k as f32 / n as f32 };
            let (x, y) = (a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t);
            if x >= 0.0 && y >= 0.0 && (x.round() as usize) < w && (y.round() as usize) < h {
                put(x.round() as usize, y.round() as usize, ARROW);
            }
        }
    };
    for &(from, to) in o.arrows {
        if !(from.iter().chain(&to).all(|v| v.is_finite())) {
            continue;
        }
        line(from, to);
        let (dx, dy) = (to[0] - from[0], to[1] - from[1]);
        let len = dx.hypot(dy);
        if len >= 1.0 {
            let (ux, uy) = (dx / len, dy / len);
            let s = len.min(3.0);
            for (px, py) in [(-uy, ux), (uy, -ux)] {
                line(to, [to[0] - s * (ux - px), to[1] - s * (uy - py)]);
            }
        }
    }
    if let Some([cx, cy]) = o.centroid {
        let (cx, cy) = (cx.round() as i64, cy.round() as i64);
        for k in -4..=4i64 {
            for (x, y) in [(cx + k, cy), (cx, cy + k)] {
                if x >= 0 && y >= 0 && (x as usize) < w && (y as usize) < h {
                    put(x as usize, y as usize, CENTROID);
                }
            }
        }
    }
    Frame::new(
        frame.sensor_id.clone(),
        frame.seq,
        frame.stamp,
        ow as u32,
        frame.height,
        img,
    )
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use unitac_core::Stamp;

    fn frame(w: u32, h: u32) -> Frame {
        Frame::new("gs", 3, Stamp(7), w, h, vec![40; (w * h * 3) as usize]).unwrap()
    }
    fn px(f: &Frame, x: u32, y: u32) -> [u8; 3] {
        let i = ((y * f.width + x) * 3) as usize;
        let d = f.data();
        [d[i], d[i + 1], d[i + 2]]
    }

    #[test]
    fn outline_centroid_arrows_and_depth_are_drawn_where_they_are() {
        let f = frame(20, 10);
        // A 6 x 4 block at (5..11, 3..7).
        let mut m = vec![false; 200];
        for y in 3..7 {
            for x in 5..11 {
                m[y * 20 + x] = true;
            }
        }
        let mut depth = vec![0.5e-3f32; 200];
        depth[0] = f32::NAN;
        let arrows = [([15.0, 2.0], [18.0, 2.0])];
        let o = Overlay {
            contact: &m,
            centroid: Some([8.0, 5.0]),
            arrows: &arrows,
            depth: Some(DepthPanel {
                depth_m: &depth,
                mask: &m,
            }),
        };
        let img = draw(&f, &o).unwrap();
        assert_eq!(
            (img.width, img.height, img.stamp, img.seq),
            (40, 10, Stamp(7), 3)
        );
        // The outline: the block's edge, not its inside nor outside.
        assert_eq!(px(&img, 5, 3), OUTLINE);
        assert_eq!(px(&img, 10, 4), OUTLINE);
        assert_eq!(px(&img, 6, 4), [40, 40, 40]);
        assert_eq!(px(&img, 4, 4), [40, 40, 40]);
        // The cross at the centroid, the arrow's line.
        assert_eq!(px(&img, 8, 5), CENTROID);
        assert_eq!(px(&img, 8, 1), CENTROID);
        assert_eq!(px(&img, 16, 2), ARROW);
        // The depth panel: the colour map where known, grey where not, the depth outline.
        assert_eq!(px(&img, 20 + 1, 0), ramp(0.5));
        assert_eq!(px(&img, 20, 0), UNKNOWN);
        assert_eq!(px(&img, 20 + 5, 3), DEPTH_OUTLINE);
        // Nothing to draw: the frame as it was.
        let plain = draw(&f, &Overlay::default()).unwrap();
        assert_eq!(plain.data(), f.data());
    }
}
