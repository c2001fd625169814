//! Entry points for the fuzz targets in crates/driver/fuzz (cargo fuzz) and for the seeded smoke
//! test that runs the same functions in CI (tests/fuzz_smoke.rs). Each takes arbitrary bytes and
//! must return without panicking, within the image size limit's memory.

use crate::decode::{Crop, DecodeConfig, FrameDecoder, PixelFormat, Rotation};
use crate::still::{self, StillFormat};

/// Largest negotiated size the MJPEG target decodes at (a 4096 x 4096 full-size decode is
/// 48 MB; the sensors stream at most 3280 x 2464).
const MAX_MJPEG_SIDE: u32 = 4096;

/// One buffer as an MJPEG frame of the size its own header claims (the stream's negotiated
/// size), through each decode path: the 1/8-scale DC-only walk with a region, the same without
/// restart-interval threads, the reduced-size and full-size `jpeg-decoder` paths, and the
/// whole-frame DC decode.
pub fn mjpeg(data: &[u8]) {
    let Some((w, h)) = sof_size(data) else {
        return;
    };
    if w > MAX_MJPEG_SIDE || h > MAX_MJPEG_SIDE {
        return;
    }
    let small = DecodeConfig::plain(w.div_ceil(8).clamp(1, 64), h.div_ceil(8).clamp(1, 64));
    let mut cropped = small;
    cropped.crop = Crop {
        left: 0.1,
        right: 0.2,
        top: 0.15,
        bottom: 0.3,
    };
    cropped.rotation = Rotation::Cw90;
    let mut quarter = DecodeConfig::plain(w.div_ceil(4).clamp(1, 64), h.div_ceil(4).clamp(1, 64));
    quarter.max_upscale = 1.0;
    let mut full = DecodeConfig::plain(w.min(64), h.min(64));
    full.dct_scaling = false;
    for (cfg, single) in [
        (small, false),
        (cropped, true),
        (quarter, false),
        (full, false),
    ] {
        if let Ok(mut d) = FrameDecoder::new(cfg) {
            d.set_single_thread(single);
            let _ = d.decode(PixelFormat::Mjpg, w, h, data);
        }
    }
    let _ = crate::dcjpeg::decode_dc(data, MAX_MJPEG_SIDE);
}

/// One buffer as a still image: as its magic bytes say, and as each format regardless.
pub fn still(data: &[u8]) {
    if let Some(f) = StillFormat::sniff(data) {
        let _ = still::decode(data, f);
    }
    for f in [StillFormat::Png, StillFormat::Jpeg] {
        let _ = still::dimensions(data, f);
    }
}

/// Width and height from the first SOFn segment, if any (the negotiated size of the stream).
fn sof_size(data: &[u8]) -> Option<(u32, u32)> {
    let mut pos = 2;
    for _ in 0..64 {
        let (&ff, &m) = (data.get(pos)?, data.get(pos + 1)?);
        if ff != 0xFF {
            return None;
        }
        let len = usize::from(*data.get(pos + 2)?) << 8 | usize::from(*data.get(pos + 3)?);
        if matches!(m, 0xC0..=0xCF) && !matches!(m, 0xC4 | 0xC8 | 0xCC) {
            let s = data.get(pos + 5..pos + 9)?;
            let h = u32::from(s[0]) << 8 | u32::from(s[1]);
            let w = u32::from(s[2]) << 8 | u32::from(s[3]);
            return (w > 0 && h > 0).then_some((w, h));
        }
        pos += 2 + len;
    }
    None
}
