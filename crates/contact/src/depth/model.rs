//! The photometric model: colour change and position -> surface gradient, and its calibration
//! file.
//!
//! Per pixel, 18 features of the prepared difference d = (dR, dG, dB) / 32 (`prep`) and the
//! position (u, v) = (x / w - 1/2, y / h - 1/2): 1, d, the six products d_i d_j, u, v, u d, v d.
//! Two coefficient vectors give the slopes (dh/dx, dh/dy) of the gel's depth h (positive into the
//! gel, depth per length). Why this and not a lookup table or a network: a table of colour -> gradient
//! (gs_sdk's first method) needs its bins filled by presses, and 30-50 ball presses leave most of
//! a 3-D colour table empty; an MLP (gs_sdk's current method) needs a training loop and an
//! inference runtime per pixel. The quadratic in colour follows the gentle nonlinearity of a real
//! gel's shading, the position terms its uneven lighting, it is fitted in closed form by least
//! squares from a few thousand pixels per press, and it costs 36 multiply-adds a pixel.

use serde::{Deserialize, Serialize};
use std::path::Path;
use unitac_core::SensorKind;
use unitac_core::frame::MAX_SIDE;

pub const FEATURES: usize = 18;
/// The features of the colour change's linear terms, dR, dG, dB (a linear model's only ones).
pub const LINEAR_TERMS: std::ops::Range<usize> = 1..4;
/// Scale of the colour difference in the features \[1/DN].
pub const COLOUR_SCALE: f32 = 1.0 / 32.0;
/// Version of the calibration file format written: 2 holds lengths in metres; format 1 (the same
/// fields in millimetres, `mm_per_px` and `ball_radius_mm`) is still read and converted.
pub const FORMAT: u32 = 2;
/// Largest calibration file read \[bytes].
pub const MAX_FILE_BYTES: u64 = 1 << 20;

/// The features of one pixel.
#[inline]
pub fn features(d: &[f32], u: f32, v: f32) -> [f32; FEATURES] {
    let (r, g, b) = (
        d[0] * COLOUR_SCALE,
        d[1] * COLOUR_SCALE,
        d[2] * COLOUR_SCALE,
    );
    [
        1.0,
        r,
        g,
        b,
        r * r,
        g * g,
        b * b,
        r * g,
        r * b,
        g * b,
        u,
        v,
        u * r,
        u * g,
        u * b,
        v * r,
        v * g,
        v * b,
    ]
}

/// What went wrong with a calibration or its use.
#[derive(Debug, thiserror::Error)]
pub enum DepthError {
    #[error("calibration file {path}: {source}")]
    Io {
        path: String,
        #[source]
        source: std::io::Error,
    },
    #[error("calibration file {path}: {why}")]
    BadFile { path: String, why: String },
    #[error(
        "the calibration is for a {cal_w}x{cal_h} image; a {w}x{h} frame has another aspect ratio (another sensor or crop?)"
    )]
    SizeMismatch {
        cal_w: u32,
        cal_h: u32,
        w: u32,
        h: u32,
    },
    #[error("the calibration is for sensor {cal} but the frames come from {frame}")]
    SensorMismatch { cal: String, frame: String },
    #[error("frame is {w}x{h}, the background is {bw}x{bh}")]
    BackgroundSize { w: u32, h: u32, bw: u32, bh: u32 },
    #[error("calibration needs at least {need} usable presses, got {got}")]
    TooFewPresses { need: usize, got: usize },
    #[error("the least-squares fit is singular (presses too alike?)")]
    Singular,
}

/// What [`DepthCalibration::check`] refuses in a calibration file.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum CalibrationInvalid {
    #[error("format {0} (this build reads 1 and {FORMAT})")]
    Format(u32),
    #[error("image size {w}x{h}")]
    ImageSize { w: u32, h: u32 },
    #[error("m_per_px {0} is outside (0, {MAX_M_PER_PX})")]
    MPerPx(f64),
    #[error("ball radius {0} m is outside (0, {MAX_BALL_RADIUS_M})")]
    BallRadius(f64),
    #[error("format {format} needs the fields {fields}")]
    MissingFields { format: u32, fields: &'static str },
    #[error("the model has {gx} / {gy} coefficients, not {FEATURES}")]
    Coefficients { gx: usize, gy: usize },
    #[error("a model coefficient is not finite")]
    NotFinite,
    #[error("serial of {0} bytes, more than {MAX_SERIAL_BYTES}")]
    Serial(usize),
}

/// Largest gel-surface length per pixel a calibration may hold \[m] (10 mm).
pub const MAX_M_PER_PX: f64 = 0.01;
/// Largest calibration ball radius \[m] (0.1 m).
pub const MAX_BALL_RADIUS_M: f64 = 0.1;

/// Longest sensor serial a calibration file may carry.
pub const MAX_SERIAL_BYTES: usize = 128;

/// Colour and position -> gradient.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GradientModel {
    /// Coefficients of dh/dx and dh/dy over [`features`].
    pub gx: Vec<f32>,
    pub gy: Vec<f32>,
}

impl GradientModel {
    /// The linear model of `slope_per_dn`: dh/dx and dh/dy (depth per length) per DN of the
    /// shading-corrected colour change (dR, dG, dB), all other terms zero.
    pub fn linear(slope_per_dn: [[f32; 3]; 2]) -> Self {
        let row = |s: [f32; 3]| {
            let mut v = vec![0.0; FEATURES];
            v[LINEAR_TERMS].copy_from_slice(&s.map(|k| k / COLOUR_SCALE));
            v
        };
        Self {
            gx: row(slope_per_dn[0]),
            gy: row(slope_per_dn[1]),
        }
    }

    /// The slopes per DN of a linear model ([`linear`](Self::linear)); `None` when any other
    /// term is not zero.
    pub fn slope_per_dn(&self) -> Option<[[f32; 3]; 2]> {
        let linear = |v: &[f32]| {
            let others_zero = v
                .iter()
                .enumerate()
                .all(|(i, k)| LINEAR_TERMS.contains(&i) || *k == 0.0);
            let s: [f32; 3] = v.get(LINEAR_TERMS)?.try_into().ok()?;
            (v.len() == FEATURES && others_zero).then(|| s.map(|k| k * COLOUR_SCALE))
        };
        Some([linear(&self.gx)?, linear(&self.gy)?])
    }

    #[inline]
    pub fn eval(&self, f: &[f32; FEATURES]) -> (f32, f32) {
        let mut a = 0.0;
        let mut b = 0.0;
        for ((x, p), q) in f.iter().zip(&self.gx).zip(&self.gy) {
            a += x * p;
            b += x * q;
        }
        (a, b)
    }
}

/// A sensor's depth calibration (`unitac calibrate depth`), stored as JSON.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "StoredCalibration")]
pub struct DepthCalibration {
    /// [`FORMAT`] once read (a format 1 file is converted on reading).
    pub format: u32,
    pub sensor: SensorKind,
    /// The sensor's serial ("" when unknown: then any sensor of the kind is accepted).
    pub serial: String,
    /// Image size the calibration was made at.
    pub width: u32,
    pub height: u32,
    /// Gel-surface metres per pixel at that size.
    pub m_per_px: f64,
    /// Radius of the calibration ball \[m].
    pub ball_radius_m: f64,
    pub presses_used: u32,
    /// RMS slope error of the fit on the pixels inside the contacts (depth per length).
    pub fit_rms_slope: f64,
    pub model: GradientModel,
}

/// A calibration file as written by either format: format 2 in metres, format 1 in millimetres.
#[derive(Deserialize)]
struct StoredCalibration {
    format: u32,
    sensor: SensorKind,
    serial: String,
    width: u32,
    height: u32,
    #[serde(default)]
    m_per_px: Option<f64>,
    #[serde(default)]
    ball_radius_m: Option<f64>,
    #[serde(default)]
    mm_per_px: Option<f64>,
    #[serde(default)]
    ball_radius_mm: Option<f64>,
    presses_used: u32,
    fit_rms_slope: f64,
    model: GradientModel,
}

impl TryFrom<StoredCalibration> for DepthCalibration {
    type Error = CalibrationInvalid;

    fn try_from(s: StoredCalibration) -> Result<Self, Self::Error> {
        // The gradient model is a slope (depth per length): it needs no conversion.
        let (m_per_px, ball_radius_m) = match (
            s.format,
            s.m_per_px,
            s.ball_radius_m,
            s.mm_per_px,
            s.ball_radius_mm,
        ) {
            (FORMAT, Some(m), Some(r), None, None) => (m, r),
            (FORMAT, ..) => {
                return Err(CalibrationInvalid::MissingFields {
                    format: FORMAT,
                    fields: "m_per_px and ball_radius_m (and no mm fields)",
                });
            }
            (1, None, None, Some(mm), Some(r_mm)) => (mm * 1e-3, r_mm * 1e-3),
            (1, ..) => {
                return Err(CalibrationInvalid::MissingFields {
                    format: 1,
                    fields: "mm_per_px and ball_radius_mm (and no m fields)",
                });
            }
            (f, ..) => return Err(CalibrationInvalid::Format(f)),
        };
        Ok(Self {
            format: FORMAT,
            sensor: s.sensor,
            serial: s.serial,
            width: s.width,
            height: s.height,
            m_per_px,
            ball_radius_m,
            presses_used: s.presses_used,
            fit_rms_slope: s.fit_rms_slope,
            model: s.model,
        })
    }
}

impl DepthCalibration {
    /// Read and check a calibration file (size bounded, every number finite, lengths right).
    pub fn load(path: &Path) -> Result<Self, DepthError> {
        let p = path.display().to_string();
        let io = |source| DepthError::Io {
            path: p.clone(),
            source,
        };
        let meta = std::fs::metadata(path).map_err(io)?;
        if meta.len() > MAX_FILE_BYTES {
            return Err(DepthError::BadFile {
                path: p,
                why: format!("{} bytes, more than {MAX_FILE_BYTES}", meta.len()),
            });
        }
        let text = std::fs::read_to_string(path).map_err(io)?;
        let cal: Self = serde_json::from_str(&text).map_err(|e| DepthError::BadFile {
            path: p.clone(),
            why: e.to_string(),
        })?;
        cal.check().map_err(|e| DepthError::BadFile {
            path: p,
            why: e.to_string(),
        })?;
        Ok(cal)
    }

    /// Write as pretty JSON.
    pub fn save(&self, path: &Path) -> Result<(), DepthError> {
        let text = serde_json::to_string_pretty(self).map_err(|e| DepthError::BadFile {
            path: path.display().to_string(),
            why: e.to_string(),
        })?;
        std::fs::write(path, text + "\n").map_err(|source| DepthError::Io {
            path: path.display().to_string(),
            source,
        })
    }

    /// The checks [`load`](Self::load) runs.
    pub fn check(&self) -> Result<(), CalibrationInvalid> {
        if self.format != FORMAT {
            return Err(CalibrationInvalid::Format(self.format));
        }
        if self.width < 8 || self.height < 8 || self.width > MAX_SIDE || self.height > MAX_SIDE {
            return Err(CalibrationInvalid::ImageSize {
                w: self.width,
                h: self.height,
            });
        }
        if !(self.m_per_px.is_finite() && self.m_per_px > 0.0 && self.m_per_px < MAX_M_PER_PX) {
            return Err(CalibrationInvalid::MPerPx(self.m_per_px));
        }
        if !(self.ball_radius_m.is_finite()
            && self.ball_radius_m > 0.0
            && self.ball_radius_m < MAX_BALL_RADIUS_M)
        {
            return Err(CalibrationInvalid::BallRadius(self.ball_radius_m));
        }
        if self.model.gx.len() != FEATURES || self.model.gy.len() != FEATURES {
            return Err(CalibrationInvalid::Coefficients {
                gx: self.model.gx.len(),
                gy: self.model.gy.len(),
            });
        }
        if !self
            .model
            .gx
            .iter()
            .chain(&self.model.gy)
            .all(|v| v.is_finite())
        {
            return Err(CalibrationInvalid::NotFinite);
        }
        if self.serial.len() > MAX_SERIAL_BYTES {
            return Err(CalibrationInvalid::Serial(self.serial.len()));
        }
        Ok(())
    }

    /// Metres per pixel of a `w` x `h` frame of this sensor: the calibrated size scaled, when the
    /// frame covers the same field of view (same aspect ratio); another aspect ratio is an error.
    pub fn m_per_px_at(&self, w: u32, h: u32) -> Result<f64, DepthError> {
        if w == 0
            || h == 0
            || u64::from(w) * u64::from(self.height) != u64::from(h) * u64::from(self.width)
        {
            return Err(DepthError::SizeMismatch {
                cal_w: self.width,
                cal_h: self.height,
                w,
                h,
            });
        }
        Ok(self.m_per_px * f64::from(self.width) / f64::from(w))
    }

    /// The sensor kind's default (its profile's `photometric`, a linear model fitted on real
    /// presses of other units): depth before a unit has its own calibration. None for a kind
    /// without one.
    pub fn kind_default(kind: SensorKind) -> Option<Self> {
        let m = kind.profile().photometric?;
        let mut cal = Self::linear_for(kind, m.slope_per_dn);
        cal.ball_radius_m = m.ball_radius_m;
        Some(cal)
    }

    /// A placeholder for a model fitted on each frame itself (`super::selfcal`): the kind's
    /// size and scale, no slopes yet.
    pub fn self_calibrated(kind: SensorKind) -> Self {
        Self::linear_for(kind, [[0.0; 3]; 2])
    }

    /// A linear model at the kind's published size and scale, fitted on no press of a unit.
    fn linear_for(kind: SensorKind, slope_per_dn: [[f32; 3]; 2]) -> Self {
        let spec = kind.spec();
        Self {
            format: FORMAT,
            sensor: kind,
            serial: String::new(),
            width: spec.width,
            height: spec.height,
            m_per_px: spec.m_per_px(),
            ball_radius_m: 0.0,
            presses_used: 0,
            fit_rms_slope: 0.0,
            model: GradientModel::linear(slope_per_dn),
        }
    }

    /// Refuse frames from another sensor (when both serials are known).
    pub fn check_serial(&self, serial: &str) -> Result<(), DepthError> {
        if !self.serial.is_empty() && !serial.is_empty() && self.serial != serial {
            return Err(DepthError::SensorMismatch {
                cal: self.serial.clone(),
                frame: serial.to_string(),
            });
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn file(format: u32, lengths: &str) -> String {
        let k = vec!["0.5"; FEATURES].join(", ");
        format!(
            r#"{{"format": {format}, "sensor": "gelsight-mini", "serial": "", "width": 320,
                "height": 240, {lengths}, "presses_used": 30, "fit_rms_slope": 0.02,
                "model": {{"gx": [{k}], "gy": [{k}]}}}}"#
        )
    }

    #[test]
    fn a_format_1_file_reads_in_metres_and_writes_back_as_format_2() {
        let old = file(1, r#""mm_per_px": 0.0634, "ball_radius_mm": 2.0"#);
        let cal: DepthCalibration = serde_json::from_str(&old).unwrap();
        assert_eq!(cal.format, FORMAT);
        assert!((cal.m_per_px - 6.34e-5).abs() < 1e-15, "{}", cal.m_per_px);
        assert!((cal.ball_radius_m - 0.002).abs() < 1e-15);
        assert_eq!(cal.model.gx, vec![0.5; FEATURES], "slopes are unitless");
        cal.check().unwrap();
        let text = serde_json::to_string(&cal).unwrap();
        assert!(
            text.contains("\"m_per_px\"") && !text.contains("mm_per_px"),
            "{text}"
        );
        let again: DepthCalibration = serde_json::from_str(&text).unwrap();
        assert_eq!(again, cal);
        let new = file(2, r#""m_per_px": 6.34e-5, "ball_radius_m": 0.002"#);
        let cal2: DepthCalibration = serde_json::from_str(&new).unwrap();
        assert!((cal2.m_per_px - cal.m_per_px).abs() < 1e-15);
    }

    #[test]
    fn mixed_missing_or_unknown_formats_are_refused() {
        for (format, lengths, needle) in [
            (
                1,
                r#""m_per_px": 6.34e-5, "ball_radius_m": 0.002"#,
                "mm_per_px",
            ),
            (
                2,
                r#""mm_per_px": 0.0634, "ball_radius_mm": 2.0"#,
                "m_per_px",
            ),
            (
                2,
                r#""m_per_px": 6.34e-5, "ball_radius_mm": 2.0"#,
                "ball_radius_m",
            ),
            (
                3,
                r#""m_per_px": 6.34e-5, "ball_radius_m": 0.002"#,
                "format 3",
            ),
        ] {
            let err = serde_json::from_str::<DepthCalibration>(&file(format, lengths))
                .unwrap_err()
                .to_string();
            assert!(err.contains(needle), "{format} {lengths}: {err}");
        }
        // A format 1 file in mm read as if it were metres would be 1000x too coarse: refused.
        let cal: DepthCalibration =
            serde_json::from_str(&file(2, r#""m_per_px": 0.0634, "ball_radius_m": 2.0"#)).unwrap();
        assert_eq!(cal.check(), Err(CalibrationInvalid::MPerPx(0.0634)));
    }

    #[test]
    fn a_linear_model_reads_its_slopes_back_and_a_full_one_has_none() {
        let s = [
            [9.26e-4, -9.156e-3, 2.14e-3],
            [4.791e-3, 1.538e-3, -4.753e-3],
        ];
        let m = GradientModel::linear(s);
        assert_eq!(m.slope_per_dn(), Some(s));
        // A colour change of 10 DN in green alone: the slopes are 10 x its column.
        let (gx, gy) = m.eval(&features(&[0.0, 10.0, 0.0], 0.3, -0.2));
        assert!((gx - 10.0 * s[0][1]).abs() < 1e-7 && (gy - 10.0 * s[1][1]).abs() < 1e-7);
        let mut full = m.clone();
        full.gx[10] = 1e-3;
        assert_eq!(full.slope_per_dn(), None);
    }

    #[test]
    fn a_kinds_default_is_its_profiles_model_at_its_size() {
        let k = SensorKind::GELSIGHT_MINI;
        let cal = DepthCalibration::kind_default(k).unwrap();
        cal.check().unwrap();
        let p = k.profile().photometric.unwrap();
        assert_eq!(cal.model.slope_per_dn(), Some(p.slope_per_dn));
        assert_eq!((cal.width, cal.height), (320, 240));
        assert_eq!(cal.m_per_px, k.spec().m_per_px());
        assert_eq!(cal.serial, "", "any unit of the kind");
        assert!(DepthCalibration::kind_default(SensorKind::DIGIT).is_none());
    }
}
