//! Per-serial calibration: region of interest, orientation, scale and camera settings.
//!
//! Units differ from one another (gel thickness, lens mount, LED), so learned models need the
//! same crop and scale for every unit: the file is keyed by serial and read at open and at every
//! reconnect. YAML or JSON (JSON is YAML), bounded in size, unknown fields rejected.

use crate::controls::{CameraSettings, SettingsError};
use crate::decode::{Crop, DecodeConfig, DecodeError, Rotation};
use serde::{Deserialize, Serialize};
use std::path::Path;
use thiserror::Error;
use unitac_core::SensorKind;

/// Largest calibration file read.
pub const MAX_CALIBRATION_BYTES: u64 = 64 * 1024;

#[derive(Debug, Error)]
pub enum CalibrationError {
    #[error("{path}: {source}")]
    Io {
        path: String,
        source: std::io::Error,
    },
    #[error("{path}: {size} bytes is more than the {max}-byte limit", max = MAX_CALIBRATION_BYTES)]
    TooLarge { path: String, size: u64 },
    #[error("{path}: {msg}")]
    Parse { path: String, msg: String },
    #[error("{path}: {source}")]
    Invalid {
        path: String,
        source: InvalidCalibration,
    },
}

/// What a parsed calibration gets wrong.
#[derive(Debug, PartialEq, Error)]
pub enum InvalidCalibration {
    #[error("serial must be 1..=64 characters")]
    Serial,
    #[error(transparent)]
    Decode(#[from] DecodeError),
    #[error("mm_per_px {0} is outside (0, 10)")]
    MmPerPx(f64),
    #[error(transparent)]
    Camera(#[from] SettingsError),
    #[error("file is for serial {file}, not {wanted}")]
    OtherSerial { file: String, wanted: String },
}

/// Calibration of one sensor unit.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Calibration {
    pub serial: String,
    pub kind: SensorKind,
    /// Border cut away before the resize, as fractions of each side.
    pub roi: Crop,
    #[serde(default)]
    pub rotation: Rotation,
    #[serde(default)]
    pub flip_horizontal: bool,
    #[serde(default)]
    pub flip_vertical: bool,
    /// Published size.
    pub width: u32,
    pub height: u32,
    /// Gel millimetres per published pixel.
    pub mm_per_px: f64,
    #[serde(default)]
    pub camera: CameraSettings,
    /// See `DecodeConfig::max_upscale` (default: the kind's profile's, 1.1 for GelSight Mini).
    #[serde(default)]
    pub max_upscale: Option<f64>,
}

impl Calibration {
    /// Vendor defaults for a model, used when a serial has no file.
    pub fn default_for(kind: SensorKind, serial: &str) -> Self {
        let spec = kind.spec();
        Self {
            serial: serial.to_string(),
            kind,
            roi: Crop::uniform(kind.profile().crop),
            rotation: Rotation::None,
            flip_horizontal: false,
            flip_vertical: false,
            width: spec.width,
            height: spec.height,
            mm_per_px: spec.mm_per_px,
            camera: CameraSettings::for_kind(kind),
            max_upscale: None,
        }
    }

    pub fn decode_config(&self) -> DecodeConfig {
        DecodeConfig {
            out_width: self.width,
            out_height: self.height,
            crop: self.roi,
            rotation: self.rotation,
            flip_horizontal: self.flip_horizontal,
            flip_vertical: self.flip_vertical,
            dct_scaling: true,
            max_upscale: self.max_upscale.unwrap_or(self.kind.profile().max_upscale),
        }
    }

    fn validate(&self) -> Result<(), InvalidCalibration> {
        if self.serial.is_empty() || self.serial.len() > 64 {
            return Err(InvalidCalibration::Serial);
        }
        self.decode_config().check()?;
        if !(self.mm_per_px.is_finite() && self.mm_per_px > 0.0 && self.mm_per_px < 10.0) {
            return Err(InvalidCalibration::MmPerPx(self.mm_per_px));
        }
        Ok(self.camera.validate()?)
    }

    pub fn parse(text: &str, path: &str) -> Result<Self, CalibrationError> {
        let c: Calibration = serde_yaml::from_str(text).map_err(|e| CalibrationError::Parse {
            path: path.to_string(),
            msg: e.to_string(),
        })?;
        c.validate().map_err(|source| CalibrationError::Invalid {
            path: path.to_string(),
            source,
        })?;
        Ok(c)
    }

    /// Read `<dir>/<serial>.yaml` if present, else the model's defaults.
    pub fn load_for(dir: &Path, kind: SensorKind, serial: &str) -> Result<Self, CalibrationError> {
        // A serial comes from the device: never let it walk out of the directory.
        if serial.is_empty()
            || !serial
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '-')
        {
            return Ok(Self::default_for(kind, serial));
        }
        let path = dir.join(format!("{serial}.yaml"));
        if !path.exists() {
            return Ok(Self::default_for(kind, serial));
        }
        let c = Self::load(&path)?;
        if c.serial != serial {
            return Err(CalibrationError::Invalid {
                path: path.display().to_string(),
                source: InvalidCalibration::OtherSerial {
                    file: c.serial,
                    wanted: serial.to_string(),
                },
            });
        }
        Ok(c)
    }

    pub fn load(path: &Path) -> Result<Self, CalibrationError> {
        let p = path.display().to_string();
        let io = |source| CalibrationError::Io {
            path: p.clone(),
            source,
        };
        let size = std::fs::metadata(path).map_err(io)?.len();
        if size > MAX_CALIBRATION_BYTES {
            return Err(CalibrationError::TooLarge { path: p, size });
        }
        let text = std::fs::read_to_string(path).map_err(io)?;
        Self::parse(&text, &p)
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
    use super::*;

    const DIGIT: &str = "serial: D00045\nkind: digit\nroi: {left: 0.0, right: 0.0, top: 0.05, bottom: 0.05}\n\
rotation: cw270\nwidth: 240\nheight: 320\nmm_per_px: 0.0405\ncamera: {led: {r: 15, g: 15, b: 8}}\n";

    #[test]
    fn parses_and_round_trips() {
        let c = Calibration::parse(DIGIT, "t").unwrap();
        assert_eq!(c.rotation, Rotation::Cw270);
        assert_eq!(c.camera.led.map(|l| l.b), Some(8));
        let again = Calibration::parse(&serde_yaml::to_string(&c).unwrap(), "t").unwrap();
        assert_eq!(again, c);
        let j = serde_json::to_string(&c).unwrap();
        assert_eq!(Calibration::parse(&j, "t").unwrap(), c);
    }

    #[test]
    fn rejects_unknown_fields_and_bad_values() {
        assert!(Calibration::parse(&format!("{DIGIT}extra: 1\n"), "t").is_err());
        let bad = DIGIT.replace("mm_per_px: 0.0405", "mm_per_px: -1");
        assert!(matches!(
            Calibration::parse(&bad, "t"),
            Err(CalibrationError::Invalid { .. })
        ));
        let bad = DIGIT.replace("width: 240", "width: 0");
        assert!(Calibration::parse(&bad, "t").is_err());
        let bad = DIGIT.replace("b: 8", "b: 16");
        assert!(Calibration::parse(&bad, "t").is_err());
    }

    #[test]
    fn load_for_uses_defaults_bounds_size_and_checks_serial() {
        let dir = std::env::temp_dir().join(format!("unitac-calib-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let d = Calibration::load_for(&dir, SensorKind::GELSIGHT_MINI, "AB12-CD34").unwrap();
        assert_eq!(
            d,
            Calibration::default_for(SensorKind::GELSIGHT_MINI, "AB12-CD34")
        );
        std::fs::write(dir.join("D00045.yaml"), DIGIT).unwrap();
        let c = Calibration::load_for(&dir, SensorKind::DIGIT, "D00045").unwrap();
        assert_eq!(c.width, 240);
        std::fs::write(dir.join("D00046.yaml"), DIGIT).unwrap();
        assert!(Calibration::load_for(&dir, SensorKind::DIGIT, "D00046").is_err());
        std::fs::write(dir.join("D00047.yaml"), vec![b'#'; 70_000]).unwrap();
        assert!(matches!(
            Calibration::load_for(&dir, SensorKind::DIGIT, "D00047"),
            Err(CalibrationError::TooLarge { .. })
        ));
        // A serial with a path in it never reaches the file system.
        let c = Calibration::load_for(&dir, SensorKind::DIGIT, "../D00045").unwrap();
        assert_eq!(c.width, 320);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
