//! Device profiles as data: a gripper is one file, `grippers/<name>.yaml`, with what differs
//! between models (stroke, force and speed ranges, register family, factory slave id and line
//! rate) and where each figure comes from. The serial driver's limits and calibration
//! (unitac-gripper), the simulated world's gripper (unitac-sim) and the safety layer's bounds
//! (unitac-policy, when a scene or trial names its gripper) all derive from it.
//!
//! The shipped files are checked and compiled in at build time (crates/core/build.rs: a broken
//! file fails the build); a directory in `UNITAC_GRIPPERS` adds profiles at run time, read once
//! per process (a file there replaces a shipped profile of the same name). Adding a gripper is a
//! file, no code.

#[path = "../build/gripper_profile.rs"]
mod raw;

use serde::Serialize;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use thiserror::Error;

pub use raw::{FAMILIES, MAX_FORCE_N, MAX_NAME, MAX_SPEED_M_S, MAX_STROKE_M};

/// Largest profile file read \[bytes], and most files read from `UNITAC_GRIPPERS`.
pub const MAX_PROFILE_BYTES: usize = 64 << 10;
pub const MAX_PROFILES: usize = 256;

/// How a gripper is driven.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum GripperFamily {
    /// Robotiq 2F registers over Modbus RTU.
    Robotiq,
    /// DH Robotics AG/PGE registers over Modbus RTU.
    Dh,
    /// No device: the simulated task world's own gripper.
    Sim,
}

/// One gripper model.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct GripperProfile {
    pub name: &'static str,
    pub family: GripperFamily,
    /// Full stroke \[m].
    pub stroke_m: f64,
    /// Weakest and strongest grip \[N].
    pub force_n: [f64; 2],
    /// Slowest and fastest opening speed \[m/s].
    pub speed_m_s: [f64; 2],
    /// Factory Modbus slave id and line rate (serial families).
    pub slave: Option<u8>,
    pub baud: Option<u32>,
}

include!(concat!(env!("OUT_DIR"), "/grippers_generated.rs"));

/// Why a profile could not be had.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum ProfileError {
    /// A file that is no profile: every problem, one line.
    #[error("gripper profile {path}: {msg}")]
    Bad { path: String, msg: String },
    #[error("gripper profiles in {dir}: {msg}")]
    Dir { dir: String, msg: String },
    #[error("unknown gripper {name:?} (known: {known})")]
    Unknown { name: String, known: String },
}

impl GripperProfile {
    /// A profile from `text`, the file `path` (its stem must be the profile's name).
    pub fn parse(text: &str, path: &Path) -> Result<GripperProfile, ProfileError> {
        let bad = |msg: String| ProfileError::Bad {
            path: path.display().to_string(),
            msg,
        };
        crate::yaml::check(text, MAX_PROFILE_BYTES).map_err(|e| bad(e.to_string()))?;
        let r: raw::RawGripper = serde_yaml::from_str(text).map_err(|e| bad(e.to_string()))?;
        let stem = path.file_stem().and_then(|s| s.to_str()).unwrap_or("");
        let problems = r.problems(stem);
        if !problems.is_empty() {
            return Err(bad(problems.join("; ")));
        }
        let family = match r.family.as_str() {
            "robotiq" => GripperFamily::Robotiq,
            "dh" => GripperFamily::Dh,
            _ => GripperFamily::Sim,
        };
        Ok(GripperProfile {
            // Bounded: at most MAX_PROFILES names of at most MAX_NAME bytes per process.
            name: Box::leak(r.name.into_boxed_str()),
            family,
            stroke_m: r.stroke_m,
            force_n: r.force_n,
            speed_m_s: r.speed_m_s,
            slave: r.slave,
            baud: r.baud,
        })
    }

    /// Whether a serial driver drives it (not the world's own gripper).
    pub fn is_serial(&self) -> bool {
        self.family != GripperFamily::Sim
    }
}

/// The profiles in `dir` (`*.yaml`, sorted by name).
pub fn read_dir(dir: &Path) -> Result<Vec<GripperProfile>, ProfileError> {
    let err = |msg: String| ProfileError::Dir {
        dir: dir.display().to_string(),
        msg,
    };
    let mut paths: Vec<PathBuf> = Vec::new();
    for e in std::fs::read_dir(dir).map_err(|e| err(e.to_string()))? {
        let p = e.map_err(|e| err(e.to_string()))?.path();
        if p.extension().is_some_and(|x| x == "yaml") {
            paths.push(p);
            if paths.len() > MAX_PROFILES {
                return Err(err(format!("more than {MAX_PROFILES} .yaml files")));
            }
        }
    }
    paths.sort();
    let mut out = Vec::new();
    for p in paths {
        let bad = |msg: String| ProfileError::Bad {
            path: p.display().to_string(),
            msg,
        };
        let len = std::fs::metadata(&p).map_err(|e| bad(e.to_string()))?.len();
        if len > MAX_PROFILE_BYTES as u64 {
            return Err(bad(format!("{len} bytes, more than {MAX_PROFILE_BYTES}")));
        }
        let text = std::fs::read_to_string(&p).map_err(|e| bad(e.to_string()))?;
        out.push(GripperProfile::parse(&text, &p)?);
    }
    Ok(out)
}

/// Every gripper profile: the shipped ones, and those of the `UNITAC_GRIPPERS` directory (read
/// once per process; one of a shipped name replaces it), sorted by name.
pub fn gripper_profiles() -> Result<&'static [GripperProfile], ProfileError> {
    static ALL: OnceLock<Result<Vec<GripperProfile>, ProfileError>> = OnceLock::new();
    ALL.get_or_init(|| {
        let mut all: Vec<GripperProfile> = SHIPPED_GRIPPERS.to_vec();
        if let Some(dir) = std::env::var_os("UNITAC_GRIPPERS") {
            for p in read_dir(Path::new(&dir))? {
                all.retain(|s| s.name != p.name);
                all.push(p);
            }
        }
        all.sort_by(|a, b| a.name.cmp(b.name));
        Ok(all)
    })
    .as_ref()
    .map(Vec::as_slice)
    .map_err(Clone::clone)
}

/// The profile named `name` (`-` and case are forgiven: `Robotiq-2F140` is `robotiq_2f140`).
pub fn gripper_profile(name: &str) -> Result<&'static GripperProfile, ProfileError> {
    let all = gripper_profiles()?;
    let k = name.to_ascii_lowercase().replace(['-', ' '], "_");
    all.iter()
        .find(|p| p.name == k || p.name.replace('_', "") == k.replace('_', ""))
        .ok_or_else(|| ProfileError::Unknown {
            name: name.to_string(),
            known: all.iter().map(|p| p.name).collect::<Vec<_>>().join(", "),
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_shipped_profiles_are_there_and_sim_is_the_worlds() {
        let names: Vec<&str> = SHIPPED_GRIPPERS.iter().map(|p| p.name).collect();
        assert_eq!(
            names,
            [
                "dh_ag95",
                "dh_pge50",
                "robotiq_2f140",
                "robotiq_2f85",
                "sim"
            ]
        );
        assert_eq!(SIM_GRIPPER.family, GripperFamily::Sim);
        assert!(!SIM_GRIPPER.is_serial());
    }

    #[test]
    fn a_broken_file_names_every_problem() {
        let e = GripperProfile::parse(
            "{name: x2, family: pneumatic, stroke_m: -1, force_n: [5, 1], speed_m_s: [0, .nan]}",
            Path::new("/p/x.yaml"),
        )
        .unwrap_err()
        .to_string();
        for want in [
            "/p/x.yaml",
            "not the file's name",
            "family \"pneumatic\"",
            "stroke_m = -1",
            "force_n = [5, 1]",
            "speed_m_s = [0, NaN]",
            "states its factory slave and baud",
        ] {
            assert!(e.contains(want), "{want}: {e}");
        }
        let e = GripperProfile::parse("name: [", Path::new("y.yaml")).unwrap_err();
        assert!(matches!(e, ProfileError::Bad { .. }), "{e}");
    }
}
