//! sensor_msgs/Image and CompressedImage <-> Frame for the nodes: a field copy into the borrowed
//! views of `unitac_bag::ros`, then the one conversion `unitac replay` uses too
//! (`unitac_bag::image`: rgb8, bgr8, rgba8, bgra8, mono8, yuv422 variants; jpeg, png), so a
//! node accepts exactly what a bag replay accepts, with the same bounds and errors. The contact
//! stage's depth goes out as `depth` (Image 32FC1) and `points` (PointCloud2) through the bag
//! crate's conversions too ([`depth`], [`points`]), so a node publishes the bytes an output bag
//! holds.

use r2r::sensor_msgs::msg::{CompressedImage, Image, PointCloud2, PointField};
use unitac_bag::ImageError;
use unitac_bag::ros::{CompressedImageView, ImageView};
use unitac_core::Frame;
use unitac_core::msg::DepthMap;

use crate::convert;

/// History depth of an image topic when every frame must arrive (`image_qos:=reliable` on the
/// contact node, `image_depth` on the sensor node): about 2.5 s of frames at 25 fps.
pub const RELIABLE_IMAGE_DEPTH: usize = 64;

/// The contact node's image subscription QoS by its `image_qos` parameter:
/// - `sensor_data` (the default, ROS's sensor-data profile: best effort, keep last 5): on a robot
///   the newest frame matters and a late one is worth nothing; a frame lost on the way shows up
///   in the `dropped` diagnostic (stamp gaps);
/// - `reliable` (reliable, keep last [`RELIABLE_IMAGE_DEPTH`]): every frame arrives unless the
///   node falls that far behind: for replays whose outputs are compared frame by frame (the
///   golden test). The publisher must be reliable too (the sensor node's is).
pub fn image_qos(name: &str) -> Result<r2r::QosProfile, QosNameError> {
    match name {
        "sensor_data" => Ok(r2r::QosProfile::sensor_data()),
        "reliable" => Ok(r2r::QosProfile::default().keep_last(RELIABLE_IMAGE_DEPTH)),
        other => Err(QosNameError(other.chars().take(64).collect())),
    }
}

/// An `image_qos` value that names no profile.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("image_qos must be sensor_data or reliable, got '{0}'")]
pub struct QosNameError(pub String);

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
    image_of(unitac_bag::Image::rgb8(f))
}

/// A bag-crate Image as r2r's.
fn image_of(m: unitac_bag::Image) -> Image {
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

/// The `depth` Image of a depth map (32FC1, metres, NaN where unknown: REP 117), as
/// `unitac_bag::Image::depth32fc1` makes it.
pub fn depth(d: &DepthMap) -> Image {
    image_of(unitac_bag::Image::depth32fc1(d))
}

/// The `points` PointCloud2 of a depth map (x y z float32 in the optical frame, one per known
/// pixel), as `unitac_bag::PointCloud2::xyz` makes it.
pub fn points(d: &DepthMap) -> PointCloud2 {
    let m = unitac_bag::PointCloud2::xyz(d);
    PointCloud2 {
        header: convert::header(&m.header),
        height: m.height,
        width: m.width,
        fields: m
            .fields
            .into_iter()
            .map(|f| PointField {
                name: f.name,
                offset: f.offset,
                datatype: f.datatype,
                count: f.count,
            })
            .collect(),
        is_bigendian: m.is_bigendian,
        point_step: m.point_step,
        row_step: m.row_step,
        data: m.data,
        is_dense: m.is_dense,
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
    fn image_qos_names_its_profiles_and_rejects_others() {
        use r2r::qos::{HistoryPolicy, ReliabilityPolicy};
        let s = image_qos("sensor_data").unwrap();
        assert_eq!(s.reliability, ReliabilityPolicy::BestEffort);
        let r = image_qos("reliable").unwrap();
        assert_eq!(r.reliability, ReliabilityPolicy::Reliable);
        assert_eq!(
            (r.history, r.depth),
            (HistoryPolicy::KeepLast, RELIABLE_IMAGE_DEPTH)
        );
        let e = image_qos("best").unwrap_err().to_string();
        assert!(
            e.contains("sensor_data or reliable") && e.contains("'best'"),
            "{e}"
        );
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
    fn depth_and_points_are_the_bag_crates_messages_field_by_field() {
        let d = DepthMap {
            header: unitac_core::msg::Header::optical(Stamp(9), "gs"),
            width: 2,
            height: 1,
            pixel_m: 1e-4,
            depth_m: vec![f32::NAN, 0.001],
        };
        let (i, b) = (depth(&d), unitac_bag::Image::depth32fc1(&d));
        assert_eq!(
            (i.encoding.as_str(), i.step, &i.data),
            ("32FC1", 8, &b.data)
        );
        assert_eq!(i.header.frame_id, "gs_optical_frame");
        let (p, q) = (points(&d), unitac_bag::PointCloud2::xyz(&d));
        assert_eq!(
            (p.width, p.point_step, &p.data, p.is_dense),
            (1, 12, &q.data, true)
        );
        assert_eq!(p.fields.len(), 3);
        assert_eq!((p.fields[2].name.as_str(), p.fields[2].offset), ("z", 8));
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
