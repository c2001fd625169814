//! What a trial is made of: its objects (drawn per seed and trial) and the camera's bias.

use serde::Serialize;

use super::{CupSpec, FabricSpec, G, Split, TaskConfig, TaskKind};
use crate::rng::SplitMix64;

/// An object of the trial.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ObjectSpec {
    Cup(CupSpec),
    Fabric(FabricSpec),
}

/// An object of the trial: its name, what it is, where it was placed (x, y) \[m].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TaskObject {
    pub name: String,
    pub spec: ObjectSpec,
    pub placed_m: [f64; 2],
}

impl TaskObject {
    pub(crate) fn friction(&self) -> (f64, f64) {
        match &self.spec {
            ObjectSpec::Cup(c) => (c.friction_static, c.friction_kinetic),
            ObjectSpec::Fabric(f) => (f.friction_static, f.friction_kinetic),
        }
    }
    /// (mass \[kg], downward force \[N]) at height z moving at v.
    pub(crate) fn load(&self, z: f64, v: f64) -> (f64, f64) {
        match &self.spec {
            ObjectSpec::Cup(c) => (c.mass_kg, c.mass_kg * G),
            ObjectSpec::Fabric(f) => f.load(z, v),
        }
    }
}

/// What reset drew for this trial (ground truth; the expert may read it, a policy must not).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TrialSpec {
    pub kind: TaskKind,
    pub split: Split,
    pub seed: u64,
    pub trial: u32,
    pub objects: Vec<TaskObject>,
    /// The camera's per-trial bias, one per visual observation name.
    pub vision_bias: Vec<f64>,
    /// The gripper's true force constant over its nominal one (its force estimate's error).
    pub gripper_gain: f64,
}

impl TrialSpec {
    /// Draw trial `trial` of `seed`: the objects, their properties and places, the camera's bias.
    pub fn draw(cfg: &TaskConfig, seed: u64, trial: u32) -> TrialSpec {
        let mut rng = trial_rng(seed, trial);
        let objects = cfg.kind.draw(cfg, &mut rng);
        let names = cfg.kind.visual_names();
        let vision_bias = names
            .iter()
            .map(|n| cfg.vision.bias_sigma(n) * rng.gaussian())
            .collect();
        let gripper_gain = cfg.sensing.draw_gain(&mut rng);
        TrialSpec {
            kind: cfg.kind,
            split: cfg.split,
            seed,
            trial,
            objects,
            vision_bias,
            gripper_gain,
        }
    }

    pub fn object(&self, name: &str) -> Option<&TaskObject> {
        self.objects.iter().find(|o| o.name == name)
    }
    /// The cup of a cup trial.
    pub fn cup(&self) -> Option<&CupSpec> {
        self.objects.iter().find_map(|o| match &o.spec {
            ObjectSpec::Cup(c) => Some(c),
            ObjectSpec::Fabric(_) => None,
        })
    }
    /// The fabric called `name`.
    pub fn fabric(&self, name: &str) -> Option<&FabricSpec> {
        match &self.object(name)?.spec {
            ObjectSpec::Fabric(f) => Some(f),
            ObjectSpec::Cup(_) => None,
        }
    }
    /// Name of the smoother fabric of a fabric trial ("" otherwise).
    pub fn smoother(&self) -> &str {
        let mut best: Option<(&str, f64)> = None;
        for o in &self.objects {
            if let ObjectSpec::Fabric(f) = &o.spec
                && best.is_none_or(|(_, r)| f.roughness_ra_m < r)
            {
                best = Some((&o.name, f.roughness_ra_m));
            }
        }
        best.map_or("", |(n, _)| n)
    }
}

/// The trial's own generator: a pure function of (seed, trial).
pub fn trial_rng(seed: u64, trial: u32) -> SplitMix64 {
    let mut r = SplitMix64::new(seed ^ (u64::from(trial) + 1).wrapping_mul(0xD1B5_4A32_D192_ED03));
    r.next_u64();
    r
}
