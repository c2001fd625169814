//! Scene -> source + stages, for every transport.
//!
//! The embedded runtime (`unitac run`), bag replay (`unitac replay`) and the ROS nodes all build
//! what they run here, from the same scene file and the same typed parameter structs:
//! - [`load_scene`] finds and checks a scene by name or path;
//! - [`overrides::apply`] merges per-stage overrides (ROS parameters such as `contact.noise_k`,
//!   params files) into the scene, rejecting an unknown stage, an unknown key or a mistyped value
//!   with one line;
//! - [`registry::stage_configs`] turns each stage's `params:` into its typed struct
//!   ([`StageConfig`]), [`registry::build_stages`] builds the stages, [`registry::build_source`]
//!   the frame source (mock sensor, bag, and with the `v4l` feature a live V4L2 sensor:
//!   [`open_v4l`] when built with it);
//! - [`scenes`] is the one list of scenes (the files in the scene directories) and of the tasks
//!   run per mode (`<task>_<mode>` scenes).
//!
//! Driving the stages is not done here: every transport uses `unitac_core::chain` (the one chain
//! driver) and `unitac_core::pace` (the one pacer).

pub mod overrides;
pub mod registry;
pub mod scenes;
#[cfg(feature = "v4l")]
pub mod v4l;

pub use registry::{
    KNOWN_STAGES, StageConfig, build_source, build_stage, build_stages, check_modes, scene_context,
    scene_dirs, stage_configs,
};
#[cfg(feature = "v4l")]
pub use v4l::open_v4l;

pub use scenes::{mode_scene, scene_names, split_mode, tasks};

use std::path::{Path, PathBuf};
use unitac_core::scene::SceneContext;
use unitac_core::{Scene, SceneError};

/// A scene by name (looked up in [`scene_dirs`], `extra_dir` first) or by path, loaded and checked
/// (including each policy stage's mode against the scene's stages, [`check_modes`]).
pub fn load_scene(name: &str, extra_dir: Option<PathBuf>) -> Result<Scene, SceneError> {
    let path = unitac_core::scene::resolve(name, &scene_dirs(extra_dir))?;
    let ctx = scene_context();
    let scene = Scene::load(&path, &ctx).map_err(|e| generated_hint(e, &ctx, &path))?;
    check_modes(&scene)?;
    Ok(scene)
}

/// A missing model in the generated model directory (`${UNITAC_MODELS}`) says what makes it: in a
/// checkout, the setup stages this scene's models need.
fn generated_hint(e: SceneError, ctx: &SceneContext, scene: &Path) -> SceneError {
    match e {
        SceneError::MissingModel {
            path,
            model,
            file,
            hint,
        } if hint.is_empty()
            && ctx
                .vars
                .get("UNITAC_MODELS")
                .is_some_and(|d| file.starts_with(d)) =>
        {
            let hint = format!(
                " (a generated model: in a checkout, `bash scripts/setup.sh scene:{}` makes what this scene names)",
                scene.display()
            );
            SceneError::MissingModel {
                path,
                model,
                file,
                hint,
            }
        }
        e => e,
    }
}

/// Each stage's effective configuration, one line per stage (`kind: {typed params}`), exactly as
/// the stages will be built from `scene`. Transports print it so a test can prove they agree.
pub fn effective_params(scene: &Scene) -> Result<Vec<String>, SceneError> {
    Ok(stage_configs(scene)?
        .iter()
        .map(|c| format!("{}: {c:?}", c.kind()))
        .collect())
}

/// A scene as [`load_scene`] loads it, except that the policy stages' own `models:` (the fitted
/// readouts) are neither named nor loaded; their params stay. For recording the demonstrations
/// those models are fitted on (`unitac-lab demos`), before they exist.
pub fn load_scene_without_policy_models(
    name: &str,
    extra_dir: Option<PathBuf>,
) -> Result<Scene, SceneError> {
    let path = unitac_core::scene::resolve(name, &scene_dirs(extra_dir))?;
    let text = std::fs::read_to_string(&path).map_err(|e| SceneError::Io {
        path: path.clone(),
        msg: e.to_string(),
    })?;
    let parse = |msg: String| SceneError::Parse {
        path: path.clone(),
        msg,
    };
    let mut doc: serde_yaml::Value =
        serde_yaml::from_str(&text).map_err(|e| parse(e.to_string()))?;
    if let Some(stages) = doc
        .get_mut("stages")
        .and_then(serde_yaml::Value::as_sequence_mut)
    {
        for st in stages {
            let is_policy = st.get("kind").and_then(serde_yaml::Value::as_str) == Some("policy");
            if let (true, Some(m)) = (is_policy, st.as_mapping_mut()) {
                m.remove("models");
            }
        }
    }
    let text = serde_yaml::to_string(&doc).map_err(|e| parse(e.to_string()))?;
    let scene = Scene::parse(&text, &path, &scene_context())?;
    check_modes(&scene)?;
    Ok(scene)
}
