//! The policy manifest: `manifest.json` next to the `.onnx` file, in the style of the model
//! bundles of unitac-infer (file + sha256 + declared tensors), with LeRobot's names.
//!
//! Inputs are flat per-feature tensors named as LeRobot names them (`observation.state`,
//! `observation.images.<camera>`, `observation.<name>` such as `observation.tactile_latent`),
//! each with its normalisation; the output is the action chunk `action` of shape
//! `[batch, chunk_size, A]` with one entry per action (name, SI unit, bounds). `chunk_size`,
//! `n_action_steps` and `temporal_ensemble_coeff` carry LeRobot's ACT configuration names, so a
//! policy exported from LeRobot with flat inputs loads by writing this file, with no code change.
//!
//! Fields that a user must state (normalisation, statistics) are optional here on purpose: a
//! missing one is reported by [`super::validate`] together with every other problem instead of
//! stopping the parse at the first.

use serde::Deserialize;
use std::path::Path;
use unitac_infer::bundle::Dim;

/// Largest manifest accepted \[bytes] (per-element image statistics make it large).
pub const MAX_MANIFEST_BYTES: u64 = 16 << 20;

#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PolicyManifest {
    /// Name used in messages and status (e.g. "cup_squeeze").
    pub policy: String,
    #[serde(default)]
    pub version: String,
    #[serde(default)]
    pub description: String,
    /// The ONNX file, relative to the manifest's directory.
    pub file: String,
    pub sha256: String,
    /// Control ticks per second the policy was trained at \[Hz]: one action row per tick.
    pub control_rate_hz: f64,
    /// H: rows of the action chunk one inference predicts.
    pub chunk_size: usize,
    /// k: rows executed from each chunk before the next inference (1..=H).
    pub n_action_steps: usize,
    /// ACT temporal ensembling: every prediction made for a tick is averaged with weights
    /// `w_i = exp(-m * i)`, i = 0 the oldest. None: the newest chunk's rows are executed as they
    /// are.
    #[serde(default)]
    pub temporal_ensemble_coeff: Option<f64>,
    pub inputs: Vec<InputSpec>,
    pub output: OutputSpec,
}

/// One model input: a flat feature tensor.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InputSpec {
    /// LeRobot feature name, also the ONNX input name.
    pub name: String,
    /// Only "float32" is fed.
    pub dtype: String,
    /// Full tensor shape, batch first: the first dimension may be symbolic ("batch") or 1, every
    /// other one is fixed. The runtime feeds batch 1.
    pub shape: Vec<Dim>,
    pub normalization: Option<NormSpec>,
    /// What each value is (LeRobot's `names` of the feature), when the exporter states it: a
    /// policy that reads a feature's values by name (the camera's estimate) checks them.
    #[serde(default)]
    pub names: Option<Vec<String>>,
}

/// The action chunk output.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OutputSpec {
    /// The ONNX output name, "action" in LeRobot.
    pub name: String,
    pub dtype: String,
    /// `[batch, chunk_size, A]`.
    pub shape: Vec<Dim>,
    /// How the model's output maps back to SI units (per action, length A).
    pub normalization: Option<NormSpec>,
    pub actions: Vec<ActionSpec>,
}

/// One column of the action chunk.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ActionSpec {
    /// e.g. "gripper.opening".
    pub name: String,
    /// SI unit, e.g. "m", "m/s", "N".
    pub unit: String,
    /// Bounds in that unit; actions outside are clamped to them (and counted).
    pub min: f64,
    pub max: f64,
}

/// Normalisation of one feature, as LeRobot's `NormalizationMode`:
/// - `mean_std`: `n = (x - mean) / std`, back: `x = n * std + mean`;
/// - `min_max`: `n = 2 (x - min) / (max - min) - 1` (to \[-1, 1]), back: `x = (n + 1) / 2 (max -
///   min) + min`;
/// - `identity`: none (stated explicitly; a missing normalisation is an error).
///
/// Statistics have one value per element of the feature (batch excluded) or one per channel
/// (the first dimension after batch, broadcast over the rest, as image statistics are).
/// LeRobot adds 1e-8 to the divisor; here std and max - min must be > 0 instead, and the
/// division is exact.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NormSpec {
    /// "mean_std" | "min_max" | "identity" (LeRobot's upper-case spellings are accepted).
    pub mode: String,
    #[serde(default)]
    pub mean: Option<Vec<f64>>,
    #[serde(default)]
    pub std: Option<Vec<f64>>,
    #[serde(default)]
    pub min: Option<Vec<f64>>,
    #[serde(default)]
    pub max: Option<Vec<f64>>,
}

/// Why a manifest could not be read at all (before any validation).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{path}: {msg}")]
pub struct ManifestError {
    pub path: String,
    pub msg: String,
}

/// Manifest text that is not a manifest: the JSON error, with a hint where the text has the
/// non-finite numbers JSON cannot spell.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error(
    "{json}{}",
    if *.non_finite { " (JSON has no NaN or Infinity: the exporter wrote non-finite statistics)" } else { "" }
)]
pub struct ManifestParseError {
    json: String,
    non_finite: bool,
}

impl PolicyManifest {
    /// Read and parse `path` (bounded size).
    pub fn read(path: &Path) -> Result<PolicyManifest, ManifestError> {
        let err = |msg: String| ManifestError {
            path: path.display().to_string(),
            msg,
        };
        let meta = std::fs::metadata(path).map_err(|e| err(e.to_string()))?;
        if meta.len() > MAX_MANIFEST_BYTES {
            return Err(err(format!(
                "{} bytes, more than {MAX_MANIFEST_BYTES}",
                meta.len()
            )));
        }
        let text = std::fs::read_to_string(path).map_err(|e| err(e.to_string()))?;
        Self::parse(&text).map_err(|e| err(e.to_string()))
    }

    /// Parse manifest text (the error is wrapped into a [`ManifestError`] by `read`).
    pub(crate) fn parse(text: &str) -> Result<PolicyManifest, ManifestParseError> {
        serde_json::from_str(text).map_err(|json| ManifestParseError {
            json: json.to_string(),
            non_finite: text.contains("NaN") || text.contains("Infinity"),
        })
    }
}
