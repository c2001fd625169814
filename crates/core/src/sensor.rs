//! Sensor specifications (facts from ../shared/notes/sensors.md).

use serde::{Deserialize, Serialize};
use std::fmt;
use std::str::FromStr;

#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum SensorKind {
    GelsightMini,
    Digit,
    /// Any other RGB tactile camera: no vendor defaults beyond the output size.
    Generic,
}

impl SensorKind {
    pub const ALL: [SensorKind; 3] = [
        SensorKind::GelsightMini,
        SensorKind::Digit,
        SensorKind::Generic,
    ];

    pub fn as_str(self) -> &'static str {
        match self {
            SensorKind::GelsightMini => "gelsight-mini",
            SensorKind::Digit => "digit",
            SensorKind::Generic => "generic",
        }
    }

    /// Whether the gel carries marker dots (GelSight Mini: a printed dot grid; DIGIT: none;
    /// a generic gel: not known). The contact stage masks them by default where there are some,
    /// the slip stage refuses a gel without them, the mock sensor draws them where there are.
    pub fn markers(self) -> Markers {
        match self {
            SensorKind::GelsightMini => Markers::Yes,
            SensorKind::Digit => Markers::No,
            SensorKind::Generic => Markers::Unknown,
        }
    }

    pub fn spec(self) -> SensorSpec {
        match self {
            // Native stream: MJPG 3280x2464 @ 25 fps only; the vendor pipeline crops a border and
            // resizes to 320x240, ~0.0634 mm/px at that size.
            SensorKind::GelsightMini => SensorSpec {
                kind: self,
                native_width: 3280,
                native_height: 2464,
                width: 320,
                height: 240,
                fps: 25.0,
                mm_per_px: 0.0634,
            },
            // QVGA 320x240 @ 60/30 fps or VGA 640x480 @ 30/15 fps; ~0.0405 mm/px.
            SensorKind::Digit => SensorSpec {
                kind: self,
                native_width: 320,
                native_height: 240,
                width: 320,
                height: 240,
                fps: 60.0,
                mm_per_px: 0.0405,
            },
            SensorKind::Generic => SensorSpec {
                kind: self,
                native_width: 320,
                native_height: 240,
                width: 320,
                height: 240,
                fps: 30.0,
                mm_per_px: 0.05,
            },
        }
    }
}

/// Whether a sensor kind's gel carries marker dots ([`SensorKind::markers`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Markers {
    Yes,
    No,
    Unknown,
}

impl fmt::Display for SensorKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// A sensor kind name that is none of [`SensorKind::ALL`].
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown sensor kind '{0}' (known: gelsight-mini, digit, generic)")]
pub struct UnknownSensorKind(pub String);

impl FromStr for SensorKind {
    type Err = UnknownSensorKind;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        SensorKind::ALL
            .into_iter()
            .find(|k| k.as_str() == s)
            .ok_or_else(|| UnknownSensorKind(s.to_string()))
    }
}

/// What the rest of the stack needs to know about a sensor's output.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SensorSpec {
    pub kind: SensorKind,
    /// Size the camera streams at.
    pub native_width: u32,
    pub native_height: u32,
    /// Size of the frames the driver publishes (after crop and resize).
    pub width: u32,
    pub height: u32,
    pub fps: f64,
    /// Gel-surface millimetres per published pixel.
    pub mm_per_px: f64,
}

impl SensorSpec {
    pub fn mm2_per_px(&self) -> f64 {
        self.mm_per_px * self.mm_per_px
    }

    /// The same sensor publishing `scale` times the width and height over the same field of
    /// view (e.g. GelSight Mini at 640x480: `scaled(2)`).
    pub fn scaled(self, scale: u32) -> Self {
        SensorSpec {
            width: self.width * scale,
            height: self.height * scale,
            mm_per_px: self.mm_per_px / f64::from(scale),
            ..self
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scaled_keeps_the_field_of_view() {
        let s = SensorKind::GelsightMini.spec();
        let d = s.scaled(2);
        assert_eq!((d.width, d.height), (640, 480));
        let fov = |s: SensorSpec| {
            (
                f64::from(s.width) * s.mm_per_px,
                f64::from(s.height) * s.mm_per_px,
            )
        };
        assert_eq!(fov(d), fov(s));
        assert_eq!(
            (d.kind, d.fps, d.native_width),
            (s.kind, s.fps, s.native_width)
        );
        assert_eq!(s.scaled(1), s);
    }

    #[test]
    fn names_round_trip() {
        for k in SensorKind::ALL {
            assert_eq!(k.as_str().parse::<SensorKind>(), Ok(k));
        }
        assert!("kinect".parse::<SensorKind>().is_err());
    }

    #[test]
    fn gelsight_streams_only_full_size() {
        let s = SensorKind::GelsightMini.spec();
        assert_eq!((s.native_width, s.native_height), (3280, 2464));
        assert_eq!((s.width, s.height), (320, 240));
    }
}
