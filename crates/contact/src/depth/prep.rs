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
//! shading on mock presses. Calibration
//! and estimation run the same steps, so the model learns the colours it is later shown.

use nalgebra::{SMatrix, SVector};

const TERMS: usize = 6;
const LATTICE: usize = 8;

/// Scratch and result of [`Prep::run`]: the prepared difference, RGB interleaved \[DN].
#[derive(Debug, Default, Clone)]
pub struct Prep {
    pub diff: Vec<f32>,
    tmp: Vec<f32>,
    lattice: Lattice,
}

/// The shading fit's lattice for one frame size, built once per size: each cell's offset into
/// the interleaved difference and its terms, and the normal matrix of the whole lattice (a fit
/// takes out the rows of the cells it leaves out).
#[derive(Debug, Default, Clone)]
struct Lattice {
    size: (usize, usize),
    cells: Vec<(usize, [f32; TERMS])>,
    ata: SMatrix<f64, TERMS, TERMS>,
    /// Per-iteration scratch: which cells the fit keeps, their residuals and the |residual|s.
    keep: Vec<bool>,
    res: Vec<f32>,
    abs: Vec<f32>,
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
                self.cells.push((
                    (y * w + x) * 3,
                    terms((x as f32 - cx) * inv, (y as f32 - cy) * inv),
                ));
            }
        }
        self.ata = self
            .cells
            .iter()
            .fold(SMatrix::zeros(), |a, (_, t)| a + outer(t));
        self.size = (w, h);
    }
}

fn terms(u: f32, v: f32) -> [f32; TERMS] {
    let (u2, v2) = (u * u, v * v);
    [1.0, u, v, u2, u * v, v2]
}

impl Prep {
    /// Prepare `frame` against `background` (RGB8, `w` x `h`, both of `w * h * 3` bytes; the
    /// caller checks the sizes).
    pub fn run(&mut self, frame: &[u8], background: &[u8], w: usize, h: usize) {
        let field = self.run_unsubtracted(frame, background, w, h);
        field.subtract(&mut self.diff, w, h);
    }

    /// As [`run`](Self::run) but leaves the shading in `diff` and returns it, for a caller that
    /// subtracts it in its own pass over the pixels ([`Shading::row`]).
    pub fn run_unsubtracted(
        &mut self,
        frame: &[u8],
        background: &[u8],
        w: usize,
        h: usize,
    ) -> Shading {
        let n = w * h * 3;
        self.diff.resize(n, 0.0);
        self.tmp.resize(4 * w * 3, 0.0);
        box3_diff(frame, background, &mut self.tmp, &mut self.diff, w, h);
        self.lattice.for_size(w, h);
        fit_shading(&self.diff, w, h, &mut self.lattice)
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

    /// w/2 and 1 / max(w, h): s = (x - cx) * inv.
    pub fn cx(&self) -> f32 {
        self.cx
    }
    pub fn inv(&self) -> f32 {
        self.inv
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

/// `box3` of `frame - background` (u8) in one pass over the rows: the difference of a row
/// taken into the first row of `rows` (four rows of scratch), its horizontal mean into a ring
/// of the last three (the other three rows), and each output row written once from the ring,
/// one row behind (no difference image, no second pass over `dst`; the same sums in the same
/// order as `box3`, so the same bytes). Built for baseline x86-64 and for AVX2.
#[multiversion::multiversion(targets("x86_64+avx2"))]
fn box3_diff(
    frame: &[u8],
    background: &[u8],
    rows: &mut [f32],
    dst: &mut [f32],
    w: usize,
    h: usize,
) {
    let stride = w * 3;
    if w < 2 || h < 2 || rows.len() < 4 * stride {
        for ((d, &f), &b) in dst.iter_mut().zip(frame).zip(background) {
            *d = f32::from(f) - f32::from(b);
        }
        return;
    }
    const THIRD: f32 = 1.0 / 3.0;
    let (row, ring) = rows.split_at_mut(stride);
    for (y, (fr, bg)) in frame
        .chunks_exact(stride)
        .zip(background.chunks_exact(stride))
        .enumerate()
        .take(h)
    {
        for ((t, &f), &b) in row.iter_mut().zip(fr).zip(bg) {
            *t = f32::from(f) - f32::from(b);
        }
        let slot = y % 3;
        horizontal3(
            row,
            &mut ring[slot * stride..(slot + 1) * stride],
            stride,
            THIRD,
        );
        if y == 0 {
            continue;
        }
        let at = |k: usize| &ring[(k % 3) * stride..(k % 3 + 1) * stride];
        let out = &mut dst[(y - 1) * stride..y * stride];
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
    }
    let (cur, prev) = (
        &ring[((h - 1) % 3) * stride..((h - 1) % 3 + 1) * stride],
        &ring[((h - 2) % 3) * stride..((h - 2) % 3 + 1) * stride],
    );
    for ((o, c), p) in dst[(h - 1) * stride..].iter_mut().zip(cur).zip(prev) {
        *o = (c + p) * 0.5;
    }
}

/// One row's horizontal three-tap mean (two taps at the ends).
#[inline(always)]
fn horizontal3(row: &[f32], out: &mut [f32], stride: usize, third: f32) {
    for c in 0..3 {
        out[c] = (row[c] + row[3 + c]) * 0.5;
        out[stride - 3 + c] = (row[stride - 6 + c] + row[stride - 3 + c]) * 0.5;
    }
    let n = stride - 6;
    let (l, m, r) = (&row[..n], &row[3..3 + n], &row[6..6 + n]);
    for (((o, a), b), c) in out[3..3 + n].iter_mut().zip(l).zip(m).zip(r) {
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

/// 3 x 3 box mean per channel (the border averages what is inside the frame): a horizontal
/// three-tap pass per row into `dst`, then a vertical one through a copy of the previous row,
/// both written as slice arithmetic over whole rows so that they vectorise.
#[cfg(test)]
fn box3(src: &[f32], dst: &mut [f32], w: usize, h: usize) {
    let stride = w * 3;
    if w < 2 || h < 2 {
        dst.copy_from_slice(src);
        return;
    }
    const THIRD: f32 = 1.0 / 3.0;
    for (row, out) in src.chunks_exact(stride).zip(dst.chunks_exact_mut(stride)) {
        horizontal3(row, out, stride, THIRD);
    }
    vertical3(dst, w, h, THIRD);
}

/// Fit the smooth shading per channel (module docs). The normal equations of each pass are the
/// whole lattice's less the rows of the cells left out (few: a press and the cells around it).
fn fit_shading(diff: &[f32], w: usize, h: usize, lat: &mut Lattice) -> Shading {
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
        ata: ata_all,
        keep,
        res,
        abs,
        ..
    } = lat;
    if cells.len() < 3 * TERMS || cells.last().is_some_and(|(i, _)| i + 2 >= diff.len()) {
        return out;
    }
    let mut fields = [[0f32; TERMS]; 3];
    let mut any = false;
    for (c, field) in fields.iter_mut().enumerate() {
        let atb_all = cells
            .iter()
            .fold(SVector::<f64, TERMS>::zeros(), |a, (i, t)| {
                a + SVector::<f64, TERMS>::from_iterator(t.iter().map(|&v| f64::from(v)))
                    * f64::from(diff[i + c])
            });
        keep.clear();
        keep.resize(cells.len(), true);
        let mut coef: Option<SVector<f64, TERMS>> = None;
        for _ in 0..3 {
            let (mut ata, mut atb) = (*ata_all, atb_all);
            let mut used = cells.len();
            for ((i, t), _) in cells.iter().zip(keep.iter()).filter(|(_, k)| !**k) {
                let tv = SVector::<f64, TERMS>::from_iterator(t.iter().map(|&v| f64::from(v)));
                ata -= tv * tv.transpose();
                atb -= tv * f64::from(diff[i + c]);
                used -= 1;
            }
            if used < 2 * TERMS {
                break;
            }
            let Some(ch) = ata.cholesky() else { break };
            let k = ch.solve(&atb);
            res.clear();
            res.extend(cells.iter().map(|(i, t)| diff[i + c] - dot(t, &k)));
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
            dilate_rejected(keep, w);
            coef = Some(k);
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
fn dilate_rejected(keep: &mut [bool], w: usize) {
    let nx = (w.saturating_sub(LATTICE / 2)).div_ceil(LATTICE).max(1);
    let ny = keep.len() / nx;
    let rejected = keep.iter().filter(|k| !**k).count();
    if rejected == 0 || rejected * 2 > keep.len() || nx * ny != keep.len() {
        return;
    }
    let reach = (2.0 * (rejected as f32 / std::f32::consts::PI).sqrt()).max(2.0);
    const D: f32 = std::f32::consts::SQRT_2;
    let mut dist: Vec<f32> = keep
        .iter()
        .map(|k| if *k { f32::MAX } else { 0.0 })
        .collect();
    for j in 0..ny {
        for i in 0..nx {
            let mut d = dist[j * nx + i];
            if i > 0 {
                d = d.min(dist[j * nx + i - 1] + 1.0);
            }
            if j > 0 {
                d = d.min(dist[(j - 1) * nx + i] + 1.0);
                if i > 0 {
                    d = d.min(dist[(j - 1) * nx + i - 1] + D);
                }
                if i + 1 < nx {
                    d = d.min(dist[(j - 1) * nx + i + 1] + D);
                }
            }
            dist[j * nx + i] = d;
        }
    }
    for j in (0..ny).rev() {
        for i in (0..nx).rev() {
            let mut d = dist[j * nx + i];
            if i + 1 < nx {
                d = d.min(dist[j * nx + i + 1] + 1.0);
            }
            if j + 1 < ny {
                d = d.min(dist[(j + 1) * nx + i] + 1.0);
                if i + 1 < nx {
                    d = d.min(dist[(j + 1) * nx + i + 1] + D);
                }
                if i > 0 {
                    d = d.min(dist[(j + 1) * nx + i - 1] + D);
                }
            }
            dist[j * nx + i] = d;
        }
    }
    let grown: Vec<bool> = dist.iter().map(|d| *d > reach).collect();
    // Keep at least half the lattice for the fit.
    if grown.iter().filter(|k| **k).count() * 2 >= keep.len() {
        keep.copy_from_slice(&grown);
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
        let mut rows = vec![0f32; 4 * w * 3];
        box3_diff(&frame, &background, &mut rows, &mut fused, w, h);
        assert_eq!(fused, dst, "the one-pass box mean gives box3's bytes");
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
