//! Mock tactile sensor: deterministic RGB frames of presses on objects, with ground truth.
//!
//! The renderer is a small photometric model of a gel sensor: an indenter height map (sphere cap
//! plus a surface texture), its gradients lit by three coloured lights from different directions
//! (as in GelSight-style sensors), a vignetted background, and per-pixel noise of about 1 DN.
//! Frames are a pure function of (scenario, sensor, seed, frame index), so the same seed gives the
//! same bytes. [`MockSensor`] implements the runtime's `Source`.

mod rng;
mod scenario;

pub use rng::SplitMix64;
pub use scenario::{Object, Phase, Scenario, ScenarioError};

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
}

impl MockConfig {
    pub fn new(sensor: SensorKind, seed: u64) -> Self {
        Self {
            sensor,
            sensor_id: format!("mock_{}", sensor.as_str().replace('-', "_")),
            fps: sensor.spec().fps,
            seed,
            noise_dn: 1.0,
        }
    }
}

/// Deterministic renderer of a scenario.
#[derive(Debug)]
pub struct MockSensor {
    cfg: MockConfig,
    spec: SensorSpec,
    scenario: Scenario,
    background: Vec<f32>,
    index: u64,
    total: u64,
}

impl MockSensor {
    pub fn new(cfg: MockConfig, scenario: Scenario) -> Self {
        let spec = cfg.sensor.spec();
        let total = (scenario.duration_s() * cfg.fps).floor() as u64;
        let background = render_background(&spec);
        Self {
            cfg,
            spec,
            scenario,
            background,
            index: 0,
            total,
        }
    }

    pub fn spec(&self) -> &SensorSpec {
        &self.spec
    }
    pub fn frame_count(&self) -> u64 {
        self.total
    }

    /// Render frame `index` (independent of what was rendered before).
    pub fn render(&self, index: u64) -> (Frame, GroundTruth) {
        let t = index as f64 / self.cfg.fps;
        let (depth, obj) = self.scenario.at(t);
        let (w, h) = (self.spec.width as usize, self.spec.height as usize);
        let mut rng = SplitMix64::new(self.cfg.seed ^ index.wrapping_mul(0x9E37_79B9_7F4A_7C15));
        let mut data = vec![0u8; w * h * 3];
        let mut contact_px = 0u32;
        // Indenter centred in the image; sizes in output pixels.
        let px_per_mm = 1.0 / self.spec.mm_per_px;
        let (cx, cy) = (w as f64 * 0.5, h as f64 * 0.5);
        let radius_px = obj.map_or(1.0, |o| o.radius_mm * px_per_mm);
        let lights: [[f64; 2]; 3] = [[1.0, 0.0], [-0.5, 0.866], [-0.5, -0.866]];
        let gain = 90.0; // DN per unit slope
        for y in 0..h {
            for x in 0..w {
                let mut dz = [0.0f64; 2];
                let mut height = 0.0;
                if let (Some(o), true) = (obj, depth > 0.0) {
                    let (dxp, dyp) = (x as f64 - cx, y as f64 - cy);
                    let r2 = (dxp * dxp + dyp * dyp) / (radius_px * radius_px);
                    // Sphere cap in mm: depth - r^2 * R / 2, R = radius.
                    let cap = depth - 0.5 * r2 * o.radius_mm;
                    if cap > 0.0 {
                        let tex = o.texture_height(x as f64 / px_per_mm, y as f64 / px_per_mm);
                        height = cap + tex * cap.min(0.2) / 0.2;
                        // Analytic gradient of the cap [mm/mm] plus the texture's.
                        let (tx, ty) =
                            o.texture_gradient(x as f64 / px_per_mm, y as f64 / px_per_mm);
                        let s = cap.min(0.2) / 0.2;
                        dz = [-dxp / radius_px + tx * s, -dyp / radius_px + ty * s];
                        contact_px += 1;
                    }
                }
                let i = (y * w + x) * 3;
                for (c, l) in lights.iter().enumerate() {
                    let shade = gain * (dz[0] * l[0] + dz[1] * l[1]) - 25.0 * height;
                    let v =
                        self.background[i + c] as f64 + shade + self.cfg.noise_dn * rng.gaussian();
                    data[i + c] = v.round().clamp(0.0, 255.0) as u8;
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
