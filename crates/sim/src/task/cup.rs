//! The cup task (the paper's unseen-size cup deformation grasp): a family of paper cups, the
//! per-trial draw, and the success criteria.
//!
//! Cups: diameters drawn from the split's ranges (objects/split.yaml: training 58-74 mm, unseen
//! 84-96 mm); height 1.3 x diameter. Wall stiffness from the world's paper-cup law (`Cup::paper`:
//! 300 N/m per side at 80 mm, ~ 1/d^3, the thin-ring law) times a per-trial factor; mass (cup and
//! contents) and the gel-on-paper friction are drawn per trial.
//! The gel penetration and the grip force come from the world ([`crate::world`]).

use serde::Serialize;

use super::split::SPLIT;
use super::{Split, Uniform};
use crate::rng::SplitMix64;
use crate::world::Cup;

/// Cup height over diameter.
pub const HEIGHT_PER_DIAMETER: f64 = 1.3;

/// Per-trial variation of a cup: the split's ranges (objects/split.yaml) and the sweeps' knobs.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct CupVariation {
    /// Diameter \[m] (the split's range).
    pub diameter_m: Uniform,
    /// Factor on the paper-cup stiffness law.
    pub stiffness_factor: Uniform,
    /// Cup plus contents \[kg].
    pub mass_kg: Uniform,
    /// Static friction coefficient, gel on paper (kinetic = `kinetic_ratio` x static).
    pub friction: Uniform,
    pub kinetic_ratio: f64,
    /// Placement on the table (x, y) around `centre_m` \[m], each uniform in +-`spread_m`.
    pub centre_m: [f64; 2],
    pub spread_m: [f64; 2],
    /// Sweeps (`unitac-lab trials --sweep`): every drawn stiffness times this, every drawn diameter
    /// plus this \[m]. 1 and 0 for the split as committed.
    pub stiffness_scale: f64,
    pub size_offset_m: f64,
}

impl CupVariation {
    /// The cups of `split` (objects/split.yaml).
    pub fn for_split(split: Split) -> Self {
        let c = SPLIT.cups;
        Self {
            diameter_m: match split {
                Split::Train => c.train_diameter_m,
                Split::Unseen => c.unseen_diameter_m,
            },
            stiffness_factor: c.stiffness_factor,
            mass_kg: c.mass_kg,
            friction: c.friction,
            kinetic_ratio: 0.8,
            centre_m: [0.45, 0.0],
            spread_m: [0.03, 0.05],
            stiffness_scale: 1.0,
            size_offset_m: 0.0,
        }
    }
}

impl Default for CupVariation {
    fn default() -> Self {
        Self::for_split(Split::Train)
    }
}

/// One trial's cup (ground truth).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CupSpec {
    pub diameter_m: f64,
    pub height_m: f64,
    pub mass_kg: f64,
    pub friction_static: f64,
    pub friction_kinetic: f64,
    /// The wall model the world squeezes.
    pub wall: Cup,
}

impl CupSpec {
    /// The cup's stiffness \[N/m] as the labels and the cup controllers use it: the grip force
    /// that holds the wall at a loss of diameter `d_m` \[m], divided by `d_m` (the wall is a cubic
    /// spring per side).
    pub fn stiffness_n_per_m(&self, d_m: f64) -> f64 {
        let (force_n, _) = self.wall.spring(d_m / 2.0);
        force_n / d_m
    }

    /// Draw a cup from `var` with `rng`.
    pub fn draw(var: &CupVariation, rng: &mut SplitMix64) -> CupSpec {
        let diameter_m = (var.diameter_m.draw(rng) + var.size_offset_m).max(0.02);
        let mut wall = Cup::paper(diameter_m);
        let k = var.stiffness_factor.draw(rng) * var.stiffness_scale;
        wall.k_n_per_m *= k;
        wall.k3_n_per_m3 *= k;
        let mu = var.friction.draw(rng);
        CupSpec {
            diameter_m,
            height_m: HEIGHT_PER_DIAMETER * diameter_m,
            mass_kg: var.mass_kg.draw(rng),
            friction_static: mu,
            friction_kinetic: mu * var.kinetic_ratio,
            wall,
        }
    }
}

/// Success criteria of the cup task and their bounds.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct CupCriteria {
    /// Target loss of diameter \[m] (the paper: 1 cm) and the tolerance either side \[m].
    pub target_deformation_m: f64,
    pub tolerance_m: f64,
    /// A peak loss of diameter beyond this crushes the cup (buckled for good) \[m].
    pub crush_m: f64,
    /// Lifted: the cup's bottom at least this high above the table (less
    /// [`super::fabric::LIFT_TOLERANCE_M`]), held \[m].
    pub lift_m: f64,
}

impl Default for CupCriteria {
    fn default() -> Self {
        Self {
            target_deformation_m: 0.010,
            tolerance_m: 0.002,
            crush_m: 0.020,
            lift_m: 0.03,
        }
    }
}

/// The cup task's outcome with the values behind each criterion.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CupOutcome {
    /// Lift success: held and at least the criterion's height up.
    pub lift: bool,
    pub lift_height_m: f64,
    pub held: bool,
    /// Deformation success: the final loss of diameter within target +- tolerance, and never
    /// over-compressed (peak beyond target + tolerance).
    pub deformation: bool,
    pub deformation_m: f64,
    pub peak_deformation_m: f64,
    pub over_compressed: bool,
    pub crushed: bool,
    /// The fingers hit the cup while too closed to pass around it.
    pub collision: bool,
    pub overall: bool,
}

impl CupOutcome {
    pub fn judge(
        c: &CupCriteria,
        held: bool,
        lift_height_m: f64,
        deformation_m: f64,
        peak_deformation_m: f64,
        collision: bool,
    ) -> CupOutcome {
        let lift = held && super::fabric::lifted(lift_height_m, c.lift_m) && !collision;
        let over_compressed = peak_deformation_m > c.target_deformation_m + c.tolerance_m;
        let crushed = peak_deformation_m > c.crush_m;
        let deformation = !over_compressed
            && !collision
            && (deformation_m - c.target_deformation_m).abs() <= c.tolerance_m;
        CupOutcome {
            lift,
            lift_height_m,
            held,
            deformation,
            deformation_m,
            peak_deformation_m,
            over_compressed,
            crushed,
            collision,
            overall: lift && deformation,
        }
    }
}
