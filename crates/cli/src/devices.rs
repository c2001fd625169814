//! `unitac devices`: the tactile sensors on the USB bus, with serial, firmware, V4L2 node and the
//! modes the node offers; and the execution providers the ONNX Runtime library has (where a
//! scene's `providers: [cuda, cpu]` will run its models).

use serde::Serialize;
use std::path::{Path, PathBuf};
use unitac_driver::discover::{Discovery, discover};
use unitac_driver::v4l_backend::list_modes;

#[derive(Debug, Serialize)]
pub struct DeviceRow {
    pub model: String,
    pub serial: String,
    pub firmware: Option<String>,
    pub product: Option<String>,
    pub usb_port: String,
    /// Capture node (the metadata node is not listed here).
    pub node: Option<PathBuf>,
    pub all_nodes: Vec<String>,
    /// Modes as "FOURCC WxH@fps".
    pub modes: Vec<String>,
    /// Why the modes could not be read, if so.
    pub error: Option<String>,
}

#[derive(Debug, Serialize)]
pub struct DevicesReport {
    pub root: PathBuf,
    pub sensors: Vec<DeviceRow>,
    pub firmware_update_mode: Vec<String>,
    pub other_cameras: Vec<String>,
    pub message: String,
    /// The ONNX Runtime library's execution providers: "cpu: yes", "cuda: no", ... or why the
    /// library could not be loaded.
    pub onnxruntime: Vec<String>,
}

/// Which execution providers the process's ONNX Runtime library has.
fn providers() -> Vec<String> {
    use unitac_infer::ExecutionProvider;
    match unitac_infer::runtime::environment(None) {
        Err(e) => vec![format!("not loaded: {e}")],
        Ok(_) => ExecutionProvider::ALL
            .iter()
            .map(|p| match p.available() {
                Ok(true) => format!("{p}: yes"),
                Ok(false) => format!("{p}: no"),
                Err(e) => format!(
                    "{p}: unknown ({})",
                    e.to_string().lines().next().unwrap_or("")
                ),
            })
            .collect(),
    }
}

/// `root` is `/` on a robot; `UNITAC_SYSFS_ROOT` points it at a fixture tree.
pub fn devices(root: &Path) -> DevicesReport {
    let (found, message) = match discover(root) {
        Ok(d) => {
            let msg = if d.sensors.is_empty() {
                format!(
                    "no tactile sensors found under {} (looking for DIGIT 2833:0209 and GelSight \
                     Mini 0c45:636d named \"GelSight Mini ...\" with a XXXX-XXXX serial)",
                    root.join("sys/bus/usb/devices").display()
                )
            } else {
                format!("{} tactile sensor(s) found", d.sensors.len())
            };
            (d, msg)
        }
        Err(e) => (
            Discovery::default(),
            format!("no tactile sensors found: no USB bus visible here ({e})"),
        ),
    };
    let sensors = found
        .sensors
        .iter()
        .map(|s| {
            let (modes, error) = match &s.capture {
                None => (
                    Vec::new(),
                    Some(
                        "no V4L2 capture node (uvcvideo not bound, or a charge-only cable)".into(),
                    ),
                ),
                Some(node) => match list_modes(node) {
                    Ok(m) => (m.iter().map(ToString::to_string).collect(), None),
                    Err(e) => (Vec::new(), Some(e.to_string())),
                },
            };
            DeviceRow {
                model: s.kind.to_string(),
                serial: s.serial.clone(),
                firmware: s.firmware.clone(),
                product: s.product.clone(),
                usb_port: s.port.clone(),
                node: s.capture.clone(),
                all_nodes: s.nodes.clone(),
                modes,
                error,
            }
        })
        .collect();
    DevicesReport {
        root: root.to_path_buf(),
        sensors,
        firmware_update_mode: found.firmware_update,
        other_cameras: found.other_cameras,
        message,
        onnxruntime: providers(),
    }
}

impl DevicesReport {
    pub fn text(&self) -> String {
        let mut s = format!("{}\n", self.message);
        for d in &self.sensors {
            s += &format!(
                "{:<13} {:<10} firmware {:<5} {:<12} modes: {}\n",
                d.model,
                d.serial,
                d.firmware.as_deref().unwrap_or("?"),
                d.node
                    .as_ref()
                    .map(|p| p.display().to_string())
                    .unwrap_or_else(|| "-".into()),
                if d.modes.is_empty() {
                    format!(
                        "none listed ({})",
                        d.error.as_deref().unwrap_or("the node lists no modes")
                    )
                } else {
                    d.modes.join(", ")
                }
            );
        }
        for f in &self.firmware_update_mode {
            s += &format!("DIGIT {f} is in firmware-update mode (0403:0fde): power-cycle it\n");
        }
        for c in &self.other_cameras {
            s += &format!("ignored camera: {c}\n");
        }
        s += &format!(
            "ONNX Runtime execution providers: {}\n",
            self.onnxruntime.join(", ")
        );
        s
    }
}
