//! The detection grid: block means of the frame, and binary-mask morphology on it.

use unitac_core::Frame;

/// Grid geometry for a frame size and stride (stride shrinks for tiny images).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Geometry {
    pub width: u32,
    pub height: u32,
    pub stride: u32,
    pub gw: usize,
    pub gh: usize,
}

impl Geometry {
    pub fn new(width: u32, height: u32, stride: u32) -> Self {
        let s = stride.min(width).min(height).max(1);
        Self {
            width,
            height,
            stride: s,
            gw: (width / s) as usize,
            gh: (height / s) as usize,
        }
    }
    pub fn cells(&self) -> usize {
        self.gw * self.gh
    }
    /// Input-image pixels covered by one cell.
    pub fn cell_px(&self) -> f32 {
        (self.stride * self.stride) as f32
    }
}

/// Block means, RGB interleaved, into `out` (resized as needed). One pass over the frame.
pub fn block_means(f: &Frame, g: &Geometry, out: &mut Vec<f32>) {
    let s = g.stride as usize;
    let w = f.width as usize;
    out.clear();
    out.resize(g.cells() * 3, 0.0);
    let data = f.data();
    for gy in 0..g.gh {
        let row_out = &mut out[gy * g.gw * 3..(gy + 1) * g.gw * 3];
        for dy in 0..s {
            let y = gy * s + dy;
            let row = &data[y * w * 3..y * w * 3 + g.gw * s * 3];
            for (cell, px) in row_out.chunks_exact_mut(3).zip(row.chunks_exact(s * 3)) {
                for p in px.chunks_exact(3) {
                    cell[0] += f32::from(p[0]);
                    cell[1] += f32::from(p[1]);
                    cell[2] += f32::from(p[2]);
                }
            }
        }
    }
    let inv = 1.0 / (s * s) as f32;
    for v in out.iter_mut() {
        *v *= inv;
    }
}

/// Separable square min (erode) or max (dilate) of radius r on a 0/1 mask.
fn morph(mask: &mut [u8], tmp: &mut Vec<u8>, gw: usize, gh: usize, r: usize, dilate: bool) {
    if r == 0 || mask.is_empty() {
        return;
    }
    tmp.clear();
    tmp.resize(mask.len(), 0);
    let pick = |a: u8, b: u8| if dilate { a.max(b) } else { a.min(b) };
    // Outside the image counts as background for dilation and as foreground for erosion, so an
    // opening does not eat contacts touching the border.
    let outside = u8::from(!dilate);
    for y in 0..gh {
        let row = &mask[y * gw..(y + 1) * gw];
        for x in 0..gw {
            let mut v = row[x];
            for k in 1..=r {
                let l = if x >= k { row[x - k] } else { outside };
                let rr = if x + k < gw { row[x + k] } else { outside };
                v = pick(v, pick(l, rr));
            }
            tmp[y * gw + x] = v;
        }
    }
    for y in 0..gh {
        for x in 0..gw {
            let mut v = tmp[y * gw + x];
            for k in 1..=r {
                let u = if y >= k {
                    tmp[(y - k) * gw + x]
                } else {
                    outside
                };
                let d = if y + k < gh {
                    tmp[(y + k) * gw + x]
                } else {
                    outside
                };
                v = pick(v, pick(u, d));
            }
            mask[y * gw + x] = v;
        }
    }
}

/// Opening (radius `open`) then closing (radius `close`).
pub fn open_close(mask: &mut [u8], tmp: &mut Vec<u8>, gw: usize, gh: usize, open: u32, close: u32) {
    let (o, c) = (open as usize, close as usize);
    morph(mask, tmp, gw, gh, o, false);
    morph(mask, tmp, gw, gh, o, true);
    morph(mask, tmp, gw, gh, c, true);
    morph(mask, tmp, gw, gh, c, false);
}

/// Keep 4-connected components of at least `min_cells`; returns how many cells were kept.
/// `labels` and `stack` are scratch buffers.
pub fn keep_components(
    mask: &mut [u8],
    gw: usize,
    gh: usize,
    min_cells: usize,
    labels: &mut Vec<u32>,
    stack: &mut Vec<usize>,
) -> usize {
    labels.clear();
    labels.resize(mask.len(), 0);
    let mut sizes: Vec<usize> = vec![0];
    for start in 0..mask.len() {
        if mask[start] == 0 || labels[start] != 0 {
            continue;
        }
        let id = sizes.len() as u32;
        let mut n = 0;
        stack.clear();
        stack.push(start);
        labels[start] = id;
        while let Some(i) = stack.pop() {
            n += 1;
            let (x, y) = (i % gw, i / gw);
            let mut visit = |j: usize| {
                if mask[j] != 0 && labels[j] == 0 {
                    labels[j] = id;
                    stack.push(j);
                }
            };
            if x > 0 {
                visit(i - 1);
            }
            if x + 1 < gw {
                visit(i + 1);
            }
            if y > 0 {
                visit(i - gw);
            }
            if y + 1 < gh {
                visit(i + gw);
            }
        }
        sizes.push(n);
    }
    let mut kept = 0;
    for (m, &l) in mask.iter_mut().zip(labels.iter()) {
        if *m != 0 {
            if sizes[l as usize] >= min_cells {
                kept += 1;
            } else {
                *m = 0;
            }
        }
    }
    kept
}

#[cfg(test)]
mod tests {
    use super::*;
    use unitac_core::Stamp;

    #[test]
    fn block_means_average_each_block() {
        // 4x2 image, stride 2: two cells.
        let mut d = Vec::new();
        for v in [0u8, 10, 20, 30, 40, 50, 60, 70] {
            d.extend([v, v, 255 - v]);
        }
        let f = Frame::new("t", 0, Stamp::ZERO, 4, 2, d).unwrap();
        let g = Geometry::new(4, 2, 2);
        let mut out = Vec::new();
        block_means(&f, &g, &mut out);
        assert_eq!(out, vec![25.0, 25.0, 230.0, 45.0, 45.0, 210.0]);
        // Tiny images shrink the stride instead of producing an empty grid.
        let g1 = Geometry::new(1, 1, 4);
        assert_eq!((g1.stride, g1.cells()), (1, 1));
    }

    #[test]
    fn opening_removes_specks_closing_fills_lines() {
        let (gw, gh) = (12, 9);
        let mut m = vec![0u8; gw * gh];
        // An 8x5 blob with a one-cell dark line through it (3 + 4 wide), and a lone speck.
        for y in 2..7 {
            for x in 2..10 {
                m[y * gw + x] = u8::from(x != 5);
            }
        }
        m[gw + 11] = 1;
        let mut tmp = Vec::new();
        open_close(&mut m, &mut tmp, gw, gh, 1, 1);
        assert_eq!(m[gw + 11], 0, "speck removed");
        assert_eq!(m[4 * gw + 5], 1, "line filled");
    }

    #[test]
    fn small_components_are_dropped() {
        let (gw, gh) = (8, 3);
        let mut m = vec![0u8; gw * gh];
        for x in 0..4 {
            m[gw + x] = 1; // 4 cells
        }
        m[7] = 1; // 1 cell
        let (mut l, mut s) = (Vec::new(), Vec::new());
        assert_eq!(keep_components(&mut m, gw, gh, 2, &mut l, &mut s), 4);
        assert_eq!(m[7], 0);
    }
}
