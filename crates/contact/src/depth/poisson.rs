//! Height from a gradient field: least-squares integration by a direct Poisson solve.
//!
//! The gradients (p, q) at the pixel centres are averaged onto the edges between neighbouring
//! pixels, with zero flux through the frame's border (Neumann), and the height h that minimises
//! the squared difference between its edge differences and those edge gradients solves the
//! discrete Poisson equation `L h = div g` with the 5-point Laplacian L reflected at the border.
//! L is `Lx (x) I + I (x) Ly`, and the DCT-II diagonalises the 1-D Neumann Laplacian Lx
//! (eigenvalues `lambda_k = 2 cos(pi k / w) - 2`). So a DCT-II of every row leaves, for each
//! row frequency k, one tridiagonal system along the column, `(Ly + lambda_k) H_k = F_k`, solved
//! by elimination (the pivots' reciprocals tabled once per size), all k of a row at once, in
//! the row layout: no column transforms and no transposes. k = 0 (Ly alone, singular: the
//! constant is free) is integrated by running sums. A DCT-III of every row goes back. O(N log
//! N), no iteration; the result is mean-free (the caller chooses the zero level).
//!
//! The row transforms ([`RowDct`]): Makhoul's DCT through an FFT of the same length (rustfft,
//! planned once per size, f32), two real rows per complex transform: the forward transform
//! separates the two rows' spectra by conjugate symmetry, and the inverse's FFT of each row is
//! real, so one row comes out in the real part and the other in the imaginary part. The same
//! unnormalised convention as rustdct: DCT-II `X_k = sum x_n cos(pi k (2n + 1) / 2N)`, DCT-III
//! `x_n = X_0 / 2 + sum_(k>0) X_k cos(pi k (2n + 1) / 2N)`, so DCT-III(DCT-II(x)) = N/2 x.

use rustfft::num_complex::Complex;
use rustfft::{Fft, FftPlanner};
use std::sync::Arc;

/// DCT-II and DCT-III of real rows of one length, two rows per complex FFT.
pub struct RowDct {
    n: usize,
    fft: Arc<dyn Fft<f32>>,
    /// e^(-i pi k / 2N).
    tw: Vec<Complex<f32>>,
    buf: Vec<Complex<f32>>,
    scratch: Vec<Complex<f32>>,
}

impl std::fmt::Debug for RowDct {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RowDct")
            .field("n", &self.n)
            .finish_non_exhaustive()
    }
}

impl RowDct {
    /// Transforms of rows of `n` (at least 1).
    pub fn new(n: usize) -> Self {
        let n = n.max(1);
        let fft = FftPlanner::new().plan_fft_forward(n);
        let tw = (0..n)
            .map(|k| {
                let a = -std::f64::consts::PI * k as f64 / (2 * n) as f64;
                Complex::new(a.cos() as f32, a.sin() as f32)
            })
            .collect();
        let scratch = vec![Complex::new(0.0, 0.0); fft.get_inplace_scratch_len()];
        Self {
            n,
            fft,
            tw,
            buf: vec![Complex::new(0.0, 0.0); n],
            scratch,
        }
    }

    /// DCT-II of `a` and `b` in place (both of the planned length, else nothing is done).
    pub fn dct2_pair(&mut self, a: &mut [f32], b: &mut [f32]) {
        let n = self.n;
        if a.len() != n || b.len() != n {
            return;
        }
        // Even elements in order, then the odd ones reversed: element 2i to i, 2i + 1 to
        // N - 1 - i.
        let even = n.div_ceil(2);
        let (lo, hi) = self.buf.split_at_mut(even);
        for (((z, zo), x), y) in lo
            .iter_mut()
            .zip(hi.iter_mut().rev())
            .zip(a.chunks_exact(2))
            .zip(b.chunks_exact(2))
        {
            *z = Complex::new(x[0], y[0]);
            *zo = Complex::new(x[1], y[1]);
        }
        if n % 2 == 1 {
            if let (Some(z), Some(x), Some(y)) = (lo.last_mut(), a.last(), b.last()) {
                *z = Complex::new(*x, *y);
            }
        }
        self.fft
            .process_with_scratch(&mut self.buf, &mut self.scratch);
        // Spectra of the two real sequences: A_k = (Z_k + conj Z_(N-k)) / 2,
        // B_k = (Z_k - conj Z_(N-k)) / 2i; then X_k = Re(V_k e^(-i pi k / 2N)). With
        // Z_k = (p, q) and Z_(N-k) = (r, s): A_k = ((p + r) / 2, (q - s) / 2),
        // B_k = ((q + s) / 2, (r - p) / 2).
        let (z0, rest) = self.buf.split_at(1);
        if let (Some(z), Some(x), Some(y)) = (z0.first(), a.first_mut(), b.first_mut()) {
            *x = z.re;
            *y = z.im;
        }
        for ((((z, zm), t), x), y) in rest
            .iter()
            .zip(rest.iter().rev())
            .zip(&self.tw[1..])
            .zip(a[1..].iter_mut())
            .zip(b[1..].iter_mut())
        {
            let (ar, ai) = (0.5 * (z.re + zm.re), 0.5 * (z.im - zm.im));
            let (br, bi) = (0.5 * (z.im + zm.im), 0.5 * (zm.re - z.re));
            *x = ar * t.re - ai * t.im;
            *y = br * t.re - bi * t.im;
        }
    }

    /// DCT-III of `a` and `b` in place (both of the planned length, else nothing is done).
    pub fn dct3_pair(&mut self, a: &mut [f32], b: &mut [f32]) {
        let n = self.n;
        if a.len() != n || b.len() != n {
            return;
        }
        // u_k = (X_k + i X_(N-k)) e^(-i pi k / 2N) / 2 (u_0 = X_0 / 2) per row; the FFT of each
        // is real, so the pair goes in as u_a + i u_b.
        if let (Some(z), Some(x), Some(y)) = (self.buf.first_mut(), a.first(), b.first()) {
            *z = Complex::new(x * 0.5, y * 0.5);
        }
        for (((((z, t), xa), xam), xb), xbm) in self.buf[1..]
            .iter_mut()
            .zip(&self.tw[1..])
            .zip(&a[1..])
            .zip(a[1..].iter().rev())
            .zip(&b[1..])
            .zip(b[1..].iter().rev())
        {
            let (tr, ti) = (0.5 * t.re, 0.5 * t.im);
            let (uar, uai) = (xa * tr - xam * ti, xa * ti + xam * tr);
            let (ubr, ubi) = (xb * tr - xbm * ti, xb * ti + xbm * tr);
            *z = Complex::new(uar - ubi, uai + ubr);
        }
        self.fft
            .process_with_scratch(&mut self.buf, &mut self.scratch);
        let even = n.div_ceil(2);
        let (lo, hi) = self.buf.split_at(even);
        for (((z, zo), x), y) in lo
            .iter()
            .zip(hi.iter().rev())
            .zip(a.chunks_exact_mut(2))
            .zip(b.chunks_exact_mut(2))
        {
            x[0] = z.re;
            x[1] = zo.re;
            y[0] = z.im;
            y[1] = zo.im;
        }
        if n % 2 == 1 {
            if let (Some(z), Some(x), Some(y)) = (lo.last(), a.last_mut(), b.last_mut()) {
                *x = z.re;
                *y = z.im;
            }
        }
    }
}

/// A planned solver for one frame size.
pub struct PoissonSolver {
    w: usize,
    h: usize,
    rows: RowDct,
    /// Reciprocal pivots of the elimination, row-major h x w: `rec[y * w + k]` for the system of
    /// row frequency k (k = 0 unused).
    rec: Vec<f32>,
    /// Column k = 0 of the transformed divergence, kept for its running-sum solve.
    col0: Vec<f32>,
    /// The partner of an odd frame's last row in the paired transforms.
    spare: Vec<f32>,
}

impl std::fmt::Debug for PoissonSolver {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PoissonSolver")
            .field("w", &self.w)
            .field("h", &self.h)
            .finish_non_exhaustive()
    }
}

impl PoissonSolver {
    /// A solver for `w` x `h` (each at least 2).
    pub fn new(w: usize, h: usize) -> Self {
        let (w, h) = (w.max(2), h.max(2));
        let rows = RowDct::new(w);
        // Tridiagonal Ly + lambda_k: off-diagonals 1, diagonal -2 + lambda_k (-1 + lambda_k in
        // the first and last row). Pivots m_0 = d_0, m_y = d_y - 1 / m_(y-1); every d is
        // below -2 + 1 for k > 0, so |m| > 1 and the elimination is stable.
        let mut rec = vec![0f32; w * h];
        for k in 1..w {
            let lam = 2.0 * (std::f64::consts::PI * k as f64 / w as f64).cos() - 2.0;
            let mut m = 0f64;
            for y in 0..h {
                let d = if y == 0 || y + 1 == h { -1.0 } else { -2.0 } + lam;
                m = if y == 0 { d } else { d - 1.0 / m };
                if let Some(r) = rec.get_mut(y * w + k) {
                    *r = (1.0 / m) as f32;
                }
            }
        }
        Self {
            w,
            h,
            rows,
            rec,
            col0: vec![0.0; h],
            spare: vec![0.0; w],
        }
    }

    pub fn size(&self) -> (usize, usize) {
        (self.w, self.h)
    }

    /// Integrate `gx`, `gy` (height change per pixel step, row-major w x h) into `out` (mean-free
    /// height in the same unit). Slices of another length leave `out` untouched and return false.
    pub fn solve(&mut self, gx: &[f32], gy: &[f32], out: &mut [f32]) -> bool {
        let (w, h) = (self.w, self.h);
        let n = w * h;
        if gx.len() != n || gy.len() != n || out.len() != n {
            return false;
        }
        // Divergence of the edge gradients (edge value = mean of its two pixels, 0 at the
        // border): half the central difference inside, one-sided at the border; row by row
        // over whole slices so that it vectorises. The inverse row transform's scale 2 / w is
        // folded in here (half = 0.5 * 2 / w).
        let half = 1.0 / w as f32;
        for ((f, p), y) in out.chunks_exact_mut(w).zip(gx.chunks_exact(w)).zip(0..h) {
            f[0] = half * (p[0] + p[1]);
            f[w - 1] = -half * (p[w - 2] + p[w - 1]);
            for ((o, a), b) in f[1..w - 1].iter_mut().zip(&p[..w - 2]).zip(&p[2..]) {
                *o = half * (b - a);
            }
            let q = &gy[y * w..(y + 1) * w];
            if y == 0 {
                let below = &gy[w..2 * w];
                for ((o, a), b) in f.iter_mut().zip(q).zip(below) {
                    *o += half * (a + b);
                }
            } else if y + 1 == h {
                let above = &gy[(y - 1) * w..y * w];
                for ((o, a), b) in f.iter_mut().zip(q).zip(above) {
                    *o -= half * (a + b);
                }
            } else {
                let above = &gy[(y - 1) * w..y * w];
                let below = &gy[(y + 1) * w..(y + 2) * w];
                for ((o, a), b) in f.iter_mut().zip(above).zip(below) {
                    *o += half * (b - a);
                }
            }
        }
        self.row_pairs(out, true);
        for (c, row) in self.col0.iter_mut().zip(out.chunks_exact(w)) {
            *c = row[0];
        }
        // Forward elimination, a row at a time over every k: g_y = (f_y - g_(y-1)) / m_y.
        for (y, rec) in self.rec.chunks_exact(w).enumerate() {
            let (above, rest) = out.split_at_mut(y * w);
            let row = &mut rest[..w];
            match above.get(above.len().saturating_sub(w)..).filter(|_| y > 0) {
                Some(g) => row
                    .iter_mut()
                    .zip(rec)
                    .zip(g)
                    .for_each(|((v, r), g)| *v = (*v - g) * r),
                None => row.iter_mut().zip(rec).for_each(|(v, r)| *v *= r),
            }
        }
        // Back substitution: x_y = g_y - x_(y+1) / m_y.
        for (y, rec) in self.rec.chunks_exact(w).enumerate().rev().skip(1) {
            let (head, tail) = out.split_at_mut((y + 1) * w);
            let row = &mut head[y * w..];
            for ((v, r), x) in row.iter_mut().zip(rec).zip(&tail[..w]) {
                *v -= x * r;
            }
        }
        // k = 0: Ly x = f with zero flux at both ends, so the difference x_(y+1) - x_y is the
        // running sum of f up to y; mean-free (the free constant).
        let (mut edge, mut x, mut sum) = (0f64, 0f64, 0f64);
        for c in self.col0.iter_mut() {
            let f = f64::from(*c);
            *c = x as f32;
            sum += x;
            edge += f;
            x += edge;
        }
        let mean = (sum / h as f64) as f32;
        for (row, c) in out.chunks_exact_mut(w).zip(&self.col0) {
            row[0] = c - mean;
        }
        self.row_pairs(out, false);
        true
    }

    /// DCT-II (`forward`) or DCT-III of every row of `out`, two rows at a time (the last row of
    /// an odd frame with a spare row).
    fn row_pairs(&mut self, out: &mut [f32], forward: bool) {
        let w = self.w;
        let mut pairs = out.chunks_exact_mut(2 * w);
        for pair in pairs.by_ref() {
            let (a, b) = pair.split_at_mut(w);
            if forward {
                self.rows.dct2_pair(a, b);
            } else {
                self.rows.dct3_pair(a, b);
            }
        }
        let last = pairs.into_remainder();
        if last.len() == w {
            self.spare.iter_mut().for_each(|v| *v = 0.0);
            if forward {
                self.rows.dct2_pair(last, &mut self.spare);
            } else {
                self.rows.dct3_pair(last, &mut self.spare);
            }
        }
    }
}
#[cfg(test)]
mod tests {
    use super::*;

    /// A smooth bump integrates back from its analytic gradients, up to a constant.
    #[test]
    fn recovers_a_gaussian_bump() {
        let (w, h) = (64usize, 48usize);
        let f = |x: f64, y: f64| (-((x - 30.0).powi(2) + (y - 20.0).powi(2)) / 60.0).exp() * 3.0;
        let mut gx = vec![0f32; w * h];
        let mut gy = vec![0f32; w * h];
        let mut truth = vec![0f64; w * h];
        for y in 0..h {
            for x in 0..w {
                let (xf, yf) = (x as f64, y as f64);
                let v = f(xf, yf);
                truth[y * w + x] = v;
                gx[y * w + x] = (v * -(2.0 * (xf - 30.0) / 60.0)) as f32;
                gy[y * w + x] = (v * -(2.0 * (yf - 20.0) / 60.0)) as f32;
            }
        }
        let mut s = PoissonSolver::new(w, h);
        let mut out = vec![0f32; w * h];
        assert!(s.solve(&gx, &gy, &mut out));
        let mean_t = truth.iter().sum::<f64>() / (w * h) as f64;
        let mean_o = out.iter().map(|&v| f64::from(v)).sum::<f64>() / (w * h) as f64;
        let worst = truth
            .iter()
            .zip(&out)
            .map(|(t, o)| ((t - mean_t) - (f64::from(*o) - mean_o)).abs())
            .fold(0.0, f64::max);
        assert!(mean_o.abs() < 1e-4, "mean-free: {mean_o}");
        assert!(worst < 0.05, "worst error {worst} of a 3.0 bump");
    }

    /// At a frame's size, on rough gradients, the result satisfies the discrete equation: its
    /// reflected 5-point Laplacian equals the edge gradients' divergence at every pixel.
    #[test]
    fn solves_the_discrete_poisson_equation_at_frame_size() {
        for (w, h) in [(320usize, 240usize), (33, 25)] {
            residual_at(w, h);
        }
    }

    fn residual_at(w: usize, h: usize) {
        let mut seed = 12345u32;
        let mut rnd = || {
            seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (seed >> 8) as f32 / (1u32 << 24) as f32 - 0.5
        };
        let gx: Vec<f32> = (0..w * h).map(|_| 0.01 * rnd()).collect();
        let gy: Vec<f32> = (0..w * h).map(|_| 0.01 * rnd()).collect();
        let mut s = PoissonSolver::new(w, h);
        let mut z = vec![0f32; w * h];
        assert!(s.solve(&gx, &gy, &mut z));
        let at = |v: &[f32], x: usize, y: usize| f64::from(v[y * w + x]);
        let mut worst = 0f64;
        for y in 0..h {
            for x in 0..w {
                let mut lap = 0.0;
                let mut div = 0.0;
                if x > 0 {
                    lap += at(&z, x - 1, y) - at(&z, x, y);
                    div -= 0.5 * (at(&gx, x - 1, y) + at(&gx, x, y));
                }
                if x + 1 < w {
                    lap += at(&z, x + 1, y) - at(&z, x, y);
                    div += 0.5 * (at(&gx, x, y) + at(&gx, x + 1, y));
                }
                if y > 0 {
                    lap += at(&z, x, y - 1) - at(&z, x, y);
                    div -= 0.5 * (at(&gy, x, y - 1) + at(&gy, x, y));
                }
                if y + 1 < h {
                    lap += at(&z, x, y + 1) - at(&z, x, y);
                    div += 0.5 * (at(&gy, x, y) + at(&gy, x, y + 1));
                }
                worst = worst.max((lap - div).abs());
            }
        }
        let mean = z.iter().map(|&v| f64::from(v)).sum::<f64>() / (w * h) as f64;
        assert!(
            worst < 1e-4,
            "largest residual {worst} (gradients up to 0.005)"
        );
        assert!(mean.abs() < 1e-4, "mean-free: {mean}");
    }

    /// The paired transforms are the DCT-II and DCT-III of their definitions, on odd and even
    /// lengths, each row of a pair on its own.
    #[test]
    fn paired_row_transforms_follow_the_definitions() {
        for n in [1usize, 2, 7, 8, 320] {
            let a: Vec<f32> = (0..n).map(|i| ((i * 37 % 11) as f32 - 5.0) * 0.3).collect();
            let b: Vec<f32> = (0..n).map(|i| ((i * 13 % 7) as f32 - 3.0) * 0.7).collect();
            let c = |k: usize, m: usize| {
                (std::f64::consts::PI * k as f64 * (2 * m + 1) as f64 / (2 * n) as f64).cos()
            };
            let dct2 = |x: &[f32]| -> Vec<f64> {
                (0..n)
                    .map(|k| (0..n).map(|m| f64::from(x[m]) * c(k, m)).sum())
                    .collect()
            };
            let dct3 = |x: &[f32]| -> Vec<f64> {
                (0..n)
                    .map(|m| {
                        f64::from(x[0]) * 0.5
                            + (1..n).map(|k| f64::from(x[k]) * c(k, m)).sum::<f64>()
                    })
                    .collect()
            };
            let mut t = RowDct::new(n);
            for (fwd, want) in [(true, [dct2(&a), dct2(&b)]), (false, [dct3(&a), dct3(&b)])] {
                let (mut x, mut y) = (a.clone(), b.clone());
                if fwd {
                    t.dct2_pair(&mut x, &mut y);
                } else {
                    t.dct3_pair(&mut x, &mut y);
                }
                for (got, want) in [(&x, &want[0]), (&y, &want[1])] {
                    for (g, w) in got.iter().zip(want) {
                        assert!(
                            (f64::from(*g) - w).abs() < 1e-3,
                            "n {n} fwd {fwd}: {g} vs {w}"
                        );
                    }
                }
            }
        }
    }

    /// A height map's own edge differences (on a grid where they are exact) come back exactly:
    /// a plane's gradient and the result's differences agree.
    #[test]
    fn a_plane_integrates_to_a_plane_and_wrong_lengths_are_refused() {
        let (w, h) = (40usize, 30usize);
        let gx = vec![0.5f32; w * h];
        let gy = vec![-0.25f32; w * h];
        let mut s = PoissonSolver::new(w, h);
        let mut out = vec![0f32; w * h];
        assert!(s.solve(&gx, &gy, &mut out));
        // Away from the border (where the zero-flux condition bends it) the slope is the plane's.
        let (x, y) = (20, 15);
        let dx = out[y * w + x + 1] - out[y * w + x];
        let dy = out[(y + 1) * w + x] - out[y * w + x];
        assert!(
            (dx - 0.5).abs() < 0.05 && (dy + 0.25).abs() < 0.05,
            "{dx} {dy}"
        );
        let mut short = vec![0f32; 3];
        assert!(!s.solve(&gx, &gy, &mut short));
        assert_eq!(short, vec![0.0; 3]);
    }
}
