#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
//! One test alone in its process (so the descriptor count means something): a sensor that stays
//! on the bus but stops streaming, 100 times over, is recovered each time by a USB reset of the
//! fake USB layer and a re-open by serial, with one open handle and no descriptor left behind.

mod common;

use common::*;
use unitac_core::{SensorKind, Source};
use unitac_driver::calib::Calibration;
use unitac_driver::stream::{LinkState, SensorStream, StreamConfig};

fn fd_count() -> usize {
    std::fs::read_dir("/proc/self/fd").unwrap().count()
}

#[test]
fn hundred_stalls_hundred_usb_resets_hundred_recoveries_descriptors_flat() {
    let world = World::new("D00045", qvga_yuyv(), yuyv_gradient(320, 240));
    world.lock().unwrap().hold_fd = true;
    let clock = FakeClock::new();
    let cal = Calibration::default_for(SensorKind::DIGIT, "D00045");
    let mut cfg = StreamConfig::new("D00045", cal);
    cfg.request.formats = vec![unitac_driver::decode::PixelFormat::Yuyv];
    let backend = FakeBackend {
        world: world.clone(),
        clock: clock.clone(),
    };
    let mut s = SensorStream::open(cfg, backend, clock).unwrap();
    let mut last_seq = s.next_frame().unwrap().unwrap().seq;
    let before = fd_count();
    for i in 1..=100u64 {
        world.lock().unwrap().stalled = true;
        // Timeouts until the stall is declared, then the reset; the device is re-enumerating
        // at the first re-open attempt, so frames come back a call or two later.
        let mut calls = 0;
        let f = loop {
            calls += 1;
            assert!(calls < 20, "stall {i} not recovered");
            if let Ok(Some(f)) = s.next_frame() {
                break f;
            }
        };
        assert!(f.seq > last_seq);
        last_seq = f.seq;
        assert_eq!(s.state(), LinkState::Streaming);
        let w = world.lock().unwrap();
        assert_eq!(w.usb_resets, i);
        assert_eq!(w.open_handles, 1);
    }
    assert_eq!(fd_count(), before);
    let w = world.lock().unwrap();
    assert_eq!(w.resets_with_open_node, 0);
    let c = s.counters();
    assert_eq!(
        (
            c.stalls,
            c.usb_resets,
            c.stall_recoveries,
            c.usb_reset_failures
        ),
        (100, 100, 100, 0)
    );
}
