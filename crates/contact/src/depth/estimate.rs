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

use super::model::{DepthCalibration, DepthError, GradientModel, features};
use super::poisson::PoissonSolver;
use super::prep::Prep;
use unitac_core::Frame;

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
        self.prep.run(frame.data(), self.background.data(), w, h);
        let (iw, ih) = (1.0 / w as f32, 1.0 / h as f32);
        // Depth change per pixel step [mm]: the model's slopes times mm per pixel (folded into
        // the coefficients at construction).
        let model = &self.step_model;
        for y in 0..h {
            let v = y as f32 * ih - 0.5;
            let row = &self.prep.diff[y * w * 3..(y + 1) * w * 3];
            let (ox, oy) = (
                &mut self.gx[y * w..(y + 1) * w],
                &mut self.gy[y * w..(y + 1) * w],
            );
            for (x, ((d, p), q)) in row.chunks_exact(3).zip(ox).zip(oy).enumerate() {
                (*p, *q) = model.eval(&features(d, x as f32 * iw - 0.5, v));
            }
        }
        self.solver.solve(&self.gx, &self.gy, &mut self.depth);
        let mut px = std::mem::take(&mut self.border);
        // Zero level: median of the two outermost rings.
        px.clear();
        for y in 0..h {
            for x in 0..w {
                if x < 2 || y < 2 || x + 2 >= w || y + 2 >= h {
                    px.push(self.depth[y * w + x]);
                }
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
        let (mut best, mut at) = (f32::MIN, 0usize);
        for y in 1..h.saturating_sub(1) {
            for x in 1..w.saturating_sub(1) {
                let mut s = 0.0;
                for yy in y - 1..=y + 1 {
                    let r = &d[yy * w + x - 1..yy * w + x + 2];
                    s += r[0] + r[1] + r[2];
                }
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
            let mut visit = |j: usize| {
                if !self.mask[j] && d[j] >= level {
                    self.mask[j] = true;
                    self.stack.push(j);
                }
            };
            if x > 0 {
                visit(i - 1);
            }
            if x + 1 < w {
                visit(i + 1);
            }
            if y > 0 {
                visit(i - w);
            }
            if y + 1 < h {
                visit(i + w);
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
