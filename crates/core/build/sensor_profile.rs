//! A sensor profile file as written (`sensors/<name>.yaml`) and its checks: shared by the build
//! script, which turns the shipped files into constants, and by `unitac_core::sensor`, which
//! reads a user's files at run time.

use serde::Deserialize;

/// One profile file, as parsed.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawSensor {
    /// The kind's name: the file's stem, and what `--sensor` and scenes take.
    pub name: String,
    pub description: String,
    /// Size the camera streams at, and the size the driver publishes (after crop and resize).
    pub native: [u32; 2],
    pub size: [u32; 2],
    pub fps: f64,
    /// Gel-surface millimetres per published pixel.
    pub mm_per_px: f64,
    /// `yes` | `no` | `unknown`: whether the gel carries marker dots.
    pub markers: String,
    /// Fraction of the width and height cut from each side before the resize.
    pub crop: f64,
    /// Largest upscale of the decoded crop to the output size.
    pub max_upscale: f64,
    /// The camera settings written at open (a calibration file may override them).
    #[serde(default)]
    pub camera: RawCamera,
    /// `none` | `digit`: how the LED colour is written (`digit`: the zoom control).
    pub led: String,
    /// How the USB device is recognised (none: only by an explicit choice).
    #[serde(default)]
    pub usb: Option<RawUsb>,
    /// The mock sensor's lit gel, per channel (R, G, B): `[base, gain, term]`, the channel's
    /// level `base + gain x term` with term one of `u`, `v`, `1-u`, `1-v`, `v(1-u)` (u, v in
    /// [0, 1) from the left and the top), before the vignette.
    pub mock_light: [(f32, f32, String); 3],
    /// The URDF macro (urdf/<urdf>.urdf.xacro, macro `<urdf>`) of its frames.
    #[serde(default)]
    pub urdf: Option<String>,
    /// The kind's default photometric model, for a unit not yet calibrated (none: no real
    /// presses of the kind were measured).
    #[serde(default)]
    pub photometric: Option<RawPhotometric>,
    /// The gel, where its figures are published.
    #[serde(default)]
    pub gel: Option<RawGel>,
    /// How the gel is lit, in words, with the source.
    #[serde(default)]
    pub lights: Option<String>,
}

/// A gel's published figures.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawGel {
    /// Thickness of the elastomer \[mm].
    #[serde(default)]
    pub thickness_mm: Option<f64>,
    /// Durometer, with its scale ("Shore 00-55", "Shore 10A").
    #[serde(default)]
    pub hardness: Option<String>,
    /// Where the figures are published.
    pub source: String,
}

/// A linear photometric model: the gel's slope from its colour change.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawPhotometric {
    /// dh/dx and dh/dy (depth per length, h into the gel) per DN of the shading-corrected colour
    /// change (dR, dG, dB), as `unitac calibrate depth --linear` prints it.
    pub slope_per_dn: [[f32; 3]; 2],
    /// Radius of the ball of those presses \[m].
    pub ball_radius_m: f64,
    /// Which presses it was fitted on, and how.
    pub source: String,
}

#[derive(Debug, Clone, PartialEq, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawCamera {
    #[serde(default)]
    pub exposure: Option<u32>,
    #[serde(default)]
    pub white_balance_k: Option<u32>,
    #[serde(default)]
    pub gain: Option<u32>,
    #[serde(default)]
    pub led: Option<[u8; 3]>,
}

#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawUsb {
    /// (vendor, product) ids.
    pub id: [u16; 2],
    /// The ids of its firmware-update mode.
    #[serde(default)]
    pub dfu_id: Option<[u16; 2]>,
    /// The product name must start with this.
    #[serde(default)]
    pub product_prefix: Option<String>,
    pub serial: RawSerial,
}

#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawSerial {
    /// `A` stands for A-Z or 0-9, anything else for itself; without one, any serial.
    #[serde(default)]
    pub pattern: Option<String>,
    /// Where the serial is read, first match wins: `usb_serial`, `product_last_word`.
    pub from: Vec<String>,
}

/// Longest name, description and pattern accepted.
pub const MAX_NAME: usize = 64;
pub const MAX_TEXT: usize = 256;
/// Largest image side and frame rate a profile may state.
pub const MAX_SIDE: u32 = 8192;
pub const MAX_FPS: f64 = 1000.0;
pub const MARKERS: [&str; 3] = ["yes", "no", "unknown"];
pub const LEDS: [&str; 2] = ["none", "digit"];
pub const LIGHT_TERMS: [&str; 5] = ["u", "v", "1-u", "1-v", "v(1-u)"];
pub const SERIAL_FROM: [&str; 2] = ["usb_serial", "product_last_word"];
/// Largest slope per DN of colour change a photometric model may state (one DN tilting the gel
/// by 45 degrees).
pub const MAX_SLOPE_PER_DN: f32 = 1.0;

/// Whether `s` is 1 to `max` bytes.
fn sized(s: &str, max: usize) -> bool {
    !s.is_empty() && s.len() <= max
}

fn ident(s: &str, extra: char) -> bool {
    !s.is_empty()
        && s.len() <= MAX_NAME
        && s.chars()
            .all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == extra)
}

impl RawSensor {
    /// Every broken rule (empty: none).
    pub fn problems(&self, stem: &str) -> Vec<String> {
        let mut p = Vec::new();
        if !ident(&self.name, '-') {
            p.push(format!(
                "name {:?} is not 1 to {MAX_NAME} of a-z, 0-9, -",
                self.name
            ));
        } else if self.name != stem {
            p.push(format!(
                "name {:?} is not the file's name {stem:?}",
                self.name
            ));
        }
        if self.description.len() > MAX_TEXT {
            p.push(format!("description is longer than {MAX_TEXT} bytes"));
        }
        for (what, [w, h]) in [("native", self.native), ("size", self.size)] {
            if !(1..=MAX_SIDE).contains(&w) || !(1..=MAX_SIDE).contains(&h) {
                p.push(format!("{what} = [{w}, {h}] is not within 1..={MAX_SIDE}"));
            }
        }
        if !(self.fps.is_finite() && self.fps > 0.0 && self.fps <= MAX_FPS) {
            p.push(format!("fps = {} is not in (0, {MAX_FPS}]", self.fps));
        }
        if !(self.mm_per_px.is_finite() && self.mm_per_px > 0.0 && self.mm_per_px < 10.0) {
            p.push(format!("mm_per_px = {} is not in (0, 10)", self.mm_per_px));
        }
        if !MARKERS.contains(&self.markers.as_str()) {
            p.push(format!(
                "markers {:?} is not one of {MARKERS:?}",
                self.markers
            ));
        }
        if !(self.crop.is_finite() && (0.0..0.5).contains(&self.crop)) {
            p.push(format!("crop = {} is not in [0, 0.5)", self.crop));
        }
        if !(self.max_upscale.is_finite() && (1.0..=8.0).contains(&self.max_upscale)) {
            p.push(format!(
                "max_upscale = {} is not in [1, 8]",
                self.max_upscale
            ));
        }
        let c = &self.camera;
        if c.exposure.is_some_and(|e| !(1..=100_000).contains(&e)) {
            p.push("camera.exposure is outside 1..=100000 (100 us units)".into());
        }
        if c.white_balance_k
            .is_some_and(|k| !(1000..=10_000).contains(&k))
        {
            p.push("camera.white_balance_k is outside 1000..=10000".into());
        }
        if c.gain.is_some_and(|g| g > 1000) {
            p.push("camera.gain is above 1000".into());
        }
        if c.led.is_some_and(|l| l.iter().any(|v| *v > 15)) {
            p.push("camera.led has a level above 15".into());
        }
        if !LEDS.contains(&self.led.as_str()) {
            p.push(format!("led {:?} is not one of {LEDS:?}", self.led));
        } else if c.led.is_some() && self.led == "none" {
            p.push("camera.led is set but led is none".into());
        }
        if let Some(u) = &self.usb {
            if u.product_prefix
                .as_ref()
                .is_some_and(|s| s.len() > MAX_TEXT)
            {
                p.push(format!(
                    "usb.product_prefix is longer than {MAX_TEXT} bytes"
                ));
            }
            if u.serial
                .pattern
                .as_ref()
                .is_some_and(|s| !sized(s, MAX_NAME))
            {
                p.push(format!("usb.serial.pattern is not 1 to {MAX_NAME} bytes"));
            }
            if u.serial.from.is_empty()
                || u.serial.from.len() > SERIAL_FROM.len()
                || u.serial
                    .from
                    .iter()
                    .any(|f| !SERIAL_FROM.contains(&f.as_str()))
            {
                p.push(format!(
                    "usb.serial.from {:?} is not a list of {SERIAL_FROM:?}",
                    u.serial.from
                ));
            }
        }
        for (i, (base, gain, term)) in self.mock_light.iter().enumerate() {
            if !(base.is_finite() && gain.is_finite() && LIGHT_TERMS.contains(&term.as_str())) {
                p.push(format!(
                    "mock_light[{i}] = [{base}, {gain}, {term:?}]: finite base and gain, a term of {LIGHT_TERMS:?}"
                ));
            }
        }
        if let Some(m) = &self.photometric {
            let s = m.slope_per_dn;
            if !s
                .iter()
                .flatten()
                .all(|k| k.is_finite() && k.abs() < MAX_SLOPE_PER_DN)
            {
                p.push(format!(
                    "photometric.slope_per_dn = {s:?}: finite, each below {MAX_SLOPE_PER_DN} in size"
                ));
            }
            if s.iter().all(|row| row.iter().all(|k| *k == 0.0)) {
                p.push("photometric.slope_per_dn is all zero".into());
            }
            if !(m.ball_radius_m.is_finite() && m.ball_radius_m > 0.0 && m.ball_radius_m < 0.1) {
                p.push(format!(
                    "photometric.ball_radius_m = {} is not in (0, 0.1)",
                    m.ball_radius_m
                ));
            }
            if !sized(&m.source, MAX_TEXT) {
                p.push(format!("photometric.source is not 1 to {MAX_TEXT} bytes"));
            }
        }
        if let Some(g) = &self.gel {
            if let Some(t) = g
                .thickness_mm
                .filter(|t| !(t.is_finite() && *t > 0.0 && *t < 50.0))
            {
                p.push(format!("gel.thickness_mm = {t} is not in (0, 50)"));
            }
            if g.hardness.as_ref().is_some_and(|h| !sized(h, MAX_NAME)) {
                p.push(format!("gel.hardness is not 1 to {MAX_NAME} bytes"));
            }
            if !sized(&g.source, MAX_TEXT) {
                p.push(format!("gel.source is not 1 to {MAX_TEXT} bytes"));
            }
        }
        if self.lights.as_ref().is_some_and(|l| !sized(l, MAX_TEXT)) {
            p.push(format!("lights is not 1 to {MAX_TEXT} bytes"));
        }
        if self.urdf.as_ref().is_some_and(|u| !ident(u, '_')) {
            p.push(format!(
                "urdf {:?} is not 1 to {MAX_NAME} of a-z, 0-9, _",
                self.urdf
            ));
        }
        p
    }
}
