//! sensor_msgs/Image and CompressedImage to a core [`Frame`] (RGB8, no row padding).
//!
//! Raw encodings: rgb8, bgr8, rgba8, bgra8, mono8, and 4:2:2 YUV. ROS's `yuv422` is UYVY byte
//! order (sensor_msgs/image_encodings.hpp), `yuv422_yuy2` / `yuyv` is YUYV, the order V4L2
//! tactile sensors deliver; both are converted with BT.601 limited-range integer arithmetic.
//! Rows may be padded (`step` > width x bytes per pixel); `data` must hold exactly
//! `step x height` bytes. Compressed: JPEG and PNG (format string or, if it names neither, the
//! magic bytes), decoded with size and allocation limits: the header's size is checked
//! against the image size limit ([`unitac_core::frame::check_image_size`]: 8192 pixels a side,
//! 4096 x 4096 in all) before a pixel is decoded. A JPEG must be whole: its scan ends with an EOI
//! marker and it is decoded with zune-jpeg's strict mode, where data that ends before the last
//! MCU is an error (the lenient decoder behind `image` fills the rest with grey and reports
//! success, which replay would read as a large false contact). Bytes after the EOI are accepted.

use crate::ros::{CompressedImageView, ImageView};
use unitac_core::frame::{MAX_SIDE, check_image_size};
use unitac_core::pixel::{Yuv422, yuv422_to_rgb_into};
use unitac_core::{Frame, FrameError, Stamp};

#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum ImageError {
    #[error(transparent)]
    Pixel(#[from] unitac_core::pixel::PixelError),
    #[error(
        "image encoding '{0}' is not supported (rgb8, bgr8, rgba8, bgra8, mono8, yuv422, yuyv)"
    )]
    Encoding(String),
    #[error("image {width}x{height} {encoding}: step {step} is less than a row ({row} bytes)")]
    Step {
        width: u32,
        height: u32,
        encoding: String,
        step: u32,
        row: usize,
    },
    #[error("image {width}x{height} step {step}: data has {got} bytes, expected {expected}")]
    Length {
        width: u32,
        height: u32,
        step: u32,
        expected: usize,
        got: usize,
    },
    #[error("yuv 4:2:2 image with odd width {0}")]
    OddWidth(u32),
    #[error("compressed image format '{0}' is not supported (jpeg, png)")]
    Format(String),
    #[error("compressed image: {0}")]
    Decode(String),
    #[error("compressed image: {0}")]
    TooLarge(#[from] unitac_core::frame::ImageTooLarge),
    #[error(transparent)]
    Frame(#[from] FrameError),
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Enc {
    Rgb8,
    Bgr8,
    Rgba8,
    Bgra8,
    Mono8,
    Yuyv,
    Uyvy,
}

impl Enc {
    fn parse(s: &str) -> Option<Enc> {
        Some(match s.to_ascii_lowercase().as_str() {
            "rgb8" => Enc::Rgb8,
            "bgr8" => Enc::Bgr8,
            "rgba8" => Enc::Rgba8,
            "bgra8" => Enc::Bgra8,
            "mono8" | "8uc1" => Enc::Mono8,
            "yuyv" | "yuv422_yuy2" => Enc::Yuyv,
            "yuv422" | "uyvy" => Enc::Uyvy,
            _ => return None,
        })
    }
    /// Bytes per pixel (2 for 4:2:2).
    fn bpp(self) -> usize {
        match self {
            Enc::Rgb8 | Enc::Bgr8 => 3,
            Enc::Rgba8 | Enc::Bgra8 => 4,
            Enc::Mono8 => 1,
            Enc::Yuyv | Enc::Uyvy => 2,
        }
    }
}

/// Decode a raw image to an RGB8 frame carrying the image's header stamp.
pub fn image_to_frame(img: &ImageView<'_>, sensor_id: &str, seq: u64) -> Result<Frame, ImageError> {
    let enc =
        Enc::parse(&img.encoding).ok_or_else(|| ImageError::Encoding(img.encoding.clone()))?;
    let out_len = Frame::byte_len(img.width, img.height)?;
    let (w, h) = (img.width as usize, img.height as usize);
    let row = w * enc.bpp();
    let step = img.step as usize;
    if step < row {
        return Err(ImageError::Step {
            width: img.width,
            height: img.height,
            encoding: img.encoding.clone(),
            step: img.step,
            row,
        });
    }
    let expected = step.saturating_mul(h);
    if img.data.len() != expected {
        return Err(ImageError::Length {
            width: img.width,
            height: img.height,
            step: img.step,
            expected,
            got: img.data.len(),
        });
    }
    if matches!(enc, Enc::Yuyv | Enc::Uyvy) && w % 2 == 1 {
        return Err(ImageError::OddWidth(img.width));
    }
    // Packed 4:2:2: the one converter the driver uses too.
    let yuv = match enc {
        Enc::Yuyv => Some(Yuv422::Yuyv),
        Enc::Uyvy => Some(Yuv422::Uyvy),
        _ => None,
    };
    if let Some(order) = yuv {
        let mut out = vec![0u8; out_len];
        yuv422_to_rgb_into(order, img.data, img.width, img.height, step, &mut out)?;
        return Ok(Frame::new(
            sensor_id,
            seq,
            img.header.stamp,
            img.width,
            img.height,
            out,
        )?);
    }
    let mut out = Vec::with_capacity(out_len);
    if enc == Enc::Rgb8 && step == row {
        out.extend_from_slice(img.data);
    } else {
        for src in img.data.chunks_exact(step) {
            let src = &src[..row];
            match enc {
                Enc::Rgb8 => out.extend_from_slice(src),
                Enc::Bgr8 => {
                    for p in src.chunks_exact(3) {
                        out.extend_from_slice(&[p[2], p[1], p[0]]);
                    }
                }
                Enc::Rgba8 => {
                    for p in src.chunks_exact(4) {
                        out.extend_from_slice(&p[..3]);
                    }
                }
                Enc::Bgra8 => {
                    for p in src.chunks_exact(4) {
                        out.extend_from_slice(&[p[2], p[1], p[0]]);
                    }
                }
                Enc::Mono8 => {
                    for &g in src {
                        out.extend_from_slice(&[g, g, g]);
                    }
                }
                // Converted above.
                Enc::Yuyv | Enc::Uyvy => {}
            }
        }
    }
    Ok(Frame::new(
        sensor_id,
        seq,
        img.header.stamp,
        img.width,
        img.height,
        out,
    )?)
}

/// Decode a JPEG or PNG compressed image to an RGB8 frame carrying the header stamp.
pub fn compressed_to_frame(
    img: &CompressedImageView<'_>,
    sensor_id: &str,
    seq: u64,
) -> Result<Frame, ImageError> {
    let f = img.format.to_ascii_lowercase();
    let format = if f.contains("jpeg") || f.contains("jpg") {
        image::ImageFormat::Jpeg
    } else if f.contains("png") {
        image::ImageFormat::Png
    } else if img.data.starts_with(&[0xff, 0xd8, 0xff]) && f.is_empty() {
        image::ImageFormat::Jpeg
    } else if img.data.starts_with(b"\x89PNG") && f.is_empty() {
        image::ImageFormat::Png
    } else {
        return Err(ImageError::Format(img.format.clone()));
    };
    decode_bytes(img.data, format, sensor_id, seq, img.header.stamp)
}

fn decode_bytes(
    data: &[u8],
    format: image::ImageFormat,
    sensor_id: &str,
    seq: u64,
    stamp: Stamp,
) -> Result<Frame, ImageError> {
    let derr = |e: &dyn std::fmt::Display| ImageError::Decode(e.to_string());
    if format == image::ImageFormat::Jpeg {
        let (w, h, rgb) = decode_jpeg_strict(data)?;
        return Ok(Frame::new(sensor_id, seq, stamp, w, h, rgb)?);
    }
    let (w, h) = image::ImageReader::with_format(std::io::Cursor::new(data), format)
        .into_dimensions()
        .map_err(|e| derr(&e))?;
    check_image_size(w, h)?;
    let mut reader = image::ImageReader::with_format(std::io::Cursor::new(data), format);
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(w);
    limits.max_image_height = Some(h);
    // The decoded image (up to 16-bit RGBA) plus the RGB8 copy.
    limits.max_alloc = Some(u64::from(w) * u64::from(h) * 11);
    reader.limits(limits);
    let img = reader.decode().map_err(|e| derr(&e))?;
    let rgb = img.into_rgb8();
    let (w, h) = rgb.dimensions();
    Ok(Frame::new(sensor_id, seq, stamp, w, h, rgb.into_raw())?)
}

/// A whole JPEG to RGB8: EOI after the scan, size within the limit, strict decode.
fn decode_jpeg_strict(data: &[u8]) -> Result<(u32, u32, Vec<u8>), ImageError> {
    use zune_jpeg::zune_core::{bytestream::ZCursor, colorspace::ColorSpace};
    let derr = |e: &dyn std::fmt::Display| ImageError::Decode(e.to_string());
    if !jpeg_has_eoi(data) {
        return Err(ImageError::Decode(
            "truncated JPEG: no EOI marker after the scan".into(),
        ));
    }
    let opts = zune_jpeg::zune_core::options::DecoderOptions::default()
        .set_strict_mode(true)
        .set_max_width(MAX_SIDE as usize)
        .set_max_height(MAX_SIDE as usize)
        .jpeg_set_out_colorspace(ColorSpace::RGB);
    let mut d = zune_jpeg::JpegDecoder::new_with_options(ZCursor::new(data), opts);
    d.decode_headers().map_err(|e| derr(&e))?;
    let info = d
        .info()
        .ok_or_else(|| ImageError::Decode("JPEG: no frame header".into()))?;
    let (w, h) = (u32::from(info.width), u32::from(info.height));
    check_image_size(w, h)?;
    let px = d.decode().map_err(|e| derr(&e))?;
    if px.len() != w as usize * h as usize * 3 {
        return Err(ImageError::Decode(format!(
            "JPEG: {} bytes decoded for {w}x{h} RGB",
            px.len()
        )));
    }
    Ok((w, h, px))
}

/// True if an EOI marker follows the first scan's start (segments are walked by their lengths
/// up to SOS, so an EOI inside an EXIF thumbnail does not count; entropy-coded data holds no
/// 0xFF 0xD9).
fn jpeg_has_eoi(data: &[u8]) -> bool {
    if data.get(..2) != Some(&[0xFF, 0xD8][..]) {
        return false;
    }
    let mut pos = 2;
    loop {
        while data.get(pos) == Some(&0xFF) && data.get(pos + 1) == Some(&0xFF) {
            pos += 1;
        }
        let (Some(&0xFF), Some(&m), Some(&a), Some(&b)) = (
            data.get(pos),
            data.get(pos + 1),
            data.get(pos + 2),
            data.get(pos + 3),
        ) else {
            return false;
        };
        let len = usize::from(a) << 8 | usize::from(b);
        if m == 0xD9 || len < 2 {
            return false;
        }
        pos += 2 + len;
        if m == 0xDA {
            return data
                .get(pos..)
                .is_some_and(|d| d.windows(2).any(|w| w == [0xFF, 0xD9]));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ros::{CompressedImage, Image};
    use unitac_core::msg::Header;

    fn raw(w: u32, h: u32, enc: &str, step: u32, data: Vec<u8>) -> Image {
        Image {
            header: Header::new(Stamp(42), "x"),
            height: h,
            width: w,
            encoding: enc.into(),
            is_bigendian: 0,
            step,
            data,
        }
    }

    #[test]
    fn encodings_to_rgb() {
        let rgb =
            image_to_frame(&raw(2, 1, "rgb8", 6, vec![1, 2, 3, 4, 5, 6]).view(), "s", 0).unwrap();
        assert_eq!(rgb.data(), &[1, 2, 3, 4, 5, 6]);
        assert_eq!(rgb.stamp, Stamp(42));
        let bgr =
            image_to_frame(&raw(2, 1, "bgr8", 6, vec![1, 2, 3, 4, 5, 6]).view(), "s", 0).unwrap();
        assert_eq!(bgr.data(), &[3, 2, 1, 6, 5, 4]);
        let mono = image_to_frame(&raw(2, 1, "mono8", 2, vec![7, 9]).view(), "s", 0).unwrap();
        assert_eq!(mono.data(), &[7, 7, 7, 9, 9, 9]);
        // Padded rows: step 8 for a 2-px rgb8 row of 6 bytes.
        let pad = image_to_frame(
            &raw(
                2,
                2,
                "rgb8",
                8,
                vec![1, 2, 3, 4, 5, 6, 0, 0, 7, 8, 9, 10, 11, 12, 0, 0],
            )
            .view(),
            "s",
            0,
        )
        .unwrap();
        assert_eq!(pad.data(), &[1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12]);
    }

    #[test]
    fn yuyv_grey_and_colours() {
        // Y=126 U=V=128 is mid grey in limited range: (126-16)*298/256 = 128.
        let f = image_to_frame(
            &raw(2, 1, "yuyv", 4, vec![126, 128, 126, 128]).view(),
            "s",
            0,
        )
        .unwrap();
        assert_eq!(f.data(), &[128, 128, 128, 128, 128, 128]);
        // Pure red in BT.601 limited range: Y=81 U=90 V=240.
        let f =
            image_to_frame(&raw(2, 1, "yuyv", 4, vec![81, 90, 81, 240]).view(), "s", 0).unwrap();
        let p = f.pixel(0, 0).unwrap();
        assert!(p[0] >= 250 && p[1] <= 5 && p[2] <= 5, "{p:?}");
        // UYVY has the same pixels in another byte order.
        let g = image_to_frame(
            &raw(2, 1, "yuv422", 4, vec![90, 81, 240, 81]).view(),
            "s",
            0,
        )
        .unwrap();
        assert_eq!(f.data(), g.data());
    }

    #[test]
    fn wrong_sizes_are_errors() {
        assert!(matches!(
            image_to_frame(&raw(2, 1, "rgb8", 6, vec![0; 5]).view(), "s", 0),
            Err(ImageError::Length { .. })
        ));
        assert!(matches!(
            image_to_frame(&raw(2, 1, "rgb8", 5, vec![0; 5]).view(), "s", 0),
            Err(ImageError::Step { .. })
        ));
        assert!(matches!(
            image_to_frame(&raw(3, 1, "yuyv", 6, vec![0; 6]).view(), "s", 0),
            Err(ImageError::OddWidth(3))
        ));
        assert!(matches!(
            image_to_frame(&raw(9000, 1, "mono8", 9000, vec![0; 9000]).view(), "s", 0),
            Err(ImageError::Frame(_))
        ));
        assert!(matches!(
            image_to_frame(&raw(1, 1, "16UC1", 2, vec![0; 2]).view(), "s", 0),
            Err(ImageError::Encoding(_))
        ));
        // A huge step times height cannot overflow or allocate.
        assert!(matches!(
            image_to_frame(&raw(8, 8192, "rgb8", u32::MAX, vec![0; 10]).view(), "s", 0),
            Err(ImageError::Length { .. })
        ));
    }

    /// A cut JPEG message (no EOI, data ending before the last MCU) is a decode error, not a
    /// frame half filled with grey; bytes after the EOI are accepted.
    #[test]
    fn cut_jpeg_is_a_decode_error() {
        let (w, h) = (64u32, 48u32);
        let rgb: Vec<u8> = (0..w * h * 3).map(|i| (i * 7 % 251) as u8).collect();
        let img = image::RgbImage::from_raw(w, h, rgb).unwrap();
        let mut jpg = Vec::new();
        image::codecs::jpeg::JpegEncoder::new_with_quality(&mut jpg, 90)
            .encode_image(&img)
            .unwrap();
        let msg = |data: Vec<u8>| CompressedImage {
            header: Header::new(Stamp(1), "x"),
            format: "jpeg".into(),
            data,
        };
        let good = compressed_to_frame(&msg(jpg.clone()).view(), "s", 0).unwrap();
        assert_eq!((good.width, good.height), (w, h));
        for cut in [
            jpg.len() / 2,
            jpg.len() * 9 / 10,
            jpg.len() - 3,
            jpg.len() - 2,
        ] {
            let r = compressed_to_frame(&msg(jpg[..cut].to_vec()).view(), "s", 0);
            assert!(
                matches!(r, Err(ImageError::Decode(_))),
                "cut at {cut} of {}: {r:?}",
                jpg.len()
            );
        }
        let mut trailing = jpg.clone();
        trailing.extend_from_slice(b"xyz");
        assert_eq!(
            compressed_to_frame(&msg(trailing).view(), "s", 0).unwrap(),
            good
        );
    }

    #[test]
    fn compressed_png_and_garbage() {
        let mut png = Vec::new();
        let img = image::RgbImage::from_raw(2, 1, vec![10, 20, 30, 40, 50, 60]).unwrap();
        img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
            .unwrap();
        let c = CompressedImage {
            header: Header::new(Stamp(7), "x"),
            format: "png".into(),
            data: png,
        };
        let f = compressed_to_frame(&c.view(), "s", 3).unwrap();
        assert_eq!(f.data(), &[10, 20, 30, 40, 50, 60]);
        assert_eq!((f.stamp, f.seq), (Stamp(7), 3));
        let bad = CompressedImage {
            format: "jpeg".into(),
            data: vec![0xff, 0xd8, 0xff, 0, 1, 2],
            ..c.clone()
        };
        assert!(matches!(
            compressed_to_frame(&bad.view(), "s", 0),
            Err(ImageError::Decode(_))
        ));
        let tiff = CompressedImage {
            format: "tiff".into(),
            ..c
        };
        assert!(matches!(
            compressed_to_frame(&tiff.view(), "s", 0),
            Err(ImageError::Format(_))
        ));
    }
}
