//! `unitac demos --scene S --split train|unseen --seeds 1,2 --trials N --out DIR`: the scripted
//! expert's cup demonstrations with what a policy could observe (unitac_trials::demos), the
//! frames going through the scene's own tactile stages (every stage before its policy stage),
//! written as `DIR/demos.json` for scripts/fit_reference_policy.py.

use crate::ConfigError;
use anyhow::Context;
use serde::Serialize;
use std::path::Path;
use unitac_pipeline::{StageConfig, build_stage, load_scene_without_policy_models, stage_configs};
use unitac_sim::MockConfig;
use unitac_sim::task::Split;
use unitac_trials::demos::{Demo, DemoConfig, record};

/// Most demonstrations one run records.
pub const MAX_DEMOS: usize = 10_000;

#[derive(Serialize)]
struct DemoFile<'a> {
    scene: &'a str,
    split: Split,
    seeds: &'a [u64],
    trials: u32,
    config: &'a DemoConfig,
    demos: Vec<Demo>,
}

/// Record and write the demonstrations; a one-line summary comes back.
pub fn demos(
    scene_name: &str,
    split: Split,
    seeds: &[u64],
    trials: u32,
    out: &Path,
) -> anyhow::Result<String> {
    let n = seeds.len().saturating_mul(trials as usize);
    let config = |msg: String| anyhow::Error::new(ConfigError(msg));
    if n == 0 || n > MAX_DEMOS {
        return Err(config(format!(
            "{n} demonstrations asked for (seeds x trials: 1 to {MAX_DEMOS})"
        )));
    }
    let scene =
        load_scene_without_policy_models(scene_name, None).map_err(|e| config(e.to_string()))?;
    let configs = stage_configs(&scene).map_err(|e| config(e.to_string()))?;
    let mut cfg = DemoConfig::default();
    if let Some(p) = configs.iter().find_map(|c| match c {
        StageConfig::Policy { params, .. } => Some(params),
        _ => None,
    }) {
        if !p.task.starts_with("squeeze") {
            return Err(config(format!(
                "scene {}: demonstrations are recorded for the cup task, its task is '{}'",
                scene.name, p.task
            )));
        }
        cfg.touch_speed_m_s = p.touch_speed_m_s;
        cfg.touch_force_n = p.touch_force_n;
        cfg.probe_release_m = p.probe_release_m;
        cfg.timeout_s = p.contact_timeout_s;
    }
    let tactile: Vec<StageConfig> = configs
        .into_iter()
        .filter(|c| !matches!(c, StageConfig::Policy { .. }))
        .collect();
    if tactile.is_empty() {
        return Err(config(format!(
            "scene {} has no tactile stage: nothing a demonstration could observe",
            scene.name
        )));
    }
    let src = &scene.source;
    let mut sensor = MockConfig::new(src.sensor, src.seed);
    if let Some(fps) = src.fps {
        sensor.fps = fps;
    }
    if let Some(id) = src.sensor_id.clone() {
        sensor.sensor_id = id;
    }
    let bar = crate::progress::bar(n as u64, "demos");
    let mut demos = Vec::with_capacity(n);
    for &seed in seeds {
        for trial in 0..trials {
            let stages = tactile
                .iter()
                .map(|c| build_stage(&scene, c.clone()))
                .collect::<Result<Vec<_>, _>>()?;
            demos.push(record(split, seed, trial, &sensor, stages, &cfg)?);
            bar.inc(1);
        }
    }
    bar.finish_and_clear();
    let ok = demos.iter().filter(|d| d.success).count();
    let with_latent = demos.iter().filter(|d| !d.latents.is_empty()).count();
    let file = DemoFile {
        scene: &scene.name,
        split,
        seeds,
        trials,
        config: &cfg,
        demos,
    };
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let path = out.join("demos.json");
    let text = serde_json::to_string(&file)?;
    std::fs::write(&path, text).with_context(|| format!("writing {}", path.display()))?;
    Ok(format!(
        "{} demonstrations of {} ({:?} cups) in {}: {with_latent} with a latent, expert succeeded in {ok}\n",
        file.demos.len(),
        file.scene,
        split,
        path.display()
    ))
}
