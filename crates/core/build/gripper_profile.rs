//! A gripper profile file as written (`grippers/<name>.yaml`) and its checks: shared by the build
//! script, which turns the shipped files into constants, and by `unitac_core::profile`, which
//! reads a user's files at run time.

use serde::Deserialize;

/// One profile file, as parsed.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawGripper {
    /// The model's name: the file's stem, and what `--gripper` / the `model` parameter take.
    pub name: String,
    /// `robotiq` | `dh` (the register protocol of the serial driver) | `sim` (no device: the
    /// simulated task world's own gripper).
    pub family: String,
    /// Full stroke: the widest opening \[m].
    pub stroke_m: f64,
    /// Weakest and strongest grip \[N].
    pub force_n: [f64; 2],
    /// Slowest and fastest opening speed \[m/s].
    pub speed_m_s: [f64; 2],
    /// Factory Modbus slave id and line rate (serial families).
    #[serde(default)]
    pub slave: Option<u8>,
    #[serde(default)]
    pub baud: Option<u32>,
}

/// The families a profile may name.
pub const FAMILIES: [&str; 3] = ["robotiq", "dh", "sim"];
/// Longest name accepted.
pub const MAX_NAME: usize = 64;
/// Largest stroke \[m], force \[N] and speed \[m/s] a profile may state: far beyond any parallel
/// gripper, far inside what the register maps and the world can hold.
pub const MAX_STROKE_M: f64 = 1.0;
pub const MAX_FORCE_N: f64 = 10_000.0;
pub const MAX_SPEED_M_S: f64 = 10.0;

impl RawGripper {
    /// Every broken rule, `; `-separated (empty: none).
    pub fn problems(&self, stem: &str) -> Vec<String> {
        let mut p = Vec::new();
        let name_ok = !self.name.is_empty()
            && self.name.len() <= MAX_NAME
            && self
                .name
                .chars()
                .all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '_');
        if !name_ok {
            p.push(format!(
                "name {:?} is not 1 to {MAX_NAME} of a-z, 0-9, _",
                self.name
            ));
        } else if self.name != stem {
            p.push(format!(
                "name {:?} is not the file's name {stem:?}",
                self.name
            ));
        }
        if !FAMILIES.contains(&self.family.as_str()) {
            p.push(format!(
                "family {:?} is none of {}",
                self.family,
                FAMILIES.join(", ")
            ));
        }
        let positive = |v: f64| v.is_finite() && v > 0.0;
        if !(positive(self.stroke_m) && self.stroke_m <= MAX_STROKE_M) {
            p.push(format!(
                "stroke_m = {} must be in (0, {MAX_STROKE_M}]",
                self.stroke_m
            ));
        }
        for (what, [lo, hi], max) in [
            ("force_n", self.force_n, MAX_FORCE_N),
            ("speed_m_s", self.speed_m_s, MAX_SPEED_M_S),
        ] {
            if !(lo.is_finite()
                && hi.is_finite()
                && 0.0 <= lo
                && lo <= hi
                && positive(hi)
                && hi <= max)
            {
                p.push(format!(
                    "{what} = [{lo}, {hi}] must be finite with 0 <= min <= max, max in (0, {max}]"
                ));
            }
        }
        let serial = self.family != "sim";
        if serial && (self.slave.is_none() || self.baud.is_none()) {
            p.push(format!(
                "a {} gripper states its factory slave and baud",
                self.family
            ));
        }
        if self.slave == Some(0) || self.slave.is_some_and(|s| s > 247) {
            p.push("slave must be a Modbus unit id, 1 to 247".to_string());
        }
        if self.baud == Some(0) {
            p.push("baud must be > 0".to_string());
        }
        p
    }
}
