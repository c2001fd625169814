#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
//! A cut MJPEG frame (its entropy-coded data ends before the last MCU) is a decode error on every
//! path of the sensor decode and a corrupt frame of the stream, never a frame half filled with
//! grey. Complete data without the EOI marker, and bytes after the EOI, are accepted. The same
//! rule for still images (files): `unitac_driver::still`.

mod common;

use common::*;
use std::time::Duration;
use unitac_core::{SensorKind, Source, SourceError};
use unitac_driver::calib::Calibration;
use unitac_driver::capture::Mode;
use unitac_driver::decode::{DecodeConfig, DecodeError, FrameDecoder, PixelFormat};
use unitac_driver::still::{self, StillFormat};
use unitac_driver::stream::{SensorStream, StreamConfig};

/// A smooth lit gel with one soft press, detailed enough that every MCU has AC coefficients.
fn gel(w: u32, h: u32) -> Vec<u8> {
    let mut v = Vec::with_capacity((w * h * 3) as usize);
    for y in 0..h {
        for x in 0..w {
            let (fx, fy) = (x as f32 / w as f32, y as f32 / h as f32);
            let d = ((fx - 0.5).powi(2) + (fy - 0.6).powi(2)).sqrt() / 0.15;
            let b = (1.0 - d).max(0.0) * 60.0;
            let t = ((x * 7 + y * 13) % 23) as f32;
            v.push((80.0 + 100.0 * fx + b + t).min(255.0) as u8);
            v.push((60.0 + 120.0 * fy - b * 0.5 + t).clamp(0.0, 255.0) as u8);
            v.push((150.0 - 50.0 * fx + b * 0.3) as u8);
        }
    }
    v
}

fn encode(w: u32, h: u32, restart: u16) -> Vec<u8> {
    let mut out = Vec::new();
    let mut enc = jpeg_encoder::Encoder::new(&mut out, 85);
    enc.set_sampling_factor(jpeg_encoder::SamplingFactor::F_2_2);
    if restart > 0 {
        enc.set_restart_interval(restart);
    }
    enc.encode(&gel(w, h), w as u16, h as u16, jpeg_encoder::ColorType::Rgb)
        .unwrap();
    assert_eq!(out[out.len() - 2..], [0xFF, 0xD9]);
    out
}

/// The decode configurations that reach each path: 1/8-scale DC walk with the crop region
/// (GelSight Mini), the DC walk of the whole frame, `jpeg-decoder` at 1/4 and at full size.
/// Each with the DCT scale it decodes a 1640 x 1232 frame at.
fn configs() -> Vec<(&'static str, DecodeConfig, u32)> {
    let mut region = DecodeConfig::gelsight_mini();
    (region.out_width, region.out_height) = (128, 96);
    let mut quarter = DecodeConfig::gelsight_mini();
    quarter.max_upscale = 1.0;
    let mut full = DecodeConfig::plain(320, 240);
    full.dct_scaling = false;
    vec![
        ("dc region", region, 8),
        ("dc whole", DecodeConfig::plain(205, 154), 8),
        ("jpeg-decoder 1/2", quarter, 2),
        ("jpeg-decoder full", full, 1),
    ]
}

/// Where a frame of `len` bytes is cut: at the start of the scan, inside it, in its last rows
/// (below the GelSight Mini crop region) and its last entropy-coded byte.
fn cuts(jpeg: &[u8]) -> Vec<usize> {
    let n = jpeg.len();
    let sos = jpeg.windows(2).position(|w| w == [0xFF, 0xDA]).unwrap();
    vec![sos + 14, n / 3, n / 2, n * 9 / 10, n * 97 / 100, n - 3]
}

#[test]
fn a_cut_mjpeg_frame_is_a_decode_error_on_every_path() {
    let (w, h) = (1640, 1232);
    for restart in [0u16, 52] {
        let jpeg = encode(w, h, restart);
        let no_eoi = &jpeg[..jpeg.len() - 2];
        let mut garbage = jpeg.clone();
        garbage.extend_from_slice(&[0x12, 0x34, 0xFF, 0x00, 0x56]);
        for (name, cfg, scale) in configs() {
            let mut d = FrameDecoder::new(cfg).unwrap();
            let good = d.decode(PixelFormat::Mjpg, w, h, &jpeg).unwrap();
            assert_eq!(d.last_jpeg_scale, scale, "{name}");
            if name == "dc region" {
                // The crop region ends above the last rows: those are not decoded.
                assert!(d.dc_stats().mcus_decoded < 103 * 77, "{:?}", d.dc_stats());
            }
            for cut in cuts(&jpeg) {
                let r = d.decode(PixelFormat::Mjpg, w, h, &jpeg[..cut]);
                assert!(
                    matches!(r, Err(DecodeError::Jpeg(_))),
                    "{name}, restart {restart}: cut at {cut} of {}: {:?}",
                    jpeg.len(),
                    r.map(|f| (f.width, f.height))
                );
            }
            // Complete data: no EOI, or bytes after it, give the same frame.
            for (what, buf) in [("no EOI", no_eoi), ("trailing bytes", &garbage[..])] {
                match d.decode(PixelFormat::Mjpg, w, h, buf) {
                    Ok(f) => assert!(f == good, "{name}, restart {restart}: {what}: other pixels"),
                    Err(e) => panic!("{name}, restart {restart}: {what}: {e}"),
                }
            }
            assert_eq!(
                d.counters.errors,
                cuts(&jpeg).len() as u64,
                "{name}, restart {restart}"
            );
        }
    }
}

#[test]
fn a_cut_mjpeg_buffer_is_a_corrupt_frame_of_the_stream() {
    let (w, h) = (640, 480);
    let jpeg = encode(w, h, 0);
    let mode = Mode {
        format: PixelFormat::Mjpg,
        width: w,
        height: h,
        fps: 25.0,
    };
    let world = World::new("28J3-CWXU", mode, jpeg.clone());
    let clock = FakeClock::new();
    let cal = Calibration::default_for(SensorKind::GELSIGHT_MINI, "28J3-CWXU");
    let mut cfg = StreamConfig::new("28J3-CWXU", cal);
    cfg.request.formats = vec![PixelFormat::Mjpg];
    cfg.request.width = w;
    cfg.request.height = h;
    let backend = FakeBackend {
        world: world.clone(),
        clock: clock.clone(),
    };
    let mut s = SensorStream::open(cfg, backend, clock.clone()).unwrap();
    world.lock().unwrap().script.extend([
        Next::Bytes(jpeg[..jpeg.len() * 2 / 3].to_vec()),
        Next::Good {
            age: Duration::ZERO,
        },
    ]);
    assert!(matches!(s.next_frame(), Err(SourceError::Frame(_))));
    assert!(s.next_frame().unwrap().is_some());
    let c = s.counters();
    assert_eq!((c.decode_errors, c.frames), (1, 1));
}

#[test]
fn a_cut_jpeg_still_image_is_an_error() {
    let (w, h) = (96, 64);
    for restart in [0u16, 3] {
        let jpeg = encode(w, h, restart);
        let good = still::decode(&jpeg, StillFormat::Jpeg).unwrap();
        assert_eq!((good.width, good.height), (w, h));
        for cut in cuts(&jpeg) {
            let r = still::decode(&jpeg[..cut], StillFormat::Jpeg);
            assert!(
                r.is_err(),
                "restart {restart}: cut at {cut} of {}",
                jpeg.len()
            );
        }
        let mut garbage = jpeg.clone();
        garbage.extend_from_slice(b"trailing");
        match still::decode(&garbage, StillFormat::Jpeg) {
            Ok(f) => assert!(f == good, "restart {restart}: trailing bytes: other pixels"),
            Err(e) => panic!("restart {restart}: trailing bytes: {e}"),
        }
        // A file without EOI was cut, even where the last MCU is whole.
        assert!(still::decode(&jpeg[..jpeg.len() - 2], StillFormat::Jpeg).is_err());
    }
}

#[test]
fn still_image_size_limit_is_checked_before_decoding() {
    // A PNG header claiming 16777216 x 1 (no pixel data).
    let mut png = b"\x89PNG\r\n\x1a\n\0\0\0\x0dIHDR".to_vec();
    png.extend_from_slice(&16_777_216u32.to_be_bytes());
    png.extend_from_slice(&1u32.to_be_bytes());
    png.extend_from_slice(&[8, 2, 0, 0, 0]);
    let crc_ihdr = crc(&png[12..]);
    png.extend_from_slice(&crc_ihdr.to_be_bytes());
    for chunk in [&b"IDAT"[..], b"IEND"] {
        png.extend_from_slice(&[0, 0, 0, 0]);
        png.extend_from_slice(chunk);
        png.extend_from_slice(&crc(chunk).to_be_bytes());
    }
    let e = still::decode(&png, StillFormat::Png).unwrap_err();
    assert_eq!(
        e.to_string(),
        "image is 16777216x1: the limit is 1..=8192 pixels a side and 16777216 pixels in all"
    );
}

fn crc(data: &[u8]) -> u32 {
    let mut c = 0xFFFF_FFFFu32;
    for &b in data {
        c ^= u32::from(b);
        for _ in 0..8 {
            c = if c & 1 != 0 {
                0xEDB8_8320 ^ (c >> 1)
            } else {
                c >> 1
            };
        }
    }
    !c
}
