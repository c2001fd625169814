//! Closed-loop task worlds: the paper's cup deformation grasp and fabric selection grasp, as a
//! world a policy (or the scripted expert) drives one control tick at a time.
//!
//! `TaskWorld::reset(config, seed, trial)` draws the trial (objects, their properties and
//! placement, the camera's biases); `step(&TaskCommand, dt)` advances the arm, the gripper (the
//! cup world of [`crate::world`] squeezing the cup or the fabric stack between the gels, sub-stepped
//! inside) and the held object's friction and slip; `observe_visual` is what a camera model could
//! estimate (noisy, never tactile properties or forces); `sensor_view` is what the mock sensor must
//! render now; `outcome` is the task's success criteria with their values. Units are SI
//! throughout, the squeeze world's included.
//!
//! - `kind`: what a task is ([`Task`], [`TaskKind`]); [`cup_deformation`] and
//!   [`fabric_selection`]: the two tasks, each in one module (its draw, camera values, criteria,
//!   expert);
//! - [`cup`], [`fabric`]: the objects the tasks draw (their physics, draw and outcome);
//! - `command`: the command and what it refuses; `trial`: what a trial draws; `truth`: the
//!   ground truth and the outcome;
//! - `arm`: the kinematic arm; `hold`: friction and slip of the held object;
//! - [`observe`]: the camera's observation and the sensor view; `noise`: every noise figure of
//!   the world with what its source is;
//! - [`expert`]: running the tasks' experts, and the demonstration record.
//!
//! Same (config, seed, trial) and the same commands give the same truth, bit for bit.

use serde::Serialize;

use crate::rng::SplitMix64;
use crate::world::{Gel, Gripper, World, WorldConfig, WorldError, WorldTruth};

mod arm;
mod command;
pub mod cup;
pub mod cup_deformation;
pub mod expert;
pub mod fabric;
pub mod fabric_selection;
mod hold;
mod kind;
mod noise;
pub mod observe;
pub mod sensing;
pub mod split;
mod trial;
mod truth;

pub use arm::{ArmLimits, ArmState};
pub use command::{ArmSetpoint, ArmTarget, GripperSetpoint, MAX_STEP_S, TaskCommand};
pub use cup::{CupCriteria, CupOutcome, CupSpec, CupVariation};
pub use cup_deformation::{CupDeformation, fixed_opening_command};
pub use expert::{DemoStep, Demonstration, expert_command, run_expert, run_policy};
pub use fabric::{
    FABRICS, Fabric, FabricCriteria, FabricOutcome, FabricSpec, FabricVariation, LIFT_TOLERANCE_M,
    lifted,
};
pub use fabric_selection::FabricSelection;
pub use hold::{G, Hold};
pub use kind::{Judged, PlotKind, Sweep, Task, TaskKind, UnknownTask, paper_column};
pub use noise::{NoiseFigure, SourceKind};
pub use observe::{ROUGHNESS_SET_SD_M, SensorView, VisionNoise, VisualObservation};
pub use sensing::{GripperReading, GripperSensing};
pub use trial::{ObjectSpec, TaskObject, TrialSpec, trial_rng};
pub use truth::{ContactTruth, CriteriaOutcome, GripperTruth, ObjectTruth, TaskOutcome, TaskTruth};

/// A uniform distribution on [lo, hi].
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Uniform(pub f64, pub f64);

impl Uniform {
    pub fn draw(&self, rng: &mut SplitMix64) -> f64 {
        self.0 + (self.1 - self.0) * rng.uniform()
    }
}

/// Which objects a trial draws: the training objects or the unseen ones (objects/split.yaml:
/// cups by diameter range, fabrics by type).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Split {
    Train,
    Unseen,
}

/// The gripper's hardware bounds (a long-stroke two-finger gripper such as a 140 mm one).
/// Openings are between the finger bodies: the gel surfaces meet at an opening of 2 x `pad_m`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct GripperLimits {
    pub max_opening_m: f64,
    /// Gel pad thickness per finger \[m].
    pub pad_m: f64,
    /// Opening speed bound (both fingers together) \[m/s].
    pub max_speed_m_s: f64,
    /// Grip force bound per finger \[N].
    pub max_force_n: f64,
    /// Half the width of the gel pad across the closing axis (horizontal) \[m]: an object whose
    /// centre lies within it of the fingertip centre is gripped across its full width.
    pub pad_half_width_m: f64,
}

impl GripperLimits {
    /// This gripper with the profile `p`'s stroke, strongest grip and fastest speed (the gel
    /// pads stay).
    pub fn with_profile(self, p: &unitac_core::profile::GripperProfile) -> Self {
        Self {
            max_opening_m: p.stroke_m,
            max_force_n: p.force_n[1],
            max_speed_m_s: p.speed_m_s[1],
            ..self
        }
    }
}

impl Default for GripperLimits {
    /// The world's own gripper (grippers/sim.yaml) with GelSight Mini pads.
    fn default() -> Self {
        let sim = unitac_core::profile::SIM_GRIPPER;
        Self {
            max_opening_m: sim.stroke_m,
            pad_m: 0.003,
            max_speed_m_s: sim.speed_m_s[1],
            max_force_n: sim.force_n[1],
            // GelSight Mini: 18.6 x 14.3 mm sensing area (datasheet), the long side horizontal.
            pad_half_width_m: 0.0093,
        }
    }
}

/// Everything a task world is made from.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TaskConfig {
    pub kind: TaskKind,
    pub split: Split,
    pub arm: ArmLimits,
    pub gripper: GripperLimits,
    pub gel: Gel,
    /// Tangential (shear) stiffness of one gel pad [N/m].
    pub gel_shear_n_per_m: f64,
    pub cup: CupVariation,
    pub cup_criteria: CupCriteria,
    pub fabric: FabricVariation,
    pub fabric_criteria: FabricCriteria,
    pub vision: VisionNoise,
    /// What the gripper measures of itself (its status: never the world's contact force).
    pub sensing: GripperSensing,
    /// Longest inner step of the arm, gripper and friction \[s] (the squeeze world sub-steps
    /// further for its own stability).
    pub substep_s: f64,
}

impl TaskConfig {
    pub fn new(kind: TaskKind, split: Split) -> Self {
        Self {
            kind,
            split,
            arm: ArmLimits::default(),
            gripper: GripperLimits::default(),
            gel: Gel::default(),
            gel_shear_n_per_m: 4000.0,
            cup: CupVariation::for_split(split),
            cup_criteria: CupCriteria::default(),
            fabric: FabricVariation::for_split(split),
            fabric_criteria: FabricCriteria::default(),
            vision: VisionNoise::default(),
            sensing: GripperSensing::default(),
            substep_s: 1e-3,
        }
    }
    pub fn cup(split: Split) -> Self {
        Self::new(TaskKind::CUP, split)
    }
    pub fn fabric(split: Split) -> Self {
        Self::new(TaskKind::FABRIC, split)
    }
}

/// Fabric: the folded edge lies along the table's x axis; fingertips within this of the edge
/// across it (y) straddle the fold (assumed: the rounded fold of a few mm, plus the pad) \[m],
/// and within half this length of the edge's middle along it \[m].
const FOLD_REACH_M: f64 = 0.01;
const EDGE_LENGTH_M: f64 = 0.2;
/// Cup: fingertip centre at least this far from bottom and rim to hold it \[m].
const CUP_MARGIN_M: f64 = 0.005;
/// Fabric: length of fabric inside the pinch; slipping this far drops it \[m].
const PINCH_DEPTH_M: f64 = 0.015;
/// Contact force that counts as touching an object \[N].
const TOUCH_N: f64 = 0.2;
/// A grasp attempt: the fingers hold an object (grip force at least `TOUCH_N`) and have
/// raised it this far off where it rests \[m]. A touch (fingers closed on it, the arm still)
/// never raises it; a lift with open fingers raises nothing.
pub const GRASP_ATTEMPT_LIFT_M: f64 = 0.002;

/// How an object sits between the fingers when it comes between them.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Grip {
    /// Width the gels close on \[m] (cup diameter or chord, fabric stack) and layers caught.
    width_m: f64,
    layers: u32,
    offset_m: [f64; 2],
}

/// Where an object is relative to fingertips moving in.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Reach {
    Outside,
    Inside(Grip),
    /// A finger would come down on it.
    Collision,
}

/// A hidden variable of a trial changed after its draw, for the test that no ground truth reaches
/// a policy: two trials that differ only in one of these must look the same to every policy
/// until the first contact.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Hidden {
    /// Every object's stiffness (cup wall, fabric stack) times this.
    Stiffness(f64),
    /// Every object's friction (static and kinetic) times this.
    Friction(f64),
    /// Every object's mass times this.
    Mass(f64),
    /// Every object's true place moved by (dx, dy) \[m], the camera's per-trial bias moved back
    /// by as much: the camera sees what it saw, the object is elsewhere (within its error).
    Position([f64; 2]),
}

/// The fingers: free (nothing between them) or around an object (its squeeze world).
#[derive(Debug, Clone)]
enum Fingers {
    Free {
        opening_m: f64,
    },
    Around {
        obj: usize,
        world: Box<World>,
        width_m: f64,
        layers: u32,
        /// Arm height over the object's lift when it came between the fingers \[m].
        z_rel_m: f64,
        /// Object centre minus fingertip centre (x across the closing axis, y along it) \[m]:
        /// kept while the object is in the fingers; the closing pushes y to 0 once they grip.
        offset_m: [f64; 2],
        last: WorldTruth,
    },
}

/// Dynamic state of an object.
#[derive(Debug, Clone, PartialEq)]
struct ObjState {
    xy: [f64; 2],
    hold: Hold,
    touch_s: f64,
}

/// A task world: one trial.
#[derive(Debug, Clone)]
pub struct TaskWorld {
    cfg: TaskConfig,
    spec: TrialSpec,
    t: f64,
    arm: ArmState,
    fingers: Fingers,
    objects: Vec<ObjState>,
    stalled: bool,
    collision: bool,
    dropped: bool,
    peak_deformation_m: f64,
    /// The object the policy announced as its choice ([`TaskWorld::decide`]).
    announced: Option<usize>,
    /// The object of the first grasp attempt: the first one the fingers held and raised
    /// [`GRASP_ATTEMPT_LIFT_M`] off the table.
    attempted: Option<usize>,
    /// Last step's slip (signed) and integrator steps.
    slip_step_m: f64,
    substeps: u32,
}

impl TaskWorld {
    /// Draw trial `trial` of `seed`: the objects, their properties and places, the camera's bias.
    pub fn reset(cfg: &TaskConfig, seed: u64, trial: u32) -> TaskWorld {
        let spec = TrialSpec::draw(cfg, seed, trial);
        let objects = spec
            .objects
            .iter()
            .map(|o| ObjState {
                xy: o.placed_m,
                hold: Hold::default(),
                touch_s: 0.0,
            })
            .collect();
        TaskWorld {
            cfg: cfg.clone(),
            spec,
            t: 0.0,
            arm: ArmState::at(cfg.arm.home_m),
            fingers: Fingers::Free {
                opening_m: cfg.gripper.max_opening_m,
            },
            objects,
            stalled: false,
            collision: false,
            dropped: false,
            peak_deformation_m: 0.0,
            announced: None,
            attempted: None,
            slip_step_m: 0.0,
            substeps: 0,
        }
    }

    pub fn config(&self) -> &TaskConfig {
        &self.cfg
    }

    /// The policy announced its decision: the object called `name` (fabric selection's choice,
    /// scored apart from the grasp). The first announcement counts; an unknown name is ignored.
    /// What the fingers do decides first: the decision is the object of the first grasp
    /// attempt (held and raised [`GRASP_ATTEMPT_LIFT_M`]); the announcement stands only for a
    /// policy that attempted no grasp (its grasp closed on nothing), and without either the
    /// decision is the object held at the end.
    pub fn decide(&mut self, name: &str) {
        if self.announced.is_none() {
            self.announced = self.spec.objects.iter().position(|o| o.name == name);
        }
    }

    /// The object of the first grasp attempt so far (None: no attempt yet).
    pub fn grasp_attempt(&self) -> Option<&str> {
        self.attempted
            .and_then(|i| self.spec.objects.get(i))
            .map(|o| o.name.as_str())
    }

    /// Change one hidden variable of a freshly reset trial (see [`Hidden`]); the trial's random
    /// streams are untouched.
    pub fn perturb(&mut self, h: Hidden) {
        for (o, s) in self.spec.objects.iter_mut().zip(&mut self.objects) {
            match (&mut o.spec, h) {
                (ObjectSpec::Cup(c), Hidden::Stiffness(f)) => {
                    c.wall.k_n_per_m *= f;
                    c.wall.k3_n_per_m3 *= f;
                }
                (ObjectSpec::Fabric(fab), Hidden::Stiffness(f)) => fab.fabric.k_n_per_m *= f,
                (ObjectSpec::Cup(c), Hidden::Friction(f)) => {
                    c.friction_static *= f;
                    c.friction_kinetic *= f;
                }
                (ObjectSpec::Fabric(fab), Hidden::Friction(f)) => {
                    fab.friction_static *= f;
                    fab.friction_kinetic *= f;
                }
                (ObjectSpec::Cup(c), Hidden::Mass(f)) => c.mass_kg *= f,
                (ObjectSpec::Fabric(fab), Hidden::Mass(f)) => fab.mass_kg *= f,
                (_, Hidden::Position(d)) => {
                    o.placed_m = [o.placed_m[0] + d[0], o.placed_m[1] + d[1]];
                    s.xy = o.placed_m;
                }
            }
        }
        if let Hidden::Position(d) = h {
            let names = self.cfg.kind.visual_names();
            for (name, b) in names.iter().zip(&mut self.spec.vision_bias) {
                if name.ends_with(".x_m") {
                    *b -= d[0];
                } else if name.ends_with(".y_m") {
                    *b -= d[1];
                }
            }
        }
    }
    pub fn spec(&self) -> &TrialSpec {
        &self.spec
    }
    pub fn time(&self) -> f64 {
        self.t
    }

    /// Advance by `dt_s` under `cmd`. A bad command or step is refused with nothing changed.
    pub fn step(&mut self, cmd: &TaskCommand, dt_s: f64) -> Result<TaskTruth, WorldError> {
        if !(dt_s.is_finite() && dt_s > 0.0 && dt_s <= MAX_STEP_S) {
            return Err(WorldError::BadStep(dt_s));
        }
        cmd.validate()?;
        let target = self.resolve(&cmd.arm.target)?;
        let n = (dt_s / self.cfg.substep_s.clamp(1e-5, MAX_STEP_S))
            .ceil()
            .clamp(1.0, 1e5) as u32;
        let h = dt_s / f64::from(n);
        // Work on a copy: an integration error leaves the world as it was.
        let mut next = self.clone();
        next.slip_step_m = 0.0;
        next.substeps = 0;
        for _ in 0..n {
            next.substep(cmd, target, h)?;
        }
        next.t = self.t + dt_s;
        *self = next;
        Ok(self.truth())
    }

    /// The object index of an arm target (None: home).
    fn resolve(&self, target: &ArmTarget) -> Result<Option<usize>, WorldError> {
        match target {
            ArmTarget::Home => Ok(None),
            ArmTarget::Object(name) => self
                .spec
                .objects
                .iter()
                .position(|o| &o.name == name)
                .map(Some)
                .ok_or_else(|| WorldError::UnknownTarget {
                    name: name.chars().take(64).collect(),
                    known: self
                        .spec
                        .objects
                        .iter()
                        .map(|o| o.name.as_str())
                        .collect::<Vec<_>>()
                        .join(", "),
                }),
        }
    }

    /// Whether object `i` comes between fingertips centred at `pos` with `inner_m` between the
    /// gel surfaces, and how it is gripped.
    ///
    /// Cup (a cylinder; the fingers close along y, the pads `2 w` wide along x): a centre within
    /// `w` of the fingertip centre across the closing axis meets the pads with its full diameter;
    /// one `e` beyond the pad's edge meets its edges on a chord `2 sqrt(r^2 - e^2)`, and the edge
    /// contacts push inward at the angle `asin(e / r)`: where its tangent exceeds the static
    /// friction the closing pushes the cup along the edge until it meets the pad (full diameter,
    /// at the pad's edge); otherwise the chord is held. Along the closing axis the cup must fit
    /// between the gels from where it stands (`|dy| + half-extent <= inner / 2`); a finger that
    /// would come down on it is a collision. The nearer finger pushes it to the middle as they
    /// close (kept in the offset until the grip).
    /// Fabric: the fold lies along x; fingertips within [`FOLD_REACH_M`] of it across and half
    /// [`EDGE_LENGTH_M`] along it straddle it and catch the layers above their height.
    fn between(&self, i: usize, pos: [f64; 3], inner_m: f64) -> Reach {
        let (Some(o), Some(s)) = (self.spec.objects.get(i), self.objects.get(i)) else {
            return Reach::Outside;
        };
        let (dx, dy) = (s.xy[0] - pos[0], s.xy[1] - pos[1]);
        let z = pos[2] - s.hold.z_m;
        match &o.spec {
            ObjectSpec::Cup(c) => {
                if z < CUP_MARGIN_M || z > c.height_m - CUP_MARGIN_M {
                    return Reach::Outside;
                }
                self.cup_reach(c, dx, dy, inner_m)
            }
            ObjectSpec::Fabric(f) => {
                if dy.abs() > FOLD_REACH_M || dx.abs() > EDGE_LENGTH_M / 2.0 {
                    return Reach::Outside;
                }
                let n = f.layers_at(z);
                if n == 0 {
                    return Reach::Outside;
                }
                let width_m = f64::from(n) * f.layer_m;
                if width_m <= inner_m {
                    Reach::Inside(Grip {
                        width_m,
                        layers: n,
                        offset_m: [dx, dy],
                    })
                } else {
                    Reach::Collision
                }
            }
        }
    }

    /// [`TaskWorld::between`] for a cup at the fingertips' height band: `(dx, dy)` its centre
    /// from the fingertip centre \[m].
    fn cup_reach(&self, c: &CupSpec, dx: f64, dy: f64, inner_m: f64) -> Reach {
        let r = c.diameter_m / 2.0;
        let w = self.cfg.gripper.pad_half_width_m;
        let e = dx.abs() - w;
        if e >= r {
            return Reach::Outside;
        }
        let (width_m, x) = if e <= 0.0 {
            (c.diameter_m, dx)
        } else {
            let tilt = (e / r).asin().tan();
            if tilt > c.friction_static {
                (c.diameter_m, w.copysign(dx))
            } else {
                (2.0 * (r * r - e * e).sqrt(), dx)
            }
        };
        let half_m = (r * r - e.max(0.0).powi(2)).sqrt();
        let gap_m = inner_m / 2.0;
        if dy.abs() + half_m <= gap_m {
            Reach::Inside(Grip {
                width_m,
                layers: 1,
                offset_m: [x, dy],
            })
        } else if dy.abs() - half_m >= gap_m {
            Reach::Outside
        } else {
            Reach::Collision
        }
    }

    /// Where fingertips at `pos` that are around object `i` and do not touch it are: still around
    /// it, and how they would grip it there (`Some`), or gone from it (`None`), whatever their
    /// opening. The geometry of leaving: only rising or moving out frees the fingers.
    ///
    /// Cup: around while the fingertip centre is below the rim less [`CUP_MARGIN_M`] (the height
    /// at which fingers coming down start to hold it, so that entering and leaving meet at one
    /// height) and the cup's wall is still between the pads across the closing axis (its centre
    /// less than its radius beyond the pad's edge). Going lower never frees them: the cup stands
    /// on the table between them. Along the closing axis the cup stays between the fingers (the
    /// nearer one pushes it, as in [`TaskWorld::between`]).
    /// Fabric: while the fingertips straddle the fold; the layers they catch follow their height.
    fn around_at(&self, i: usize, pos: [f64; 3]) -> Option<Grip> {
        let (o, s) = (self.spec.objects.get(i)?, self.objects.get(i)?);
        let reach = match &o.spec {
            ObjectSpec::Cup(c) => {
                if pos[2] - s.hold.z_m > c.height_m - CUP_MARGIN_M {
                    return None;
                }
                self.cup_reach(c, s.xy[0] - pos[0], s.xy[1] - pos[1], f64::INFINITY)
            }
            ObjectSpec::Fabric(_) => self.between(i, pos, f64::INFINITY),
        };
        match reach {
            Reach::Inside(g) => Some(g),
            Reach::Outside | Reach::Collision => None,
        }
    }

    /// Opening at which the gel surfaces meet \[m].
    fn pad2_m(&self) -> f64 {
        2.0 * self.cfg.gripper.pad_m
    }

    /// The squeeze world's object: the cup's wall across `width_m` (its diameter, or the chord
    /// an offset grip meets; same wall law), or the fabric's stack of `layers`.
    fn squeezed(&self, i: usize, layers: u32, width_m: f64) -> Option<crate::world::Cup> {
        match &self.spec.objects.get(i)?.spec {
            ObjectSpec::Cup(c) => {
                let mut wall = c.wall.clone();
                wall.diameter_m = width_m;
                Some(wall)
            }
            ObjectSpec::Fabric(f) => Some(f.stack(layers)),
        }
    }

    /// One substep of `h` seconds: the arm, the gripper, the objects' vertical motion, then
    /// drops and leaving.
    fn substep(
        &mut self,
        cmd: &TaskCommand,
        target: Option<usize>,
        h: f64,
    ) -> Result<(), WorldError> {
        self.move_arm(cmd, target, h)?;
        self.drive_gripper(cmd, h)?;
        self.move_objects(h);
        self.drops_and_leaving()
    }

    /// The arm, and what comes between the fingers on its way.
    fn move_arm(
        &mut self,
        cmd: &TaskCommand,
        target: Option<usize>,
        h: f64,
    ) -> Result<(), WorldError> {
        let goal = match target {
            None => self.cfg.arm.home_m,
            Some(_) => [
                cmd.arm.xy_m[0],
                cmd.arm.xy_m[1],
                cmd.arm.z_m + cmd.arm.lift_m,
            ],
        };
        let cand = self.arm.advanced(&self.cfg.arm, goal, h);
        let mut blocked = false;
        if let Fingers::Free { opening_m } = self.fingers {
            let inner_m = opening_m - self.pad2_m();
            for i in 0..self.objects.len() {
                match self.between(i, cand.position_m, inner_m) {
                    Reach::Outside => continue,
                    Reach::Inside(grip) => {
                        self.engage(i, grip, opening_m, cand.position_m[2])?;
                    }
                    Reach::Collision => {
                        self.collision = true;
                        blocked = true;
                    }
                }
                break;
            }
        }
        self.arm = if blocked {
            self.arm.blocked(goal)
        } else {
            cand
        };
        Ok(())
    }

    /// The gripper: its bounds, then free fingers or the squeeze world.
    fn drive_gripper(&mut self, cmd: &TaskCommand, h: f64) -> Result<(), WorldError> {
        let lim = self.cfg.gripper;
        let g = &cmd.gripper;
        let open_m = g.opening_m.min(lim.max_opening_m);
        let speed_m_s = g.speed_m_s.min(lim.max_speed_m_s);
        let force_n = g.force_n.min(lim.max_force_n);
        self.stalled = false;
        match &mut self.fingers {
            Fingers::Free { opening_m } => {
                *opening_m += (open_m - *opening_m).clamp(-speed_m_s * h, speed_m_s * h);
            }
            Fingers::Around {
                world,
                width_m,
                last,
                ..
            } => {
                // Each finger takes half the opening change.
                let target_p = (*width_m - (open_m - 2.0 * lim.pad_m)) / 2.0;
                let d = world.drive(h, target_p, speed_m_s / 2.0, force_n)?;
                self.stalled = d.stalled;
                *last = d.truth;
                self.substeps += last.substeps;
            }
        }
        Ok(())
    }

    /// Every object's vertical motion; the one between the fingers feels the grip.
    fn move_objects(&mut self, h: f64) {
        let (held, grip_n) = match &self.fingers {
            Fingers::Around { obj, last, .. } => (Some(*obj), last.force_n),
            Fingers::Free { .. } => (None, 0.0),
        };
        let (va, aa) = (self.arm.velocity_m_s[2], self.arm.accel_m_s2[2]);
        for (i, (o, s)) in self.spec.objects.iter().zip(&mut self.objects).enumerate() {
            let grip = if held == Some(i) { grip_n } else { 0.0 };
            let load = |z: f64, v: f64| o.load(z, v);
            let slip = s.hold.step(h, va, aa, grip, o.friction(), &load);
            if held == Some(i) {
                self.slip_step_m += slip;
                if grip >= TOUCH_N {
                    s.touch_s += h;
                    if self.attempted.is_none() && s.hold.z_m >= GRASP_ATTEMPT_LIFT_M {
                        self.attempted = Some(i);
                    }
                }
                if grip <= 0.0
                    && let Fingers::Around { offset_m, .. } = &mut self.fingers
                {
                    // Not gripped: it stands where it is while the fingers move around it.
                    *offset_m = [
                        s.xy[0] - self.arm.position_m[0],
                        s.xy[1] - self.arm.position_m[1],
                    ];
                } else if let Fingers::Around { offset_m, .. } = &mut self.fingers {
                    // Gripped: the closing has pushed it to the middle along the closing axis;
                    // across it keeps its offset, and it goes where the fingers go (lifted, or
                    // slid over the table).
                    offset_m[1] = 0.0;
                    s.xy = [
                        self.arm.position_m[0] + offset_m[0],
                        self.arm.position_m[1] + offset_m[1],
                    ];
                }
            }
        }
    }

    /// Drops and leaving: an object slips out of the pinch or past the rim. Fingers that do not
    /// touch it slide freely along it: they leave it only where geometry says
    /// ([`TaskWorld::around_at`]), and while around it the grip they will close on (the cup's
    /// chord, the fabric's layers, the height) follows where they are.
    fn drops_and_leaving(&mut self) -> Result<(), WorldError> {
        let pos = self.arm.position_m;
        if let Fingers::Around {
            obj,
            width_m,
            z_rel_m,
            layers,
            last,
            ..
        } = &self.fingers
        {
            let (i, width_m, z_rel, layers, last) = (*obj, *width_m, *z_rel_m, *layers, *last);
            let s = self.objects.get(i).map_or(Hold::default(), |s| s.hold);
            let margin = match self.spec.objects.get(i).map(|o| &o.spec) {
                Some(ObjectSpec::Cup(c)) => c.height_m - CUP_MARGIN_M - z_rel,
                _ => PINCH_DEPTH_M,
            };
            let touching = last.force_n > 0.0 || last.penetration_m > 0.0;
            let pad2 = self.pad2_m();
            if s.slip_net_m > margin {
                self.dropped = true;
                self.fingers = Fingers::Free {
                    opening_m: last.width_m.min(width_m) + pad2,
                };
            } else if !touching {
                match self.around_at(i, pos) {
                    None => {
                        self.fingers = Fingers::Free {
                            opening_m: last.width_m + pad2,
                        };
                    }
                    Some(g) if g.width_m != width_m || g.layers != layers => {
                        self.engage(i, g, last.width_m + pad2, pos[2])?;
                    }
                    Some(_) => {
                        if let Fingers::Around { z_rel_m, .. } = &mut self.fingers {
                            *z_rel_m = pos[2] - s.z_m;
                        }
                    }
                }
            }
            if let Some(ObjectSpec::Cup(_)) = self.spec.objects.get(i).map(|o| &o.spec) {
                self.peak_deformation_m = self.peak_deformation_m.max(last.deformation_m);
            }
        }
        Ok(())
    }

    fn engage(
        &mut self,
        i: usize,
        grip: Grip,
        opening_m: f64,
        arm_z: f64,
    ) -> Result<(), WorldError> {
        let Some(model) = self.squeezed(i, grip.layers, grip.width_m) else {
            return Ok(());
        };
        let lim = self.cfg.gripper;
        let mut wc = WorldConfig::new(model);
        wc.gel = self.cfg.gel;
        wc.gripper = Gripper {
            speed_m_s: lim.max_speed_m_s / 2.0,
            max_force_n: lim.max_force_n,
            ..Gripper::default()
        };
        wc.start_m = (grip.width_m - (opening_m - self.pad2_m())) / 2.0;
        let world = World::new(wc);
        let last = world.truth(0);
        let s = &mut self.objects[i];
        s.hold.regrasp();
        self.fingers = Fingers::Around {
            obj: i,
            world: Box::new(world),
            width_m: grip.width_m,
            layers: grip.layers,
            z_rel_m: arm_z - s.hold.z_m,
            offset_m: grip.offset_m,
            last,
        };
        Ok(())
    }

    /// Ground truth now.
    pub fn truth(&self) -> TaskTruth {
        let (gripper, contact) = match &self.fingers {
            Fingers::Free { opening_m } => (
                GripperTruth {
                    opening_m: *opening_m,
                    force_n: 0.0,
                    stalled: false,
                },
                ContactTruth::default(),
            ),
            Fingers::Around {
                obj, layers, last, ..
            } => {
                let hold = self.objects.get(*obj).map_or(Hold::default(), |s| s.hold);
                let name = self
                    .spec
                    .objects
                    .get(*obj)
                    .map_or(String::new(), |o| o.name.clone());
                (
                    GripperTruth {
                        opening_m: last.width_m + self.pad2_m(),
                        force_n: last.force_n,
                        stalled: self.stalled,
                    },
                    ContactTruth {
                        object: name,
                        layers: *layers,
                        penetration_m: last.penetration_m,
                        deformation_m: last.deformation_m,
                        deformation_rate_m_s: 2.0 * last.wall_velocity_m_s,
                        friction_n: hold.friction_n,
                        tangential_m: 0.5 * hold.friction_n / self.cfg.gel_shear_n_per_m.max(1.0),
                        slip_step_m: self.slip_step_m,
                        slip_total_m: hold.slip_total_m,
                        stuck: hold.stuck,
                    },
                )
            }
        };
        let held = match &self.fingers {
            Fingers::Around { obj, last, .. } if last.force_n > 0.0 => Some(*obj),
            _ => None,
        };
        TaskTruth {
            t_s: self.t,
            arm: self.arm,
            gripper,
            contact,
            objects: self
                .spec
                .objects
                .iter()
                .zip(&self.objects)
                .enumerate()
                .map(|(i, (o, s))| ObjectTruth {
                    name: o.name.clone(),
                    position_m: [s.xy[0], s.xy[1], s.hold.z_m],
                    held: held == Some(i),
                    touch_s: s.touch_s,
                })
                .collect(),
            peak_deformation_m: self.peak_deformation_m,
            collision: self.collision,
            dropped: self.dropped,
            substeps: self.substeps,
        }
    }

    /// The task's success criteria, judged now, with their values.
    pub fn outcome(&self) -> TaskOutcome {
        let truth = self.truth();
        let held = truth.objects.iter().position(|o| o.held);
        let lift_m = held
            .and_then(|i| truth.objects.get(i))
            .map_or(0.0, |o| o.position_m[2]);
        self.cfg.kind.judge(
            &self.cfg,
            &Judged {
                truth: &truth,
                spec: &self.spec,
                held,
                lift_m,
                attempted: self.attempted,
                announced: self.announced,
            },
        )
    }
}
