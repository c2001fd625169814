//! What the depth model sees of a frame: its difference to the background, smoothed over 3 x 3
//! pixels, less the smooth shading across the gel.
//!
//! The shading is a quadratic surface per channel (6 terms) fitted on a lattice of every 8th
//! pixel by least squares with hard rejection (three passes; a lattice cell further than 3
//! robust sigmas of the fit, or 3 DN, from it leaves the next pass, and so do the cells around
//! it: `dilate_rejected`): LED drift, exposure and gel stretch change a whole gel smoothly and
//! would integrate into a bowl of height; a press is compact and is rejected from the fit. Not a
//! quartic as the contact detector's (`crate::shading`): with the cells around a press left out,
//! a quartic swings up in the gap near the frame's border, and one press of 40 was found 12 px
//! off its centre; the quadratic left a penetration error of 0.03 mm at 0.9 mm with 20 DN of
//! shading on mock presses. The fit reads the 3 x 3 mean at the lattice's cells alone
//! (`box3_at`), so it comes before any pass over the whole frame; the frame's rows then come one
//! at a time (`box3_rows`) to the caller, who takes the shading off: estimation applies the model
//! to each row as it comes (no difference image), calibration keeps the rows in [`Prep::diff`].
//! Both run the same sums in the same order, so the model learns the colours it is later shown.

use nalgebra::{SMatrix, SVector};

const TERMS: usize = 6;
const LATTICE: usize = 8;
/// Fits per channel: the first on the whole lattice, each later one without the cells the one
/// before rejected.
const PASSES: usize = 3;

/// Scratch and result of [`Prep::run`]: the prepared difference, RGB interleaved \[DN].
#[derive(Debug, Default, Clone)]
pub struct Prep {
    pub diff: Vec<f32>,
    rows: Vec<f32>,
    lattice: Lattice,
}

/// The shading fit's lattice for one frame size, built once per size: each cell's pixel (x, y)
/// and its terms, and the normal matrix of the whole lattice (a fit takes out the rows of the
/// cells it leaves out); per frame, the box mean of the difference at each cell.
#[derive(Debug, Default, Clone)]
struct Lattice {
    size: (usize, usize),
    cells: Vec<((usize, usize), [f32; TERMS])>,
    /// The prepared difference (before the shading) at each cell, per channel.
    samples: Vec<[f32; 3]>,
    ata: SMatrix<f64, TERMS, TERMS>,
    /// Per-iteration scratch: which cells the fit keeps, their residuals and the |residual|s.
    keep: Vec<bool>,
    res: Vec<f32>,
    abs: Vec<f32>,
    /// `dilate_rejected`'s distances.
    dist: Vec<f32>,
}

fn outer(t: &[f32; TERMS]) -> SMatrix<f64, TERMS, TERMS> {
    let tv = SVector::<f64, TERMS>::from_iterator(t.iter().map(|&v| f64::from(v)));
    tv * tv.transpose()
}

impl Lattice {
    fn for_size(&mut self, w: usize, h: usize) {
        if self.size == (w, h) && !self.cells.is_empty() {
            return;
        }
        let inv = 1.0 / w.max(h) as f32;
        let (cx, cy) = (w as f32 * 0.5, h as f32 * 0.5);
        self.cells.clear();
        for y in (LATTICE / 2..h).step_by(LATTICE) {
            for x in (LATTICE / 2..w).step_by(LATTICE) {
                self.cells
                    .push(((x, y), terms((x as f32 - cx) * inv, (y as f32 - cy) * inv)));
            }
        }
        self.ata = self
            .cells
            .iter()
            .fold(SMatrix::zeros(), |a, (_, t)| a + outer(t));
        self.size = (w, h);
    }

    /// The box mean of `frame - background` at each cell (`box3_at`; none if the images are
    /// short of `w * h * 3` bytes).
    fn sample(&mut self, frame: &[u8], background: &[u8], w: usize, h: usize) {
        self.samples.clear();
        if frame.len() < w * h * 3 || background.len() < w * h * 3 {
            return;
        }
        self.samples.extend(
            self.cells
                .iter()
                .map(|((x, y), _)| box3_at(frame, background, w, h, *x, *y)),
        );
    }
}

fn terms(u: f32, v: f32) -> [f32; TERMS] {
    let (u2, v2) = (u * u, v * v);
    [1.0, u, v, u2, u * v, v2]
}

impl Prep {
    /// Prepare `frame` against `background` (RGB8, `w` x `h`, both of `w * h * 3` bytes; the
    /// caller checks the sizes) into `diff`.
    pub fn run(&mut self, frame: &[u8], background: &[u8], w: usize, h: usize) {
        let field = self.shading(frame, background, w, h);
        self.diff.resize(w * h * 3, 0.0);
        box3_interleaved(frame, background, &mut self.rows, &mut self.diff, w, h);
        field.subtract(&mut self.diff, w, h);
    }

    /// The shading of `frame` against `background`, fitted on the lattice alone: the box mean
    /// is taken at the lattice's cells only, so a caller that prepares the rest itself, row by
    /// row (`box3_rows` and [`Shading::row`]), needs no difference image.
    pub fn shading(&mut self, frame: &[u8], background: &[u8], w: usize, h: usize) -> Shading {
        self.lattice.for_size(w, h);
        self.lattice.sample(frame, background, w, h);
        fit_shading(w, h, &mut self.lattice)
    }

    /// Scratch rows for `box3_rows`.
    pub(super) fn rows(&mut self) -> &mut Vec<f32> {
        &mut self.rows
    }
}

/// The fitted shading: a quadratic per channel in (x - w/2, y - h/2) / max(w, h).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Shading {
    fields: [[f32; TERMS]; 3],
    inv: f32,
    cx: f32,
    cy: f32,
}

impl Shading {
    /// Row `y`'s shading per channel as `a + b s + c s^2`, s = (x - w/2) / max(w, h).
    pub fn row(&self, y: usize) -> [[f32; 3]; 3] {
        let v = (y as f32 - self.cy) * self.inv;
        let mut out = [[0f32; 3]; 3];
        for (o, f) in out.iter_mut().zip(&self.fields) {
            *o = [f[0] + f[2] * v + f[5] * v * v, f[1] + f[4] * v, f[3]];
        }
        out
    }

    /// (x - w/2) / max(w, h) of column x.
    pub fn s(&self, x: usize) -> f32 {
        (x as f32 - self.cx) * self.inv
    }

    fn subtract(&self, diff: &mut [f32], w: usize, h: usize) {
        if self.fields == [[0.0; TERMS]; 3] {
            return;
        }
        for y in 0..h {
            let r = self.row(y);
            for (x, px) in diff[y * w * 3..(y + 1) * w * 3]
                .chunks_exact_mut(3)
                .enumerate()
            {
                let s = self.s(x);
                for (d, k) in px.iter_mut().zip(&r) {
                    *d -= k[0] + k[1] * s + k[2] * s * s;
                }
            }
        }
    }
}

/// Where `box3_rows` sends each output row. Implementations mark `row` `#[inline(always)]`, so
/// that it is built with the target features of the function that runs `box3_rows` (a closure
/// would be built once, for baseline x86-64).
pub(super) trait RowSink {
    /// Row `y` as planes `[R | G | B]` of `w` each.
    fn row(&mut self, y: usize, planes: &[f32]);
}

/// `box3` of `frame - background` (u8), one output row at a time: each input row's difference
/// goes into planar scratch (R, G, B planes of `w`), its horizontal mean into a ring of three
/// rows, and each output row, one input row behind, to the sink as planes `[R | G | B]` (no
/// difference image). The same sums in the same order as `box3`, so the same bytes. Nothing is
/// sent for images short of `w * h * 3` bytes. Inlined into its callers, which are built for
/// baseline x86-64 and for AVX2.
#[inline(always)]
pub(super) fn box3_rows(
    frame: &[u8],
    background: &[u8],
    rows: &mut Vec<f32>,
    w: usize,
    h: usize,
    sink: &mut impl RowSink,
) {
    let stride = w * 3;
    if w == 0 || frame.len() < h * stride || background.len() < h * stride {
        return;
    }
    rows.resize(5 * stride, 0.0);
    let (diff, rest) = rows.split_at_mut(stride);
    let (ring, out) = rest.split_at_mut(3 * stride);
    // A frame of one row or column has no neighbours to average: its difference as it is.
    let single = w < 2 || h < 2;
    const THIRD: f32 = 1.0 / 3.0;
    for (y, (fr, bg)) in frame
        .chunks_exact(stride)
        .zip(background.chunks_exact(stride))
        .enumerate()
        .take(h)
    {
        if single {
            planar_diff(fr, bg, out, w);
            sink.row(y, out);
            continue;
        }
        planar_diff(fr, bg, diff, w);
        let slot = y % 3;
        let hrow = &mut ring[slot * stride..(slot + 1) * stride];
        for (d, o) in diff.chunks_exact(w).zip(hrow.chunks_exact_mut(w)) {
            horizontal3(d, o, THIRD);
        }
        if y == 0 {
            continue;
        }
        let at = |k: usize| &ring[(k % 3) * stride..(k % 3 + 1) * stride];
        let (cur, next) = (at(y - 1), at(y));
        if y == 1 {
            for ((o, c), n) in out.iter_mut().zip(cur).zip(next) {
                *o = (c + n) * 0.5;
            }
        } else {
            let prev = at(y - 2);
            for (((o, c), p), n) in out.iter_mut().zip(cur).zip(prev).zip(next) {
                *o = (c + p + n) * THIRD;
            }
        }
        sink.row(y - 1, out);
    }
    if single {
        return;
    }
    let (cur, prev) = (
        &ring[((h - 1) % 3) * stride..((h - 1) % 3 + 1) * stride],
        &ring[((h - 2) % 3) * stride..((h - 2) % 3 + 1) * stride],
    );
    for ((o, c), p) in out.iter_mut().zip(cur).zip(prev) {
        *o = (c + p) * 0.5;
    }
    sink.row(h - 1, out);
}

/// `frame - background` of one RGB row into planes `[R | G | B]` of `w` each.
#[inline(always)]
fn planar_diff(fr: &[u8], bg: &[u8], out: &mut [f32], w: usize) {
    let (r, gb) = out.split_at_mut(w);
    let (g, b) = gb.split_at_mut(w);
    for ((((f, k), r), g), b) in fr
        .chunks_exact(3)
        .zip(bg.chunks_exact(3))
        .zip(r.iter_mut())
        .zip(g.iter_mut())
        .zip(b.iter_mut())
    {
        *r = f32::from(f[0]) - f32::from(k[0]);
        *g = f32::from(f[1]) - f32::from(k[1]);
        *b = f32::from(f[2]) - f32::from(k[2]);
    }
}

/// `box3_rows` into an interleaved image `dst` (RGB, `w * h * 3`), built for baseline x86-64
/// and for AVX2.
#[multiversion::multiversion(targets("x86_64+avx2"))]
fn box3_interleaved(
    frame: &[u8],
    background: &[u8],
    rows: &mut Vec<f32>,
    dst: &mut [f32],
    w: usize,
    h: usize,
) {
    box3_rows(frame, background, rows, w, h, &mut Interleave { dst, w });
}

/// Rows into an interleaved image.
struct Interleave<'a> {
    dst: &'a mut [f32],
    w: usize,
}

impl RowSink for Interleave<'_> {
    #[inline(always)]
    fn row(&mut self, y: usize, planes: &[f32]) {
        let w = self.w;
        let Some(out) = self.dst.get_mut(y * w * 3..(y + 1) * w * 3) else {
            return;
        };
        let (r, gb) = planes.split_at(w);
        let (g, b) = gb.split_at(w);
        for (((px, r), g), b) in out.chunks_exact_mut(3).zip(r).zip(g).zip(b) {
            px[0] = *r;
            px[1] = *g;
            px[2] = *b;
        }
    }
}

/// `box3` of `frame - background` at pixel (x, y) alone, per channel: the same sums in the
/// same order as `box3_rows`, so the same bytes.
fn box3_at(frame: &[u8], background: &[u8], w: usize, h: usize, x: usize, y: usize) -> [f32; 3] {
    const THIRD: f32 = 1.0 / 3.0;
    // Inside the frame (every lattice cell): three pixels of three rows, read as slices.
    if (1..w.saturating_sub(1)).contains(&x) && (1..h.saturating_sub(1)).contains(&y) {
        let across = |yy: usize| -> Option<[f32; 3]> {
            let i = (yy * w + x - 1) * 3;
            let (f, b) = (frame.get(i..i + 9)?, background.get(i..i + 9)?);
            let d = |k: usize| f32::from(f[k]) - f32::from(b[k]);
            Some([0, 1, 2].map(|c| (d(c) + d(3 + c) + d(6 + c)) * THIRD))
        };
        if let (Some(p), Some(q), Some(r)) = (across(y), across(y - 1), across(y + 1)) {
            return [0, 1, 2].map(|c| (p[c] + q[c] + r[c]) * THIRD);
        }
    }
    let d = |xx: usize, yy: usize| -> [f32; 3] {
        let i = (yy * w + xx) * 3;
        match (frame.get(i..i + 3), background.get(i..i + 3)) {
            (Some(f), Some(b)) => [0, 1, 2].map(|c| f32::from(f[c]) - f32::from(b[c])),
            _ => [0.0; 3],
        }
    };
    if w < 2 || h < 2 {
        return d(x, y);
    }
    // The horizontal mean of row yy at x, per channel.
    let across = |yy: usize| -> [f32; 3] {
        let (a, b, c, third) = if x == 0 {
            (d(0, yy), d(1, yy), None, 0.5)
        } else if x + 1 == w {
            (d(w - 2, yy), d(w - 1, yy), None, 0.5)
        } else {
            (d(x - 1, yy), d(x, yy), Some(d(x + 1, yy)), THIRD)
        };
        [0, 1, 2].map(|k| match c {
            Some(c) => (a[k] + b[k] + c[k]) * third,
            None => (a[k] + b[k]) * third,
        })
    };
    let (p, q, r, third) = if y == 0 {
        (across(0), across(1), None, 0.5)
    } else if y + 1 == h {
        (across(h - 1), across(h - 2), None, 0.5)
    } else {
        (across(y), across(y - 1), Some(across(y + 1)), THIRD)
    };
    [0, 1, 2].map(|k| match r {
        Some(r) => (p[k] + q[k] + r[k]) * third,
        None => (p[k] + q[k]) * third,
    })
}

/// One plane row's horizontal three-tap mean (two taps at the ends).
#[inline(always)]
fn horizontal3(row: &[f32], out: &mut [f32], third: f32) {
    let w = row.len().min(out.len());
    if w < 2 {
        out[..w].copy_from_slice(&row[..w]);
        return;
    }
    out[0] = (row[0] + row[1]) * 0.5;
    out[w - 1] = (row[w - 2] + row[w - 1]) * 0.5;
    let n = w - 2;
    let (l, m, r) = (&row[..n], &row[1..1 + n], &row[2..2 + n]);
    for (((o, a), b), c) in out[1..1 + n].iter_mut().zip(l).zip(m).zip(r) {
        *o = (a + b + c) * third;
    }
}

/// The vertical three-tap mean of `dst` in place (two taps at the first and last rows).
#[cfg(test)]
fn vertical3(dst: &mut [f32], w: usize, h: usize, third: f32) {
    let stride = w * 3;
    let mut prev = dst[..stride].to_vec();
    let mut cur = vec![0f32; stride];
    for y in 0..h {
        cur.copy_from_slice(&dst[y * stride..(y + 1) * stride]);
        if y == 0 {
            let (head, tail) = dst.split_at_mut(stride);
            for (o, n) in head.iter_mut().zip(&tail[..stride]) {
                *o = (*o + n) * 0.5;
            }
        } else if y + 1 == h {
            for (o, p) in dst[y * stride..].iter_mut().zip(&prev) {
                *o = (*o + p) * 0.5;
            }
        } else {
            let (head, tail) = dst.split_at_mut((y + 1) * stride);
            let out = &mut head[y * stride..];
            for ((o, p), n) in out.iter_mut().zip(&prev).zip(&tail[..stride]) {
                *o = (*o + p + n) * third;
            }
        }
        std::mem::swap(&mut prev, &mut cur);
    }
}

/// 3 x 3 box mean per channel of an interleaved image (the border averages what is inside the
/// frame) in two whole-image passes, horizontal then vertical: the reference `box3_rows` and
/// `box3_at` are held to.
#[cfg(test)]
fn box3(src: &[f32], dst: &mut [f32], w: usize, h: usize) {
    let stride = w * 3;
    if w < 2 || h < 2 {
        dst.copy_from_slice(src);
        return;
    }
    const THIRD: f32 = 1.0 / 3.0;
    let (mut plane, mut across) = (vec![0f32; w], vec![0f32; w]);
    for (row, out) in src.chunks_exact(stride).zip(dst.chunks_exact_mut(stride)) {
        for c in 0..3 {
            for (p, px) in plane.iter_mut().zip(row.chunks_exact(3)) {
                *p = px[c];
            }
            horizontal3(&plane, &mut across, THIRD);
            for (a, px) in across.iter().zip(out.chunks_exact_mut(3)) {
                px[c] = *a;
            }
        }
    }
    vertical3(dst, w, h, THIRD);
}

/// Fit the smooth shading per channel (module docs). The normal equations of each pass are the
/// whole lattice's less the rows of the cells left out (few: a press and the cells around it).
fn fit_shading(w: usize, h: usize, lat: &mut Lattice) -> Shading {
    let inv = 1.0 / w.max(h) as f32;
    let (cx, cy) = (w as f32 * 0.5, h as f32 * 0.5);
    let mut out = Shading {
        fields: [[0.0; TERMS]; 3],
        inv,
        cx,
        cy,
    };
    let Lattice {
        cells,
        samples,
        ata: ata_all,
        keep,
        res,
        abs,
        dist,
        ..
    } = lat;
    if cells.len() < 3 * TERMS || samples.len() != cells.len() {
        return out;
    }
    let mut fields = [[0f32; TERMS]; 3];
    let mut any = false;
    for (c, field) in fields.iter_mut().enumerate() {
        let atb_all = cells.iter().zip(samples.iter()).fold(
            SVector::<f64, TERMS>::zeros(),
            |a, ((_, t), d)| {
                a + SVector::<f64, TERMS>::from_iterator(t.iter().map(|&v| f64::from(v)))
                    * f64::from(d[c])
            },
        );
        keep.clear();
        keep.resize(cells.len(), true);
        let mut coef: Option<SVector<f64, TERMS>> = None;
        for pass in 0..PASSES {
            let (mut ata, mut atb) = (*ata_all, atb_all);
            let mut used = cells.len();
            for (((_, t), d), _) in cells
                .iter()
                .zip(samples.iter())
                .zip(keep.iter())
                .filter(|(_, k)| !**k)
            {
                let tv = SVector::<f64, TERMS>::from_iterator(t.iter().map(|&v| f64::from(v)));
                ata -= tv * tv.transpose();
                atb -= tv * f64::from(d[c]);
                used -= 1;
            }
            if used < 2 * TERMS {
                break;
            }
            let Some(ch) = ata.cholesky() else { break };
            let k = ch.solve(&atb);
            coef = Some(k);
            if pass + 1 == PASSES {
                break;
            }
            res.clear();
            res.extend(
                cells
                    .iter()
                    .zip(samples.iter())
                    .map(|((_, t), d)| d[c] - dot(t, &k)),
            );
            abs.clear();
            abs.extend(
                res.iter()
                    .zip(keep.iter())
                    .filter(|(_, k)| **k)
                    .map(|(r, _)| r.abs()),
            );
            let mid = abs.len() / 2;
            let med = if abs.is_empty() {
                0.0
            } else {
                *abs.select_nth_unstable_by(mid, f32::total_cmp).1
            };
            let limit = (3.0 * 1.4826 * med).max(3.0);
            for (k, r) in keep.iter_mut().zip(res.iter()) {
                *k = r.abs() <= limit;
            }
            dilate_rejected(keep, w, dist);
        }
        if let Some(k) = coef {
            for (f, v) in field.iter_mut().zip(k.iter()) {
                *f = *v as f32;
            }
            any = true;
        }
    }
    if any {
        out.fields = fields;
    }
    out
}

/// Also leave out the lattice cells near rejected ones, out to twice the rejected area's
/// equivalent radius (at least two lattice steps): the gel's skirt around a press is broad and
/// faint, under the rejection threshold, and a fit that keeps it takes part of the press's depth
/// for shading (17 % of the penetration on mock ball presses without this).
/// The distance to the nearest rejected cell comes from a two-pass chamfer transform on the
/// lattice (steps 1 and sqrt 2: within 8 % of Euclidean), linear in the lattice's size.
fn dilate_rejected(keep: &mut [bool], w: usize, dist: &mut Vec<f32>) {
    let nx = (w.saturating_sub(LATTICE / 2)).div_ceil(LATTICE).max(1);
    if nx * (keep.len() / nx) != keep.len() {
        return;
    }
    let Some(reach) = dilation_reach(keep) else {
        return;
    };
    chamfer_distances(keep, nx, dist);
    keep_beyond(keep, dist, reach);
}

/// How far around the rejected cells the dilation reaches \[lattice steps]: twice their
/// equivalent radius, at least 2; none when nothing or more than half the lattice is rejected.
fn dilation_reach(keep: &[bool]) -> Option<f32> {
    let rejected = keep.iter().filter(|k| !**k).count();
    (rejected > 0 && rejected * 2 <= keep.len())
        .then(|| (2.0 * (rejected as f32 / std::f32::consts::PI).sqrt()).max(2.0))
}

/// Keep only the cells further than `reach` from every rejected cell, unless that would keep
/// less than half the lattice for the fit.
fn keep_beyond(keep: &mut [bool], dist: &[f32], reach: f32) {
    if dist.iter().filter(|d| **d > reach).count() * 2 >= keep.len() {
        for (k, d) in keep.iter_mut().zip(dist) {
            *k = *d > reach;
        }
    }
}

/// Chamfer distance (steps 1 and sqrt 2) of every cell of an `nx`-wide lattice to the nearest
/// cell `keep` leaves out, into `dist`. Forward (top-left to bottom-right), then backward: each
/// pass takes a row's candidates from the row before it in one loop over the row (no dependence
/// between cells: it vectorises), then runs along the row for the one candidate that depends on
/// the cell just done. The same candidates as cell by cell, so the same distances.
fn chamfer_distances(keep: &[bool], nx: usize, dist: &mut Vec<f32>) {
    let ny = keep.len() / nx.max(1);
    dist.clear();
    dist.extend(keep.iter().map(|k| if *k { f32::MAX } else { 0.0 }));
    for j in 0..ny {
        let (done, rest) = dist.split_at_mut(j * nx);
        let row = &mut rest[..nx];
        if j > 0 {
            chamfer_from_row(row, &done[(j - 1) * nx..]);
        }
        for i in 1..nx {
            row[i] = lo(row[i], row[i - 1] + 1.0);
        }
    }
    for j in (0..ny).rev() {
        let (head, next) = dist.split_at_mut((j + 1) * nx);
        let row = &mut head[j * nx..];
        if j + 1 < ny {
            chamfer_from_row(row, &next[..nx]);
        }
        for i in (0..nx - 1).rev() {
            row[i] = lo(row[i], row[i + 1] + 1.0);
        }
    }
}

/// The smaller of two distances (neither is NaN).
#[inline(always)]
fn lo(a: f32, b: f32) -> f32 {
    if b < a { b } else { a }
}

/// A lattice row's chamfer candidates from its neighbour row `other` (already final in this
/// pass): straight across (step 1) and diagonal (step sqrt 2).
#[inline(always)]
fn chamfer_from_row(row: &mut [f32], other: &[f32]) {
    const D: f32 = std::f32::consts::SQRT_2;
    let n = row.len();
    if n == 0 || other.len() < n {
        return;
    }
    row[0] = lo(row[0], other[0] + 1.0);
    if n > 1 {
        row[0] = lo(row[0], other[1] + D);
        row[n - 1] = lo(lo(row[n - 1], other[n - 1] + 1.0), other[n - 2] + D);
    }
    if n > 2 {
        let (mid, l, c, r) = (
            &mut row[1..n - 1],
            &other[..n - 2],
            &other[1..n - 1],
            &other[2..],
        );
        for (((o, a), b), d) in mid.iter_mut().zip(l).zip(c).zip(r) {
            *o = lo(lo(lo(*o, *b + 1.0), *a + D), *d + D);
        }
    }
}

fn dot(t: &[f32; TERMS], k: &SVector<f64, TERMS>) -> f32 {
    t.iter()
        .zip(k.iter())
        .map(|(&a, &b)| f64::from(a) * b)
        .sum::<f64>() as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn box3_is_the_mean_of_the_neighbours_inside_the_frame() {
        let (w, h) = (5usize, 4usize);
        let src: Vec<f32> = (0..w * h * 3).map(|i| (i * 7 % 11) as f32).collect();
        let mut dst = vec![0f32; src.len()];
        box3(&src, &mut dst, w, h);
        // The same from two u8 images whose difference is src.
        let frame: Vec<u8> = src.iter().map(|&v| v as u8 + 20).collect();
        let background = vec![20u8; src.len()];
        let mut fused = vec![0f32; src.len()];
        box3_interleaved(&frame, &background, &mut Vec::new(), &mut fused, w, h);
        assert_eq!(fused, dst, "the row-by-row box mean gives box3's bytes");
        for y in 0..h {
            for x in 0..w {
                let at = box3_at(&frame, &background, w, h, x, y);
                assert_eq!(at[..], dst[(y * w + x) * 3..][..3], "box3_at ({x}, {y})");
            }
        }
        for y in 0..h {
            for x in 0..w {
                for c in 0..3 {
                    let (mut s, mut n) = (0.0, 0.0);
                    for yy in y.saturating_sub(1)..=(y + 1).min(h - 1) {
                        for xx in x.saturating_sub(1)..=(x + 1).min(w - 1) {
                            s += src[(yy * w + xx) * 3 + c];
                            n += 1.0;
                        }
                    }
                    let got = dst[(y * w + x) * 3 + c];
                    assert!(
                        (got - s / n).abs() < 1e-4,
                        "({x}, {y}, {c}): {got} vs {}",
                        s / n
                    );
                }
            }
        }
    }

    /// A chamfer pass's neighbours: (dx, dy, step).
    type Steps = [(isize, isize, f32); 4];

    /// The chamfer distances cell by cell, as the textbook writes them: each cell takes the
    /// smallest of its own distance and its four neighbours' done before it, plus their steps.
    fn distances_cell_by_cell(keep: &[bool], nx: usize) -> Vec<f32> {
        let ny = keep.len() / nx;
        const D: f32 = std::f32::consts::SQRT_2;
        let mut dist: Vec<f32> = keep
            .iter()
            .map(|k| if *k { f32::MAX } else { 0.0 })
            .collect();
        let passes: [(Vec<usize>, Vec<usize>, Steps); 2] = [
            (
                (0..ny).collect(),
                (0..nx).collect(),
                [(-1, 0, 1.0), (0, -1, 1.0), (-1, -1, D), (1, -1, D)],
            ),
            (
                (0..ny).rev().collect(),
                (0..nx).rev().collect(),
                [(1, 0, 1.0), (0, 1, 1.0), (1, 1, D), (-1, 1, D)],
            ),
        ];
        for (rows, cols, steps) in passes {
            for &j in &rows {
                for &i in &cols {
                    let mut d = dist[j * nx + i];
                    for (di, dj, step) in steps {
                        let (a, b) = (i as isize + di, j as isize + dj);
                        if a >= 0 && b >= 0 && (a as usize) < nx && (b as usize) < ny {
                            d = d.min(dist[b as usize * nx + a as usize] + step);
                        }
                    }
                    dist[j * nx + i] = d;
                }
            }
        }
        dist
    }

    #[test]
    fn the_row_wise_chamfer_leaves_out_the_cells_the_cell_by_cell_one_does() {
        let (w, nx, ny) = (320usize, 40usize, 30usize);
        let mut seed = 7u64;
        let mut rand = move || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 33) as usize
        };
        let mut dist = Vec::new();
        for case in 0..60 {
            let mut keep = vec![true; nx * ny];
            // One to three blobs, and some lone cells, anywhere, the frame's edges included.
            for _ in 0..1 + case % 3 {
                let (cx, cy, r) = (rand() % nx, rand() % ny, 1 + rand() % 5);
                for j in 0..ny {
                    for i in 0..nx {
                        if i.abs_diff(cx).pow(2) + j.abs_diff(cy).pow(2) <= r * r {
                            keep[j * nx + i] = false;
                        }
                    }
                }
            }
            for _ in 0..case % 4 {
                keep[rand() % (nx * ny)] = false;
            }
            let reference = distances_cell_by_cell(&keep, nx);
            let mut expect = keep.clone();
            if let Some(reach) = dilation_reach(&expect) {
                keep_beyond(&mut expect, &reference, reach);
            }
            dilate_rejected(&mut keep, w, &mut dist);
            assert_eq!(keep, expect, "case {case}");
            assert!(
                keep.iter().any(|k| !*k),
                "case {case} leaves some cells out"
            );
        }
    }

    #[test]
    fn a_smooth_tilt_is_removed_and_a_compact_press_is_kept() {
        let (w, h) = (160usize, 120usize);
        let bg = vec![100u8; w * h * 3];
        let mut f = bg.clone();
        for y in 0..h {
            for x in 0..w {
                let tilt = (x as f32 / w as f32) * 12.0;
                let press = if (x as f32 - 60.0).hypot(y as f32 - 60.0) < 10.0 {
                    30.0
                } else {
                    0.0
                };
                for c in 0..3 {
                    f[(y * w + x) * 3 + c] = (100.0 + tilt + press) as u8;
                }
            }
        }
        let mut p = Prep::default();
        p.run(&f, &bg, w, h);
        let at = |x: usize, y: usize| p.diff[(y * w + x) * 3];
        assert!(at(150, 10).abs() < 1.5, "{}", at(150, 10));
        assert!(at(60, 60) > 25.0, "{}", at(60, 60));
    }
}
