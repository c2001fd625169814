//! Stages: the touch encoder + property head on contact-episode clips, and Property Comparison.

use crate::bundle::{Bundle, Model};
use crate::preprocess::Preprocess;
use crate::runtime::{InferError, RuntimeConfig};
use serde::Deserialize;
use std::collections::VecDeque;
use std::path::Path;
use std::time::Instant;
use unitac_core::msg::{
    EpisodeClip, Header, LatentSource, PropertyComparison, TactileLatent, TactileProperties, Winner,
};
use unitac_core::{Clock, Msg, Stage, StageError};

/// Property index in the head's output (the manifest's `properties` list must match).
pub const PROPERTIES: [&str; 3] = ["hardness", "roughness", "texture"];

fn model_err(e: InferError) -> StageError {
    StageError::Model(e.to_string())
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

/// Encoder + property head on each `EpisodeClip`: a real `TactileLatent` and `TactileProperties`.
#[derive(Debug)]
pub struct EncoderStage {
    pre: Preprocess,
    encoder: Model,
    head: Model,
    /// Latencies of the last episodes (encoder + head) [s].
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
    pub fn encode(&mut self, clip: &EpisodeClip) -> Result<Encoded, StageError> {
        let bg = clip
            .background
            .as_ref()
            .ok_or_else(|| StageError::BadInput("episode clip without background".into()))?;
        let x = self
            .pre
            .clip(&clip.frames, clip.peak_index)
            .ok_or_else(|| StageError::BadInput("empty clip".into()))?;
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
            .ok_or_else(|| StageError::Model("encoder: no output".into()))?;
        let heads = self.head.run(&[(&tok_shape, &tokens)]).map_err(model_err)?;
        let mut it = heads.into_iter();
        let (Some((_, scores)), Some((_, stds))) = (it.next(), it.next()) else {
            return Err(StageError::Model("property head: missing outputs".into()));
        };
        if scores.len() != 3 || stds.len() != 3 {
            return Err(StageError::Model(format!(
                "property head returned {} scores and {} stds",
                scores.len(),
                stds.len()
            )));
        }
        if tokens
            .iter()
            .chain(&scores)
            .chain(&stds)
            .any(|v| !v.is_finite())
        {
            return Err(StageError::Model(
                "encoder or property head returned a non-finite value".into(),
            ));
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
        let Msg::Clip(clip) = input else {
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
        Ok(vec![Msg::Latent(latent), Msg::Properties(props)])
    }
}

#[derive(Debug, Clone, PartialEq, Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct CompareParams {
    /// hardness | roughness | texture
    pub property: String,
    /// Label pairs to compare (A, B); empty = compare each episode with the one before.
    pub pairs: Vec<[String; 2]>,
    /// |score_a - score_b| below this is a tie.
    pub tie_margin: f32,
}

impl Default for CompareParams {
    fn default() -> Self {
        Self {
            property: "roughness".into(),
            pairs: Vec::new(),
            tie_margin: 0.02,
        }
    }
}

/// Property Comparison between touched objects ("which fabric is smoother?").
#[derive(Debug)]
pub struct CompareStage {
    p: CompareParams,
    index: usize,
    seen: VecDeque<TactileProperties>,
    done: Vec<[String; 2]>,
}

/// Most episodes remembered for pairing.
const MAX_REMEMBERED: usize = 64;

fn normal_cdf(x: f64) -> f64 {
    // Abramowitz-Stegun 7.1.26 erf approximation (|error| < 1.5e-7).
    let z = x.abs() / std::f64::consts::SQRT_2;
    let t = 1.0 / (1.0 + 0.327_591_1 * z);
    let poly = t
        * (0.254_829_592
            + t * (-0.284_496_736
                + t * (1.421_413_741 + t * (-1.453_152_027 + t * 1.061_405_429))));
    let erf = 1.0 - poly * (-z * z).exp();
    if x >= 0.0 {
        0.5 * (1.0 + erf)
    } else {
        0.5 * (1.0 - erf)
    }
}

impl CompareStage {
    pub fn new(p: CompareParams) -> Result<Self, String> {
        let index = PROPERTIES
            .iter()
            .position(|&q| q == p.property)
            .ok_or_else(|| format!("property '{}' is not one of {PROPERTIES:?}", p.property))?;
        if !(p.tie_margin.is_finite() && p.tie_margin >= 0.0) {
            return Err("tie_margin must be >= 0".into());
        }
        Ok(Self {
            p,
            index,
            seen: VecDeque::new(),
            done: Vec::new(),
        })
    }

    fn score(&self, t: &TactileProperties) -> (f32, f32) {
        match self.index {
            0 => (t.hardness, t.hardness_std),
            1 => (t.roughness, t.roughness_std),
            _ => (t.texture, t.texture_std),
        }
    }

    /// Compare a and b on the stage's property.
    pub fn compare(&self, a: &TactileProperties, b: &TactileProperties) -> PropertyComparison {
        let ((sa, da), (sb, db)) = (self.score(a), self.score(b));
        let margin = sa - sb;
        let sigma = f64::from(da * da + db * db).sqrt().max(1e-6);
        let confidence = normal_cdf(f64::from(margin.abs()) / sigma) as f32;
        let winner = if margin.abs() < self.p.tie_margin {
            Winner::Tie
        } else if margin > 0.0 {
            Winner::A
        } else {
            Winner::B
        };
        let name = |t: &TactileProperties| {
            if t.label.is_empty() {
                format!("episode {}", t.episode_id)
            } else {
                t.label.clone()
            }
        };
        let (na, nb) = (name(a), name(b));
        let (more, less) = match self.index {
            0 => ("harder", "softer"),
            1 => ("rougher", "smoother"),
            _ => ("bumpier", "flatter"),
        };
        let sentence = match winner {
            Winner::Tie => format!("{na} and {nb} feel the same ({})", self.p.property),
            // B has less of the property: "B is smoother than A".
            Winner::A => format!("{nb} is {less} than {na}"),
            Winner::B => format!("{nb} is {more} than {na}"),
        };
        PropertyComparison {
            header: Header::new(
                a.header.stamp.max(b.header.stamp),
                a.header.frame_id.clone(),
            ),
            property: self.p.property.clone(),
            episode_a: a.episode_id,
            label_a: a.label.clone(),
            episode_b: b.episode_id,
            label_b: b.label.clone(),
            winner,
            score_a: sa,
            score_b: sb,
            margin,
            confidence,
            sentence,
        }
    }
}

impl Stage for CompareStage {
    fn name(&self) -> &str {
        "compare"
    }
    fn process(&mut self, input: &Msg, _clock: &dyn Clock) -> Result<Vec<Msg>, StageError> {
        let Msg::Properties(props) = input else {
            return Ok(Vec::new());
        };
        let mut out = Vec::new();
        if self.p.pairs.is_empty() {
            if let Some(prev) = self.seen.back() {
                out.push(Msg::Comparison(self.compare(prev, props)));
            }
        } else {
            for pair in self.p.pairs.clone() {
                if self.done.contains(&pair) || !pair.contains(&props.label) {
                    continue;
                }
                let find = |l: &str| {
                    if props.label == l {
                        Some(props)
                    } else {
                        self.seen.iter().rev().find(|t| t.label == l)
                    }
                };
                if let (Some(a), Some(b)) = (find(&pair[0]), find(&pair[1])) {
                    out.push(Msg::Comparison(self.compare(a, b)));
                    self.done.push(pair);
                }
            }
        }
        if self.seen.len() == MAX_REMEMBERED {
            self.seen.pop_front();
        }
        self.seen.push_back(props.clone());
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use unitac_core::Stamp;

    fn props(id: u64, label: &str, roughness: f32) -> TactileProperties {
        TactileProperties {
            header: Header::new(Stamp(id as i64), "s"),
            sensor_id: "s".into(),
            episode_id: id,
            label: label.into(),
            hardness: 0.5,
            hardness_std: 0.1,
            roughness,
            roughness_std: 0.05,
            texture: 0.5,
            texture_std: 0.1,
            model_id: String::new(),
        }
    }

    #[test]
    fn compares_labelled_pairs_once_and_says_who_is_smoother() {
        let p = CompareParams {
            pairs: vec![["fabric_a".into(), "fabric_b".into()]],
            ..Default::default()
        };
        let mut st = CompareStage::new(p).unwrap();
        let c = unitac_core::ManualClock::default();
        assert!(
            st.process(&Msg::Properties(props(1, "fabric_a", 0.8)), &c)
                .unwrap()
                .is_empty()
        );
        let out = st
            .process(&Msg::Properties(props(2, "fabric_b", 0.2)), &c)
            .unwrap();
        let Some(Msg::Comparison(k)) = out.first() else {
            panic!("{out:?}")
        };
        assert_eq!(k.winner, Winner::A);
        assert_eq!(k.sentence, "fabric_b is smoother than fabric_a");
        assert!((k.margin - 0.6).abs() < 1e-6);
        assert!(k.confidence > 0.99);
        // Touching fabric_b again does not repeat the comparison.
        assert!(
            st.process(&Msg::Properties(props(3, "fabric_b", 0.2)), &c)
                .unwrap()
                .is_empty()
        );
    }

    #[test]
    fn ties_and_last_two_pairing() {
        let mut st = CompareStage::new(CompareParams::default()).unwrap();
        let c = unitac_core::ManualClock::default();
        st.process(&Msg::Properties(props(1, "", 0.50)), &c)
            .unwrap();
        let out = st
            .process(&Msg::Properties(props(2, "", 0.51)), &c)
            .unwrap();
        let Some(Msg::Comparison(k)) = out.first() else {
            panic!()
        };
        assert_eq!(k.winner, Winner::Tie);
        assert!(k.confidence < 0.6);
        assert!(
            CompareStage::new(CompareParams {
                property: "colour".into(),
                ..Default::default()
            })
            .is_err()
        );
        assert!((normal_cdf(0.0) - 0.5).abs() < 1e-7 && (normal_cdf(1.96) - 0.975).abs() < 1e-4);
    }
}
