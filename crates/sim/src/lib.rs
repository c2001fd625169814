//! Mock tactile sensor: deterministic RGB frames of presses on objects, with ground truth.
//!
//! The renderer is a small photometric model of a gel sensor: an indenter height map (sphere cap
//! plus a surface texture), its gradients lit by three coloured lights from different directions
//! (as in GelSight-style sensors), a vignetted background, and per-pixel noise of about 1 DN.
//! Frames are a pure function of (scenario, sensor, seed, frame index), so the same seed gives the
//! same bytes. [`MockSensor`] implements the runtime's `Source`.

pub mod bench;
pub mod degrade;
pub mod numerics;
mod object;
pub mod plot;
mod rng;
mod scenario;
pub mod world;

pub use object::{BUMP_ASPECT, FLAT_FILLET, Object, Shape};
pub use rng::{GaussianTable, NoiseStream, SplitMix64, normal_quantile, quantise_f32};
pub use scenario::{Phase, Scenario, ScenarioError};
pub use world::{
    Command, Cup, Gel, GripSample, Gripper, Method, Substep, World, WorldConfig, WorldError,
    WorldTruth,
};

use unitac_core::{Frame, SensorKind, SensorSpec, Source, SourceError, Stamp};

/// Capture time of frame 0: a fixed ROS time so runs are reproducible (2023-11-14T22:13:20Z).
pub const EPOCH: Stamp = Stamp(1_700_000_000_000_000_000);

/// What the world knew when a frame was rendered.
#[derive(Debug, Clone, PartialEq)]
pub struct GroundTruth {
    /// Indenter penetration into the gel [mm] (0 = not touching).
    pub penetration_mm: f64,
    /// Label of the object being touched ("" when none).
    pub label: String,
    /// Pixels where the indenter touches the gel (height > 0), in output pixels.
    pub contact_px: u32,
    /// Row-major mask of those pixels (width x height of the frame).
    pub mask: Vec<bool>,
    /// Global illumination gain applied to this frame (drift, exposure steps).
    pub gain: f64,
    /// Grip force per finger [N] when the world drives the scenario (0 otherwise).
    pub force_n: f64,
    /// Cup deformation (loss of diameter) [mm] when the world drives the scenario (0 otherwise).
    pub deformation_mm: f64,
}

/// Slow illumination changes of a real sensor: LED warm-up, slow wander, exposure steps.
/// The frame is multiplied by `gain(t)`.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Drift {
    /// Relative gain at t = 0 that decays away (LED warm-up), e.g. -0.08.
    pub warmup: f64,
    /// Warm-up time constant [s].
    pub warmup_tau_s: f64,
    /// Relative amplitude of a slow sinusoidal wander, e.g. 0.01.
    pub wander: f64,
    /// Wander period [s].
    pub wander_period_s: f64,
    /// Exposure steps: from time t [s] on, multiply by gain.
    pub steps: Vec<(f64, f64)>,
}

impl Drift {
    /// A realistic mix: 8 % warm-up over ~90 s plus 1 % wander with a 47 s period.
    pub fn warmup() -> Self {
        Self {
            warmup: -0.08,
            warmup_tau_s: 90.0,
            wander: 0.01,
            wander_period_s: 47.0,
            steps: Vec::new(),
        }
    }
    pub fn gain(&self, t: f64) -> f64 {
        let mut g = 1.0;
        if self.warmup != 0.0 && self.warmup_tau_s > 0.0 {
            g *= 1.0 + self.warmup * (-t / self.warmup_tau_s).exp();
        }
        if self.wander != 0.0 && self.wander_period_s > 0.0 {
            g *= 1.0 + self.wander * (std::f64::consts::TAU * t / self.wander_period_s).sin();
        }
        for &(ts, gs) in &self.steps {
            if t >= ts {
                g *= gs;
            }
        }
        g
    }
}

/// Mock sensor settings.
#[derive(Debug, Clone, PartialEq)]
pub struct MockConfig {
    pub sensor: SensorKind,
    pub sensor_id: String,
    pub fps: f64,
    pub seed: u64,
    /// Per-pixel noise sigma [DN].
    pub noise_dn: f64,
    pub drift: Drift,
    /// Black marker dots on the gel that move with it (GelSight Mini has them; DIGIT does not).
    pub markers: bool,
}

impl MockConfig {
    pub fn new(sensor: SensorKind, seed: u64) -> Self {
        Self {
            sensor,
            sensor_id: format!("mock_{}", sensor.as_str().replace('-', "_")),
            fps: sensor.spec().fps,
            seed,
            noise_dn: 1.0,
            drift: Drift::default(),
            markers: sensor == SensorKind::GelsightMini,
        }
    }
}

/// Marker grid: spacing and dot radius in output pixels, darkening factor inside a dot.
const MARKER_SPACING: f64 = 24.0;
const MARKER_RADIUS: f64 = 2.6;
const MARKER_DARK: f64 = 0.35;
/// Lateral marker displacement per mm of local gel depression [px/mm].
const MARKER_SHIFT_PX_PER_MM: f64 = 6.0;

/// Deterministic renderer of a scenario.
#[derive(Debug)]
pub struct MockSensor {
    cfg: MockConfig,
    spec: SensorSpec,
    scenario: Scenario,
    background: Vec<f32>,
    /// Background times the marker dots at rest.
    base: Vec<f32>,
    /// Per-pixel noise, sigma = noise_dn.
    noise: GaussianTable,
    index: u64,
    total: u64,
}

impl MockSensor {
    pub fn new(cfg: MockConfig, scenario: Scenario) -> Self {
        let spec = cfg.sensor.spec();
        Self::with_spec(cfg, spec, scenario)
    }

    /// A mock sensor with its own output size (e.g. DIGIT's VGA mode, 640x480 at 0.02 mm/px).
    /// The spec's size must be within `unitac_core::frame::MAX_SIDE`.
    pub fn with_spec(cfg: MockConfig, spec: SensorSpec, scenario: Scenario) -> Self {
        let total = (scenario.duration_s() * cfg.fps).floor() as u64;
        let background = render_background(&spec);
        let base = render_base(&spec, &background, cfg.markers);
        let noise = GaussianTable::new(cfg.noise_dn);
        Self {
            cfg,
            spec,
            scenario,
            background,
            base,
            noise,
            index: 0,
            total,
        }
    }

    pub fn spec(&self) -> &SensorSpec {
        &self.spec
    }
    pub fn config(&self) -> &MockConfig {
        &self.cfg
    }
    pub fn scenario(&self) -> &Scenario {
        &self.scenario
    }
    pub fn frame_count(&self) -> u64 {
        self.total
    }

    /// Render frame `index` (independent of what was rendered before).
    pub fn render(&self, index: u64) -> (Frame, GroundTruth) {
        let t = index as f64 / self.cfg.fps;
        let (approach, obj) = self.scenario.at(t);
        let grip = self.scenario.grip_at(t);
        let (w, h) = (self.spec.width as usize, self.spec.height as usize);
        let mut rng = self.noise.stream(SplitMix64::new(
            self.cfg.seed ^ index.wrapping_mul(0x9E37_79B9_7F4A_7C15),
        ));
        let gain = self.cfg.drift.gain(t);
        let mut data = vec![0u8; w * h * 3];
        let mut mask = vec![false; w * h];
        let mut contact_px = 0u32;
        let touching = obj.filter(|_| approach > 0.0);
        let depth = touching.map_or(0.0, |o| o.gel_depth(approach));
        let press = touching.map(|o| Press::new(o, depth, &self.spec, w, h));
        // Rows and columns the press can change (contact, skirt, dragged markers); everything
        // else is the lit background times the gain, plus noise.
        let (x0, x1, y0, y1) = press.as_ref().map_or((0, 0, 0, 0), |p| p.bbox);
        let g = gain as f32;
        let mut noise = vec![0f32; w * 3];
        for (y, ((out, base), bg)) in data
            .chunks_exact_mut(w * 3)
            .zip(self.base.chunks_exact(w * 3))
            .zip(self.background.chunks_exact(w * 3))
            .enumerate()
        {
            // This row's noise, in raster order.
            rng.fill(&mut noise);
            let pressed = match &press {
                Some(p) if y >= y0 && y < y1 => Some(p),
                _ => None,
            };
            let Some(p) = pressed else {
                quantise_row(out, base, &noise, g);
                continue;
            };
            let (a, b) = (x0 * 3, x1 * 3);
            quantise_row(&mut out[..a], &base[..a], &noise[..a], g);
            quantise_row(&mut out[b..], &base[b..], &noise[b..], g);
            let row_trig = p.row_trig(y);
            let mask_row = &mut mask[y * w + x0..y * w + x1];
            for (xi, ((((o, bs), bk), n), m)) in out[a..b]
                .chunks_exact_mut(3)
                .zip(base[a..b].chunks_exact(3))
                .zip(bg[a..b].chunks_exact(3))
                .zip(noise[a..b].chunks_exact(3))
                .zip(mask_row.iter_mut())
                .enumerate()
            {
                let Some(px) = p.pixel(x0 + xi, y, row_trig, self.cfg.markers) else {
                    // At rest: the background path.
                    quantise_row(o, bs, n, g);
                    continue;
                };
                if px.in_contact {
                    *m = true;
                    contact_px += 1;
                }
                let dg = (px.dark * gain) as f32;
                for c in 0..3 {
                    o[c] = quantise_f32((bk[c] + px.shade[c] as f32) * dg + n[c]);
                }
            }
        }
        let stamp = EPOCH.saturating_add_nanos((index as f64 * 1e9 / self.cfg.fps).round() as i64);
        let frame = Frame::new(
            &self.cfg.sensor_id,
            index,
            stamp,
            self.spec.width,
            self.spec.height,
            data,
        );
        // The size comes from our own spec, which is within bounds.
        let frame = frame.unwrap_or_else(|_| unreachable_frame(&self.cfg.sensor_id));
        let truth = GroundTruth {
            penetration_mm: depth.max(0.0),
            label: obj.map(|o| o.label.clone()).unwrap_or_default(),
            contact_px,
            mask,
            gain,
            force_n: grip.map_or(0.0, |g| g.force_n),
            deformation_mm: grip.map_or(0.0, |g| g.deformation_mm),
        };
        (frame, truth)
    }

    /// Next frame with its ground truth, or None at the end of the scenario.
    pub fn next_with_truth(&mut self) -> Option<(Frame, GroundTruth)> {
        if self.index >= self.total {
            return None;
        }
        let out = self.render(self.index);
        self.index += 1;
        Some(out)
    }
}

/// `out = quantise(base * gain + noise)`, element-wise (vectorises).
#[inline]
fn quantise_row(out: &mut [u8], base: &[f32], noise: &[f32], gain: f32) {
    for ((o, &b), &n) in out.iter_mut().zip(base).zip(noise) {
        *o = quantise_f32(b * gain + n);
    }
}

/// Darkening factor of the marker dots at (sx, y) [px] (1 = no marker).
fn marker_dark(sx: f64, sy: f64) -> f64 {
    let mx = floor(sx / MARKER_SPACING) * MARKER_SPACING + MARKER_SPACING * 0.5;
    let my = floor(sy / MARKER_SPACING) * MARKER_SPACING + MARKER_SPACING * 0.5;
    let d2 = (sx - mx) * (sx - mx) + (sy - my) * (sy - my);
    let reach = MARKER_RADIUS + 1.0;
    if d2 < reach * reach {
        let edge = (reach - d2.sqrt()).clamp(0.0, 1.0);
        1.0 - (1.0 - MARKER_DARK) * edge
    } else {
        1.0
    }
}

/// floor() without a libm call (baseline x86-64 has no rounding instruction); exact for
/// |x| < 2^52.
#[inline]
fn floor(x: f64) -> f64 {
    let t = x as i64 as f64;
    if t > x { t - 1.0 } else { t }
}

/// The lights' directions in the image plane (GelSight-style R, G, B from 120 degrees apart).
const LIGHTS: [[f64; 2]; 3] = [[1.0, 0.0], [-0.5, 0.866], [-0.5, -0.866]];
/// DN per unit slope of the gel surface.
const SHADE_GAIN: f64 = 90.0;
/// DN per mm of depression (the pressed gel is a little darker).
const DEPTH_DARK: f64 = 25.0;

/// What one pixel of a pressed gel looks like before the background and noise.
struct PressPixel {
    in_contact: bool,
    /// Added to the background per channel [DN].
    shade: [f64; 3],
    /// Marker darkening.
    dark: f64,
}

/// One object pressed `depth` mm into the gel at the image centre, in pixel terms.
struct Press<'a> {
    obj: &'a Object,
    depth: f64,
    px_per_mm: f64,
    cx: f64,
    cy: f64,
    /// Contact half-width [px] (radius; half the band for an edge).
    a_px: f64,
    /// Width of the skirt outside the contact where the gel slopes back to rest [px].
    skirt_px: f64,
    /// Pixel box [x0, x1) x [y0, y1) outside which the gel is at rest.
    bbox: (usize, usize, usize, usize),
    /// Texture wave: k [1/mm], and (sin, cos) of k x per column of the box.
    k: f64,
    cols: Vec<(f64, f64)>,
    /// Precomputed reciprocals: mm per px, 1 / effective radius [1/mm], 1 / skirt [1/px].
    mm_per_px: f64,
    inv_r: f64,
    inv_skirt: f64,
    /// Outer radius of the deformed area [px].
    outer_px: f64,
}

impl<'a> Press<'a> {
    fn new(obj: &'a Object, depth: f64, spec: &SensorSpec, w: usize, h: usize) -> Self {
        let px_per_mm = 1.0 / spec.mm_per_px;
        let a_px = obj.contact_half_width_mm(depth) * px_per_mm;
        let mut p = Self {
            obj,
            depth,
            px_per_mm,
            cx: spec.width as f64 * 0.5,
            cy: spec.height as f64 * 0.5,
            a_px,
            // The gel deforms a little past the contact: 60 % of the contact size plus 4 px.
            skirt_px: a_px * 0.6 + 4.0,
            bbox: (0, 0, 0, 0),
            k: std::f64::consts::TAU / obj.period_mm,
            cols: Vec::new(),
            mm_per_px: spec.mm_per_px,
            inv_r: 1.0 / obj.effective_radius_mm(),
            inv_skirt: 1.0 / (a_px * 0.6 + 4.0),
            outer_px: a_px * 1.6 + 4.0,
        };
        p.bbox = p.find_bbox(w, h);
        let (x0, x1, _, _) = p.bbox;
        p.cols = (x0..x1)
            .map(|x| (p.k * x as f64 / px_per_mm).sin_cos())
            .collect();
        p
    }

    /// (sin, cos) of the texture's row phase at row y.
    fn row_trig(&self, y: usize) -> (f64, f64) {
        (self.k * (y as f64 / self.px_per_mm) * 0.8 + 0.5).sin_cos()
    }

    /// Pixel box [x0, x1) x [y0, y1) outside which the gel is at rest.
    fn find_bbox(&self, w: usize, h: usize) -> (usize, usize, usize, usize) {
        // Reach of the deformation plus the farthest a marker dot can be dragged into view.
        // Beyond the skirt the gel is at rest (markers are sampled at the pixel, so a dragged
        // dot never shows outside the deformed area).
        let reach = self.a_px + self.skirt_px + 2.0;
        let span = |c: f64, n: usize| {
            let lo = (c - reach).floor().max(0.0) as usize;
            let hi = ((c + reach).ceil().max(0.0) as usize).min(n);
            (lo.min(n), hi)
        };
        let (x0, x1) = span(self.cx, w);
        let (y0, y1) = match self.obj.shape {
            Shape::Edge => (0, h),
            _ => span(self.cy, h),
        };
        (x0, x1, y0, y1)
    }

    /// The pressed gel at pixel (x, y); None where it is at rest.
    fn pixel(&self, x: usize, y: usize, (sy, cy): (f64, f64), markers: bool) -> Option<PressPixel> {
        let o = self.obj;
        let (dxp, dyp) = (x as f64 - self.cx, y as f64 - self.cy);
        // Distance outside the contact boundary [px] and the outward direction.
        let (r, nx, ny) = match o.shape {
            Shape::Edge => (dxp.abs(), dxp.signum(), 0.0),
            _ => {
                let r2 = dxp * dxp + dyp * dyp;
                if r2 >= self.outer_px * self.outer_px {
                    return None;
                }
                let r = r2.sqrt();
                // The outward direction (skirt slope, marker drag), normalised below if used.
                (r, dxp, dyp)
            }
        };
        if r >= self.outer_px {
            return None;
        }
        let unit = || -> (f64, f64) {
            match o.shape {
                Shape::Edge => (nx, ny),
                _ if r > 0.0 => (nx / r, ny / r),
                _ => (0.0, 0.0),
            }
        };
        let mut dz = [0.0f64; 2];
        let mut height = 0.0;
        let mut in_contact = false;
        {
            let (dx, dy) = (dxp * self.mm_per_px, dyp * self.mm_per_px);
            // Object::gap, with the reciprocal precomputed for the common shapes.
            let (g, gx, gy) = match o.shape {
                Shape::Sphere => (
                    0.5 * (dx * dx + dy * dy) * self.inv_r,
                    dx * self.inv_r,
                    dy * self.inv_r,
                ),
                Shape::Edge => (0.5 * dx * dx * self.inv_r, dx * self.inv_r, 0.0),
                Shape::Flat => o.gap(dx, dy),
            };
            let cap = self.depth - g;
            if cap > 0.0 {
                // Texture (Object::texture_height / texture_gradient, with the trigonometry
                // per row and column).
                let (sx, cx) = self
                    .cols
                    .get(x - self.bbox.0)
                    .copied()
                    .unwrap_or((0.0, 1.0));
                let amp = o.roughness_mm;
                let mut th = amp * sx * cy;
                let mut tx = amp * self.k * cx * cy;
                let mut ty = -amp * self.k * 0.8 * sx * sy;
                if o.bump_mm > 0.0 {
                    let (bh, bx, by) = o.bump(x as f64 * self.mm_per_px, y as f64 * self.mm_per_px);
                    th += bh;
                    tx += bx;
                    ty += by;
                }
                let s = cap.min(0.2) * 5.0;
                height = cap + th * s;
                dz = [-gx + tx * s, -gy + ty * s];
                in_contact = true;
            } else if self.a_px > 0.0 {
                // Outside the contact the gel slopes back up to rest (smooth skirt).
                let u = ((r - self.a_px) * self.inv_skirt).clamp(0.0, 1.0);
                height = (1.0 - u) * (1.0 - u) * self.depth * 0.15;
                let slope = 2.0 * (1.0 - u) * self.depth * 0.15 * self.inv_skirt * 0.05;
                let (ux, uy) = unit();
                dz = [-ux * slope, -uy * slope];
            }
        }
        let mut dark = 1.0;
        if markers {
            // Markers are dragged outward by the local depression (sampled at the pixel: render
            // the dot that would have moved here).
            let shift = MARKER_SHIFT_PX_PER_MM * height.max(0.0);
            let (ux, uy) = unit();
            dark = marker_dark(x as f64 - ux * shift, y as f64 - uy * shift);
        }
        let mut shade = [0.0; 3];
        for (c, l) in LIGHTS.iter().enumerate() {
            shade[c] = SHADE_GAIN * (dz[0] * l[0] + dz[1] * l[1]) - DEPTH_DARK * height;
        }
        Some(PressPixel {
            in_contact,
            shade,
            dark,
        })
    }
}

/// Background with the marker dots at rest (what every pixel away from a press shows).
fn render_base(spec: &SensorSpec, background: &[f32], markers: bool) -> Vec<f32> {
    let w = spec.width as usize;
    let mut base = background.to_vec();
    if markers {
        for (p, px) in base.chunks_exact_mut(3).enumerate() {
            let dark = marker_dark((p % w) as f64, (p / w) as f64) as f32;
            for v in px {
                *v *= dark;
            }
        }
    }
    base
}

fn unreachable_frame(id: &str) -> Frame {
    // 1x1 black frame; only reachable if a SensorSpec were out of bounds.
    Frame::new(id, 0, Stamp::ZERO, 1, 1, vec![0, 0, 0]).unwrap_or_else(|_| unreachable_frame(id))
}

impl Source for MockSensor {
    fn name(&self) -> &str {
        "mock"
    }
    fn next_frame(&mut self) -> Result<Option<Frame>, SourceError> {
        Ok(self.next_with_truth().map(|(f, _)| f))
    }
    fn is_replay(&self) -> bool {
        true
    }
}

/// Lit, vignetted gel without contact (float DN per channel, RGB).
fn render_background(spec: &SensorSpec) -> Vec<f32> {
    let (w, h) = (spec.width as usize, spec.height as usize);
    let mut bg = vec![0f32; w * h * 3];
    let digit = spec.kind == SensorKind::Digit;
    for y in 0..h {
        for x in 0..w {
            let u = x as f32 / w as f32;
            let v = y as f32 / h as f32;
            let r2 = (u - 0.5).powi(2) + (v - 0.5).powi(2);
            let vig = 1.0 - 0.6 * r2;
            let rgb = if digit {
                // DIGIT: strong colour gradients from LEDs at the edges.
                [
                    70.0 + 110.0 * u,
                    80.0 + 90.0 * (1.0 - v),
                    90.0 + 100.0 * v * (1.0 - u),
                ]
            } else {
                // GelSight Mini: bright, mostly uniform, slightly tinted.
                [150.0 + 20.0 * u, 145.0 + 15.0 * v, 160.0 - 20.0 * u]
            };
            let i = (y * w + x) * 3;
            for c in 0..3 {
                bg[i + c] = rgb[c] * vig;
            }
        }
    }
    bg
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sensor(kind: SensorKind, seed: u64) -> MockSensor {
        MockSensor::new(MockConfig::new(kind, seed), Scenario::fabric_selection())
    }

    #[test]
    fn same_seed_same_bytes_other_seed_other_bytes() {
        let a = sensor(SensorKind::GelsightMini, 7).render(40).0;
        let b = sensor(SensorKind::GelsightMini, 7).render(40).0;
        let c = sensor(SensorKind::GelsightMini, 8).render(40).0;
        assert_eq!(a, b);
        assert_ne!(a.data(), c.data());
    }

    #[test]
    fn frames_are_stamped_at_the_frame_rate() {
        let mut s = sensor(SensorKind::Digit, 1);
        let f0 = s.next_frame().unwrap().unwrap();
        let f1 = s.next_frame().unwrap().unwrap();
        assert_eq!(f0.stamp, EPOCH);
        assert!((f1.stamp.secs_since(f0.stamp) - 1.0 / 60.0).abs() < 1e-9);
        assert_eq!((f1.seq, f1.width, f1.height), (1, 320, 240));
    }

    #[test]
    fn contact_changes_pixels_only_where_truth_says() {
        let s = sensor(SensorKind::GelsightMini, 3);
        let fps = s.cfg.fps;
        let (idle, t_idle) = s.render(0);
        assert_eq!((t_idle.penetration_mm, t_idle.contact_px), (0.0, 0));
        // Mid-hold on fabric A.
        let k = (Scenario::fabric_selection()
            .first_hold_time("fabric_a")
            .unwrap()
            * fps) as u64;
        let (press, truth) = s.render(k);
        assert!(
            truth.penetration_mm > 0.3 && truth.contact_px > 500,
            "{truth:?}"
        );
        assert_eq!(truth.label, "fabric_a");
        let diff = |x: u32, y: u32| -> i32 {
            let (a, b) = (idle.pixel(x, y).unwrap(), press.pixel(x, y).unwrap());
            (0..3)
                .map(|c| (i32::from(a[c]) - i32::from(b[c])).abs())
                .sum()
        };
        // Far corner: only noise. Inside the contact ring: a clear signal.
        assert!(diff(5, 5) <= 12);
        let r = (truth.contact_px as f64 / std::f64::consts::PI).sqrt();
        assert!(diff(160 + (r * 0.7) as u32, 120) > 20);
    }

    #[test]
    fn truth_mask_matches_contact_pixels_and_drift_scales_the_image() {
        let mut cfg = MockConfig::new(SensorKind::Digit, 2);
        cfg.drift.steps.push((1.0, 1.25));
        let s = MockSensor::new(cfg, Scenario::fabric_selection());
        let (before, tb) = s.render(10);
        let (after, ta) = s.render(61);
        assert_eq!(tb.gain, 1.0);
        assert_eq!(ta.gain, 1.25);
        let mean =
            |f: &Frame| f.data().iter().map(|&v| f64::from(v)).sum::<f64>() / f.data().len() as f64;
        assert!((mean(&after) / mean(&before) - 1.25).abs() < 0.02);
        let k = (Scenario::fabric_selection()
            .first_hold_time("fabric_a")
            .unwrap()
            * 60.0) as u64;
        let (_, t) = s.render(k);
        assert_eq!(t.mask.iter().filter(|&&m| m).count() as u32, t.contact_px);
        assert!(t.mask[120 * 320 + 160], "the centre is in contact");
        assert!(!t.mask[0]);
    }

    #[test]
    fn gelsight_has_marker_dots_digit_does_not() {
        let g = sensor(SensorKind::GelsightMini, 1).render(0).0;
        let d = sensor(SensorKind::Digit, 1).render(0).0;
        // A marker centre (12, 12) is much darker than the gel beside it (24, 12).
        let lum = |f: &Frame, x, y| {
            f.pixel(x, y)
                .unwrap()
                .iter()
                .map(|&v| u32::from(v))
                .sum::<u32>()
        };
        assert!(lum(&g, 12, 12) * 2 < lum(&g, 24, 12));
        assert!(lum(&d, 12, 12) * 10 > lum(&d, 24, 12) * 8);
    }

    #[test]
    fn warmup_drift_decays() {
        let d = Drift::warmup();
        assert!((d.gain(0.0) - 0.92).abs() < 1e-9);
        assert!((d.gain(600.0) - 1.0).abs() < 0.011);
    }

    #[test]
    fn scenario_runs_to_its_end() {
        let mut s = sensor(SensorKind::GelsightMini, 0);
        let n = s.frame_count();
        let mut k = 0;
        while s.next_frame().unwrap().is_some() {
            k += 1;
        }
        assert_eq!(k, n);
        assert!(n > 100);
    }
}
