//! The real device: a V4L2 capture node through the `v4l` crate (mmap streaming).
//!
//! Thin on purpose: everything that can be decided without a device lives in `capture`,
//! `stream`, `controls` and `decode` and is tested there. What only hardware can check is in the
//! crate README's hardware checklist.

use crate::capture::{CaptureDevice, DeviceError, Mode, RawBuffer};
use crate::decode::PixelFormat;
use crate::discover::{DiscoverError, find_by_serial};
use crate::stream::{Backend, OpenedDevice};
use crate::usb::Usb;
use std::io;
use std::path::{Path, PathBuf};
use std::time::Duration;
use v4l::buffer::Type as BufType;
use v4l::control::{Control, Value};
use v4l::format::FourCC;
use v4l::frameinterval::FrameIntervalEnum;
use v4l::io::mmap::Stream as MmapStream;
use v4l::io::traits::CaptureStream;
use v4l::video::Capture;

/// Buffers in the driver's queue: enough to ride out a slow consumer for a few frames, few
/// enough that stale frames are at most this many.
pub const BUFFER_COUNT: u32 = 4;
/// Most modes listed per device (formats x sizes x rates).
const MAX_MODES: usize = 256;

fn dev_err(e: io::Error) -> DeviceError {
    // ENODEV / ENXIO / ESHUTDOWN / ENOENT: the device is gone (unplugged, USB reset).
    match e.raw_os_error() {
        Some(19 | 6 | 108 | 2) => DeviceError::Gone(e.to_string()),
        _ if e.kind() == io::ErrorKind::NotFound => DeviceError::Gone(e.to_string()),
        _ => DeviceError::Io(e.to_string()),
    }
}

/// One open V4L2 capture node.
pub struct V4lDevice {
    path: PathBuf,
    dev: v4l::Device,
    stream: Option<MmapStream<'static>>,
}

impl std::fmt::Debug for V4lDevice {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("V4lDevice")
            .field("path", &self.path)
            .field("streaming", &self.stream.is_some())
            .finish()
    }
}

impl V4lDevice {
    /// Open a node and check that it is a video capture node (not the UVC metadata node).
    pub fn open(path: &Path) -> Result<Self, DeviceError> {
        let at = |e: io::Error| match dev_err(e) {
            DeviceError::Gone(m) => DeviceError::Gone(format!("{}: {m}", path.display())),
            DeviceError::Io(m) => DeviceError::Io(format!("{}: {m}", path.display())),
            other => other,
        };
        let dev = v4l::Device::with_path(path).map_err(at)?;
        let caps = dev.query_caps().map_err(at)?;
        if !caps
            .capabilities
            .contains(v4l::capability::Flags::VIDEO_CAPTURE)
        {
            return Err(DeviceError::Unsupported(format!(
                "{} ({}) is not a video capture node",
                path.display(),
                caps.card
            )));
        }
        Ok(Self {
            path: path.to_path_buf(),
            dev,
            stream: None,
        })
    }
}

impl CaptureDevice for V4lDevice {
    fn modes(&mut self) -> Result<Vec<Mode>, DeviceError> {
        let mut out = Vec::new();
        for f in self.dev.enum_formats().map_err(dev_err)? {
            let Some(format) = PixelFormat::from_fourcc(f.fourcc.repr) else {
                continue;
            };
            for size in self.dev.enum_framesizes(f.fourcc).map_err(dev_err)? {
                for d in size.size.to_discrete() {
                    let intervals = self
                        .dev
                        .enum_frameintervals(f.fourcc, d.width, d.height)
                        .map_err(dev_err)?;
                    for i in intervals {
                        let FrameIntervalEnum::Discrete(fr) = i.interval else {
                            continue;
                        };
                        if fr.numerator == 0 {
                            continue;
                        }
                        out.push(Mode {
                            format,
                            width: d.width,
                            height: d.height,
                            fps: f64::from(fr.denominator) / f64::from(fr.numerator),
                        });
                        if out.len() >= MAX_MODES {
                            return Ok(out);
                        }
                    }
                }
            }
        }
        Ok(out)
    }

    fn set_mode(&mut self, mode: &Mode) -> Result<Mode, DeviceError> {
        let mut fmt = self.dev.format().map_err(dev_err)?;
        fmt.width = mode.width;
        fmt.height = mode.height;
        fmt.fourcc = FourCC::new(&mode.format.fourcc());
        let got = self.dev.set_format(&fmt).map_err(dev_err)?;
        let format = PixelFormat::from_fourcc(got.fourcc.repr).ok_or_else(|| {
            DeviceError::Unsupported(format!("device switched to {}", got.fourcc))
        })?;
        let fps = mode.fps.round().clamp(1.0, 1000.0) as u32;
        let params = self
            .dev
            .set_params(&v4l::video::capture::Parameters::with_fps(fps))
            .map_err(dev_err)?;
        let fr = params.interval;
        let fps = if fr.numerator == 0 {
            mode.fps
        } else {
            f64::from(fr.denominator) / f64::from(fr.numerator)
        };
        Ok(Mode {
            format,
            width: got.width,
            height: got.height,
            fps,
        })
    }

    fn start(&mut self) -> Result<(), DeviceError> {
        // The first `next` queues every buffer and turns streaming on.
        let s = MmapStream::with_buffers(&self.dev, BufType::VideoCapture, BUFFER_COUNT)
            .map_err(dev_err)?;
        self.stream = Some(s);
        Ok(())
    }

    fn next_buffer(&mut self, timeout: Duration) -> Result<RawBuffer<'_>, DeviceError> {
        let Some(stream) = self.stream.as_mut() else {
            return Err(DeviceError::Io("not streaming".into()));
        };
        stream.set_timeout(timeout);
        let (data, meta) = match CaptureStream::next(stream) {
            Ok(x) => x,
            Err(e) if e.kind() == io::ErrorKind::TimedOut => {
                return Err(DeviceError::Timeout(timeout));
            }
            Err(e) => return Err(dev_err(e)),
        };
        let used = (meta.bytesused as usize).min(data.len());
        let ts = meta.timestamp;
        let timestamp = Duration::new(
            u64::try_from(ts.sec).unwrap_or(0),
            u32::try_from(ts.usec).unwrap_or(0).saturating_mul(1000),
        );
        Ok(RawBuffer {
            data: &data[..used],
            sequence: meta.sequence,
            timestamp,
        })
    }

    fn queue_len(&self) -> u32 {
        BUFFER_COUNT
    }

    fn set_control(&mut self, id: u32, value: i64) -> Result<(), DeviceError> {
        self.dev
            .set_control(Control {
                id,
                value: Value::Integer(value),
            })
            .map_err(dev_err)
    }

    fn control(&mut self, id: u32) -> Result<i64, DeviceError> {
        match self.dev.control(id).map_err(dev_err)?.value {
            Value::Integer(v) => Ok(v),
            Value::Boolean(b) => Ok(i64::from(b)),
            other => Err(DeviceError::Unsupported(format!(
                "control {id:#x} has a non-integer value {other:?}"
            ))),
        }
    }
}

/// Opens sensors by serial through sysfs discovery under `root` ("/" on a robot); resets them
/// and waits for hotplug events through libusb (`crate::usb`) when `root` is the real "/".
#[derive(Debug)]
pub struct V4lBackend {
    pub root: PathBuf,
    /// `None` under a test sysfs root, or where libusb cannot start (no USB reset, sysfs polling).
    usb: Option<Usb>,
}

impl V4lBackend {
    pub fn new(root: impl Into<PathBuf>) -> Self {
        let root = root.into();
        let usb = if root == Path::new("/") {
            Usb::new()
                .map_err(|e| tracing::warn!("libusb unavailable ({e}): no USB reset on stalls"))
                .ok()
        } else {
            None
        };
        Self { root, usb }
    }
}

fn not_found(e: DiscoverError) -> DeviceError {
    match e {
        // Not on the bus (yet): keep retrying.
        DiscoverError::NotFound(..)
        | DiscoverError::FirmwareUpdateMode(_)
        | DiscoverError::NoCaptureNode(_)
        | DiscoverError::Io { .. } => DeviceError::Gone(e.to_string()),
        DiscoverError::Ambiguous { .. } => DeviceError::Unsupported(e.to_string()),
    }
}

impl Backend for V4lBackend {
    fn open(&mut self, serial: &str) -> Result<OpenedDevice, DeviceError> {
        let (found, node) = find_by_serial(&self.root, serial).map_err(not_found)?;
        let device = V4lDevice::open(&node)?;
        Ok(OpenedDevice {
            device: Box::new(device),
            firmware: found.firmware,
        })
    }

    fn reset_usb(&mut self, serial: &str) -> Result<(), DeviceError> {
        let Some(usb) = &self.usb else {
            return Err(DeviceError::Unsupported("no libusb access".into()));
        };
        let port = match find_by_serial(&self.root, serial) {
            Ok((found, _)) => found.port,
            // Found on the bus but without a capture node (a stalled UVC function can lose it).
            Err(DiscoverError::NoCaptureNode(_)) => crate::discover::discover(&self.root)
                .ok()
                .and_then(|d| d.sensors.into_iter().find(|s| s.serial == serial))
                .map(|s| s.port)
                .ok_or_else(|| DeviceError::Gone(format!("{serial} not on the bus")))?,
            Err(e) => return Err(not_found(e)),
        };
        usb.reset_port(&port)
    }

    fn wait_usb_event(&mut self, max: Duration) -> Option<bool> {
        self.usb.as_mut()?.wait_event(max)
    }
}

/// Modes of a capture node, for `unitac devices` (empty if it cannot be opened).
pub fn list_modes(node: &Path) -> Result<Vec<Mode>, DeviceError> {
    V4lDevice::open(node)?.modes()
}
