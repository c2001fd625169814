//! sensor_msgs/Image <-> Frame. Sizes are bounded; unsupported encodings are errors.

use r2r::sensor_msgs::msg::Image;
use unitac_core::Frame;
use unitac_core::frame::MAX_SIDE;

use crate::convert;

/// Image (rgb8, bgr8, mono8; any row padding) -> RGB8 frame with the header's stamp.
pub fn to_frame(m: &Image, sensor_id: &str, seq: u64) -> Result<Frame, String> {
    let (w, h) = (m.width, m.height);
    if w == 0 || h == 0 || w > MAX_SIDE || h > MAX_SIDE {
        return Err(format!("image size {w}x{h} is out of bounds"));
    }
    let bpp = match m.encoding.as_str() {
        "rgb8" | "bgr8" => 3,
        "mono8" | "8UC1" => 1,
        other => {
            return Err(format!(
                "unsupported encoding '{other}' (rgb8, bgr8, mono8)"
            ));
        }
    };
    let row = w as usize * bpp;
    let step = m.step as usize;
    if step < row || m.data.len() < step * (h as usize - 1) + row {
        return Err(format!(
            "image data {} bytes too short for {w}x{h} step {step}",
            m.data.len()
        ));
    }
    let mut out = Vec::with_capacity(w as usize * h as usize * 3);
    for y in 0..h as usize {
        let r = &m.data[y * step..y * step + row];
        match m.encoding.as_str() {
            "rgb8" => out.extend_from_slice(r),
            "bgr8" => r
                .chunks_exact(3)
                .for_each(|p| out.extend([p[2], p[1], p[0]])),
            _ => r.iter().for_each(|&v| out.extend([v, v, v])),
        }
    }
    Frame::new(sensor_id, seq, convert::stamp(&m.header.stamp), w, h, out)
        .map_err(|e| e.to_string())
}

/// RGB8 frame -> Image (rgb8), header stamp = capture time, frame_id = `<sensor>_optical_frame`.
pub fn from_frame(f: &Frame) -> Image {
    let mut m = Image::default();
    m.header.stamp = convert::time(f.stamp);
    m.header.frame_id = format!("{}_optical_frame", f.sensor_id);
    m.height = f.height;
    m.width = f.width;
    m.encoding = "rgb8".into();
    m.step = f.width * 3;
    m.data = f.data().to_vec();
    m
}

/// Largest compressed image accepted \[bytes] (a lossless 8192x8192 RGB PNG stays below this).
pub const MAX_COMPRESSED_BYTES: usize = 256 << 20;

/// sensor_msgs/CompressedImage (jpeg, png; image_transport's "compressed") -> RGB8 frame with the
/// header's stamp. Sizes bounded before and during decoding.
pub fn compressed_to_frame(
    m: &r2r::sensor_msgs::msg::CompressedImage,
    sensor_id: &str,
    seq: u64,
) -> Result<Frame, String> {
    if m.data.len() > MAX_COMPRESSED_BYTES {
        return Err(format!(
            "compressed image of {} bytes is over the {MAX_COMPRESSED_BYTES} byte limit",
            m.data.len()
        ));
    }
    let view = unitac_bag::ros::CompressedImageView {
        header: convert::header_from(&m.header),
        format: m.format.clone(),
        data: &m.data,
    };
    unitac_bag::image::compressed_to_frame(&view, sensor_id, seq).map_err(|e| e.to_string())
}
