//! The sensor-level condition: the touch encoder's sensor tokens of a non-contact frame (the
//! contact stage's background), averaged over the tokens into one vector Z_sen. It tells a
//! sensor's gel, illumination and camera apart before anything touches it.

use crate::bundle::Model;
use crate::preprocess::Preprocess;
use crate::runtime::InferError;
use unitac_core::Frame;

/// The encoder and its preprocessing, run on backgrounds only.
#[derive(Debug)]
pub struct SensorPrior {
    pre: Preprocess,
    encoder: Model,
}

impl SensorPrior {
    pub fn new(pre: Preprocess, encoder: Model) -> Self {
        Self { pre, encoder }
    }

    /// Z_sen of the background `bg`: the encoder's sensor tokens, mean over the tokens.
    pub fn of(&mut self, bg: &Frame) -> Result<Vec<f32>, InferError> {
        let name = self.encoder.name.clone();
        let bad = |msg: &str| InferError::Output {
            model: name.clone(),
            msg: msg.into(),
        };
        let mut b = Vec::new();
        self.pre.frame_into(bg, &mut b);
        // The encoder takes a clip too; the background repeated stands in (no contact).
        let clip: Vec<f32> = (0..self.pre.clip_frames)
            .flat_map(|_| b.iter().copied())
            .collect();
        let (t, s) = (i64::from(self.pre.clip_frames), i64::from(self.pre.size));
        let outs = self
            .encoder
            .run(&[(&[1, t, 3, s, s], &clip), (&[1, 3, s, s], &b)])?;
        let (shape, sen) = outs
            .into_iter()
            .nth(1)
            .ok_or_else(|| bad("no sensor_tokens"))?;
        let (n, w) = (
            shape.get(1).copied().unwrap_or(1).max(1) as usize,
            shape.get(2).copied().unwrap_or(0).max(0) as usize,
        );
        if sen.len() != n * w || sen.iter().any(|v| !v.is_finite()) {
            return Err(bad("bad sensor tokens"));
        }
        Ok((0..w)
            .map(|j| (0..n).map(|i| sen[i * w + j]).sum::<f32>() / n as f32)
            .collect())
    }
}
