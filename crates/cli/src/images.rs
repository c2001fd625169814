//! Reading image files into frames, with every size bounded.

use anyhow::Context;
use std::path::Path;
use unitac_core::frame::MAX_SIDE;
use unitac_core::{Frame, Stamp};

/// Largest image file read \[bytes].
const MAX_FILE_BYTES: u64 = 64 << 20;

/// PNG or JPEG (8- or 16-bit, gray, RGB or RGBA) -> RGB8 frame. Errors name the file.
pub fn read_frame(path: &Path, sensor_id: &str, seq: u64) -> anyhow::Result<Frame> {
    let meta = std::fs::metadata(path).with_context(|| format!("{}", path.display()))?;
    if meta.len() == 0 {
        anyhow::bail!("{}: empty file", path.display());
    }
    if meta.len() > MAX_FILE_BYTES {
        anyhow::bail!(
            "{}: {} bytes, more than {MAX_FILE_BYTES}",
            path.display(),
            meta.len()
        );
    }
    let mut reader = image::ImageReader::open(path)
        .with_context(|| format!("{}", path.display()))?
        .with_guessed_format()
        .with_context(|| format!("{}", path.display()))?;
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(MAX_SIDE);
    limits.max_image_height = Some(MAX_SIDE);
    limits.max_alloc = Some(512 << 20);
    reader.limits(limits);
    let img = reader
        .decode()
        .with_context(|| format!("{}: cannot decode", path.display()))?;
    let rgb = img.to_rgb8();
    let (w, h) = rgb.dimensions();
    Frame::new(sensor_id, seq, Stamp::ZERO, w, h, rgb.into_raw())
        .with_context(|| format!("{}", path.display()))
}
