//! Reading image files into frames, with every size bounded before anything is decoded.

use anyhow::Context;
use std::path::Path;
use unitac_core::frame::MAX_SIDE;
use unitac_core::{Frame, Stamp};

/// Largest image file read \[bytes].
const MAX_FILE_BYTES: u64 = 64 << 20;
/// Most pixels decoded from one file (a 4096 x 4096 image; the largest tactile sensor frame we
/// know, GelSight Mini's full 3280 x 2464, is half of it). A PNG of zeros claiming 8192 x 8192 is
/// 212 KB: its header is checked against this before a byte is decoded.
pub const MAX_PIXELS: u64 = 4096 * 4096;

fn reader(path: &Path) -> anyhow::Result<image::ImageReader<std::io::BufReader<std::fs::File>>> {
    image::ImageReader::open(path)
        .with_context(|| format!("{}", path.display()))?
        .with_guessed_format()
        .with_context(|| format!("{}", path.display()))
}

/// PNG or JPEG (8- or 16-bit, gray, RGB or RGBA) -> RGB8 frame. Errors name the file.
/// The header's dimensions are checked against [`MAX_PIXELS`] and, with `expect`, against the
/// size the frame must have (the background's), before the image is decoded.
pub fn read_frame(
    path: &Path,
    sensor_id: &str,
    seq: u64,
    expect: Option<(u32, u32)>,
) -> anyhow::Result<Frame> {
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
    let (w, h) = reader(path)?
        .into_dimensions()
        .with_context(|| format!("{}: cannot read the image header", path.display()))?;
    if u64::from(w) * u64::from(h) > MAX_PIXELS || w > MAX_SIDE || h > MAX_SIDE {
        anyhow::bail!(
            "{}: image is {w}x{h}, more than {MAX_PIXELS} pixels",
            path.display()
        );
    }
    if let Some((ew, eh)) = expect {
        if (w, h) != (ew, eh) {
            anyhow::bail!(
                "{}: frame is {w}x{h}, the background is {ew}x{eh}",
                path.display()
            );
        }
    }
    let mut reader = reader(path)?;
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(w);
    limits.max_image_height = Some(h);
    // The decoded image (up to 16-bit RGBA) plus the RGB8 copy.
    limits.max_alloc = Some(u64::from(w) * u64::from(h) * 11);
    reader.limits(limits);
    let img = reader
        .decode()
        .with_context(|| format!("{}: cannot decode", path.display()))?;
    let rgb = img.to_rgb8();
    let (w, h) = rgb.dimensions();
    Frame::new(sensor_id, seq, Stamp::ZERO, w, h, rgb.into_raw())
        .with_context(|| format!("{}", path.display()))
}
