//! Calibration from ball presses: find each press's contact circle, then fit the gradient model
//! to the ball's known slopes inside it.
//!
//! The circle: on the prepared difference (`prep`), the colour magnitude that is not common to
//! the three channels, `|d - mean(d)|`, follows the gel's slope (the lights come from three
//! sides); it rises towards the contact edge and falls off outside it (a ball's slope is largest
//! at the edge of the contact). The press is the largest connected region over 5x the frame's
//! median of that magnitude (at least 6 DN); from its magnitude-weighted centroid, each of 72
//! rays finds the edge where the magnitude peaks along it, and a circle fitted to those points
//! (outliers dropped, then again from the fitted centre) is the contact circle. Users review a PNG
//! per press and pass corrected circles back (the CLI).
//!
//! The fit: pixels inside 0.9 contact radii take the ball's slope, `-(p - c) / sqrt(R^2 - r^2)`
//! (exact sphere, depth per length), and the gel at rest (no colour change, at every 4th pixel in each
//! direction, once per press) takes zero slope (not the press frame's pixels far from the
//! contact: the skirt still slopes there, and taking it for zero taught the model to shrink
//! small slopes, 5 % too little depth on mock presses); least squares on
//! the normal equations (f64), a ridge of 1e-9 of the trace.

use super::model::{
    DepthCalibration, DepthError, FEATURES, FORMAT, GradientModel, LINEAR_TERMS, features,
};
use super::prep::Prep;
use nalgebra::{SMatrix, SVector};
use unitac_core::{Frame, SensorKind};

/// A contact circle in pixels.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Circle {
    pub x: f64,
    pub y: f64,
    pub r: f64,
}

/// Fewest presses a fit accepts.
pub const MIN_PRESSES: usize = 3;

/// Colour magnitude that is not common to the channels, per pixel.
fn chroma(diff: &[f32]) -> Vec<f32> {
    diff.chunks_exact(3)
        .map(|d| {
            let m = (d[0] + d[1] + d[2]) / 3.0;
            ((d[0] - m).powi(2) + (d[1] - m).powi(2) + (d[2] - m).powi(2)).sqrt()
        })
        .collect()
}

/// Find the contact circle of a press in its prepared difference (module docs); None when no
/// press stands out or it touches the frame's border.
pub fn find_circle(diff: &[f32], w: usize, h: usize) -> Option<Circle> {
    let m = chroma(diff);
    if m.len() != w * h || w < 8 || h < 8 {
        return None;
    }
    let mut sorted = m.clone();
    let mid = sorted.len() / 2;
    let med = *sorted.select_nth_unstable_by(mid, f32::total_cmp).1;
    let thr = (5.0 * med).max(6.0);
    // Largest 4-connected component over the threshold.
    let mut label = vec![0u32; w * h];
    let mut best: (usize, u32) = (0, 0);
    let mut next = 0u32;
    let mut stack = Vec::new();
    for start in 0..w * h {
        if m[start] <= thr || label[start] != 0 {
            continue;
        }
        next += 1;
        label[start] = next;
        stack.push(start);
        let mut n = 0usize;
        while let Some(i) = stack.pop() {
            n += 1;
            for j in crate::grid::neighbours4(i, w, h) {
                if m[j] > thr && label[j] == 0 {
                    label[j] = next;
                    stack.push(j);
                }
            }
        }
        if n > best.0 {
            best = (n, next);
        }
    }
    if best.0 < 12 {
        return None;
    }
    let (mut sw, mut sx, mut sy, mut reach) = (0f64, 0f64, 0f64, 0f64);
    for (i, _) in label.iter().enumerate().filter(|(_, l)| **l == best.1) {
        let wt = f64::from(m[i]);
        sw += wt;
        sx += wt * (i % w) as f64;
        sy += wt * (i / w) as f64;
    }
    let (cx, cy) = (sx / sw, sy / sw);
    for (i, _) in label.iter().enumerate().filter(|(_, l)| **l == best.1) {
        reach = f64::max(reach, ((i % w) as f64 - cx).hypot((i / w) as f64 - cy));
    }
    // The edge: on each ray from the centre, where the magnitude peaks; a circle fitted to those
    // points, outliers rejected, then again from the fitted centre (the component's centroid
    // leans to the lights' side by a pixel or more).
    let lim = (1.5 * reach + 4.0).min(0.5 * w.min(h) as f64);
    let mut c = Circle {
        x: cx,
        y: cy,
        r: 0.0,
    };
    for _ in 0..3 {
        c = ray_circle(&m, w, h, c.x, c.y, lim)?;
    }
    if c.r < 2.0
        || c.x - c.r < 0.0
        || c.y - c.r < 0.0
        || c.x + c.r > w as f64
        || c.y + c.r > h as f64
    {
        return None;
    }
    Some(c)
}

/// Rays from a press's centre along which its edge is sought.
const RAYS: usize = 72;
/// Fewest rays with an edge that make a circle.
const MIN_RAYS: usize = 12;

/// The circle through the points where `m` peaks along each of [`RAYS`] rays from (cx, cy), out to
/// `reach` (a ray's peak at its end or the frame's edge is no edge): least squares (Kasa's
/// algebraic fit), three times, each dropping the points further from the circle than 2 px or
/// 2.5 times the median distance. Per ray, not the mean over rings: the lights make one side of
/// a press brighter than the other, and a ring's mean then peaks inside the edge on the dim side.
fn ray_circle(m: &[f32], w: usize, h: usize, cx: f64, cy: f64, reach: f64) -> Option<Circle> {
    let mut pts: Vec<(f64, f64)> = Vec::with_capacity(RAYS);
    let steps = ((reach - 2.0) / 0.5).max(0.0) as usize;
    let mut ray: Vec<(f32, f64, f64)> = Vec::with_capacity(steps);
    for k in 0..RAYS {
        let t = std::f64::consts::TAU * k as f64 / RAYS as f64;
        ray.clear();
        for s in 0..steps {
            let r = 2.0 + 0.5 * s as f64;
            let (x, y) = (cx + r * t.cos(), cy + r * t.sin());
            let (xi, yi) = (x.round(), y.round());
            if xi < 0.0 || yi < 0.0 || xi >= w as f64 || yi >= h as f64 {
                break;
            }
            ray.push((m[yi as usize * w + xi as usize], x, y));
        }
        let peak = ray
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.0.total_cmp(&b.1.0))
            .map(|(i, p)| (i, p.1, p.2));
        // A peak at the ray's end (its reach or the frame's edge) is no edge.
        if let Some((_, x, y)) = peak.filter(|(i, _, _)| *i + 1 < ray.len() && ray.len() >= 8) {
            pts.push((x, y));
        }
    }
    let mut keep = vec![true; pts.len()];
    let mut c = None;
    for _ in 0..3 {
        let kept: Vec<(f64, f64)> = pts
            .iter()
            .zip(&keep)
            .filter(|(_, k)| **k)
            .map(|(p, _)| *p)
            .collect();
        if kept.len() < MIN_RAYS {
            return None;
        }
        let fit = fit_circle(&kept)?;
        let dist: Vec<f64> = pts
            .iter()
            .map(|p| ((p.0 - fit.x).hypot(p.1 - fit.y) - fit.r).abs())
            .collect();
        let mut kd: Vec<f64> = dist
            .iter()
            .zip(&keep)
            .filter(|(_, k)| **k)
            .map(|(d, _)| *d)
            .collect();
        let mid = kd.len() / 2;
        let med = *kd.select_nth_unstable_by(mid, f64::total_cmp).1;
        let tol = (2.5 * med).max(2.0);
        keep = dist.iter().map(|d| *d < tol).collect();
        c = Some(fit);
    }
    c
}

/// Least-squares circle through `pts` (Kasa: x^2 + y^2 = 2 a x + 2 b y + c, linear in a, b, c);
/// None when they are collinear or the fit is not a circle.
fn fit_circle(pts: &[(f64, f64)]) -> Option<Circle> {
    let mut ata = SMatrix::<f64, 3, 3>::zeros();
    let mut atb = SVector::<f64, 3>::zeros();
    for &(x, y) in pts {
        let row = SVector::<f64, 3>::new(2.0 * x, 2.0 * y, 1.0);
        ata += row * row.transpose();
        atb += row * (x * x + y * y);
    }
    let sol = ata.lu().solve(&atb)?;
    let (a, b) = (sol[0], sol[1]);
    let r2 = sol[2] + a * a + b * b;
    (r2 > 0.0 && r2.is_finite()).then(|| Circle {
        x: a,
        y: b,
        r: r2.sqrt(),
    })
}

/// Which of the model's [`features`] a fit uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Terms {
    /// All of them: colour, its products and position, for one unit's gel and lighting.
    All,
    /// The colour change's three linear terms alone (no offset, products or position): a model
    /// that carries to other units of the kind, a sensor profile's default
    /// (`GradientModel::slope_per_dn`).
    Linear,
}

/// Normal equations of the gradient fit, accumulated press by press.
#[derive(Debug, Clone)]
pub struct Fit {
    ata: SMatrix<f64, FEATURES, FEATURES>,
    atb: [SVector<f64, FEATURES>; 2],
    presses: usize,
    inside: Vec<([f32; FEATURES], [f32; 2])>,
}

impl Default for Fit {
    fn default() -> Self {
        Self {
            ata: SMatrix::zeros(),
            atb: [SVector::zeros(), SVector::zeros()],
            presses: 0,
            inside: Vec::new(),
        }
    }
}

impl Fit {
    fn add(&mut self, f: &[f32; FEATURES], g: [f32; 2]) {
        let v = SVector::<f64, FEATURES>::from_iterator(f.iter().map(|&x| f64::from(x)));
        self.ata += v * v.transpose();
        self.atb[0] += v * f64::from(g[0]);
        self.atb[1] += v * f64::from(g[1]);
    }

    /// Add one press: its prepared difference, its circle, the ball radius \[m] and metres per
    /// pixel.
    pub fn add_press(
        &mut self,
        diff: &[f32],
        w: usize,
        h: usize,
        c: Circle,
        ball_radius_m: f64,
        m_per_px: f64,
    ) {
        let (iw, ih) = (1.0 / w as f32, 1.0 / h as f32);
        let big_r2 = ball_radius_m * ball_radius_m;
        for y in 0..h {
            for x in 0..w {
                let r = (x as f64 - c.x).hypot(y as f64 - c.y);
                if r >= 0.9 * c.r {
                    continue;
                }
                let i = (y * w + x) * 3;
                let f = features(&diff[i..i + 3], x as f32 * iw - 0.5, y as f32 * ih - 0.5);
                let (dx, dy) = ((x as f64 - c.x) * m_per_px, (y as f64 - c.y) * m_per_px);
                // Kept off zero at (1 um)^2, the old (1e-3 mm)^2.
                let z = (big_r2 - dx * dx - dy * dy).max(1e-12).sqrt();
                let g = [(-dx / z) as f32, (-dy / z) as f32];
                self.add(&f, g);
                self.inside.push((f, g));
            }
        }
        // The gel at rest: no colour change, no slope, at every 4th pixel of the frame.
        for y in (0..h).step_by(4) {
            for x in (0..w).step_by(4) {
                let f = features(&[0.0; 3], x as f32 * iw - 0.5, y as f32 * ih - 0.5);
                self.add(&f, [0.0, 0.0]);
            }
        }
        self.presses += 1;
    }

    /// Solve for the model over `terms` and make the calibration file's contents.
    pub fn finish(
        &self,
        terms: Terms,
        sensor: SensorKind,
        serial: &str,
        (width, height): (u32, u32),
        m_per_px: f64,
        ball_radius_m: f64,
    ) -> Result<DepthCalibration, DepthError> {
        if self.presses < MIN_PRESSES {
            return Err(DepthError::TooFewPresses {
                need: MIN_PRESSES,
                got: self.presses,
            });
        }
        // The terms left out of the fit are kept at zero: their rows and columns of the normal
        // equations become the identity's.
        let fitted = |i: usize| terms == Terms::All || LINEAR_TERMS.contains(&i);
        let mut a = self.ata;
        let (mut bx, mut by) = (self.atb[0], self.atb[1]);
        for i in (0..FEATURES).filter(|&i| !fitted(i)) {
            for j in 0..FEATURES {
                a[(i, j)] = 0.0;
                a[(j, i)] = 0.0;
            }
            a[(i, i)] = 1.0;
            bx[i] = 0.0;
            by[i] = 0.0;
        }
        let ridge = 1e-9 * a.trace().max(1e-12);
        for i in 0..FEATURES {
            a[(i, i)] += ridge;
        }
        let ch = a.cholesky().ok_or(DepthError::Singular)?;
        let kx = ch.solve(&bx);
        let ky = ch.solve(&by);
        let model = GradientModel {
            gx: kx.iter().map(|&v| v as f32).collect(),
            gy: ky.iter().map(|&v| v as f32).collect(),
        };
        if !model.gx.iter().chain(&model.gy).all(|v| v.is_finite()) {
            return Err(DepthError::Singular);
        }
        let mut se = 0f64;
        for (f, g) in &self.inside {
            let (p, q) = model.eval(f);
            se += f64::from(p - g[0]).powi(2) + f64::from(q - g[1]).powi(2);
        }
        let rms = (se / (2 * self.inside.len().max(1)) as f64).sqrt();
        Ok(DepthCalibration {
            format: FORMAT,
            sensor,
            serial: serial.to_string(),
            width,
            height,
            m_per_px,
            ball_radius_m,
            presses_used: self.presses as u32,
            fit_rms_slope: rms,
            model,
        })
    }
}

/// Prepare a press frame against the background (sizes must match).
pub fn prepare(prep: &mut Prep, frame: &Frame, background: &Frame) -> Result<(), DepthError> {
    if (frame.width, frame.height) != (background.width, background.height) {
        return Err(DepthError::BackgroundSize {
            w: frame.width,
            h: frame.height,
            bw: background.width,
            bh: background.height,
        });
    }
    prep.run(
        frame.data(),
        background.data(),
        frame.width as usize,
        frame.height as usize,
    );
    Ok(())
}
