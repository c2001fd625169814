//! Stage: the touch encoder + property head on contact-episode clips.

use crate::bundle::{Bundle, Model};
use crate::preprocess::Preprocess;
use crate::runtime::{InferError, RuntimeConfig};
use std::path::Path;
use std::time::Instant;
use unitac_core::msg::{ContactClip, Header, LatentSource, TactileLatent, TactileProperties};
use unitac_core::{Clock, Msg, Stage, StageError};

// Kept at its old path for callers that name `encoder::CompareStage`.
pub use crate::compare::{CompareParams, CompareStage};

/// Property index in the head's output (the manifest's `properties` list must match).
pub const PROPERTIES: [&str; 3] = ["hardness", "roughness", "texture"];

fn model_err(e: InferError) -> StageError {
    StageError::model(e)
}

/// Why the encoder refused a clip ([`StageError::BadInput`]) or its models' answer
/// ([`StageError::Model`]).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum EncodeError {
    #[error("episode clip without background")]
    NoBackground,
    #[error("empty clip")]
    EmptyClip,
    #[error("encoder: no output")]
    NoEncoderOutput,
    #[error("property head: missing outputs")]
    MissingHeadOutputs,
    #[error("property head returned {scores} scores and {stds} stds")]
    HeadShape { scores: usize, stds: usize },
    #[error("encoder or property head returned a non-finite value")]
    NonFinite,
}

/// What the encoder and the property head said about one clip.
#[derive(Debug, Clone, PartialEq)]
pub struct Encoded {
    /// Shape of `tokens` including the batch dimension of 1.
    pub tok_shape: Vec<i64>,
    pub tokens: Vec<f32>,
    /// hardness, roughness, texture.
    pub scores: Vec<f32>,
    pub stds: Vec<f32>,
}

/// Encoder + property head on each `ContactClip`: a real `TactileLatent` and `TactileProperties`.
#[derive(Debug)]
pub struct EncoderStage {
    pre: Preprocess,
    encoder: Model,
    head: Model,
    /// Latencies of the last episodes (encoder + head) \[s].
    pub latencies: Vec<f64>,
}

impl EncoderStage {
    pub fn new(bundle_dir: &Path, cfg: &RuntimeConfig) -> Result<Self, InferError> {
        let bundle = Bundle::open(bundle_dir)?;
        if bundle.manifest.properties != PROPERTIES {
            return Err(InferError::Bundle {
                dir: bundle_dir.to_path_buf(),
                msg: format!(
                    "properties are {:?}, this stage reads {PROPERTIES:?}",
                    bundle.manifest.properties
                ),
            });
        }
        let mut models = bundle.load(&["encoder", "properties"], cfg)?.into_iter();
        let (Some(encoder), Some(head)) = (models.next(), models.next()) else {
            return Err(InferError::Bundle {
                dir: bundle_dir.to_path_buf(),
                msg: "models missing".into(),
            });
        };
        Ok(Self {
            pre: bundle.manifest.preprocess,
            encoder,
            head,
            latencies: Vec::new(),
        })
    }

    /// Run the models on one clip.
    pub fn encode(&mut self, clip: &ContactClip) -> Result<Encoded, StageError> {
        let bg = clip
            .background
            .as_ref()
            .ok_or(StageError::bad_input(EncodeError::NoBackground))?;
        let x = self
            .pre
            .clip(&clip.frames, clip.peak_index)
            .ok_or_else(|| StageError::bad_input(EncodeError::EmptyClip))?;
        let mut b = Vec::new();
        self.pre.frame_into(bg, &mut b);
        let (t, s) = (i64::from(self.pre.clip_frames), i64::from(self.pre.size));
        let outs = self
            .encoder
            .run(&[(&[1, t, 3, s, s], &x), (&[1, 3, s, s], &b)])
            .map_err(model_err)?;
        let (tok_shape, tokens) = outs
            .into_iter()
            .next()
            .ok_or_else(|| StageError::model(EncodeError::NoEncoderOutput))?;
        let heads = self.head.run(&[(&tok_shape, &tokens)]).map_err(model_err)?;
        let mut it = heads.into_iter();
        let (Some((_, scores)), Some((_, stds))) = (it.next(), it.next()) else {
            return Err(StageError::model(EncodeError::MissingHeadOutputs));
        };
        if scores.len() != 3 || stds.len() != 3 {
            return Err(StageError::model(EncodeError::HeadShape {
                scores: scores.len(),
                stds: stds.len(),
            }));
        }
        if tokens
            .iter()
            .chain(&scores)
            .chain(&stds)
            .any(|v| !v.is_finite())
        {
            return Err(StageError::model(EncodeError::NonFinite));
        }
        Ok(Encoded {
            tok_shape,
            tokens,
            scores,
            stds,
        })
    }
}

impl Stage for EncoderStage {
    fn name(&self) -> &str {
        "encoder"
    }
    fn process(&mut self, input: &Msg, clock: &dyn Clock) -> Result<Vec<Msg>, StageError> {
        let Msg::ContactClip(clip) = input else {
            return Ok(Vec::new());
        };
        // Compute time through the injected clock: real when live, 0 in replay, so replayed
        // outputs stay byte-identical. `latencies` keeps the wall time for benchmarks.
        let (c0, t0) = (clock.now(), Instant::now());
        let Encoded {
            tok_shape: shape,
            tokens,
            scores: sc,
            stds: sd,
        } = self.encode(clip)?;
        if self.latencies.len() < 1000 {
            self.latencies.push(t0.elapsed().as_secs_f64());
        }
        let elapsed = clock.now().secs_since(c0).max(0.0);
        let stamp = input.stamp();
        let header = Header::optical(stamp, &clip.sensor_id);
        let latent = TactileLatent {
            header: header.clone(),
            source: LatentSource::Real,
            sensor_id: clip.sensor_id.clone(),
            shape: shape
                .iter()
                .skip(1)
                .map(|&d| u32::try_from(d).unwrap_or(0))
                .collect(),
            data: tokens,
            model_id: self.encoder.id.clone(),
            solver: String::new(),
            steps: 0,
            guidance: 0.0,
            elapsed_s: elapsed,
            valid: true,
            guard_report: String::new(),
            object: String::new(),
            condition_sources: Vec::new(),
            condition_age_s: Vec::new(),
        };
        let props = TactileProperties {
            header,
            sensor_id: clip.sensor_id.clone(),
            episode_id: clip.episode_id,
            label: clip.label.clone(),
            hardness: sc[0],
            hardness_std: sd[0],
            roughness: sc[1],
            roughness_std: sd[1],
            texture: sc[2],
            texture_std: sd[2],
            model_id: self.head.id.clone(),
        };
        Ok(vec![
            Msg::TactileLatent(latent),
            Msg::TactileProperties(props),
        ])
    }
}
