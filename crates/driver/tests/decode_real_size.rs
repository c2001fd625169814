#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
//! Decode of real-size buffers generated here: a 3280x2464 GelSight Mini MJPEG made with a JPEG
//! encoder, truncated and corrupted copies of it, and DIGIT YUYV buffers.

use image::codecs::jpeg::JpegEncoder;
use unitac_driver::decode::{
    Crop, DecodeConfig, FrameDecoder, PixelFormat, Rgb, crop_resize, decode_jpeg_scaled,
};

/// A smooth scene with a few soft blobs, like a lit gel with contacts.
fn gel_image(w: u32, h: u32) -> Vec<u8> {
    let mut v = Vec::with_capacity((w * h * 3) as usize);
    for y in 0..h {
        for x in 0..w {
            let (fx, fy) = (x as f32 / w as f32, y as f32 / h as f32);
            let blob = |cx: f32, cy: f32, r: f32| {
                let d = ((fx - cx).powi(2) + (fy - cy).powi(2)).sqrt() / r;
                (1.0 - d).max(0.0) * 60.0
            };
            let b = blob(0.4, 0.5, 0.12) + blob(0.7, 0.3, 0.08);
            v.push((80.0 + 100.0 * fx + b).min(255.0) as u8);
            v.push((60.0 + 120.0 * fy - b * 0.5).max(0.0) as u8);
            v.push((150.0 - 50.0 * fx + b * 0.3) as u8);
        }
    }
    v
}

fn encode(w: u32, h: u32, rgb: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    JpegEncoder::new_with_quality(&mut out, 85)
        .encode(rgb, w, h, image::ExtendedColorType::Rgb8)
        .unwrap();
    out
}

fn mean_abs_diff(a: &[u8], b: &[u8]) -> f64 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(&x, &y)| (f64::from(x) - f64::from(y)).abs())
        .sum::<f64>()
        / a.len() as f64
}

#[test]
fn gelsight_mini_full_size_mjpeg_decodes_at_reduced_scale_to_320x240() {
    let (w, h) = (3280, 2464);
    let src = gel_image(w, h);
    let jpeg = encode(w, h, &src);
    let cfg = DecodeConfig::gelsight_mini();
    let mut d = FrameDecoder::new(cfg).unwrap();
    let out = d.decode(PixelFormat::Mjpg, w, h, &jpeg).unwrap();
    assert_eq!((out.width, out.height), (320, 240));
    assert_eq!(d.last_jpeg_scale, 8);

    // Reference: the vendor pipeline, full-size decode then crop + resize.
    let full = image::load_from_memory(&jpeg).unwrap().to_rgb8();
    let full = Rgb {
        width: w,
        height: h,
        data: full.into_raw(),
    };
    let reference = crop_resize(&full, &Crop::uniform(1.0 / 7.0), 320, 240).unwrap();
    let mad = mean_abs_diff(&out.data, &reference.data);
    assert!(mad < 3.0, "1/8: mean abs diff to full decode {mad}");
    let mut quarter = cfg;
    quarter.max_upscale = 1.0;
    let mut d4 = FrameDecoder::new(quarter).unwrap();
    let out4 = d4.decode(PixelFormat::Mjpg, w, h, &jpeg).unwrap();
    assert_eq!(d4.last_jpeg_scale, 4);
    let mad4 = mean_abs_diff(&out4.data, &reference.data);
    assert!(mad4 < 2.0, "1/4: mean abs diff to full decode {mad4}");
    eprintln!("mean abs diff to full decode: 1/8 {mad:.2}, 1/4 {mad4:.2}");

    // With DCT scaling off the result is the same pipeline as the reference.
    let mut full_cfg = cfg;
    full_cfg.dct_scaling = false;
    let (img, scale) = decode_jpeg_scaled(&jpeg, w, h, &full_cfg).unwrap();
    assert_eq!((img.width, img.height, scale), (w, h, 1));

    // 1/8 scale when no crop is asked for (410x308 -> 320x240).
    let (img, scale) = decode_jpeg_scaled(&jpeg, w, h, &DecodeConfig::plain(320, 240)).unwrap();
    assert_eq!((img.width, img.height, scale), (410, 308, 8));
}

#[test]
fn truncated_corrupt_and_wrong_size_jpegs_are_frame_errors() {
    let (w, h) = (640, 480);
    let jpeg = encode(w, h, &gel_image(w, h));
    let mut d = FrameDecoder::new(DecodeConfig::plain(320, 240)).unwrap();
    assert!(d.decode(PixelFormat::Mjpg, w, h, &jpeg).is_ok());
    // Truncated at many points: error or (if the decoder pads) a full-size frame; never a panic.
    for cut in [2, 20, 200, 600, jpeg.len() / 2, jpeg.len() - 3] {
        if let Ok(f) = d.decode(PixelFormat::Mjpg, w, h, &jpeg[..cut]) {
            assert_eq!((f.width, f.height), (320, 240));
        }
    }
    assert!(d.counters.errors >= 4, "{:?}", d.counters);
    // Flipped bytes in the header.
    let mut bad = jpeg.clone();
    for b in bad.iter_mut().skip(2).take(200) {
        *b ^= 0x5a;
    }
    assert!(d.decode(PixelFormat::Mjpg, w, h, &bad).is_err());
    // A JPEG of another size than the stream's.
    assert!(matches!(
        d.decode(PixelFormat::Mjpg, 320, 240, &jpeg),
        Err(unitac_driver::decode::DecodeError::WrongJpegSize { .. })
    ));
    // Still decodes good frames afterwards.
    assert!(d.decode(PixelFormat::Mjpg, w, h, &jpeg).is_ok());
}

#[test]
fn digit_mjpeg_and_yuyv_of_the_same_scene_agree() {
    let (w, h) = (320, 240);
    let rgb = gel_image(w, h);
    let jpeg = encode(w, h, &rgb);
    let mut d = FrameDecoder::new(DecodeConfig::plain(320, 240)).unwrap();
    let from_jpeg = d.decode(PixelFormat::Mjpg, w, h, &jpeg).unwrap();
    // YUYV of the same scene (BT.601 limited range, chroma averaged per pair).
    let mut yuyv = Vec::new();
    for p in rgb.chunks_exact(6) {
        let yuv = |r: u8, g: u8, b: u8| {
            let (r, g, b) = (f64::from(r), f64::from(g), f64::from(b));
            (
                16.0 + 0.2568 * r + 0.5041 * g + 0.0979 * b,
                128.0 - 0.1482 * r - 0.2910 * g + 0.4392 * b,
                128.0 + 0.4392 * r - 0.3678 * g - 0.0714 * b,
            )
        };
        let (y0, u0, v0) = yuv(p[0], p[1], p[2]);
        let (y1, u1, v1) = yuv(p[3], p[4], p[5]);
        yuyv.extend_from_slice(&[
            y0.round() as u8,
            ((u0 + u1) / 2.0).round() as u8,
            y1.round() as u8,
            ((v0 + v1) / 2.0).round() as u8,
        ]);
    }
    let from_yuyv = d.decode(PixelFormat::Yuyv, w, h, &yuyv).unwrap();
    assert!(mean_abs_diff(&from_yuyv.data, &rgb) < 1.5);
    assert!(mean_abs_diff(&from_jpeg.data, &rgb) < 2.5);
}

/// Remove every DHT segment and add an AVI1 APP0, as UVC MJPEG frames come.
fn strip_dht(jpeg: &[u8]) -> Vec<u8> {
    let mut out = vec![
        0xFF, 0xD8, 0xFF, 0xE0, 0x00, 0x08, b'A', b'V', b'I', b'1', 0, 0,
    ];
    let mut pos = 2;
    loop {
        let m = jpeg[pos + 1];
        let len = (usize::from(jpeg[pos + 2]) << 8) | usize::from(jpeg[pos + 3]);
        if m == 0xDA {
            out.extend_from_slice(&jpeg[pos..]);
            return out;
        }
        if m != 0xC4 {
            out.extend_from_slice(&jpeg[pos..pos + 2 + len]);
        }
        pos += 2 + len;
    }
}

#[test]
fn dc_only_fast_path_matches_jpeg_decoder_at_one_eighth() {
    for (w, h) in [(3280u32, 2464u32), (640, 480), (333, 250)] {
        let jpeg = encode(w, h, &gel_image(w, h));
        let fast = unitac_driver::dcjpeg::decode_dc(&jpeg, 8192).unwrap();
        assert_eq!((fast.width, fast.height), (w.div_ceil(8), h.div_ceil(8)));
        let mut dec = jpeg_decoder::Decoder::new(&jpeg[..]);
        dec.read_info().unwrap();
        let (rw, rh) = dec
            .scale(w.div_ceil(8) as u16, h.div_ceil(8) as u16)
            .unwrap();
        assert_eq!((u32::from(rw), u32::from(rh)), (fast.width, fast.height));
        let reference = dec.decode().unwrap();
        let mad = mean_abs_diff(&fast.rgb, &reference);
        assert!(mad < 1.5, "{w}x{h}: mean abs diff {mad}");
        // Without Huffman tables (MJPEG): the standard tables give the same image.
        let bare = strip_dht(&jpeg);
        assert!(bare.len() < jpeg.len());
        let again = unitac_driver::dcjpeg::decode_dc(&bare, 8192).unwrap();
        assert_eq!(again, fast);
    }
    // Grey JPEG.
    let grey: Vec<u8> = (0..64 * 48).map(|i| (i % 251) as u8).collect();
    let mut out = Vec::new();
    JpegEncoder::new_with_quality(&mut out, 90)
        .encode(&grey, 64, 48, image::ExtendedColorType::L8)
        .unwrap();
    let g = unitac_driver::dcjpeg::decode_dc(&out, 8192).unwrap();
    assert_eq!((g.width, g.height), (8, 6));
}

#[test]
fn dc_only_path_rejects_truncated_and_corrupt_data() {
    let jpeg = encode(640, 480, &gel_image(640, 480));
    for cut in [2, 50, 300, 600] {
        assert!(unitac_driver::dcjpeg::decode_dc(&jpeg[..cut], 8192).is_err());
    }
    let mut bad = jpeg.clone();
    let n = bad.len();
    for b in bad[n / 3..n / 3 + 400].iter_mut() {
        *b = 0xFF;
    }
    // Garbage in the entropy-coded data: an error or some image, never a panic.
    let _ = unitac_driver::dcjpeg::decode_dc(&bad, 8192);
    let mut small = jpeg.clone();
    small.truncate(n - n / 4);
    let _ = unitac_driver::dcjpeg::decode_dc(&small, 8192);
    assert!(unitac_driver::dcjpeg::decode_dc(&jpeg, 100).is_err());
}

/// The same scene from an encoder that writes restart markers (`interval` MCUs each).
fn encode_with_restarts(w: u32, h: u32, rgb: &[u8], interval: u16) -> Vec<u8> {
    let mut out = Vec::new();
    let mut enc = jpeg_encoder::Encoder::new(&mut out, 85);
    enc.set_sampling_factor(jpeg_encoder::SamplingFactor::F_2_2);
    enc.set_restart_interval(interval);
    enc.encode(rgb, w as u16, h as u16, jpeg_encoder::ColorType::Rgb)
        .unwrap();
    out
}

#[test]
fn restart_markers_decode_on_two_threads_to_the_same_image_as_one() {
    use unitac_driver::dcjpeg::{BlockRect, DcDecoder};
    // One decoder for all sizes: its reused buffers hold the previous (larger) frame's blocks,
    // which must never show through.
    let mut two = DcDecoder::new();
    for (w, h, interval) in [(3280u32, 2464u32, 205u16), (640, 480, 7), (333, 250, 1)] {
        let jpeg = encode_with_restarts(w, h, &gel_image(w, h), interval);
        assert!(jpeg.windows(2).any(|p| p == [0xFF, 0xDD]), "no DRI");
        let a = two.decode(&jpeg, 8192, None).unwrap().rgb.to_vec();
        assert_eq!(two.stats.threads, 2, "{w}x{h}");
        assert_eq!(two.stats.intervals_skipped, 0);
        let mcus = w.div_ceil(16) * h.div_ceil(16);
        assert_eq!(
            two.stats.restart_intervals,
            mcus.div_ceil(u32::from(interval))
        );
        assert_eq!(two.stats.mcus_decoded, mcus);
        let mut one = DcDecoder::new();
        one.single_thread = true;
        let b = one.decode(&jpeg, 8192, None).unwrap().rgb.to_vec();
        assert_eq!(one.stats.threads, 1);
        assert_eq!(a, b, "{w}x{h}: two threads differ from one");
        // And both agree with jpeg-decoder's own 1/8 decode.
        let mut dec = jpeg_decoder::Decoder::new(&jpeg[..]);
        dec.read_info().unwrap();
        dec.scale(w.div_ceil(8) as u16, h.div_ceil(8) as u16)
            .unwrap();
        let reference = dec.decode().unwrap();
        // (Rounding of the colour conversion and chroma placement differ; a restart interval
        // decoded from the wrong place would be off by tens of DN.)
        let mad = mean_abs_diff(&a, &reference);
        assert!(mad < 2.0, "{w}x{h}: mean abs diff {mad}");
        // A region: intervals outside it are skipped, the region itself is the same bytes.
        let (ow, oh) = (w.div_ceil(8), h.div_ceil(8));
        let roi = BlockRect {
            x0: ow / 4,
            y0: oh / 4,
            x1: ow * 3 / 4,
            y1: oh * 3 / 4,
        };
        let c = two.decode(&jpeg, 8192, Some(roi)).unwrap().rgb.to_vec();
        assert!(two.stats.intervals_skipped > 0, "{w}x{h}: nothing skipped");
        assert!(two.stats.mcus_decoded < mcus);
        for y in roi.y0..roi.y1 {
            let r = ((y * ow + roi.x0) * 3) as usize..((y * ow + roi.x1) * 3) as usize;
            assert_eq!(c[r.clone()], a[r], "{w}x{h}: row {y}");
        }
    }
}

#[test]
fn the_crop_region_path_gives_the_same_bytes_as_decoding_everything() {
    let (w, h) = (3280, 2464);
    let img = gel_image(w, h);
    for jpeg in [encode(w, h, &img), encode_with_restarts(w, h, &img, 205)] {
        let cfg = DecodeConfig::gelsight_mini();
        let mut d = FrameDecoder::new(cfg).unwrap();
        let out = d.decode(PixelFormat::Mjpg, w, h, &jpeg).unwrap();
        assert_eq!(d.last_jpeg_scale, 8);
        // Stops after the crop's last MCU row, or skips whole restart intervals.
        let mut everything = unitac_driver::dcjpeg::DcDecoder::new();
        let full = everything.decode(&jpeg, 8192, None).unwrap();
        let full = Rgb {
            width: full.width,
            height: full.height,
            data: full.rgb.to_vec(),
        };
        assert!(d.dc_stats().mcus_decoded < everything.stats.mcus_decoded);
        let reference = crop_resize(&full, &cfg.crop, 320, 240).unwrap();
        assert_eq!(out.data, reference.data);
        // The decoder's buffers are reused: a second frame gives the same bytes again.
        assert_eq!(d.decode(PixelFormat::Mjpg, w, h, &jpeg).unwrap(), out);
    }
}
