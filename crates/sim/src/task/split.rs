//! The committed object split (`objects/split.yaml`, turned into [`SPLIT`] by the build script):
//! which cups and fabrics a trial of the training split or of the unseen split draws. Training
//! and unseen objects differ by range (cups: diameter) and by type (fabrics). Every training and
//! evaluation step reads this one file: the task worlds, `unitac-lab trials`, `unitac-lab demos`
//! and the fits that setup runs on demonstrations.

use serde::Serialize;

use super::Uniform;

/// Cups: diameter ranges per split, and what both splits share.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct CupSplit {
    /// Cup diameter \[m].
    pub train_diameter_m: Uniform,
    pub unseen_diameter_m: Uniform,
    /// Factor on the paper-cup wall law.
    pub stiffness_factor: Uniform,
    /// Cup plus contents \[kg].
    pub mass_kg: Uniform,
    /// Static friction coefficient, gel on paper.
    pub friction: Uniform,
}

/// A fabric type: the ranges a fabric of it is drawn from.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FabricType {
    pub name: &'static str,
    /// Sine texture amplitude and period \[m], bump radius \[m] and density \[per m^2],
    /// hardness (the share of the approach the gel takes).
    pub roughness_m: Uniform,
    pub period_m: Uniform,
    pub bump_m: Uniform,
    pub bump_density: Uniform,
    pub hardness: Uniform,
    /// One layer's thickness \[m], compression stiffness per side at no load [N/m], static
    /// friction gel on cloth, mass \[kg].
    pub layer_m: Uniform,
    pub k_n_per_m: Uniform,
    pub friction: Uniform,
    pub mass_kg: Uniform,
    /// Layers at the folded edge, inclusive.
    pub layers: (u32, u32),
}

/// Fabrics: the types of each split and every type's ranges.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FabricSplit {
    pub train_types: &'static [&'static str],
    pub unseen_types: &'static [&'static str],
    pub types: &'static [FabricType],
}

impl FabricSplit {
    /// The type called `name`.
    pub fn get(&self, name: &str) -> Option<&'static FabricType> {
        self.types.iter().find(|t| t.name == name)
    }
}

/// The whole split.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ObjectSplit {
    pub cups: CupSplit,
    pub fabrics: FabricSplit,
}

include!(concat!(env!("OUT_DIR"), "/split.rs"));

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_committed_split_separates_training_from_unseen_objects() {
        let c = SPLIT.cups;
        // By range: no training diameter reaches an unseen one.
        assert!(c.train_diameter_m.1 < c.unseen_diameter_m.0, "{c:?}");
        let f = SPLIT.fabrics;
        // By type: every listed type exists, none is on both sides.
        for t in f.train_types.iter().chain(f.unseen_types) {
            assert!(f.get(t).is_some(), "{t}");
        }
        assert!(f.train_types.iter().all(|t| !f.unseen_types.contains(t)));
        assert!(f.train_types.len() >= 2 && f.unseen_types.len() >= 2);
    }
}
