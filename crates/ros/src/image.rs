//! sensor_msgs/Image and CompressedImage <-> Frame for the nodes: a field copy into the borrowed
//! views of `unitac_bag::ros`, then the one conversion `unitac replay` uses too
//! (`unitac_bag::image`: rgb8, bgr8, rgba8, bgra8, mono8, yuv422 variants; jpeg, png), so a
//! node accepts exactly what a bag replay accepts, with the same bounds and errors.

use r2r::sensor_msgs::msg::{CompressedImage, Image};
use unitac_bag::ImageError;
use unitac_bag::ros::{CompressedImageView, ImageView};
use unitac_core::Frame;

use crate::convert;

/// Image (any encoding `unitac_bag::image` knows; any row padding) -> RGB8 frame with the
/// header's stamp.
pub fn to_frame(m: &Image, sensor_id: &str, seq: u64) -> Result<Frame, ImageError> {
    let view = ImageView {
        header: convert::header_from(&m.header),
        height: m.height,
        width: m.width,
        encoding: m.encoding.clone(),
        is_bigendian: m.is_bigendian,
        step: m.step,
        data: &m.data,
    };
    unitac_bag::image::image_to_frame(&view, sensor_id, seq)
}

/// RGB8 frame -> Image (rgb8), header stamp = capture time, frame_id = `<sensor>_optical_frame`.
pub fn from_frame(f: &Frame) -> Image {
    let m = unitac_bag::Image::rgb8(f);
    Image {
        header: convert::header(&m.header),
        height: m.height,
        width: m.width,
        encoding: m.encoding,
        is_bigendian: m.is_bigendian,
        step: m.step,
        data: m.data,
    }
}

/// sensor_msgs/CompressedImage (jpeg, png; image_transport's "compressed") -> RGB8 frame with the
/// header's stamp. Sizes bounded before and during decoding.
pub fn compressed_to_frame(
    m: &CompressedImage,
    sensor_id: &str,
    seq: u64,
) -> Result<Frame, ImageError> {
    let view = CompressedImageView {
        header: convert::header_from(&m.header),
        format: m.format.clone(),
        data: &m.data,
    };
    unitac_bag::image::compressed_to_frame(&view, sensor_id, seq)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use unitac_core::Stamp;

    fn frame() -> Frame {
        let data: Vec<u8> = (0..4 * 3 * 3).map(|i| i as u8).collect();
        Frame::new("gs", 5, Stamp(1_700_000_000_000_000_123), 4, 3, data).unwrap()
    }

    #[test]
    fn an_rgb8_frame_round_trips() {
        let f = frame();
        let m = from_frame(&f);
        assert_eq!(m.header.frame_id, "gs_optical_frame");
        assert_eq!((m.encoding.as_str(), m.step), ("rgb8", 12));
        let back = to_frame(&m, "gs", 5).unwrap();
        assert_eq!(back, f);
    }

    #[test]
    fn every_encoding_a_bag_replay_takes_is_taken_here_too() {
        let f = frame();
        let mut m = from_frame(&f);
        // bgra8 with two bytes of row padding: known to the bag conversion, not to the old node.
        m.encoding = "bgra8".into();
        m.step = 4 * 4 + 2;
        m.data = vec![0; m.step as usize * 3];
        for y in 0..3 {
            for x in 0..4 {
                let (s, d) = ((y * 4 + x) * 3, y * 18 + x * 4);
                let p = &f.data()[s..s + 3];
                m.data[d..d + 4].copy_from_slice(&[p[2], p[1], p[0], 255]);
            }
        }
        assert_eq!(to_frame(&m, "gs", 5).unwrap(), f);
        m.encoding = "32FC1".into();
        let e = to_frame(&m, "gs", 5).unwrap_err().to_string();
        assert!(e.contains("32FC1"), "{e}");
    }
}
