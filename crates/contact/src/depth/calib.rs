//! Calibration from ball presses: find each press's contact circle, then fit the gradient model
//! to the ball's known slopes inside it.
//!
//! The circle: on the prepared difference (`prep`), the colour magnitude that is not common to
//! the three channels, `|d - mean(d)|`, follows the gel's slope (the lights come from three
//! sides); it rises towards the contact edge and falls off outside it (a ball's slope is largest
//! at the edge of the contact). The press is the largest connected region over 5x the frame's
//! median of that magnitude (at least 6 DN); its magnitude-weighted centroid is the centre, and
//! the radius where the mean magnitude over a one-pixel ring around it peaks is the contact
//! radius. Users review a PNG per press and pass corrected circles back (the CLI).
//!
//! The fit: pixels inside 0.9 contact radii take the ball's slope, `-(p - c) / sqrt(R^2 - r^2)`
//! (exact sphere, depth per length), and the gel at rest (no colour change, at every 4th pixel in each
//! direction, once per press) takes zero slope (not the press frame's pixels far from the
//! contact: the skirt still slopes there, and taking it for zero taught the model to shrink
//! small slopes, 5 % too little depth on mock presses); least squares on
//! the normal equations (f64), a ridge of 1e-9 of the trace.

use super::model::{DepthCalibration, DepthError, FEATURES, FORMAT, GradientModel, features};
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
    let (mut cx, mut cy) = (sx / sw, sy / sw);
    for (i, _) in label.iter().enumerate().filter(|(_, l)| **l == best.1) {
        reach = f64::max(reach, ((i % w) as f64 - cx).hypot((i / w) as f64 - cy));
    }
    let mut r = radial_peak(&m, w, h, cx, cy, reach);
    // Refine: the centroid of the magnitude over a quarter of its peak within 1.5 radii, then
    // the ring again (a threshold region left asymmetric by shading or noise moves the first
    // centroid by a pixel or two).
    for _ in 0..3 {
        let lim = 1.5 * r + 2.0;
        let (x0, x1) = (
            (cx - lim).max(0.0) as usize,
            ((cx + lim) as usize + 1).min(w),
        );
        let (y0, y1) = (
            (cy - lim).max(0.0) as usize,
            ((cy + lim) as usize + 1).min(h),
        );
        let mut peak = 0f32;
        for y in y0..y1 {
            for x in x0..x1 {
                peak = peak.max(m[y * w + x]);
            }
        }
        let (mut sw, mut sx, mut sy) = (0f64, 0f64, 0f64);
        for y in y0..y1 {
            for x in x0..x1 {
                let v = m[y * w + x] - 0.25 * peak;
                if v > 0.0 && (x as f64 - cx).hypot(y as f64 - cy) <= lim {
                    sw += f64::from(v);
                    sx += f64::from(v) * x as f64;
                    sy += f64::from(v) * y as f64;
                }
            }
        }
        if sw <= 0.0 {
            break;
        }
        (cx, cy) = (sx / sw, sy / sw);
        r = radial_peak(&m, w, h, cx, cy, lim);
    }
    let c = Circle { x: cx, y: cy, r };
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

/// The radius (sub-pixel) where the mean of `m` over one-pixel rings around (cx, cy) peaks,
/// out to `reach`.
fn radial_peak(m: &[f32], w: usize, h: usize, cx: f64, cy: f64, reach: f64) -> f64 {
    let bins = (reach.ceil() as usize + 2).min(w.max(h));
    let mut sum = vec![0f64; bins];
    let mut cnt = vec![0u32; bins];
    let (x0, x1) = (
        (cx - reach - 2.0).max(0.0) as usize,
        ((cx + reach + 2.0) as usize).min(w),
    );
    let (y0, y1) = (
        (cy - reach - 2.0).max(0.0) as usize,
        ((cy + reach + 2.0) as usize).min(h),
    );
    for y in y0..y1 {
        for x in x0..x1 {
            let b = (x as f64 - cx).hypot(y as f64 - cy).round() as usize;
            if b < bins {
                sum[b] += f64::from(m[y * w + x]);
                cnt[b] += 1;
            }
        }
    }
    let prof: Vec<f64> = sum
        .iter()
        .zip(&cnt)
        .map(|(s, &c)| if c > 0 { s / f64::from(c) } else { 0.0 })
        .collect();
    let (k, _) =
        prof.iter().enumerate().skip(1).fold(
            (1, f64::MIN),
            |acc, (i, &v)| if v > acc.1 { (i, v) } else { acc },
        );
    // Parabolic refinement of the peak.
    if k + 1 < prof.len() {
        let (a, b, c) = (prof[k - 1], prof[k], prof[k + 1]);
        let den = a - 2.0 * b + c;
        if den < 0.0 {
            return k as f64 + (0.5 * (a - c) / den).clamp(-0.5, 0.5);
        }
    }
    k as f64
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

    /// Solve for the model and make the calibration file's contents.
    pub fn finish(
        &self,
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
        let mut a = self.ata;
        let ridge = 1e-9 * a.trace().max(1e-12);
        for i in 0..FEATURES {
            a[(i, i)] += ridge;
        }
        let ch = a.cholesky().ok_or(DepthError::Singular)?;
        let kx = ch.solve(&self.atb[0]);
        let ky = ch.solve(&self.atb[1]);
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
