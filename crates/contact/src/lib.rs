//! Contact detection by background subtraction, as a pure [`Stage`].
//!
//! Per frame: learn a background from the first frames (mean) and the sensor noise (from
//! frame-to-frame differences); then sum the per-channel absolute difference to the background on
//! a strided grid, threshold it at a multiple of the measured noise, and measure area, centroid,
//! bounding box and strength. Hysteresis (enter/exit areas) and debounce (k frames) turn that into
//! contact episodes. The background follows slow changes by an EMA that runs only while there is
//! no contact, so a held contact is never absorbed.

use serde::Deserialize;
use unitac_core::msg::{ContactEpisode, ContactState, Header};
use unitac_core::{Clock, Frame, Msg, SensorSpec, Stage, StageError, Stamp};

/// Parameters (scene file `params:` of a `contact` stage). Unknown keys are errors.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ContactParams {
    /// Frames averaged into the initial background.
    pub learn_frames: u32,
    /// Grid stride in pixels (1 = every pixel).
    pub stride: u32,
    /// Threshold on the 3-channel absolute difference, in units of the measured noise sigma.
    pub noise_k: f32,
    /// Lower bound of that threshold [DN, summed over channels].
    pub min_threshold: f32,
    /// Contact starts when the area reaches this [px] ...
    pub enter_area_px: f32,
    /// ... and ends when it falls below this [px].
    pub exit_area_px: f32,
    /// Consecutive frames needed to enter / leave contact.
    pub debounce_frames: u32,
    /// Background EMA weight per no-contact frame.
    pub ema_alpha: f32,
    /// Labels given to episodes in order (e.g. [fabric_a, fabric_b]); later episodes get "".
    pub episode_labels: Vec<String>,
}

impl Default for ContactParams {
    fn default() -> Self {
        Self {
            learn_frames: 10,
            stride: 2,
            noise_k: 3.0,
            min_threshold: 6.0,
            enter_area_px: 120.0,
            exit_area_px: 60.0,
            debounce_frames: 2,
            ema_alpha: 0.02,
            episode_labels: Vec::new(),
        }
    }
}

impl ContactParams {
    pub fn check(&self) -> Result<(), String> {
        if !(1..=1000).contains(&self.learn_frames) {
            return Err(format!(
                "learn_frames {} is outside 1..=1000",
                self.learn_frames
            ));
        }
        if !(1..=16).contains(&self.stride) {
            return Err(format!("stride {} is outside 1..=16", self.stride));
        }
        if !(self.exit_area_px >= 0.0 && self.exit_area_px <= self.enter_area_px) {
            return Err("need 0 <= exit_area_px <= enter_area_px".into());
        }
        if !(self.ema_alpha >= 0.0 && self.ema_alpha < 1.0) {
            return Err(format!("ema_alpha {} is outside [0, 1)", self.ema_alpha));
        }
        if !(self.noise_k.is_finite() && self.noise_k > 0.0 && self.min_threshold.is_finite()) {
            return Err("noise_k must be > 0 and min_threshold finite".into());
        }
        if self.debounce_frames > 1000 {
            return Err(format!(
                "debounce_frames {} is above 1000",
                self.debounce_frames
            ));
        }
        Ok(())
    }
}

#[derive(Debug, Clone)]
struct Episode {
    id: u64,
    start: Stamp,
    last: Stamp,
    frames: u32,
    peak_area: f32,
    peak_seq: u64,
}

/// Measurement of one frame against the background.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Measurement {
    pub area_px: f32,
    pub centroid: [f32; 2],
    pub bbox: [u32; 4],
    pub strength: f32,
}

#[derive(Debug)]
pub struct ContactDetector {
    p: ContactParams,
    spec: SensorSpec,
    size: Option<(u32, u32)>,
    /// Background on the strided grid, RGB, float DN.
    bg: Vec<f32>,
    learn_sum: Vec<f64>,
    learned: u32,
    prev: Vec<f32>,
    noise_acc: f64,
    noise_n: u64,
    noise_sigma: f32,
    bg_stamp: Stamp,
    in_contact: bool,
    streak: u32,
    next_episode: u64,
    episode: Option<Episode>,
    last_episode: u64,
}

impl ContactDetector {
    pub fn new(p: ContactParams, spec: SensorSpec) -> Result<Self, String> {
        p.check()?;
        Ok(Self {
            p,
            spec,
            size: None,
            bg: Vec::new(),
            learn_sum: Vec::new(),
            learned: 0,
            prev: Vec::new(),
            noise_acc: 0.0,
            noise_n: 0,
            noise_sigma: 0.0,
            bg_stamp: Stamp::ZERO,
            in_contact: false,
            streak: 0,
            next_episode: 1,
            episode: None,
            last_episode: 0,
        })
    }

    pub fn is_learned(&self) -> bool {
        self.learned >= self.p.learn_frames
    }
    /// Measured per-channel noise sigma [DN].
    pub fn noise_sigma(&self) -> f32 {
        self.noise_sigma
    }
    pub fn threshold(&self) -> f32 {
        (self.p.noise_k * 3.0 * self.noise_sigma).max(self.p.min_threshold)
    }

    fn grid(&self, f: &Frame) -> Vec<f32> {
        let s = self.p.stride as usize;
        let (w, h) = (f.width as usize, f.height as usize);
        let d = f.data();
        let mut g = Vec::with_capacity((w / s + 1) * (h / s + 1) * 3);
        for y in (0..h).step_by(s) {
            let row = &d[y * w * 3..(y + 1) * w * 3];
            for px in row.chunks_exact(3).step_by(s) {
                g.extend(px.iter().map(|&v| f32::from(v)));
            }
        }
        g
    }

    /// Measure a frame against the background (no state change).
    pub fn measure(&self, f: &Frame) -> Measurement {
        let s = self.p.stride as usize;
        let g = self.grid(f);
        let gw = (f.width as usize).div_ceil(s);
        let thr = self.threshold();
        let (mut n, mut sx, mut sy, mut sd) = (0u64, 0f64, 0f64, 0f64);
        let mut bb = [u32::MAX, u32::MAX, 0u32, 0u32];
        for (i, (px, bg)) in g.chunks_exact(3).zip(self.bg.chunks_exact(3)).enumerate() {
            let d = (px[0] - bg[0]).abs() + (px[1] - bg[1]).abs() + (px[2] - bg[2]).abs();
            if d > thr {
                let (x, y) = (((i % gw) * s) as u32, ((i / gw) * s) as u32);
                n += 1;
                sx += f64::from(x);
                sy += f64::from(y);
                sd += f64::from(d);
                bb = [
                    bb[0].min(x),
                    bb[1].min(y),
                    bb[2].max(x + 1),
                    bb[3].max(y + 1),
                ];
            }
        }
        if n == 0 {
            return Measurement {
                area_px: 0.0,
                centroid: [0.0; 2],
                bbox: [0; 4],
                strength: 0.0,
            };
        }
        let cell = (s * s) as f32;
        let mean_d = (sd / n as f64) as f32;
        Measurement {
            area_px: n as f32 * cell,
            centroid: [(sx / n as f64) as f32, (sy / n as f64) as f32],
            bbox: bb,
            strength: ((mean_d - thr) / 60.0).clamp(0.0, 1.0),
        }
    }

    fn learn(&mut self, f: &Frame) {
        let g = self.grid(f);
        if self.learn_sum.is_empty() {
            self.learn_sum = vec![0.0; g.len()];
        }
        if !self.prev.is_empty() {
            // E|a - b| = 2 sigma / sqrt(pi) for two independent N(., sigma^2) samples.
            let mad: f64 = g
                .iter()
                .zip(&self.prev)
                .map(|(a, b)| f64::from((a - b).abs()))
                .sum();
            self.noise_acc += mad;
            self.noise_n += g.len() as u64;
        }
        for (s, v) in self.learn_sum.iter_mut().zip(&g) {
            *s += f64::from(*v);
        }
        self.prev = g;
        self.learned += 1;
        if self.is_learned() {
            let n = f64::from(self.learned);
            self.bg = self.learn_sum.iter().map(|s| (s / n) as f32).collect();
            let mean_abs = if self.noise_n > 0 {
                self.noise_acc / self.noise_n as f64
            } else {
                0.0
            };
            self.noise_sigma = (mean_abs * std::f64::consts::PI.sqrt() / 2.0) as f32;
            self.bg_stamp = f.stamp;
            self.learn_sum = Vec::new();
            self.prev = Vec::new();
        }
    }

    /// One frame in, zero or more events out.
    pub fn step(&mut self, f: &Frame) -> Result<Vec<Msg>, StageError> {
        match self.size {
            None => self.size = Some((f.width, f.height)),
            Some((w, h)) if (w, h) != (f.width, f.height) => {
                return Err(StageError::BadInput(format!(
                    "frame {} is {}x{}, the background is {w}x{h}",
                    f.seq, f.width, f.height
                )));
            }
            Some(_) => {}
        }
        if !self.is_learned() {
            self.learn(f);
            return Ok(Vec::new());
        }
        let m = self.measure(f);
        let raw = if self.in_contact {
            m.area_px >= self.p.exit_area_px
        } else {
            m.area_px >= self.p.enter_area_px
        };
        let mut out = Vec::new();
        if raw != self.in_contact {
            self.streak += 1;
            if self.streak >= self.p.debounce_frames.max(1) {
                self.streak = 0;
                self.in_contact = raw;
                if raw {
                    let id = self.next_episode;
                    self.next_episode += 1;
                    self.last_episode = id;
                    self.episode = Some(Episode {
                        id,
                        start: f.stamp,
                        last: f.stamp,
                        frames: 0,
                        peak_area: 0.0,
                        peak_seq: f.seq,
                    });
                } else if let Some(ep) = self.episode.take() {
                    out.push(Msg::Episode(self.episode_msg(&f.sensor_id, ep)));
                }
            }
        } else {
            self.streak = 0;
        }
        if let (true, Some(ep)) = (self.in_contact, self.episode.as_mut()) {
            ep.frames += 1;
            ep.last = f.stamp;
            if m.area_px > ep.peak_area {
                ep.peak_area = m.area_px;
                ep.peak_seq = f.seq;
            }
        }
        if !self.in_contact && !raw && m.area_px < self.p.exit_area_px {
            let a = self.p.ema_alpha;
            let g = self.grid(f);
            for (b, v) in self.bg.iter_mut().zip(g) {
                *b += a * (v - *b);
            }
        }
        let mm2 = self.spec.mm2_per_px() as f32;
        let state = ContactState {
            header: Header::optical(f.stamp, &f.sensor_id),
            sensor_id: f.sensor_id.clone(),
            frame_seq: f.seq,
            in_contact: self.in_contact,
            area_px: m.area_px,
            area_mm2: m.area_px * mm2,
            centroid_px: m.centroid,
            bbox_px: m.bbox,
            strength: m.strength,
            episode_id: self.last_episode,
            background_age_s: f.stamp.secs_since(self.bg_stamp),
        };
        out.insert(0, Msg::Contact(state));
        Ok(out)
    }

    fn episode_msg(&self, sensor_id: &str, ep: Episode) -> ContactEpisode {
        let label = usize::try_from(ep.id - 1)
            .ok()
            .and_then(|i| self.p.episode_labels.get(i))
            .cloned()
            .unwrap_or_default();
        ContactEpisode {
            header: Header::optical(ep.last, sensor_id),
            sensor_id: sensor_id.to_string(),
            episode_id: ep.id,
            start: ep.start,
            end: ep.last,
            frame_count: ep.frames,
            peak_area_px: ep.peak_area,
            peak_area_mm2: ep.peak_area * self.spec.mm2_per_px() as f32,
            peak_frame_seq: ep.peak_seq,
            label,
        }
    }

    /// Close an open episode (end of input).
    pub fn flush(&mut self, sensor_id: &str) -> Vec<Msg> {
        self.in_contact = false;
        self.episode
            .take()
            .map(|ep| Msg::Episode(self.episode_msg(sensor_id, ep)))
            .into_iter()
            .collect()
    }
}

/// The detector as a runtime stage: consumes frames, emits ContactState and ContactEpisode.
#[derive(Debug)]
pub struct ContactStage {
    det: ContactDetector,
    sensor_id: String,
}

impl ContactStage {
    pub fn new(p: ContactParams, spec: SensorSpec) -> Result<Self, String> {
        Ok(Self {
            det: ContactDetector::new(p, spec)?,
            sensor_id: String::new(),
        })
    }
    pub fn detector(&self) -> &ContactDetector {
        &self.det
    }
}

impl Stage for ContactStage {
    fn name(&self) -> &str {
        "contact"
    }
    fn process(&mut self, input: &Msg, _clock: &dyn Clock) -> Result<Vec<Msg>, StageError> {
        match input {
            Msg::Frame(f) => {
                self.sensor_id.clone_from(&f.sensor_id);
                self.det.step(f)
            }
            _ => Ok(Vec::new()),
        }
    }
    fn finish(&mut self, _clock: &dyn Clock) -> Result<Vec<Msg>, StageError> {
        Ok(self.det.flush(&self.sensor_id))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use unitac_core::{ManualClock, SensorKind};
    use unitac_sim::{MockConfig, MockSensor, Scenario};

    fn run(
        kind: SensorKind,
        scenario: Scenario,
        p: ContactParams,
    ) -> (Vec<Msg>, Vec<(bool, bool)>) {
        let mut sensor = MockSensor::new(MockConfig::new(kind, 11), scenario);
        let mut stage = ContactStage::new(p, kind.spec()).unwrap();
        let clock = ManualClock::default();
        let mut out = Vec::new();
        let mut agree = Vec::new();
        while let Some((f, truth)) = sensor.next_with_truth() {
            let msgs = stage.process(&Msg::Frame(f), &clock).unwrap();
            for m in &msgs {
                if let Msg::Contact(c) = m {
                    agree.push((c.in_contact, truth.penetration_mm > 0.05));
                }
            }
            out.extend(msgs);
        }
        out.extend(stage.finish(&clock).unwrap());
        (out, agree)
    }

    #[test]
    fn fabric_scenario_gives_two_labelled_episodes() {
        for kind in [SensorKind::GelsightMini, SensorKind::Digit] {
            let p = ContactParams {
                episode_labels: vec!["fabric_a".into(), "fabric_b".into()],
                ..Default::default()
            };
            let (out, agree) = run(kind, Scenario::fabric_selection(), p);
            let eps: Vec<&ContactEpisode> = out
                .iter()
                .filter_map(|m| {
                    if let Msg::Episode(e) = m {
                        Some(e)
                    } else {
                        None
                    }
                })
                .collect();
            assert_eq!(eps.len(), 2, "{kind}: {eps:?}");
            assert_eq!(
                (eps[0].label.as_str(), eps[1].label.as_str()),
                ("fabric_a", "fabric_b")
            );
            assert!(
                eps.iter()
                    .all(|e| e.frame_count > 10 && e.peak_area_px > 1000.0),
                "{eps:?}"
            );
            // Per-frame agreement with ground truth on clearly pressed / clearly free frames.
            let right = agree.iter().filter(|(d, t)| d == t).count();
            assert!(
                right as f64 / agree.len() as f64 > 0.9,
                "{kind}: {right}/{}",
                agree.len()
            );
        }
    }

    #[test]
    fn no_contact_no_episode() {
        let (out, agree) = run(
            SensorKind::GelsightMini,
            Scenario::by_name("idle").unwrap(),
            ContactParams::default(),
        );
        assert!(out.iter().all(|m| !matches!(m, Msg::Episode(_))));
        assert!(agree.iter().all(|(d, _)| !d));
    }

    #[test]
    fn wrong_size_frame_is_an_error_and_state_survives() {
        let kind = SensorKind::GelsightMini;
        let mut sensor = MockSensor::new(MockConfig::new(kind, 1), Scenario::fabric_selection());
        let mut stage = ContactStage::new(ContactParams::default(), kind.spec()).unwrap();
        let clock = ManualClock::default();
        for _ in 0..15 {
            let (f, _) = sensor.next_with_truth().unwrap();
            stage.process(&Msg::Frame(f), &clock).unwrap();
        }
        let small = Frame::new("mock", 99, Stamp(1), 4, 4, vec![0; 48]).unwrap();
        let e = stage.process(&Msg::Frame(small), &clock).unwrap_err();
        assert!(e.to_string().contains("4x4"), "{e}");
        let (f, _) = sensor.next_with_truth().unwrap();
        let out = stage.process(&Msg::Frame(f), &clock).unwrap();
        assert!(matches!(&out[0], Msg::Contact(c) if !c.in_contact));
    }

    #[test]
    fn noise_is_measured() {
        let kind = SensorKind::Digit;
        let mut sensor =
            MockSensor::new(MockConfig::new(kind, 5), Scenario::by_name("idle").unwrap());
        let mut det = ContactDetector::new(ContactParams::default(), kind.spec()).unwrap();
        for _ in 0..10 {
            det.step(&sensor.next_with_truth().unwrap().0).unwrap();
        }
        assert!(det.is_learned());
        // The mock's noise is 1 DN; rounding to integers adds ~0.29 DN.
        assert!(
            (0.8..1.3).contains(&det.noise_sigma()),
            "{}",
            det.noise_sigma()
        );
    }

    #[test]
    fn bad_params_are_rejected() {
        let spec = SensorKind::Digit.spec();
        let p = ContactParams {
            stride: 0,
            ..Default::default()
        };
        assert!(ContactDetector::new(p, spec).is_err());
        let p = ContactParams {
            exit_area_px: 500.0,
            ..Default::default()
        };
        assert!(ContactDetector::new(p, spec).is_err());
    }
}
