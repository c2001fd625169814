//! The slip stage behind the contact stage on mock GelSight Mini frames: a stuck pull reads as
//! shear without slip, slipping gel is flagged, and bad input (DIGIT, a frame of another size, a
//! gel without dots) is an error or an invalid state, never NaN. The accuracy sweep is
//! `unitac eval slip`.
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
    let mut cfg = MockConfig::new(SensorKind::GelsightMini, 11);
    cfg.markers = markers;
    let sensor = MockSensor::new(cfg, Scenario::idle(1.0));
    let fabric = Scenario::fabric("fabric", 0.02, 0.8);
    let mut c = chain(SensorKind::GelsightMini);
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
    let err = SlipStage::new(SlipParams::default(), SensorKind::Digit.spec()).unwrap_err();
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
    assert!(SlipStage::new(bad, SensorKind::GelsightMini.spec()).is_err());
}

#[test]
fn a_frame_of_another_size_is_rejected_and_tracking_goes_on() {
    let sensor = MockSensor::new(
        MockConfig::new(SensorKind::GelsightMini, 3),
        Scenario::idle(1.0),
    );
    let fabric = Scenario::fabric("fabric", 0.02, 0.8);
    let spec = SensorKind::GelsightMini.spec();
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
