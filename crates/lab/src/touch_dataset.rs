//! `unitac-lab dataset touch --split train|unseen --seeds 1,2 --trials N --sensor S --out DIR`: what
//! is known about an object before it is touched, paired with what the touch encoder says when
//! it is touched, for the touch projector (python/unitac_tools/train_projector.py).
//!
//! For each (seed, trial) of the split: the cup task's cup and the fabric task's two fabrics, each
//! one sample of
//! - `visual`: the camera's values of the object before contact (its task world's camera model,
//!   with its per-trial bias and noise), keyed by field as the VisualObservation message names
//!   them without the object (`width_m`, `height_m`, `edge_height_m`, `roughness`, ...);
//! - `category`: `cup` or `fabric` (the object's camera name without its `_a`/`_b`);
//! - `sensor_prior`: Z_sen, the encoder's sensor tokens of the background of this sample's sensor;
//! - `latent`: the pooled encoder latent of the touch, [2, 48] row-major: the token mean and the
//!   token mean of squares (what the property head reads, and the stiffness readout of
//!   predicted latents);
//! - `truth`: labels for evaluation only (cups: diameter and stiffness; fabrics: type, Ra,
//!   hardness), never part of a condition.
//!
//! Cups are touched by the probe the cup controllers make (`unitac_trials::demos`, through the
//! `cup_deformation_vtla_real` scene's tactile stages); fabrics by a press whose depth follows
//! their hardness (as `dataset fabrics`), through the contact stage and the encoder. Written as
//! `DIR/touch.json`. Same arguments, same bytes.

use crate::dataset::{first_clip, press};
use anyhow::{Context, bail};
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use unitac_cli::ConfigError;
use unitac_contact::{ContactParams, ContactStage};
use unitac_core::{Chain, Frame, Msg, SensorKind};
use unitac_infer::Bundle;
use unitac_infer::encoder::EncoderStage;
use unitac_infer::prior::SensorPrior;
use unitac_pipeline::{StageConfig, build_stage, load_scene_without_policy_models, stage_configs};
use unitac_sim::task::{self, ObjectSpec, Split, TaskConfig, TaskWorld, trial_rng};
use unitac_sim::{MockConfig, MockSensor};
use unitac_trials::bridge::visual_message;
use unitac_trials::demos::{DemoConfig, demo_sensor, pooled, record};

/// Most (seed, trial) pairs one run records.
pub const MAX_TRIALS: usize = 5_000;
/// Salt of the camera noise stream of a touch sample.
const CAMERA_SALT: u64 = 0x544F_5543_4843_414D;
/// The scene whose tactile stages touch the cups.
const CUP_SCENE: &str = "cup_deformation_vtla_real";
/// Fabric press depth for hardness 0 and 1 \[mm] (as `dataset fabrics`).
const DEPTH_MM: (f64, f64) = (0.25, 0.75);

#[derive(Serialize)]
struct Sample {
    category: &'static str,
    object: String,
    seed: u64,
    trial: u32,
    visual: BTreeMap<String, f64>,
    sensor_prior: Vec<f32>,
    latent: Vec<f32>,
    truth: serde_json::Value,
}

#[derive(Serialize)]
struct TouchFile<'a> {
    split: Split,
    sensor: SensorKind,
    seeds: &'a [u64],
    trials: u32,
    latent_shape: [u32; 2],
    samples: Vec<Sample>,
}

/// The camera's values of `object` as the VisualObservation message names them
/// (`<object>_<field>`), keyed by field.
fn object_values(v: &task::VisualObservation, object: &str) -> BTreeMap<String, f64> {
    let m = visual_message(v);
    let prefix = format!("{object}_");
    m.names
        .iter()
        .zip(&m.values)
        .filter_map(|(n, x)| n.strip_prefix(&prefix).map(|f| (f.to_string(), *x)))
        .collect()
}

/// The contact stage's background of an idle sensor.
pub fn background_of(mut sensor: MockSensor, kind: SensorKind) -> anyhow::Result<Frame> {
    let stage =
        ContactStage::new(ContactParams::default(), kind.spec()).map_err(anyhow::Error::msg)?;
    let mut chain = Chain::new(vec![Box::new(stage)]);
    while let Some((f, _)) = sensor.next_with_truth() {
        let out = chain.run(Msg::Frame(f));
        if let Some(e) = out.errors.first() {
            bail!("{e}");
        }
        if let Some(bg) = out.produced.into_iter().find_map(|m| match m {
            Msg::Background(b) => Some(b),
            _ => None,
        }) {
            return Ok(bg);
        }
    }
    bail!("the contact stage learnt no background")
}

/// The two fabrics of trial `seed`/`trial` of `split`: the camera's values, then the encoder's
/// latent of a press of each on the mock sensor, with the sensor prior of its background.
fn fabric_samples(
    split: Split,
    seed: u64,
    trial: u32,
    sensor: &MockConfig,
    clip_frames: u32,
    (encoder, prior): (&mut EncoderStage, &mut SensorPrior),
) -> anyhow::Result<Vec<Sample>> {
    let at = |what: &str| format!("seed {seed} trial {trial}: {what}");
    let mut samples = Vec::new();
    let world = TaskWorld::reset(&TaskConfig::fabric(split), seed, trial);
    let visual = world.observe_visual(&mut trial_rng(seed ^ CAMERA_SALT, trial));
    for (k, o) in world.spec().objects.iter().enumerate() {
        let ObjectSpec::Fabric(f) = &o.spec else {
            continue;
        };
        let depth = DEPTH_MM.0 + (DEPTH_MM.1 - DEPTH_MM.0) * f.fabric.hardness;
        let mut cfg = demo_sensor(sensor, seed, trial).config().clone();
        cfg.seed = cfg.seed.wrapping_add(1 + k as u64);
        let s = MockSensor::new(cfg, press(&f.fabric.object(&o.name), depth));
        let clip = first_clip(s, clip_frames * 2).with_context(|| at(&o.name))?;
        let bg = clip
            .background
            .clone()
            .with_context(|| at("clip without background"))?;
        let e = encoder
            .encode(&clip)
            .map_err(|e| anyhow::anyhow!(at(&e.to_string())))?;
        let w = e.tok_shape.last().copied().unwrap_or(1).max(1) as usize;
        samples.push(Sample {
            category: "fabric",
            object: o.name.clone(),
            seed,
            trial,
            visual: object_values(&visual, &o.name),
            sensor_prior: prior.of(&bg)?,
            latent: pooled(&e.tokens, w),
            truth: serde_json::json!({
                "type": f.fabric.name,
                "roughness_ra_m": f.roughness_ra_m,
                "hardness": f.fabric.hardness,
            }),
        });
    }
    Ok(samples)
}

pub fn touch(
    split: Split,
    seeds: &[u64],
    trials: u32,
    kind: SensorKind,
    out: &Path,
) -> anyhow::Result<String> {
    let n = seeds.len().saturating_mul(trials as usize);
    if n == 0 || n > MAX_TRIALS {
        return Err(anyhow::Error::new(ConfigError(format!(
            "{n} trials asked for (seeds x trials: 1 to {MAX_TRIALS})"
        ))));
    }
    let mut scene = load_scene_without_policy_models(CUP_SCENE, None)?;
    scene.source.sensor = kind;
    let configs: Vec<StageConfig> = stage_configs(&scene)?
        .into_iter()
        .filter(|c| !matches!(c, StageConfig::Policy { .. }))
        .collect();
    let bundle: PathBuf = configs
        .iter()
        .find_map(|c| match c {
            StageConfig::Encoder { bundle, .. } => Some(bundle.clone()),
            _ => None,
        })
        .with_context(|| format!("scene {CUP_SCENE} has no encoder stage"))?;
    let opened = Bundle::open(&bundle)?;
    let runtime = unitac_infer::RuntimeConfig::default();
    let enc_model = opened
        .load(&["encoder"], &runtime)?
        .into_iter()
        .next()
        .context("no encoder")?;
    let pre = opened.manifest.preprocess.clone();
    let mut prior = SensorPrior::new(pre.clone(), enc_model);
    let mut encoder = EncoderStage::new(&bundle, &runtime)?;
    let mut sensor = MockConfig::new(kind, scene.source.seed);
    if let Some(fps) = scene.source.fps {
        sensor.fps = fps;
    }
    let demo_cfg = DemoConfig {
        run_s: Some(0.0),
        ..DemoConfig::default()
    };
    let bar = crate::progress::bar(n as u64, "touch");
    let mut samples = Vec::new();
    for &seed in seeds {
        for trial in 0..trials {
            let at = |what: &str| format!("seed {seed} trial {trial}: {what}");
            // The cup: its camera values, the background's Z_sen, the probe's latent.
            let world = TaskWorld::reset(&TaskConfig::cup(split), seed, trial);
            let visual = world.observe_visual(&mut trial_rng(seed ^ CAMERA_SALT, trial));
            let stages = configs
                .iter()
                .map(|c| build_stage(&scene, c.clone()))
                .collect::<Result<Vec<_>, _>>()?;
            let demo = record(split, seed, trial, &sensor, stages, &demo_cfg)?;
            let real = demo
                .latents
                .iter()
                .find(|l| l.source == "real" && l.touch == 1)
                .with_context(|| at("the cup's probe touch gave no latent"))?;
            let w = real.shape.last().copied().unwrap_or(1) as usize;
            let bg = background_of(demo_sensor(&sensor, seed, trial), kind)?;
            samples.push(Sample {
                category: "cup",
                object: "cup".into(),
                seed,
                trial,
                visual: object_values(&visual, "cup"),
                sensor_prior: prior.of(&bg)?,
                latent: pooled(&real.data, w),
                truth: serde_json::json!({
                    "diameter_m": demo.diameter_m,
                    "stiffness_n_per_m": demo.stiffness_n_per_m,
                }),
            });
            // The two fabrics: camera values, then a press of each.
            let fabrics = (&mut encoder, &mut prior);
            samples.extend(fabric_samples(
                split,
                seed,
                trial,
                &sensor,
                pre.clip_frames,
                fabrics,
            )?);
            bar.inc(1);
        }
    }
    bar.finish_and_clear();
    let w = samples.first().map_or(0, |s| s.latent.len() / 2) as u32;
    let file = TouchFile {
        split,
        sensor: kind,
        seeds,
        trials,
        latent_shape: [2, w],
        samples,
    };
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let path = out.join("touch.json");
    std::fs::write(&path, serde_json::to_string(&file)?)
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(format!(
        "{} touch samples ({:?} split, {kind:?}) in {}\n",
        file.samples.len(),
        split,
        path.display()
    ))
}
