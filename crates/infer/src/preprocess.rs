//! Frames -> encoder tensors: centre square crop, area resize, normalisation, as the bundle's
//! manifest declares. Pure and deterministic; the dataset exporter and the encoder stage share it.

use serde::Deserialize;
use thiserror::Error;
use unitac_core::Frame;

/// A manifest's preprocessing this crate cannot follow.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum PreprocessError {
    #[error("preprocess.crop '{0}' is not supported (center_square)")]
    Crop(String),
    #[error("preprocess.sampling '{0}' is not supported (peak_centred)")]
    Sampling(String),
    #[error(
        "preprocess.size must be 8..=1024 and clip_frames 1..=64 (got {size} and {clip_frames})"
    )]
    Size { size: u32, clip_frames: u32 },
    #[error("preprocess.std must be > 0 and mean finite (got std {std}, mean {mean})")]
    Normalisation { mean: f32, std: f32 },
}

#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Preprocess {
    /// Only "center_square" is supported.
    pub crop: String,
    /// Side of the centre square in input pixels (0 = the largest square that fits). Fabric
    /// texture survives only when the square is not shrunk too much.
    #[serde(default)]
    pub crop_size: u32,
    /// Output side \[px].
    pub size: u32,
    /// value = (pixel / 255 - mean) / std
    pub mean: f32,
    pub std: f32,
    /// Frames per clip.
    pub clip_frames: u32,
    /// Only "peak_centred" is supported.
    pub sampling: String,
}

impl Preprocess {
    /// The reference bundle's preprocessing (python/unitac_tools/generate_reference.py uses the same numbers
    /// and checks them against the dataset it is fitted on).
    pub fn reference() -> Self {
        Self {
            crop: "center_square".into(),
            crop_size: 128,
            size: 64,
            mean: 0.5,
            std: 0.25,
            clip_frames: 4,
            sampling: "peak_centred".into(),
        }
    }

    pub fn check(&self) -> Result<(), PreprocessError> {
        if self.crop != "center_square" {
            return Err(PreprocessError::Crop(self.crop.clone()));
        }
        if self.sampling != "peak_centred" {
            return Err(PreprocessError::Sampling(self.sampling.clone()));
        }
        if !(8..=1024).contains(&self.size) || !(1..=64).contains(&self.clip_frames) {
            return Err(PreprocessError::Size {
                size: self.size,
                clip_frames: self.clip_frames,
            });
        }
        if !(self.std.is_finite() && self.std > 0.0 && self.mean.is_finite()) {
            return Err(PreprocessError::Normalisation {
                mean: self.mean,
                std: self.std,
            });
        }
        Ok(())
    }

    /// One frame -> 3 x size x size (CHW), appended to `out`.
    pub fn frame_into(&self, f: &Frame, out: &mut Vec<f32>) {
        let s = self.size as usize;
        let full = f.width.min(f.height);
        let side = if self.crop_size == 0 {
            full
        } else {
            self.crop_size.min(full)
        } as usize;
        let (x0, y0) = (
            (f.width as usize - side) / 2,
            (f.height as usize - side) / 2,
        );
        let w = f.width as usize;
        let data = f.data();
        let base = out.len();
        out.resize(base + 3 * s * s, 0.0);
        let scale = 1.0 / (255.0 * self.std);
        let offset = self.mean / self.std;
        for oy in 0..s {
            let (ya, yb) = (
                y0 + oy * side / s,
                (y0 + (oy + 1) * side / s).max(y0 + oy * side / s + 1),
            );
            for ox in 0..s {
                let (xa, xb) = (
                    x0 + ox * side / s,
                    (x0 + (ox + 1) * side / s).max(x0 + ox * side / s + 1),
                );
                let mut acc = [0u32; 3];
                for y in ya..yb {
                    for px in data[(y * w + xa) * 3..(y * w + xb) * 3].chunks_exact(3) {
                        acc[0] += u32::from(px[0]);
                        acc[1] += u32::from(px[1]);
                        acc[2] += u32::from(px[2]);
                    }
                }
                let n = ((yb - ya) * (xb - xa)) as f32;
                for (c, a) in acc.iter().enumerate() {
                    out[base + c * s * s + oy * s + ox] = *a as f32 / n * scale - offset;
                }
            }
        }
    }

    /// `clip_frames` frames centred on `peak` (repeating the ends when the clip is short) ->
    /// T x 3 x size x size.
    pub fn clip(&self, frames: &[Frame], peak: usize) -> Option<Vec<f32>> {
        if frames.is_empty() {
            return None;
        }
        let t = self.clip_frames as usize;
        let start = peak as i64 - (t / 2) as i64;
        let mut out = Vec::with_capacity(t * 3 * (self.size * self.size) as usize);
        for k in 0..t as i64 {
            let i = (start + k).clamp(0, frames.len() as i64 - 1) as usize;
            self.frame_into(&frames[i], &mut out);
        }
        Some(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use unitac_core::Stamp;

    fn pre() -> Preprocess {
        Preprocess {
            crop: "center_square".into(),
            crop_size: 0,
            size: 2,
            mean: 0.5,
            std: 0.25,
            clip_frames: 3,
            sampling: "peak_centred".into(),
        }
    }

    #[test]
    fn unsupported_settings_are_typed_errors() {
        let r = Preprocess::reference();
        assert_eq!(r.check(), Ok(()));
        let bad = |f: fn(&mut Preprocess)| {
            let mut p = Preprocess::reference();
            f(&mut p);
            p.check()
        };
        assert_eq!(
            bad(|p| p.crop = "letterbox".into()),
            Err(PreprocessError::Crop("letterbox".into()))
        );
        assert_eq!(
            bad(|p| p.sampling = "uniform".into()),
            Err(PreprocessError::Sampling("uniform".into()))
        );
        assert_eq!(
            bad(|p| p.clip_frames = 0),
            Err(PreprocessError::Size {
                size: 64,
                clip_frames: 0
            })
        );
        assert!(matches!(
            bad(|p| p.std = 0.0),
            Err(PreprocessError::Normalisation { .. })
        ));
    }

    #[test]
    fn crops_the_centre_and_averages_blocks() {
        // 6x4 image: centre square is x 1..5; left half of it dark, right half bright.
        let mut d = Vec::new();
        for _y in 0..4 {
            for x in 0..6 {
                let v = if x < 3 { 0 } else { 255 };
                d.extend([v, v, v]);
            }
        }
        let f = Frame::new("s", 0, Stamp::ZERO, 6, 4, d).unwrap();
        let mut out = Vec::new();
        pre().frame_into(&f, &mut out);
        // (0/255 - 0.5)/0.25 = -2, (1 - 0.5)/0.25 = 2
        assert_eq!(&out[..4], &[-2.0, 2.0, -2.0, 2.0]);
        assert_eq!(out.len(), 12);
    }

    #[test]
    fn clip_is_centred_on_the_peak_and_padded() {
        let frames: Vec<Frame> = (0..5u8)
            .map(|v| Frame::new("s", v.into(), Stamp::ZERO, 2, 2, vec![v * 50; 12]).unwrap())
            .collect();
        let c = pre().clip(&frames, 0).unwrap();
        let first = |k: usize| c[k * 12];
        let val = |v: u8| (f32::from(v * 50) / 255.0 - 0.5) / 0.25;
        for (k, v) in [(0, 0), (1, 0), (2, 1)] {
            assert!(
                (first(k) - val(v)).abs() < 1e-6,
                "frame {k}: {} vs {}",
                first(k),
                val(v)
            );
        }
        assert!(pre().clip(&[], 0).is_none());
    }
}
