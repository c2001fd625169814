//! What a policy's configuration can get wrong: its params, its scene's stages, an input name, a
//! fitted model. Each error is one line; where several rules are checked at once, every broken
//! rule is listed.

use std::path::PathBuf;
use thiserror::Error;

/// Every broken rule of a checked set of values (params, bounds), in one line.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[error("{}", .0.join("; "))]
pub struct Problems(pub Vec<String>);

impl Problems {
    /// Ok when nothing was found.
    pub fn into_result(self) -> Result<(), Problems> {
        if self.0.is_empty() { Ok(()) } else { Err(self) }
    }
}

/// A scene's stage list against the mode of its policy stage.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum SceneStagesError {
    #[error(
        "mode {mode} reads {input} ({what}), which only a {producer} stage produces: add one before the policy stage"
    )]
    MissingProducer {
        mode: &'static str,
        input: &'static str,
        what: &'static str,
        producer: &'static str,
    },
    #[error(
        "mode {mode} does not use the {stage} stage's output: remove it from the scene (a scene loads nothing its mode does not use)"
    )]
    UnusedStage { mode: &'static str, stage: String },
}

/// An input name the policy does not have.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum InputError {
    /// Not an input any mode reads.
    #[error("unknown input {0}")]
    Unknown(String),
    /// Not an input of this mode (the mode's inputs listed).
    #[error("'{name}' is not an input of this mode ({})", .inputs.join(", "))]
    NotOfMode {
        name: String,
        inputs: Vec<&'static str>,
    },
}

/// Why a policy stage could not be built.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum PolicyLoadError {
    #[error(transparent)]
    Params(#[from] Problems),
    #[error(transparent)]
    SceneStages(#[from] SceneStagesError),
    #[error(transparent)]
    Input(#[from] InputError),
    #[error("a pick task needs two objects (A and B)")]
    PickNeedsTwoObjects,
    /// The fitted stiffness model in `dir`: every problem.
    #[error("stiffness model {}: {}", .dir.display(), .problems.join("; "))]
    StiffnessModel { dir: PathBuf, problems: Vec<String> },
    /// The learned policy bundle in `dir` for this scene: every problem.
    #[error("learned policy {}: {}", .dir.display(), .problems.join("; "))]
    LearnedPolicy { dir: PathBuf, problems: Vec<String> },
    #[error("a learned policy needs its bundle in the stage's models:")]
    LearnedPolicyMissing,
}

/// Why a message cannot fill its input's slice of the observation (the input is then invalid,
/// with this as the reason).
#[derive(Debug, Clone, PartialEq, Error)]
pub enum FeatureError {
    #[error("not a {0}")]
    WrongKind(&'static str),
    #[error("{name} is {value}")]
    NotFinite { name: String, value: f64 },
    #[error("gripper fault: {0}")]
    GripperFault(String),
    #[error("opening {opening_m} m outside the stroke [0, {stroke_m}] m")]
    OpeningOutsideStroke { opening_m: f64, stroke_m: f64 },
    #[error("latent marked invalid: {0}")]
    LatentInvalid(String),
    #[error("latent has {got} values, the observation layout has {want} (latent_len)")]
    LatentLen { got: usize, want: usize },
    #[error("latent value {index} is {value}")]
    LatentValue { index: usize, value: f32 },
    #[error("visual observation has no {0}")]
    NoVisual(String),
}
