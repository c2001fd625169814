//! Degraded press fixtures for contact detection: what a real gel shows between the background
//! frame and a press frame besides the press itself.
//!
//! A fixture is built from two noise-free renders of the mock sensor (the background and a held
//! press): the press's change `pressed - background` is moved to `shift` (a multiple of the
//! marker spacing keeps GelSight markers aligned, so presses near the border can be made), added
//! back to the clean background together with a smooth shading field (uneven LED drift, gel
//! stretch, exposure: broad and low-frequency, `shading_dn` at its strongest summed over the
//! channels) and per-channel Gaussian camera noise of `noise_dn`. The background frame given to
//! the detector is the clean background with its own noise and no shading. Ground truth (the
//! contact mask, its centroid and equivalent radius) moves with the press.

use crate::{MockConfig, MockSensor, Scenario, SplitMix64, quantise_f32};
use unitac_core::{Frame, FrameError, SensorSpec};

/// How a press frame is degraded.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Degrade {
    /// Largest sum over channels of |shading| \[DN].
    pub shading_dn: f64,
    /// Camera noise sigma per channel \[DN].
    pub noise_dn: f64,
    /// Moves the press \[px] (x, y) from the image centre.
    pub shift: (i32, i32),
    pub seed: u64,
}

/// A background frame, a press frame and the press's ground truth.
#[derive(Debug, Clone)]
pub struct Fixture {
    pub background: Frame,
    pub frame: Frame,
    /// Pixels where the indenter touches the gel, row-major.
    pub mask: Vec<bool>,
    pub contact_px: u32,
    /// Centroid of the mask \[px] (x, y).
    pub centroid: [f64; 2],
    /// Radius of the disc with the mask's area \[px].
    pub radius_px: f64,
    /// Gel penetration of the press \[mm].
    pub penetration_mm: f64,
}

/// A smooth shading field, RGB interleaved \[DN]: per channel a tilt plus two broad Gaussian
/// bumps (sigma 25-50 % of the frame width) with random signs, scaled so that the largest sum
/// over channels of |field| is `amplitude_dn`.
pub fn shading_field(width: u32, height: u32, amplitude_dn: f64, seed: u64) -> Vec<f32> {
    let (w, h) = (width as usize, height as usize);
    let mut rng = SplitMix64::new(seed ^ 0x5AD1_4E55);
    let sign = |r: &mut SplitMix64| if r.uniform() < 0.5 { -1.0 } else { 1.0 };
    // Per channel: tilt (a, b) and two bumps (centre, sigma, weight).
    let mut ch = Vec::new();
    for _ in 0..3 {
        let tilt = (
            sign(&mut rng) * rng.uniform(),
            sign(&mut rng) * rng.uniform(),
        );
        let bumps: Vec<(f64, f64, f64, f64)> = (0..2)
            .map(|_| {
                (
                    rng.uniform(),
                    rng.uniform() * h as f64 / w as f64,
                    0.25 + 0.25 * rng.uniform(),
                    sign(&mut rng) * (0.5 + rng.uniform()),
                )
            })
            .collect();
        ch.push((tilt, bumps));
    }
    let mut field = vec![0f32; w * h * 3];
    let inv_w = 1.0 / w.max(1) as f64;
    for y in 0..h {
        let v = y as f64 * inv_w;
        for x in 0..w {
            let u = x as f64 * inv_w;
            for (c, (tilt, bumps)) in ch.iter().enumerate() {
                let mut s = tilt.0 * (u - 0.5) + tilt.1 * (v - 0.5 * h as f64 * inv_w);
                for &(bx, by, sig, wt) in bumps {
                    let d2 = (u - bx) * (u - bx) + (v - by) * (v - by);
                    s += wt * (-d2 / (2.0 * sig * sig)).exp();
                }
                field[(y * w + x) * 3 + c] = s as f32;
            }
        }
    }
    let peak = field
        .chunks_exact(3)
        .map(|p| p.iter().map(|v| v.abs()).sum::<f32>())
        .fold(0f32, f32::max);
    if peak > 0.0 {
        let k = amplitude_dn as f32 / peak;
        field.iter_mut().for_each(|v| *v *= k);
    }
    field
}

/// `clean + field + noise`, quantised, as a frame like `like`.
pub(crate) fn noisy(
    like: &Frame,
    clean: &[f32],
    field: Option<&[f32]>,
    noise_dn: f64,
    seed: u64,
) -> Result<Frame, FrameError> {
    let mut rng = SplitMix64::new(seed);
    let sigma = noise_dn as f32;
    let data = clean
        .iter()
        .enumerate()
        .map(|(i, &v)| {
            let s = field.map_or(0.0, |f| f[i]);
            quantise_f32(v + s + sigma * rng.gaussian_fast() as f32)
        })
        .collect();
    Frame::new(
        &like.sensor_id,
        like.seq,
        like.stamp,
        like.width,
        like.height,
        data,
    )
}

/// A press of `object`-like `scenario` (its first hold on `label`), rendered noise-free on a
/// sensor of `spec`, then degraded by `d`.
pub fn press_fixture(
    cfg: &MockConfig,
    spec: SensorSpec,
    scenario: &Scenario,
    label: &str,
    d: Degrade,
) -> Option<Fixture> {
    let mut clean_cfg = cfg.clone();
    clean_cfg.noise_dn = 0.0;
    clean_cfg.drift = crate::Drift::default();
    let fps = clean_cfg.fps;
    let s = MockSensor::with_spec(clean_cfg, spec, scenario.clone()).ok()?;
    let (bg, _) = s.render(0);
    let k = (scenario.first_hold_time(label)? * fps) as u64;
    let (pressed, truth) = s.render(k);
    let (w, h) = (spec.width as usize, spec.height as usize);
    let base: Vec<f32> = bg.data().iter().map(|&v| f32::from(v)).collect();
    let mut moved = base.clone();
    let mut mask = vec![false; w * h];
    let (dx, dy) = (d.shift.0 as isize, d.shift.1 as isize);
    for y in 0..h {
        let sy = y as isize - dy;
        if sy < 0 || sy >= h as isize {
            continue;
        }
        for x in 0..w {
            let sx = x as isize - dx;
            if sx < 0 || sx >= w as isize {
                continue;
            }
            let (i, j) = (y * w + x, sy as usize * w + sx as usize);
            mask[i] = truth.mask[j];
            for c in 0..3 {
                let delta = f32::from(pressed.data()[j * 3 + c]) - f32::from(bg.data()[j * 3 + c]);
                moved[i * 3 + c] += delta;
            }
        }
    }
    let field = shading_field(spec.width, spec.height, d.shading_dn, d.seed);
    let frame = noisy(&pressed, &moved, Some(&field), d.noise_dn, d.seed ^ 0xF00D).ok()?;
    let background = noisy(&bg, &base, None, d.noise_dn, d.seed ^ 0xBEEF).ok()?;
    let (mut n, mut sx, mut sy) = (0u32, 0f64, 0f64);
    for (i, _) in mask.iter().enumerate().filter(|(_, m)| **m) {
        n += 1;
        sx += (i % w) as f64;
        sy += (i / w) as f64;
    }
    let nf = f64::from(n.max(1));
    Some(Fixture {
        background,
        frame,
        mask,
        contact_px: n,
        centroid: [sx / nf, sy / nf],
        radius_px: (f64::from(n) / std::f64::consts::PI).sqrt(),
        penetration_mm: truth.penetration_mm,
    })
}

/// The background with noise and a shading field but no press: a frame that must read as "no
/// contact".
pub fn idle_fixture(cfg: &MockConfig, spec: SensorSpec, d: Degrade) -> Option<(Frame, Frame)> {
    let mut clean_cfg = cfg.clone();
    clean_cfg.noise_dn = 0.0;
    clean_cfg.drift = crate::Drift::default();
    let s = MockSensor::with_spec(clean_cfg, spec, Scenario::idle(1.0)).ok()?;
    let (bg, _) = s.render(0);
    let base: Vec<f32> = bg.data().iter().map(|&v| f32::from(v)).collect();
    let field = shading_field(spec.width, spec.height, d.shading_dn, d.seed);
    let frame = noisy(&bg, &base, Some(&field), d.noise_dn, d.seed ^ 0xF00D).ok()?;
    let background = noisy(&bg, &base, None, d.noise_dn, d.seed ^ 0xBEEF).ok()?;
    Some((background, frame))
}

#[cfg(test)]
mod tests {
    use super::*;
    use unitac_core::SensorKind;

    #[test]
    fn shading_peaks_at_its_amplitude_and_is_smooth() {
        let f = shading_field(320, 240, 40.0, 3);
        let peak = f
            .chunks_exact(3)
            .map(|p| p.iter().map(|v| v.abs()).sum::<f32>())
            .fold(0f32, f32::max);
        assert!((peak - 40.0).abs() < 1e-3, "{peak}");
        // Neighbouring pixels of a row differ by a small fraction of a DN.
        let step = f
            .chunks_exact(320 * 3)
            .flat_map(|row| {
                row.chunks_exact(3)
                    .zip(row.chunks_exact(3).skip(1))
                    .map(|(a, b)| (a[0] - b[0]).abs())
            })
            .fold(0f32, f32::max);
        assert!(step < 0.5, "{step}");
    }

    #[test]
    fn a_shifted_press_moves_its_truth() {
        let cfg = MockConfig::new(SensorKind::DIGIT, 1);
        let sc = Scenario::held(&crate::Object::sphere("ball", 5.0), 0.5, 1.0);
        let d = Degrade {
            shading_dn: 0.0,
            noise_dn: 0.0,
            shift: (0, 0),
            seed: 1,
        };
        let a = press_fixture(&cfg, SensorKind::DIGIT.spec(), &sc, "ball", d).unwrap();
        let b = press_fixture(
            &cfg,
            SensorKind::DIGIT.spec(),
            &sc,
            "ball",
            Degrade {
                shift: (-48, 24),
                ..d
            },
        )
        .unwrap();
        assert!(a.contact_px > 100 && a.contact_px == b.contact_px);
        assert!((a.centroid[0] - 48.0 - b.centroid[0]).abs() < 1e-9);
        assert!((a.centroid[1] + 24.0 - b.centroid[1]).abs() < 1e-9);
    }
}
