//! Stage: Property Comparison between touched objects, from the encoder's property estimates.

use crate::encoder::PROPERTIES;
use serde::Deserialize;
use std::collections::VecDeque;
use thiserror::Error;
use unitac_core::msg::{Header, PropertyComparison, TactileProperties, Winner};
use unitac_core::{Clock, Msg, Stage, StageError};

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

/// Parameters the comparison stage cannot run with.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum CompareError {
    #[error("property '{0}' is not one of {PROPERTIES:?}")]
    UnknownProperty(String),
    #[error("tie_margin must be >= 0 (got {0})")]
    TieMargin(f32),
}

impl CompareStage {
    pub fn new(p: CompareParams) -> Result<Self, CompareError> {
        let index = PROPERTIES
            .iter()
            .position(|&q| q == p.property)
            .ok_or_else(|| CompareError::UnknownProperty(p.property.clone()))?;
        if !(p.tie_margin.is_finite() && p.tie_margin >= 0.0) {
            return Err(CompareError::TieMargin(p.tie_margin));
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
        let Msg::TactileProperties(props) = input else {
            return Ok(Vec::new());
        };
        let mut out = Vec::new();
        if self.p.pairs.is_empty() {
            if let Some(prev) = self.seen.back() {
                out.push(Msg::PropertyComparison(self.compare(prev, props)));
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
                    out.push(Msg::PropertyComparison(self.compare(a, b)));
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
            st.process(&Msg::TactileProperties(props(1, "fabric_a", 0.8)), &c)
                .unwrap()
                .is_empty()
        );
        let out = st
            .process(&Msg::TactileProperties(props(2, "fabric_b", 0.2)), &c)
            .unwrap();
        let Some(Msg::PropertyComparison(k)) = out.first() else {
            panic!("{out:?}")
        };
        assert_eq!(k.winner, Winner::A);
        assert_eq!(k.sentence, "fabric_b is smoother than fabric_a");
        assert!((k.margin - 0.6).abs() < 1e-6);
        assert!(k.confidence > 0.99);
        // Touching fabric_b again does not repeat the comparison.
        assert!(
            st.process(&Msg::TactileProperties(props(3, "fabric_b", 0.2)), &c)
                .unwrap()
                .is_empty()
        );
    }

    #[test]
    fn ties_and_last_two_pairing() {
        let mut st = CompareStage::new(CompareParams::default()).unwrap();
        let c = unitac_core::ManualClock::default();
        st.process(&Msg::TactileProperties(props(1, "", 0.50)), &c)
            .unwrap();
        let out = st
            .process(&Msg::TactileProperties(props(2, "", 0.51)), &c)
            .unwrap();
        let Some(Msg::PropertyComparison(k)) = out.first() else {
            panic!()
        };
        assert_eq!(k.winner, Winner::Tie);
        assert!(k.confidence < 0.6);
        assert_eq!(
            CompareStage::new(CompareParams {
                property: "colour".into(),
                ..Default::default()
            })
            .err(),
            Some(CompareError::UnknownProperty("colour".into()))
        );
        assert_eq!(
            CompareStage::new(CompareParams {
                tie_margin: -0.1,
                ..Default::default()
            })
            .err(),
            Some(CompareError::TieMargin(-0.1))
        );
        assert!((normal_cdf(0.0) - 0.5).abs() < 1e-7 && (normal_cdf(1.96) - 0.975).abs() < 1e-4);
    }
}
