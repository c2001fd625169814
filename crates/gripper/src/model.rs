//! The supported models: register family, defaults and the calibration of raw ranges to SI.
//!
//! Where each figure comes from (see the README's table): strokes, force and speed ranges are the
//! manufacturers' published specifications; the linear raw <-> SI maps between them, Robotiq's
//! fully-closed raw position and DH's percent scales are assumptions to check on the unit.

use crate::gripper::{Limits, Linear};
use serde::Serialize;
use std::fmt;
use std::str::FromStr;

/// Register family.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Family {
    /// Robotiq 2F: 0x03E8 command block, 0x07D0 status block, 0x17 read+write.
    Robotiq,
    /// DH Robotics AG/PGE: single-register writes at 0x01xx, status reads at 0x02xx.
    Dh,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Model {
    Robotiq2F85,
    Robotiq2F140,
    DhAg95,
    DhPge50,
}

/// Calibration of one model's raw registers.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Calibration {
    /// Raw position register <-> fingertip opening \[m].
    pub position: Linear,
    /// Raw speed register <-> opening speed [m/s].
    pub speed: Linear,
    /// Raw force register <-> grip force \[N].
    pub force: Linear,
    pub limits: Limits,
}

impl Model {
    pub const ALL: [Model; 4] = [
        Model::Robotiq2F85,
        Model::Robotiq2F140,
        Model::DhAg95,
        Model::DhPge50,
    ];
    pub fn name(self) -> &'static str {
        match self {
            Model::Robotiq2F85 => "robotiq_2f85",
            Model::Robotiq2F140 => "robotiq_2f140",
            Model::DhAg95 => "dh_ag95",
            Model::DhPge50 => "dh_pge50",
        }
    }
    pub fn family(self) -> Family {
        match self {
            Model::Robotiq2F85 | Model::Robotiq2F140 => Family::Robotiq,
            Model::DhAg95 | Model::DhPge50 => Family::Dh,
        }
    }
    /// Factory slave id (Robotiq manual: 9; DH manual: 1).
    pub fn default_slave(self) -> u8 {
        match self.family() {
            Family::Robotiq => 9,
            Family::Dh => 1,
        }
    }
    /// Factory line rate (both manuals: 115200 8N1).
    pub fn default_baud(self) -> u32 {
        115_200
    }
    pub fn calibration(self) -> Calibration {
        // (stroke m, min/max force N, min/max speed m/s): published specifications.
        let (stroke, fmin, fmax, vmin, vmax) = match self {
            Model::Robotiq2F85 => (0.085, 20.0, 235.0, 0.020, 0.150),
            Model::Robotiq2F140 => (0.140, 10.0, 125.0, 0.030, 0.250),
            // DH give an opening/closing time (0.7 s for the full stroke), not a speed: the top
            // speed here is stroke / 0.7 s.
            Model::DhAg95 => (0.095, 45.0, 160.0, 0.095 / 0.7 / 100.0, 0.095 / 0.7),
            Model::DhPge50 => (0.050, 15.0, 50.0, 0.050 / 0.7 / 100.0, 0.050 / 0.7),
        };
        let limits = Limits {
            max_opening_m: stroke,
            min_speed_m_s: vmin,
            max_speed_m_s: vmax,
            min_force_n: fmin,
            max_force_n: fmax,
        };
        match self.family() {
            // Assumption: raw 0 = fully open, 0xE3 = fingertips touching (units differ by a few
            // counts; calibrate), speed and force linear over 0..255.
            Family::Robotiq => Calibration {
                position: Linear::new(0.0, stroke, ROBOTIQ_CLOSED_RAW, 0.0),
                speed: Linear::new(0.0, vmin, 255.0, vmax),
                force: Linear::new(0.0, fmin, 255.0, fmax),
                limits,
            },
            // Position in per mille of the stroke, 1000 = open (manual); force 20..100 % and speed
            // 1..100 % mapped linearly onto the ranges (assumption).
            Family::Dh => Calibration {
                position: Linear::new(0.0, 0.0, 1000.0, stroke),
                speed: Linear::new(1.0, vmin, 100.0, vmax),
                force: Linear::new(20.0, fmin, 100.0, fmax),
                limits,
            },
        }
    }
}

/// Robotiq raw position at which the fingertips touch (assumption, see the README).
pub const ROBOTIQ_CLOSED_RAW: f64 = 227.0;

impl fmt::Display for Model {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A gripper model name that is none of [`Model::ALL`].
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown gripper model {name:?} (known: {known})", name = .0, known = known_models())]
pub struct UnknownModel(pub String);

fn known_models() -> String {
    let names: Vec<_> = Model::ALL.iter().map(|m| m.name()).collect();
    names.join(", ")
}

impl FromStr for Model {
    type Err = UnknownModel;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let k = s.to_ascii_lowercase().replace(['-', ' '], "_");
        Model::ALL
            .into_iter()
            .find(|m| m.name() == k || m.name().replace('_', "") == k.replace('_', ""))
            .ok_or_else(|| UnknownModel(s.to_string()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_parse_back() {
        for m in Model::ALL {
            assert_eq!(m.name().parse::<Model>().unwrap(), m);
        }
        assert_eq!("Robotiq-2F85".parse::<Model>().unwrap(), Model::Robotiq2F85);
        assert!(
            "robotiq_3f"
                .parse::<Model>()
                .unwrap_err()
                .to_string()
                .contains("dh_ag95")
        );
    }

    #[test]
    fn calibrations_cover_the_limits() {
        for m in Model::ALL {
            let c = m.calibration();
            let l = c.limits;
            // Open and closed ends map inside the raw ranges and back within a count.
            for o in [0.0, l.max_opening_m] {
                let raw = c.position.to_raw(o);
                assert!((c.position.to_si(f64::from(raw)) - o).abs() < l.max_opening_m / 200.0);
            }
            assert!(
                (c.force.to_si(f64::from(c.force.to_raw(l.max_force_n))) - l.max_force_n).abs()
                    < 1.0
            );
            assert!(
                (c.speed.to_si(f64::from(c.speed.to_raw(l.min_speed_m_s))) - l.min_speed_m_s).abs()
                    < 1e-3
            );
        }
    }
}
