//! Finding sensors: USB devices in sysfs, their V4L2 capture nodes, and which are tactile sensors.
//!
//! Everything is read below a root directory: `/` on a robot, a fixture tree in tests
//! (crates/driver/tests/fixtures). The layout used is the one sysfs has:
//! `sys/bus/usb/devices/<port>/{idVendor,idProduct,serial,bcdDevice,product,manufacturer}` and, per
//! interface, `<port>/<port>:<cfg>.<intf>/video4linux/videoN/{name,index}`. A UVC camera has two
//! nodes per interface: `index` 0 is the capture node, 1 the metadata node (skipped).
//!
//! Matching: DIGIT is 2833:0209. GelSight Mini uses the generic Arducam/Microdia id 0c45:636d, so
//! it must also have a product name starting "GelSight Mini" and a serial of the form
//! XXXX-XXXX (A-Z, 0-9); an ordinary camera with the same id is not a sensor.

use serde::Serialize;
use std::path::{Path, PathBuf};
use thiserror::Error;
use unitac_core::SensorKind;

/// Most sysfs entries looked at per directory, and the most bytes read per attribute.
const MAX_ENTRIES: usize = 4096;
const MAX_ATTR_BYTES: u64 = 4096;

pub const DIGIT_ID: (u16, u16) = (0x2833, 0x0209);
/// DIGIT in firmware-update (DFU) mode: not a camera until it is power-cycled.
pub const DIGIT_DFU_ID: (u16, u16) = (0x0403, 0x0fde);
pub const GELSIGHT_MINI_ID: (u16, u16) = (0x0c45, 0x636d);

#[derive(Debug, Error)]
pub enum DiscoverError {
    #[error("{path}: {source}")]
    Io {
        path: String,
        source: std::io::Error,
    },
    #[error("no tactile sensor with serial '{0}' (connected: {1})")]
    NotFound(String, String),
    #[error("sensor {0} is in firmware-update mode (USB 0403:0fde); power-cycle it")]
    FirmwareUpdateMode(String),
    #[error("sensor {0} has no V4L2 capture node (uvcvideo not loaded, or a charge-only cable?)")]
    NoCaptureNode(String),
    #[error("{n} sensors report serial '{serial}'")]
    Ambiguous { serial: String, n: usize },
}

/// One V4L2 node under a USB device.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct VideoNode {
    /// `video2`
    pub name: String,
    /// `<root>/dev/video2`
    pub dev_path: PathBuf,
    /// 0 = capture, 1 = metadata (UVC).
    pub index: Option<u32>,
    /// V4L2 card name (truncated by the kernel to 31 bytes).
    pub card: String,
}

impl VideoNode {
    pub fn is_capture(&self) -> bool {
        self.index == Some(0)
    }
}

/// A USB device as sysfs describes it.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct UsbDevice {
    /// sysfs name, e.g. `1-2` or `3-1.4`.
    pub port: String,
    pub vendor: u16,
    pub product_id: u16,
    pub serial: Option<String>,
    /// bcdDevice, e.g. `0200` (the DIGIT firmware revision).
    pub bcd_device: Option<String>,
    pub product: Option<String>,
    pub manufacturer: Option<String>,
    pub video: Vec<VideoNode>,
}

impl UsbDevice {
    pub fn id(&self) -> String {
        format!("{:04x}:{:04x}", self.vendor, self.product_id)
    }
    pub fn capture_node(&self) -> Option<&VideoNode> {
        self.video.iter().find(|v| v.is_capture())
    }
}

/// What a USB device is, for this stack.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Identity {
    Sensor(SensorKind),
    DigitFirmwareUpdate,
    /// A camera that is not a tactile sensor (e.g. an Arducam with GelSight's USB id).
    OtherCamera,
    NotACamera,
}

/// `[A-Z0-9]{4}-[A-Z0-9]{4}`
pub fn is_gelsight_serial(s: &str) -> bool {
    let b = s.as_bytes();
    let ok = |c: &u8| c.is_ascii_uppercase() || c.is_ascii_digit();
    b.len() == 9 && b[4] == b'-' && b[..4].iter().all(ok) && b[5..].iter().all(ok)
}

/// The GelSight Mini serial: the USB serial, or else the product name's last word
/// ("GelSight Mini R0B 28J3-CWXU").
pub fn gelsight_serial(d: &UsbDevice) -> Option<String> {
    if let Some(s) = d.serial.as_deref().filter(|s| is_gelsight_serial(s)) {
        return Some(s.to_string());
    }
    d.product
        .as_deref()
        .and_then(|p| p.split_whitespace().last())
        .filter(|s| is_gelsight_serial(s))
        .map(str::to_string)
}

pub fn identify(d: &UsbDevice) -> Identity {
    let id = (d.vendor, d.product_id);
    if id == DIGIT_ID {
        return Identity::Sensor(SensorKind::Digit);
    }
    if id == DIGIT_DFU_ID {
        return Identity::DigitFirmwareUpdate;
    }
    if id == GELSIGHT_MINI_ID
        && d.product
            .as_deref()
            .is_some_and(|p| p.starts_with("GelSight Mini"))
        && gelsight_serial(d).is_some()
    {
        return Identity::Sensor(SensorKind::GelsightMini);
    }
    if d.video.is_empty() {
        Identity::NotACamera
    } else {
        Identity::OtherCamera
    }
}

/// A tactile sensor found on the bus.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct FoundSensor {
    pub kind: SensorKind,
    pub serial: String,
    /// bcdDevice as sysfs shows it.
    pub firmware: Option<String>,
    pub product: Option<String>,
    pub port: String,
    /// The capture node, if the kernel made one.
    pub capture: Option<PathBuf>,
    /// Every V4L2 node of the device (capture and metadata).
    pub nodes: Vec<String>,
}

/// Everything found under a root.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize)]
pub struct Discovery {
    pub sensors: Vec<FoundSensor>,
    /// Serials (or ports) of DIGITs in firmware-update mode.
    pub firmware_update: Vec<String>,
    /// Cameras that are not sensors (id, product), e.g. look-alikes with GelSight's USB id.
    pub other_cameras: Vec<String>,
}

fn read_attr(dir: &Path, name: &str) -> Option<String> {
    use std::io::Read;
    let f = std::fs::File::open(dir.join(name)).ok()?;
    let mut s = String::new();
    f.take(MAX_ATTR_BYTES).read_to_string(&mut s).ok()?;
    let t = s.trim();
    (!t.is_empty()).then(|| t.to_string())
}

fn read_hex_u16(dir: &Path, name: &str) -> Option<u16> {
    u16::from_str_radix(&read_attr(dir, name)?, 16).ok()
}

fn sorted_entries(dir: &Path) -> Vec<(String, PathBuf)> {
    let Ok(rd) = std::fs::read_dir(dir) else {
        return Vec::new();
    };
    let mut v: Vec<(String, PathBuf)> = rd
        .take(MAX_ENTRIES)
        .filter_map(Result::ok)
        .filter_map(|e| Some((e.file_name().into_string().ok()?, e.path())))
        .collect();
    v.sort();
    v
}

fn video_nodes(root: &Path, dev_dir: &Path, port: &str) -> Vec<VideoNode> {
    let mut out = Vec::new();
    let prefix = format!("{port}:");
    for (intf, intf_dir) in sorted_entries(dev_dir) {
        if !intf.starts_with(&prefix) {
            continue;
        }
        for (name, node_dir) in sorted_entries(&intf_dir.join("video4linux")) {
            if !name.starts_with("video") || !name[5..].chars().all(|c| c.is_ascii_digit()) {
                continue;
            }
            out.push(VideoNode {
                dev_path: root.join("dev").join(&name),
                index: read_attr(&node_dir, "index").and_then(|s| s.parse().ok()),
                card: read_attr(&node_dir, "name").unwrap_or_default(),
                name,
            });
        }
    }
    out
}

/// Every USB device under `<root>/sys/bus/usb/devices`, sorted by port.
pub fn scan_usb(root: &Path) -> Result<Vec<UsbDevice>, DiscoverError> {
    let dir = root.join("sys/bus/usb/devices");
    if !dir.is_dir() {
        return Err(DiscoverError::Io {
            path: dir.display().to_string(),
            source: std::io::Error::new(std::io::ErrorKind::NotFound, "no such directory"),
        });
    }
    let mut out = Vec::new();
    for (port, dev_dir) in sorted_entries(&dir) {
        // Interfaces (`1-2:1.0`) are listed beside devices; only devices have idVendor.
        if port.contains(':') {
            continue;
        }
        let (Some(vendor), Some(product_id)) = (
            read_hex_u16(&dev_dir, "idVendor"),
            read_hex_u16(&dev_dir, "idProduct"),
        ) else {
            continue;
        };
        out.push(UsbDevice {
            vendor,
            product_id,
            serial: read_attr(&dev_dir, "serial"),
            bcd_device: read_attr(&dev_dir, "bcdDevice"),
            product: read_attr(&dev_dir, "product"),
            manufacturer: read_attr(&dev_dir, "manufacturer"),
            video: video_nodes(root, &dev_dir, &port),
            port,
        });
    }
    Ok(out)
}

/// Tactile sensors (and what was skipped) under `root`.
pub fn discover(root: &Path) -> Result<Discovery, DiscoverError> {
    let mut d = Discovery::default();
    for dev in scan_usb(root)? {
        match identify(&dev) {
            Identity::Sensor(kind) => {
                let serial = match kind {
                    SensorKind::GelsightMini => gelsight_serial(&dev),
                    _ => dev.serial.clone(),
                }
                .unwrap_or_else(|| format!("usb-{}", dev.port));
                d.sensors.push(FoundSensor {
                    kind,
                    serial,
                    firmware: dev.bcd_device.clone(),
                    product: dev.product.clone(),
                    capture: dev.capture_node().map(|n| n.dev_path.clone()),
                    nodes: dev.video.iter().map(|n| n.name.clone()).collect(),
                    port: dev.port.clone(),
                });
            }
            Identity::DigitFirmwareUpdate => d
                .firmware_update
                .push(dev.serial.clone().unwrap_or_else(|| dev.port.clone())),
            Identity::OtherCamera => d.other_cameras.push(format!(
                "{} {}",
                dev.id(),
                dev.product.as_deref().unwrap_or("?")
            )),
            Identity::NotACamera => {}
        }
    }
    Ok(d)
}

/// The sensor with this serial, with its capture node.
pub fn find_by_serial(root: &Path, serial: &str) -> Result<(FoundSensor, PathBuf), DiscoverError> {
    let d = discover(root)?;
    let hits: Vec<&FoundSensor> = d.sensors.iter().filter(|s| s.serial == serial).collect();
    match hits.as_slice() {
        [one] => {
            let node = one
                .capture
                .clone()
                .ok_or_else(|| DiscoverError::NoCaptureNode(serial.to_string()))?;
            Ok(((*one).clone(), node))
        }
        [] if d.firmware_update.iter().any(|s| s == serial) => {
            Err(DiscoverError::FirmwareUpdateMode(serial.to_string()))
        }
        [] => {
            let known: Vec<&str> = d.sensors.iter().map(|s| s.serial.as_str()).collect();
            Err(DiscoverError::NotFound(
                serial.to_string(),
                if known.is_empty() {
                    "none".into()
                } else {
                    known.join(", ")
                },
            ))
        }
        many => Err(DiscoverError::Ambiguous {
            serial: serial.to_string(),
            n: many.len(),
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gelsight_serial_pattern() {
        assert!(is_gelsight_serial("28J3-CWXU"));
        assert!(is_gelsight_serial("0000-AAAA"));
        assert!(!is_gelsight_serial("28j3-CWXU"));
        assert!(!is_gelsight_serial("28J3CWXU"));
        assert!(!is_gelsight_serial("28J3-CWXU1"));
        assert!(!is_gelsight_serial("SN0001"));
        assert!(!is_gelsight_serial("28J3_CWXU"));
        assert!(!is_gelsight_serial("28J3-CWX\u{e9}"));
    }
}
