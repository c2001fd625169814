//! `unitac-lab eval contact`: detection quality against the mock sensor's ground truth.
//!
//! Press-depth sweep from barely touching to deep, on GelSight Mini and DIGIT renders with noise
//! (1 DN) and illumination drift (LED warm-up + wander), at 25 fps. A frame is a positive when the
//! penetration exceeds `POSITIVE_MM`, a negative when nothing touches; frames in between (the
//! first and last instants of a touch) are reported per depth but not scored. Then ten simulated
//! minutes with drift and noise and no contact, counting false episodes. Last, the contact
//! region's area against the physical contact disc on ball presses of a Hertz gel
//! (`unitac_sim::ballpress`), where the scenario renderer's own truth mask is not physical.

use serde::Serialize;
use unitac_contact::{ContactDetector, ContactParams};
use unitac_core::{Msg, SensorKind};
use unitac_sim::ballpress::Skirt;
use unitac_sim::{Drift, MockConfig, MockSensor, Scenario};

/// Penetration above which a frame must be detected \[mm].
pub const POSITIVE_MM: f64 = 0.05;
/// Hold depths of the sweep \[mm].
pub const DEPTHS: [f64; 10] = [0.01, 0.02, 0.03, 0.05, 0.08, 0.12, 0.2, 0.35, 0.6, 1.0];

#[derive(Debug, Serialize)]
pub struct DepthRow {
    pub depth_mm: f64,
    /// Share of the hold frames at this depth that were in contact.
    pub detected: f64,
    /// Mean IoU of detected and true contact masks over those frames.
    pub iou: f64,
}

#[derive(Debug, Serialize)]
pub struct SensorReport {
    pub sensor: String,
    pub positives: u64,
    pub negatives: u64,
    pub precision: f64,
    pub recall: f64,
    pub f1: f64,
    /// Mean IoU over true-positive frames.
    pub mean_iou: f64,
    pub depths: Vec<DepthRow>,
    pub idle_minutes: f64,
    pub idle_false_episodes: u64,
    pub idle_false_frames: u64,
}

#[derive(Debug, Serialize)]
pub struct EvalReport {
    pub positive_mm: f64,
    pub sensors: Vec<SensorReport>,
    /// The contact region's area against the physical disc on mock ball presses.
    pub ball_presses: Vec<BallAreaRow>,
}

/// Area of the contact region on ball presses (`unitac_sim::ballpress`: a Hertz gel with its
/// skirt), one background image as `unitac contact` runs, against the Hertz disc pi R d and the
/// geometric one pi (2 R d - d^2).
#[derive(Debug, Serialize)]
pub struct BallAreaRow {
    pub sensor: String,
    /// The gel's skirt around the press (`unitac_sim::ballpress::Skirt`).
    pub skirt: String,
    /// The contact stage's `peel_skirt`: the region ended at the press's ridge.
    pub peel_skirt: bool,
    pub ball_radius_mm: f64,
    pub approach_mm: f64,
    pub presses: usize,
    pub found: usize,
    pub area_over_hertz: f64,
    pub area_over_geometric: f64,
}

/// Approaches of the ball presses \[mm].
pub const BALL_APPROACHES: [f64; 5] = [0.2, 0.4, 0.6, 0.8, 1.0];

/// The skirts of the sweep beside the default one (the surface a GelSight gel's published
/// finite-element response gives, `Skirt::Fem`), at [`SWEEP_APPROACHES`]: Hertz's profile faded
/// over a thin layer to a thick one, and the whole half-space.
pub const SWEEP_SKIRTS: [Skirt; 5] = [
    Skirt::Layer { thickness_mm: 0.5 },
    Skirt::Layer { thickness_mm: 1.0 },
    Skirt::Layer { thickness_mm: 2.0 },
    Skirt::Layer { thickness_mm: 4.0 },
    Skirt::HalfSpace,
];
pub const SWEEP_APPROACHES: [f64; 3] = [0.2, 0.6, 1.0];

/// The ball presses' rows of one sensor: the default skirt at every approach, then the sweep,
/// then every skirt again with the region at the half-level contour alone (`peel_skirt` off).
fn ball_areas(kind: SensorKind) -> anyhow::Result<Vec<BallAreaRow>> {
    let default = ContactParams::default().peel_skirt;
    let mut rows = Vec::new();
    for approach in BALL_APPROACHES {
        rows.push(ball_area(kind, Skirt::default(), approach, default)?);
    }
    for peel in [default, !default] {
        for skirt in std::iter::once(Skirt::default()).chain(SWEEP_SKIRTS) {
            for approach in SWEEP_APPROACHES {
                if peel == default && skirt == Skirt::default() {
                    continue;
                }
                rows.push(ball_area(kind, skirt, approach, peel)?);
            }
        }
    }
    Ok(rows)
}

fn ball_area(
    kind: SensorKind,
    skirt: Skirt,
    approach: f64,
    peel_skirt: bool,
) -> anyhow::Result<BallAreaRow> {
    use unitac_sim::ballpress::{BallPress, PressNoise, render_presses_with};
    let spec = kind.spec();
    let mut cfg = MockConfig::new(kind, 11);
    cfg.markers = false;
    let radius_mm = 2.0;
    let presses: Vec<BallPress> = [[110.0, 95.0], [210.0, 140.0], [160.0, 120.0]]
        .iter()
        .map(|c| BallPress {
            center_px: *c,
            radius_mm,
            approach_mm: approach,
        })
        .collect();
    let noise = PressNoise {
        noise_dn: 1.0,
        shading_dn: 0.0,
        seed: 5,
    };
    let (bg, rendered) = render_presses_with(&cfg, spec, &presses, noise, skirt)
        .ok_or_else(|| anyhow::anyhow!("rendering ball presses"))?;
    let params = ContactParams {
        peel_skirt,
        ..ContactParams::default()
    };
    let mut det = ContactDetector::new(params, spec).map_err(anyhow::Error::msg)?;
    det.set_background_frame(&bg);
    let (mut found, mut h, mut g) = (0usize, 0f64, 0f64);
    for p in &rendered {
        let m = det.measure(&p.frame).map_err(anyhow::Error::msg)?;
        if m.area_px <= 0.0 {
            continue;
        }
        found += 1;
        let area = f64::from(m.area_px) * spec.m2_per_px() * 1e6;
        h += area / (std::f64::consts::PI * p.press.contact_radius_mm().powi(2));
        g += area / (std::f64::consts::PI * p.press.geometric_radius_mm().powi(2));
    }
    let n = found.max(1) as f64;
    Ok(BallAreaRow {
        sensor: kind.to_string(),
        skirt: skirt.to_string(),
        peel_skirt,
        ball_radius_mm: radius_mm,
        approach_mm: approach,
        presses: rendered.len(),
        found,
        area_over_hertz: h / n,
        area_over_geometric: g / n,
    })
}

fn iou(a: &[bool], b: &[bool]) -> f64 {
    let (mut i, mut u) = (0u64, 0u64);
    for (&x, &y) in a.iter().zip(b) {
        i += u64::from(x && y);
        u += u64::from(x || y);
    }
    if u == 0 { 1.0 } else { i as f64 / u as f64 }
}

fn eval_sensor(kind: SensorKind, idle_s: f64) -> anyhow::Result<SensorReport> {
    let mut cfg = MockConfig::new(kind, 2024);
    cfg.fps = 25.0;
    cfg.drift = Drift::warmup();
    let object = Scenario::fabric("sweep", 0.03, 0.8);
    let mut sensor = MockSensor::new(cfg.clone(), Scenario::press_sweep(&object, &DEPTHS));
    let mut det =
        ContactDetector::new(ContactParams::default(), kind.spec()).map_err(anyhow::Error::msg)?;
    let (mut tp, mut fp, mut fneg, mut tn) = (0u64, 0u64, 0u64, 0u64);
    let (mut iou_sum, mut iou_n) = (0.0, 0u64);
    let mut per_depth: Vec<(u64, u64, f64)> = vec![(0, 0, 0.0); DEPTHS.len()];
    while let Some((f, truth)) = sensor.next_with_truth() {
        let out = det.step(&f).map_err(|e| anyhow::anyhow!("{e}"))?;
        let Some(Msg::ContactState(c)) = out.first() else {
            continue;
        };
        let pen = truth.penetration_mm;
        let overlap = if c.in_contact && truth.contact_px > 0 {
            Some(iou(&det.mask_px(), &truth.mask))
        } else {
            None
        };
        if pen > POSITIVE_MM {
            if c.in_contact {
                tp += 1;
            } else {
                fneg += 1;
            }
            if let Some(v) = overlap {
                iou_sum += v;
                iou_n += 1;
            }
        } else if pen == 0.0 {
            if c.in_contact {
                fp += 1;
            } else {
                tn += 1;
            }
        }
        // Hold phases sit exactly at one of the sweep depths.
        if let Some(k) = DEPTHS.iter().position(|&d| (d - pen).abs() < 1e-12) {
            let row = &mut per_depth[k];
            row.0 += 1;
            row.1 += u64::from(c.in_contact);
            row.2 += overlap.unwrap_or(0.0);
        }
    }
    let precision = tp as f64 / (tp + fp).max(1) as f64;
    let recall = tp as f64 / (tp + fneg).max(1) as f64;
    let f1 = if precision + recall > 0.0 {
        2.0 * precision * recall / (precision + recall)
    } else {
        0.0
    };

    // Long idle run with drift and noise.
    let mut idle = MockSensor::new(cfg, Scenario::idle(idle_s));
    let mut det =
        ContactDetector::new(ContactParams::default(), kind.spec()).map_err(anyhow::Error::msg)?;
    let (mut episodes, mut frames_on) = (0u64, 0u64);
    while let Some((f, _)) = idle.next_with_truth() {
        for m in det.step(&f).map_err(|e| anyhow::anyhow!("{e}"))? {
            match m {
                Msg::ContactEpisode(_) => episodes += 1,
                Msg::ContactState(c) if c.in_contact => frames_on += 1,
                _ => {}
            }
        }
    }
    episodes += det.flush("idle").len() as u64;

    Ok(SensorReport {
        sensor: kind.as_str().into(),
        positives: tp + fneg,
        negatives: tn + fp,
        precision,
        recall,
        f1,
        mean_iou: if iou_n > 0 {
            iou_sum / iou_n as f64
        } else {
            0.0
        },
        depths: DEPTHS
            .iter()
            .zip(&per_depth)
            .map(|(&d, &(n, on, iou))| DepthRow {
                depth_mm: d,
                detected: on as f64 / n.max(1) as f64,
                iou: if on > 0 { iou / on as f64 } else { 0.0 },
            })
            .collect(),
        idle_minutes: idle_s / 60.0,
        idle_false_episodes: episodes,
        idle_false_frames: frames_on,
    })
}

pub fn eval_contact(idle_s: f64) -> anyhow::Result<EvalReport> {
    let sensors = [SensorKind::GELSIGHT_MINI, SensorKind::DIGIT]
        .into_iter()
        .map(|k| eval_sensor(k, idle_s))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let mut ball_presses = ball_areas(SensorKind::GELSIGHT_MINI)?;
    ball_presses.extend(ball_areas(SensorKind::DIGIT)?);
    Ok(EvalReport {
        positive_mm: POSITIVE_MM,
        sensors,
        ball_presses,
    })
}

impl EvalReport {
    pub fn text(&self) -> String {
        use std::fmt::Write;
        let mut s = String::new();
        let _ = writeln!(
            s,
            "contact quality on mock renders (noise 1 DN, LED warm-up + wander drift, 25 fps)"
        );
        let _ = writeln!(
            s,
            "positives: penetration > {} mm; negatives: no touch",
            self.positive_mm
        );
        for r in &self.sensors {
            let _ = writeln!(
                s,
                "\n{}: precision {:.4}  recall {:.4}  F1 {:.4}  mean IoU {:.3}  ({} positive, {} negative frames)",
                r.sensor, r.precision, r.recall, r.f1, r.mean_iou, r.positives, r.negatives
            );
            let _ = writeln!(s, "  hold depth [mm]  detected  IoU");
            for d in &r.depths {
                let _ = writeln!(
                    s,
                    "  {:>14.2}  {:>8.3}  {:.3}",
                    d.depth_mm, d.detected, d.iou
                );
            }
            let _ = writeln!(
                s,
                "  {:.0} min without contact: {} false episodes, {} false contact frames",
                r.idle_minutes, r.idle_false_episodes, r.idle_false_frames
            );
        }
        let _ = writeln!(
            s,
            "\ncontact area on ball presses (R 2 mm, Hertz pressure on a GelSight gel's finite-element response, noise 1 DN, one background image)\n  sensor         approach [mm]  found  area / Hertz disc  area / geometric disc"
        );
        let default_skirt = Skirt::default().to_string();
        let default_peel = ContactParams::default().peel_skirt;
        for b in self
            .ball_presses
            .iter()
            .filter(|b| b.skirt == default_skirt && b.peel_skirt == default_peel)
        {
            let _ = writeln!(
                s,
                "  {:<13}  {:>13.2}  {:>2}/{:<2}  {:>17.3}  {:>21.3}",
                b.sensor,
                b.approach_mm,
                b.found,
                b.presses,
                b.area_over_hertz,
                b.area_over_geometric
            );
        }
        for (peel, title) in [
            (default_peel, "the same by skirt"),
            (
                !default_peel,
                "the same by skirt, the region at the residual's half-level contour alone (peel_skirt: false)",
            ),
        ] {
            let _ = writeln!(
                s,
                "\n{title}: area over the Hertz disc, over the geometric disc\n  sensor         skirt        {}",
                SWEEP_APPROACHES.map(|a| format!("{a:>9.1} mm")).join("")
            );
            self.skirt_rows(&mut s, peel);
        }
        s
    }

    /// One row per sensor and skirt: area over the Hertz and geometric discs per approach.
    fn skirt_rows(&self, s: &mut String, peel: bool) {
        use std::fmt::Write as _;
        for kind in [SensorKind::GELSIGHT_MINI, SensorKind::DIGIT] {
            for skirt in std::iter::once(Skirt::default()).chain(SWEEP_SKIRTS) {
                let name = skirt.to_string();
                let cells: String = SWEEP_APPROACHES
                    .iter()
                    .filter_map(|&a| {
                        self.ball_presses.iter().find(|b| {
                            b.sensor == kind.to_string()
                                && b.skirt == name
                                && b.approach_mm == a
                                && b.peel_skirt == peel
                        })
                    })
                    .map(|b| {
                        format!(
                            "  {:>5.2} {:>5.2}",
                            b.area_over_hertz, b.area_over_geometric
                        )
                    })
                    .collect();
                let _ = writeln!(s, "  {:<13}  {name:<13}{cells}", kind.to_string());
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The goal as a regression guard: F1 >= 0.98 on frames deeper than POSITIVE_MM.
    #[test]
    fn sweep_meets_the_f1_goal_on_both_sensors() {
        let r = eval_contact(0.0).unwrap();
        for s in &r.sensors {
            assert!(s.f1 >= 0.98, "{}: F1 {}", s.sensor, s.f1);
            assert!(s.positives > 100 && s.negatives > 200);
            // Deep presses are always found, and their masks overlap the truth.
            let deep = s.depths.iter().find(|d| d.depth_mm == 0.35).unwrap();
            assert_eq!(deep.detected, 1.0);
            assert!(deep.iou > 0.8, "{}: {}", s.sensor, deep.iou);
            // What is found at 0.01 mm (the contact region's growth can lift a real 0.01 mm
            // touch over the enter area on some frames) is the press, not noise: it overlaps
            // the true contact. Noise is never a contact: none in the idle minutes.
            let lightest = &s.depths[0];
            assert_eq!(lightest.depth_mm, 0.01);
            assert!(
                lightest.detected == 0.0 || lightest.iou > 0.8,
                "{}: {:?}",
                s.sensor,
                lightest
            );
            assert_eq!((s.idle_false_episodes, s.idle_false_frames), (0, 0));
        }
        // Every ball press is found on both sensors, at every skirt, with either region rule.
        assert_eq!(
            r.ball_presses.len(),
            2 * (BALL_APPROACHES.len() + (2 * SWEEP_SKIRTS.len() + 1) * SWEEP_APPROACHES.len())
        );
        // The region is the contact, not its skirt. Ended at the press's ridge (the default),
        // it reads 0.9-1.5x the Hertz disc on every skirt, where the ball leaves the surface:
        // the skirt's width no longer matters. The half-level contour alone reads a thin
        // layer's steep skirt as contact (up to 2.5x).
        for b in &r.ball_presses {
            assert_eq!(b.found, b.presses, "{b:?}");
            if b.peel_skirt {
                assert!((0.9..=1.5).contains(&b.area_over_hertz), "{b:?}");
            } else {
                assert!((1.0..=2.7).contains(&b.area_over_hertz), "{b:?}");
            }
        }
        let widest = |peel: bool| {
            r.ball_presses
                .iter()
                .filter(|b| b.peel_skirt == peel)
                .map(|b| b.area_over_hertz)
                .fold(0.0, f64::max)
        };
        assert!(widest(false) > 2.0 && widest(true) < 1.5);
    }
}
