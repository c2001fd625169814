//! The detection grid: block means of the frame, and binary-mask morphology on it.

use unitac_core::Frame;

/// Largest stride: a cell's channel sum (at most 255 x stride^2) stays below 2^31, so that it
/// converts to f32 as an i32 (a vector instruction; u32 has none before AVX-512).
const MAX_STRIDE: u32 = 1024;

/// The 4-neighbours of cell `i` of a `w` x `h` grid that lie inside it, in the order left,
/// right, up, down (the flood fills of the depth calibration and the depth contact region).
pub(crate) fn neighbours4(i: usize, w: usize, h: usize) -> impl Iterator<Item = usize> {
    let (x, y) = (i % w, i / w);
    [
        (x > 0).then(|| i - 1),
        (x + 1 < w).then(|| i + 1),
        (y > 0).then(|| i - w),
        (y + 1 < h).then(|| i + w),
    ]
    .into_iter()
    .flatten()
}

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
        let s = stride.min(width).min(height).clamp(1, MAX_STRIDE);
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

/// Scratch of [`block_means`]: one cell row's pixel rows summed per column, then per cell.
#[derive(Debug, Default, Clone)]
pub struct BlockScratch {
    rows: Vec<u16>,
    sums: Vec<u32>,
}

/// Pixel rows summed in u16 before they are flushed into the cell sums (255 x 257 fits).
const ROWS_PER_BATCH: usize = 257;

/// Block means, RGB interleaved, into `out` (resized as needed). One pass over the frame: the
/// pixel rows of a cell row are added column by column in u16 (a loop the compiler vectorises),
/// then each cell's columns are added, and each cell is converted once. Integer sums, so the
/// result does not depend on the order.
#[multiversion::multiversion(targets("x86_64+avx2"))]
pub fn block_means(f: &Frame, g: &Geometry, out: &mut Vec<f32>, s: &mut BlockScratch) {
    let st = g.stride as usize;
    let w3 = f.width as usize * 3;
    let used = g.gw * st * 3;
    // Every cell is written below.
    out.resize(g.cells() * 3, 0.0);
    s.rows.resize(used, 0);
    s.sums.resize(g.gw * 3, 0);
    let data = f.data();
    let inv = 1.0 / (st * st) as f32;
    for (gy, dst) in out.chunks_exact_mut(g.gw * 3).enumerate().take(g.gh) {
        let first = gy * st;
        let mut dy = 0;
        while dy < st {
            let n = (st - dy).min(ROWS_PER_BATCH);
            // The batch's first row is copied in (no zero fill), the others added.
            for (k, y) in (first + dy..first + dy + n).enumerate() {
                match data.get(y * w3..y * w3 + used) {
                    Some(row) if k == 0 => {
                        for (a, &b) in s.rows.iter_mut().zip(row) {
                            *a = u16::from(b);
                        }
                    }
                    Some(row) => {
                        for (a, &b) in s.rows.iter_mut().zip(row) {
                            *a += u16::from(b);
                        }
                    }
                    None if k == 0 => s.rows.fill(0),
                    None => {}
                }
            }
            // The first batch sets the cell sums, later ones add to them.
            let set = dy == 0;
            match st {
                1 => add_cells::<1>(&s.rows, &mut s.sums, set),
                2 => add_cells::<2>(&s.rows, &mut s.sums, set),
                3 => add_cells::<3>(&s.rows, &mut s.sums, set),
                4 => add_cells::<4>(&s.rows, &mut s.sums, set),
                8 => add_cells::<8>(&s.rows, &mut s.sums, set),
                _ => add_cells_n(&s.rows, &mut s.sums, st, set),
            }
            dy += n;
        }
        // The same value either way; through i32 the loop vectorises (see MAX_STRIDE).
        for (o, &v) in dst.iter_mut().zip(&s.sums) {
            *o = v as i32 as f32 * inv;
        }
    }
}

/// Add each cell's `S` columns (RGB) of the summed rows into its sums (`set`: store them).
#[inline]
fn add_cells<const S: usize>(rows: &[u16], sums: &mut [u32], set: bool) {
    for (cell, px) in sums.chunks_exact_mut(3).zip(rows.chunks_exact(3 * S)) {
        let mut a = [0u32; 3];
        for p in px.chunks_exact(3) {
            a[0] += u32::from(p[0]);
            a[1] += u32::from(p[1]);
            a[2] += u32::from(p[2]);
        }
        if set {
            cell.copy_from_slice(&a);
        } else {
            cell[0] += a[0];
            cell[1] += a[1];
            cell[2] += a[2];
        }
    }
}

/// [`add_cells`] for a stride known only at run time.
#[inline]
fn add_cells_n(rows: &[u16], sums: &mut [u32], st: usize, set: bool) {
    for (cell, px) in sums.chunks_exact_mut(3).zip(rows.chunks_exact(3 * st)) {
        if set {
            cell.fill(0);
        }
        for p in px.chunks_exact(3) {
            cell[0] += u32::from(p[0]);
            cell[1] += u32::from(p[1]);
            cell[2] += u32::from(p[2]);
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
    /// Set row `y` from one byte per cell, each 0 or 1 (`bytes.len()` = the row's width): eight
    /// cells per multiply, which gathers the low bits of eight bytes into one byte.
    pub fn set_row(&mut self, y: usize, bytes: &[u8]) {
        const GATHER: u64 = 0x0102_0408_1020_4080;
        let row = &mut self.words[y * self.wpr..(y + 1) * self.wpr];
        for (word, cells) in row.iter_mut().zip(bytes.chunks(64)) {
            let mut acc = 0u64;
            for (k, eight) in cells.chunks(8).enumerate() {
                let mut le = [0u8; 8];
                le[..eight.len()].copy_from_slice(eight);
                acc |= (u64::from_le_bytes(le).wrapping_mul(GATHER) >> 56) << (8 * k);
            }
            *word = acc;
        }
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
        self.set_ones(out);
    }

    /// Write 1 into `out` (one byte per cell, `gw` x `gh`) at every set cell; the other bytes are
    /// left as they are.
    pub fn set_ones(&self, out: &mut [u8]) {
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
    stack: &mut Vec<(usize, usize)>,
) -> usize {
    let sizes = label_components(mask, gw, gh, labels, stack);
    let largest = sizes.iter().copied().max().unwrap_or(0);
    let min_cells = min_cells.max((share_of_largest * largest as f32).ceil() as usize);
    let kept = sizes.iter().skip(1).filter(|&&n| n >= min_cells).sum();
    // Only when a component is dropped is the mask walked (past the empty cells, eight at a
    // time).
    if sizes.iter().skip(1).any(|&n| n < min_cells) {
        for (m, l) in mask.chunks_mut(8).zip(labels.chunks(8)) {
            if m.iter().fold(0u8, |a, &v| a | v) == 0 {
                continue;
            }
            for (m, &l) in m.iter_mut().zip(l) {
                if *m != 0 && sizes[l as usize] < min_cells {
                    *m = 0;
                }
            }
        }
    }
    kept
}

/// Label the 4-connected components of `mask` (gw x gh, non-zero = set) into `labels` (0 for
/// unset cells, 1.. per component); returns each label's size in cells (index 0: none).
/// `stack` is a scratch buffer.
pub fn label_components(
    mask: &[u8],
    gw: usize,
    gh: usize,
    labels: &mut Vec<u32>,
    stack: &mut Vec<(usize, usize)>,
) -> Vec<usize> {
    labels.clear();
    labels.resize(mask.len(), 0);
    let mut sizes: Vec<usize> = vec![0];
    // Eight cells at a time past the empty ones (most of the grid).
    let starts = mask.chunks(8).enumerate().flat_map(|(k, eight)| {
        let empty = eight.iter().fold(0u8, |a, &m| a | m) == 0;
        let n = if empty { 0 } else { eight.len() };
        (k * 8..k * 8 + n).filter(|&i| mask[i] != 0)
    });
    for start in starts {
        if labels[start] != 0 {
            continue;
        }
        let id = sizes.len() as u32;
        let mut n = 0;
        // A scanline flood: each popped seed labels its whole run of the row, and pushes one
        // seed per unlabelled run of the rows above and below that touches it (4-connected).
        stack.clear();
        stack.push((start % gw, start / gw));
        while let Some((x, y)) = stack.pop() {
            let row = y * gw;
            if labels[row + x] != 0 {
                continue;
            }
            let free = |i: usize, labels: &[u32]| mask[i] != 0 && labels[i] == 0;
            let (mut l, mut r) = (x, x);
            while l > 0 && free(row + l - 1, labels) {
                l -= 1;
            }
            while r + 1 < gw && free(row + r + 1, labels) {
                r += 1;
            }
            labels[row + l..=row + r].fill(id);
            n += r - l + 1;
            for ny in [y.wrapping_sub(1), y + 1] {
                if ny >= gh {
                    continue;
                }
                let nrow = ny * gw;
                let mut i = l;
                while i <= r {
                    if free(nrow + i, labels) {
                        stack.push((i, ny));
                        while i <= r && free(nrow + i, labels) {
                            i += 1;
                        }
                    } else {
                        i += 1;
                    }
                }
            }
        }
        sizes.push(n);
    }
    sizes
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
        block_means(&f, &g, &mut out, &mut BlockScratch::default());
        assert_eq!(out, vec![25.0, 25.0, 230.0, 45.0, 45.0, 210.0]);
        // Tiny images shrink the stride instead of producing an empty grid.
        let g1 = Geometry::new(1, 1, 4);
        assert_eq!((g1.stride, g1.cells()), (1, 1));
    }

    /// Block means against a direct per-cell mean, for strides with a specialised loop, one
    /// without, and one over the u16 batch of rows; widths with a remainder.
    #[test]
    fn block_means_match_a_direct_mean() {
        let mut seed = 99u64;
        for (w, h, st) in [
            (13, 7, 1),
            (21, 10, 2),
            (19, 11, 3),
            (42, 17, 4),
            (37, 29, 5),
            (300, 280, 270),
        ] {
            let d: Vec<u8> = (0..w * h * 3)
                .map(|_| {
                    seed = seed
                        .wrapping_mul(6364136223846793005)
                        .wrapping_add(1442695040888963407);
                    (seed >> 56) as u8
                })
                .collect();
            let f = Frame::new("t", 0, Stamp::ZERO, w as u32, h as u32, d.clone()).unwrap();
            let g = Geometry::new(w as u32, h as u32, st as u32);
            let mut out = Vec::new();
            block_means(&f, &g, &mut out, &mut BlockScratch::default());
            assert_eq!(out.len(), g.cells() * 3);
            for cy in 0..g.gh {
                for cx in 0..g.gw {
                    for c in 0..3 {
                        let mut sum = 0u32;
                        for y in cy * st..(cy + 1) * st {
                            for x in cx * st..(cx + 1) * st {
                                sum += u32::from(d[(y * w + x) * 3 + c]);
                            }
                        }
                        let want = sum as f32 * (1.0 / (st * st) as f32);
                        assert_eq!(
                            out[(cy * g.gw + cx) * 3 + c],
                            want,
                            "{w}x{h}/{st} ({cx}, {cy}, {c})"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn set_row_packs_bytes_like_set() {
        let mut seed = 5u64;
        for gw in [1, 7, 8, 63, 64, 65, 130] {
            let gh = 3;
            let m: Vec<u8> = (0..gw * gh)
                .map(|_| {
                    seed = seed
                        .wrapping_mul(6364136223846793005)
                        .wrapping_add(1442695040888963407);
                    u8::from((seed >> 33) % 3 == 0)
                })
                .collect();
            let (mut a, mut b) = (BitMask::default(), BitMask::default());
            a.reset(gw, gh);
            b.reset(gw, gh);
            for (i, &v) in m.iter().enumerate() {
                if v != 0 {
                    a.set(i % gw, i / gw);
                }
            }
            for (y, row) in m.chunks_exact(gw).enumerate() {
                b.set_row(y, row);
            }
            assert_eq!(a.words, b.words, "gw {gw}");
        }
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

    /// The labels of a plain per-cell flood (4-connected, ids in raster order of each
    /// component's first cell) and each component's size.
    fn labels_by_cell_flood(mask: &[u8], gw: usize, gh: usize) -> (Vec<u32>, Vec<usize>) {
        let mut labels = vec![0u32; mask.len()];
        let mut sizes = vec![0usize];
        for start in 0..mask.len() {
            if mask[start] == 0 || labels[start] != 0 {
                continue;
            }
            let id = sizes.len() as u32;
            let (mut stack, mut n) = (vec![start], 0);
            labels[start] = id;
            while let Some(i) = stack.pop() {
                n += 1;
                let (x, y) = (i % gw, i / gw);
                let mut near = Vec::new();
                if x > 0 {
                    near.push(i - 1);
                }
                if x + 1 < gw {
                    near.push(i + 1);
                }
                if y > 0 {
                    near.push(i - gw);
                }
                if y + 1 < gh {
                    near.push(i + gw);
                }
                for j in near {
                    if mask[j] != 0 && labels[j] == 0 {
                        labels[j] = id;
                        stack.push(j);
                    }
                }
            }
            sizes.push(n);
        }
        (labels, sizes)
    }

    /// The scanline flood labels every cell as a per-cell flood does, on random masks of every
    /// density (spirals, combs and single cells among them), and keeps the same cells.
    #[test]
    fn scanline_components_match_a_cell_flood() {
        let mut seed = 11u64;
        let mut next = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 33) as u32
        };
        for case in 0..300 {
            let (gw, gh) = (1 + next() as usize % 40, 1 + next() as usize % 30);
            let density = next() % 100;
            let mask: Vec<u8> = (0..gw * gh)
                .map(|_| u8::from(next() % 100 < density))
                .collect();
            let (want, sizes) = labels_by_cell_flood(&mask, gw, gh);
            let (mut m, mut l, mut st) = (mask.clone(), Vec::new(), Vec::new());
            let min_cells = 1 + case % 5;
            let kept = keep_components(&mut m, gw, gh, min_cells, 0.0, &mut l, &mut st);
            assert_eq!(l, want, "case {case}: {gw}x{gh} at {density} %");
            let want_kept: usize = sizes.iter().skip(1).filter(|&&n| n >= min_cells).sum();
            assert_eq!(kept, want_kept, "case {case}");
            for (i, (&a, &b)) in m.iter().zip(&mask).enumerate() {
                let keep = b != 0 && sizes[want[i] as usize] >= min_cells;
                assert_eq!(a != 0, keep, "case {case}, cell {i}");
            }
        }
    }
}
