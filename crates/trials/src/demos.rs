//! Demonstrations with observations: the scripted expert on either task, recorded with what a
//! policy of every mode could observe (the tactile latents the scenes' stages make of the mock
//! sensor's frames, the camera's estimate, the gripper's status) next to the expert's labels (the
//! cup's true stiffness, the expert's setpoints). The reference policies are fitted on the cup's
//! (python/unitac_tools/fit_reference_policy.py), the learned policies on the per-tick record of both tasks
//! ([`DemoTick`], written in LeRobot's layout by python/unitac_tools/lerobot_dataset.py), on training objects
//! only.
//!
//! A demonstration is one mode's ([`DemoConfig::mode`]): the expert decides only from what that
//! mode observes, so that its policy can imitate the decision. It reads the truth for where
//! things are, as a teleoperator sees them (the objects' places, the fingers' geometry, the
//! visible deformation; unitac_sim::task::expert), never for what only touch could tell.
//!
//! One cup demonstration, per tick of `dt_s`:
//!
//! ```text
//! approach: the expert's arm command to the cup, the fingers at the camera's width + the pads +
//!           the pre-grasp margin (`pregrasp_m`, as the cup controller opens), until the arm has
//!           arrived and has had `approach_s` since its target was commanded
//! touch:    (vtla_real) close at touch_speed_m_s with touch_force_n until the contact stage
//!           says contact (the opening there is D0): the probe touch the vtla_real controller
//!           makes, from a distance that varies with the camera's error as the controller's does
//! press:    (vtla_real) to D0 - probe_press_m for probe_press_s (the sensor sees a steady
//!           press of the wall, what the stiffness readout reads)
//! release:  (vtla_real) open to D0 + probe_release_m until the contact stage says the contact
//!           ended (the episode's clip goes to the encoder: its latent is the touch's observation)
//! expert:   the expert's own commands (squeeze to its setpoint, settle, lift) for `run_s`
//! ```
//!
//! The probe is vtla_real's alone: its trigger, the contact state, is in that mode's observation
//! and not in vla's or vtla_pred's, whose demonstrations go from the approach to the squeeze.
//!
//! This is the shape of a task whose demonstrations probe first
//! ([`unitac_sim::task::Task::probe_first`]; the approach opens to the camera value
//! [`unitac_sim::task::Task::approach_width`] names). Any other task's demonstration is its
//! expert for `run_s`. The fabric expert touches fabric A and lets go, touches
//! B and lets go (each contact episode ends, so the encoder and the comparison stage see both),
//! waits open for the decision, then grasps the chosen fabric and lifts it. The decision, made
//! here once both touches are over, is the mode's: vtla_real's from the live PropertyComparison
//! it holds (the smoother by touch; on a tie, the camera's guess), vla's and vtla_pred's from the
//! camera's roughness guesses (their mean so far, as `observation.visual` holds them; vtla_pred's
//! predicted latent is drawn without the object and says nothing about which is smoother). It is
//! kept as [`Demo::chosen`] and [`Demo::decided_s`]. A vtla_real demonstration whose comparison
//! does not come within `timeout_s` of the second release is an error.
//!
//! Several chains of stages may watch one demonstration (one per mode's scene: contact + encoder
//! for vtla_real, contact + sampler for vtla_pred), each fed the same camera estimates and
//! frames; the first chain's contact state drives the probe and the contact observation, so
//! every tick carries every mode's observations whichever mode's expert acts.
//!
//! Each tick the camera's estimate goes into the stages first (as in a trial: the sampler's
//! object-level condition), then the frames are rendered at the sensor's own frame times by
//! [`crate::bridge::SensorRig`] and pushed through the stages with [`Chain`]: the stages are
//! built by the caller from the scene, so this module sees only `Stage`s. Every latent the stages
//! send is kept with the number of contacts begun before it (0: a prediction before any touch;
//! 1: the first touch). Same inputs, same bytes.
//!
//! Each tick also goes into [`Demo::ticks`]: the observation slices every mode may read (the
//! gripper status as the policy's `gripper` input reads it, the camera's estimate, the contact
//! state, the opening latched at the first object-detect, the pooled latents per object, the
//! comparison) and the command the expert gave, as the policy's action values. Nothing in a
//! tick's observation is ground truth.

use serde::Serialize;
use thiserror::Error;
use unitac_core::Stage;
use unitac_core::chain::Chain;
use unitac_core::msg::{
    ArmCommand, ContactState, GripperCommand, GripperStatus, LatentSource, Msg, VisualObservation,
};
use unitac_policy::Mode;
use unitac_policy::learned::Memory;
use unitac_policy::observation::{Layout, input};
use unitac_sim::task::{
    self, ArmSetpoint, GripperSetpoint, Split, TaskCommand, TaskConfig, TaskKind, TaskTruth,
    TaskWorld, TrialSpec, expert_command, trial_rng,
};
use unitac_sim::{MockConfig, MockSensor, Scenario};

use crate::bridge::visual_message;
use crate::gripper::TrialGripper;
use crate::stepper::{StepError, WorldStepper};

/// Salt of the camera noise stream of a demonstration (its own, apart from the trial's draw).
const VISION_SALT: u64 = 0x4445_4D4F_5649_5301;
/// Most latents one demonstration keeps.
const MAX_LATENTS: usize = 64;
/// Most chains of stages one demonstration feeds.
pub const MAX_CHAINS: usize = 4;
/// Most ticks one demonstration records (10 min at 30 Hz).
pub const MAX_TICKS: usize = 18_000;
/// Values of the comparison, contact and gripper slices (schema/policy.json).
pub use unitac_policy::schema::{COMPARISON_LEN, CONTACT_LEN, STATE_LEN};

/// How a demonstration touches and how long it runs.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DemoConfig {
    /// Which task.
    pub task: TaskKind,
    /// Whose demonstration: what the expert decides from (module docs). vtla_real: the probe
    /// touch before the cup's squeeze, the fabric chosen from the live PropertyComparison; vla and
    /// vtla_pred: no probe, the fabric chosen from the camera's roughness guesses.
    pub mode: Mode,
    /// Control period \[s].
    pub dt_s: f64,
    /// The probe touch: closing speed \[m/s], force bound \[N], opening added back to end it \[m]
    /// (the cup controller's `touch_speed_m_s`, `touch_force_n`, `probe_release_m`).
    pub touch_speed_m_s: f64,
    pub touch_force_n: f64,
    pub probe_release_m: f64,
    /// Longest approach, touch or release \[s].
    pub timeout_s: f64,
    /// How long the expert runs (after the probe, in a task that probes first) \[s]; None: the
    /// task's own length ([`unitac_sim::task::Task::demo_s`]).
    pub run_s: Option<f64>,
    /// Values of one pooled latent ([`pooled`] of the encoder's tokens; the sampler's latent is
    /// pooled already): a latent of another size is an error.
    pub pooled_len: usize,
    /// The arm's travel time to a target \[s] (the scenes' `approach_s`): the probe touch starts
    /// once the arm has had it since its target was commanded (and has arrived).
    pub approach_s: f64,
    /// Cup: the fingers open to the camera's diameter plus this while the arm approaches \[m]
    /// (the cup controller's two gel pads and pre-grasp margin), so that the probe touch starts
    /// where a policy's would.
    pub pregrasp_m: f64,
    /// The probe's press after first contact: opening closed further \[m] and how long \[s].
    pub probe_press_m: f64,
    pub probe_press_s: f64,
}

impl Default for DemoConfig {
    fn default() -> Self {
        // The probe as the cup controller makes it (its params' defaults).
        let p = unitac_policy::PolicyParams::default();
        Self {
            task: TaskKind::CUP,
            mode: Mode::VtlaReal,
            dt_s: 1.0 / 30.0,
            touch_speed_m_s: p.touch_speed_m_s,
            touch_force_n: p.touch_force_n,
            probe_release_m: p.probe_release_m,
            timeout_s: 8.0,
            run_s: None,
            pooled_len: 96,
            approach_s: 1.5,
            pregrasp_m: 2.0 * p.pad_m + p.pregrasp_margin_m,
            probe_press_m: p.probe_press_m,
            probe_press_s: p.probe_press_s,
        }
    }
}

#[derive(Debug, Clone, PartialEq, Error)]
pub enum DemoError {
    #[error("seed {seed} trial {trial}: {what} within {timeout_s} s")]
    Timeout {
        seed: u64,
        trial: u32,
        what: &'static str,
        timeout_s: f64,
    },
    #[error("seed {seed} trial {trial}: stage {stage}: {msg}")]
    Stage {
        seed: u64,
        trial: u32,
        stage: String,
        msg: String,
    },
    #[error("seed {seed} trial {trial}: world: {msg}")]
    World { seed: u64, trial: u32, msg: String },
    #[error("seed {seed} trial {trial}: observation: {msg}")]
    Observation { seed: u64, trial: u32, msg: String },
    #[error("bad demo config: {0}")]
    Config(String),
}

/// A latent the stages sent during a demonstration.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LatentRecord {
    /// World time of arrival \[s].
    pub t_s: f64,
    /// Contacts begun before it arrived (0: before any touch).
    pub touch: u32,
    /// real | predicted.
    pub source: String,
    pub shape: Vec<u32>,
    pub data: Vec<f32>,
}

/// One control tick of a demonstration: what the policies could observe before the command,
/// and the command. Unknown values are 0 with their `known` flag 0.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DemoTick {
    /// World time \[s].
    pub t_s: f64,
    /// The gripper's status as the policy's `gripper` input reads it ([`STATE_LEN`] values).
    pub state: Vec<f32>,
    /// The mean of the camera's estimates up to this tick, in [`Demo::visual_names`]' order
    /// (`observation.visual`).
    pub visual: Vec<f32>,
    /// The first chain's latest contact state: in contact, area \[mm^2], strength.
    pub contact: Vec<f32>,
    /// The opening the gripper reported at its first object-detect \[m], and known.
    pub latched: Vec<f32>,
    /// Time since the commanded arm target last changed \[s] (at most 10) and whether the arm
    /// has had its travel time ([`DemoConfig::approach_s`]): `observation.arm`.
    pub arm: Vec<f32>,
    /// Per object of [`Demo::objects`]: the pooled live latent of its touch (the first latent
    /// of touch k + 1 for object k: the expert touches them in order), then known.
    pub latent_real: Vec<f32>,
    /// Per object: the latest predicted latent for it, then known.
    pub latent_pred: Vec<f32>,
    /// The latest property comparison as the policy's `comparison` input reads it.
    pub comparison: Vec<f32>,
    /// The command, as the policy's action values ([`unitac_policy::Action::values`] order).
    pub action: Vec<f32>,
    /// Where the arm went: 0 home, k + 1 object k.
    pub arm_target: u32,
}

/// One demonstration: observations and labels.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Demo {
    pub task: TaskKind,
    pub seed: u64,
    pub trial: u32,
    pub split: Split,
    /// The task's objects, in the order of the per-object slices.
    pub objects: Vec<String>,
    /// Observations. The camera's estimate at the first tick (names as the VisualObservation
    /// message has them, values).
    pub visual_names: Vec<String>,
    pub visual_values: Vec<f64>,
    /// The gripper at the probe's first contact: opening \[m] and force \[N], and the contact
    /// stage's area \[m^2] there (cup; NaN for the fabrics).
    pub contact_opening_m: f64,
    pub contact_force_n: f64,
    pub contact_area_m2: f32,
    pub latents: Vec<LatentRecord>,
    /// Labels (ground truth and the expert). The cup's diameter \[m], its stiffness as the
    /// controllers use it (grip force at the target deformation / the target deformation,
    /// \[N/m]), the expert's squeeze setpoint (opening) \[m], its grip force at the end \[N]
    /// (NaN where the task has no cup).
    pub diameter_m: f64,
    pub stiffness_n_per_m: f64,
    pub expert_opening_m: f64,
    pub expert_force_n: f64,
    /// The expert's outcome at the end: the cup's loss of diameter \[m] (NaN for the fabrics)
    /// and overall success.
    pub deformation_m: f64,
    pub success: bool,
    /// Fabric: the fabric the expert decided to grasp ("" none, and for the cup) and the world
    /// time of the decision \[s] (NaN: none); the decision's tick is the first with `t_s` at or
    /// after it.
    pub chosen: String,
    pub decided_s: f64,
    /// Every control tick, first first.
    pub ticks: Vec<DemoTick>,
}

pub use unitac_policy::learned::pooled;

/// The driver's answer to one input: its commands, when both came (a tick's answer), and
/// whether its policy has ended.
struct Driven {
    command: Option<(GripperCommand, ArmCommand)>,
    ended: bool,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Phase {
    Approach,
    Touch,
    Press,
    Release,
    Expert,
}

/// The mock sensor of a demonstration: the scene's sensor settings with a noise seed of its own
/// per (seed, trial).
pub fn demo_sensor(base: &MockConfig, seed: u64, trial: u32) -> MockSensor {
    let mut cfg = base.clone();
    cfg.seed = base
        .seed
        .wrapping_add(seed.wrapping_mul(1_000_003))
        .wrapping_add(u64::from(trial));
    MockSensor::new(cfg, Scenario::idle(1.0))
}

/// What the chains have said so far: the first chain's latest contact state (it drives the
/// probe), the latents, and what a learned policy remembers of it all ([`Memory`]).
#[derive(Debug)]
struct Seen {
    contact: Option<ContactState>,
    latents: Vec<LatentRecord>,
    memory: Memory,
    /// A message the policy's inputs cannot read (the first one).
    bad: Option<String>,
}

impl Seen {
    fn keep(&mut self, out: Vec<Msg>, chain: usize, t_s: f64, layout: &Layout) {
        for m in out {
            match m {
                // The first chain's contact state drives the probe and the contact slice.
                Msg::ContactState(s) if chain == 0 => {
                    let m = Msg::ContactState(s.clone());
                    match features("contact", Some(m), layout, CONTACT_LEN) {
                        Ok(v) => self.memory.contact(v),
                        Err(e) => {
                            self.bad.get_or_insert(e);
                        }
                    }
                    self.contact = Some(s);
                }
                Msg::TactileLatent(l) => {
                    if let Err(e) = self.memory.latent(&l) {
                        self.bad.get_or_insert(e);
                    }
                    if self.latents.len() < MAX_LATENTS {
                        let real = l.source == LatentSource::Real;
                        self.latents.push(LatentRecord {
                            t_s,
                            touch: self.memory.touches,
                            source: if real { "real" } else { "predicted" }.into(),
                            shape: l.shape,
                            data: l.data,
                        });
                    }
                }
                Msg::PropertyComparison(c) => {
                    let m = Some(Msg::PropertyComparison(c));
                    match features("comparison", m, layout, COMPARISON_LEN) {
                        Ok(v) => self.memory.comparison(v),
                        Err(e) => {
                            self.bad.get_or_insert(e);
                        }
                    }
                }
                _ => {}
            }
        }
    }
}

/// The features of `msg` as the policy's input `name` reads them (`len` zeros when none yet).
fn features(name: &str, msg: Option<Msg>, layout: &Layout, len: usize) -> Result<Vec<f32>, String> {
    let Some(m) = msg else {
        return Ok(vec![0.0; len]);
    };
    let spec = input(name).ok_or_else(|| format!("no policy input '{name}'"))?;
    let mut out = Vec::with_capacity(len);
    (spec.features)(&m, layout, &mut out).map_err(|e| format!("{name}: {e}"))?;
    Ok(out)
}

/// The recording settings within their ranges, and at most [`MAX_CHAINS`] chains.
fn check_config(c: &DemoConfig, n_chains: usize) -> Result<(), DemoError> {
    if !(c.dt_s.is_finite() && c.dt_s > 0.0 && c.dt_s <= task::MAX_STEP_S) {
        return Err(DemoError::Config(format!("dt_s = {}", c.dt_s)));
    }
    for (k, v) in [
        ("touch_speed_m_s", c.touch_speed_m_s),
        ("touch_force_n", c.touch_force_n),
        ("timeout_s", c.timeout_s),
    ] {
        if !(v.is_finite() && v > 0.0) {
            return Err(DemoError::Config(format!("{k} = {v} must be > 0")));
        }
    }
    let ok = c.probe_release_m.is_finite()
        && c.probe_release_m >= 0.0
        && c.run_s.is_none_or(|s| (0.0..=600.0).contains(&s))
        && c.timeout_s <= 600.0
        && (0.0..=60.0).contains(&c.approach_s);
    if !ok {
        return Err(DemoError::Config(
            "probe_release_m must be >= 0; run_s in [0, 600] s; timeout_s at most 600 s; approach_s in [0, 60] s".into(),
        ));
    }
    if !(1..=4096).contains(&c.pooled_len) {
        return Err(DemoError::Config(format!(
            "pooled_len = {} (1 to 4096)",
            c.pooled_len
        )));
    }
    if n_chains > MAX_CHAINS {
        return Err(DemoError::Config(format!(
            "{} chains of stages (at most {MAX_CHAINS})",
            n_chains
        )));
    }
    Ok(())
}

/// What the driver's chain said: an error stops the demonstration; its commands, once both
/// came (a tick's status), drive the world.
fn driven(
    out: unitac_core::chain::ChainOutput,
    stage_err: &dyn Fn(&unitac_core::chain::Rejection) -> DemoError,
) -> Result<Driven, DemoError> {
    if let Some(r) = out.errors.first() {
        return Err(stage_err(r));
    }
    let mut gripper = None;
    let mut arm = None;
    let mut ended = false;
    for m in out.produced {
        match m {
            Msg::GripperCommand(g) => gripper = Some(g),
            Msg::ArmCommand(a) => arm = Some(a),
            Msg::PolicyStatus(s) => ended = matches!(s.phase.as_str(), "done" | "failed"),
            _ => {}
        }
    }
    Ok(Driven {
        command: gripper.zip(arm),
        ended,
    })
}

/// The command of `phase`: the expert's, or the probe's touch, press and release around the
/// opening `d0` at contact (the approach holds the expert's first opening, narrowed to the
/// camera's `seen_width` plus the pre-grasp, in `approach_grip`).
fn phase_command(
    phase: Phase,
    expert: TaskCommand,
    c: &DemoConfig,
    (d0, seen_width): (f64, Option<f64>),
    approach_grip: &mut Option<GripperSetpoint>,
) -> TaskCommand {
    match phase {
        // Fingers at the expert's first opening (a cup: the camera's width + the pads + the
        // pre-grasp margin, as the cup controller opens) until the probe or the squeeze: the
        // expert's own closing starts on the arm's true arrival, which no policy observes.
        Phase::Approach => TaskCommand {
            gripper: *approach_grip.get_or_insert_with(|| {
                let mut g = expert.gripper;
                if let Some(w) = seen_width {
                    g.opening_m = (w + c.pregrasp_m).min(g.opening_m);
                }
                g
            }),
            arm: expert.arm,
        },
        Phase::Expert => expert,
        Phase::Touch => TaskCommand {
            gripper: GripperSetpoint {
                opening_m: 0.0,
                speed_m_s: c.touch_speed_m_s,
                force_n: c.touch_force_n,
            },
            arm: expert.arm.clone(),
        },
        Phase::Press => TaskCommand {
            gripper: GripperSetpoint {
                opening_m: d0 - c.probe_press_m,
                speed_m_s: c.touch_speed_m_s,
                force_n: c.touch_force_n,
            },
            arm: ArmSetpoint {
                lift_m: 0.0,
                ..expert.arm.clone()
            },
        },
        Phase::Release => TaskCommand {
            gripper: GripperSetpoint {
                opening_m: d0 + c.probe_release_m,
                speed_m_s: c.touch_speed_m_s,
                force_n: c.touch_force_n,
            },
            arm: ArmSetpoint {
                lift_m: 0.0,
                ..expert.arm.clone()
            },
        },
    }
}

/// Record trial `trial` of `seed` on a cup of `split`, the frames going through `stages` (fresh
/// ones: they keep state per trial).
pub fn record(
    split: Split,
    seed: u64,
    trial: u32,
    sensor: &MockConfig,
    stages: Vec<Box<dyn Stage>>,
    c: &DemoConfig,
) -> Result<Demo, DemoError> {
    record_chains(split, seed, trial, sensor, vec![stages], c)
}

/// Record trial `trial` of `seed` of `c.task` on objects of `split`, the camera's estimates and
/// the frames going through each of `chains` (fresh stages: they keep state per trial).
pub fn record_chains(
    split: Split,
    seed: u64,
    trial: u32,
    sensor: &MockConfig,
    chains: Vec<Vec<Box<dyn Stage>>>,
    c: &DemoConfig,
) -> Result<Demo, DemoError> {
    record_inner(split, seed, trial, sensor, chains, None, c)
}

/// [`record_chains`] with the world driven by `driver` (a learned scene's stages, its policy
/// stage last, fresh): the states a learned policy visits, each tick labelled with the command
/// the expert would give there (DAgger's relabelling). The driver's chain takes each tick as a
/// trial feeds it (the frames, the camera's estimate, the gripper's status: crate::run) and its
/// GripperCommand and ArmCommand move the world; the recorded tick, its observation slices and
/// its label are what [`record_chains`] records, the probe's phases following what the first
/// chain observes. Where the expert's phases would time out (the policy never reached or touched
/// the cup) the demonstration ends there, its ticks kept; it also ends when the driver's
/// policy reports `done` or `failed`.
pub fn record_driven(
    split: Split,
    seed: u64,
    trial: u32,
    sensor: &MockConfig,
    chains: Vec<Vec<Box<dyn Stage>>>,
    driver: Vec<Box<dyn Stage>>,
    c: &DemoConfig,
) -> Result<Demo, DemoError> {
    record_inner(split, seed, trial, sensor, chains, Some(driver), c)
}

fn record_inner(
    split: Split,
    seed: u64,
    trial: u32,
    sensor: &MockConfig,
    chains: Vec<Vec<Box<dyn Stage>>>,
    driver: Option<Vec<Box<dyn Stage>>>,
    c: &DemoConfig,
) -> Result<Demo, DemoError> {
    check_config(c, chains.len())?;
    let (x, world) = Ctx::new(c, split, (seed, trial), driver.is_some());
    let mut world = WorldStepper::new(
        world,
        demo_sensor(sensor, seed, trial),
        trial_rng(seed ^ VISION_SALT, trial),
        TrialGripper::InProcess,
        (seed, trial),
        c.dt_s,
    )
    .map_err(|e| x.world_err(e))?;
    let mut chains: Vec<Chain> = chains.into_iter().map(Chain::new).collect();
    let mut driver = driver.map(Chain::new);
    let visual = world.visual();
    // The object's width as the camera first sees it: the approach opens to it plus the
    // pre-grasp.
    let seen_width = c.task.approach_width().and_then(|n| visual.get(n));
    let visual_msg = visual_message(&visual);
    let layout = Layout {
        latent_len: 0,
        visual_names: visual_msg.names.clone(),
        stroke_m: Some(x.cfg.gripper.max_opening_m),
    };
    let mut seen = Seen {
        contact: None,
        latents: Vec::new(),
        memory: Memory::new(&x.objects, c.pooled_len, c.approach_s),
        bad: None,
    };
    let mut expert = Expert::new(c, x.cfg.gripper.max_opening_m);
    let mut ticks = Vec::new();
    let stage_err = |r: &unitac_core::chain::Rejection| x.stage_err(r);
    loop {
        let t = world.time();
        // The camera's estimate first, as in a trial (the sampler's object-level condition).
        let seen_visual = if t == 0.0 {
            visual.clone()
        } else {
            world.visual()
        };
        let camera = visual_message(&seen_visual);
        let feed = (chains.as_mut_slice(), driver.as_mut(), &mut seen);
        observe(&x, &mut world, feed, &camera, &layout)?;
        let status = world.status().map_err(|e| x.world_err(e))?;
        // The driver's tick: the camera, then the gripper's status, as a trial feeds them.
        let driven_cmd = match driver.as_mut() {
            Some(d) => {
                driven(d.run(Msg::VisualObservation(camera.clone())), &stage_err)?;
                Some(driven(
                    d.run(Msg::GripperStatus(status.clone())),
                    &stage_err,
                )?)
            }
            None => None,
        };
        seen.memory
            .gripper(status.object_detected, status.opening_m);
        let visual = features("visual", Some(Msg::VisualObservation(camera)), &layout, 0)
            .map_err(|m| x.obs_err(m))?;
        let visual = seen.memory.visual(&visual);
        let truth = world.world().truth();
        let comparison = seen.memory.comparison.as_deref();
        if let Flow::End = expert.decide(&x, &truth, comparison, &seen_visual.names, &visual, t)? {
            break;
        }
        let to_do = expert_command(&truth, &x.spec, &x.cfg, expert.chosen.as_deref());
        let arm = seen.memory.arm(t);
        if let Flow::End = expert.advance(&x, &truth, &to_do, &arm, seen.contact.as_ref(), t)? {
            break;
        }
        let at = (expert.d0, seen_width);
        let cmd = phase_command(expert.phase, to_do, c, at, &mut expert.approach_grip);
        if ticks.len() >= MAX_TICKS {
            return Err(DemoError::Config(format!(
                "more than {MAX_TICKS} ticks in one demonstration"
            )));
        }
        let slices = (visual, arm);
        let tick = demo_tick(t, status, slices, &seen.memory, &cmd, &x.objects, &layout);
        ticks.push(tick.map_err(|m| x.obs_err(m))?);
        let Some(applied) = x.applied(&mut world, driven_cmd, &cmd, t)? else {
            break;
        };
        seen.memory.commanded(applied.arm.target.name(), t);
        expert.applied_target = applied.arm.target.name().to_string();
        world.step(Some(applied)).map_err(|e| x.world_err(e))?;
        if expert.phase == Phase::Expert {
            expert.last_cmd = Some(cmd);
        }
    }
    finish(&x, world.time(), &mut chains, &mut seen, &layout)?;
    Ok(expert.demo(
        &x,
        &world,
        (visual_msg.names, visual.values),
        seen.latents,
        ticks,
    ))
}

/// A step of the recording loop: go on, or the demonstration ends here (its ticks kept).
enum Flow {
    Go,
    End,
}

/// One demonstration's fixed context: its settings, task, objects and where it comes from.
struct Ctx<'a> {
    c: &'a DemoConfig,
    cfg: TaskConfig,
    spec: TrialSpec,
    objects: Vec<String>,
    split: Split,
    seed: u64,
    trial: u32,
    /// A driver's chain moves the world (DAgger): where the expert would time out, the
    /// demonstration ends instead.
    driven: bool,
    probe: bool,
    run_s: f64,
}

impl<'a> Ctx<'a> {
    /// The context of trial (`seed`, `trial`) of `c.task` on objects of `split`, and its world.
    fn new(
        c: &'a DemoConfig,
        split: Split,
        (seed, trial): (u64, u32),
        driven: bool,
    ) -> (Self, TaskWorld) {
        let cfg = TaskConfig::new(c.task, split);
        let world = TaskWorld::reset(&cfg, seed, trial);
        let spec = world.spec().clone();
        let x = Ctx {
            c,
            objects: spec.objects.iter().map(|o| o.name.clone()).collect(),
            spec,
            cfg,
            split,
            seed,
            trial,
            driven,
            // The probe touch is vtla_real's: its trigger, the contact state, is in its
            // observation.
            probe: c.mode == Mode::VtlaReal,
            run_s: c.run_s.unwrap_or_else(|| c.task.demo_s()),
        };
        (x, world)
    }

    fn world_err(&self, e: StepError) -> DemoError {
        DemoError::World {
            seed: self.seed,
            trial: self.trial,
            msg: e.to_string(),
        }
    }

    fn obs_err(&self, msg: String) -> DemoError {
        DemoError::Observation {
            seed: self.seed,
            trial: self.trial,
            msg,
        }
    }

    fn stage_err(&self, r: &unitac_core::chain::Rejection) -> DemoError {
        DemoError::Stage {
            seed: self.seed,
            trial: self.trial,
            stage: r.stage.clone(),
            msg: r.error.clone(),
        }
    }

    fn timeout(&self, what: &'static str) -> DemoError {
        DemoError::Timeout {
            seed: self.seed,
            trial: self.trial,
            what,
            timeout_s: self.c.timeout_s,
        }
    }

    /// The command the world takes at `t`: the driver's when one drives (None: its policy
    /// ended), else the expert's `cmd`.
    fn applied(
        &self,
        world: &mut WorldStepper,
        driven: Option<Driven>,
        cmd: &TaskCommand,
        t: f64,
    ) -> Result<Option<TaskCommand>, DemoError> {
        Ok(Some(match driven {
            Some(Driven { ended: true, .. }) => return Ok(None),
            Some(Driven {
                command: Some((g, a)),
                ..
            }) => world.command(&g, &a).map_err(|e| self.world_err(e))?,
            Some(Driven { command: None, .. }) => {
                return Err(DemoError::Stage {
                    seed: self.seed,
                    trial: self.trial,
                    stage: "policy".into(),
                    msg: format!("t = {t:.3} s: the driver gave no command for the gripper status"),
                });
            }
            None => cmd.clone(),
        }))
    }
}

/// The tick's observations through the chains (and the driver's, whose commands wait for the
/// gripper's status): the camera's estimate, then each frame; what the chains make of them goes
/// into `seen`, and a message the policy's inputs cannot read ends the demonstration.
fn observe(
    x: &Ctx,
    world: &mut WorldStepper,
    (chains, mut driver, seen): (&mut [Chain], Option<&mut Chain>, &mut Seen),
    camera: &VisualObservation,
    layout: &Layout,
) -> Result<(), DemoError> {
    let t = world.time();
    let stage_err = |r: &unitac_core::chain::Rejection| x.stage_err(r);
    for (k, chain) in chains.iter_mut().enumerate() {
        let out = chain.run(Msg::VisualObservation(camera.clone()));
        if let Some(r) = out.errors.first() {
            return Err(stage_err(r));
        }
        seen.keep(out.produced, k, t, layout);
    }
    for (frame, _truth) in world.frames() {
        if let Some(d) = driver.as_deref_mut() {
            driven(d.run(Msg::Frame(frame.clone())), &stage_err)?;
        }
        for (k, chain) in chains.iter_mut().enumerate() {
            let out = chain.run(Msg::Frame(frame.clone()));
            if let Some(r) = out.errors.first() {
                return Err(stage_err(r));
            }
            seen.keep(out.produced, k, t, layout);
        }
    }
    match seen.bad.take() {
        Some(msg) => Err(x.obs_err(msg)),
        None => Ok(()),
    }
}

/// The chains' pending output at the end (an open episode's), into `seen`.
fn finish(
    x: &Ctx,
    t: f64,
    chains: &mut [Chain],
    seen: &mut Seen,
    layout: &Layout,
) -> Result<(), DemoError> {
    for (k, chain) in chains.iter_mut().enumerate() {
        let out = chain.finish();
        if let Some(r) = out.errors.first() {
            return Err(x.stage_err(r));
        }
        seen.keep(out.produced, k, t, layout);
    }
    Ok(())
}

/// The recorded tick at `t`: the observation slices as a learned policy reads them (`memory`,
/// the camera's `visual` and the `arm`), the gripper's `status`, and the command `cmd` as the
/// action (its arm target as an index: 0 home, then the objects).
fn demo_tick(
    t: f64,
    status: GripperStatus,
    (visual, arm): (Vec<f32>, Vec<f32>),
    memory: &Memory,
    cmd: &TaskCommand,
    objects: &[String],
    layout: &Layout,
) -> Result<DemoTick, String> {
    let [
        (_, latched),
        (_, contact),
        (_, latent_real),
        (_, latent_pred),
        (_, comparison),
    ] = memory.features();
    Ok(DemoTick {
        t_s: t,
        state: features("gripper", Some(Msg::GripperStatus(status)), layout, 0)?,
        visual,
        contact,
        latched,
        arm,
        latent_real,
        latent_pred,
        comparison,
        action: action_values(cmd),
        arm_target: match cmd.arm.target.name() {
            "home" => 0,
            name => objects
                .iter()
                .position(|o| o == name)
                .map_or(0, |k| k as u32 + 1),
        },
    })
}

/// The expert's state through one demonstration: its phase and since when, the fabric decision
/// (when it was made, since when it was awaited), the probe's contact (opening `d0`, force,
/// area), the approach's grip, the last expert command and the arm target last applied.
struct Expert {
    phase: Phase,
    since: f64,
    chosen: Option<String>,
    decided_s: f64,
    waiting_since: Option<f64>,
    at_contact: (f64, f64, f32),
    d0: f64,
    last_cmd: Option<TaskCommand>,
    approach_grip: Option<GripperSetpoint>,
    applied_target: String,
}

impl Expert {
    fn new(c: &DemoConfig, max_opening_m: f64) -> Self {
        Expert {
            phase: if c.task.probe_first() {
                Phase::Approach
            } else {
                Phase::Expert
            },
            since: 0.0,
            chosen: None,
            decided_s: f64::NAN,
            waiting_since: None,
            at_contact: (f64::NAN, f64::NAN, f32::NAN),
            d0: max_opening_m,
            last_cmd: None,
            approach_grip: None,
            applied_target: String::new(),
        }
    }

    /// The fabric decision, once the task awaits it: from the live comparison (VTLA-real:
    /// [A rougher, B rougher, tie, ..], the smoother grasped; a tie leaves the camera) or the
    /// camera's guesses as the mode's policy reads them (`visual`, the mean so far, named by
    /// `names`). No decision within the timeout fails the demonstration (ends it, when driven).
    fn decide(
        &mut self,
        x: &Ctx,
        truth: &TaskTruth,
        comparison: Option<&[f32]>,
        names: &[String],
        visual: &[f32],
        t: f64,
    ) -> Result<Flow, DemoError> {
        let c = x.c;
        if !(c.task.decides()
            && self.chosen.is_none()
            && c.task.awaits_decision(truth, &x.spec, &x.cfg))
        {
            return Ok(Flow::Go);
        }
        let from = *self.waiting_since.get_or_insert(t);
        let camera = |name: &str| {
            let i = names.iter().position(|n| n == name)?;
            visual.get(i).map(|v| f64::from(*v))
        };
        let sight = || c.task.camera_choice(&x.spec, &camera).map(str::to_string);
        self.chosen = match c.mode {
            Mode::VtlaReal => match comparison {
                Some([a, ..]) if *a > 0.5 => x.objects.get(1).cloned(),
                Some([_, b, ..]) if *b > 0.5 => x.objects.first().cloned(),
                Some(_) => sight(),
                None => None,
            },
            Mode::Vla | Mode::VtlaPred => sight(),
        };
        if self.chosen.is_some() {
            self.decided_s = t;
        } else if t - from > c.timeout_s {
            if x.driven {
                return Ok(Flow::End);
            }
            return Err(x.timeout("no property comparison after both touches"));
        }
        Ok(Flow::Go)
    }

    /// The phase after this tick's observations (`arm`: the arm slice; `contact`: the first
    /// chain's latest contact state), the expert about to command `to_do`. The probe's phases
    /// time out (or end a driven demonstration); the expert's ends after `run_s`.
    fn advance(
        &mut self,
        x: &Ctx,
        truth: &TaskTruth,
        to_do: &TaskCommand,
        arm: &[f32],
        contact: Option<&ContactState>,
        t: f64,
    ) -> Result<Flow, DemoError> {
        let c = x.c;
        let in_contact = contact.is_some_and(|s| s.in_contact);
        let elapsed = t - self.since;
        let next = match self.phase {
            // Arrived where the expert sends the arm (a driver may have sent it elsewhere).
            Phase::Approach
                if truth.arm.arrived
                    && self.applied_target == to_do.arm.target.name()
                    && elapsed > c.dt_s
                    && arm[1] > 0.5 =>
            {
                Some(if x.probe { Phase::Touch } else { Phase::Expert })
            }
            Phase::Touch if in_contact => {
                self.d0 = truth.gripper.opening_m;
                self.at_contact = (
                    self.d0,
                    truth.gripper.force_n,
                    contact.map_or(f32::NAN, |s| s.area_m2),
                );
                Some(Phase::Press)
            }
            Phase::Press if elapsed >= c.probe_press_s => Some(Phase::Release),
            Phase::Release if !in_contact => Some(Phase::Expert),
            Phase::Expert if elapsed >= x.run_s => return Ok(Flow::End),
            Phase::Approach | Phase::Touch | Phase::Press | Phase::Release
                if elapsed > c.timeout_s && x.driven =>
            {
                return Ok(Flow::End);
            }
            Phase::Approach | Phase::Touch | Phase::Press | Phase::Release
                if elapsed > c.timeout_s =>
            {
                return Err(x.timeout(match self.phase {
                    Phase::Approach => "the arm did not reach the cup",
                    Phase::Touch => "no contact with the cup",
                    _ => "the probe contact did not end",
                }));
            }
            _ => None,
        };
        if let Some(p) = next {
            self.phase = p;
            self.since = t;
        }
        Ok(Flow::Go)
    }

    /// The demonstration once the world stopped: the camera's first view (`visual`: names and
    /// values), the latents, the ticks, the probe's contact, the cup's truth and the outcome.
    fn demo(
        self,
        x: &Ctx,
        world: &WorldStepper,
        (visual_names, visual_values): (Vec<String>, Vec<f64>),
        latents: Vec<LatentRecord>,
        ticks: Vec<DemoTick>,
    ) -> Demo {
        let truth = world.world().truth();
        let outcome = world.outcome();
        let deformation_m = match &outcome {
            task::TaskOutcome::Cup(o) => o.deformation_m,
            _ => f64::NAN,
        };
        let cup = x.spec.cup();
        let d = x.cfg.cup_criteria.target_deformation_m;
        Demo {
            task: x.c.task,
            seed: x.seed,
            trial: x.trial,
            split: x.split,
            objects: x.objects.clone(),
            visual_names,
            visual_values,
            contact_opening_m: self.at_contact.0,
            contact_force_n: self.at_contact.1,
            contact_area_m2: self.at_contact.2,
            latents,
            diameter_m: cup.map_or(f64::NAN, |c| c.diameter_m),
            stiffness_n_per_m: cup.map_or(f64::NAN, |c| c.stiffness_n_per_m(d)),
            expert_opening_m: self.last_cmd.map_or(f64::NAN, |c| c.gripper.opening_m),
            expert_force_n: truth.gripper.force_n,
            deformation_m,
            success: outcome.overall(),
            chosen: self.chosen.unwrap_or_default(),
            decided_s: self.decided_s,
            ticks,
        }
    }
}

/// A world command as the policy's action values ([`unitac_policy::Action::values`]' order and names).
pub fn action_values(cmd: &TaskCommand) -> Vec<f32> {
    let g = &cmd.gripper;
    let a = &cmd.arm;
    [
        g.opening_m,
        g.speed_m_s,
        g.force_n,
        a.xy_m[0],
        a.xy_m[1],
        a.z_m,
        a.lift_m,
    ]
    .iter()
    .map(|&v| v as f32)
    .collect()
}

/// The names of [`action_values`], as [`unitac_policy::Action::values`] has them (schema/policy.json).
pub fn action_names() -> Vec<&'static str> {
    unitac_policy::schema::COMMANDS.to_vec()
}
