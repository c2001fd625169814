//! One frame to depth: prepare, gradients from the model, Poisson integration, zero level,
//! penetration and the contact region.
//!
//! Zero level: the median depth over the frame's outermost two pixels (the gel at rest, where a
//! press's skirt has faded; the Neumann solve leaves the constant free). Penetration: the
//! largest value of the depth's 3 x 3 box mean. Contact region: the connected pixels around that
//! peak whose depth is at least `contact_level` (default 1/2) of the penetration. For a ball on a
//! gel that follows Hertz (`unitac_sim::ballpress`), the surface at the contact edge lies at
//! exactly half the approach, so the half-depth contour is the contact edge; the gel's skirt
//! outside it is deformation, not contact. With a penetration under `min_penetration_m` there
//! is no contact. Depth is in metres throughout.

use super::model::{COLOUR_SCALE, DepthCalibration, DepthError, GradientModel};
use super::poisson::PoissonSolver;
use super::prep::{Prep, RowSink, Shading, box3_rows};
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

/// Slopes per pixel step of a frame (estimate's pass over the pixels): the box mean of the
/// difference row by row (`box3_rows`), the shading taken off and the model applied to each row
/// as it comes, built for baseline x86-64 and for AVX2, taken at run time (no FMA, no reordered
/// sums: the same bytes).
#[multiversion::multiversion(targets("x86_64+avx2"))]
#[allow(clippy::too_many_arguments)]
fn model_pass(
    frame: &[u8],
    background: &[u8],
    rows: &mut Vec<f32>,
    cols: &mut Vec<f32>,
    (w, h): (usize, usize),
    shading: &Shading,
    model: &GradientModel,
    (gx, gy): (&mut [f32], &mut [f32]),
) {
    // Per column: the model's u and the shading's s.
    let iw = 1.0 / w as f32;
    cols.clear();
    cols.extend((0..w).map(|x| x as f32 * iw - 0.5));
    cols.extend((0..w).map(|x| shading.s(x)));
    let (us, ss) = cols.split_at(w);
    let mut sink = ModelRows {
        h,
        us,
        ss,
        shading,
        model,
        gx,
        gy,
    };
    box3_rows(frame, background, rows, w, h, &mut sink);
}

/// The model pass's rows: each prepared row to slopes.
struct ModelRows<'a> {
    h: usize,
    us: &'a [f32],
    ss: &'a [f32],
    shading: &'a Shading,
    model: &'a GradientModel,
    gx: &'a mut [f32],
    gy: &'a mut [f32],
}

impl RowSink for ModelRows<'_> {
    #[inline(always)]
    fn row(&mut self, y: usize, planes: &[f32]) {
        let w = self.us.len();
        let (Some(ox), Some(oy)) = (
            self.gx.get_mut(y * w..(y + 1) * w),
            self.gy.get_mut(y * w..(y + 1) * w),
        ) else {
            return;
        };
        model_row(
            y,
            self.h,
            planes,
            self.us,
            self.ss,
            self.shading,
            self.model,
            ox,
            oy,
        );
    }
}

/// One row of [`model_pass`]: depth change per pixel step [mm] from the row's planes
/// `[R | G | B]`: the model's slopes times mm per pixel (folded into its coefficients at
/// construction), with the colour scale and this row's v folded in here and the shading
/// subtracted per pixel: no feature vector.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn model_row(
    y: usize,
    h: usize,
    planes: &[f32],
    us: &[f32],
    ss: &[f32],
    shading: &Shading,
    model: &GradientModel,
    ox: &mut [f32],
    oy: &mut [f32],
) {
    let w = ox.len();
    if planes.len() < 3 * w || us.len() < w || ss.len() < w || oy.len() < w {
        return;
    }
    let v = y as f32 / h as f32 - 0.5;
    let sh = shading.row(y);
    let kx = RowModel::new(&model.gx, v, COLOUR_SCALE);
    let ky = RowModel::new(&model.gy, v, COLOUR_SCALE);
    let (rs, rest) = planes.split_at(w);
    let (gs, bs) = rest.split_at(w);
    let (gs, bs, us, ss, oy) = (&gs[..w], &bs[..w], &us[..w], &ss[..w], &mut oy[..w]);
    for x in 0..w {
        let s = ss[x];
        let r = rs[x] - (sh[0][0] + sh[0][1] * s + sh[0][2] * s * s);
        let g = gs[x] - (sh[1][0] + sh[1][1] * s + sh[1][2] * s * s);
        let b = bs[x] - (sh[2][0] + sh[2][1] * s + sh[2][2] * s * s);
        ox[x] = kx.eval(us[x], r, g, b);
        oy[x] = ky.eval(us[x], r, g, b);
    }
}

/// Settings of the contact region from depth.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DepthParams {
    /// Share of the penetration at the contact edge.
    pub contact_level: f32,
    /// Shallower presses are no contact \[m].
    pub min_penetration_m: f32,
}

impl Default for DepthParams {
    fn default() -> Self {
        Self {
            contact_level: 0.5,
            min_penetration_m: 3e-5,
        }
    }
}

/// The summary of one frame's depth (the map itself: [`DepthEstimator::depth_m`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DepthSummary {
    /// Deepest penetration \[m].
    pub penetration_m: f32,
    pub contact: bool,
    pub area_px: u32,
    /// Contact area \[m^2].
    pub area_m2: f64,
    /// Centroid of the contact region \[px] (x, y); the peak when there is none.
    pub centroid_px: [f32; 2],
    /// Gel-surface metres per pixel of the frame.
    pub m_per_px: f64,
}

/// Depth per frame against one background, for one calibration.
#[derive(Debug)]
pub struct DepthEstimator {
    cal: DepthCalibration,
    params: DepthParams,
    background: Frame,
    w: usize,
    h: usize,
    m_per_px: f64,
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
    /// One row's 3 x 3 sums (the peak search).
    sums: Vec<f32>,
    /// The model pass's per-column values.
    cols: Vec<f32>,
    step_model: GradientModel,
}

impl DepthEstimator {
    /// For frames of the background's size (any size of the calibration's aspect ratio).
    pub fn new(
        cal: DepthCalibration,
        background: Frame,
        params: DepthParams,
    ) -> Result<Self, DepthError> {
        let m_per_px = cal.m_per_px_at(background.width, background.height)?;
        let (w, h) = (background.width as usize, background.height as usize);
        let step = m_per_px as f32;
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
            m_per_px,
            prep: Prep::default(),
            gx: vec![0.0; w * h],
            gy: vec![0.0; w * h],
            depth: vec![0.0; w * h],
            mask: vec![false; w * h],
            solver: PoissonSolver::new(w, h),
            stack: Vec::new(),
            border: Vec::new(),
            col: Vec::new(),
            sums: Vec::new(),
            cols: Vec::new(),
            step_model,
        })
    }

    pub fn calibration(&self) -> &DepthCalibration {
        &self.cal
    }
    /// The background the depth is measured against.
    pub fn background(&self) -> &Frame {
        &self.background
    }
    /// Take a linear model (`GradientModel::linear`'s slopes per DN) for the next frames
    /// instead of the calibration's (a model fitted on the frame itself, `super::selfcal`).
    pub fn set_linear_model(&mut self, slope_per_dn: [[f32; 3]; 2]) {
        self.cal.model = GradientModel::linear(slope_per_dn);
        let step = self.m_per_px as f32;
        self.step_model = GradientModel {
            gx: self.cal.model.gx.iter().map(|v| v * step).collect(),
            gy: self.cal.model.gy.iter().map(|v| v * step).collect(),
        };
    }
    /// The last frame's depth \[m, positive into the gel], row-major.
    pub fn depth_m(&self) -> &[f32] {
        &self.depth
    }
    /// The last frame's contact region, row-major.
    pub fn mask(&self) -> &[bool] {
        &self.mask
    }
    /// The last frame's depth change per pixel step (x, y) \[m].
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
        let (fr, bg) = (frame.data(), self.background.data());
        let shading = self.prep.shading(fr, bg, w, h);
        model_pass(
            fr,
            bg,
            self.prep.rows(),
            &mut self.cols,
            (w, h),
            &shading,
            &self.step_model,
            (&mut self.gx, &mut self.gy),
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
        let (col, sums) = (&mut self.col, &mut self.sums);
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
            // The row's sums, then its largest (branch-free: it vectorises), and only where
            // that beats the best so far, the first pixel that holds it: the first largest in
            // scan order, as a scan pixel by pixel would find.
            let n = w.saturating_sub(2);
            sums.resize(n, 0.0);
            if n == 0 {
                continue;
            }
            for (((o, l), m), r) in sums.iter_mut().zip(&col[..n]).zip(&col[1..]).zip(&col[2..]) {
                *o = l + m + r;
            }
            let top = row_max(sums);
            if top > best {
                best = top;
                let x = sums.iter().position(|&s| s == top).unwrap_or(0);
                at = y * w + x + 1;
            }
        }
        let pen = (best / 9.0).max(0.0);
        self.mask.iter_mut().for_each(|m| *m = false);
        let mut summary = DepthSummary {
            penetration_m: pen,
            contact: false,
            area_px: 0,
            area_m2: 0.0,
            centroid_px: [(at % w.max(1)) as f32, (at / w.max(1)) as f32],
            m_per_px: self.m_per_px,
        };
        if pen < self.params.min_penetration_m {
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
        summary.area_m2 = n as f64 * summary.m_per_px * summary.m_per_px;
        summary.centroid_px = [(sx / nf) as f32, (sy / nf) as f32];
        summary
    }
}

/// The largest value of `v` (`f32::MIN` if empty; NaN never counts), in eight lanes so that it
/// vectorises.
fn row_max(v: &[f32]) -> f32 {
    let mut lanes = [f32::MIN; 8];
    let chunks = v.chunks_exact(8);
    let tail = chunks.remainder();
    for c in chunks {
        for (m, &s) in lanes.iter_mut().zip(c) {
            if s > *m {
                *m = s;
            }
        }
    }
    lanes
        .iter()
        .chain(tail)
        .fold(f32::MIN, |a, &s| if s > a { s } else { a })
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
