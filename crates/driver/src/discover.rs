//! Finding sensors: USB devices in sysfs, their V4L2 capture nodes, and which are tactile sensors.
//!
//! Everything is read below a root directory: `/` on a robot, a fixture tree in tests
//! (crates/driver/tests/fixtures). The layout used is the one sysfs has:
//! `sys/bus/usb/devices/<port>/{idVendor,idProduct,serial,bcdDevice,product,manufacturer}` and, per
//! interface, `<port>/<port>:<cfg>.<intf>/video4linux/videoN/{name,index}`. A UVC camera has two
//! nodes per interface: `index` 0 is the capture node, 1 the metadata node (skipped).
//!
//! Matching: each sensor profile's `usb` (`sensors/<kind>.yaml`, `unitac_core::sensor::UsbMatch`).
//! DIGIT is 2833:0209. GelSight Mini uses the generic Arducam/Microdia id 0c45:636d, so its
//! profile also asks for a product name starting "GelSight Mini" and a serial of the form
//! XXXX-XXXX (A-Z, 0-9); an ordinary camera with the same id is not a sensor.

use serde::Serialize;
use std::path::{Path, PathBuf};
use thiserror::Error;
use unitac_core::SensorKind;
use unitac_core::sensor::{SerialFrom, UsbMatch};

/// Most sysfs entries looked at per directory, and the most bytes read per attribute.
const MAX_ENTRIES: usize = 4096;
const MAX_ATTR_BYTES: u64 = 4096;

#[derive(Debug, Error)]
pub enum DiscoverError {
    #[error("{path}: {source}")]
    Io {
        path: String,
        source: std::io::Error,
    },
    #[error("no tactile sensor with serial '{0}' (connected: {1})")]
    NotFound(String, String),
    #[error("sensor {0} is in firmware-update mode; power-cycle it")]
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
    /// A sensor of this kind in its firmware-update mode (not a camera until power-cycled).
    FirmwareUpdate(SensorKind),
    /// A camera that is not a tactile sensor (e.g. an Arducam with GelSight's USB id).
    OtherCamera,
    NotACamera,
}

/// The serial of a device of the kind `usb` describes: from where its profile says, first match
/// of its pattern wins.
pub fn serial_of(d: &UsbDevice, usb: &UsbMatch) -> Option<String> {
    usb.serial_from.iter().find_map(|from| {
        let s = match from {
            SerialFrom::UsbSerial => d.serial.as_deref(),
            SerialFrom::ProductLastWord => d
                .product
                .as_deref()
                .and_then(|p| p.split_whitespace().last()),
        }?;
        usb.serial_ok(s).then(|| s.to_string())
    })
}

/// What the device is: the sensor kind whose profile matches it (ids, product name, serial), a
/// kind's firmware-update mode, or another device.
pub fn identify(d: &UsbDevice) -> Identity {
    let id = [d.vendor, d.product_id];
    for k in SensorKind::all() {
        let Some(u) = &k.profile().usb else { continue };
        if u.dfu_id == Some(id) {
            return Identity::FirmwareUpdate(*k);
        }
        let named = u
            .product_prefix
            .is_none_or(|pre| d.product.as_deref().is_some_and(|p| p.starts_with(pre)));
        if u.id == id && named && (u.serial_pattern.is_none() || serial_of(d, u).is_some()) {
            return Identity::Sensor(*k);
        }
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
                let serial = kind
                    .profile()
                    .usb
                    .as_ref()
                    .and_then(|u| serial_of(&dev, u))
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
            Identity::FirmwareUpdate(_) => d
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
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn dev(id: [u16; 2], serial: Option<&str>, product: Option<&str>) -> UsbDevice {
        UsbDevice {
            port: "1-2".into(),
            vendor: id[0],
            product_id: id[1],
            serial: serial.map(String::from),
            bcd_device: None,
            product: product.map(String::from),
            manufacturer: None,
            video: Vec::new(),
        }
    }

    #[test]
    fn gelsight_serials_follow_the_profiles_pattern() {
        let u = SensorKind::GELSIGHT_MINI.profile().usb.clone().unwrap();
        let id = [0x0c45, 0x636d];
        for good in ["28J3-CWXU", "0000-AAAA"] {
            assert_eq!(
                serial_of(&dev(id, Some(good), None), &u).as_deref(),
                Some(good)
            );
        }
        for bad in [
            "28j3-CWXU",
            "28J3CWXU",
            "28J3-CWXU1",
            "SN0001",
            "28J3_CWXU",
            "28J3-CWX\u{e9}",
        ] {
            assert_eq!(serial_of(&dev(id, Some(bad), None), &u), None, "{bad}");
        }
        // Else the product name's last word.
        let d = dev(id, Some("x"), Some("GelSight Mini R0B 28J3-CWXU"));
        assert_eq!(serial_of(&d, &u).as_deref(), Some("28J3-CWXU"));
        assert_eq!(identify(&d), Identity::Sensor(SensorKind::GELSIGHT_MINI));
        // The same id on another camera is not a sensor.
        assert_eq!(
            identify(&dev(id, Some("28J3-CWXU"), Some("USB Camera"))),
            Identity::NotACamera
        );
        assert_eq!(
            identify(&dev([0x0403, 0x0fde], Some("D00051"), None)),
            Identity::FirmwareUpdate(SensorKind::DIGIT)
        );
        // The id is a generic camera's: the name and a serial of the pattern decide.
        let gs = |p: &str, s: Option<&str>| identify(&dev(id, s, Some(p)));
        assert_eq!(
            gs("GelSight Mini R0B 28J3-CWXU", Some("28J3-CWXU")),
            Identity::Sensor(SensorKind::GELSIGHT_MINI)
        );
        assert_eq!(gs("USB Camera", Some("28J3-CWXU")), Identity::NotACamera);
        assert_eq!(gs("GelSight Mini", Some("28j3-cwxu")), Identity::NotACamera);
        assert_eq!(gs("GelSight Mini", None), Identity::NotACamera);
        assert_eq!(
            identify(&dev([0x2833, 0x0209], None, None)),
            Identity::Sensor(SensorKind::DIGIT)
        );
        assert_eq!(identify(&dev([1, 2], None, None)), Identity::NotACamera);
    }
}
