#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
//! Discovery on sysfs fixture trees (tests/fixtures/README.md).

use std::path::{Path, PathBuf};
use unitac_core::SensorKind;
use unitac_driver::discover::{
    DiscoverError, Identity, discover, find_by_serial, identify, scan_usb,
};

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures")
        .join(name)
}

#[test]
fn lists_usb_devices_with_ids_serials_firmware_and_nodes() {
    let root = fixture("two_sensors");
    let devs = scan_usb(&root).unwrap();
    let ports: Vec<&str> = devs.iter().map(|d| d.port.as_str()).collect();
    // Interfaces (1-1:1.0) are skipped; sorted by port.
    assert_eq!(
        ports,
        ["1-1", "1-2", "1-3", "1-4", "1-5", "2-1", "2-2.1", "usb1"]
    );
    let digit = &devs[0];
    assert_eq!(digit.id(), "2833:0209");
    assert_eq!(digit.serial.as_deref(), Some("D00045"));
    assert_eq!(digit.bcd_device.as_deref(), Some("0200"));
    assert_eq!(digit.product.as_deref(), Some("DIGIT"));
    assert_eq!(digit.video.len(), 2);
    let gs = &devs[1];
    // The capture node is found by its index, not by its position.
    assert_eq!(gs.capture_node().unwrap().name, "video2");
    assert_eq!(gs.capture_node().unwrap().dev_path, root.join("dev/video2"));
}

#[test]
fn identifies_sensors_and_rejects_look_alikes() {
    let devs = scan_usb(&fixture("two_sensors")).unwrap();
    let ids: Vec<Identity> = devs.iter().map(identify).collect();
    assert_eq!(
        ids,
        [
            Identity::Sensor(SensorKind::DIGIT),
            Identity::Sensor(SensorKind::GELSIGHT_MINI),
            Identity::OtherCamera, // Arducam with GelSight's USB id
            Identity::OtherCamera, // "GelSight Mini R0B" without a serial
            Identity::NotACamera,
            Identity::FirmwareUpdate(SensorKind::DIGIT),
            Identity::Sensor(SensorKind::DIGIT), // no V4L2 node, still a DIGIT
            Identity::NotACamera,
        ]
    );
}

#[test]
fn discovery_summary() {
    let d = discover(&fixture("two_sensors")).unwrap();
    let s: Vec<(SensorKind, &str, Option<&str>)> = d
        .sensors
        .iter()
        .map(|s| (s.kind, s.serial.as_str(), s.firmware.as_deref()))
        .collect();
    assert_eq!(
        s,
        [
            (SensorKind::DIGIT, "D00045", Some("0200")),
            (SensorKind::GELSIGHT_MINI, "28J3-CWXU", Some("0100")),
            (SensorKind::DIGIT, "D00102", Some("0103")),
        ]
    );
    assert_eq!(d.sensors[1].nodes, ["video2", "video3"]);
    assert_eq!(d.sensors[2].capture, None);
    assert_eq!(d.firmware_update, ["D00051"]);
    assert_eq!(d.other_cameras.len(), 2);
    let none = discover(&fixture("no_sensors")).unwrap();
    assert!(none.sensors.is_empty());
    assert_eq!(none.other_cameras, ["0c45:636d USB Camera"]);
}

#[test]
fn open_by_serial_finds_the_capture_node_or_says_why_not() {
    let root = fixture("two_sensors");
    let (s, node) = find_by_serial(&root, "28J3-CWXU").unwrap();
    assert_eq!(s.kind, SensorKind::GELSIGHT_MINI);
    assert_eq!(node, root.join("dev/video2"));
    let (_, node) = find_by_serial(&root, "D00045").unwrap();
    assert_eq!(node, root.join("dev/video0"));
    assert!(matches!(
        find_by_serial(&root, "SN0001"),
        Err(DiscoverError::NotFound(..))
    ));
    assert!(matches!(
        find_by_serial(&root, "D00051"),
        Err(DiscoverError::FirmwareUpdateMode(_))
    ));
    assert!(matches!(
        find_by_serial(&root, "D00102"),
        Err(DiscoverError::NoCaptureNode(_))
    ));
    let e = find_by_serial(&root, "D99999").unwrap_err().to_string();
    assert!(e.contains("D00045") && e.contains("28J3-CWXU"), "{e}");
    assert!(find_by_serial(Path::new("/nonexistent-root"), "D00045").is_err());
}

#[test]
fn udev_rules_cover_both_models_and_only_capture_nodes_get_links() {
    let rules = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("udev/99-unitac-tactile.rules"),
    )
    .unwrap();
    let lines: Vec<&str> = rules
        .lines()
        .filter(|l| !l.trim().is_empty() && !l.starts_with('#'))
        .collect();
    assert_eq!(lines.len(), 7);
    // Both sensors' USB devices are writable (USB reset of a stalled sensor through libusb).
    for vid in ["\"2833\"", "\"0c45\""] {
        assert!(
            lines
                .iter()
                .any(|l| l.contains("SUBSYSTEM==\"usb\"") && l.contains(vid) && l.contains("MODE")),
            "no usb_device rule for {vid}"
        );
    }
    for l in &lines {
        // Every rule is keyed on a vendor id the driver knows.
        assert!(
            ["\"2833\"", "\"0403\"", "\"0c45\""]
                .iter()
                .any(|v| l.contains(v)),
            "{l}"
        );
        if l.contains("SYMLINK") {
            assert!(l.contains("ATTR{index}==\"0\""), "{l}");
        }
        if l.contains("\"0c45\"") {
            assert!(
                l.contains("GelSight Mini*") && l.contains("ATTRS{serial}"),
                "{l}"
            );
        }
    }
}
