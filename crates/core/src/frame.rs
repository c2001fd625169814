//! A tactile frame: RGB8 pixels plus where and when they were captured.

use crate::clock::Stamp;
use crate::sensor::SensorKind;
use thiserror::Error;

/// Largest accepted frame side, in pixels. GelSight Mini's native 3280x2464 fits; anything larger
/// coming from a device, a bag or a file is rejected before allocation.
pub const MAX_SIDE: u32 = 8192;

/// Most pixels of one image decoded from a file or a compressed bag message (4096 x 4096; the
/// largest tactile sensor frame we know, GelSight Mini's full 3280 x 2464, is half of it). Checked
/// with [`check_image_size`] against the header before anything is decoded.
pub const MAX_PIXELS: u64 = 4096 * 4096;

/// An image header whose size is over [`MAX_SIDE`] a side or [`MAX_PIXELS`] in all.
#[derive(Debug, Error, PartialEq, Eq)]
#[error(
    "image is {width}x{height}: the limit is 1..={max_side} pixels a side and {max_pixels} pixels \
     in all",
    max_side = MAX_SIDE,
    max_pixels = MAX_PIXELS
)]
pub struct ImageTooLarge {
    pub width: u32,
    pub height: u32,
}

/// The size limit of a decoded image: 1..=[`MAX_SIDE`] a side and at most [`MAX_PIXELS`].
pub fn check_image_size(width: u32, height: u32) -> Result<(), ImageTooLarge> {
    let side = 1..=MAX_SIDE;
    if side.contains(&width)
        && side.contains(&height)
        && u64::from(width) * u64::from(height) <= MAX_PIXELS
    {
        Ok(())
    } else {
        Err(ImageTooLarge { width, height })
    }
}

#[derive(Debug, Error, PartialEq, Eq)]
pub enum FrameError {
    #[error("frame size {width}x{height} is outside 1..={max} per side", max = MAX_SIDE)]
    BadSize { width: u32, height: u32 },
    #[error("frame {width}x{height} RGB8 needs {expected} bytes, got {got}")]
    BadLength {
        width: u32,
        height: u32,
        expected: usize,
        got: usize,
    },
}

/// One RGB8 image (row-major, 3 bytes per pixel, no padding).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Frame {
    /// Sensor serial or configured name; stays the same across reconnects.
    pub sensor_id: String,
    /// Per-sensor sequence number from the source (gaps mean drops).
    pub seq: u64,
    /// Capture time (device buffer time mapped to ROS time), never read time.
    pub stamp: Stamp,
    pub width: u32,
    pub height: u32,
    data: Vec<u8>,
}

impl Frame {
    pub fn new(
        sensor_id: impl Into<String>,
        seq: u64,
        stamp: Stamp,
        width: u32,
        height: u32,
        data: Vec<u8>,
    ) -> Result<Self, FrameError> {
        let expected = Self::byte_len(width, height)?;
        if data.len() != expected {
            return Err(FrameError::BadLength {
                width,
                height,
                expected,
                got: data.len(),
            });
        }
        Ok(Self {
            sensor_id: sensor_id.into(),
            seq,
            stamp,
            width,
            height,
            data,
        })
    }

    /// Bytes an RGB8 frame of this size needs, after checking the size bounds.
    pub fn byte_len(width: u32, height: u32) -> Result<usize, FrameError> {
        if width == 0 || height == 0 || width > MAX_SIDE || height > MAX_SIDE {
            return Err(FrameError::BadSize { width, height });
        }
        Ok(width as usize * height as usize * 3)
    }

    /// A black frame at the output size of a built-in sensor kind, seq 0, stamp 0. Those sizes
    /// are constants within the bounds (see the test), so this cannot fail.
    pub fn black_of(kind: SensorKind, sensor_id: impl Into<String>) -> Self {
        let spec = kind.spec();
        Self {
            sensor_id: sensor_id.into(),
            seq: 0,
            stamp: Stamp::ZERO,
            width: spec.width,
            height: spec.height,
            data: vec![0; spec.width as usize * spec.height as usize * 3],
        }
    }

    pub fn data(&self) -> &[u8] {
        &self.data
    }
    /// The pixels, to write in place (the length, and so the size, cannot change).
    pub fn data_mut(&mut self) -> &mut [u8] {
        &mut self.data
    }
    /// RGB of pixel (x, y), or None outside the image.
    pub fn pixel(&self, x: u32, y: u32) -> Option<[u8; 3]> {
        if x >= self.width || y >= self.height {
            return None;
        }
        let i = (y as usize * self.width as usize + x as usize) * 3;
        let p = self.data.get(i..i + 3)?;
        Some([p[0], p[1], p[2]])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rejects_wrong_length_and_size() {
        assert!(matches!(
            Frame::new("s", 0, Stamp::ZERO, 2, 2, vec![0; 11]),
            Err(FrameError::BadLength {
                expected: 12,
                got: 11,
                ..
            })
        ));
        assert!(matches!(
            Frame::new("s", 0, Stamp::ZERO, 0, 2, vec![]),
            Err(FrameError::BadSize { .. })
        ));
        assert!(matches!(
            Frame::byte_len(MAX_SIDE + 1, 1),
            Err(FrameError::BadSize { .. })
        ));
    }

    #[test]
    fn built_in_sizes_are_within_bounds() {
        for kind in SensorKind::SHIPPED {
            let f = Frame::black_of(kind, "s");
            let spec = kind.spec();
            let rebuilt = Frame::new(
                "s",
                0,
                Stamp::ZERO,
                spec.width,
                spec.height,
                f.data().to_vec(),
            );
            assert_eq!(rebuilt, Ok(f), "{kind}");
        }
    }

    #[test]
    fn image_size_limit_is_per_side_and_in_all() {
        assert_eq!(check_image_size(4096, 4096), Ok(()));
        assert_eq!(check_image_size(8192, 2048), Ok(()));
        assert_eq!(check_image_size(4097, 10), Ok(()));
        for (w, h) in [
            (0, 1),
            (8193, 1),
            (16_777_216, 1),
            (8192, 2049),
            (4097, 4097),
        ] {
            assert_eq!(
                check_image_size(w, h),
                Err(ImageTooLarge {
                    width: w,
                    height: h
                })
            );
        }
        assert_eq!(
            ImageTooLarge {
                width: 16_777_216,
                height: 1
            }
            .to_string(),
            "image is 16777216x1: the limit is 1..=8192 pixels a side and 16777216 pixels in all"
        );
    }

    #[test]
    fn pixel_access() {
        let f = Frame::new("s", 0, Stamp::ZERO, 2, 1, vec![1, 2, 3, 4, 5, 6]).unwrap();
        assert_eq!(f.pixel(1, 0), Some([4, 5, 6]));
        assert_eq!(f.pixel(2, 0), None);
    }
}

/// Suffix of a sensor's optical frame (REP 103): `<sensor_id>_optical_frame`.
pub const OPTICAL_FRAME_SUFFIX: &str = "_optical_frame";

/// The frame_id of everything a sensor produces: `<sensor_id>_optical_frame`.
pub fn optical_frame_id(sensor_id: &str) -> String {
    format!("{sensor_id}{OPTICAL_FRAME_SUFFIX}")
}

/// The sensor id of a message: `configured` when set (non-empty), else its frame_id without
/// `_optical_frame`, else `fallback` (an empty frame_id).
pub fn sensor_id_of(configured: Option<&str>, frame_id: &str, fallback: &str) -> String {
    if let Some(c) = configured.filter(|c| !c.is_empty()) {
        return c.to_string();
    }
    let id = frame_id
        .strip_suffix(OPTICAL_FRAME_SUFFIX)
        .unwrap_or(frame_id);
    if id.is_empty() { fallback } else { id }.to_string()
}

#[cfg(test)]
mod frame_id_tests {
    use super::*;

    #[test]
    fn optical_frame_ids_round_trip() {
        assert_eq!(optical_frame_id("gsmini"), "gsmini_optical_frame");
        assert_eq!(sensor_id_of(None, "gsmini_optical_frame", "x"), "gsmini");
        assert_eq!(sensor_id_of(Some(""), "cam", "x"), "cam");
        assert_eq!(sensor_id_of(Some("d1"), "gsmini_optical_frame", "x"), "d1");
        assert_eq!(sensor_id_of(None, "", "bag"), "bag");
        assert_eq!(sensor_id_of(None, "_optical_frame", "bag"), "bag");
    }
}
