//! Reading image files into frames, with every size bounded before anything is decoded.

use anyhow::Context;
use std::path::Path;
use unitac_core::{Frame, Stamp};
use unitac_driver::still::{self, StillFormat};

/// Largest image file read \[bytes].
const MAX_FILE_BYTES: u64 = 64 << 20;

/// PNG or JPEG (8- or 16-bit, gray, RGB or RGBA) -> RGB8 frame. Errors name the file.
/// The header's dimensions are checked against the image size limit
/// ([`unitac_core::frame::check_image_size`]) and, with `expect`, against the size the frame
/// must have (the background's), before the image is decoded. A cut JPEG (no EOI marker, or data
/// that ends before the last MCU) is an error, as a cut PNG is (`unitac_driver::still`).
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
    let data = std::fs::read(path).with_context(|| format!("{}", path.display()))?;
    let format = StillFormat::sniff(&data)
        .with_context(|| format!("{}: not a PNG or JPEG image", path.display()))?;
    let (w, h) = still::dimensions(&data, format).with_context(|| format!("{}", path.display()))?;
    if let Some((ew, eh)) = expect {
        if (w, h) != (ew, eh) {
            anyhow::bail!(
                "{}: frame is {w}x{h}, the background is {ew}x{eh}",
                path.display()
            );
        }
    }
    let rgb = still::decode(&data, format).with_context(|| format!("{}", path.display()))?;
    Frame::new(sensor_id, seq, Stamp::ZERO, rgb.width, rgb.height, rgb.data)
        .with_context(|| format!("{}", path.display()))
}
