//! Raw camera buffers to published RGB8 frames: YUYV and MJPEG decode, crop, resize, rotate.
//!
//! Pure: no device, no clock. A bad buffer (truncated JPEG, short YUYV, wrong size) is an error
//! for that one frame; the caller counts it and goes on.
//!
//! GelSight Mini streams only MJPEG 3280x2464. Decoding that at full size and then throwing away
//! 99 % of the pixels is what makes the vendor pipeline miss 25 fps. Here the JPEG is decoded at
//! 1/2, 1/4 or 1/8 scale in the DCT domain (`jpeg_decoder::Decoder::scale`, the reduced-size
//! IDCT), picking the smallest scale whose cropped region is still at least the output size, so
//! the resize that follows never upsamples.

use serde::{Deserialize, Serialize};
use thiserror::Error;
use unitac_core::pixel::{self, PixelError, Yuv422};

/// Largest raw buffer accepted from a device or a file (a 3280x2464 MJPEG is about 1-3 MB).
pub const MAX_RAW_BYTES: usize = 32 << 20;
/// Largest side of a raw image or of the output.
pub const MAX_SIDE: u32 = unitac_core::frame::MAX_SIDE;

#[derive(Debug, Error, PartialEq, Eq)]
pub enum DecodeError {
    #[error("buffer of {got} bytes is larger than the {max}-byte limit")]
    TooLarge { got: usize, max: usize },
    #[error("size {width}x{height} is outside 1..={max} per side", max = MAX_SIDE)]
    BadSize { width: u32, height: u32 },
    #[error("YUYV {width}x{height} needs {expected} bytes, got {got}")]
    ShortYuyv {
        width: u32,
        height: u32,
        expected: usize,
        got: usize,
    },
    #[error("YUYV width {0} is odd")]
    OddYuyvWidth(u32),
    #[error("JPEG: {0}")]
    Jpeg(String),
    #[error("JPEG is {got_w}x{got_h}, the stream was negotiated at {want_w}x{want_h}")]
    WrongJpegSize {
        got_w: u32,
        got_h: u32,
        want_w: u32,
        want_h: u32,
    },
    #[error("crop leaves no pixels: {0}")]
    BadCrop(String),
}

/// Pixel format of the raw stream.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum PixelFormat {
    /// YUV 4:2:2 packed Y0 U Y1 V, BT.601 limited range.
    Yuyv,
    /// YUV 4:2:2 packed U Y0 V Y1, BT.601 limited range.
    Uyvy,
    /// Motion JPEG: one baseline JPEG per buffer (Huffman tables may be omitted).
    Mjpg,
}

impl PixelFormat {
    pub fn fourcc(self) -> [u8; 4] {
        match self {
            PixelFormat::Yuyv => *b"YUYV",
            PixelFormat::Uyvy => *b"UYVY",
            PixelFormat::Mjpg => *b"MJPG",
        }
    }
    pub fn from_fourcc(cc: [u8; 4]) -> Option<Self> {
        match &cc {
            b"YUYV" => Some(PixelFormat::Yuyv),
            b"UYVY" => Some(PixelFormat::Uyvy),
            b"MJPG" => Some(PixelFormat::Mjpg),
            _ => None,
        }
    }
}

/// Rotation applied after crop and resize (clockwise).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Rotation {
    #[default]
    None,
    Cw90,
    Cw180,
    Cw270,
}

impl Rotation {
    fn swaps_axes(self) -> bool {
        matches!(self, Rotation::Cw90 | Rotation::Cw270)
    }
}

/// Region of the native image kept before the resize, as fractions of each side cut away.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Crop {
    pub left: f64,
    pub right: f64,
    pub top: f64,
    pub bottom: f64,
}

impl Crop {
    pub const NONE: Crop = Crop::uniform(0.0);
    pub const fn uniform(f: f64) -> Crop {
        Crop {
            left: f,
            right: f,
            top: f,
            bottom: f,
        }
    }
    fn check(&self) -> Result<(), DecodeError> {
        let ok =
            |a: f64, b: f64| a.is_finite() && b.is_finite() && a >= 0.0 && b >= 0.0 && a + b < 0.95;
        if ok(self.left, self.right) && ok(self.top, self.bottom) {
            Ok(())
        } else {
            Err(DecodeError::BadCrop(format!(
                "{self:?}: each fraction >= 0, opposite sides together < 0.95"
            )))
        }
    }
    fn kept_w(&self) -> f64 {
        1.0 - self.left - self.right
    }
    fn kept_h(&self) -> f64 {
        1.0 - self.top - self.bottom
    }
}

/// How a raw buffer becomes a published frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DecodeConfig {
    /// Published size (after rotation).
    pub out_width: u32,
    pub out_height: u32,
    pub crop: Crop,
    pub rotation: Rotation,
    /// Mirror left-right after the rotation.
    #[serde(default)]
    pub flip_horizontal: bool,
    /// Mirror top-bottom after the rotation.
    #[serde(default)]
    pub flip_vertical: bool,
    /// Allow decoding MJPEG at reduced scale in the DCT domain (on by default; off = full decode).
    #[serde(default = "yes")]
    pub dct_scaling: bool,
    /// How much the resize may upsample to allow a smaller DCT scale (1.0 = never upsample;
    /// 1.1 lets GelSight Mini decode at 1/8: 410x308 cropped 1/7 per side is 293x220 for 320x240).
    #[serde(default = "one")]
    pub max_upscale: f64,
}

fn one() -> f64 {
    1.0
}

fn yes() -> bool {
    true
}

impl DecodeConfig {
    /// 320x240, no crop, no rotation.
    pub fn plain(out_width: u32, out_height: u32) -> Self {
        Self {
            out_width,
            out_height,
            crop: Crop::NONE,
            rotation: Rotation::None,
            flip_horizontal: false,
            flip_vertical: false,
            dct_scaling: true,
            max_upscale: 1.0,
        }
    }
    /// A kind's pipeline from its profile: its crop, published size and largest upscale.
    pub fn for_kind(kind: unitac_core::SensorKind) -> Self {
        let p = kind.profile();
        Self {
            crop: Crop::uniform(p.crop),
            max_upscale: p.max_upscale,
            ..Self::plain(p.size[0], p.size[1])
        }
    }
    /// GelSight Mini vendor pipeline (sensors/gelsight-mini.yaml): 1/7 border per side,
    /// 320x240. Decoded at 1/8 scale (DC only, `crate::dcjpeg`): the cropped region is then
    /// 293x220, upsampled 1.09x to 320x240 (its `max_upscale` 1.1 allows it); `max_upscale: 1.0`
    /// decodes at 1/4 instead (full detail, about 2.5x the CPU).
    pub fn gelsight_mini() -> Self {
        Self::for_kind(unitac_core::SensorKind::GELSIGHT_MINI)
    }
    pub fn check(&self) -> Result<(), DecodeError> {
        check_size(self.out_width, self.out_height)?;
        if !(self.max_upscale.is_finite() && (1.0..=2.0).contains(&self.max_upscale)) {
            return Err(DecodeError::BadCrop(format!(
                "max_upscale {} is outside 1..=2",
                self.max_upscale
            )));
        }
        self.crop.check()
    }
    /// Size the resize produces, before the rotation.
    fn pre_rotation_size(&self) -> (u32, u32) {
        if self.rotation.swaps_axes() {
            (self.out_height, self.out_width)
        } else {
            (self.out_width, self.out_height)
        }
    }
}

fn check_size(width: u32, height: u32) -> Result<(), DecodeError> {
    if width == 0 || height == 0 || width > MAX_SIDE || height > MAX_SIDE {
        Err(DecodeError::BadSize { width, height })
    } else {
        Ok(())
    }
}

/// An RGB8 image (row-major, no padding).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Rgb {
    pub width: u32,
    pub height: u32,
    pub data: Vec<u8>,
}

/// YUYV (BT.601 limited range, as UVC cameras send it) to RGB8.
pub fn yuyv_to_rgb(buf: &[u8], width: u32, height: u32) -> Result<Rgb, DecodeError> {
    yuv422_to_rgb(Yuv422::Yuyv, buf, width, height)
}

/// Packed 4:2:2 (YUYV or UYVY) to RGB8 with the shared converter of `unitac_core::pixel`.
/// Drivers may report a bytesused larger than the image (padding): extra bytes are ignored.
pub fn yuv422_to_rgb(
    order: Yuv422,
    buf: &[u8],
    width: u32,
    height: u32,
) -> Result<Rgb, DecodeError> {
    check_size(width, height)?;
    let data = pixel::yuv422_to_rgb(order, buf, width, height).map_err(|e| match e {
        PixelError::OddWidth(w) => DecodeError::OddYuyvWidth(w),
        PixelError::Short { expected, got, .. } => DecodeError::ShortYuyv {
            width,
            height,
            expected,
            got,
        },
        _ => DecodeError::BadSize { width, height },
    })?;
    Ok(Rgb {
        width,
        height,
        data,
    })
}

/// Per-frame statistics of the decoder.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct DecodeCounters {
    pub ok: u64,
    pub errors: u64,
}

/// Reusable decoder for one stream: checks the configuration once, keeps counters and the
/// DC-only JPEG decoder's tables and buffers (nothing full-size is allocated per frame).
#[derive(Debug, Clone)]
pub struct FrameDecoder {
    cfg: DecodeConfig,
    pub counters: DecodeCounters,
    /// DCT scale denominator (1, 2, 4, 8) used for the last MJPEG frame.
    pub last_jpeg_scale: u32,
    dc: crate::dcjpeg::DcDecoder,
}

impl FrameDecoder {
    pub fn new(cfg: DecodeConfig) -> Result<Self, DecodeError> {
        cfg.check()?;
        Ok(Self {
            cfg,
            counters: DecodeCounters::default(),
            last_jpeg_scale: 1,
            dc: crate::dcjpeg::DcDecoder::new(),
        })
    }
    pub fn config(&self) -> &DecodeConfig {
        &self.cfg
    }
    /// What the DC-only JPEG path did on the last 1/8-scale frame (restart intervals skipped,
    /// threads).
    pub fn dc_stats(&self) -> crate::dcjpeg::DcStats {
        self.dc.stats
    }
    /// Keep the DC-only JPEG path on one thread (it uses two only when restart markers allow).
    pub fn set_single_thread(&mut self, on: bool) {
        self.dc.single_thread = on;
    }

    /// Decode one raw buffer of the negotiated format and size into the published frame.
    pub fn decode(
        &mut self,
        format: PixelFormat,
        width: u32,
        height: u32,
        buf: &[u8],
    ) -> Result<Rgb, DecodeError> {
        let r = self.decode_inner(format, width, height, buf);
        match r {
            Ok(_) => self.counters.ok += 1,
            Err(_) => self.counters.errors += 1,
        }
        r
    }

    fn decode_inner(
        &mut self,
        format: PixelFormat,
        width: u32,
        height: u32,
        buf: &[u8],
    ) -> Result<Rgb, DecodeError> {
        if buf.len() > MAX_RAW_BYTES {
            return Err(DecodeError::TooLarge {
                got: buf.len(),
                max: MAX_RAW_BYTES,
            });
        }
        check_size(width, height)?;
        let (tw, th) = self.cfg.pre_rotation_size();
        let full = match format {
            PixelFormat::Yuyv => yuv422_to_rgb(Yuv422::Yuyv, buf, width, height)?,
            PixelFormat::Uyvy => yuv422_to_rgb(Yuv422::Uyvy, buf, width, height)?,
            PixelFormat::Mjpg => {
                if choose_jpeg_scale(width, height, &self.cfg) == 8
                    && let Some(out) = self.decode_dc_region(buf, width, height, tw, th)?
                {
                    self.last_jpeg_scale = 8;
                    return Ok(self.orient(out));
                }
                let (img, scale) = decode_jpeg_scaled(buf, width, height, &self.cfg)?;
                self.last_jpeg_scale = scale;
                img
            }
        };
        let resized = if self.cfg.crop == Crop::NONE && (full.width, full.height) == (tw, th) {
            full
        } else {
            crop_resize(&full, &self.cfg.crop, tw, th)?
        };
        Ok(self.orient(resized))
    }

    fn orient(&self, img: Rgb) -> Rgb {
        orient(
            img,
            self.cfg.rotation,
            self.cfg.flip_horizontal,
            self.cfg.flip_vertical,
        )
    }

    /// The 1/8-scale DC-only path, decoding only the blocks the crop + resize reads. `None`:
    /// a JPEG kind it does not handle (the caller falls back to `jpeg-decoder`).
    fn decode_dc_region(
        &mut self,
        buf: &[u8],
        width: u32,
        height: u32,
        tw: u32,
        th: u32,
    ) -> Result<Option<Rgb>, DecodeError> {
        let (sw, sh) = (width.div_ceil(8), height.div_ceil(8));
        let c = &self.cfg.crop;
        // The bilinear taps reach at most one pixel past the crop on each side.
        let lo = |f: f64, n: u32| ((f * f64::from(n)).floor() as u32).saturating_sub(1);
        let hi = |f: f64, n: u32| (((1.0 - f) * f64::from(n)).ceil() as u32 + 2).min(n);
        let roi = crate::dcjpeg::BlockRect {
            x0: lo(c.left, sw),
            y0: lo(c.top, sh),
            x1: hi(c.right, sw),
            y1: hi(c.bottom, sh),
        };
        let img = match self.dc.decode(buf, MAX_SIDE, Some(roi)) {
            Ok(img) => img,
            Err(crate::dcjpeg::DcError::Corrupt(m)) => return Err(DecodeError::Jpeg(m)),
            Err(crate::dcjpeg::DcError::Unsupported(_)) => return Ok(None),
        };
        if (img.full_width, img.full_height) != (width, height) {
            return Err(DecodeError::WrongJpegSize {
                got_w: img.full_width,
                got_h: img.full_height,
                want_w: width,
                want_h: height,
            });
        }
        let view = RgbView {
            width: img.width,
            height: img.height,
            data: img.rgb,
        };
        crop_resize_view(view, c, tw, th).map(Some)
    }
}

/// Largest DCT scale denominator (8, 4, 2, 1) whose cropped region is still >= the target.
pub fn choose_jpeg_scale(width: u32, height: u32, cfg: &DecodeConfig) -> u32 {
    if !cfg.dct_scaling {
        return 1;
    }
    let (tw, th) = cfg.pre_rotation_size();
    for d in [8u32, 4, 2] {
        let w = width.div_ceil(d);
        let h = height.div_ceil(d);
        let up = cfg.max_upscale;
        if f64::from(w) * cfg.crop.kept_w() * up >= f64::from(tw)
            && f64::from(h) * cfg.crop.kept_h() * up >= f64::from(th)
        {
            return d;
        }
    }
    1
}

/// Decode a JPEG whose header must say `width`x`height`, at the scale `choose_jpeg_scale` picks.
/// Returns the decoded image and the scale denominator.
pub fn decode_jpeg_scaled(
    buf: &[u8],
    width: u32,
    height: u32,
    cfg: &DecodeConfig,
) -> Result<(Rgb, u32), DecodeError> {
    let d = choose_jpeg_scale(width, height, cfg);
    if d == 8 {
        // Fast path: DC coefficients only (crate::dcjpeg); other JPEG kinds fall back below.
        match crate::dcjpeg::decode_dc(buf, MAX_SIDE) {
            Ok(img) if (img.full_width, img.full_height) == (width, height) => {
                let rgb = Rgb {
                    width: img.width,
                    height: img.height,
                    data: img.rgb,
                };
                return Ok((rgb, 8));
            }
            Ok(img) => {
                return Err(DecodeError::WrongJpegSize {
                    got_w: img.full_width,
                    got_h: img.full_height,
                    want_w: width,
                    want_h: height,
                });
            }
            Err(crate::dcjpeg::DcError::Corrupt(m)) => return Err(DecodeError::Jpeg(m)),
            Err(crate::dcjpeg::DcError::Unsupported(_)) => {}
        }
    }
    // `jpeg-decoder` fills a scan that ends early (at a marker) with zeros and reports success,
    // and fails on a frame with no EOI marker even when its data is complete. The DC walk reads
    // every MCU of a baseline frame and fails if the data ends before the last one; a complete
    // frame without EOI then gets one. Other JPEG kinds (progressive, 12-bit) must end in EOI.
    let with_eoi;
    let buf = match crate::dcjpeg::decode_dc(buf, MAX_SIDE) {
        Err(crate::dcjpeg::DcError::Corrupt(m)) => return Err(DecodeError::Jpeg(m)),
        Ok(_) if !buf.ends_with(&[0xFF, 0xD9]) && !crate::dcjpeg::has_eoi(buf) => {
            with_eoi = [buf, &[0xFF, 0xD9][..]].concat();
            &with_eoi[..]
        }
        _ => buf,
    };
    let jerr = |e: jpeg_decoder::Error| DecodeError::Jpeg(e.to_string());
    let mut dec = jpeg_decoder::Decoder::new(buf);
    // Output at full size, 3 bytes per pixel, is the most we ever allow.
    dec.set_max_decoding_buffer_size(MAX_SIDE as usize * MAX_SIDE as usize * 3);
    dec.read_info().map_err(jerr)?;
    let info = dec
        .info()
        .ok_or_else(|| DecodeError::Jpeg("no frame header".into()))?;
    if (u32::from(info.width), u32::from(info.height)) != (width, height) {
        return Err(DecodeError::WrongJpegSize {
            got_w: info.width.into(),
            got_h: info.height.into(),
            want_w: width,
            want_h: height,
        });
    }
    let (w, h) = if d > 1 {
        let rw = u16::try_from(width.div_ceil(d)).unwrap_or(u16::MAX);
        let rh = u16::try_from(height.div_ceil(d)).unwrap_or(u16::MAX);
        dec.scale(rw, rh).map_err(jerr)?
    } else {
        (info.width, info.height)
    };
    let pixels = dec.decode().map_err(jerr)?;
    let (w, h) = (u32::from(w), u32::from(h));
    let n = w as usize * h as usize;
    let data = match info.pixel_format {
        jpeg_decoder::PixelFormat::RGB24 if pixels.len() == n * 3 => pixels,
        jpeg_decoder::PixelFormat::L8 if pixels.len() == n => {
            pixels.iter().flat_map(|&g| [g, g, g]).collect()
        }
        f => {
            return Err(DecodeError::Jpeg(format!(
                "unsupported pixel format {f:?} or truncated output ({} bytes for {w}x{h})",
                pixels.len()
            )));
        }
    };
    Ok((
        Rgb {
            width: w,
            height: h,
            data,
        },
        d,
    ))
}

/// A borrowed RGB8 image (row-major, no padding).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RgbView<'a> {
    pub width: u32,
    pub height: u32,
    pub data: &'a [u8],
}

/// Crop by fractions and resize to `tw`x`th` (bilinear at pixel centres; the source is at most
/// about twice the target per axis here, where bilinear is a 2x2 box filter).
pub fn crop_resize(src: &Rgb, crop: &Crop, tw: u32, th: u32) -> Result<Rgb, DecodeError> {
    let view = RgbView {
        width: src.width,
        height: src.height,
        data: &src.data,
    };
    crop_resize_view(view, crop, tw, th)
}

/// [`crop_resize`] of a borrowed image.
pub fn crop_resize_view(
    src: RgbView<'_>,
    crop: &Crop,
    tw: u32,
    th: u32,
) -> Result<Rgb, DecodeError> {
    crop.check()?;
    check_size(tw, th)?;
    let sw = f64::from(src.width);
    let sh = f64::from(src.height);
    let x0 = crop.left * sw;
    let y0 = crop.top * sh;
    let cw = crop.kept_w() * sw;
    let ch = crop.kept_h() * sh;
    if cw < 1.0 || ch < 1.0 || src.data.len() != src.width as usize * src.height as usize * 3 {
        return Err(DecodeError::BadCrop(format!(
            "{}x{} source, crop {crop:?}",
            src.width, src.height
        )));
    }
    if x0 == 0.0 && y0 == 0.0 && src.width == tw && src.height == th {
        return Ok(Rgb {
            width: tw,
            height: th,
            data: src.data.to_vec(),
        });
    }
    let sx = cw / f64::from(tw);
    let sy = ch / f64::from(th);
    let max_x = src.width as usize - 1;
    let max_y = src.height as usize - 1;
    // Horizontal taps once per column, in 8-bit fixed point.
    let cols: Vec<(usize, usize, u32)> = (0..tw)
        .map(|x| {
            let fx = (x0 + (f64::from(x) + 0.5) * sx - 0.5).max(0.0);
            let ix = (fx.floor() as usize).min(max_x);
            let wx = ((fx - ix as f64) * 256.0).round().clamp(0.0, 256.0) as u32;
            (ix * 3, (ix + 1).min(max_x) * 3, wx)
        })
        .collect();
    let stride = src.width as usize * 3;
    let mut out = vec![0u8; tw as usize * th as usize * 3];
    for (y, row) in out.chunks_exact_mut(tw as usize * 3).enumerate() {
        let fy = (y0 + (y as f64 + 0.5) * sy - 0.5).max(0.0);
        let iy = (fy.floor() as usize).min(max_y);
        let wy = ((fy - iy as f64) * 256.0).round().clamp(0.0, 256.0) as u32;
        let r0 = &src.data[iy * stride..(iy + 1) * stride];
        let iy1 = (iy + 1).min(max_y);
        let r1 = &src.data[iy1 * stride..(iy1 + 1) * stride];
        for (d, &(a, b, wx)) in row.chunks_exact_mut(3).zip(&cols) {
            for c in 0..3 {
                let top = u32::from(r0[a + c]) * (256 - wx) + u32::from(r0[b + c]) * wx;
                let bot = u32::from(r1[a + c]) * (256 - wx) + u32::from(r1[b + c]) * wx;
                d[c] = ((top * (256 - wy) + bot * wy + 32_768) >> 16) as u8;
            }
        }
    }
    Ok(Rgb {
        width: tw,
        height: th,
        data: out,
    })
}

/// Rotate clockwise, then mirror.
pub fn orient(src: Rgb, rotation: Rotation, flip_h: bool, flip_v: bool) -> Rgb {
    if rotation == Rotation::None && !flip_h && !flip_v {
        return src;
    }
    let (w, h) = (src.width as usize, src.height as usize);
    let (ow, oh) = if rotation.swaps_axes() {
        (h, w)
    } else {
        (w, h)
    };
    let mut out = vec![0u8; src.data.len()];
    for oy in 0..oh {
        for ox in 0..ow {
            let tx = if flip_h { ow - 1 - ox } else { ox };
            let ty = if flip_v { oh - 1 - oy } else { oy };
            // (tx, ty) in the rotated image -> (x, y) in the source.
            let (x, y) = match rotation {
                Rotation::None => (tx, ty),
                Rotation::Cw90 => (ty, h - 1 - tx),
                Rotation::Cw180 => (w - 1 - tx, h - 1 - ty),
                Rotation::Cw270 => (w - 1 - ty, tx),
            };
            let s = (y * w + x) * 3;
            let d = (oy * ow + ox) * 3;
            out[d..d + 3].copy_from_slice(&src.data[s..s + 3]);
        }
    }
    Rgb {
        width: ow as u32,
        height: oh as u32,
        data: out,
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
    use super::*;

    fn yuyv(width: u32, height: u32, y: u8, u: u8, v: u8) -> Vec<u8> {
        [y, u, y, v].repeat((width * height / 2) as usize)
    }

    #[test]
    fn yuyv_grey_white_black_and_colour() {
        let g = yuyv_to_rgb(&yuyv(320, 240, 126, 128, 128), 320, 240).unwrap();
        assert_eq!((g.width, g.height, g.data.len()), (320, 240, 320 * 240 * 3));
        assert!(g.data.iter().all(|&b| b == 128), "{:?}", &g.data[..6]);
        let w = yuyv_to_rgb(&yuyv(640, 480, 235, 128, 128), 640, 480).unwrap();
        assert!(w.data.iter().all(|&b| b == 255));
        let k = yuyv_to_rgb(&yuyv(2, 1, 16, 128, 128), 2, 1).unwrap();
        assert_eq!(k.data, vec![0; 6]);
        // BT.601 red: Y 81, U 90, V 240.
        let r = yuyv_to_rgb(&yuyv(2, 1, 81, 90, 240), 2, 1).unwrap();
        assert!(
            r.data[0] >= 250 && r.data[1] <= 3 && r.data[2] <= 3,
            "{:?}",
            r.data
        );
    }

    #[test]
    fn yuyv_short_odd_and_oversize_are_errors() {
        let buf = yuyv(320, 240, 100, 128, 128);
        assert!(matches!(
            yuyv_to_rgb(&buf[..buf.len() - 1], 320, 240),
            Err(DecodeError::ShortYuyv { .. })
        ));
        assert!(matches!(
            yuyv_to_rgb(&buf, 3, 2),
            Err(DecodeError::OddYuyvWidth(3))
        ));
        assert!(matches!(
            yuyv_to_rgb(&buf, 0, 2),
            Err(DecodeError::BadSize { .. })
        ));
        assert!(matches!(
            yuyv_to_rgb(&buf, 100_000, 2),
            Err(DecodeError::BadSize { .. })
        ));
        // Padding after the image is ignored.
        let mut padded = buf.clone();
        padded.extend_from_slice(&[0; 64]);
        assert!(yuyv_to_rgb(&padded, 320, 240).is_ok());
    }

    #[test]
    fn uyvy_is_yuyv_with_the_bytes_swapped_per_pair() {
        let yuyv: Vec<u8> = (0..320u32 * 240 / 2)
            .flat_map(|i| {
                [
                    (16 + i % 200) as u8,
                    (90 + i % 50) as u8,
                    (20 + i % 190) as u8,
                    150,
                ]
            })
            .collect();
        let uyvy: Vec<u8> = yuyv
            .chunks_exact(4)
            .flat_map(|q| [q[1], q[0], q[3], q[2]])
            .collect();
        let mut d = FrameDecoder::new(DecodeConfig::plain(320, 240)).unwrap();
        let a = d.decode(PixelFormat::Yuyv, 320, 240, &yuyv).unwrap();
        let b = d.decode(PixelFormat::Uyvy, 320, 240, &uyvy).unwrap();
        assert_eq!(a, b);
        assert_eq!(PixelFormat::from_fourcc(*b"UYVY"), Some(PixelFormat::Uyvy));
        assert_eq!(PixelFormat::Uyvy.fourcc(), *b"UYVY");
    }

    #[test]
    fn vga_yuyv_resizes_to_qvga() {
        let mut d = FrameDecoder::new(DecodeConfig::plain(320, 240)).unwrap();
        let out = d
            .decode(PixelFormat::Yuyv, 640, 480, &yuyv(640, 480, 126, 128, 128))
            .unwrap();
        assert_eq!((out.width, out.height), (320, 240));
        assert!(out.data.iter().all(|&b| b == 128));
        assert_eq!(d.counters, DecodeCounters { ok: 1, errors: 0 });
        assert!(d.decode(PixelFormat::Yuyv, 640, 480, &[1, 2, 3]).is_err());
        assert_eq!(d.counters, DecodeCounters { ok: 1, errors: 1 });
    }

    fn numbered(w: u32, h: u32) -> Rgb {
        let data = (0..w * h).flat_map(|i| [i as u8, 0, 0]).collect();
        Rgb {
            width: w,
            height: h,
            data,
        }
    }

    #[test]
    fn rotations_and_flips_move_pixels_where_expected() {
        // 3x2 image, pixel value = index: 0 1 2 / 3 4 5
        let src = numbered(3, 2);
        let r = |rot, fh, fv| {
            let o = orient(src.clone(), rot, fh, fv);
            (
                o.width,
                o.height,
                o.data.chunks(3).map(|p| p[0]).collect::<Vec<_>>(),
            )
        };
        assert_eq!(
            r(Rotation::None, false, false),
            (3, 2, vec![0, 1, 2, 3, 4, 5])
        );
        assert_eq!(
            r(Rotation::Cw90, false, false),
            (2, 3, vec![3, 0, 4, 1, 5, 2])
        );
        assert_eq!(
            r(Rotation::Cw180, false, false),
            (3, 2, vec![5, 4, 3, 2, 1, 0])
        );
        assert_eq!(
            r(Rotation::Cw270, false, false),
            (2, 3, vec![2, 5, 1, 4, 0, 3])
        );
        assert_eq!(
            r(Rotation::None, true, false),
            (3, 2, vec![2, 1, 0, 5, 4, 3])
        );
        assert_eq!(
            r(Rotation::None, false, true),
            (3, 2, vec![3, 4, 5, 0, 1, 2])
        );
        // The reference DIGIT SDK's transpose + vertical flip = 90 degrees counter-clockwise.
        assert_eq!(r(Rotation::Cw270, false, false).2, {
            // transpose: (x,y)->(y,x), then flip rows
            let t = [0u8, 3, 1, 4, 2, 5];
            vec![t[4], t[5], t[2], t[3], t[0], t[1]]
        });
    }

    #[test]
    fn rotated_output_has_the_configured_size() {
        let mut cfg = DecodeConfig::plain(240, 320);
        cfg.rotation = Rotation::Cw270;
        let mut d = FrameDecoder::new(cfg).unwrap();
        let out = d
            .decode(PixelFormat::Yuyv, 320, 240, &yuyv(320, 240, 100, 128, 128))
            .unwrap();
        assert_eq!((out.width, out.height), (240, 320));
    }

    #[test]
    fn crop_keeps_the_middle() {
        // 4x1 image 0 1 2 3; cut a quarter each side -> 1 2 at 2x1.
        let src = numbered(4, 1);
        let crop = Crop {
            left: 0.25,
            right: 0.25,
            top: 0.0,
            bottom: 0.0,
        };
        let o = crop_resize(&src, &crop, 2, 1).unwrap();
        assert_eq!(o.data.chunks(3).map(|p| p[0]).collect::<Vec<_>>(), [1, 2]);
        assert!(crop_resize(&src, &Crop::uniform(0.5), 2, 1).is_err());
        assert!(crop_resize(&src, &Crop::uniform(f64::NAN), 2, 1).is_err());
    }

    #[test]
    fn jpeg_scale_choice_upsamples_at_most_max_upscale() {
        let g = DecodeConfig::gelsight_mini();
        // 3280x2464 / 8 = 410x308, 5/7 of that is 293x220: 1/8 only because max_upscale 1.1.
        assert_eq!(choose_jpeg_scale(3280, 2464, &g), 8);
        let mut strict = g;
        strict.max_upscale = 1.0;
        // 1/4 then (820x616 -> 586x440 after the crop).
        assert_eq!(choose_jpeg_scale(3280, 2464, &strict), 4);
        assert_eq!(
            choose_jpeg_scale(3280, 2464, &DecodeConfig::plain(320, 240)),
            8
        );
        assert_eq!(
            choose_jpeg_scale(640, 480, &DecodeConfig::plain(320, 240)),
            2
        );
        assert_eq!(
            choose_jpeg_scale(320, 240, &DecodeConfig::plain(320, 240)),
            1
        );
        let mut off = g;
        off.dct_scaling = false;
        assert_eq!(choose_jpeg_scale(3280, 2464, &off), 1);
    }

    #[test]
    fn bad_configs_are_rejected() {
        assert!(FrameDecoder::new(DecodeConfig::plain(0, 240)).is_err());
        let mut c = DecodeConfig::plain(320, 240);
        c.crop = Crop::uniform(-0.1);
        assert!(FrameDecoder::new(c).is_err());
    }

    #[test]
    fn garbage_jpeg_is_an_error_not_a_panic() {
        let mut d = FrameDecoder::new(DecodeConfig::plain(320, 240)).unwrap();
        for buf in [
            &[][..],
            &[0xFF, 0xD8][..],
            &[0u8; 100][..],
            &[0xFF; 1000][..],
        ] {
            assert!(d.decode(PixelFormat::Mjpg, 320, 240, buf).is_err());
        }
        assert_eq!(d.counters.errors, 4);
    }

    #[test]
    fn oversize_buffer_is_rejected_before_decoding() {
        let mut d = FrameDecoder::new(DecodeConfig::plain(320, 240)).unwrap();
        let big = vec![0u8; MAX_RAW_BYTES + 1];
        assert!(matches!(
            d.decode(PixelFormat::Mjpg, 320, 240, &big),
            Err(DecodeError::TooLarge { .. })
        ));
    }
}
