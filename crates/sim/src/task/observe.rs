//! What the robot's other senses get from a task world: the camera's noisy estimate and the
//! view the mock tactile sensor renders.
//!
//! The camera model estimates what an RGB(-D) camera over the table could: each object's
//! position, the cup's diameter (undeformed: the fingers hide the squeezed section, the rim is
//! what the camera measures) and height, a fabric's folded-edge height, and a poor guess of a
//! fabric's roughness (Ra). Each value is the truth plus a per-trial bias (calibration,
//! segmentation; for roughness, how the fabric's sheen and weave happen to look) plus per-frame
//! noise, both near-normal (`SplitMix64::gaussian`). It never sees softness, friction,
//! stiffness, force, deformation or slip.
//!
//! Roughness: the fabrics' texture amplitudes (0.015 to 0.06 mm) are a tenth of a pixel or
//! less for a table camera (about 0.3 to 0.5 mm per pixel at 0.5 m), so the camera cannot
//! measure them; it can only guess from appearance, which the fabrics here share by design
//! (alike in colour, size and drape). Its estimate is therefore modelled as no better than
//! knowing the set the fabric comes from: the per-trial bias has the standard deviation of the
//! set's Ra ([`ROUGHNESS_SET_SD_M`]), the per-frame noise a quarter of it (image noise on an
//! appearance cue).

use serde::Serialize;

use super::{ObjectSpec, TaskWorld};
use crate::mock::{GroundTruth, MockSensor};
use crate::object::{FoldEdge, MM_PER_M, Object};
use crate::rng::SplitMix64;
use crate::tangential::{DEFAULT_LIMIT_M, Tangential};
use unitac_core::Frame;

/// Camera noise: per-trial bias and per-frame noise (standard deviations) \[m].
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct VisionNoise {
    pub position_bias_m: f64,
    pub position_m: f64,
    pub size_bias_m: f64,
    pub size_m: f64,
    /// Fabric edge height (a few mm seen from above, at a slant).
    pub edge_bias_m: f64,
    pub edge_m: f64,
    /// Fabric roughness (Ra, guessed from appearance) \[m].
    pub roughness_bias_m: f64,
    pub roughness_m: f64,
}

/// Standard deviation of the Ra of the five fabrics in [`super::FABRICS`] \[m] (population
/// standard deviation of `roughness_ra_m`, checked by a test): the spread a camera that cannot
/// resolve the texture is left with.
pub const ROUGHNESS_SET_SD_M: f64 = 1.0125e-5;

impl Default for VisionNoise {
    fn default() -> Self {
        Self {
            position_bias_m: 0.003,
            position_m: 0.002,
            size_bias_m: 0.002,
            size_m: 0.001,
            edge_bias_m: 0.0005,
            edge_m: 0.0005,
            roughness_bias_m: ROUGHNESS_SET_SD_M,
            roughness_m: 0.25 * ROUGHNESS_SET_SD_M,
        }
    }
}

impl VisionNoise {
    /// Every figure times `f` (the sweep's camera noise x0.5 / x1 / x2).
    pub fn scaled(&self, f: f64) -> Self {
        Self {
            position_bias_m: self.position_bias_m * f,
            position_m: self.position_m * f,
            size_bias_m: self.size_bias_m * f,
            size_m: self.size_m * f,
            edge_bias_m: self.edge_bias_m * f,
            edge_m: self.edge_m * f,
            roughness_bias_m: self.roughness_bias_m * f,
            roughness_m: self.roughness_m * f,
        }
    }
    fn sigmas(&self, name: &str) -> (f64, f64) {
        if name.ends_with("roughness_ra_m") {
            (self.roughness_bias_m, self.roughness_m)
        } else if name.ends_with("edge_height_m") {
            (self.edge_bias_m, self.edge_m)
        } else if name.ends_with("diameter_m") || name.ends_with("height_m") {
            (self.size_bias_m, self.size_m)
        } else {
            (self.position_bias_m, self.position_m)
        }
    }
    /// Standard deviation of the per-trial bias of the value called `name` \[m].
    pub fn bias_sigma(&self, name: &str) -> f64 {
        self.sigmas(name).0
    }
    /// Standard deviation of the per-frame noise of the value called `name` \[m].
    pub fn frame_sigma(&self, name: &str) -> f64 {
        self.sigmas(name).1
    }
}

/// `<object>.<field>` for each field.
pub fn per_object(object: &str, fields: &[&str]) -> Vec<String> {
    fields.iter().map(|f| format!("{object}.{f}")).collect()
}

/// A camera observation: names and values (same order every tick).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct VisualObservation {
    pub t_s: f64,
    pub names: Vec<String>,
    pub values: Vec<f64>,
}

impl VisualObservation {
    pub fn get(&self, name: &str) -> Option<f64> {
        let i = self.names.iter().position(|n| n == name)?;
        self.values.get(i).copied()
    }
}

/// What the mock sensor must render now (the sensor on one finger; the other is symmetric).
/// Sensor plane axes: x right, y down (world down along the finger).
#[derive(Debug, Clone, PartialEq)]
pub struct SensorView {
    pub t_s: f64,
    /// The touched object as the gel sees it (None: nothing between the fingers); a fabric
    /// carries its folded edge ([`FoldEdge`]: where the fold's top crosses the gel, the layer
    /// thickness), so the press shows where the pinch is on the fold.
    pub object: Option<Object>,
    /// Gel penetration \[m] (0 when not touching).
    pub penetration_m: f64,
    pub force_n: f64,
    /// Contact centre in the sensor plane from the gel's centre \[m].
    pub contact_centre_m: [f64; 2],
    /// Tangential displacement of the gel surface under the contact \[m].
    pub tangential_m: [f64; 2],
    /// Relative motion of the object over the gel in the last step \[m] and since the grasp
    /// (summed unsigned) \[m].
    pub slip_m: [f64; 2],
    pub slip_total_m: f64,
    /// Deformation of the touched object (cup diameter loss, stack compression) \[m].
    pub deformation_m: f64,
}

impl SensorView {
    /// The gel's sideways displacement as the renderer's input (None: not touching, or no
    /// displacement). The world moves the gel surface by `tangential_m` (friction force over the
    /// pad's shear stiffness). Stuck (no relative motion this step): the object and the gel under
    /// it moved together by that much, stick ratio 1. Slipping: the object slides on over a gel
    /// held at its friction limit, so the renderer's gross slip (stick ratio 0) with the limit at
    /// the gel's displacement and the object's travel (gel displacement plus the slip since the
    /// grasp, in the slip's direction) as the shift.
    pub fn tangential(&self) -> Option<Tangential> {
        let [tx, ty] = self.tangential_m;
        let gel = tx.hypot(ty);
        if self.object.is_none() || self.penetration_m <= 0.0 || !(gel > 0.0 && gel.is_finite()) {
            return None;
        }
        let step = self.slip_m[0].hypot(self.slip_m[1]);
        if step > 0.0 && step.is_finite() {
            let along = self.slip_total_m.max(0.0) / step;
            Some(Tangential {
                shift_m: [tx + self.slip_m[0] * along, ty + self.slip_m[1] * along],
                rotation_rad: 0.0,
                stick_ratio: 0.0,
                limit_m: gel,
            })
        } else {
            Some(Tangential {
                shift_m: [tx, ty],
                rotation_rad: 0.0,
                stick_ratio: 1.0,
                limit_m: gel.max(DEFAULT_LIMIT_M),
            })
        }
    }

    /// Render it as frame `index` of `sensor`: the object pressed to the penetration, the marker
    /// dots moved by [`SensorView::tangential`]; force and deformation go into the ground truth
    /// as they are.
    pub fn render(&self, sensor: &MockSensor, index: u64) -> (Frame, GroundTruth) {
        let press = self
            .object
            .as_ref()
            .map(|o| (o, self.penetration_m * MM_PER_M));
        let (frame, mut truth) = sensor.render_contact(index, press, self.tangential().as_ref());
        truth.label = self
            .object
            .as_ref()
            .map(|o| o.label.clone())
            .unwrap_or_default();
        truth.force_n = self.force_n;
        truth.deformation_m = self.deformation_m;
        (frame, truth)
    }
}

impl TaskWorld {
    /// The camera's estimate now, with this frame's noise drawn from `rng`.
    pub fn observe_visual(&self, rng: &mut SplitMix64) -> VisualObservation {
        let names = self.cfg.kind.visual_names();
        let truth = self.truth();
        let values = names
            .iter()
            .zip(&self.spec.vision_bias)
            .map(|(name, bias)| {
                let v = self.visual_truth(name, &truth.objects).unwrap_or(0.0);
                v + bias + self.cfg.vision.frame_sigma(name) * rng.gaussian()
            })
            .collect();
        VisualObservation {
            t_s: self.t,
            names,
            values,
        }
    }

    fn visual_truth(&self, name: &str, objects: &[super::ObjectTruth]) -> Option<f64> {
        let (obj, field) = name.split_once('.')?;
        let i = self.spec.objects.iter().position(|o| o.name == obj)?;
        let (o, s) = (self.spec.objects.get(i)?, objects.get(i)?);
        Some(match (field, &o.spec) {
            ("x_m", _) => s.position_m[0],
            ("y_m", _) => s.position_m[1],
            ("z_m", _) => s.position_m[2],
            ("diameter_m", ObjectSpec::Cup(c)) => c.diameter_m,
            ("height_m", ObjectSpec::Cup(c)) => c.height_m,
            ("edge_height_m", ObjectSpec::Fabric(f)) => f.stack_m(),
            ("roughness_ra_m", ObjectSpec::Fabric(f)) => f.roughness_ra_m,
            _ => return None,
        })
    }

    /// What the mock sensor must render now.
    pub fn sensor_view(&self) -> SensorView {
        let truth = self.truth();
        let c = &truth.contact;
        let object = self
            .spec
            .objects
            .iter()
            .find(|o| !c.object.is_empty() && o.name == c.object)
            .map(|o| match &o.spec {
                ObjectSpec::Cup(cup) => {
                    let mut obj = cup.wall.object();
                    obj.label = o.name.clone();
                    obj
                }
                ObjectSpec::Fabric(f) => {
                    let obj = f.fabric.object(&o.name);
                    // The fold's top above the fingertip centre (the contact centre): the fabric's
                    // folded edge stands `stack_m` above its base, which is lifted with it.
                    let base = truth
                        .objects
                        .iter()
                        .find(|t| t.name == o.name)
                        .map_or(0.0, |t| t.position_m[2]);
                    let above_m = f.stack_m() - (truth.arm.position_m[2] - base);
                    obj.with_fold(FoldEdge {
                        edge_mm: above_m * MM_PER_M,
                        layer_mm: f.layer_m * MM_PER_M,
                    })
                }
            });
        let touching = c.penetration_m > 0.0;
        SensorView {
            t_s: self.t,
            object,
            penetration_m: c.penetration_m.max(0.0),
            force_n: truth.gripper.force_n,
            contact_centre_m: [0.0, 0.0],
            tangential_m: [0.0, if touching { c.tangential_m } else { 0.0 }],
            slip_m: [0.0, c.slip_step_m],
            slip_total_m: c.slip_total_m,
            deformation_m: c.deformation_m,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::task::{FABRICS, fabric::roughness_ra_m};

    #[test]
    fn the_roughness_sigma_is_the_fabric_sets_ra_spread() {
        let ra: Vec<f64> = FABRICS
            .iter()
            .map(|f| roughness_ra_m(&f.object("x")))
            .collect();
        let mean = ra.iter().sum::<f64>() / ra.len() as f64;
        let var = ra.iter().map(|r| (r - mean).powi(2)).sum::<f64>() / ra.len() as f64;
        let sd = var.sqrt();
        assert!(
            (sd - ROUGHNESS_SET_SD_M).abs() < 0.01 * sd,
            "{sd:e} vs {ROUGHNESS_SET_SD_M:e}"
        );
        let v = VisionNoise::default();
        assert_eq!(v.bias_sigma("fabric_a.roughness_ra_m"), ROUGHNESS_SET_SD_M);
        assert_eq!(
            v.frame_sigma("fabric_b.roughness_ra_m"),
            0.25 * ROUGHNESS_SET_SD_M
        );
        assert_eq!(v.bias_sigma("fabric_a.edge_height_m"), v.edge_bias_m);
    }
}
