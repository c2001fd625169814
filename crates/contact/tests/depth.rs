//! Depth from one image on mock ball presses with exact depth (unitac_sim::ballpress):
//! calibrate from presses, then measure depth, penetration and contact area on other presses.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use unitac_contact::depth::{
    Circle, DepthCalibration, DepthError, DepthEstimator, DepthParams, Fit, Prep, Terms,
    find_circle, prepare,
};
use unitac_core::{SensorKind, SensorSpec};
use unitac_sim::MockConfig;
use unitac_sim::ballpress::{BallPress, PressNoise, random_presses, render_presses};

const BALL_MM: f64 = 2.0;

fn cfg() -> MockConfig {
    let mut c = MockConfig::new(SensorKind::GELSIGHT_MINI, 11);
    c.markers = false;
    c
}

fn calibrate(spec: SensorSpec, noise_dn: f64) -> (DepthCalibration, Vec<(Circle, BallPress)>) {
    let presses = random_presses(spec, 40, BALL_MM, (0.3, 1.0), 5);
    let (bg, rendered) = render_presses(
        &cfg(),
        spec,
        &presses,
        PressNoise {
            noise_dn,
            shading_dn: 0.0,
            seed: 9,
        },
    )
    .unwrap();
    let (w, h) = (spec.width as usize, spec.height as usize);
    let mut prep = Prep::default();
    let mut fit = Fit::default();
    let mut found = Vec::new();
    for p in &rendered {
        prepare(&mut prep, &p.frame, &bg).unwrap();
        let Some(c) = find_circle(&prep.diff, w, h) else {
            continue;
        };
        fit.add_press(&prep.diff, w, h, c, BALL_MM * 1e-3, spec.m_per_px());
        found.push((c, p.press));
    }
    let cal = fit
        .finish(
            Terms::All,
            spec.kind,
            "MOCK-0001",
            (spec.width, spec.height),
            spec.m_per_px(),
            BALL_MM * 1e-3,
        )
        .unwrap();
    (cal, found)
}

struct Score {
    rmse_mm: f64,
    pen_err_mm: f64,
    area_ratio: f64,
}

fn evaluate(cal: &DepthCalibration, spec: SensorSpec, approach: f64, noise: PressNoise) -> Score {
    let presses: Vec<BallPress> = [[120.0, 100.0], [200.0, 140.0], [160.0, 120.0]]
        .iter()
        .map(|c| BallPress {
            center_px: [
                c[0] * f64::from(spec.width) / 320.0,
                c[1] * f64::from(spec.height) / 240.0,
            ],
            radius_mm: BALL_MM,
            approach_mm: approach,
        })
        .collect();
    let (bg, rendered) = render_presses(&cfg(), spec, &presses, noise).unwrap();
    let mut est = DepthEstimator::new(cal.clone(), bg, DepthParams::default()).unwrap();
    let (mut se, mut n, mut pen, mut area) = (0f64, 0usize, 0f64, 0f64);
    for p in &rendered {
        let s = est.estimate(&p.frame).unwrap();
        // The renderer's truth is in mm of gel.
        for (a, b) in est.depth_m().iter().zip(&p.depth_mm) {
            se += f64::from(a * 1e3 - b).powi(2);
            n += 1;
        }
        pen = f64::max(pen, (f64::from(s.penetration_m) * 1e3 - approach).abs());
        let disc = std::f64::consts::PI * p.press.contact_radius_mm().powi(2);
        area += s.area_m2 * 1e6 / disc / rendered.len() as f64;
    }
    Score {
        rmse_mm: (se / n as f64).sqrt(),
        pen_err_mm: pen,
        area_ratio: area,
    }
}

#[test]
fn circles_are_found_where_the_presses_are() {
    let spec = SensorKind::GELSIGHT_MINI.spec();
    let (_, found) = calibrate(spec, 1.0);
    assert!(found.len() >= 38, "{} of 40 presses found", found.len());
    for (c, p) in &found {
        let a = p.contact_radius_mm() / spec.mm_per_px;
        let off = (c.x - p.center_px[0]).hypot(c.y - p.center_px[1]);
        assert!(off < 1.5, "centre off by {off} px");
        // The ring of largest slope sits a pixel or two inside the contact edge (the 3 x 3 mean
        // and the skirt's slope falling off just outside it); the fit uses 0.9 of it.
        assert!(
            c.r < a + 1.0 && c.r > 0.85 * a - 1.0,
            "radius {} vs {a}",
            c.r
        );
    }
}

#[test]
fn depth_from_a_calibration_matches_the_truth_under_noise_and_shading() {
    let spec = SensorKind::GELSIGHT_MINI.spec();
    let (cal, _) = calibrate(spec, 1.0);
    eprintln!("fit rms slope {:.4}", cal.fit_rms_slope);
    let mut bad = false;
    for approach in [0.3, 0.6, 0.9] {
        for (noise_dn, shading_dn) in [(1.0, 0.0), (4.0, 0.0), (1.0, 20.0), (4.0, 20.0)] {
            let s = evaluate(
                &cal,
                spec,
                approach,
                PressNoise {
                    noise_dn,
                    shading_dn,
                    seed: 77,
                },
            );
            eprintln!(
                "d {approach} noise {noise_dn} shading {shading_dn}: rmse {:.4} mm, penetration error {:.4} mm, area / disc {:.3}",
                s.rmse_mm, s.pen_err_mm, s.area_ratio
            );
            bad |= s.rmse_mm >= 0.03
                || s.pen_err_mm >= 0.05 * approach + 0.01
                || !(0.8..1.15).contains(&s.area_ratio);
        }
    }
    assert!(!bad);
}

#[test]
fn a_calibration_applies_at_twice_the_size_and_refuses_another_aspect() {
    let spec = SensorKind::GELSIGHT_MINI.spec();
    let (cal, _) = calibrate(spec, 1.0);
    let big = spec.scaled(2);
    let s = evaluate(
        &cal,
        big,
        0.6,
        PressNoise {
            noise_dn: 1.0,
            shading_dn: 0.0,
            seed: 3,
        },
    );
    eprintln!(
        "640x480: rmse {:.4}, penetration error {:.4}, area / disc {:.3}",
        s.rmse_mm, s.pen_err_mm, s.area_ratio
    );
    assert!(
        s.rmse_mm < 0.03 && s.pen_err_mm < 0.04,
        "{} {}",
        s.rmse_mm,
        s.pen_err_mm
    );
    assert!((0.8..1.15).contains(&s.area_ratio), "{}", s.area_ratio);
    let odd = unitac_core::Frame::new(
        "x",
        0,
        unitac_core::Stamp::ZERO,
        320,
        320,
        vec![0; 320 * 320 * 3],
    )
    .unwrap();
    let err = DepthEstimator::new(cal.clone(), odd, DepthParams::default()).unwrap_err();
    assert!(matches!(err, DepthError::SizeMismatch { .. }), "{err}");
    assert!(cal.check_serial("OTHER-0002").is_err());
    assert!(cal.check_serial("MOCK-0001").is_ok());
}

/// The contact stage with a depth calibration reports the press's physical contact area (the
/// half-depth contour); without it, the colour residual's region, here at its half-level contour
/// alone (`peel_skirt: false`), a larger one.
#[test]
fn the_contact_stage_takes_its_area_from_depth_when_a_scene_gives_a_calibration() {
    use unitac_contact::{ContactParams, ContactStage};
    use unitac_core::{Msg, Stage, Stamp};
    let spec = SensorKind::GELSIGHT_MINI.spec();
    let (cal, _) = calibrate(spec, 1.0);
    let press = BallPress {
        center_px: [150.0, 110.0],
        radius_mm: BALL_MM,
        approach_mm: 0.6,
    };
    let noise = PressNoise {
        noise_dn: 1.0,
        shading_dn: 0.0,
        seed: 13,
    };
    let (bg, rendered) = render_presses(&cfg(), spec, &[press, press, press], noise).unwrap();
    let disc = std::f64::consts::PI * press.contact_radius_mm().powi(2);
    let clock = unitac_core::ManualClock::new(Stamp::ZERO);
    let mut last = Vec::new();
    for with_depth in [false, true] {
        let params = ContactParams {
            peel_skirt: false,
            ..ContactParams::default()
        };
        let stage = ContactStage::new(params, spec).unwrap();
        let mut stage = if with_depth {
            stage.with_depth(cal.clone())
        } else {
            stage
        };
        let mut area = None;
        let frames = std::iter::repeat_n(&bg, 12).chain(rendered.iter().map(|p| &p.frame));
        for (seq, f) in frames.enumerate() {
            let mut f = f.clone();
            f.seq = seq as u64;
            f.stamp = Stamp(seq as i64 * 40_000_000);
            for m in stage.process(&Msg::Frame(f), &clock).unwrap() {
                if let Msg::ContactState(cs) = m {
                    if cs.in_contact {
                        area = Some((f64::from(cs.area_m2) * 1e6, cs.centroid_px));
                    }
                }
            }
        }
        let (a, c) = area.expect("in contact");
        last.push(a / disc);
        if with_depth {
            assert!(
                (0.8..1.15).contains(&(a / disc)),
                "area {a} mm^2, disc {disc}"
            );
            let off = f64::from(c[0] - 150.0).hypot(f64::from(c[1] - 110.0));
            assert!(off < 1.5, "{c:?}");
        }
    }
    // Without a calibration the colour residual's half-level region lies between the Hertz disc
    // and the geometric one (2x at this depth), off depth's reading: the depth path is the one
    // taken.
    assert!((1.0..2.0).contains(&last[0]), "{last:?}");
    assert!(last[0] - last[1] > 0.2, "{last:?}");
}

/// With a calibration, every frame after the background gets its depth map (metres, NaN under
/// the marker dots, the press's penetration at its peak, in the optical frame); the overlay
/// picture comes only with the `overlay` param.
#[test]
fn the_contact_stage_emits_a_depth_map_per_frame_and_an_overlay_only_when_asked() {
    use unitac_contact::overlay::{CENTROID, OUTLINE};
    use unitac_contact::{ContactParams, ContactStage};
    use unitac_core::{Msg, Stage, Stamp};
    let spec = SensorKind::GELSIGHT_MINI.spec();
    let (cal, _) = calibrate(spec, 1.0);
    let press = BallPress {
        center_px: [150.0, 110.0],
        radius_mm: BALL_MM,
        approach_mm: 0.6,
    };
    let noise = PressNoise {
        noise_dn: 1.0,
        shading_dn: 0.0,
        seed: 13,
    };
    // With the marker dots this time.
    let mut marked = cfg();
    marked.markers = true;
    let (bg, rendered) = render_presses(&marked, spec, &[press, press, press], noise).unwrap();
    let clock = unitac_core::ManualClock::new(Stamp::ZERO);
    for overlay in [false, true] {
        let p = ContactParams {
            overlay,
            ..Default::default()
        };
        let mut stage = ContactStage::new(p, spec).unwrap().with_depth(cal.clone());
        let (mut depths, mut overlays, mut last) = (0, Vec::new(), None);
        let frames = std::iter::repeat_n(&bg, 12).chain(rendered.iter().map(|p| &p.frame));
        for (seq, f) in frames.enumerate() {
            let mut f = f.clone();
            f.seq = seq as u64;
            f.stamp = Stamp(seq as i64 * 40_000_000);
            let out = stage.process(&Msg::Frame(f.clone()), &clock).unwrap();
            let kinds: Vec<&str> = out.iter().map(Msg::kind).collect();
            if kinds.contains(&"contact_state") {
                let at = kinds
                    .iter()
                    .position(|k| *k == "depth")
                    .expect("a depth map");
                assert!(kinds[..at].contains(&"contact_state"), "{kinds:?}");
            }
            for m in out {
                match m {
                    Msg::Depth(d) => {
                        depths += 1;
                        assert_eq!(d.header.stamp, f.stamp);
                        assert_eq!(d.header.frame_id, format!("{}_optical_frame", f.sensor_id));
                        assert_eq!((d.width, d.height), (spec.width, spec.height));
                        assert_eq!(d.depth_m.len(), (spec.width * spec.height) as usize);
                        assert!((d.pixel_m - spec.m_per_px()).abs() < 1e-9);
                        last = Some(d);
                    }
                    Msg::ContactOverlay(o) => overlays.push(o),
                    _ => {}
                }
            }
        }
        assert!(depths >= 3, "{depths}");
        let d = last.unwrap();
        let unknown = d.depth_m.iter().filter(|v| v.is_nan()).count();
        let share = unknown as f64 / d.depth_m.len() as f64;
        assert!(
            (0.01..0.3).contains(&share),
            "NaN under the markers only: {share}"
        );
        let max = d
            .depth_m
            .iter()
            .copied()
            .filter(|v| v.is_finite())
            .fold(0.0, f32::max);
        assert!(
            (f64::from(max) * 1e3 - 0.6).abs() < 0.1,
            "penetration {max} m"
        );
        // The deepest point is at the press, pushed toward the sensor (negative optical z).
        let pts = d.points();
        assert_eq!(pts.len(), d.depth_m.len() - unknown);
        let zmin = pts.iter().map(|p| p[2]).fold(0.0, f32::min);
        assert_eq!(zmin, -max);
        if overlay {
            assert_eq!(overlays.len(), 12 + rendered.len(), "one per frame");
            assert!(
                overlays
                    .iter()
                    .all(|o| (o.width, o.height) == (2 * spec.width, spec.height)),
                "the depth panel is there from the first frame on (one picture size)"
            );
            let o = overlays.last().unwrap();
            assert_eq!((o.width, o.height), (2 * spec.width, spec.height));
            let px: Vec<[u8; 3]> = o
                .data()
                .chunks_exact(3)
                .map(|c| [c[0], c[1], c[2]])
                .collect();
            assert!(px.contains(&OUTLINE), "the contact outline is drawn");
            assert!(px.contains(&CENTROID), "the centroid is drawn");
        } else {
            assert!(overlays.is_empty(), "off by default");
        }
    }
}
