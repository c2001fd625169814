//! `unitac-lab demos --scene S[,S2] [--mode M] --split train|unseen --seeds 1,2 --trials N --out DIR`:
//! the scripted expert's demonstrations for mode M (default: the first scene's mode) of the
//! scenes' task, with what a policy of every mode could observe (unitac_trials::demos), the
//! frames going through each scene's own tactile stages (every stage before its policy stage; one
//! chain per scene, the first one's contact state drives vtla_real's cup probe), written as
//! `DIR/demos.json` for python/unitac_tools/fit_reference_policy.py and python/unitac_tools/lerobot_dataset.py. The
//! expert decides from what M observes: vtla_real's demonstrations probe the cup and choose the
//! fabric from the live comparison, vla's and vtla_pred's do neither (the camera's guesses).
//!
//! `--drive L [--drive-model M]` (DAgger): the learned scene L (its policy bundle M if given)
//! drives the world through its own stages as in a trial, and every tick is labelled with the
//! expert's command there (unitac_trials::demos::record_driven).

use anyhow::Context;
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use unitac_cli::ConfigError;
use unitac_pipeline::{StageConfig, build_stage, load_scene_without_policy_models, stage_configs};
use unitac_policy::{Mode, PolicyParams};
use unitac_sim::MockConfig;
use unitac_sim::task::{Split, TaskKind};
use unitac_trials::demos::{
    Demo, DemoConfig, MAX_CHAINS, action_names, record_chains, record_driven,
};
use unitac_trials::scene::scene_task;

/// Most demonstrations one run records.
pub const MAX_DEMOS: usize = 10_000;

#[derive(Serialize)]
struct DemoFile<'a> {
    /// The scenes' names joined by '+'.
    scene: &'a str,
    scenes: &'a [String],
    /// The task as the first scene's policy states it (the dataset's task text).
    instruction: &'a str,
    split: Split,
    seeds: &'a [u64],
    trials: u32,
    config: &'a DemoConfig,
    /// The learned scene that drove the world (DAgger), if one did.
    driver: Option<&'a str>,
    /// The names of each tick's action values.
    action_names: Vec<&'static str>,
    /// Per action value, the range the first scene's safety layer holds it to: [min, max].
    action_bounds: BTreeMap<&'static str, [f64; 2]>,
    demos: Vec<Demo>,
}

/// The scene that drives the world instead of the expert, and the policy bundle it runs.
pub struct Driver {
    pub scene: String,
    pub model: Option<PathBuf>,
}

/// The expert's settings from the first scene's policy parameters (its task, the `mode` given
/// or the scene's, the probe's speed, force, release and timeouts).
fn demo_config(p: &PolicyParams, kind: TaskKind, mode: Option<&str>) -> anyhow::Result<DemoConfig> {
    let mode = match mode {
        Some(m) => m
            .parse::<Mode>()
            .map_err(|e| anyhow::Error::new(ConfigError(e.to_string())))?,
        None => p.mode,
    };
    Ok(DemoConfig {
        task: kind,
        mode,
        touch_speed_m_s: p.touch_speed_m_s,
        touch_force_n: p.touch_force_n,
        probe_release_m: p.probe_release_m,
        approach_s: p.approach_s,
        timeout_s: p.contact_timeout_s,
        ..DemoConfig::default()
    })
}

/// The scene that drives the world (its policy bundle replaced by `d.model`), of the
/// demonstrations' `task`, its stages built once so a bad bundle fails before any
/// demonstration runs.
fn driving_scene(d: Driver, task: Option<TaskKind>) -> anyhow::Result<unitac_core::Scene> {
    let config = |msg: String| anyhow::Error::new(ConfigError(msg));
    let mut scene =
        unitac_pipeline::load_scene(&d.scene, None).map_err(|e| config(e.to_string()))?;
    if let Some(m) = d.model {
        scene.models.insert("policy".into(), m);
    }
    let (p, kind) = scene_task(&scene).map_err(|e| config(e.to_string()))?;
    if Some(kind) != task {
        return Err(config(format!(
            "driving scene {}: its task is '{}', the demonstrations' is another",
            scene.name, p.task
        )));
    }
    // Built once here so a bad bundle fails before any demonstration runs.
    unitac_pipeline::build_stages(&scene).map_err(|e| config(e.to_string()))?;
    Ok(scene)
}

/// A recording scene's stages without its policy: what a demonstration observes (at least one).
fn tactile_stages(scene: &unitac_core::Scene) -> anyhow::Result<Vec<StageConfig>> {
    let config = |msg: String| anyhow::Error::new(ConfigError(msg));
    let tactile: Vec<StageConfig> = stage_configs(scene)
        .map_err(|e| config(e.to_string()))?
        .into_iter()
        .filter(|c| !matches!(c, StageConfig::Policy { .. }))
        .collect();
    if tactile.is_empty() {
        return Err(config(format!(
            "scene {} has no tactile stage: nothing a demonstration could observe",
            scene.name
        )));
    }
    Ok(tactile)
}

/// The mock sensor of the first scene's source (its kind, seed, rate and id).
fn mock_sensor(src: &unitac_core::scene::SourceSpec) -> MockConfig {
    let mut sensor = MockConfig::new(src.sensor, src.seed);
    if let Some(fps) = src.fps {
        sensor.fps = fps;
    }
    if let Some(id) = src.sensor_id.clone() {
        sensor.sensor_id = id;
    }
    sensor
}

/// Record and write the demonstrations; a one-line summary comes back.
pub fn demos(
    scene_names: &[String],
    split: Split,
    seeds: &[u64],
    trials: u32,
    out: &Path,
    driver: Option<Driver>,
    mode: Option<&str>,
) -> anyhow::Result<String> {
    let n = seeds.len().saturating_mul(trials as usize);
    let config = |msg: String| anyhow::Error::new(ConfigError(msg));
    if n == 0 || n > MAX_DEMOS {
        return Err(config(format!(
            "{n} demonstrations asked for (seeds x trials: 1 to {MAX_DEMOS})"
        )));
    }
    if scene_names.is_empty() || scene_names.len() > MAX_CHAINS {
        return Err(config(format!(
            "{} scenes named (1 to {MAX_CHAINS})",
            scene_names.len()
        )));
    }
    let mut cfg = DemoConfig::default();
    let mut scenes = Vec::new();
    let mut task: Option<TaskKind> = None;
    let mut instruction = String::new();
    let mut action_bounds = BTreeMap::new();
    for (k, name) in scene_names.iter().enumerate() {
        let scene =
            load_scene_without_policy_models(name, None).map_err(|e| config(e.to_string()))?;
        let (p, kind) = scene_task(&scene).map_err(|e| config(e.to_string()))?;
        if task.is_some_and(|t| t != kind) {
            return Err(config(format!(
                "scene {}: its task is '{}', another scene's is the {} task",
                scene.name,
                p.task,
                task.map_or("", |t| t.name())
            )));
        }
        task = Some(kind);
        if k == 0 {
            instruction.clone_from(&p.task);
            cfg = demo_config(&p, kind, mode)?;
            action_bounds = p
                .bounds()
                .ranges()
                .into_iter()
                .map(|(k, lo, hi)| (k, [lo, hi]))
                .collect();
        }
        let tactile = tactile_stages(&scene)?;
        scenes.push((scene, tactile));
    }
    let Some((first, _)) = scenes.first() else {
        return Err(config("no scene".into()));
    };
    let driver = match driver {
        Some(d) => Some(driving_scene(d, task)?),
        None => None,
    };
    let sensor = mock_sensor(&first.source);
    let bar = crate::progress::bar(n as u64, "demos");
    let mut demos = Vec::with_capacity(n);
    for &seed in seeds {
        for trial in 0..trials {
            let mut chains = Vec::with_capacity(scenes.len());
            for (scene, tactile) in &scenes {
                chains.push(
                    tactile
                        .iter()
                        .map(|c| build_stage(scene, c.clone()))
                        .collect::<Result<Vec<_>, _>>()?,
                );
            }
            let demo = match &driver {
                Some(scene) => record_driven(
                    split,
                    seed,
                    trial,
                    &sensor,
                    chains,
                    unitac_pipeline::build_stages(scene)?,
                    &cfg,
                )?,
                None => record_chains(split, seed, trial, &sensor, chains, &cfg)?,
            };
            demos.push(demo);
            bar.inc(1);
        }
    }
    bar.finish_and_clear();
    let joined = scenes
        .iter()
        .map(|(s, _)| s.name.as_str())
        .collect::<Vec<_>>()
        .join("+");
    let names: Vec<String> = scenes.iter().map(|(s, _)| s.name.clone()).collect();
    let file = DemoFile {
        scene: &joined,
        scenes: &names,
        instruction: &instruction,
        split,
        seeds,
        trials,
        config: &cfg,
        driver: driver.as_ref().map(|s| s.name.as_str()),
        action_names: action_names(),
        action_bounds,
        demos,
    };
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let path = out.join("demos.json");
    let text = serde_json::to_string(&file)?;
    std::fs::write(&path, text).with_context(|| format!("writing {}", path.display()))?;
    Ok(summary(&file, &path))
}

/// The one-line summary of a demonstration file written to `path`.
fn summary(file: &DemoFile<'_>, path: &Path) -> String {
    let ok = file.demos.iter().filter(|d| d.success).count();
    let with_latent = file.demos.iter().filter(|d| !d.latents.is_empty()).count();
    let objects = file.config.task.objects();
    let who = file
        .driver
        .map_or_else(|| "expert".to_string(), |d| format!("driver {d}"));
    format!(
        "{} demonstrations of {} ({:?} {objects}) in {}: {with_latent} with a latent, {who} succeeded in {ok}, deciding as {} observes\n",
        file.demos.len(),
        file.scene,
        file.split,
        path.display(),
        file.config.mode.as_str()
    )
}
