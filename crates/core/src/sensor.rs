//! Sensor kinds as data: a sensor kind is one file, `sensors/<name>.yaml`, with what differs
//! between kinds (image size and crop, mm per pixel, markers, the camera settings and LED control,
//! how its USB device is recognised, the mock sensor's lighting, its URDF macro) and where each
//! figure comes from. The driver, the contact stage, the mock sensor and the launch planner read
//! the profile; no code asks which kind a sensor is.
//!
//! The shipped files are checked and compiled in at build time (crates/core/build.rs: a broken
//! file fails the build); a directory in `UNITAC_SENSORS` adds kinds at run time, read once per
//! process (a file there replaces a shipped kind of the same name). [`SensorKind`] is a copyable
//! handle to a profile, compared, hashed and serialized by its name.

#[path = "../build/sensor_profile.rs"]
mod raw;

use serde::{Deserialize, Deserializer, Serialize, Serializer};
use std::fmt;
use std::hash::{Hash, Hasher};
use std::path::{Path, PathBuf};
use std::str::FromStr;
use std::sync::OnceLock;

/// Largest profile file read \[bytes], and most files read from `UNITAC_SENSORS`.
pub const MAX_PROFILE_BYTES: usize = 64 << 10;
pub const MAX_PROFILES: usize = 64;

/// One sensor kind (module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct SensorProfile {
    pub name: &'static str,
    pub description: &'static str,
    /// Size the camera streams at, and the size the driver publishes.
    pub native: [u32; 2],
    pub size: [u32; 2],
    pub fps: f64,
    /// Gel-surface millimetres per published pixel.
    pub mm_per_px: f64,
    pub markers: Markers,
    /// Fraction of the width and height cut from each side before the resize.
    pub crop: f64,
    /// Largest upscale of the decoded crop to the output size.
    pub max_upscale: f64,
    /// The camera settings written at open (a calibration file may override them).
    pub camera: CameraDefaults,
    pub led: LedControl,
    /// How its USB device is recognised (None: only by an explicit choice).
    pub usb: Option<UsbMatch>,
    /// The mock sensor's lit gel, R, G, B.
    pub mock_light: [LightChannel; 3],
    /// Its URDF macro (`urdf/<urdf>.urdf.xacro`).
    pub urdf: Option<&'static str>,
    /// Its default photometric model, for a unit not yet calibrated.
    pub photometric: Option<Photometric>,
    /// The gel's published figures.
    pub gel: Option<Gel>,
    /// How the gel is lit, in words, with the source.
    pub lights: Option<&'static str>,
}

/// A gel's published figures.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Gel {
    /// Thickness of the elastomer \[mm].
    pub thickness_mm: Option<f64>,
    /// Durometer, with its scale ("Shore 00-55").
    pub hardness: Option<&'static str>,
    /// Where the figures are published.
    pub source: &'static str,
}

/// A linear photometric model: the gel's slope from its colour change (the contact stage's depth
/// before a unit has its own calibration).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Photometric {
    /// dh/dx and dh/dy (depth per length, h into the gel) per DN of the shading-corrected colour
    /// change (dR, dG, dB).
    pub slope_per_dn: [[f32; 3]; 2],
    /// Radius of the ball of the presses it was fitted on \[m].
    pub ball_radius_m: f64,
    /// Which presses it was fitted on, and how.
    pub source: &'static str,
}

/// The camera settings a kind opens with.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct CameraDefaults {
    /// Manual exposure in 100 us units.
    pub exposure: Option<u32>,
    pub white_balance_k: Option<u32>,
    pub gain: Option<u32>,
    /// LED levels R, G, B (0..=15).
    pub led: Option<[u8; 3]>,
}

/// How a kind's LEDs are set.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LedControl {
    None,
    /// DIGIT: the V4L2 zoom control carries (r << 8) | (g << 4) | b from firmware 200.
    Digit,
}

/// How a kind's USB device is recognised and where its serial is.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct UsbMatch {
    /// (vendor, product) ids.
    pub id: [u16; 2],
    /// The ids of its firmware-update mode.
    pub dfu_id: Option<[u16; 2]>,
    /// The product name must start with this.
    pub product_prefix: Option<&'static str>,
    /// `A` stands for A-Z or 0-9, anything else for itself; None: any serial (and a device
    /// without one is still the kind).
    pub serial_pattern: Option<&'static str>,
    /// Where the serial is read, first match wins.
    pub serial_from: &'static [SerialFrom],
}

/// Where a serial number is read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SerialFrom {
    UsbSerial,
    /// The product name's last word ("GelSight Mini R0B 28J3-CWXU").
    ProductLastWord,
}

impl UsbMatch {
    /// Whether `s` is a serial of this kind.
    pub fn serial_ok(&self, s: &str) -> bool {
        let Some(p) = self.serial_pattern else {
            return !s.is_empty();
        };
        s.len() == p.len()
            && s.bytes().zip(p.bytes()).all(|(c, want)| match want {
                b'A' => c.is_ascii_uppercase() || c.is_ascii_digit(),
                _ => c == want,
            })
    }
}

/// One channel of the mock sensor's lit gel: `base + gain x term(u, v)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LightChannel {
    pub base: f32,
    pub gain: f32,
    pub term: LightTerm,
}

/// The shape of a channel's gradient over the image (u, v in [0, 1) from the left and the top).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LightTerm {
    U,
    V,
    OneMinusU,
    OneMinusV,
    VOneMinusU,
}

impl LightChannel {
    /// The channel's level at (u, v), before the vignette.
    pub fn at(&self, u: f32, v: f32) -> f32 {
        let g = self.gain;
        self.base
            + match self.term {
                LightTerm::U => g * u,
                LightTerm::V => g * v,
                LightTerm::OneMinusU => g * (1.0 - u),
                LightTerm::OneMinusV => g * (1.0 - v),
                LightTerm::VOneMinusU => g * v * (1.0 - u),
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

include!(concat!(env!("OUT_DIR"), "/sensors_generated.rs"));

/// A sensor kind: a handle to its profile.
#[derive(Clone, Copy)]
pub struct SensorKind(&'static SensorProfile);

impl SensorKind {
    pub fn as_str(self) -> &'static str {
        self.0.name
    }
    pub fn profile(self) -> &'static SensorProfile {
        self.0
    }

    /// Whether the gel carries marker dots (GelSight Mini: a printed dot grid; DIGIT: none;
    /// a generic gel: not known). The contact stage masks them by default where there are some,
    /// the slip stage refuses a gel without them, the mock sensor draws them where there are.
    pub fn markers(self) -> Markers {
        self.0.markers
    }

    pub fn spec(self) -> SensorSpec {
        let p = self.0;
        SensorSpec {
            kind: self,
            native_width: p.native[0],
            native_height: p.native[1],
            width: p.size[0],
            height: p.size[1],
            fps: p.fps,
            mm_per_px: p.mm_per_px,
        }
    }

    /// Every known kind: the shipped ones and those of `UNITAC_SENSORS`, sorted by name.
    pub fn all() -> &'static [SensorKind] {
        &registry().0
    }
}

impl PartialEq for SensorKind {
    fn eq(&self, other: &Self) -> bool {
        self.0.name == other.0.name
    }
}
impl Eq for SensorKind {}
impl Hash for SensorKind {
    fn hash<H: Hasher>(&self, h: &mut H) {
        self.0.name.hash(h);
    }
}
impl fmt::Debug for SensorKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.0.name)
    }
}
impl fmt::Display for SensorKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}
impl Serialize for SensorKind {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.0.name)
    }
}
impl<'de> Deserialize<'de> for SensorKind {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let s = String::deserialize(d)?;
        s.parse().map_err(serde::de::Error::custom)
    }
}

/// A sensor kind name that is no known kind, or a `UNITAC_SENSORS` file that is no profile.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum UnknownSensorKind {
    #[error("unknown sensor kind '{name}' (known: {known})")]
    Unknown { name: String, known: String },
    #[error("sensor profile {path}: {msg}")]
    Bad { path: String, msg: String },
}

impl FromStr for SensorKind {
    type Err = UnknownSensorKind;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let (all, err) = registry();
        if let Some(e) = err {
            return Err(e.clone());
        }
        all.iter()
            .find(|k| k.as_str() == s)
            .copied()
            .ok_or_else(|| UnknownSensorKind::Unknown {
                name: s.chars().take(64).collect(),
                known: all
                    .iter()
                    .map(|k| k.as_str())
                    .collect::<Vec<_>>()
                    .join(", "),
            })
    }
}

impl SensorProfile {
    /// A profile from `text`, the file `path` (its stem must be the kind's name). Its strings are
    /// leaked: bounded, at most [`MAX_PROFILES`] small files per process.
    pub fn parse(text: &str, path: &Path) -> Result<SensorProfile, UnknownSensorKind> {
        let bad = |msg: String| UnknownSensorKind::Bad {
            path: path.display().to_string(),
            msg,
        };
        crate::yaml::check(text, MAX_PROFILE_BYTES).map_err(|e| bad(e.to_string()))?;
        let r: raw::RawSensor = serde_yaml::from_str(text).map_err(|e| bad(e.to_string()))?;
        let stem = path.file_stem().and_then(|s| s.to_str()).unwrap_or("");
        let problems = r.problems(stem);
        if !problems.is_empty() {
            return Err(bad(problems.join("; ")));
        }
        let leak = |s: String| -> &'static str { Box::leak(s.into_boxed_str()) };
        let term = |t: &str| match t {
            "u" => LightTerm::U,
            "v" => LightTerm::V,
            "1-u" => LightTerm::OneMinusU,
            "1-v" => LightTerm::OneMinusV,
            _ => LightTerm::VOneMinusU,
        };
        let light = |(base, gain, t): &(f32, f32, String)| LightChannel {
            base: *base,
            gain: *gain,
            term: term(t),
        };
        let [r0, r1, r2] = &r.mock_light;
        Ok(SensorProfile {
            name: leak(r.name),
            description: leak(r.description),
            native: r.native,
            size: r.size,
            fps: r.fps,
            mm_per_px: r.mm_per_px,
            markers: match r.markers.as_str() {
                "yes" => Markers::Yes,
                "no" => Markers::No,
                _ => Markers::Unknown,
            },
            crop: r.crop,
            max_upscale: r.max_upscale,
            camera: CameraDefaults {
                exposure: r.camera.exposure,
                white_balance_k: r.camera.white_balance_k,
                gain: r.camera.gain,
                led: r.camera.led,
            },
            led: if r.led == "digit" {
                LedControl::Digit
            } else {
                LedControl::None
            },
            usb: r.usb.map(|u| UsbMatch {
                id: u.id,
                dfu_id: u.dfu_id,
                product_prefix: u.product_prefix.map(leak),
                serial_pattern: u.serial.pattern.map(leak),
                serial_from: Box::leak(
                    u.serial
                        .from
                        .iter()
                        .map(|f| {
                            if f == "usb_serial" {
                                SerialFrom::UsbSerial
                            } else {
                                SerialFrom::ProductLastWord
                            }
                        })
                        .collect::<Vec<_>>()
                        .into_boxed_slice(),
                ),
            }),
            mock_light: [light(r0), light(r1), light(r2)],
            urdf: r.urdf.map(leak),
            photometric: r.photometric.map(|m| Photometric {
                slope_per_dn: m.slope_per_dn,
                ball_radius_m: m.ball_radius_m,
                source: leak(m.source),
            }),
            gel: r.gel.map(|g| Gel {
                thickness_mm: g.thickness_mm,
                hardness: g.hardness.map(leak),
                source: leak(g.source),
            }),
            lights: r.lights.map(leak),
        })
    }
}

/// The profiles in `dir` (`*.yaml`, sorted by name).
pub fn read_dir(dir: &Path) -> Result<Vec<SensorProfile>, UnknownSensorKind> {
    let err = |path: &Path, msg: String| UnknownSensorKind::Bad {
        path: path.display().to_string(),
        msg,
    };
    let mut paths: Vec<PathBuf> = Vec::new();
    for e in std::fs::read_dir(dir).map_err(|e| err(dir, e.to_string()))? {
        let p = e.map_err(|e| err(dir, e.to_string()))?.path();
        if p.extension().is_some_and(|x| x == "yaml") {
            paths.push(p);
            if paths.len() > MAX_PROFILES {
                return Err(err(dir, format!("more than {MAX_PROFILES} .yaml files")));
            }
        }
    }
    paths.sort();
    let mut out = Vec::new();
    for p in paths {
        let len = std::fs::metadata(&p)
            .map_err(|e| err(&p, e.to_string()))?
            .len();
        if len > MAX_PROFILE_BYTES as u64 {
            return Err(err(
                &p,
                format!("{len} bytes, more than {MAX_PROFILE_BYTES}"),
            ));
        }
        let text = std::fs::read_to_string(&p).map_err(|e| err(&p, e.to_string()))?;
        out.push(SensorProfile::parse(&text, &p)?);
    }
    Ok(out)
}

/// Every kind (shipped, then `UNITAC_SENSORS`' replacing or adding, sorted by name), and the
/// error of a `UNITAC_SENSORS` directory that could not be read (its kinds are then absent).
fn registry() -> &'static (Vec<SensorKind>, Option<UnknownSensorKind>) {
    static ALL: OnceLock<(Vec<SensorKind>, Option<UnknownSensorKind>)> = OnceLock::new();
    ALL.get_or_init(|| {
        let mut all: Vec<SensorKind> = SensorKind::SHIPPED.to_vec();
        let mut error = None;
        if let Some(dir) = std::env::var_os("UNITAC_SENSORS") {
            match read_dir(Path::new(&dir)) {
                Ok(ps) => {
                    for p in ps {
                        all.retain(|k| k.as_str() != p.name);
                        all.push(SensorKind(Box::leak(Box::new(p))));
                    }
                }
                Err(e) => error = Some(e),
            }
        }
        all.sort_by(|a, b| a.as_str().cmp(b.as_str()));
        (all, error)
    })
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
    /// Gel-surface millimetres per published pixel (the device's figure, as its profile and
    /// calibration give it; [`SensorSpec::m_per_px`] is the same in SI).
    pub mm_per_px: f64,
}

impl SensorSpec {
    /// Gel-surface metres per published pixel: the one conversion of the device's mm figure.
    pub fn m_per_px(&self) -> f64 {
        self.mm_per_px * 1e-3
    }
    /// Gel-surface square metres per published pixel.
    pub fn m2_per_px(&self) -> f64 {
        self.m_per_px() * self.m_per_px()
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
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn scaled_keeps_the_field_of_view() {
        let s = SensorKind::GELSIGHT_MINI.spec();
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
        for k in SensorKind::SHIPPED {
            assert_eq!(k.as_str().parse::<SensorKind>(), Ok(k));
        }
        assert_eq!(
            "kinect".parse::<SensorKind>().unwrap_err().to_string(),
            "unknown sensor kind 'kinect' (known: digit, gelsight-2017, gelsight-mini, generic)"
        );
    }

    #[test]
    fn a_broken_profile_names_every_problem() {
        let text = "{name: x, description: d, native: [0, 1], size: [320, 240], fps: .nan, \
                    mm_per_px: 0.05, markers: maybe, crop: 0.6, max_upscale: 1, led: rgb, \
                    mock_light: [[1, 2, u], [1, 2, w], [1, 2, v]], \
                    photometric: {slope_per_dn: [[0, 0, 0], [0, 0, 0]], ball_radius_m: 2, \
                    source: ''}, gel: {thickness_mm: -1, hardness: '', source: s}, lights: ''}";
        let e = SensorProfile::parse(text, Path::new("/p/y.yaml"))
            .unwrap_err()
            .to_string();
        for want in [
            "/p/y.yaml",
            "not the file's name",
            "native = [0, 1]",
            "fps = NaN",
            "markers \"maybe\"",
            "crop = 0.6",
            "led \"rgb\"",
            "mock_light[1]",
            "photometric.slope_per_dn is all zero",
            "photometric.ball_radius_m = 2",
            "photometric.source is not 1 to",
            "gel.thickness_mm = -1 is not",
            "gel.hardness is not",
            "lights is not",
        ] {
            assert!(e.contains(want), "{want}: {e}");
        }
    }

    #[test]
    fn a_photometric_model_is_read_and_bounded() {
        let head = "{name: y, description: d, native: [320, 240], size: [320, 240], fps: 30, \
                    mm_per_px: 0.05, markers: no, crop: 0, max_upscale: 1, led: none, \
                    mock_light: [[1, 2, u], [1, 2, v], [1, 2, u]]";
        let with = |slopes: &str| {
            format!(
                "{head}, photometric: {{slope_per_dn: {slopes}, ball_radius_m: 0.002, source: s}}}}"
            )
        };
        let p = SensorProfile::parse(
            &with("[[1e-3, 0, -1e-3], [0, 2e-3, 0]]"),
            Path::new("y.yaml"),
        )
        .unwrap();
        let m = p.photometric.unwrap();
        assert_eq!(m.slope_per_dn, [[1e-3, 0.0, -1e-3], [0.0, 2e-3, 0.0]]);
        assert_eq!((m.ball_radius_m, m.source), (0.002, "s"));
        let e = SensorProfile::parse(&with("[[1e-3, .nan, 0], [0, 5, 0]]"), Path::new("y.yaml"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("photometric.slope_per_dn"), "{e}");
        let none = SensorProfile::parse(&format!("{head}}}"), Path::new("y.yaml")).unwrap();
        assert_eq!(none.photometric, None);
        // GelSight Mini's gel as its vendor publishes it.
        let gel = SensorKind::GELSIGHT_MINI.profile().gel.unwrap();
        assert_eq!(
            (gel.thickness_mm, gel.hardness),
            (Some(4.25), Some("Shore 00-55"))
        );
        // The shipped kinds: GelSight Mini has one (fitted on real presses), the others none.
        assert!(SensorKind::GELSIGHT_MINI.profile().photometric.is_some());
        assert!(SensorKind::DIGIT.profile().photometric.is_none());
        assert!(SensorKind::GENERIC.profile().photometric.is_none());
        assert!(SensorKind::GELSIGHT_2017.profile().photometric.is_none());
    }

    #[test]
    fn gelsight_streams_only_full_size() {
        let s = SensorKind::GELSIGHT_MINI.spec();
        assert_eq!((s.native_width, s.native_height), (3280, 2464));
        assert_eq!((s.width, s.height), (320, 240));
    }
}
