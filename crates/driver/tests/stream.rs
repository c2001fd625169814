#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
//! The live-sensor stream on a fake device: timestamps, drops, flush, bad buffers, controls,
//! reconnect with backoff.

mod common;

use common::*;
use std::time::Duration;
use unitac_core::{SensorKind, Source, SourceError};
use unitac_driver::calib::Calibration;
use unitac_driver::capture::Mode;
use unitac_driver::controls::{CameraSettings, Led, cid};
use unitac_driver::decode::PixelFormat;
use unitac_driver::stream::{LinkState, SensorStream, StreamConfig};

fn digit_stream(
    world: &std::sync::Arc<std::sync::Mutex<World>>,
    clock: &FakeClock,
) -> SensorStream<FakeBackend, FakeClock> {
    let cal = Calibration::default_for(SensorKind::DIGIT, "D00045");
    let mut cfg = StreamConfig::new("D00045", cal);
    cfg.request.formats = vec![PixelFormat::Yuyv];
    SensorStream::open(
        cfg,
        FakeBackend {
            world: world.clone(),
            clock: clock.clone(),
        },
        clock.clone(),
    )
    .unwrap()
}

fn digit_world() -> std::sync::Arc<std::sync::Mutex<World>> {
    World::new("D00045", qvga_yuyv(), yuyv_gradient(320, 240))
}

#[test]
fn frames_carry_the_buffer_capture_time_not_the_read_time() {
    let (world, clock) = (digit_world(), FakeClock::new());
    let mut s = digit_stream(&world, &clock);
    world.lock().unwrap().script.push_back(Next::Good {
        age: Duration::from_millis(17),
    });
    let f = s.next_frame().unwrap().unwrap();
    let read_time = clock.mono().as_nanos() as i64 + clock.offset();
    assert_eq!(f.stamp.0, read_time - 17_000_000);
    assert_eq!((f.width, f.height), (320, 240));
    assert_eq!(f.sensor_id, "D00045");
    assert_eq!(s.state(), LinkState::Streaming);
    assert_eq!(s.mode().unwrap().format, PixelFormat::Yuyv);
}

#[test]
fn system_clock_steps_are_followed() {
    let (world, clock) = (digit_world(), FakeClock::new());
    let mut s = digit_stream(&world, &clock);
    s.next_frame().unwrap().unwrap();
    // NTP steps the system clock by +3 s; after the next re-check stamps follow it.
    clock.0.lock().unwrap().real_offset_ns += 3_000_000_000;
    clock.advance(Duration::from_secs(2));
    let f = s.next_frame().unwrap().unwrap();
    let read_time = clock.mono().as_nanos() as i64 + clock.offset();
    assert_eq!(f.stamp.0, read_time - 5_000_000);
    assert_eq!(s.counters().clock_resyncs, 1);
}

#[test]
fn drops_are_counted_from_sequence_gaps_and_sequence_goes_on() {
    let (world, clock) = (digit_world(), FakeClock::new());
    let mut s = digit_stream(&world, &clock);
    world.lock().unwrap().script.extend([
        Next::Good {
            age: Duration::ZERO,
        },
        Next::Skip(3),
        Next::Good {
            age: Duration::ZERO,
        },
    ]);
    let seqs: Vec<u64> = (0..3)
        .map(|_| s.next_frame().unwrap().unwrap().seq)
        .collect();
    assert_eq!(seqs, [0, 4, 5]);
    assert_eq!(s.counters().dropped, 3);
}

#[test]
fn stale_buffers_are_flushed_at_start() {
    let (world, clock) = (digit_world(), FakeClock::new());
    world
        .lock()
        .unwrap()
        .script
        .extend([Next::Stale, Next::Stale]);
    let mut s = digit_stream(&world, &clock);
    let f = s.next_frame().unwrap().unwrap();
    assert_eq!(s.counters().flushed, 2);
    // The first published frame is the fresh one; flushed buffers are not drops.
    assert_eq!(f.seq, 0);
    assert_eq!(s.counters().dropped, 0);
    assert_eq!(s.counters().frames, 1);
}

#[test]
fn bad_buffers_are_per_frame_errors_and_capture_goes_on() {
    let (world, clock) = (digit_world(), FakeClock::new());
    let mut s = digit_stream(&world, &clock);
    world.lock().unwrap().script.extend([
        Next::Bytes(vec![0; 1000]),
        Next::Bytes(Vec::new()),
        Next::NoTimestamp,
        Next::Timeout,
        Next::Good {
            age: Duration::ZERO,
        },
    ]);
    for _ in 0..4 {
        assert!(matches!(s.next_frame(), Err(SourceError::Frame(_))));
    }
    assert!(s.next_frame().unwrap().is_some());
    let c = s.counters();
    assert_eq!(
        (c.decode_errors, c.no_timestamp, c.timeouts, c.frames),
        (2, 1, 1, 1)
    );
    assert_eq!(s.state(), LinkState::Streaming);
}

#[test]
fn repeated_timeouts_reopen_the_device() {
    let (world, clock) = (digit_world(), FakeClock::new());
    let mut s = digit_stream(&world, &clock);
    world
        .lock()
        .unwrap()
        .script
        .extend([Next::Timeout, Next::Timeout, Next::Timeout]);
    assert!(matches!(s.next_frame(), Err(SourceError::Frame(_))));
    assert!(matches!(s.next_frame(), Err(SourceError::Frame(_))));
    assert!(matches!(s.next_frame(), Err(SourceError::Unavailable(_))));
    assert!(s.next_frame().unwrap().is_some());
    assert_eq!(world.lock().unwrap().opens, 2);
    assert_eq!(world.lock().unwrap().open_handles, 1);
}

#[test]
fn a_missing_sensor_at_start_is_an_error() {
    let (world, clock) = (digit_world(), FakeClock::new());
    let cfg = StreamConfig::new(
        "D99999",
        Calibration::default_for(SensorKind::DIGIT, "D99999"),
    );
    let r = SensorStream::open(
        cfg,
        FakeBackend {
            world,
            clock: clock.clone(),
        },
        clock,
    );
    assert!(matches!(r, Err(SourceError::Unavailable(_))));
}

#[test]
fn no_wanted_format_is_fatal_at_open() {
    let (world, clock) = (digit_world(), FakeClock::new());
    let mut cfg = StreamConfig::new(
        "D00045",
        Calibration::default_for(SensorKind::DIGIT, "D00045"),
    );
    cfg.request.formats = vec![PixelFormat::Mjpg];
    let r = SensorStream::open(
        cfg,
        FakeBackend {
            world,
            clock: clock.clone(),
        },
        clock,
    );
    let e = r.unwrap_err().to_string();
    assert!(e.contains("YUYV 320x240"), "{e}");
}

#[test]
fn digit_leds_are_written_verified_and_changed() {
    let (world, clock) = (digit_world(), FakeClock::new());
    let mut s = digit_stream(&world, &clock);
    assert_eq!(world.lock().unwrap().controls[&cid::ZOOM_ABSOLUTE], 4095);
    assert!(s.control_mismatches().is_empty());
    let bad = s
        .set_camera_settings(CameraSettings {
            led: Some(Led { r: 15, g: 0, b: 4 }),
            ..CameraSettings::default()
        })
        .unwrap();
    assert!(bad.is_empty());
    assert_eq!(world.lock().unwrap().controls[&cid::ZOOM_ABSOLUTE], 0xF04);
}

#[test]
fn old_digit_firmware_gets_a_global_level() {
    let (world, clock) = (digit_world(), FakeClock::new());
    world.lock().unwrap().firmware = Some("0103".into());
    let _s = digit_stream(&world, &clock);
    assert_eq!(world.lock().unwrap().controls[&cid::ZOOM_ABSOLUTE], 15);
}

fn gelsight_world() -> std::sync::Arc<std::sync::Mutex<World>> {
    let mode = Mode {
        format: PixelFormat::Yuyv,
        width: 640,
        height: 480,
        fps: 25.0,
    };
    let w = World::new("28J3-CWXU", mode, yuyv_gradient(640, 480));
    {
        let mut g = w.lock().unwrap();
        // Power-on state: auto everything.
        g.defaults = [
            (cid::EXPOSURE_AUTO, 3),
            (cid::EXPOSURE_ABSOLUTE, 300),
            (cid::AUTO_WHITE_BALANCE, 1),
            (cid::WHITE_BALANCE_TEMPERATURE, 6500),
            (cid::GAIN, 10),
        ]
        .into();
        g.firmware = Some("0100".into());
    }
    w
}

fn gelsight_stream(
    world: &std::sync::Arc<std::sync::Mutex<World>>,
    clock: &FakeClock,
) -> SensorStream<FakeBackend, FakeClock> {
    let cal = Calibration::default_for(SensorKind::GELSIGHT_MINI, "28J3-CWXU");
    let mut cfg = StreamConfig::new("28J3-CWXU", cal);
    cfg.request.formats = vec![PixelFormat::Yuyv];
    cfg.request.width = 640;
    cfg.request.height = 480;
    SensorStream::open(
        cfg,
        FakeBackend {
            world: world.clone(),
            clock: clock.clone(),
        },
        clock.clone(),
    )
    .unwrap()
}

fn gelsight_settings_in_effect(world: &std::sync::Arc<std::sync::Mutex<World>>) -> bool {
    let w = world.lock().unwrap();
    w.controls[&cid::EXPOSURE_AUTO] == 1
        && w.controls[&cid::EXPOSURE_ABSOLUTE] == 156
        && w.controls[&cid::AUTO_WHITE_BALANCE] == 0
        && w.controls[&cid::WHITE_BALANCE_TEMPERATURE] == 4500
        && w.controls[&cid::GAIN] == 0
}

#[test]
fn gelsight_settings_are_written_and_a_clamped_value_is_reported() {
    let (world, clock) = (gelsight_world(), FakeClock::new());
    let s = gelsight_stream(&world, &clock);
    assert!(gelsight_settings_in_effect(&world));
    assert!(s.control_mismatches().is_empty());
    drop(s);
    world
        .lock()
        .unwrap()
        .clamp
        .insert(cid::WHITE_BALANCE_TEMPERATURE, 5000);
    let s = gelsight_stream(&world, &clock);
    let m = s.control_mismatches();
    assert_eq!(m.len(), 1);
    assert_eq!(
        (m[0].name, m[0].wanted, m[0].got),
        ("white_balance_k", 4500, Some(5000))
    );
    assert_eq!(s.counters().control_mismatches, 1);
}

#[test]
fn reconnect_backs_off_then_reopens_by_serial_and_restores_settings() {
    let (world, clock) = (gelsight_world(), FakeClock::new());
    let mut s = gelsight_stream(&world, &clock);
    let first = s.next_frame().unwrap().unwrap();
    let settings = CameraSettings {
        exposure: Some(200),
        ..CameraSettings::for_kind(unitac_core::SensorKind::GELSIGHT_MINI)
    };
    s.set_camera_settings(settings).unwrap();
    world.lock().unwrap().present = false;
    assert!(matches!(s.next_frame(), Err(SourceError::Unavailable(_))));
    assert_eq!(s.state(), LinkState::Lost);
    assert_eq!(s.counters().disconnects, 1);
    world.lock().unwrap().open_attempts.clear();
    // Away for a while: each call returns Unavailable after at most report_every (2 s).
    for _ in 0..5 {
        let t0 = clock.mono();
        assert!(matches!(s.next_frame(), Err(SourceError::Unavailable(_))));
        assert!(clock.mono() - t0 <= Duration::from_millis(4100));
    }
    let attempts = world.lock().unwrap().open_attempts.clone();
    let gaps: Vec<u128> = attempts
        .windows(2)
        .map(|w| (w[1] - w[0]).as_millis())
        .collect();
    assert_eq!(&gaps[..6], [100, 200, 400, 800, 1600, 2000]);
    assert!(gaps[6..].iter().all(|&g| g == 2000), "{gaps:?}");
    // Back on the bus, power-cycled: its controls are at defaults until the stream restores them.
    world.lock().unwrap().present = true;
    let f = s.next_frame().unwrap().unwrap();
    assert_eq!(f.sensor_id, first.sensor_id);
    assert!(f.seq > first.seq);
    assert_eq!(s.state(), LinkState::Streaming);
    assert_eq!(s.counters().reconnects, 1);
    let w = world.lock().unwrap();
    assert_eq!(w.controls[&cid::EXPOSURE_ABSOLUTE], 200);
    assert_eq!(w.controls[&cid::WHITE_BALANCE_TEMPERATURE], 4500);
    assert_eq!(w.open_handles, 1);
}

#[test]
fn vanishing_and_returning_100_times_keeps_one_handle_and_the_settings() {
    let (world, clock) = (gelsight_world(), FakeClock::new());
    let mut s = gelsight_stream(&world, &clock);
    let mut last_seq = s.next_frame().unwrap().unwrap().seq;
    for i in 1..=100u64 {
        world.lock().unwrap().present = false;
        assert!(matches!(s.next_frame(), Err(SourceError::Unavailable(_))));
        assert_eq!(world.lock().unwrap().open_handles, 0);
        // Sometimes it stays away for a few attempts.
        for _ in 0..(i % 3) {
            assert!(s.next_frame().is_err());
        }
        world.lock().unwrap().present = true;
        let f = s.next_frame().unwrap().unwrap();
        assert_eq!(f.sensor_id, "28J3-CWXU");
        assert!(f.seq > last_seq);
        last_seq = f.seq;
        assert!(gelsight_settings_in_effect(&world), "after return {i}");
        let w = world.lock().unwrap();
        assert_eq!(w.opens, i + 1);
        assert_eq!(w.open_handles, 1);
    }
    let c = s.counters();
    assert_eq!((c.disconnects, c.reconnects), (100, 100));
    assert_eq!(c.dropped, 0);
}

#[test]
fn a_stalled_stream_is_reset_over_usb_reopened_and_its_settings_restored() {
    let (world, clock) = (gelsight_world(), FakeClock::new());
    let mut s = gelsight_stream(&world, &clock);
    let first = s.next_frame().unwrap().unwrap();
    world.lock().unwrap().stalled = true;
    let stalled_at = clock.mono();
    // Two 1 s timeouts are per-frame errors; the third (3 s without a frame) is the stall.
    assert!(matches!(s.next_frame(), Err(SourceError::Frame(_))));
    assert!(matches!(s.next_frame(), Err(SourceError::Frame(_))));
    assert_eq!(world.lock().unwrap().usb_resets, 0);
    assert!(matches!(s.next_frame(), Err(SourceError::Unavailable(_))));
    assert!(clock.mono() - stalled_at >= Duration::from_secs(3));
    {
        let w = world.lock().unwrap();
        assert_eq!(w.usb_resets, 1);
        assert_eq!(w.resets_with_open_node, 0);
        assert_eq!(w.open_handles, 0);
        // The reset power-cycled the camera: settings at defaults until the stream restores them.
        assert_eq!(w.controls[&cid::GAIN], 10);
    }
    let f = s.next_frame().unwrap().unwrap();
    assert_eq!(f.sensor_id, first.sensor_id);
    assert!(f.seq > first.seq);
    assert!(gelsight_settings_in_effect(&world));
    assert_eq!(world.lock().unwrap().open_handles, 1);
    let c = s.counters();
    assert_eq!(
        (c.stalls, c.usb_resets, c.stall_recoveries, c.reconnects),
        (1, 1, 1, 1)
    );
    assert_eq!(c.hotplug_events, 0);
}

#[test]
fn without_usb_access_a_stall_falls_back_to_reopening_the_node() {
    let (world, clock) = (digit_world(), FakeClock::new());
    world.lock().unwrap().can_reset = false;
    let mut s = digit_stream(&world, &clock);
    s.next_frame().unwrap().unwrap();
    world.lock().unwrap().stalled = true;
    for _ in 0..2 {
        assert!(matches!(s.next_frame(), Err(SourceError::Frame(_))));
    }
    assert!(matches!(s.next_frame(), Err(SourceError::Unavailable(_))));
    // Re-opening the node does not cure this stall: the stream keeps trying, counting each.
    world.lock().unwrap().stalled = false;
    assert!(s.next_frame().unwrap().is_some());
    let c = s.counters();
    assert_eq!(
        (
            c.stalls,
            c.usb_resets,
            c.usb_reset_failures,
            c.stall_recoveries
        ),
        (1, 0, 0, 1)
    );
    assert_eq!(world.lock().unwrap().usb_resets, 0);
}

#[test]
fn a_hotplug_arrival_wakes_the_reconnect_before_the_backoff_ends() {
    let (world, clock) = (gelsight_world(), FakeClock::new());
    {
        let mut w = world.lock().unwrap();
        w.hotplug = Some(Default::default());
        // Re-enumeration takes four open attempts; the arrival event comes with the last.
        w.reenumerate_opens = 4;
    }
    let mut s = gelsight_stream(&world, &clock);
    s.next_frame().unwrap().unwrap();
    world.lock().unwrap().stalled = true;
    world.lock().unwrap().open_attempts.clear();
    let f = loop {
        match s.next_frame() {
            Ok(Some(f)) => break f,
            Ok(None) => {}
            Err(_) => {}
        }
    };
    assert_eq!(f.sensor_id, "28J3-CWXU");
    let attempts = world.lock().unwrap().open_attempts.clone();
    let gaps: Vec<u128> = attempts
        .windows(2)
        .map(|w| (w[1] - w[0]).as_millis())
        .collect();
    // Backoff 100, 200, 400 ms between the failing attempts (waiting on events that do not
    // come), then the arrival wakes the last attempt after 1 ms instead of 800 ms.
    assert_eq!(gaps, [100, 200, 400, 1]);
    let c = s.counters();
    assert_eq!((c.hotplug_events, c.stall_recoveries), (1, 1));
    assert!(world.lock().unwrap().hotplug_waits >= 4);
}
