//! One frame to depth: prepare, gradients from the model, Poisson integration, zero level,
//! penetration and the contact region.
//!
//! Zero level: the median depth over the frame's outermost two pixels (the gel at rest, where a
//! press's skirt has faded; the Neumann solve leaves the constant free). Penetration: the
//! largest value of the depth's 3 x 3 box mean. Contact region: the connected pixels around that
//! peak whose depth is at least `contact_level` (default 1/2) of the penetration. For a ball on a
//! gel that follows Hertz (`unitac_sim::ballpress`), the surface at the contact edge lies at
//! exactly half the approach, so the half-depth contour is the contact edge; the gel's skirt
//! outside it is deformation, not contact. With a penetration under `min_penetration_mm` there
//! is no contact.

use super::model::{COLOUR_SCALE, DepthCalibration, DepthError, GradientModel};
use super::poisson::PoissonSolver;
use super::prep::{Prep, Shading};
use unitac_core::Frame;

/// One output of the gradient model for one row (`model::features` with v fixed and the colour
/// scale folded into the coefficients): the same sum, in the same terms, as `GradientModel::eval`.
#[derive(Debug, Clone, Copy)]
struct RowModel {
    c0: f32,
    cu: f32,
    lin: [f32; 3],
    lin_u: [f32; 3],
    quad: [f32; 6],
}

impl RowModel {
    fn new(k: &[f32], v: f32, s: f32) -> Self {
        let k = |i: usize| k.get(i).copied().unwrap_or(0.0);
        let s2 = s * s;
        Self {
            c0: k(0) + k(11) * v,
            cu: k(10),
            lin: [
                (k(1) + k(15) * v) * s,
                (k(2) + k(16) * v) * s,
                (k(3) + k(17) * v) * s,
            ],
            lin_u: [k(12) * s, k(13) * s, k(14) * s],
            quad: [
                k(4) * s2,
                k(5) * s2,
                k(6) * s2,
                k(7) * s2,
                k(8) * s2,
                k(9) * s2,
            ],
        }
    }

    #[inline]
    fn eval(&self, u: f32, r: f32, g: f32, b: f32) -> f32 {
        let q = &self.quad;
        self.c0
            + self.cu * u
            + (self.lin[0] + self.lin_u[0] * u) * r
            + (self.lin[1] + self.lin_u[1] * u) * g
            + (self.lin[2] + self.lin_u[2] * u) * b
            + q[0] * r * r
            + q[1] * g * g
            + q[2] * b * b
            + q[3] * r * g
            + q[4] * r * b
            + q[5] * g * b
    }
}

/// Slopes per pixel step from the prepared difference (estimate's second pass), built for
/// baseline x86-64 and for AVX2, taken at run time (no FMA, no reordered sums: the same bytes).
#[multiversion::multiversion(targets("x86_64+avx2"))]
fn model_pass(
    diff: &[f32],
    w: usize,
    h: usize,
    shading: &Shading,
    model: &GradientModel,
    gx: &mut [f32],
    gy: &mut [f32],
) {
    // Depth change per pixel step [mm]: the model's slopes times mm per pixel (folded into
    // its coefficients at construction), with the colour scale and this row's v folded in
    // here and the shading subtracted per pixel: one pass, no feature vector.
    let iw = 1.0 / w as f32;
    let cs = COLOUR_SCALE;
    for y in 0..h {
        let v = y as f32 / h as f32 - 0.5;
        let sh = shading.row(y);
        let kx = RowModel::new(&model.gx, v, cs);
        let ky = RowModel::new(&model.gy, v, cs);
        let row = &diff[y * w * 3..(y + 1) * w * 3];
        let (ox, oy) = (&mut gx[y * w..(y + 1) * w], &mut gy[y * w..(y + 1) * w]);
        // Blocks of 32 pixels, de-interleaved into arrays, so that the arithmetic
        // vectorises (the per-pixel loop over RGB triples did not).
        const B: usize = 32;
        let mut x0 = 0;
        for ((d, p), q) in row
            .chunks(3 * B)
            .zip(ox.chunks_mut(B))
            .zip(oy.chunks_mut(B))
        {
            let n = p.len();
            let (mut r, mut g, mut b, mut u) = ([0f32; B], [0f32; B], [0f32; B], [0f32; B]);
            for (k, px) in d.chunks_exact(3).enumerate().take(B) {
                r[k] = px[0];
                g[k] = px[1];
                b[k] = px[2];
                u[k] = (x0 + k) as f32;
            }
            for k in 0..B {
                let x = u[k];
                let s = (x - shading.cx()) * shading.inv();
                r[k] -= sh[0][0] + sh[0][1] * s + sh[0][2] * s * s;
                g[k] -= sh[1][0] + sh[1][1] * s + sh[1][2] * s * s;
                b[k] -= sh[2][0] + sh[2][1] * s + sh[2][2] * s * s;
                u[k] = x * iw - 0.5;
            }
            let (mut pa, mut qa) = ([0f32; B], [0f32; B]);
            for k in 0..B {
                pa[k] = kx.eval(u[k], r[k], g[k], b[k]);
                qa[k] = ky.eval(u[k], r[k], g[k], b[k]);
            }
            p.copy_from_slice(&pa[..n]);
            q.copy_from_slice(&qa[..n]);
            x0 += n;
        }
    }
}

/// Settings of the contact region from depth.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DepthParams {
    /// Share of the penetration at the contact edge.
    pub contact_level: f32,
    /// Shallower presses are no contact \[mm].
    pub min_penetration_mm: f32,
}

impl Default for DepthParams {
    fn default() -> Self {
        Self {
            contact_level: 0.5,
            min_penetration_mm: 0.03,
        }
    }
}

/// The summary of one frame's depth (the map itself: [`DepthEstimator::depth_mm`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DepthSummary {
    pub penetration_mm: f32,
    pub contact: bool,
    pub area_px: u32,
    pub area_mm2: f64,
    /// Centroid of the contact region \[px] (x, y); the peak when there is none.
    pub centroid_px: [f32; 2],
    pub mm_per_px: f64,
}

/// Depth per frame against one background, for one calibration.
#[derive(Debug)]
pub struct DepthEstimator {
    cal: DepthCalibration,
    params: DepthParams,
    background: Frame,
    w: usize,
    h: usize,
    mm_per_px: f64,
    prep: Prep,
    gx: Vec<f32>,
    gy: Vec<f32>,
    depth: Vec<f32>,
    mask: Vec<bool>,
    solver: PoissonSolver,
    stack: Vec<usize>,
    border: Vec<f32>,
    /// Column sums of three rows (the peak search), kept between frames.
    col: Vec<f32>,
    step_model: GradientModel,
}

impl DepthEstimator {
    /// For frames of the background's size (any size of the calibration's aspect ratio).
    pub fn new(
        cal: DepthCalibration,
        background: Frame,
        params: DepthParams,
    ) -> Result<Self, DepthError> {
        let mm_per_px = cal.mm_per_px_at(background.width, background.height)?;
        let (w, h) = (background.width as usize, background.height as usize);
        let step = mm_per_px as f32;
        let step_model = GradientModel {
            gx: cal.model.gx.iter().map(|v| v * step).collect(),
            gy: cal.model.gy.iter().map(|v| v * step).collect(),
        };
        Ok(Self {
            cal,
            params,
            background,
            w,
            h,
            mm_per_px,
            prep: Prep::default(),
            gx: vec![0.0; w * h],
            gy: vec![0.0; w * h],
            depth: vec![0.0; w * h],
            mask: vec![false; w * h],
            solver: PoissonSolver::new(w, h),
            stack: Vec::new(),
            border: Vec::new(),
            col: Vec::new(),
            step_model,
        })
    }

    pub fn calibration(&self) -> &DepthCalibration {
        &self.cal
    }
    /// The last frame's depth \[mm, positive into the gel], row-major.
    pub fn depth_mm(&self) -> &[f32] {
        &self.depth
    }
    /// The last frame's contact region, row-major.
    pub fn mask(&self) -> &[bool] {
        &self.mask
    }
    /// The last frame's depth change per pixel step (x, y) \[mm].
    pub fn gradients(&self) -> (&[f32], &[f32]) {
        (&self.gx, &self.gy)
    }
    pub fn size(&self) -> (usize, usize) {
        (self.w, self.h)
    }

    /// Depth of one frame; a frame of another size than the background's is an error.
    pub fn estimate(&mut self, frame: &Frame) -> Result<DepthSummary, DepthError> {
        let (w, h) = (self.w, self.h);
        if (frame.width as usize, frame.height as usize) != (w, h) {
            return Err(DepthError::BackgroundSize {
                w: frame.width,
                h: frame.height,
                bw: self.background.width,
                bh: self.background.height,
            });
        }
        let shading = self
            .prep
            .run_unsubtracted(frame.data(), self.background.data(), w, h);
        model_pass(
            &self.prep.diff,
            w,
            h,
            &shading,
            &self.step_model,
            &mut self.gx,
            &mut self.gy,
        );
        self.solver.solve(&self.gx, &self.gy, &mut self.depth);
        let mut px = std::mem::take(&mut self.border);
        // Zero level: median of the two outermost rings.
        px.clear();
        for (y, row) in self.depth.chunks_exact(w).enumerate() {
            if y < 2 || y + 2 >= h || w <= 4 {
                px.extend_from_slice(row);
            } else {
                px.extend_from_slice(&row[..2]);
                px.extend_from_slice(&row[w - 2..]);
            }
        }
        let mid = px.len() / 2;
        let zero = if px.is_empty() {
            0.0
        } else {
            *px.select_nth_unstable_by(mid, f32::total_cmp).1
        };
        self.border = px;
        for v in &mut self.depth {
            *v -= zero;
        }
        Ok(self.region())
    }

    /// Penetration and the contact region of the current depth map.
    fn region(&mut self) -> DepthSummary {
        let (w, h) = (self.w, self.h);
        let d = &self.depth;
        // The largest 3 x 3 sum: column sums of three rows, then three of those per pixel.
        let (mut best, mut at) = (f32::MIN, 0usize);
        let col = &mut self.col;
        col.resize(w, 0.0);
        for y in 1..h.saturating_sub(1) {
            let (a, b, c) = (
                &d[(y - 1) * w..y * w],
                &d[y * w..(y + 1) * w],
                &d[(y + 1) * w..(y + 2) * w],
            );
            for (((o, p), q), r) in col.iter_mut().zip(a).zip(b).zip(c) {
                *o = p + q + r;
            }
            for x in 1..w.saturating_sub(1) {
                let s = col[x - 1] + col[x] + col[x + 1];
                if s > best {
                    best = s;
                    at = y * w + x;
                }
            }
        }
        let pen = (best / 9.0).max(0.0);
        self.mask.iter_mut().for_each(|m| *m = false);
        let mut summary = DepthSummary {
            penetration_mm: pen,
            contact: false,
            area_px: 0,
            area_mm2: 0.0,
            centroid_px: [(at % w.max(1)) as f32, (at / w.max(1)) as f32],
            mm_per_px: self.mm_per_px,
        };
        if pen < self.params.min_penetration_mm {
            return summary;
        }
        let level = self.params.contact_level * pen;
        self.stack.clear();
        self.stack.push(at);
        self.mask[at] = true;
        let (mut n, mut sx, mut sy) = (0u64, 0f64, 0f64);
        while let Some(i) = self.stack.pop() {
            n += 1;
            let (x, y) = (i % w, i / w);
            sx += x as f64;
            sy += y as f64;
            for j in crate::grid::neighbours4(i, w, h) {
                if !self.mask[j] && d[j] >= level {
                    self.mask[j] = true;
                    self.stack.push(j);
                }
            }
        }
        let nf = n.max(1) as f64;
        summary.contact = true;
        summary.area_px = n as u32;
        summary.area_mm2 = n as f64 * self.mm_per_px * self.mm_per_px;
        summary.centroid_px = [(sx / nf) as f32, (sy / nf) as f32];
        summary
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::depth::model::features;

    #[test]
    fn the_row_model_is_the_feature_model() {
        let k: Vec<f32> = (0..18)
            .map(|i| ((i * 37 % 11) as f32 - 5.0) * 0.013)
            .collect();
        let m = GradientModel {
            gx: k.clone(),
            gy: k.iter().rev().copied().collect(),
        };
        for (u, v, d) in [
            (-0.5f32, -0.5f32, [3.0f32, -7.0, 12.0]),
            (0.2, 0.1, [40.0, 0.5, -22.0]),
            (0.49, 0.3, [0.0, 0.0, 0.0]),
        ] {
            let (a, b) = m.eval(&features(&d, u, v));
            let rx = RowModel::new(&m.gx, v, COLOUR_SCALE).eval(u, d[0], d[1], d[2]);
            let ry = RowModel::new(&m.gy, v, COLOUR_SCALE).eval(u, d[0], d[1], d[2]);
            assert!(
                (a - rx).abs() < 1e-5 && (b - ry).abs() < 1e-5,
                "{a} {rx} {b} {ry}"
            );
        }
    }
}
