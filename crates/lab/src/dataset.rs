//! `unitac-lab dataset fabrics`: mock-sensor presses on fabrics with known properties, run through
//! the real contact stage and the encoder's preprocessing, written for the reference bundle's
//! fitting script (python/unitac_tools/generate_reference.py).
//!
//! Output directory: `clips.f32` (N x T x 3 x S x S), `backgrounds.f32` (N x 3 x S x S),
//! `labels.jsonl` (one object per sample: hardness, roughness, texture in 0..1, the physical
//! values, split), `meta.json`.

use anyhow::{Context, bail};
use std::io::Write;
use std::path::Path;
use unitac_contact::{ContactParams, ContactStage};
use unitac_core::chain::ChainOutput;
use unitac_core::msg::ContactClip;
use unitac_core::{Chain, Msg, SensorKind};
use unitac_infer::preprocess::Preprocess;
use unitac_sim::{MockConfig, MockSensor, Object, Phase, Scenario, SplitMix64};

/// Property ranges of the generated fabrics and their 0..1 scores.
pub const ROUGHNESS_MM: (f64, f64) = (0.005, 0.08);
pub const PERIOD_MM: (f64, f64) = (0.4, 1.6);
/// Press depth for hardness 0 and 1 at the same grip force: a harder fabric indents the gel more.
pub const DEPTH_MM: (f64, f64) = (0.25, 0.75);

/// A fabric drawn from the ranges above, and its scores (hardness, roughness, texture).
pub fn fabric(rng: &mut SplitMix64, label: &str) -> (Object, f64, [f64; 3]) {
    let u = |rng: &mut SplitMix64, (a, b): (f64, f64)| a + (b - a) * rng.uniform();
    let roughness = u(rng, ROUGHNESS_MM);
    let period = u(rng, PERIOD_MM);
    let hardness = rng.uniform();
    let depth = DEPTH_MM.0 + (DEPTH_MM.1 - DEPTH_MM.0) * hardness;
    let scores = [
        hardness,
        (roughness - ROUGHNESS_MM.0) / (ROUGHNESS_MM.1 - ROUGHNESS_MM.0),
        (period - PERIOD_MM.0) / (PERIOD_MM.1 - PERIOD_MM.0),
    ];
    (Object::new(label, 6.0, roughness, period), depth, scores)
}

/// One short press: learn the background, press, hold, release.
pub fn press(object: &Object, depth: f64) -> Scenario {
    let free = |d| Phase {
        duration_s: d,
        object: None,
        from_mm: 0.0,
        to_mm: 0.0,
    };
    let on = |d, a, b| Phase {
        duration_s: d,
        object: Some(object.clone()),
        from_mm: a,
        to_mm: b,
    };
    Scenario {
        name: "dataset_press".into(),
        phases: vec![
            free(0.5),
            on(0.4, -0.1, depth),
            on(0.6, depth, depth),
            on(0.3, depth, -0.1),
            free(0.2),
        ],
        grip: Vec::new(),
    }
}

/// The first contact episode's clip of `sensor` through a contact stage keeping `clip_frames`
/// frames, driven by the one chain driver (the stage's clock is each frame's stamp, as in every
/// transport).
pub fn first_clip(mut sensor: MockSensor, clip_frames: u32) -> anyhow::Result<ContactClip> {
    let kind = sensor.config().sensor;
    let p = ContactParams {
        clip_frames,
        ..Default::default()
    };
    let stage = ContactStage::new(p, kind.spec()).map_err(anyhow::Error::msg)?;
    let mut chain = Chain::new(vec![Box::new(stage)]);
    let mut clip = None;
    let mut keep = |out: ChainOutput| -> anyhow::Result<()> {
        if let Some(e) = out.errors.first() {
            bail!("{e}");
        }
        for m in out.produced {
            if let Msg::ContactClip(c) = m {
                clip.get_or_insert(c);
            }
        }
        Ok(())
    };
    while let Some((f, _)) = sensor.next_with_truth() {
        keep(chain.run(Msg::Frame(f)))?;
    }
    keep(chain.finish())?;
    clip.context("the contact stage found no episode")
}

/// Run one press through the contact stage; the episode's clip, preprocessed.
pub fn clip_of(
    kind: SensorKind,
    seed: u64,
    scenario: Scenario,
    pre: &Preprocess,
) -> anyhow::Result<(Vec<f32>, Vec<f32>)> {
    let sensor = MockSensor::new(MockConfig::new(kind, seed), scenario);
    let c = first_clip(sensor, pre.clip_frames * 2)?;
    let bg = c.background.as_ref().context("clip without background")?;
    let x = pre.clip(&c.frames, c.peak_index).context("empty clip")?;
    let mut b = Vec::new();
    pre.frame_into(bg, &mut b);
    Ok((x, b))
}

fn f32_bytes(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// Most samples (train + test) of one `dataset fabrics`.
pub const MAX_SAMPLES: usize = 100_000;

pub fn fabrics(out: &Path, train: usize, test: usize, seed: u64) -> anyhow::Result<()> {
    let n = train.saturating_add(test);
    if n == 0 || n > MAX_SAMPLES {
        return Err(unitac_cli::args::usage(format!(
            "--train {train} + --test {test} is {n}; 1 to {MAX_SAMPLES} (inclusive)"
        )));
    }
    std::fs::create_dir_all(out)
        .map_err(|e| unitac_cli::args::usage(format!("--out {}: {e}", out.display())))?;
    let pre = Preprocess::reference();
    let mut clips = std::io::BufWriter::new(std::fs::File::create(out.join("clips.f32"))?);
    let mut bgs = std::io::BufWriter::new(std::fs::File::create(out.join("backgrounds.f32"))?);
    let mut labels = std::io::BufWriter::new(std::fs::File::create(out.join("labels.jsonl"))?);
    let mut rng = SplitMix64::new(seed);
    let bar = crate::progress::bar((train + test) as u64, "fabrics");
    for i in 0..train + test {
        let (obj, depth, s) = fabric(&mut rng, &format!("fabric_{i}"));
        let (x, b) = clip_of(
            SensorKind::GELSIGHT_MINI,
            seed.wrapping_add(i as u64),
            press(&obj, depth),
            &pre,
        )
        .with_context(|| format!("sample {i}"))?;
        clips.write_all(&f32_bytes(&x))?;
        bgs.write_all(&f32_bytes(&b))?;
        let split = if i < train { "train" } else { "test" };
        let line = serde_json::json!({
            "hardness": s[0], "roughness": s[1], "texture": s[2], "roughness_mm": obj.roughness_mm,
            "period_mm": obj.period_mm, "depth_mm": depth, "split": split, "sensor": "gelsight-mini",
        });
        writeln!(labels, "{line}")?;
        bar.inc(1);
    }
    bar.finish();
    clips.flush()?;
    bgs.flush()?;
    labels.flush()?;
    let meta = serde_json::json!({
        "count": train + test, "train": train, "test": test, "clip_frames": pre.clip_frames, "crop_size": pre.crop_size,
        "size": pre.size, "seed": seed,
    });
    std::fs::write(out.join("meta.json"), serde_json::to_string_pretty(&meta)?)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use unitac_infer::encoder::EncoderStage;

    /// The fitted reference head ranks UNSEEN mock fabrics (a seed the fit never saw) by
    /// roughness through the real contact and encoder stages: right on >= 90 % of the pairs whose
    /// true roughness differs by more than 0.01 mm.
    #[test]
    fn comparison_is_right_on_unseen_fabrics() {
        let root = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..");
        let models = std::env::var_os("UNITAC_MODELS")
            .map(std::path::PathBuf::from)
            .unwrap_or(root.join(".build/models"));
        let bundle = models.join("reference");
        assert!(
            bundle.join("manifest.json").is_file(),
            "run scripts/setup.sh first"
        );
        let mut enc = EncoderStage::new(&bundle, &unitac_infer::RuntimeConfig::default()).unwrap();
        let pre = Preprocess::reference();
        let mut rng = SplitMix64::new(0xDEC0DE);
        let mut seen = Vec::new();
        for i in 0..40 {
            let (obj, depth, _) = fabric(&mut rng, "unseen");
            let kind = SensorKind::GELSIGHT_MINI;
            let sensor = MockSensor::new(MockConfig::new(kind, 777 + i), press(&obj, depth));
            let clip = first_clip(sensor, pre.clip_frames * 2).unwrap();
            let out = enc.encode(&clip).unwrap();
            seen.push((obj.roughness_mm, out.scores[1]));
        }
        let (mut right, mut total) = (0, 0);
        for a in 0..seen.len() {
            for b in a + 1..seen.len() {
                if (seen[a].0 - seen[b].0).abs() > 0.01 {
                    total += 1;
                    right += usize::from((seen[a].0 > seen[b].0) == (seen[a].1 > seen[b].1));
                }
            }
        }
        let acc = right as f64 / total as f64;
        eprintln!(
            "unseen fabrics, roughness pairs differing by > 0.01 mm: {right}/{total} right ({acc:.3})"
        );
        assert!(total > 400 && acc >= 0.9, "{right}/{total} = {acc:.3}");
    }
}
