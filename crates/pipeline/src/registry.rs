//! Stage kinds and sources a scene can name, and how each is built.

use serde::de::DeserializeOwned;
use std::path::PathBuf;
use unitac_bag::{BagSource, ReplayOptions};
use unitac_contact::{ContactParams, ContactStage, SlipParams, SlipStage};
use unitac_core::graph::StageGraph;
use unitac_core::scene::{SceneContext, SceneError, SensorArg, SourceKind, StageSpec};
use unitac_core::{Scene, Source, Stage};

use unitac_infer::RuntimeConfig;
use unitac_infer::encoder::{CompareParams, CompareStage, EncoderStage};
use unitac_infer::predict::{SamplerParams, SamplerStage};
use unitac_policy::{PolicyParams, PolicyStage};
use unitac_sim::{MockConfig, MockSensor, Scenario};

/// Where scene names are looked up: `extra` first, then `UNITAC_SCENES`, `$UNITAC_ROOT/launch/scenes`,
/// `./launch/scenes` and the source tree this binary was built from.
pub fn scene_dirs(extra: Option<PathBuf>) -> Vec<PathBuf> {
    let mut dirs: Vec<PathBuf> = extra.into_iter().collect();
    if let Some(d) = std::env::var_os("UNITAC_SCENES") {
        dirs.push(d.into());
    }
    if let Some(root) = std::env::var_os("UNITAC_ROOT") {
        dirs.push(PathBuf::from(root).join("launch/scenes"));
    }
    dirs.push(PathBuf::from("launch/scenes"));
    dirs.push(PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../launch/scenes"
    )));
    dirs
}

/// What scenes are checked against: the stage kinds built here, and `${UNITAC_MODELS}` (the
/// environment's, else `$UNITAC_ROOT/.build/models`, else the source tree's).
pub fn scene_context() -> SceneContext {
    let mut ctx = SceneContext {
        known_stages: KNOWN_STAGES.iter().map(|s| s.to_string()).collect(),
        graph: graph().clone(),
        ..Default::default()
    };
    let models = std::env::var_os("UNITAC_MODELS")
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            let root = std::env::var_os("UNITAC_ROOT")
                .map(PathBuf::from)
                .unwrap_or_else(|| PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../..")));
            root.join(".build/models")
        });
    ctx.vars.insert("UNITAC_MODELS".into(), models);
    ctx
}

/// Stage kinds a scene may name.
pub const KNOWN_STAGES: &[&str] = &["contact", "slip", "encoder", "compare", "sampler", "policy"];
/// The shipped stage graph (launch/stage_graph.yaml, compiled in; a test checks that it
/// parses and declares exactly [`KNOWN_STAGES`]).
pub fn graph() -> &'static StageGraph {
    static GRAPH: std::sync::OnceLock<StageGraph> = std::sync::OnceLock::new();
    GRAPH.get_or_init(|| StageGraph::shipped().unwrap_or_default())
}

fn params<T: DeserializeOwned + Default>(
    scene: &Scene,
    index: usize,
    st: &StageSpec,
) -> Result<T, SceneError> {
    if st.params.is_null() {
        return Ok(T::default());
    }
    serde_yaml::from_value(st.params.clone()).map_err(|e| SceneError::BadValue {
        path: scene.path.clone(),
        field: format!("stages[{index}].params ({})", st.kind),
        msg: e
            .to_string()
            .split_whitespace()
            .collect::<Vec<_>>()
            .join(" "),
    })
}

/// A stage of a scene with its typed parameters, checked, before anything is loaded. The one
/// place scene params become the structs the stages take, for every transport.
#[derive(Debug, Clone, PartialEq)]
pub enum StageConfig {
    Contact {
        params: ContactParams,
        sensor: unitac_core::SensorSpec,
    },
    Slip {
        params: SlipParams,
        sensor: unitac_core::SensorSpec,
    },
    Encoder {
        runtime: RuntimeConfig,
        bundle: PathBuf,
    },
    Compare(CompareParams),
    Sampler {
        params: SamplerParams,
        bundle: PathBuf,
    },
    /// The scene's name goes into PolicyStatus.scene; `model`: the bundle directory the stage
    /// names in `models:`: the learned policy itself (`policy: learned`), or the scene
    /// controller's fitted latent -> stiffness model (none: the params' linear readout).
    Policy {
        params: Box<PolicyParams>,
        scene: String,
        model: Option<PathBuf>,
    },
}

impl StageConfig {
    /// The scene's stage kind.
    pub fn kind(&self) -> &'static str {
        match self {
            StageConfig::Contact { .. } => "contact",
            StageConfig::Slip { .. } => "slip",
            StageConfig::Encoder { .. } => "encoder",
            StageConfig::Compare(_) => "compare",
            StageConfig::Sampler { .. } => "sampler",
            StageConfig::Policy { .. } => "policy",
        }
    }
}

/// The model bundle directory of a stage that names exactly one model.
fn bundle_of(
    scene: &Scene,
    st: &StageSpec,
    bad: &dyn Fn(String) -> SceneError,
) -> Result<PathBuf, SceneError> {
    let [name] = st.models.as_slice() else {
        return Err(bad(format!(
            "a {} stage names exactly one model bundle in models:",
            st.kind
        )));
    };
    // Scene::load checked that the file exists; the bundle is the manifest's directory.
    let manifest = scene
        .models
        .get(name)
        .ok_or_else(|| bad(format!("model '{name}' not loaded")))?;
    Ok(manifest
        .parent()
        .unwrap_or(std::path::Path::new("."))
        .to_path_buf())
}

/// Every stage's typed parameters, in order; fails on the first bad one (one line).
pub fn stage_configs(scene: &Scene) -> Result<Vec<StageConfig>, SceneError> {
    let spec = scene.source.sensor.spec();
    let mut out = Vec::new();
    for (i, st) in scene.stages.iter().enumerate() {
        let index = i + 1;
        let bad = |msg: String| SceneError::BadValue {
            path: scene.path.clone(),
            field: format!("stages[{index}].params ({})", st.kind),
            msg,
        };
        out.push(match st.kind.as_str() {
            "contact" => {
                let params: ContactParams = params(scene, index, st)?;
                params.check().map_err(|e| bad(e.to_string()))?;
                StageConfig::Contact {
                    params,
                    sensor: spec,
                }
            }
            "slip" => {
                let params: SlipParams = params(scene, index, st)?;
                // A sensor without marker dots is refused here, naming it.
                params
                    .check_for(spec.kind)
                    .map_err(|e| bad(e.to_string()))?;
                StageConfig::Slip {
                    params,
                    sensor: spec,
                }
            }
            "encoder" => StageConfig::Encoder {
                runtime: params(scene, index, st)?,
                bundle: bundle_of(scene, st, &bad)?,
            },
            "sampler" => StageConfig::Sampler {
                params: params(scene, index, st)?,
                bundle: bundle_of(scene, st, &bad)?,
            },
            "compare" => StageConfig::Compare(params(scene, index, st)?),
            "policy" => {
                let params: PolicyParams = params(scene, index, st)?;
                params.check().map_err(|e| bad(e.to_string()))?;
                let model = if st.models.is_empty() {
                    None
                } else {
                    Some(bundle_of(scene, st, &bad)?)
                };
                StageConfig::Policy {
                    params: Box::new(params),
                    scene: scene.name.clone(),
                    model,
                }
            }
            other => {
                return Err(SceneError::UnknownStage {
                    path: scene.path.clone(),
                    index,
                    kind: other.to_string(),
                    known: KNOWN_STAGES.join(", "),
                });
            }
        });
    }
    Ok(out)
}

/// The policy stages' modes against the scene's full stage list (before a transport keeps only
/// the stages it runs): every input a mode reads that a stage produces has its producer before
/// the policy stage, and no stage runs whose output the mode does not use. One line.
pub fn check_modes(scene: &Scene) -> Result<(), SceneError> {
    for (i, st) in scene.stages.iter().enumerate() {
        if st.kind != "policy" {
            continue;
        }
        let index = i + 1;
        let p: PolicyParams = params(scene, index, st)?;
        let before: Vec<&str> = scene.stages[..i].iter().map(|s| s.kind.as_str()).collect();
        unitac_policy::check_scene(&p, &before, &graph().stage_needs()).map_err(|e| {
            SceneError::BadValue {
                path: scene.path.clone(),
                field: format!("stages[{index}].params (policy)"),
                msg: e.to_string(),
            }
        })?;
    }
    Ok(())
}

/// Build one stage (loads its models).
pub fn build_stage(scene: &Scene, cfg: StageConfig) -> Result<Box<dyn Stage>, SceneError> {
    let kind = cfg.kind();
    let bad = |msg: String| SceneError::BadValue {
        path: scene.path.clone(),
        field: format!("stage {kind}"),
        msg,
    };
    Ok(match cfg {
        StageConfig::Contact { params, sensor } => {
            let cal = match &params.depth_calibration {
                Some(path) => {
                    let cal = unitac_contact::depth::DepthCalibration::load(path)
                        .map_err(|e| bad(e.to_string()))?;
                    if cal.sensor != sensor.kind {
                        return Err(bad(format!(
                            "depth calibration {} is for a {}, the scene's sensor is a {}",
                            path.display(),
                            cal.sensor,
                            sensor.kind
                        )));
                    }
                    cal.m_per_px_at(sensor.width, sensor.height)
                        .map_err(|e| bad(format!("depth calibration {}: {e}", path.display())))?;
                    Some(cal)
                }
                None => None,
            };
            let stage = ContactStage::new(params, sensor).map_err(|e| bad(e.to_string()))?;
            Box::new(match cal {
                Some(c) => stage.with_depth(c),
                None => stage,
            })
        }
        StageConfig::Slip { params, sensor } => {
            Box::new(SlipStage::new(params, sensor).map_err(|e| bad(e.to_string()))?)
        }
        StageConfig::Encoder { runtime, bundle } => Box::new(
            EncoderStage::new(&bundle, &runtime)
                .map_err(|e| bad(format!("model {}: {e}", bundle.display())))?,
        ),
        StageConfig::Sampler { params, bundle } => Box::new(
            SamplerStage::new(&bundle, params)
                .map_err(|e| bad(format!("model {}: {e}", bundle.display())))?,
        ),
        StageConfig::Compare(p) => Box::new(CompareStage::new(p).map_err(|e| bad(e.to_string()))?),
        StageConfig::Policy {
            params,
            scene,
            model,
        } => Box::new(
            PolicyStage::load(&scene, *params, model.as_deref()).map_err(|e| bad(e.to_string()))?,
        ),
    })
}

/// Build every stage of the scene, in order. Fails before anything runs.
pub fn build_stages(scene: &Scene) -> Result<Vec<Box<dyn Stage>>, SceneError> {
    stage_configs(scene)?
        .into_iter()
        .map(|c| build_stage(scene, c))
        .collect()
}

/// The frame source: the scene's, or the command line's `--sensor` override.
pub fn build_source(scene: &Scene, arg: Option<&SensorArg>) -> Result<Box<dyn Source>, SceneError> {
    let kind = match arg {
        Some(SensorArg::Mock) => SourceKind::Mock,
        Some(SensorArg::V4l(_)) => SourceKind::V4l,
        Some(SensorArg::Bag(_)) => SourceKind::Bag,
        None => scene.source.kind,
    };
    let bad = |field: &str, msg: String| SceneError::BadValue {
        path: scene.path.clone(),
        field: field.to_string(),
        msg,
    };
    match kind {
        SourceKind::Mock => {
            let name = scene
                .source
                .scenario
                .clone()
                .unwrap_or_else(|| scene.name.clone());
            let scenario =
                Scenario::by_name(&name).map_err(|e| bad("source.scenario", e.to_string()))?;
            let mut cfg = MockConfig::new(scene.source.sensor, scene.source.seed);
            if let Some(fps) = scene.source.fps {
                cfg.fps = fps;
            }
            if let Some(id) = scene.source.sensor_id.clone() {
                cfg.sensor_id = id;
            }
            Ok(Box::new(MockSensor::new(cfg, scenario)))
        }
        SourceKind::V4l => {
            let serial = match arg {
                Some(SensorArg::V4l(s)) => s.clone(),
                _ => scene.source.serial.clone(),
            };
            #[cfg(feature = "v4l")]
            {
                crate::v4l::open_v4l(scene.source.sensor, serial.as_deref())
                    .map_err(|(field, msg)| bad(field, msg))
            }
            #[cfg(not(feature = "v4l"))]
            {
                let _ = serial;
                Err(bad(
                    "source.kind",
                    "this build has no live sensors (the pipeline's v4l feature is off)".into(),
                ))
            }
        }
        SourceKind::Bag => {
            let path = match arg {
                Some(SensorArg::Bag(p)) => p.clone(),
                _ => scene
                    .source
                    .path
                    .clone()
                    .ok_or_else(|| bad("source.path", "a bag source needs a path".into()))?,
            };
            let opts = ReplayOptions {
                sensor_id: scene.source.sensor_id.clone(),
                ..ReplayOptions::default()
            };
            let src =
                BagSource::open(&path, opts).map_err(|e| bad("source.path", e.to_string()))?;
            Ok(Box::new(src))
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::panic)]
    use super::*;

    /// A scene on `sensor` with these stages (YAML flow list).
    fn scene(name: &str, sensor: &str, stages: &str) -> Result<Scene, SceneError> {
        let dir = std::env::temp_dir().join(format!("unitac-registry-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join(format!("{name}.yaml"));
        std::fs::write(
            &path,
            format!(
                "scene: {name}\nsource: {{kind: mock, sensor: {sensor}, scenario: fabric_selection}}\n\
                 stages: {stages}\n"
            ),
        )
        .unwrap();
        Scene::load(&path, &scene_context())
    }

    #[test]
    fn a_slip_stage_gets_its_typed_params_after_contact_on_a_marker_gel() {
        let s = scene(
            "slip_ok",
            "gelsight-mini",
            "[{kind: contact}, {kind: slip, params: {slip_on: 0.2, slip_off: 0.1}}]",
        )
        .unwrap();
        let cfgs = stage_configs(&s).unwrap();
        let StageConfig::Slip { params, sensor } = &cfgs[1] else {
            panic!("{cfgs:?}")
        };
        assert_eq!((params.slip_on, params.slip_off), (0.2, 0.1));
        assert_eq!(sensor.kind, unitac_core::SensorKind::GELSIGHT_MINI);
        assert_eq!(build_stages(&s).unwrap()[1].name(), "slip");
    }

    #[test]
    fn a_slip_stage_on_a_digit_or_before_contact_is_refused_at_load() {
        let s = scene("slip_digit", "digit", "[{kind: contact}, {kind: slip}]").unwrap();
        let e = stage_configs(&s).unwrap_err().to_string();
        assert!(e.contains("digit") && e.contains("slip"), "{e}");
        let e = scene(
            "slip_first",
            "gelsight-mini",
            "[{kind: slip}, {kind: contact}]",
        );
        assert!(e.is_err(), "{e:?}");
        let s = scene(
            "slip_bad",
            "gelsight-mini",
            "[{kind: contact}, {kind: slip, params: {slip_on: 0.1, slip_off: 0.3}}]",
        )
        .unwrap();
        let e = stage_configs(&s).unwrap_err().to_string();
        assert!(e.contains("slip_off"), "{e}");
    }

    #[test]
    fn a_depth_calibration_is_loaded_and_checked_against_the_scene_sensor() {
        use unitac_contact::depth::{DepthCalibration, GradientModel, model::FEATURES};
        use unitac_core::SensorKind;
        let dir = std::env::temp_dir().join(format!("unitac-registry-cal-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let cal = |name: &str, sensor: SensorKind, w: u32, h: u32| {
            let c = DepthCalibration {
                format: unitac_contact::depth::model::FORMAT,
                sensor,
                serial: String::new(),
                width: w,
                height: h,
                m_per_px: 6.34e-5,
                ball_radius_m: 0.002,
                presses_used: 30,
                fit_rms_slope: 0.01,
                model: GradientModel {
                    gx: vec![0.0; FEATURES],
                    gy: vec![0.0; FEATURES],
                },
            };
            let p = dir.join(name);
            c.save(&p).unwrap();
            p
        };
        let with = |name: &str, path: &std::path::Path| {
            scene(
                name,
                "gelsight-mini",
                &format!(
                    "[{{kind: contact, params: {{depth_calibration: {}}}}}]",
                    path.display()
                ),
            )
            .unwrap()
        };
        let good = cal("good.json", SensorKind::GELSIGHT_MINI, 640, 480);
        assert_eq!(
            build_stages(&with("depth_ok", &good)).unwrap()[0].name(),
            "contact"
        );
        let digit = cal("digit.json", SensorKind::DIGIT, 320, 240);
        let e = build_stages(&with("depth_digit", &digit))
            .err()
            .unwrap()
            .to_string();
        assert!(e.contains("digit") && e.contains("gelsight-mini"), "{e}");
        let square = cal("square.json", SensorKind::GELSIGHT_MINI, 320, 320);
        let e = build_stages(&with("depth_square", &square))
            .err()
            .unwrap()
            .to_string();
        assert!(e.contains("aspect ratio"), "{e}");
        let e = build_stages(&with("depth_missing", &dir.join("none.json")))
            .err()
            .unwrap()
            .to_string();
        assert!(e.contains("none.json"), "{e}");
        std::fs::write(dir.join("junk.json"), "{\"format\": 1}").unwrap();
        let e = build_stages(&with("depth_junk", &dir.join("junk.json")))
            .err()
            .unwrap()
            .to_string();
        assert!(e.contains("junk.json"), "{e}");
        std::fs::remove_dir_all(&dir).ok();
    }
}
