//! GelSight Mini and DIGIT drivers over V4L2/USB.
//!
//! - [`decode`]: YUYV / MJPEG buffers to published RGB8 frames (DCT-domain downscale for the
//!   3280x2464 GelSight Mini stream), crop, resize, rotation.
//! - [`still`]: PNG / JPEG images (files) to RGB8, size-checked before decoding; a truncated
//!   JPEG is an error.
//! - [`fuzzing`]: the entry functions of the fuzz targets (crates/driver/fuzz) and their CI smoke.
//! - [`calib`]: per-serial calibration files (ROI, rotation, mm per pixel, camera settings).
//! - [`discover`]: USB devices and their V4L2 capture nodes from sysfs, sensor matching.
//! - [`capture`]: the device trait and the pure capture logic (mode choice, timestamp mapping,
//!   drop counting, stale-buffer flush).
//! - [`controls`]: DIGIT LEDs, GelSight Mini exposure / white balance / gain, verified.
//! - [`stream`]: the `Source` for the runtime, with reconnect by serial.
//! - [`usb`]: libusb (rusb): USB reset of a stalled sensor (the software replug), hotplug events.
//! - [`v4l_backend`]: the real V4L2 device and backend (with `usb`, the only hardware modules).
//!
//! No ROS, no ONNX Runtime here.

pub mod calib;
pub mod capture;
pub mod controls;
pub mod dcjpeg;
pub mod decode;
pub mod discover;
pub mod fuzzing;
pub mod still;
pub mod stream;
pub mod usb;
pub mod v4l_backend;

pub use calib::Calibration;
pub use capture::{CaptureDevice, DeviceError, Mode};
pub use stream::{Backend, SensorStream, StreamConfig, StreamError, SystemDriverClock};
pub use v4l_backend::V4lBackend;

use std::path::Path;
use unitac_core::{SensorKind, SourceError};

/// A live sensor by serial: discovers it under `root` ("/" on a robot), loads its calibration
/// from `calibration_dir` (`<serial>.yaml`, vendor defaults if absent), opens it.
pub fn open_v4l(
    root: &Path,
    serial: &str,
    calibration_dir: Option<&Path>,
) -> Result<SensorStream<V4lBackend, SystemDriverClock>, SourceError> {
    let found = discover::find_by_serial(root, serial)
        .map_err(SourceError::unavailable)?
        .0;
    let kind: SensorKind = found.kind;
    let calibration = match calibration_dir {
        Some(dir) => Calibration::load_for(dir, kind, serial).map_err(SourceError::fatal)?,
        None => Calibration::default_for(kind, serial),
    };
    SensorStream::open(
        StreamConfig::new(serial, calibration),
        V4lBackend::new(root),
        SystemDriverClock,
    )
}
