//! The slip stage behind the contact stage on mock GelSight Mini frames: a stuck pull reads as
//! shear without slip, slipping gel is flagged, and bad input (DIGIT, a frame of another size, a
//! gel without dots) is an error or an invalid state, never NaN. The accuracy sweep is
//! `unitac-lab eval slip`.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use unitac_contact::{ContactParams, ContactStage, ParamsError, SlipParams, SlipStage};
use unitac_core::msg::SlipState;
use unitac_core::{Chain, Frame, Msg, SensorKind, Stage};
use unitac_sim::{MockConfig, MockSensor, Scenario, Tangential};

fn chain(kind: SensorKind) -> Chain {
    let spec = kind.spec();
    let stages: Vec<Box<dyn Stage>> = vec![
        Box::new(ContactStage::new(ContactParams::default(), spec).unwrap()),
        Box::new(SlipStage::new(SlipParams::default(), spec).unwrap()),
    ];
    Chain::new(stages)
}

fn slip_states(out: Vec<Msg>) -> Vec<SlipState> {
    out.into_iter()
        .filter_map(|m| match m {
            Msg::SlipState(s) => Some(s),
            _ => None,
        })
        .collect()
}

/// 12 frames at rest, 8 pressed 0.8 mm, `tan` ramped in over 8 frames, held 4: the SlipStates.
fn touch(markers: bool, tan: Tangential) -> Vec<SlipState> {
    let mut cfg = MockConfig::new(SensorKind::GELSIGHT_MINI, 11);
    cfg.markers = markers;
    let sensor = MockSensor::new(cfg, Scenario::idle(1.0));
    let fabric = Scenario::fabric("fabric", 0.02, 0.8);
    let mut c = chain(SensorKind::GELSIGHT_MINI);
    let mut states = Vec::new();
    for k in 0..32u64 {
        let share = (k.saturating_sub(20) as f64 / 8.0).min(1.0);
        let t = Tangential {
            shift_m: [tan.shift_m[0] * share, tan.shift_m[1] * share],
            rotation_rad: tan.rotation_rad * share,
            ..tan
        };
        let (f, _) = sensor.render_contact(k, (k >= 12).then_some((&fabric, 0.8)), Some(&t));
        let out = c.run(Msg::Frame(f));
        assert!(out.errors.is_empty(), "{:?}", out.errors);
        states.extend(slip_states(out.produced));
    }
    states
}

fn finite(s: &SlipState) -> bool {
    [
        s.shear_x_m,
        s.shear_y_m,
        s.rotation_rad,
        s.residual_px,
        s.slip_score,
    ]
    .iter()
    .all(|v| v.is_finite())
}

#[test]
fn a_stuck_pull_is_shear_without_slip() {
    let states = touch(true, Tangential::new([0.3e-3, -0.1e-3], 0.03, 1.0));
    // One state per frame in contact (after the contact stage's debounce), all NaN-free.
    assert!(states.len() >= 10, "{}", states.len());
    assert!(states.iter().all(finite));
    // Before the onset reference: invalid, every number 0.
    let first = &states[0];
    assert!(!first.valid && first.shear_x_m == 0.0 && first.slip_score == 0.0);
    let last = states.last().unwrap();
    assert!(last.valid, "{last:?}");
    assert!(last.markers_tracked >= 6, "{last:?}");
    assert!((last.shear_x_m - 0.3e-3).abs() < 0.03e-3, "{last:?}");
    assert!((last.shear_y_m + 0.1e-3).abs() < 0.03e-3, "{last:?}");
    assert!((last.rotation_rad - 0.03).abs() < 0.01, "{last:?}");
    assert!(!states.iter().any(|s| s.slip), "{states:?}");
    assert_eq!(last.header.frame_id, "mock_gelsight_mini_optical_frame");
}

#[test]
fn slipping_gel_is_flagged() {
    for stick in [0.3, 0.0] {
        let t = Tangential::new([0.4e-3, 0.0], 0.0, stick);
        let last = touch(true, t).pop().unwrap();
        assert!(last.valid && last.slip, "stick ratio {stick}: {last:?}");
    }
}

#[test]
fn a_gel_without_dots_gives_invalid_states_not_nan() {
    let states = touch(false, Tangential::new([0.3e-3, 0.0], 0.0, 0.5));
    assert!(!states.is_empty());
    for s in &states {
        assert!(
            !s.valid && !s.slip && finite(s) && s.markers_tracked == 0,
            "{s:?}"
        );
    }
}

#[test]
fn a_sensor_without_markers_is_refused_by_name() {
    let err = SlipStage::new(SlipParams::default(), SensorKind::DIGIT.spec()).unwrap_err();
    assert_eq!(
        err,
        ParamsError::NoMarkers {
            sensor: "digit".into()
        }
    );
    assert!(err.to_string().contains("digit"), "{err}");
    let bad = SlipParams {
        slip_off: 0.5,
        slip_on: 0.2,
        ..SlipParams::default()
    };
    assert!(SlipStage::new(bad, SensorKind::GELSIGHT_MINI.spec()).is_err());
}

#[test]
fn a_frame_of_another_size_is_rejected_and_tracking_goes_on() {
    let sensor = MockSensor::new(
        MockConfig::new(SensorKind::GELSIGHT_MINI, 3),
        Scenario::idle(1.0),
    );
    let fabric = Scenario::fabric("fabric", 0.02, 0.8);
    let spec = SensorKind::GELSIGHT_MINI.spec();
    let mut slip = SlipStage::new(SlipParams::default(), spec).unwrap();
    let clock = unitac_core::ManualClock::default();
    let (bg, _) = sensor.render_contact(0, None, None);
    assert!(
        slip.process(&Msg::Background(bg), &clock)
            .unwrap()
            .is_empty()
    );
    assert!(slip.reference().unwrap().points.len() > 100);
    let contact = |seq: u64| {
        let mut c = unitac_core::msg::samples::contact_state();
        c.frame_seq = seq;
        c.in_contact = true;
        c.area_px = 7000.0;
        c.centroid_px = [160.0, 120.0];
        Msg::ContactState(c)
    };
    let mut run = |f: Frame| {
        slip.process(&contact(f.seq), &clock).unwrap();
        slip.process(&Msg::Frame(f), &clock)
    };
    for k in 1..4 {
        let (f, _) = sensor.render_contact(k, Some((&fabric, 0.8)), None);
        assert_eq!(run(f).unwrap().len(), 1);
    }
    let small = Frame::new(
        "mock_gelsight_mini",
        4,
        unitac_core::Stamp(4),
        160,
        120,
        vec![90; 160 * 120 * 3],
    )
    .unwrap();
    let err = run(small).unwrap_err();
    assert!(err.to_string().contains("160x120"), "{err}");
    let (f, _) = sensor.render_contact(5, Some((&fabric, 0.8)), None);
    let out = run(f).unwrap();
    let Some(Msg::SlipState(s)) = out.first() else {
        panic!("{out:?}")
    };
    assert!(s.valid && s.shear_x_m.abs() < 0.02e-3, "{s:?}");
}

/// The contact stage's overlay draws each marker's displacement from rest while in contact (a
/// stuck pull: the arrows point along the pull, as long as it), none at rest, and none on a gel
/// without dots.
#[test]
fn the_overlay_draws_the_markers_displacements_from_rest_while_in_contact() {
    use unitac_contact::MarkerField;
    use unitac_contact::overlay::ARROW;
    let spec = SensorKind::GELSIGHT_MINI.spec();
    let shift_m = [0.3e-3, -0.1e-3];
    for markers in [true, false] {
        let mut cfg = MockConfig::new(SensorKind::GELSIGHT_MINI, 11);
        cfg.markers = markers;
        let sensor = MockSensor::new(cfg, Scenario::idle(1.0));
        let fabric = Scenario::fabric("fabric", 0.02, 0.8);
        let p = ContactParams {
            overlay: true,
            ..Default::default()
        };
        let mut c = Chain::new(vec![Box::new(ContactStage::new(p, spec).unwrap())]);
        let mut field = MarkerField::default();
        let (mut at_rest, mut pulled) = (Vec::new(), 0usize);
        for k in 0..24u64 {
            let share = (k.saturating_sub(16) as f64 / 4.0).min(1.0);
            let t = Tangential {
                shift_m: [shift_m[0] * share, shift_m[1] * share],
                ..Tangential::default()
            };
            let pressed = k >= 12;
            let (f, _) = sensor.render_contact(k, pressed.then_some((&fabric, 0.8)), Some(&t));
            if k == 0 {
                // The field a user would follow by hand, from the same rest frame.
                let learned = field.learn(&f, &SlipParams::default());
                assert_eq!(learned.is_ok(), markers, "{learned:?}");
            }
            let followed = field.follow(&f, &SlipParams::default()).unwrap().is_some();
            assert_eq!(followed, markers);
            let out = c.run(Msg::Frame(f));
            assert!(out.errors.is_empty(), "{:?}", out.errors);
            let arrows = out
                .produced
                .iter()
                .filter_map(|m| match m {
                    Msg::ContactOverlay(o) => Some(
                        o.data()
                            .chunks_exact(3)
                            .filter(|px| *px == ARROW.as_slice())
                            .count(),
                    ),
                    _ => None,
                })
                .sum::<usize>();
            if !pressed {
                at_rest.push(arrows);
            } else if k == 23 {
                pulled = arrows;
            }
        }
        assert!(at_rest.iter().all(|&n| n == 0), "{at_rest:?}");
        if !markers {
            assert_eq!(pulled, 0, "no dots, no arrows");
            continue;
        }
        assert!(pulled > 50, "arrows under the pull: {pulled} px");
        // The displacements the arrows are drawn from: around the contact their mean (the
        // press's radial spread cancels) is the pull.
        let d = field.displacements();
        let px = |m: f64| m * 1e3 / spec.mm_per_px;
        let near: Vec<[f32; 2]> = d
            .iter()
            .filter(|(a, _)| (a[0] - 160.0).hypot(a[1] - 120.0) < 40.0)
            .map(|(a, b)| [b[0] - a[0], b[1] - a[1]])
            .collect();
        assert!(near.len() >= 3, "{d:?}");
        let mean = |i: usize| near.iter().map(|v| f64::from(v[i])).sum::<f64>() / near.len() as f64;
        assert!(
            (mean(0) - px(shift_m[0])).abs() < 0.3 * px(shift_m[0]),
            "{near:?}"
        );
        assert!(
            (mean(1) - px(shift_m[1])).abs() < 0.3 * px(shift_m[0]),
            "{near:?}"
        );
    }
}
