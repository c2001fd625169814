#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
//! One test alone in its process, so the process's descriptor count means something: a device
//! that vanishes and returns 100 times (each open holds a real descriptor) leaves no descriptor
//! behind.

mod common;

use common::*;
use unitac_core::{SensorKind, Source};
use unitac_driver::calib::Calibration;
use unitac_driver::stream::{SensorStream, StreamConfig};

fn fd_count() -> usize {
    std::fs::read_dir("/proc/self/fd").unwrap().count()
}

#[test]
fn descriptors_do_not_grow_over_100_reconnects() {
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
    s.next_frame().unwrap().unwrap();
    let before = fd_count();
    for _ in 0..100 {
        world.lock().unwrap().present = false;
        assert!(s.next_frame().is_err());
        world.lock().unwrap().present = true;
        assert!(s.next_frame().unwrap().is_some());
    }
    assert_eq!(fd_count(), before);
    assert_eq!(world.lock().unwrap().open_handles, 1);
    assert_eq!(s.counters().reconnects, 100);
}
