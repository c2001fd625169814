//! Still images (PNG, JPEG) to RGB8: image files given to `unitac contact` and `unitac calibrate`.
//!
//! The header's size is checked against the image size limit
//! ([`unitac_core::frame::check_image_size`]: 8192 pixels a side, 4096 x 4096 in all) before a
//! pixel is decoded, and the decoders allocate within it.
//!
//! A JPEG must be whole: its scan must end with an EOI marker (a file or a message is written
//! whole by its encoder; without EOI it was cut), a baseline JPEG's entropy-coded data must hold
//! every MCU (the DC walk of [`crate::dcjpeg`] reads them all), and it is decoded with zune-jpeg's
//! strict mode, where a scan that ends early, extra bytes between segments or an unexpected
//! marker inside the scan are errors. The lenient decoders (`image`'s JPEG codec, browsers) fill
//! what is missing with grey and report success; a half-grey frame read as a press or as the
//! background is a false contact. Bytes after the EOI are accepted (nothing of the image is
//! missing). The sensor stream is more lenient about EOI only, as some cameras leave it out
//! ([`crate::decode`]). PNG is decoded by `image`'s PNG codec, which already fails on a cut file
//! (a missing IDAT chunk or IEND, a bad CRC).

use crate::decode::Rgb;
use thiserror::Error;
use unitac_core::frame::{ImageTooLarge, MAX_SIDE, check_image_size};
use zune_jpeg::zune_core::bytestream::ZCursor;
use zune_jpeg::zune_core::colorspace::ColorSpace;
use zune_jpeg::zune_core::options::DecoderOptions;

/// Container of a still image.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StillFormat {
    Png,
    Jpeg,
}

impl StillFormat {
    /// The format from the magic bytes.
    pub fn sniff(data: &[u8]) -> Option<Self> {
        if data.starts_with(&[0xff, 0xd8, 0xff]) {
            Some(StillFormat::Jpeg)
        } else if data.starts_with(b"\x89PNG\r\n\x1a\n") {
            Some(StillFormat::Png)
        } else {
            None
        }
    }
}

#[derive(Debug, Error, PartialEq, Eq)]
pub enum StillError {
    #[error("not a PNG or JPEG image")]
    UnknownFormat,
    #[error(transparent)]
    TooLarge(#[from] ImageTooLarge),
    #[error("cannot read the image header: {0}")]
    Header(String),
    #[error("cannot decode: {0}")]
    Decode(String),
}

/// Width and height from the header, within the image size limit.
pub fn dimensions(data: &[u8], format: StillFormat) -> Result<(u32, u32), StillError> {
    let (w, h) = match format {
        StillFormat::Jpeg => {
            let mut d = jpeg_decoder(data);
            d.decode_headers()
                .map_err(|e| StillError::Header(e.to_string()))?;
            let info = d
                .info()
                .ok_or_else(|| StillError::Header("no frame header".into()))?;
            (u32::from(info.width), u32::from(info.height))
        }
        StillFormat::Png => {
            let r = image::ImageReader::with_format(std::io::Cursor::new(data), png());
            r.into_dimensions()
                .map_err(|e| StillError::Header(e.to_string()))?
        }
    };
    check_image_size(w, h)?;
    Ok((w, h))
}

/// Decode to RGB8 (8- or 16-bit, gray, RGB or RGBA PNG; gray, YCbCr or CMYK JPEG).
pub fn decode(data: &[u8], format: StillFormat) -> Result<Rgb, StillError> {
    let (w, h) = dimensions(data, format)?;
    let rgb = match format {
        StillFormat::Jpeg => {
            if !crate::dcjpeg::has_eoi(data) {
                return Err(StillError::Decode(
                    "truncated JPEG: no EOI marker after the scan".into(),
                ));
            }
            if let Err(crate::dcjpeg::DcError::Corrupt(m)) =
                crate::dcjpeg::decode_dc(data, MAX_SIDE)
            {
                return Err(StillError::Decode(format!("JPEG: {m}")));
            }
            let mut d = jpeg_decoder(data);
            let px = d.decode().map_err(|e| StillError::Decode(e.to_string()))?;
            // The header was checked above; the frame size must not change on the way.
            let info = d
                .info()
                .ok_or_else(|| StillError::Header("no frame header".into()))?;
            if (u32::from(info.width), u32::from(info.height)) != (w, h)
                || px.len() != w as usize * h as usize * 3
            {
                return Err(StillError::Decode(format!(
                    "{} bytes decoded for {w}x{h} RGB",
                    px.len()
                )));
            }
            px
        }
        StillFormat::Png => {
            let mut r = image::ImageReader::with_format(std::io::Cursor::new(data), png());
            let mut limits = image::Limits::default();
            limits.max_image_width = Some(w);
            limits.max_image_height = Some(h);
            // The decoded image (up to 16-bit RGBA) plus the RGB8 copy.
            limits.max_alloc = Some(u64::from(w) * u64::from(h) * 11);
            r.limits(limits);
            let img = r.decode().map_err(|e| StillError::Decode(e.to_string()))?;
            img.into_rgb8().into_raw()
        }
    };
    Ok(Rgb {
        width: w,
        height: h,
        data: rgb,
    })
}

fn png() -> image::ImageFormat {
    image::ImageFormat::Png
}

fn jpeg_decoder(data: &[u8]) -> zune_jpeg::JpegDecoder<ZCursor<&[u8]>> {
    let opts = DecoderOptions::default()
        .set_strict_mode(true)
        .set_max_width(MAX_SIDE as usize)
        .set_max_height(MAX_SIDE as usize)
        .jpeg_set_out_colorspace(ColorSpace::RGB);
    zune_jpeg::JpegDecoder::new_with_options(ZCursor::new(data), opts)
}
