//! Height from a gradient field: least-squares integration by a DCT Poisson solve.
//!
//! The gradients (p, q) at the pixel centres are averaged onto the edges between neighbouring
//! pixels, with zero flux through the frame's border (Neumann), and the height h that minimises
//! the squared difference between its edge differences and those edge gradients solves the
//! discrete Poisson equation `L h = div g` with the 5-point Laplacian L reflected at the border.
//! The DCT-II diagonalises that L (eigenvalues `2 cos(pi k / N) - 2` per axis), so the solve is
//! a 2-D DCT-II of the divergence, a division, and a 2-D DCT-III back: O(N log N), no iteration.
//! The constant is free (the (0, 0) coefficient is set to zero: a mean-free height); the caller
//! chooses the zero level. Transforms are rustdct's (planned once per size, f32); the division
//! and the transposes between the row passes are the only loops here.

use rustdct::{DctPlanner, TransformType2And3};
use std::sync::Arc;

/// A planned solver for one frame size.
pub struct PoissonSolver {
    w: usize,
    h: usize,
    rows: Arc<dyn TransformType2And3<f32>>,
    cols: Arc<dyn TransformType2And3<f32>>,
    /// 1 / (lambda_x + lambda_y) in the transposed layout (w rows of h), 0 at (0, 0); times the
    /// inverse transforms' scale 4 / (w h).
    inv: Vec<f32>,
    buf: Vec<f32>,
    tbuf: Vec<f32>,
    scratch: Vec<f32>,
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
        let mut planner = DctPlanner::new();
        let rows = planner.plan_dct2(w);
        let cols = planner.plan_dct2(h);
        let scale = 4.0 / (w as f64 * h as f64);
        let lam =
            |k: usize, n: usize| 2.0 * (std::f64::consts::PI * k as f64 / n as f64).cos() - 2.0;
        let mut inv = vec![0f32; w * h];
        for kx in 0..w {
            for ky in 0..h {
                let l = lam(kx, w) + lam(ky, h);
                inv[kx * h + ky] = if kx == 0 && ky == 0 {
                    0.0
                } else {
                    (scale / l) as f32
                };
            }
        }
        let scratch_len = rows.get_scratch_len().max(cols.get_scratch_len());
        Self {
            w,
            h,
            rows,
            cols,
            inv,
            buf: vec![0.0; w * h],
            tbuf: vec![0.0; w * h],
            scratch: vec![0.0; scratch_len],
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
        // over whole slices so that it vectorises.
        for ((f, p), y) in self
            .buf
            .chunks_exact_mut(w)
            .zip(gx.chunks_exact(w))
            .zip(0..h)
        {
            f[0] = 0.5 * (p[0] + p[1]);
            f[w - 1] = -0.5 * (p[w - 2] + p[w - 1]);
            for ((o, a), b) in f[1..w - 1].iter_mut().zip(&p[..w - 2]).zip(&p[2..]) {
                *o = 0.5 * (b - a);
            }
            let q = &gy[y * w..(y + 1) * w];
            if y == 0 {
                let below = &gy[w..2 * w];
                for ((o, a), b) in f.iter_mut().zip(q).zip(below) {
                    *o += 0.5 * (a + b);
                }
            } else if y + 1 == h {
                let above = &gy[(y - 1) * w..y * w];
                for ((o, a), b) in f.iter_mut().zip(q).zip(above) {
                    *o -= 0.5 * (a + b);
                }
            } else {
                let above = &gy[(y - 1) * w..y * w];
                let below = &gy[(y + 1) * w..(y + 2) * w];
                for ((o, a), b) in f.iter_mut().zip(above).zip(below) {
                    *o += 0.5 * (b - a);
                }
            }
        }
        for row in self.buf.chunks_exact_mut(w) {
            self.rows.process_dct2_with_scratch(row, &mut self.scratch);
        }
        transpose(&self.buf, &mut self.tbuf, w, h);
        for (col, inv) in self.tbuf.chunks_exact_mut(h).zip(self.inv.chunks_exact(h)) {
            self.cols.process_dct2_with_scratch(col, &mut self.scratch);
            for (v, k) in col.iter_mut().zip(inv) {
                *v *= k;
            }
            self.cols.process_dct3_with_scratch(col, &mut self.scratch);
        }
        transpose(&self.tbuf, out, h, w);
        for row in out.chunks_exact_mut(w) {
            self.rows.process_dct3_with_scratch(row, &mut self.scratch);
        }
        true
    }
}

/// `dst` (w rows of h) = transpose of `src` (h rows of w), in 32 x 32 tiles.
fn transpose(src: &[f32], dst: &mut [f32], w: usize, h: usize) {
    const T: usize = 32;
    for y0 in (0..h).step_by(T) {
        for x0 in (0..w).step_by(T) {
            for y in y0..(y0 + T).min(h) {
                for x in x0..(x0 + T).min(w) {
                    dst[x * h + y] = src[y * w + x];
                }
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
