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

/// Block means, RGB interleaved, into `out` (resized as needed). One pass over the frame, integer
/// sums per cell row, one conversion per cell.
pub fn block_means(f: &Frame, g: &Geometry, out: &mut Vec<f32>) {
    let s = g.stride as usize;
    let w = f.width as usize;
    let used = g.gw * s * 3;
    out.clear();
    out.resize(g.cells() * 3, 0.0);
    let data = f.data();
    let inv = 1.0 / (s * s) as f32;
    let mut sums = vec![0u32; g.gw * 3];
    for gy in 0..g.gh {
        sums.fill(0);
        for dy in 0..s {
            let y = gy * s + dy;
            let row = &data[y * w * 3..y * w * 3 + used];
            if s == 2 {
                for (cell, px) in sums.chunks_exact_mut(3).zip(row.chunks_exact(6)) {
                    cell[0] += u32::from(px[0]) + u32::from(px[3]);
                    cell[1] += u32::from(px[1]) + u32::from(px[4]);
                    cell[2] += u32::from(px[2]) + u32::from(px[5]);
                }
            } else {
                for (cell, px) in sums.chunks_exact_mut(3).zip(row.chunks_exact(s * 3)) {
                    for p in px.chunks_exact(3) {
                        cell[0] += u32::from(p[0]);
                        cell[1] += u32::from(p[1]);
                        cell[2] += u32::from(p[2]);
                    }
                }
            }
        }
        for (o, &v) in out[gy * g.gw * 3..(gy + 1) * g.gw * 3]
            .iter_mut()
            .zip(&sums)
        {
            *o = v as f32 * inv;
        }
    }
}

/// A binary mask packed 64 cells per word, row by row; bit j of word i of a row is cell
/// x = 64 i + j. Padding bits past the row's end are kept at zero between operations.
#[derive(Debug, Default, Clone)]
pub struct BitMask {
    gw: usize,
    gh: usize,
    wpr: usize,
    words: Vec<u64>,
    tmp: Vec<u64>,
}

impl BitMask {
    pub fn reset(&mut self, gw: usize, gh: usize) {
        self.gw = gw;
        self.gh = gh;
        self.wpr = gw.div_ceil(64);
        self.words.clear();
        self.words.resize(self.wpr * gh, 0);
    }
    pub fn set(&mut self, x: usize, y: usize) {
        self.words[y * self.wpr + x / 64] |= 1u64 << (x % 64);
    }
    pub fn get(&self, x: usize, y: usize) -> bool {
        self.words[y * self.wpr + x / 64] >> (x % 64) & 1 == 1
    }
    pub fn is_empty(&self) -> bool {
        self.words.iter().all(|&w| w == 0)
    }
    fn pad_mask(&self) -> u64 {
        match self.gw % 64 {
            0 => !0,
            r => (1u64 << r) - 1,
        }
    }
    fn set_padding(&mut self, ones: bool) {
        let (m, wpr) = (self.pad_mask(), self.wpr);
        if wpr == 0 {
            return;
        }
        for row in self.words.chunks_exact_mut(wpr) {
            if let Some(last) = row.last_mut() {
                *last = if ones { *last | !m } else { *last & m };
            }
        }
    }

    /// Horizontal then vertical min (erode) or max (dilate) over a (2r+1)^2 square. Outside the
    /// grid counts as background for dilation and as foreground for erosion, so an opening does
    /// not eat contacts touching the border.
    fn morph(&mut self, r: usize, dilate: bool) {
        if r == 0 || self.words.is_empty() {
            return;
        }
        let r = r.min(63);
        let wpr = self.wpr;
        let outside = if dilate { 0 } else { !0u64 };
        self.set_padding(!dilate);
        self.tmp.clear();
        self.tmp.resize(self.words.len(), 0);
        for (row, out) in self
            .words
            .chunks_exact(wpr)
            .zip(self.tmp.chunks_exact_mut(wpr))
        {
            for i in 0..wpr {
                let w = row[i];
                let prev = if i > 0 { row[i - 1] } else { outside };
                let next = if i + 1 < wpr { row[i + 1] } else { outside };
                let mut acc = w;
                for k in 1..=r as u32 {
                    let left = (w << k) | (prev >> (64 - k));
                    let right = (w >> k) | (next << (64 - k));
                    acc = if dilate {
                        acc | left | right
                    } else {
                        acc & left & right
                    };
                }
                out[i] = acc;
            }
        }
        let gh = self.gh;
        for y in 0..gh {
            let (lo, hi) = (y.saturating_sub(r), (y + r).min(gh - 1));
            for i in 0..wpr {
                let mut acc = self.tmp[y * wpr + i];
                for yy in lo..=hi {
                    let v = self.tmp[yy * wpr + i];
                    acc = if dilate { acc | v } else { acc & v };
                }
                self.words[y * wpr + i] = acc;
            }
        }
        self.set_padding(false);
    }

    /// Opening (radius `open`) then closing (radius `close`), in cells.
    pub fn open_close(&mut self, open: u32, close: u32) {
        let (o, c) = (open as usize, close as usize);
        self.morph(o, false);
        self.morph(o, true);
        self.morph(c, true);
        self.morph(c, false);
    }

    /// Unpack into one byte per cell (0 or 1).
    pub fn to_bytes(&self, out: &mut Vec<u8>) {
        out.clear();
        out.resize(self.gw * self.gh, 0);
        for y in 0..self.gh {
            for i in 0..self.wpr {
                let mut w = self.words[y * self.wpr + i];
                while w != 0 {
                    let j = w.trailing_zeros() as usize;
                    out[y * self.gw + i * 64 + j] = 1;
                    w &= w - 1;
                }
            }
        }
    }
}

/// Opening then closing of a byte mask (0/1), through [`BitMask`].
pub fn open_close(
    mask: &mut [u8],
    bits: &mut BitMask,
    gw: usize,
    gh: usize,
    open: u32,
    close: u32,
) {
    bits.reset(gw, gh);
    for (i, &m) in mask.iter().enumerate() {
        if m != 0 {
            bits.set(i % gw, i / gw);
        }
    }
    bits.open_close(open, close);
    let mut out = Vec::new();
    bits.to_bytes(&mut out);
    mask.copy_from_slice(&out);
}

/// Box mean of radius `r` cells over an RGB-interleaved `gw` x `gh` grid, in place (separable,
/// running sums; windows are cut at the border and divided by the cells they hold).
pub fn box_mean3(data: &mut [f32], gw: usize, gh: usize, r: usize, tmp: &mut Vec<f32>) {
    if r == 0 || gw == 0 || gh == 0 || data.len() < gw * gh * 3 {
        return;
    }
    tmp.clear();
    tmp.resize(gw * gh * 3, 0.0);
    // Rows into tmp.
    for (src, dst) in data.chunks_exact(gw * 3).zip(tmp.chunks_exact_mut(gw * 3)) {
        let mut acc = [0f32; 3];
        let mut n = 0f32;
        for x in 0..r.min(gw) {
            for c in 0..3 {
                acc[c] += src[x * 3 + c];
            }
            n += 1.0;
        }
        for x in 0..gw {
            if x + r < gw {
                for c in 0..3 {
                    acc[c] += src[(x + r) * 3 + c];
                }
                n += 1.0;
            }
            if x > r {
                for c in 0..3 {
                    acc[c] -= src[(x - r - 1) * 3 + c];
                }
                n -= 1.0;
            }
            for c in 0..3 {
                dst[x * 3 + c] = acc[c] / n;
            }
        }
    }
    // Columns back into data, a whole row of accumulators at a time.
    let w3 = gw * 3;
    let mut acc = vec![0f32; w3];
    let mut n = 0f32;
    for y in 0..r.min(gh) {
        for (a, v) in acc.iter_mut().zip(&tmp[y * w3..(y + 1) * w3]) {
            *a += v;
        }
        n += 1.0;
    }
    for y in 0..gh {
        if y + r < gh {
            let row = &tmp[(y + r) * w3..(y + r + 1) * w3];
            for (a, v) in acc.iter_mut().zip(row) {
                *a += v;
            }
            n += 1.0;
        }
        if y > r {
            let row = &tmp[(y - r - 1) * w3..(y - r) * w3];
            for (a, v) in acc.iter_mut().zip(row) {
                *a -= v;
            }
            n -= 1.0;
        }
        let inv = 1.0 / n;
        for (d, a) in data[y * w3..(y + 1) * w3].iter_mut().zip(&acc) {
            *d = a * inv;
        }
    }
}

/// Keep the 4-connected components of at least `min_cells` that are also at least
/// `share_of_largest` times the largest one (0 keeps every component over `min_cells`); returns
/// how many cells were kept. `labels` and `stack` are scratch buffers.
pub fn keep_components(
    mask: &mut [u8],
    gw: usize,
    gh: usize,
    min_cells: usize,
    share_of_largest: f32,
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
    let largest = sizes.iter().copied().max().unwrap_or(0);
    let min_cells = min_cells.max((share_of_largest * largest as f32).ceil() as usize);
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
        let mut bits = BitMask::default();
        open_close(&mut m, &mut bits, gw, gh, 1, 1);
        assert_eq!(m[gw + 11], 0, "speck removed");
        assert_eq!(m[4 * gw + 5], 1, "line filled");
    }

    /// The packed morphology against a plain per-cell reference, on random masks whose width
    /// crosses word boundaries.
    #[test]
    fn packed_morphology_matches_reference() {
        fn reference(m: &[u8], gw: usize, gh: usize, r: usize, dilate: bool) -> Vec<u8> {
            let outside = u8::from(!dilate);
            (0..gw * gh)
                .map(|i| {
                    let (x, y) = ((i % gw) as i64, (i / gw) as i64);
                    let mut v = u8::from(!dilate);
                    for dy in -(r as i64)..=r as i64 {
                        for dx in -(r as i64)..=r as i64 {
                            let (nx, ny) = (x + dx, y + dy);
                            let inside = nx >= 0 && ny >= 0 && nx < gw as i64 && ny < gh as i64;
                            let c = if inside {
                                m[ny as usize * gw + nx as usize]
                            } else {
                                outside
                            };
                            v = if dilate { v.max(c) } else { v.min(c) };
                        }
                    }
                    v
                })
                .collect()
        }
        let mut seed = 12345u64;
        for (gw, gh) in [(7, 5), (64, 3), (65, 4), (130, 6), (160, 9)] {
            let m: Vec<u8> = (0..gw * gh)
                .map(|_| {
                    seed = seed
                        .wrapping_mul(6364136223846793005)
                        .wrapping_add(1442695040888963407);
                    u8::from((seed >> 33) % 3 != 0)
                })
                .collect();
            for (r, dilate) in [(1, false), (1, true), (2, false), (3, true)] {
                let mut bits = BitMask::default();
                bits.reset(gw, gh);
                for (i, &v) in m.iter().enumerate() {
                    if v != 0 {
                        bits.set(i % gw, i / gw);
                    }
                }
                bits.morph(r, dilate);
                let mut got = Vec::new();
                bits.to_bytes(&mut got);
                assert_eq!(
                    got,
                    reference(&m, gw, gh, r, dilate),
                    "{gw}x{gh} r={r} dilate={dilate}"
                );
            }
        }
    }

    #[test]
    fn box_mean_matches_a_direct_mean() {
        let (gw, gh, r) = (9, 7, 2);
        let data: Vec<f32> = (0..gw * gh * 3).map(|i| ((i * 37) % 23) as f32).collect();
        let mut got = data.clone();
        box_mean3(&mut got, gw, gh, r, &mut Vec::new());
        for y in 0..gh {
            for x in 0..gw {
                for c in 0..3 {
                    let (mut s, mut n) = (0.0, 0.0);
                    for yy in y.saturating_sub(r)..(y + r + 1).min(gh) {
                        for xx in x.saturating_sub(r)..(x + r + 1).min(gw) {
                            s += data[(yy * gw + xx) * 3 + c];
                            n += 1.0;
                        }
                    }
                    let want: f32 = s / n;
                    let g = got[(y * gw + x) * 3 + c];
                    assert!((g - want).abs() < 1e-3, "({x}, {y}, {c}): {g} vs {want}");
                }
            }
        }
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
        let mut m2 = m.clone();
        assert_eq!(keep_components(&mut m, gw, gh, 2, 0.0, &mut l, &mut s), 4);
        assert_eq!(m[7], 0);
        // Relative to the largest (4 cells) at share 0.6: 3 cells stay, 2 go.
        m2[6] = 1;
        m2[5] = 1;
        assert_eq!(keep_components(&mut m2, gw, gh, 1, 0.6, &mut l, &mut s), 7);
        m2[5] = 0;
        assert_eq!(keep_components(&mut m2, gw, gh, 1, 0.6, &mut l, &mut s), 4);
    }
}
