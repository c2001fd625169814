//! The paper's three modes and what each observes.
//!
//! A mode is a set of inputs (names of [`crate::observation::INPUTS`]). The scene check
//! ([`check_scene_stages`]) uses it both ways: every input a mode reads that a scene stage
//! produces must have its producer in the scene, and the scene must not run a stage that no input
//! of the mode needs (no encoder for vla, no sampler for vtla_real).

use crate::error::SceneStagesError;
use crate::observation::{INPUTS, input};
use crate::schema;
use serde::{Deserialize, Serialize};
use std::str::FromStr;
use thiserror::Error;

/// vla: vision only. vtla_real: live latents from the touch encoder. vtla_pred: latents
/// predicted by the flow sampler from the sensor prior, before or without touch.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Mode {
    Vla,
    #[default]
    VtlaReal,
    VtlaPred,
}

/// A name that is no mode; says which are.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[error("unknown mode '{0}' (known: {known})", known = Mode::names().join(", "))]
pub struct UnknownMode(pub String);

impl Mode {
    /// Every mode, in the paper's order (the table's columns).
    pub const ALL: [Mode; 3] = [Mode::Vla, Mode::VtlaReal, Mode::VtlaPred];

    /// The names of [`Mode::ALL`], in its order.
    pub fn names() -> Vec<&'static str> {
        Mode::ALL.iter().map(|m| m.as_str()).collect()
    }

    pub fn as_str(self) -> &'static str {
        match self {
            Mode::Vla => "vla",
            Mode::VtlaReal => "vtla_real",
            Mode::VtlaPred => "vtla_pred",
        }
    }

    /// The inputs this mode reads (names in [`INPUTS`]), for the given task kind, as
    /// schema/policy.json lists them. Every mode aims the arm where the camera sees the objects
    /// (`visual`). vtla_real reads the contact state and, for a fabric, the comparison of the two
    /// touches' latents (the compare stage consumes the encoder's output), for a cup the probe
    /// touch's live latent (it sets the squeeze's force cap). vtla_pred reads the predicted
    /// latent (sampled once, from the background frame before the approach) and nothing derived
    /// from a tactile frame after that: no contact state, no live comparison.
    pub fn inputs(self, fabric: bool) -> Vec<&'static str> {
        let task = if fabric {
            "fabric_selection"
        } else {
            "cup_deformation"
        };
        schema::mode_inputs(self.as_str(), task)
            .map(<[&str]>::to_vec)
            .unwrap_or_default()
    }
}

impl FromStr for Mode {
    type Err = UnknownMode;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Mode::ALL
            .into_iter()
            .find(|m| m.as_str() == s)
            .ok_or_else(|| UnknownMode(s.to_string()))
    }
}

impl std::fmt::Display for Mode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// Checks a scene's stage list against a mode: `kinds` are the scene's stage kinds before the
/// policy stage, `needs` the registry's (stage kind -> the kind it consumes). Errors name the
/// stage or input, one line.
pub fn check_scene_stages(
    mode: Mode,
    fabric: bool,
    kinds: &[&str],
    needs: &[(&str, &str)],
) -> Result<(), SceneStagesError> {
    let inputs = mode.inputs(fabric);
    let mut used: Vec<&str> = Vec::new();
    for name in &inputs {
        let Some(spec) = input(name) else { continue };
        let Some(producer) = spec.produced_by else {
            continue;
        };
        if !kinds.contains(&producer) {
            return Err(SceneStagesError::MissingProducer {
                mode: mode.as_str(),
                input: spec.name,
                what: spec.what,
                producer,
            });
        }
        // The producer and everything it consumes, transitively.
        let mut k = producer;
        loop {
            if !used.contains(&k) {
                used.push(k);
            }
            match needs.iter().find(|(a, _)| *a == k) {
                Some((_, b)) => k = b,
                None => break,
            }
        }
    }
    for k in kinds {
        let feeds_an_input = INPUTS.iter().any(|i| i.produced_by == Some(*k));
        if feeds_an_input && !used.contains(k) {
            return Err(SceneStagesError::UnusedStage {
                mode: mode.as_str(),
                stage: (*k).to_string(),
            });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    const NEEDS: &[(&str, &str)] = &[
        ("encoder", "contact"),
        ("sampler", "contact"),
        ("compare", "encoder"),
    ];

    #[test]
    fn names_parse_back_and_the_error_lists_every_mode() {
        for m in Mode::ALL {
            assert_eq!(m.as_str().parse::<Mode>(), Ok(m));
            assert_eq!(m.to_string(), m.as_str());
        }
        let e = "vtla".parse::<Mode>().unwrap_err().to_string();
        assert_eq!(e, "unknown mode 'vtla' (known: vla, vtla_real, vtla_pred)");
    }

    #[test]
    fn each_mode_needs_its_producers_and_nothing_else() {
        let real = ["contact", "encoder", "compare"];
        assert_eq!(
            check_scene_stages(Mode::VtlaReal, true, &real, NEEDS),
            Ok(())
        );
        assert_eq!(
            check_scene_stages(Mode::VtlaReal, false, &["contact", "encoder"], NEEDS),
            Ok(())
        );
        assert_eq!(check_scene_stages(Mode::Vla, true, &[], NEEDS), Ok(()));
        assert_eq!(
            check_scene_stages(Mode::VtlaPred, false, &["contact", "sampler"], NEEDS),
            Ok(())
        );
        // vla loads no encoder; vtla_real no sampler.
        let e = check_scene_stages(Mode::Vla, true, &real, NEEDS)
            .unwrap_err()
            .to_string();
        assert!(e.contains("does not use the contact stage"), "{e}");
        let e = check_scene_stages(
            Mode::VtlaReal,
            false,
            &["contact", "encoder", "sampler"],
            NEEDS,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("does not use the sampler stage"), "{e}");
        // A missing producer names the input.
        let e = check_scene_stages(Mode::VtlaPred, false, &["contact"], NEEDS)
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "mode vtla_pred reads latent_pred (predicted tactile latent), which only a sampler stage produces: add one before the policy stage"
        );
    }
}
