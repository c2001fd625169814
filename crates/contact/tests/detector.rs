//! Contact detector behaviour on mock-sensor frames with ground truth.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use unitac_contact::{Background, ContactDetector, ContactParams, ContactStage, FrameRefused};
use unitac_core::msg::ContactEpisode;
use unitac_core::{Frame, ManualClock, Msg, SensorKind, Stage, StageError, Stamp};
use unitac_sim::{Drift, MockConfig, MockSensor, Scenario};

struct Run {
    episodes: Vec<ContactEpisode>,
    /// (detected in_contact, truth penetration) per frame after learning.
    frames: Vec<(bool, f64)>,
    clips: Vec<unitac_core::msg::ContactClip>,
    errors: usize,
}

fn run(cfg: MockConfig, scenario: Scenario, p: ContactParams) -> Run {
    let kind = cfg.sensor;
    let mut sensor = MockSensor::new(cfg, scenario);
    let mut stage = ContactStage::new(p, kind.spec()).unwrap();
    let clock = ManualClock::default();
    let mut r = Run {
        episodes: Vec::new(),
        frames: Vec::new(),
        clips: Vec::new(),
        errors: 0,
    };
    let take = |msgs: Vec<Msg>, truth: f64, r: &mut Run| {
        for m in msgs {
            match m {
                Msg::ContactState(c) => r.frames.push((c.in_contact, truth)),
                Msg::ContactEpisode(e) => r.episodes.push(e),
                Msg::ContactClip(c) => r.clips.push(c),
                _ => {}
            }
        }
    };
    while let Some((f, t)) = sensor.next_with_truth() {
        match stage.process(&Msg::Frame(f), &clock) {
            Ok(msgs) => take(msgs, t.penetration_mm, &mut r),
            Err(_) => r.errors += 1,
        }
    }
    take(stage.finish(&clock).unwrap(), 0.0, &mut r);
    r
}

fn labels() -> ContactParams {
    ContactParams {
        episode_labels: vec!["fabric_a".into(), "fabric_b".into()],
        ..Default::default()
    }
}

#[test]
fn fabric_scenario_gives_two_labelled_episodes_on_both_sensors() {
    for kind in [SensorKind::GELSIGHT_MINI, SensorKind::DIGIT] {
        let r = run(
            MockConfig::new(kind, 11),
            Scenario::fabric_selection(),
            labels(),
        );
        assert_eq!(r.errors, 0);
        assert_eq!(r.episodes.len(), 2, "{kind}: {:?}", r.episodes);
        assert_eq!(
            (r.episodes[0].label.as_str(), r.episodes[1].label.as_str()),
            ("fabric_a", "fabric_b")
        );
        for e in &r.episodes {
            assert!(
                e.frame_count > 20 && e.peak_area_px > 2000.0,
                "{kind}: {e:?}"
            );
            assert!(e.end > e.start);
        }
        // Frames clearly pressed (> 0.05 mm) or clearly free are classified right.
        let clear: Vec<_> = r
            .frames
            .iter()
            .filter(|(_, t)| *t == 0.0 || *t > 0.05)
            .collect();
        let right = clear.iter().filter(|(d, t)| *d == (*t > 0.0)).count();
        assert!(
            right as f64 >= 0.95 * clear.len() as f64,
            "{kind}: {right}/{}",
            clear.len()
        );
    }
}

#[test]
fn ten_minutes_of_drift_and_noise_without_contact_give_no_episode() {
    for kind in [SensorKind::GELSIGHT_MINI, SensorKind::DIGIT] {
        let mut cfg = MockConfig::new(kind, 99);
        cfg.drift = Drift::warmup();
        cfg.fps = 25.0;
        let r = run(cfg, Scenario::idle(600.0), ContactParams::default());
        assert_eq!(r.errors, 0);
        assert_eq!(r.frames.len(), 15_000 - 10);
        let false_frames = r.frames.iter().filter(|(d, _)| *d).count();
        assert_eq!((r.episodes.len(), false_frames), (0, 0), "{kind}");
    }
}

#[test]
fn exposure_steps_do_not_fire_or_break_contacts() {
    let mut cfg = MockConfig::new(SensorKind::GELSIGHT_MINI, 5);
    // +30 % at 0.7 s (no contact yet), -25 % at 1.9 s (during the hold on fabric A).
    cfg.drift.steps = vec![(0.7, 1.3), (1.9, 0.75)];
    let r = run(cfg, Scenario::fabric_selection(), labels());
    assert_eq!(r.errors, 0);
    assert_eq!(r.episodes.len(), 2, "{:?}", r.episodes);
    let false_on = r.frames.iter().filter(|(d, t)| *d && *t == 0.0).count();
    assert!(
        false_on <= 4,
        "only debounce-lag frames after a release may read as contact: {false_on}"
    );
}

#[test]
fn a_contact_held_for_three_minutes_is_not_absorbed() {
    let mut cfg = MockConfig::new(SensorKind::DIGIT, 3);
    cfg.fps = 25.0;
    cfg.drift = Drift::warmup();
    let fabric = Scenario::fabric("fabric_a", 0.03, 0.9);
    let r = run(cfg, Scenario::held(&fabric, 0.5, 180.0), labels());
    assert_eq!(r.episodes.len(), 1, "{:?}", r.episodes);
    let held: Vec<_> = r
        .frames
        .iter()
        .filter(|(_, t)| (*t - 0.5).abs() < 1e-9)
        .collect();
    assert!(held.len() > 4400);
    assert!(
        held.iter().all(|(d, _)| *d),
        "in contact for the whole hold"
    );
    let ep = &r.episodes[0];
    assert!(ep.frame_count as usize >= held.len());
}

#[test]
fn saturated_dark_and_wrong_size_frames_are_errors_and_leave_state_intact() {
    let kind = SensorKind::GELSIGHT_MINI;
    let mut sensor = MockSensor::new(MockConfig::new(kind, 1), Scenario::fabric_selection());
    let mut det = ContactDetector::new(ContactParams::default(), kind.spec()).unwrap();
    for _ in 0..15 {
        det.step(&sensor.next_with_truth().unwrap().0).unwrap();
    }
    let bg_before = det.background().unwrap().clone();
    let white = Frame::new("s", 100, Stamp(1), 320, 240, vec![255; 320 * 240 * 3]).unwrap();
    let black = Frame::new("s", 101, Stamp(2), 320, 240, vec![0; 320 * 240 * 3]).unwrap();
    let small = Frame::new("s", 102, Stamp(3), 4, 4, vec![0; 48]).unwrap();
    // Each refusal is a bad input whose cause is the detector's own typed error.
    let refused = |e: StageError| match e {
        StageError::BadInput(c) => c.downcast::<FrameRefused>().map(|b| *b).unwrap(),
        other => panic!("{other}"),
    };
    assert!(matches!(
        refused(det.step(&white).unwrap_err()),
        FrameRefused::Saturated { seq: 100, percent } if percent > 99.0
    ));
    assert!(matches!(
        refused(det.step(&black).unwrap_err()),
        FrameRefused::Dark { seq: 101, .. }
    ));
    let e = det.step(&small).unwrap_err();
    assert!(e.to_string().contains("4x4"), "{e}");
    assert!(matches!(
        refused(e),
        FrameRefused::SizeChanged {
            seq: 102,
            width: 4,
            height: 4,
            bg_width: 320,
            bg_height: 240,
            ..
        }
    ));
    assert_eq!(det.background().unwrap(), &bg_before);
    let out = det.step(&sensor.next_with_truth().unwrap().0).unwrap();
    assert!(matches!(&out[0], Msg::ContactState(c) if !c.in_contact && c.area_px == 0.0));
}

#[test]
fn noise_is_measured_per_cell() {
    let kind = SensorKind::DIGIT;
    let mut sensor = MockSensor::new(MockConfig::new(kind, 5), Scenario::idle(2.0));
    let mut det = ContactDetector::new(ContactParams::default(), kind.spec()).unwrap();
    for _ in 0..10 {
        det.step(&sensor.next_with_truth().unwrap().0).unwrap();
    }
    // 1 DN per pixel (+ rounding) averaged over 2x2 blocks: ~0.52 DN per cell.
    assert!(
        (0.4..0.65).contains(&det.cell_sigma()),
        "{}",
        det.cell_sigma()
    );
}

#[test]
fn coordinates_are_in_input_pixels() {
    for stride in [1, 2, 4] {
        let kind = SensorKind::DIGIT;
        let s = MockSensor::new(MockConfig::new(kind, 8), Scenario::fabric_selection());
        let p = ContactParams {
            stride,
            ..Default::default()
        };
        let mut det = ContactDetector::new(p, kind.spec()).unwrap();
        det.set_background_frame(&s.render(0).0);
        let k = (Scenario::fabric_selection()
            .first_hold_time("fabric_b")
            .unwrap()
            * 60.0) as u64;
        let (f, truth) = s.render(k);
        let m = det.measure(&f).unwrap();
        // The press is centred at (160, 120).
        assert!(
            (m.centroid[0] - 160.0).abs() < 3.0 && (m.centroid[1] - 120.0).abs() < 3.0,
            "{stride}: {m:?}"
        );
        let (tx0, tx1) = (0..320u32).fold((320u32, 0u32), |(a, b), x| {
            if (0..240).any(|y| truth.mask[(y * 320 + x) as usize]) {
                (a.min(x), b.max(x + 1))
            } else {
                (a, b)
            }
        });
        // The detected box holds the true contact (within one cell) and overshoots it by no more
        // than the gel's skirt (the deformation visible around a contact).
        let st = det.params().stride;
        assert!(
            m.bbox[0] <= tx0 + st && m.bbox[2] + st >= tx1,
            "{stride}: {m:?} vs {tx0}..{tx1}"
        );
        let (dw, tw) = ((m.bbox[2] - m.bbox[0]) as f32, (tx1 - tx0) as f32);
        assert!(
            dw <= 1.6 * tw,
            "{stride}: box {dw} px wide, contact {tw} px"
        );
        let ratio = m.area_px / truth.contact_px as f32;
        assert!(
            (0.8..1.8).contains(&ratio),
            "{stride}: area {} vs truth {}",
            m.area_px,
            truth.contact_px
        );
    }
}

#[test]
fn episode_clips_are_bounded_and_hold_the_peak() {
    let p = ContactParams {
        clip_frames: 8,
        ..labels()
    };
    let r = run(
        MockConfig::new(SensorKind::GELSIGHT_MINI, 4),
        Scenario::fabric_selection(),
        p,
    );
    assert_eq!(r.clips.len(), 2);
    for (c, e) in r.clips.iter().zip(&r.episodes) {
        assert_eq!(c.episode_id, e.episode_id);
        assert_eq!(c.frames.len(), 8);
        assert_eq!(c.frames[c.peak_index].seq, e.peak_frame_seq);
        assert!(
            c.frames
                .windows(2)
                .all(|w| w[0].seq < w[1].seq || c.peak_index == 0)
        );
    }
}

#[test]
fn background_saves_loads_and_rejects_bad_files() {
    let kind = SensorKind::GELSIGHT_MINI;
    let s = MockSensor::new(MockConfig::new(kind, 2), Scenario::idle(1.0));
    let mut det = ContactDetector::new(ContactParams::default(), kind.spec()).unwrap();
    for k in 0..10 {
        det.step(&s.render(k).0).unwrap();
    }
    let bg = det.background().unwrap().clone();
    let dir = std::env::temp_dir().join(format!("unitac-bg-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = Background::path_for(&dir, "GS/0A1B 2C3D");
    assert!(
        path.file_name()
            .unwrap()
            .to_str()
            .unwrap()
            .starts_with("GS_0A1B_2C3D")
    );
    // A file of the user's beside it, named as a temporary would be, is never overwritten.
    let theirs = path.with_extension("unitac-bg.tmp");
    std::fs::write(&theirs, b"mine").unwrap();
    bg.save(&path).unwrap();
    assert_eq!(std::fs::read(&theirs).unwrap(), b"mine");
    assert_eq!(Background::load(&path, 320, 240, 2).unwrap(), bg);
    // No temporary is left behind: the directory holds the two files.
    assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 2);
    // One at the temporary's own name makes the save fail, and stays as it was.
    let mut name = path.file_name().unwrap().to_os_string();
    name.push(format!(".{}.unitac-bg.tmp", std::process::id()));
    let clash = path.with_file_name(name);
    std::fs::write(&clash, b"mine too").unwrap();
    assert!(bg.save(&path).is_err());
    assert_eq!(std::fs::read(&clash).unwrap(), b"mine too");
    std::fs::remove_file(&clash).unwrap();
    std::fs::remove_file(&theirs).unwrap();
    assert!(
        Background::load(&path, 640, 480, 2)
            .unwrap_err()
            .to_string()
            .contains("640x480")
    );
    let bytes = std::fs::read(&path).unwrap();
    std::fs::write(&path, &bytes[..bytes.len() - 7]).unwrap();
    assert!(Background::load(&path, 320, 240, 2).is_err(), "truncated");
    std::fs::write(&path, b"garbage").unwrap();
    assert!(Background::load(&path, 320, 240, 2).is_err());
    // A fresh detector given the saved background detects without learning.
    let mut det2 = ContactDetector::new(ContactParams::default(), kind.spec()).unwrap();
    det2.set_background(bg);
    assert!(det2.is_learned());
    assert!(det2.background_frame("gs").is_some());
    det2.recapture();
    assert!(!det2.is_learned());
    std::fs::remove_dir_all(dir).ok();
}

#[test]
fn markers_are_masked_on_gelsight() {
    let kind = SensorKind::GELSIGHT_MINI;
    let s = MockSensor::new(MockConfig::new(kind, 21), Scenario::fabric_selection());
    let k = (Scenario::fabric_selection()
        .first_hold_time("fabric_a")
        .unwrap()
        * 25.0) as u64;
    let (f, truth) = s.render(k);
    let area = |mask_markers| {
        let p = ContactParams {
            mask_markers: Some(mask_markers),
            ..Default::default()
        };
        let mut det = ContactDetector::new(p, kind.spec()).unwrap();
        det.set_background_frame(&s.render(0).0);
        det.measure(&f).unwrap().area_px
    };
    let (with, without) = (area(true), area(false));
    let t = truth.contact_px as f32;
    // Moving markers add area unless masked (outside the contact only where they join it: the
    // scattered ones are not a coherent region anyway).
    assert!(
        (with - t).abs() < 0.1 * t && without >= with,
        "masked {with}, unmasked {without}, truth {t}"
    );
}

/// A gel not known to have markers (`generic`): the dots are found from the background where it
/// shows a grid of them, and nothing is masked on a gel without them, whose dark vignetted corners
/// are no dots.
#[test]
fn a_generic_gel_masks_the_dots_its_background_shows_and_nothing_else() {
    let masked = |render_kind: SensorKind, detect_kind: SensorKind| {
        let s = MockSensor::new(
            MockConfig::new(render_kind, 21),
            Scenario::fabric_selection(),
        );
        let mut det = ContactDetector::new(ContactParams::default(), detect_kind.spec()).unwrap();
        det.set_background_frame(&s.render(0).0);
        det.marker_mask_px().iter().filter(|m| **m).count()
    };
    let (mini, generic) = (SensorKind::GELSIGHT_MINI, SensorKind::GENERIC);
    // GelSight Mini's own rule masks its dots; the generic rule finds the same grid.
    let (own, found) = (masked(mini, mini), masked(mini, generic));
    assert!(
        own > 0 && found > own / 2 && found <= own,
        "own {own}, found {found}"
    );
    // A gel without dots: the generic rule masks nothing.
    assert_eq!(masked(generic, generic), 0);
    // A vignette dark enough to pass the dark-cell test in its corners is still no grid.
    let mut f = MockSensor::new(MockConfig::new(generic, 21), Scenario::fabric_selection())
        .render(0)
        .0;
    let (w, h) = (f.width as usize, f.height as usize);
    for (i, px) in f.data_mut().chunks_exact_mut(3).enumerate() {
        let (x, y) = (
            (i % w) as f32 / w as f32 - 0.5,
            (i / w) as f32 / h as f32 - 0.5,
        );
        if x.hypot(y) > 0.55 {
            px.iter_mut().for_each(|v| *v /= 3);
        }
    }
    let count = |p: ContactParams| {
        let mut det = ContactDetector::new(p, generic.spec()).unwrap();
        det.set_background_frame(&f);
        det.marker_mask_px().iter().filter(|m| **m).count()
    };
    assert_eq!(count(ContactParams::default()), 0);
    // (The corners are dark cells: a scene that says the gel has markers masks them.)
    let say_yes = ContactParams {
        mask_markers: Some(true),
        ..Default::default()
    };
    assert!(count(say_yes) > w * h / 50);
}

#[test]
fn bad_params_are_rejected() {
    let spec = SensorKind::DIGIT.spec();
    for p in [
        ContactParams {
            stride: 0,
            ..Default::default()
        },
        ContactParams {
            exit_area_px: 500.0,
            ..Default::default()
        },
        ContactParams {
            noise_k: f32::NAN,
            ..Default::default()
        },
        ContactParams {
            clip_frames: 100_000,
            ..Default::default()
        },
        ContactParams {
            area_level: 1.0,
            ..Default::default()
        },
        ContactParams {
            area_level: f32::NAN,
            ..Default::default()
        },
    ] {
        assert!(ContactDetector::new(p, spec).is_err());
    }
}

#[test]
fn stage_saves_its_background_and_the_next_run_starts_without_learning() {
    let dir = std::env::temp_dir().join(format!("unitac-bgdir-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let kind = SensorKind::DIGIT;
    let p = ContactParams {
        background_dir: Some(dir.clone()),
        ..Default::default()
    };
    let s = MockSensor::new(MockConfig::new(kind, 6), Scenario::idle(1.0));
    let clock = ManualClock::default();
    let mut first = ContactStage::new(p.clone(), kind.spec()).unwrap();
    for k in 0..12 {
        first.process(&Msg::Frame(s.render(k).0), &clock).unwrap();
    }
    first.finish(&clock).unwrap();
    assert!(Background::path_for(&dir, "mock_digit").exists());
    // The second run measures from its very first frame.
    let mut second = ContactStage::new(p, kind.spec()).unwrap();
    let out = second.process(&Msg::Frame(s.render(20).0), &clock).unwrap();
    // It announces the loaded background, then measures from its very first frame.
    assert!(matches!(out.first(), Some(Msg::Background(_))), "{out:?}");
    assert!(
        out.iter()
            .any(|m| matches!(m, Msg::ContactState(c) if !c.in_contact)),
        "{out:?}"
    );
    std::fs::remove_dir_all(dir).ok();
}
