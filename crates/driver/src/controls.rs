//! Camera controls: DIGIT LEDs, GelSight Mini exposure / white balance / gain.
//!
//! Every setting is written, read back and compared, because UVC cameras silently clamp or ignore
//! values ("LED settings with no effect" is a common complaint). The settings are kept by the
//! stream and written again after every reconnect.

use crate::capture::{CaptureDevice, DeviceError};
use serde::{Deserialize, Serialize};
use unitac_core::SensorKind;
use unitac_core::sensor::LedControl;

/// V4L2 control ids (linux/v4l2-controls.h).
pub mod cid {
    pub const BASE: u32 = 0x0098_0900;
    pub const AUTO_WHITE_BALANCE: u32 = BASE + 12;
    pub const GAIN: u32 = BASE + 19;
    pub const WHITE_BALANCE_TEMPERATURE: u32 = BASE + 26;
    pub const CAMERA_CLASS_BASE: u32 = 0x009a_0900;
    /// Menu: 1 = manual, 3 = aperture priority (auto).
    pub const EXPOSURE_AUTO: u32 = CAMERA_CLASS_BASE + 1;
    /// In units of 100 us.
    pub const EXPOSURE_ABSOLUTE: u32 = CAMERA_CLASS_BASE + 2;
    /// DIGIT firmware reuses zoom for the LEDs.
    pub const ZOOM_ABSOLUTE: u32 = CAMERA_CLASS_BASE + 13;
}

pub const EXPOSURE_MANUAL: i64 = 1;

/// First DIGIT firmware revision (USB bcdDevice read as decimal digits, "0200" = 200) with
/// per-colour LED control.
pub const DIGIT_RGB_LED_FIRMWARE: u32 = 200;

/// LED intensities, each 0..=15.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Led {
    pub r: u8,
    pub g: u8,
    pub b: u8,
}

impl Led {
    pub const FULL: Led = Led {
        r: 15,
        g: 15,
        b: 15,
    };
}

/// The zoom-control value that sets the DIGIT LEDs.
///
/// Firmware >= 200: `(r << 8) | (g << 4) | b`, each 0..=15 (4095 = all full).
/// Older firmware has one global level 0..=15 in the low bits; the reference SDK scaled a full
/// request down to 0 there (LEDs off). Here the global level is the brightest channel, so "full"
/// stays full and only "all off" gives 0. `None` if a channel is above 15.
pub fn digit_led_value(led: Led, firmware: u32) -> Option<i64> {
    if led.r > 15 || led.g > 15 || led.b > 15 {
        return None;
    }
    if firmware >= DIGIT_RGB_LED_FIRMWARE {
        Some((i64::from(led.r) << 8) | (i64::from(led.g) << 4) | i64::from(led.b))
    } else {
        Some(i64::from(led.r.max(led.g).max(led.b)))
    }
}

/// Parse a USB bcdDevice string ("0200") the way the DIGIT tools do: as decimal digits.
pub fn firmware_number(bcd_device: &str) -> Option<u32> {
    let s = bcd_device.trim();
    if s.is_empty() || s.len() > 4 || !s.chars().all(|c| c.is_ascii_digit()) {
        return None;
    }
    s.parse().ok()
}

/// A camera setting outside what the sensors accept.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum SettingsError {
    #[error("exposure {0} is outside 1..=100000 (100 us units)")]
    Exposure(u32),
    #[error("white_balance_k {0} is outside 1000..=10000")]
    WhiteBalance(u32),
    #[error("gain {0} is above 1000")]
    Gain(u32),
    #[error("led {0}: each channel is 0..=15")]
    Led(String),
}

/// Settings written at open and after every reconnect. `None` leaves the camera's value alone.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraSettings {
    /// Manual exposure in 100 us units (auto exposure is switched off when set).
    #[serde(default)]
    pub exposure: Option<u32>,
    /// White balance in kelvin (auto white balance is switched off when set).
    #[serde(default)]
    pub white_balance_k: Option<u32>,
    #[serde(default)]
    pub gain: Option<u32>,
    /// Written on kinds whose profile has an LED control (DIGIT).
    #[serde(default)]
    pub led: Option<Led>,
}

impl CameraSettings {
    /// The settings a kind opens with (its profile's `camera`: GelSight Mini, the vendor's auto
    /// white balance off at 4500 K, manual exposure, gain 0; DIGIT, its LEDs full).
    pub fn for_kind(kind: SensorKind) -> Self {
        let c = kind.profile().camera;
        Self {
            exposure: c.exposure,
            white_balance_k: c.white_balance_k,
            gain: c.gain,
            led: c.led.map(|[r, g, b]| Led { r, g, b }),
        }
    }
    pub fn validate(&self) -> Result<(), SettingsError> {
        match self.exposure {
            Some(e) if !(1..=100_000).contains(&e) => return Err(SettingsError::Exposure(e)),
            _ => {}
        }
        match self.white_balance_k {
            Some(k) if !(1000..=10_000).contains(&k) => {
                return Err(SettingsError::WhiteBalance(k));
            }
            _ => {}
        }
        match self.gain {
            Some(g) if g > 1000 => return Err(SettingsError::Gain(g)),
            _ => {}
        }
        match self.led {
            Some(l) if digit_led_value(l, DIGIT_RGB_LED_FIRMWARE).is_none() => {
                return Err(SettingsError::Led(format!("{l:?}")));
            }
            _ => {}
        }
        Ok(())
    }

    /// The control writes, in the order they must happen (auto modes off first).
    pub fn plan(&self, kind: SensorKind, firmware: u32) -> Vec<ControlWrite> {
        let mut v = Vec::new();
        if let Some(e) = self.exposure {
            v.push(ControlWrite::new(
                "exposure_auto",
                cid::EXPOSURE_AUTO,
                EXPOSURE_MANUAL,
            ));
            v.push(ControlWrite::new(
                "exposure",
                cid::EXPOSURE_ABSOLUTE,
                e.into(),
            ));
        }
        if let Some(k) = self.white_balance_k {
            v.push(ControlWrite::new(
                "white_balance_auto",
                cid::AUTO_WHITE_BALANCE,
                0,
            ));
            v.push(ControlWrite::new(
                "white_balance_k",
                cid::WHITE_BALANCE_TEMPERATURE,
                k.into(),
            ));
        }
        if let Some(g) = self.gain {
            v.push(ControlWrite::new("gain", cid::GAIN, g.into()));
        }
        if kind.profile().led == LedControl::Digit {
            if let Some(value) = self.led.and_then(|l| digit_led_value(l, firmware)) {
                v.push(ControlWrite::new("led", cid::ZOOM_ABSOLUTE, value));
            }
        }
        v
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct ControlWrite {
    pub name: &'static str,
    pub id: u32,
    pub value: i64,
}

impl ControlWrite {
    pub fn new(name: &'static str, id: u32, value: i64) -> Self {
        Self { name, id, value }
    }
}

/// A control the device did not take as written.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct ControlMismatch {
    pub name: &'static str,
    pub wanted: i64,
    /// What the device reports after the write; `None` if the write or the read failed.
    pub got: Option<i64>,
    pub error: Option<String>,
}

/// Write each control, read it back, compare. A device that is gone ends it with the error; a
/// control the device rejects or changes is reported and the rest are still written.
pub fn apply_and_verify(
    dev: &mut dyn CaptureDevice,
    writes: &[ControlWrite],
) -> Result<Vec<ControlMismatch>, DeviceError> {
    let mut bad = Vec::new();
    for w in writes {
        let r = dev
            .set_control(w.id, w.value)
            .and_then(|()| dev.control(w.id));
        match r {
            Ok(got) if got == w.value => {}
            Ok(got) => bad.push(ControlMismatch {
                name: w.name,
                wanted: w.value,
                got: Some(got),
                error: None,
            }),
            Err(e @ DeviceError::Gone(_)) => return Err(e),
            Err(e) => bad.push(ControlMismatch {
                name: w.name,
                wanted: w.value,
                got: None,
                error: Some(e.to_string()),
            }),
        }
    }
    Ok(bad)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
    use super::*;

    #[test]
    fn digit_led_encoding_by_firmware() {
        assert_eq!(digit_led_value(Led::FULL, 200), Some(4095));
        let l = Led { r: 1, g: 2, b: 3 };
        assert_eq!(digit_led_value(l, 200), Some(0x123));
        assert_eq!(digit_led_value(l, 310), Some(0x123));
        // Old firmware: one global level; full stays full (the reference SDK sent 0 here).
        assert_eq!(digit_led_value(Led::FULL, 100), Some(15));
        assert_eq!(digit_led_value(l, 199), Some(3));
        assert_eq!(digit_led_value(Led { r: 0, g: 0, b: 0 }, 100), Some(0));
        assert_eq!(digit_led_value(Led { r: 16, g: 0, b: 0 }, 200), None);
    }

    #[test]
    fn firmware_strings() {
        assert_eq!(firmware_number("0200"), Some(200));
        assert_eq!(firmware_number("0101\n"), Some(101));
        assert_eq!(firmware_number("02a0"), None);
        assert_eq!(firmware_number(""), None);
        assert_eq!(firmware_number("123456"), None);
    }

    #[test]
    fn plan_turns_auto_modes_off_first() {
        let p =
            CameraSettings::for_kind(SensorKind::GELSIGHT_MINI).plan(SensorKind::GELSIGHT_MINI, 0);
        let names: Vec<_> = p.iter().map(|w| w.name).collect();
        assert_eq!(
            names,
            [
                "exposure_auto",
                "exposure",
                "white_balance_auto",
                "white_balance_k",
                "gain"
            ]
        );
        // LEDs only where the profile has an LED control (DIGIT).
        let s = CameraSettings::for_kind(SensorKind::DIGIT);
        assert_eq!(s.led, Some(Led::FULL));
        assert!(s.plan(SensorKind::GELSIGHT_MINI, 200).is_empty());
        assert_eq!(
            s.plan(SensorKind::DIGIT, 200),
            [ControlWrite::new("led", cid::ZOOM_ABSOLUTE, 4095)]
        );
    }
}
