//! Scene files: the one place that says what a scene runs.
//!
//! `launch/scenes/<scene>.yaml` lists the source, the models and the stages of a scene. The
//! embedded runner and the ROS launch files read the same file, and a scene loads nothing it does
//! not name. Every problem is reported as one line naming the file and the offending entry.

use crate::sensor::SensorKind;
use serde::Deserialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use thiserror::Error;

/// Largest scene file accepted (it is configuration, not data).
pub const MAX_SCENE_BYTES: u64 = 1 << 20;
/// Slowest source frame rate accepted \[Hz]: below it a run of any sensible length sees no frame.
pub const MIN_FPS: f64 = 1.0;

#[derive(Debug, Error)]
pub enum SceneError {
    #[error("scene '{name}' not found (looked in: {looked}; available: {available})")]
    NotFound {
        name: String,
        looked: String,
        available: String,
    },
    #[error("{path}: cannot read: {msg}")]
    Io { path: PathBuf, msg: String },
    #[error("{path}: {msg}")]
    Parse { path: PathBuf, msg: String },
    #[error("{path}: stage {index} has unknown kind '{kind}' (known: {known})")]
    UnknownStage {
        path: PathBuf,
        index: usize,
        kind: String,
        known: String,
    },
    #[error(
        "{path}: stage {index} ({kind}) uses model '{model}', which the scene's models: section does not declare"
    )]
    UndeclaredModel {
        path: PathBuf,
        index: usize,
        kind: String,
        model: String,
    },
    #[error("{path}: model '{model}': file not found: {file}{hint}")]
    MissingModel {
        path: PathBuf,
        model: String,
        file: PathBuf,
        /// What makes the file, when the loader knows (empty, or text that starts with a space).
        hint: String,
    },
    #[error("{path}: bad value for {field}: {msg}")]
    BadValue {
        path: PathBuf,
        field: String,
        msg: String,
    },
}

/// A model path that names an unknown `${VAR}` or leaves one open.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum ExpandError {
    #[error("unclosed ${{ in '{0}'")]
    Unclosed(String),
    #[error("unknown variable ${{{name}}} in '{path}'")]
    UnknownVar { name: String, path: String },
}

/// A `--sensor` value that is none of the known forms.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[error("'{0}' is not one of: mock, v4l, v4l:<serial>, bag:<path>")]
pub struct SensorArgError(String);

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SourceKind {
    Mock,
    V4l,
    Bag,
}

#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SourceSpec {
    pub kind: SourceKind,
    #[serde(default = "default_sensor")]
    pub sensor: SensorKind,
    /// Mock sensor scenario (defaults to the scene's name).
    #[serde(default)]
    pub scenario: Option<String>,
    #[serde(default)]
    pub seed: u64,
    /// Frame rate; defaults to the sensor's.
    #[serde(default)]
    pub fps: Option<f64>,
    /// Serial of a live sensor (v4l).
    #[serde(default)]
    pub serial: Option<String>,
    /// Sensor id of the frames (frame_id `<sensor_id>_optical_frame`): default `mock_<sensor>`
    /// for the mock sensor, the serial for a live one, the recorded frame_id for a bag.
    #[serde(default)]
    pub sensor_id: Option<String>,
    /// Bag path (bag).
    #[serde(default)]
    pub path: Option<PathBuf>,
}

fn default_sensor() -> SensorKind {
    SensorKind::GELSIGHT_MINI
}

#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StageSpec {
    pub kind: String,
    /// Names of models (keys of the scene's `models:`) this stage loads.
    #[serde(default)]
    pub models: Vec<String>,
    /// Stage parameters; each stage checks its own (unknown keys are errors).
    #[serde(default)]
    pub params: serde_yaml::Value,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EdgeSpec {
    /// Frames queued per edge before the oldest frame is dropped (and counted).
    #[serde(default = "default_frame_capacity")]
    pub frame_capacity: usize,
    /// Events queued per edge; a full edge blocks its producer (events are never dropped).
    #[serde(default = "default_event_capacity")]
    pub event_capacity: usize,
}

fn default_frame_capacity() -> usize {
    4
}
fn default_event_capacity() -> usize {
    1024
}

impl Default for EdgeSpec {
    fn default() -> Self {
        Self {
            frame_capacity: default_frame_capacity(),
            event_capacity: default_event_capacity(),
        }
    }
}

#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
struct SceneFile {
    scene: String,
    #[serde(default)]
    description: String,
    #[serde(default)]
    task: Option<String>,
    source: SourceSpec,
    #[serde(default)]
    models: BTreeMap<String, PathBuf>,
    #[serde(default)]
    stages: Vec<StageSpec>,
    #[serde(default)]
    edges: EdgeSpec,
}

/// A parsed and checked scene.
#[derive(Debug, Clone, PartialEq)]
pub struct Scene {
    pub name: String,
    pub description: String,
    /// The task the scene works on (`task: cup_deformation`; the sim's task world and the
    /// trials look it up by this name), if it names one.
    pub task: Option<String>,
    pub path: PathBuf,
    pub source: SourceSpec,
    /// Model name -> resolved file path (only the models some stage uses).
    pub models: BTreeMap<String, PathBuf>,
    pub stages: Vec<StageSpec>,
    pub edges: EdgeSpec,
}

/// What a scene is checked against.
#[derive(Debug, Clone, Default)]
pub struct SceneContext {
    /// Stage kinds the runner can build.
    pub known_stages: Vec<String>,
    /// `${NAME}` prefixes allowed in model paths (e.g. `UNITAC_MODELS` -> the model directory).
    pub vars: BTreeMap<String, PathBuf>,
    /// What each stage kind consumes and produces: a stage's needed inputs must come from
    /// outside or from a stage earlier in the list (an encoder before the contact stage never
    /// sees a clip). Empty: no order is checked.
    pub graph: crate::graph::StageGraph,
}

/// Find `name` (a path, or a scene name looked up as `<dir>/<name>.yaml`).
pub fn resolve(name: &str, dirs: &[PathBuf]) -> Result<PathBuf, SceneError> {
    let as_path = Path::new(name);
    if name.ends_with(".yaml") || name.ends_with(".yml") || name.contains('/') {
        if as_path.is_file() {
            return Ok(as_path.to_path_buf());
        }
    } else {
        for d in dirs {
            let p = d.join(format!("{name}.yaml"));
            if p.is_file() {
                return Ok(p);
            }
        }
    }
    let mut available: Vec<String> = dirs.iter().flat_map(|d| list(d)).collect();
    available.sort();
    available.dedup();
    Err(SceneError::NotFound {
        name: name.to_string(),
        looked: dirs
            .iter()
            .map(|d| d.display().to_string())
            .collect::<Vec<_>>()
            .join(", "),
        available: if available.is_empty() {
            "none".into()
        } else {
            available.join(", ")
        },
    })
}

/// Scene names (file stems) in a directory, sorted.
pub fn list(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .into_iter()
        .flatten()
        .flatten()
        .filter_map(|e| {
            let p = e.path();
            (p.extension().and_then(|x| x.to_str()) == Some("yaml"))
                .then(|| p.file_stem().and_then(|s| s.to_str()).map(str::to_string))
                .flatten()
        })
        .collect();
    v.sort();
    v
}

impl Scene {
    pub fn load(path: &Path, ctx: &SceneContext) -> Result<Scene, SceneError> {
        let io = |e: std::io::Error| SceneError::Io {
            path: path.to_path_buf(),
            msg: e.to_string(),
        };
        let meta = std::fs::metadata(path).map_err(io)?;
        if meta.len() > MAX_SCENE_BYTES {
            return Err(SceneError::Parse {
                path: path.to_path_buf(),
                msg: format!("file is {} bytes, more than {MAX_SCENE_BYTES}", meta.len()),
            });
        }
        let text = std::fs::read_to_string(path).map_err(io)?;
        Self::parse(&text, path, ctx)
    }

    /// Parse and check scene text; `path` names the file in errors and anchors relative model paths.
    pub fn parse(text: &str, path: &Path, ctx: &SceneContext) -> Result<Scene, SceneError> {
        let p = || path.to_path_buf();
        crate::yaml::check(text, MAX_SCENE_BYTES as usize).map_err(|e| SceneError::Parse {
            path: p(),
            msg: e.to_string(),
        })?;
        let file: SceneFile = serde_yaml::from_str(text).map_err(|e| SceneError::Parse {
            path: p(),
            msg: one_line(&e.to_string()),
        })?;
        let bad = |field: &str, msg: String| SceneError::BadValue {
            path: p(),
            field: field.into(),
            msg,
        };

        if file.scene.is_empty()
            || !file
                .scene
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
        {
            return Err(bad(
                "scene",
                format!("'{}' must be non-empty [A-Za-z0-9_-]", file.scene),
            ));
        }
        if let Some(t) = &file.task
            && (t.is_empty() || !t.chars().all(|c| c.is_ascii_alphanumeric() || c == '_'))
        {
            return Err(bad(
                "task",
                format!("'{}' must be non-empty [A-Za-z0-9_]", one_line(t)),
            ));
        }
        if let Some(fps) = file.source.fps {
            if !(fps.is_finite() && (MIN_FPS..=1000.0).contains(&fps)) {
                return Err(bad(
                    "source.fps",
                    format!("{fps} is outside [{MIN_FPS}, 1000]"),
                ));
            }
        }
        if !(1..=1024).contains(&file.edges.frame_capacity) {
            return Err(bad(
                "edges.frame_capacity",
                format!("{} is outside 1..=1024", file.edges.frame_capacity),
            ));
        }
        if !(1..=1_000_000).contains(&file.edges.event_capacity) {
            return Err(bad(
                "edges.event_capacity",
                format!("{} is outside 1..=1000000", file.edges.event_capacity),
            ));
        }
        match file.source.kind {
            SourceKind::Bag if file.source.path.is_none() => {
                return Err(bad("source.path", "a bag source needs a path".into()));
            }
            _ => {}
        }

        let kinds: Vec<&str> = file.stages.iter().map(|s| s.kind.as_str()).collect();
        if let Err((index, e)) = ctx.graph.check_order(&kinds) {
            return Err(bad(&format!("stages[{}]", index + 1), e.to_string()));
        }

        let base = path.parent().unwrap_or(Path::new("."));
        let mut models = BTreeMap::new();
        for (index, st) in file.stages.iter().enumerate() {
            if !ctx.known_stages.iter().any(|k| k == &st.kind) {
                return Err(SceneError::UnknownStage {
                    path: p(),
                    index: index + 1,
                    kind: st.kind.clone(),
                    known: ctx.known_stages.join(", "),
                });
            }
            for m in &st.models {
                let Some(rel) = file.models.get(m) else {
                    return Err(SceneError::UndeclaredModel {
                        path: p(),
                        index: index + 1,
                        kind: st.kind.clone(),
                        model: m.clone(),
                    });
                };
                let resolved = expand(rel, base, &ctx.vars)
                    .map_err(|e| bad(&format!("models.{m}"), e.to_string()))?;
                if !resolved.is_file() {
                    return Err(SceneError::MissingModel {
                        path: p(),
                        model: m.clone(),
                        file: resolved,
                        hint: String::new(),
                    });
                }
                models.insert(m.clone(), resolved);
            }
        }
        Ok(Scene {
            name: file.scene,
            description: file.description,
            task: file.task,
            path: p(),
            source: file.source,
            models,
            stages: file.stages,
            edges: file.edges,
        })
    }
}

/// `${NAME}/rest` -> vars[NAME]/rest; a relative path -> base/path.
fn expand(p: &Path, base: &Path, vars: &BTreeMap<String, PathBuf>) -> Result<PathBuf, ExpandError> {
    let s = p.to_string_lossy();
    if let Some(rest) = s.strip_prefix("${") {
        let (name, tail) = rest
            .split_once('}')
            .ok_or_else(|| ExpandError::Unclosed(s.to_string()))?;
        let root = vars.get(name).ok_or_else(|| ExpandError::UnknownVar {
            name: name.to_string(),
            path: s.to_string(),
        })?;
        return Ok(root.join(tail.trim_start_matches('/')));
    }
    Ok(if p.is_absolute() {
        p.to_path_buf()
    } else {
        base.join(p)
    })
}

fn one_line(s: &str) -> String {
    s.split_whitespace().collect::<Vec<_>>().join(" ")
}

/// `--sensor` on the command line: overrides the scene's source.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum SensorArg {
    Mock,
    V4l(Option<String>),
    Bag(PathBuf),
}

impl std::str::FromStr for SensorArg {
    type Err = SensorArgError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.split_once(':') {
            None if s == "mock" => Ok(SensorArg::Mock),
            None if s == "v4l" => Ok(SensorArg::V4l(None)),
            Some(("v4l", serial)) if !serial.is_empty() => Ok(SensorArg::V4l(Some(serial.into()))),
            Some(("bag", path)) if !path.is_empty() => Ok(SensorArg::Bag(path.into())),
            _ => Err(SensorArgError(s.to_string())),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ctx() -> SceneContext {
        SceneContext {
            known_stages: vec!["contact".into()],
            ..SceneContext::default()
        }
    }

    const OK: &str =
        "scene: demo\nsource: {kind: mock, sensor: digit, seed: 3}\nstages:\n  - kind: contact\n";

    #[test]
    fn parses_a_minimal_scene() {
        let s = Scene::parse(OK, Path::new("demo.yaml"), &ctx()).unwrap();
        assert_eq!(s.name, "demo");
        assert_eq!(s.source.sensor, SensorKind::DIGIT);
        assert_eq!(s.source.seed, 3);
        assert_eq!(s.stages.len(), 1);
        assert_eq!(s.edges, EdgeSpec::default());
    }

    #[test]
    fn unknown_stage_is_one_line_naming_it() {
        let t = OK.replace("kind: contact", "kind: teleport");
        let e = Scene::parse(&t, Path::new("x.yaml"), &ctx())
            .unwrap_err()
            .to_string();
        assert!(e.contains("stage 1 has unknown kind 'teleport'"), "{e}");
        assert!(e.contains("known: contact"), "{e}");
        assert!(!e.contains('\n'));
    }

    #[test]
    fn missing_and_undeclared_models() {
        let t = format!("{OK}    models: [encoder]\nmodels: {{encoder: /nonexistent/enc.onnx}}\n");
        let e = Scene::parse(&t, Path::new("x.yaml"), &ctx()).unwrap_err();
        assert!(
            matches!(e, SceneError::MissingModel { ref model, .. } if model == "encoder"),
            "{e}"
        );
        let t = format!("{OK}    models: [encoder]\n");
        let e = Scene::parse(&t, Path::new("x.yaml"), &ctx()).unwrap_err();
        assert!(matches!(e, SceneError::UndeclaredModel { .. }), "{e}");
    }

    #[test]
    fn model_paths_expand_variables() {
        let dir = std::env::temp_dir().join(format!("unitac-scene-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("enc.onnx"), b"x").unwrap();
        let mut c = ctx();
        c.vars.insert("UNITAC_MODELS".into(), dir.clone());
        let t =
            format!("{OK}    models: [enc]\nmodels: {{enc: \"${{UNITAC_MODELS}}/enc.onnx\"}}\n");
        let s = Scene::parse(&t, Path::new("x.yaml"), &c).unwrap();
        assert_eq!(s.models["enc"], dir.join("enc.onnx"));
        let t = t.replace("UNITAC_MODELS}", "NOPE}");
        assert!(
            Scene::parse(&t, Path::new("x.yaml"), &c)
                .unwrap_err()
                .to_string()
                .contains("unknown variable")
        );
        std::fs::remove_dir_all(dir).ok();
    }

    #[test]
    fn bad_values_are_named() {
        for (from, to, field) in [
            ("seed: 3", "seed: 3, fps: -1", "source.fps"),
            ("seed: 3", "seed: 3, fps: .nan", "source.fps"),
            (
                "stages:",
                "edges: {frame_capacity: 0}\nstages:",
                "edges.frame_capacity",
            ),
        ] {
            let e = Scene::parse(&OK.replace(from, to), Path::new("x.yaml"), &ctx()).unwrap_err();
            assert!(
                matches!(&e, SceneError::BadValue { field: f, .. } if f == field),
                "{e}"
            );
        }
        // A typo in a key is an error too, not silently ignored.
        let e = Scene::parse(&OK.replace("seed", "sead"), Path::new("x.yaml"), &ctx()).unwrap_err();
        assert!(e.to_string().contains("sead"), "{e}");
        let e = Scene::parse("scene: [", Path::new("x.yaml"), &ctx()).unwrap_err();
        assert!(matches!(e, SceneError::Parse { .. }));
    }

    #[test]
    fn deep_nesting_and_stage_order_and_slow_sources_are_refused() {
        // 100 000 levels took 30 s inside serde_yaml; refused before parsing.
        let deep = format!(
            "{OK}    params: {{a: {}{}}}\n",
            "[".repeat(100_000),
            "]".repeat(100_000)
        );
        let e = Scene::parse(&deep, Path::new("x.yaml"), &ctx()).unwrap_err();
        assert!(
            e.to_string().contains("nested more than 64 deep at line 5"),
            "{e}"
        );
        // An encoder before the contact stage never sees a clip.
        let mut c = ctx();
        c.known_stages.push("encoder".into());
        c.graph = crate::graph::StageGraph::shipped().unwrap();
        let t = "scene: d\nsource: {kind: mock}\nstages:\n  - kind: encoder\n  - kind: contact\n";
        let e = Scene::parse(t, Path::new("x.yaml"), &c).unwrap_err();
        assert!(
            matches!(&e, SceneError::BadValue { field, .. } if field == "stages[1]"),
            "{e}"
        );
        let t = "scene: d\nsource: {kind: mock}\nstages:\n  - kind: contact\n  - kind: encoder\n";
        assert!(Scene::parse(t, Path::new("x.yaml"), &c).is_ok());
        let e = Scene::parse(
            &OK.replace("seed: 3", "fps: 0.001"),
            Path::new("x.yaml"),
            &ctx(),
        )
        .unwrap_err();
        assert!(e.to_string().contains("0.001 is outside [1, 1000]"), "{e}");
    }

    #[test]
    fn resolve_lists_available_scenes() {
        let dir = std::env::temp_dir().join(format!("unitac-scenes-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("a.yaml"), OK).unwrap();
        assert_eq!(
            resolve("a", std::slice::from_ref(&dir)).unwrap(),
            dir.join("a.yaml")
        );
        let e = resolve("b", std::slice::from_ref(&dir))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("scene 'b' not found") && e.contains("available: a"),
            "{e}"
        );
        std::fs::remove_dir_all(dir).ok();
    }

    #[test]
    fn sensor_arg() {
        assert_eq!("mock".parse(), Ok(SensorArg::Mock));
        assert_eq!(
            "v4l:D00045".parse(),
            Ok(SensorArg::V4l(Some("D00045".into())))
        );
        assert_eq!("bag:/x".parse(), Ok(SensorArg::Bag("/x".into())));
        assert!("usb".parse::<SensorArg>().is_err());
    }
}
