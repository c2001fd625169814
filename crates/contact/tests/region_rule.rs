//! The contact region's rule (`region: auto | depth | residual`): where the detector's area,
//! centroid, box and `mask_px` come from, on mock ball presses with exact depth
//! (unitac_sim::ballpress) and the GelSight Mini profile's default photometric model.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use unitac_contact::{ContactDetector, ContactParams, RegionRule};
use unitac_core::{Frame, SensorKind};
use unitac_sim::MockConfig;
use unitac_sim::ballpress::{BallPress, PressNoise, render_presses};

const BALL_MM: f64 = 2.0;

fn presses(approach_mm: &[f64]) -> (Frame, Vec<(Frame, BallPress)>) {
    presses_of(
        SensorKind::GELSIGHT_MINI,
        approach_mm,
        ([120.0, 100.0], [40.0, 10.0]),
        21,
    )
}

/// Ball presses of `kind`'s mock gel (no markers): the i-th at `start + i * step` px.
fn presses_of(
    kind: SensorKind,
    approach_mm: &[f64],
    (start, step): ([f64; 2], [f64; 2]),
    seed: u64,
) -> (Frame, Vec<(Frame, BallPress)>) {
    let mut cfg = MockConfig::new(kind, 11);
    cfg.markers = false;
    let ps: Vec<BallPress> = approach_mm
        .iter()
        .enumerate()
        .map(|(i, &d)| BallPress {
            center_px: [start[0] + step[0] * i as f64, start[1] + step[1] * i as f64],
            radius_mm: BALL_MM,
            approach_mm: d,
        })
        .collect();
    let noise = PressNoise {
        noise_dn: 1.0,
        shading_dn: 0.0,
        seed,
    };
    let (bg, rendered) = render_presses(&cfg, kind.spec(), &ps, noise).unwrap();
    (
        bg,
        rendered.into_iter().map(|p| (p.frame, p.press)).collect(),
    )
}

fn detector(region: RegionRule, bg: &Frame) -> ContactDetector {
    detector_of(SensorKind::GELSIGHT_MINI, region, bg)
}

fn detector_of(kind: SensorKind, region: RegionRule, bg: &Frame) -> ContactDetector {
    let p = ContactParams {
        region,
        ..ContactParams::default()
    };
    let mut det = ContactDetector::new(p, kind.spec()).unwrap();
    det.set_background_frame(bg);
    det
}

/// `depth` on GelSight Mini takes the region from the profile's default model: the half-depth
/// contour, within x1.5 of the Hertz contact disc (the mock's photometric model is not the real
/// gel's, so this holds the rule's plumbing, not its calibration: the real frames' test does
/// that), its centroid within a quarter of the contact radius of the press's; `residual` and `auto` without a calibration keep the
/// residual's region.
#[test]
fn region_depth_reads_ball_presses_through_the_kinds_default_model() {
    let (bg, frames) = presses(&[0.4, 0.7, 1.0]);
    let spec = SensorKind::GELSIGHT_MINI.spec();
    for rule in [RegionRule::Depth, RegionRule::Auto, RegionRule::Residual] {
        let mut det = detector(rule, &bg);
        for (f, p) in &frames {
            let m = det.measure(f).unwrap();
            assert_eq!(m.from_depth, rule == RegionRule::Depth, "{rule:?}");
            assert!(m.contact, "{rule:?} {p:?}");
            let disc_px =
                std::f64::consts::PI * (p.contact_radius_mm() / (spec.m_per_px() * 1e3)).powi(2);
            let ratio = f64::from(m.area_px) / disc_px;
            assert!(
                (1.0 / 1.5..1.5).contains(&ratio),
                "{rule:?} {p:?}: {ratio:.2}x"
            );
            let off = f64::from(m.centroid[0]) - p.center_px[0];
            let off = off.hypot(f64::from(m.centroid[1]) - p.center_px[1]);
            assert!(
                off < 0.25 * disc_px.sqrt() / std::f64::consts::PI.sqrt(),
                "{rule:?} {p:?}: centroid {:?}",
                m.centroid
            );
            // mask_px is the region the area counts.
            let mask = det.mask_px();
            let n = mask.iter().filter(|v| **v).count() as f32;
            assert!(
                (n - m.area_px).abs() <= 0.02 * m.area_px,
                "{rule:?}: {n} vs {}",
                m.area_px
            );
            // The depth is estimated only where the region needs it.
            assert_eq!(
                det.depth().and_then(|(_, s)| s).is_some(),
                rule == RegionRule::Depth
            );
        }
    }
}

/// A frame without deformation: no depth is estimated (a frame at rest costs no Poisson solve)
/// unless every frame's depth is asked for; and no contact either way.
#[test]
fn depth_is_estimated_only_on_deformed_frames_unless_asked_for_every_frame() {
    let (bg, _) = presses(&[0.5]);
    for every in [false, true] {
        let mut det = detector(RegionRule::Depth, &bg);
        det.estimate_depth_every_frame(every);
        let m = det.measure(&bg).unwrap();
        assert!(!m.contact && m.area_px == 0.0, "{m:?}");
        let estimated = det.depth().and_then(|(_, s)| s);
        assert_eq!(estimated.is_some(), every);
        if let Some(s) = estimated {
            assert!(!s.contact, "the background against itself: {s:?}");
        }
        assert!(det.mask_px().iter().all(|v| !v));
    }
}

/// A kind without a photometric model (DIGIT) takes its depth region from a model fitted on each
/// frame (`depth::selfcal`, up to scale: no penetration in metres); `auto` there is the residual,
/// with no depth at all.
#[test]
fn region_depth_on_a_kind_without_a_model_fits_one_on_each_frame() {
    let p = ContactParams {
        region: RegionRule::Depth,
        ..ContactParams::default()
    };
    let det = ContactDetector::new(p, SensorKind::DIGIT.spec()).unwrap();
    assert_eq!(det.depth_model(), Some("self-calibrated"));
    let auto = ContactParams::default();
    assert_eq!(auto.region, RegionRule::Auto);
    let det = ContactDetector::new(auto, SensorKind::DIGIT.spec()).unwrap();
    assert!(det.depth_model().is_none());
}

/// Frames of another aspect ratio than the model's: `depth` refuses each one with the reason (the
/// detector is otherwise unchanged); `residual` measures them.
#[test]
fn region_depth_refuses_frames_the_model_does_not_fit() {
    let (bg, frames) = presses(&[0.6]);
    // 320 x 200: the top 200 rows.
    let crop = |f: &Frame| {
        Frame::new(
            &f.sensor_id,
            f.seq,
            f.stamp,
            320,
            200,
            f.data()[..320 * 200 * 3].to_vec(),
        )
        .unwrap()
    };
    let (bg, press) = (crop(&bg), crop(&frames[0].0));
    let mut det = detector(RegionRule::Depth, &bg);
    assert!(det.depth_unusable().is_some());
    let err = det.measure(&press).unwrap_err().to_string();
    assert!(err.contains("region: depth"), "{err}");
    let mut det = detector(RegionRule::Residual, &bg);
    assert!(det.measure(&press).unwrap().contact);
}

/// A gel without a model (the same GelSight Mini mock presses read as `generic`, and DIGIT's own
/// mock presses): `region: depth` fits a linear model on each frame's press and reads the Hertz
/// contact disc within x1.5, its centroid within a quarter radius; the depth has no scale, so no
/// penetration in metres.
#[test]
fn a_self_calibrated_depth_reads_ball_presses_on_a_gel_without_a_model() {
    let (bg, frames) = presses(&[0.4, 0.7, 1.0]);
    let (digit_bg, digit_frames) = presses_of(
        SensorKind::DIGIT,
        &[0.4, 0.7, 1.0],
        ([110.0, 150.0], [40.0, -20.0]),
        22,
    );
    // (kind read as, kind rendered, background, presses)
    for (kind, rendered, bg, frames) in [
        (SensorKind::GENERIC, SensorKind::GELSIGHT_MINI, &bg, &frames),
        (
            SensorKind::DIGIT,
            SensorKind::DIGIT,
            &digit_bg,
            &digit_frames,
        ),
    ] {
        let mut det = detector_of(kind, RegionRule::Depth, bg);
        assert_eq!(det.depth_model(), Some("self-calibrated"));
        let m_per_px = rendered.spec().m_per_px();
        for (f, p) in frames {
            let m = det.measure(f).unwrap();
            assert!(m.from_depth && m.contact, "{kind} {p:?}: {m:?}");
            let r_px = p.contact_radius_mm() / (m_per_px * 1e3);
            let ratio = f64::from(m.area_px) / (std::f64::consts::PI * r_px * r_px);
            assert!(
                (1.0 / 1.5..1.5).contains(&ratio),
                "{kind} {p:?}: {ratio:.2}x"
            );
            let off = (f64::from(m.centroid[0]) - p.center_px[0])
                .hypot(f64::from(m.centroid[1]) - p.center_px[1]);
            assert!(off < 0.25 * r_px, "{kind} {p:?}: centroid {:?}", m.centroid);
            let (_, s) = det.depth().unwrap();
            assert!(
                s.unwrap().penetration_m.is_nan(),
                "no scale, no penetration"
            );
            // Nor a depth map in metres to draw or publish.
            assert!(det.depth_map_m().unwrap().iter().all(|v| v.is_nan()));
        }
        // The gel at rest: no contact.
        assert!(!det.measure(bg).unwrap().contact);
    }
}

/// A change that is no gel's shading (a grey square brighter on every channel alike: colour
/// changes along one line) gives a self-calibration no model: that frame's region is the
/// residual's, not "no contact".
#[test]
fn a_press_with_no_self_calibrated_model_reads_the_residuals_region() {
    let (w, h) = (80u32, 60u32);
    let img = |pressed: bool| {
        let mut data = Vec::with_capacity((w * h * 3) as usize);
        for y in 0..h {
            for x in 0..w {
                let v = 100 + ((x * 7 + y * 13) % 5) as u8;
                let v = if pressed && (25..55).contains(&x) && (15..45).contains(&y) {
                    v + 60
                } else {
                    v
                };
                data.extend_from_slice(&[v, v, v]);
            }
        }
        Frame::new("s", 0, unitac_core::Stamp::ZERO, w, h, data).unwrap()
    };
    let p = ContactParams {
        region: RegionRule::Depth,
        ..ContactParams::default()
    };
    let mut det = ContactDetector::new(p, SensorKind::GENERIC.spec()).unwrap();
    det.set_background_frame(&img(false));
    let m = det.measure(&img(true)).unwrap();
    assert!(m.contact && !m.from_depth, "{m:?}");
    assert!((700.0..1100.0).contains(&m.area_px), "{m:?}");
    assert_eq!(
        det.mask_px().iter().filter(|v| **v).count() as f32,
        m.area_px
    );
}
