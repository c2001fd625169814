//! The contact stage around the detector: saved backgrounds through a store, frame-size changes.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use unitac_contact::{
    Background, BackgroundFileError, BackgroundStore, ContactParams, ContactStage,
};
use unitac_core::{Frame, ManualClock, Msg, SensorKind, Stage};
use unitac_sim::{MockConfig, MockSensor, Scenario};

/// (errors, contact states, backgrounds announced) over `frames`.
fn feed(
    stage: &mut ContactStage,
    frames: impl IntoIterator<Item = Frame>,
) -> (usize, usize, usize) {
    let clock = ManualClock::default();
    let (mut errors, mut states, mut bgs) = (0, 0, 0);
    for f in frames {
        match stage.process(&Msg::Frame(f), &clock) {
            Ok(out) => {
                for m in out {
                    match m {
                        Msg::ContactState(_) => states += 1,
                        Msg::Background(_) => bgs += 1,
                        _ => {}
                    }
                }
            }
            Err(_) => errors += 1,
        }
    }
    (errors, states, bgs)
}

fn idle_frames(kind: SensorKind, n: u64) -> Vec<Frame> {
    let s = MockSensor::new(MockConfig::new(kind, 6), Scenario::idle(2.0));
    (0..n).map(|k| s.render(k).0).collect()
}

#[test]
fn a_saved_background_that_fails_to_load_is_warned_about_once_and_learned() {
    let dir = std::env::temp_dir().join(format!("unitac-badbg-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let kind = SensorKind::DIGIT;
    std::fs::write(
        Background::path_for(&dir, "mock_digit"),
        b"not a background",
    )
    .unwrap();
    let p = ContactParams {
        background_dir: Some(dir.clone()),
        ..Default::default()
    };
    let learn = p.learn_frames as usize;
    let mut stage = ContactStage::new(p, kind.spec()).unwrap();
    let (errors, states, bgs) = feed(&mut stage, idle_frames(kind, 30));
    assert_eq!(errors, 0, "the bad file costs no frame");
    assert_eq!(states, 30 - learn, "learned from the first frames instead");
    assert_eq!(bgs, 1);
    assert!(
        stage
            .store_error()
            .unwrap()
            .contains("not a background file"),
        "{:?}",
        stage.store_error()
    );
    std::fs::remove_dir_all(dir).ok();
}

#[derive(Debug)]
struct FailingStore {
    loads: Arc<AtomicUsize>,
    saves: Arc<AtomicUsize>,
}

impl BackgroundStore for FailingStore {
    fn load(
        &mut self,
        _: &str,
        _: u32,
        _: u32,
        _: u32,
    ) -> Result<Option<Background>, BackgroundFileError> {
        self.loads.fetch_add(1, Ordering::SeqCst);
        Err(BackgroundFileError::Format("memory".into()))
    }
    fn save(&mut self, _: &str, _: &Background) -> Result<(), BackgroundFileError> {
        self.saves.fetch_add(1, Ordering::SeqCst);
        Ok(())
    }
}

#[test]
fn the_store_is_asked_once_and_given_the_background_at_the_end() {
    let (loads, saves) = (Arc::new(AtomicUsize::new(0)), Arc::new(AtomicUsize::new(0)));
    let store = FailingStore {
        loads: Arc::clone(&loads),
        saves: Arc::clone(&saves),
    };
    let kind = SensorKind::GELSIGHT_MINI;
    let mut stage =
        ContactStage::with_store(ContactParams::default(), kind.spec(), Some(Box::new(store)))
            .unwrap();
    let (errors, states, _) = feed(&mut stage, idle_frames(kind, 20));
    assert_eq!((errors, states), (0, 10));
    stage.finish(&ManualClock::default()).unwrap();
    assert_eq!(loads.load(Ordering::SeqCst), 1);
    assert_eq!(saves.load(Ordering::SeqCst), 1);
}

/// Frames of `w` x `h` from a DIGIT-like mock sensor, without contact.
fn sized_frames(w: u32, h: u32, range: std::ops::Range<u64>) -> Vec<Frame> {
    let spec = unitac_core::SensorSpec {
        width: w,
        height: h,
        mm_per_px: 0.0405 * 320.0 / f64::from(w),
        ..SensorKind::DIGIT.spec()
    };
    let s = MockSensor::with_spec(
        MockConfig::new(SensorKind::DIGIT, 4),
        spec,
        Scenario::idle(3.0),
    )
    .unwrap();
    range.map(|k| s.render(k).0).collect()
}

#[test]
fn a_sustained_new_frame_size_is_learned_again_and_an_odd_frame_is_only_rejected() {
    let p = ContactParams::default();
    let (learn, n) = (p.learn_frames as usize, p.new_size_frames as usize);
    let mut stage = ContactStage::new(p, SensorKind::DIGIT.spec()).unwrap();
    // One 32x24 frame first, then 60 of 64x48 (the first frame used to lock the size).
    let mut frames = sized_frames(32, 24, 0..1);
    frames.extend(sized_frames(64, 48, 1..61));
    let (errors, states, bgs) = feed(&mut stage, frames);
    assert_eq!(errors, n - 1, "rejected until {n} in a row");
    assert_eq!(states, 60 - (n - 1) - learn);
    assert_eq!(bgs, 1, "the new background is announced");
    assert_eq!(stage.detector().size_changes(), 1);
    let bg = stage.detector().background().unwrap();
    assert_eq!((bg.geo.width, bg.geo.height), (64, 48));

    // Odd frames in between good ones are rejected and change nothing.
    let before = bg.clone();
    let mut odd = Vec::new();
    for k in 61..80 {
        odd.extend(sized_frames(64, 48, k..k + 1));
        if k % 3 == 0 {
            odd.extend(sized_frames(32, 24, k..k + 1));
        }
    }
    let (errors, states, bgs) = feed(&mut stage, odd);
    assert_eq!((errors, states, bgs), (6, 19, 0));
    assert_eq!(stage.detector().size_changes(), 1);
    let after = stage.detector().background().unwrap();
    assert_eq!(
        (after.geo, after.captured_at),
        (before.geo, before.captured_at)
    );
}
