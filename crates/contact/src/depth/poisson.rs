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
//! N), no iteration; the result is mean-free (the caller chooses the zero level). Transforms are
//! rustdct's (planned once per size, f32).

use rustdct::{DctPlanner, TransformType2And3};
use std::sync::Arc;

/// A planned solver for one frame size.
pub struct PoissonSolver {
    w: usize,
    h: usize,
    rows: Arc<dyn TransformType2And3<f32>>,
    /// Reciprocal pivots of the elimination, row-major h x w: `rec[y * w + k]` for the system of
    /// row frequency k (k = 0 unused).
    rec: Vec<f32>,
    /// Column k = 0 of the transformed divergence, kept for its running-sum solve.
    col0: Vec<f32>,
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
        let scratch_len = rows.get_scratch_len();
        Self {
            w,
            h,
            rows,
            rec,
            col0: vec![0.0; h],
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
            self.rows.process_dct2_with_scratch(f, &mut self.scratch);
        }
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
            self.rows.process_dct3_with_scratch(row, &mut self.scratch);
        }
        true
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
        let (w, h) = (320usize, 240usize);
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
