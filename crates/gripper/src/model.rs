//! The supported models: register family, defaults and the calibration of raw ranges to SI.
//!
//! A model is a gripper profile (`grippers/<name>.yaml`, `unitac_core::profile`: stroke, force and
//! speed ranges, family, factory slave id and line rate, each figure with its source) of a serial
//! family; a new model of a known family is a new file, no code. The linear raw <-> SI maps
//! between the ranges, Robotiq's fully-closed raw position and DH's percent scales are this
//! crate's, per family: assumptions to check on the unit (see the README's table).

use crate::gripper::{Limits, Linear};
use serde::Serialize;
use std::fmt;
use std::str::FromStr;
use unitac_core::profile::{self, GripperFamily, GripperProfile, ProfileError};

/// Register family.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Family {
    /// Robotiq 2F: 0x03E8 command block, 0x07D0 status block, 0x17 read+write.
    Robotiq,
    /// DH Robotics AG/PGE: single-register writes at 0x01xx, status reads at 0x02xx.
    Dh,
}

/// A serial gripper model: its profile and register family (equal by name: one name, one profile
/// per process).
#[derive(Debug, Clone, Copy)]
pub struct Model {
    profile: &'static GripperProfile,
    family: Family,
}

impl PartialEq for Model {
    fn eq(&self, other: &Self) -> bool {
        self.name() == other.name()
    }
}

impl Eq for Model {}

impl Serialize for Model {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.name())
    }
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
    /// The model of a profile; None for the world's own gripper (no serial family).
    pub fn of(profile: &'static GripperProfile) -> Option<Model> {
        let family = match profile.family {
            GripperFamily::Robotiq => Family::Robotiq,
            GripperFamily::Dh => Family::Dh,
            GripperFamily::Sim => return None,
        };
        Some(Model { profile, family })
    }

    /// Every serial model, by name (the shipped profiles and `UNITAC_GRIPPERS`'; none if that
    /// directory holds a broken file: naming a model then says why).
    pub fn all() -> Vec<Model> {
        profile::gripper_profiles()
            .map(|all| all.iter().filter_map(Model::of).collect())
            .unwrap_or_default()
    }

    /// The model named `name`.
    pub fn named(name: &str) -> Result<Model, UnknownModel> {
        let p = profile::gripper_profile(name).map_err(|e| match e {
            ProfileError::Unknown { .. } => UnknownModel(format!(
                "unknown gripper model {name:?} (known: {})",
                known_models()
            )),
            other => UnknownModel(other.to_string()),
        })?;
        Model::of(p).ok_or_else(|| {
            UnknownModel(format!(
                "{name:?} is the simulated world's gripper, not a serial model (known: {})",
                known_models()
            ))
        })
    }

    pub fn name(self) -> &'static str {
        self.profile.name
    }
    pub fn profile(self) -> &'static GripperProfile {
        self.profile
    }
    pub fn family(self) -> Family {
        self.family
    }
    /// Factory slave id (Robotiq manual: 9; DH manual: 1), from the profile.
    pub fn default_slave(self) -> u8 {
        self.profile.slave.unwrap_or(1)
    }
    /// Factory line rate (both manuals: 115200 8N1), from the profile.
    pub fn default_baud(self) -> u32 {
        self.profile.baud.unwrap_or(115_200)
    }
    pub fn calibration(self) -> Calibration {
        let p = self.profile;
        let (stroke, [fmin, fmax], [vmin, vmax]) = (p.stroke_m, p.force_n, p.speed_m_s);
        let limits = Limits {
            max_opening_m: stroke,
            min_speed_m_s: vmin,
            max_speed_m_s: vmax,
            min_force_n: fmin,
            max_force_n: fmax,
        };
        match self.family {
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

/// A gripper model name that is no serial model's (the message says which are, or why the
/// profiles could not be read).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct UnknownModel(pub String);

fn known_models() -> String {
    let names: Vec<_> = Model::all().iter().map(|m| m.name()).collect();
    names.join(", ")
}

impl FromStr for Model {
    type Err = UnknownModel;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Model::named(s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_parse_back() {
        for m in Model::all() {
            assert_eq!(m.name().parse::<Model>().unwrap(), m);
        }
        assert_eq!(
            "Robotiq-2F85".parse::<Model>().unwrap().name(),
            "robotiq_2f85"
        );
        assert!(
            "sim"
                .parse::<Model>()
                .unwrap_err()
                .to_string()
                .contains("not a serial model")
        );
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
        for m in Model::all() {
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
