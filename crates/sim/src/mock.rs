//! The mock sensor as a frame source: a scenario played at the sensor's frame rate through the
//! renderer, each frame stamped and paired with the world's ground truth.
//!
//! Frames are a pure function of (scenario, sensor, seed, frame index), so the same seed gives the
//! same bytes. [`MockSensor`] implements the runtime's `Source`.

use unitac_core::{Frame, FrameError, SensorKind, SensorSpec, Source, SourceError, Stamp};

use crate::object::Object;
use crate::render::Renderer;
use crate::scenario::Scenario;
use crate::tangential::{MarkerTruth, Tangential};

/// Capture time of frame 0: a fixed ROS time so runs are reproducible (2023-11-14T22:13:20Z).
pub const EPOCH: Stamp = Stamp(1_700_000_000_000_000_000);

/// What the world knew when a frame was rendered.
#[derive(Debug, Clone, PartialEq)]
pub struct GroundTruth {
    /// Indenter penetration into the gel \[mm] (0 = not touching).
    pub penetration_mm: f64,
    /// Label of the object being touched ("" when none).
    pub label: String,
    /// Pixels where the indenter touches the gel (height > 0), in output pixels.
    pub contact_px: u32,
    /// Row-major mask of those pixels (width x height of the frame).
    pub mask: Vec<bool>,
    /// Global illumination gain applied to this frame (drift, exposure steps).
    pub gain: f64,
    /// Grip force per finger \[N] when the world drives the scenario (0 otherwise).
    pub force_n: f64,
    /// Cup deformation (loss of diameter) \[m] when the world drives the scenario (0 otherwise).
    pub deformation_m: f64,
    /// The tangential input of this frame (zero: none).
    pub tangential: Tangential,
    /// Every marker dot whose rest centre is in the frame, at rest and moved by the tangential
    /// input (empty for a sensor without markers).
    pub markers: Vec<MarkerTruth>,
}

/// Slow illumination changes of a real sensor: LED warm-up, slow wander, exposure steps.
/// The frame is multiplied by `gain(t)`.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Drift {
    /// Relative gain at t = 0 that decays away (LED warm-up), e.g. -0.08.
    pub warmup: f64,
    /// Warm-up time constant \[s].
    pub warmup_tau_s: f64,
    /// Relative amplitude of a slow sinusoidal wander, e.g. 0.01.
    pub wander: f64,
    /// Wander period \[s].
    pub wander_period_s: f64,
    /// Exposure steps: from time t \[s] on, multiply by gain.
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
    /// Per-pixel noise sigma \[DN].
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
            markers: sensor.markers() == unitac_core::sensor::Markers::Yes,
        }
    }
}

/// Deterministic renderer of a scenario.
#[derive(Debug)]
pub struct MockSensor {
    cfg: MockConfig,
    scenario: Scenario,
    renderer: Renderer,
    /// A black frame of the output size, checked against the frame bounds once; every rendered
    /// frame starts as a copy of it.
    blank: Frame,
    index: u64,
    total: u64,
}

impl MockSensor {
    /// A mock sensor at its kind's output size.
    pub fn new(cfg: MockConfig, scenario: Scenario) -> Self {
        let spec = cfg.sensor.spec();
        let blank = Frame::black_of(cfg.sensor, &cfg.sensor_id);
        Self::build(cfg, spec, scenario, blank)
    }

    /// A mock sensor with its own output size (e.g. DIGIT's VGA mode, 640x480 at 0.02 mm/px).
    /// A size outside `unitac_core::frame::MAX_SIDE` per side is an error.
    pub fn with_spec(
        cfg: MockConfig,
        spec: SensorSpec,
        scenario: Scenario,
    ) -> Result<Self, FrameError> {
        let len = Frame::byte_len(spec.width, spec.height)?;
        let blank = Frame::new(
            &cfg.sensor_id,
            0,
            EPOCH,
            spec.width,
            spec.height,
            vec![0; len],
        )?;
        Ok(Self::build(cfg, spec, scenario, blank))
    }

    fn build(cfg: MockConfig, spec: SensorSpec, scenario: Scenario, blank: Frame) -> Self {
        let total = (scenario.duration_s() * cfg.fps).floor() as u64;
        let renderer = Renderer::new(spec, cfg.noise_dn, cfg.markers);
        Self {
            cfg,
            scenario,
            renderer,
            blank,
            index: 0,
            total,
        }
    }

    pub fn spec(&self) -> &SensorSpec {
        self.renderer.spec()
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
        let touching = obj.filter(|_| approach > 0.0);
        let depth = touching.map_or(0.0, |o| o.gel_depth(approach));
        let (frame, mut truth) = self.render_contact(index, touching.map(|o| (o, depth)), None);
        truth.label = obj.map(|o| o.label.clone()).unwrap_or_default();
        truth.force_n = grip.map_or(0.0, |g| g.force_n);
        truth.deformation_m = grip.map_or(0.0, |g| g.deformation_m);
        (frame, truth)
    }

    /// Render frame `index` of a press the caller gives instead of the scenario (a task world's
    /// sensor view): `press` = (object, gel penetration \[mm]); `force_n` and `deformation_m`
    /// go into the ground truth as they are, and the label is the object's even when it does not
    /// touch.
    pub fn render_press(
        &self,
        index: u64,
        press: Option<(&Object, f64)>,
        force_n: f64,
        deformation_m: f64,
    ) -> (Frame, GroundTruth) {
        let label = press.map(|(o, _)| o.label.clone()).unwrap_or_default();
        let (frame, mut truth) = self.render_contact(index, press, None);
        truth.label = label;
        truth.force_n = force_n;
        truth.deformation_m = deformation_m;
        (frame, truth)
    }

    /// Frame `index` (its stamp, gain and noise) showing `press` = (object, gel depth \[mm]) and
    /// the object's sideways motion `tangential` instead of the scenario's: what a world that
    /// moves objects drives. The truth's label is the object's.
    pub fn render_contact(
        &self,
        index: u64,
        press: Option<(&Object, f64)>,
        tangential: Option<&Tangential>,
    ) -> (Frame, GroundTruth) {
        let t = index as f64 / self.cfg.fps;
        let gain = self.cfg.drift.gain(t);
        let mut frame = self.blank.clone();
        frame.seq = index;
        frame.stamp =
            EPOCH.saturating_add_nanos((index as f64 * 1e9 / self.cfg.fps).round() as i64);
        let press = press.filter(|&(_, depth)| depth > 0.0);
        let contact = self.renderer.render_into(
            frame.data_mut(),
            press,
            tangential,
            gain,
            self.cfg.seed ^ index.wrapping_mul(0x9E37_79B9_7F4A_7C15),
        );
        let truth = GroundTruth {
            penetration_mm: press.map_or(0.0, |(_, d)| d),
            label: press.map(|(o, _)| o.label.clone()).unwrap_or_default(),
            contact_px: contact.contact_px,
            mask: contact.mask,
            gain,
            force_n: 0.0,
            deformation_m: 0.0,
            tangential: tangential.copied().unwrap_or_default(),
            markers: self.renderer.marker_truth(press, tangential),
        };
        (frame, truth)
    }

    /// Frame `index` (its stamp, gain and noise) of the gel depressed by the height map `height`
    /// \[mm, row-major, the output size, positive into the gel]: the map is the frame's depth
    /// truth (ball presses for depth calibration, `crate::ballpress`). None when the map's
    /// length is not width x height.
    pub fn render_height(&self, index: u64, height: &[f32]) -> Option<Frame> {
        let t = index as f64 / self.cfg.fps;
        let gain = self.cfg.drift.gain(t);
        let mut frame = self.blank.clone();
        frame.seq = index;
        frame.stamp =
            EPOCH.saturating_add_nanos((index as f64 * 1e9 / self.cfg.fps).round() as i64);
        self.renderer.render_height_into(
            frame.data_mut(),
            height,
            gain,
            self.cfg.seed ^ index.wrapping_mul(0x9E37_79B9_7F4A_7C15),
        )?;
        Some(frame)
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

#[cfg(test)]
mod tests {
    use super::*;

    fn sensor(kind: SensorKind, seed: u64) -> MockSensor {
        MockSensor::new(MockConfig::new(kind, seed), Scenario::fabric_selection())
    }

    #[test]
    fn same_seed_same_bytes_other_seed_other_bytes() {
        let a = sensor(SensorKind::GELSIGHT_MINI, 7).render(40).0;
        let b = sensor(SensorKind::GELSIGHT_MINI, 7).render(40).0;
        let c = sensor(SensorKind::GELSIGHT_MINI, 8).render(40).0;
        assert_eq!(a, b);
        assert_ne!(a.data(), c.data());
    }

    #[test]
    fn frames_are_stamped_at_the_frame_rate() {
        let mut s = sensor(SensorKind::DIGIT, 1);
        let f0 = s.next_frame().unwrap().unwrap();
        let f1 = s.next_frame().unwrap().unwrap();
        assert_eq!(f0.stamp, EPOCH);
        assert!((f1.stamp.secs_since(f0.stamp) - 1.0 / 60.0).abs() < 1e-9);
        assert_eq!((f1.seq, f1.width, f1.height), (1, 320, 240));
    }

    #[test]
    fn contact_changes_pixels_only_where_truth_says() {
        let s = sensor(SensorKind::GELSIGHT_MINI, 3);
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
        let mut cfg = MockConfig::new(SensorKind::DIGIT, 2);
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
        let g = sensor(SensorKind::GELSIGHT_MINI, 1).render(0).0;
        let d = sensor(SensorKind::DIGIT, 1).render(0).0;
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
    fn a_spec_outside_the_frame_bounds_is_refused_at_construction() {
        let cfg = MockConfig::new(SensorKind::DIGIT, 1);
        let spec = SensorKind::DIGIT.spec();
        for (width, height) in [(0, 240), (320, unitac_core::frame::MAX_SIDE + 1)] {
            let bad = SensorSpec {
                width,
                height,
                ..spec
            };
            let err = MockSensor::with_spec(cfg.clone(), bad, Scenario::fabric_selection());
            assert_eq!(
                err.err(),
                Some(FrameError::BadSize { width, height }),
                "{width}x{height}"
            );
        }
        let vga = SensorSpec {
            width: 640,
            height: 480,
            ..spec
        };
        let s = MockSensor::with_spec(cfg, vga, Scenario::fabric_selection()).unwrap();
        let (f, t) = s.render(0);
        assert_eq!((f.width, f.height, t.mask.len()), (640, 480, 640 * 480));
    }

    #[test]
    fn warmup_drift_decays() {
        let d = Drift::warmup();
        assert!((d.gain(0.0) - 0.92).abs() < 1e-9);
        assert!((d.gain(600.0) - 1.0).abs() < 0.011);
    }

    #[test]
    fn scenario_runs_to_its_end() {
        let mut s = sensor(SensorKind::GELSIGHT_MINI, 0);
        let n = s.frame_count();
        let mut k = 0;
        while s.next_frame().unwrap().is_some() {
            k += 1;
        }
        assert_eq!(k, n);
        assert!(n > 100);
    }
}
