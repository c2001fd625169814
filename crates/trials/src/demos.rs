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
use unitac_core::msg::{ArmCommand, ContactState, GripperCommand, LatentSource, Msg};
use unitac_policy::Mode;
use unitac_policy::learned::Memory;
use unitac_policy::observation::{Layout, input};
use unitac_sim::task::{
    self, ArmSetpoint, GripperSetpoint, Split, TaskCommand, TaskConfig, TaskKind, TaskWorld,
    expert_command, trial_rng,
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
    let cfg = TaskConfig::new(c.task, split);
    let world = TaskWorld::reset(&cfg, seed, trial);
    let spec = world.spec().clone();
    let objects: Vec<String> = spec.objects.iter().map(|o| o.name.clone()).collect();
    let cup = spec.cup().cloned();
    let world_err = |e: StepError| DemoError::World {
        seed,
        trial,
        msg: e.to_string(),
    };
    let obs_err = |msg: String| DemoError::Observation { seed, trial, msg };
    let mut world = WorldStepper::new(
        world,
        demo_sensor(sensor, seed, trial),
        trial_rng(seed ^ VISION_SALT, trial),
        TrialGripper::InProcess,
        (seed, trial),
        c.dt_s,
    )
    .map_err(world_err)?;
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
        stroke_m: Some(cfg.gripper.max_opening_m),
    };
    let width = c.pooled_len;

    let mut phase = if c.task.probe_first() {
        Phase::Approach
    } else {
        Phase::Expert
    };
    let run_s = c.run_s.unwrap_or_else(|| c.task.demo_s());
    let mut since = 0.0;
    // The probe touch is vtla_real's: its trigger, the contact state, is in its observation.
    let probe = c.mode == Mode::VtlaReal;
    // The fabric decision, when it was made, and since when the expert has waited for it.
    let mut chosen: Option<String> = None;
    let mut decided_s = f64::NAN;
    let mut waiting_since: Option<f64> = None;
    let mut seen = Seen {
        contact: None,
        latents: Vec::new(),
        memory: Memory::new(&objects, width, c.approach_s),
        bad: None,
    };
    let mut at_contact = (f64::NAN, f64::NAN, f32::NAN);
    let mut d0 = cfg.gripper.max_opening_m;
    let mut last_cmd: Option<TaskCommand> = None;
    let mut approach_grip: Option<GripperSetpoint> = None;
    // The arm target the world was last sent.
    let mut applied_target = String::new();
    let mut ticks = Vec::new();
    let stage_err = |r: &unitac_core::chain::Rejection| DemoError::Stage {
        seed,
        trial,
        stage: r.stage.clone(),
        msg: r.error.clone(),
    };
    let driven = |out| driven(out, &stage_err);
    let timeout = |what| DemoError::Timeout {
        seed,
        trial,
        what,
        timeout_s: c.timeout_s,
    };
    loop {
        let t = world.time();
        // The camera's estimate first, as in a trial (the sampler's object-level condition).
        let seen_visual = if t == 0.0 {
            visual.clone()
        } else {
            world.visual()
        };
        let camera = visual_message(&seen_visual);
        for (k, chain) in chains.iter_mut().enumerate() {
            let out = chain.run(Msg::VisualObservation(camera.clone()));
            if let Some(r) = out.errors.first() {
                return Err(stage_err(r));
            }
            seen.keep(out.produced, k, t, &layout);
        }
        for (frame, _truth) in world.frames() {
            if let Some(d) = driver.as_mut() {
                driven(d.run(Msg::Frame(frame.clone())))?;
            }
            for (k, chain) in chains.iter_mut().enumerate() {
                let out = chain.run(Msg::Frame(frame.clone()));
                if let Some(r) = out.errors.first() {
                    return Err(stage_err(r));
                }
                seen.keep(out.produced, k, t, &layout);
            }
        }
        if let Some(msg) = seen.bad.take() {
            return Err(obs_err(msg));
        }
        let status = world.status().map_err(world_err)?;
        // The driver's tick: the camera, then the gripper's status, as a trial feeds them.
        let driven_cmd = match driver.as_mut() {
            Some(d) => {
                driven(d.run(Msg::VisualObservation(camera.clone())))?;
                Some(driven(d.run(Msg::GripperStatus(status.clone())))?)
            }
            None => None,
        };
        seen.memory
            .gripper(status.object_detected, status.opening_m);
        let visual = features("visual", Some(Msg::VisualObservation(camera)), &layout, 0)
            .map_err(obs_err)?;
        let visual = seen.memory.visual(&visual);
        let truth = world.world().truth();
        if c.task.decides() && chosen.is_none() && c.task.awaits_decision(&truth, &spec, &cfg) {
            let from = *waiting_since.get_or_insert(t);
            // The camera's guesses as this mode's policy reads them: the mean so far.
            let camera = |name: &str| {
                let i = seen_visual.names.iter().position(|n| n == name)?;
                visual.get(i).map(|v| f64::from(*v))
            };
            let sight = || c.task.camera_choice(&spec, &camera).map(str::to_string);
            chosen = match c.mode {
                // [A rougher, B rougher, tie, ..]: grasp the smoother; a tie leaves the camera.
                Mode::VtlaReal => match seen.memory.comparison.as_deref() {
                    Some([a, ..]) if *a > 0.5 => objects.get(1).cloned(),
                    Some([_, b, ..]) if *b > 0.5 => objects.first().cloned(),
                    Some(_) => sight(),
                    None => None,
                },
                Mode::Vla | Mode::VtlaPred => sight(),
            };
            if chosen.is_some() {
                decided_s = t;
            } else if t - from > c.timeout_s {
                if driver.is_some() {
                    break;
                }
                return Err(timeout("no property comparison after both touches"));
            }
        }
        let expert = expert_command(&truth, &spec, &cfg, chosen.as_deref());
        let arm = seen.memory.arm(t);
        let in_contact = seen.contact.as_ref().is_some_and(|s| s.in_contact);
        let elapsed = t - since;
        let next = match phase {
            // Arrived where the expert sends the arm (a driver may have sent it elsewhere).
            Phase::Approach
                if truth.arm.arrived
                    && applied_target == expert.arm.target.name()
                    && elapsed > c.dt_s
                    && arm[1] > 0.5 =>
            {
                Some(if probe { Phase::Touch } else { Phase::Expert })
            }
            Phase::Touch if in_contact => {
                d0 = truth.gripper.opening_m;
                at_contact = (
                    d0,
                    truth.gripper.force_n,
                    seen.contact.as_ref().map_or(f32::NAN, |s| s.area_m2),
                );
                Some(Phase::Press)
            }
            Phase::Press if elapsed >= c.probe_press_s => Some(Phase::Release),
            Phase::Release if !in_contact => Some(Phase::Expert),
            Phase::Expert if elapsed >= run_s => break,
            Phase::Approach | Phase::Touch | Phase::Press | Phase::Release
                if elapsed > c.timeout_s && driver.is_some() =>
            {
                break;
            }
            Phase::Approach | Phase::Touch | Phase::Press | Phase::Release
                if elapsed > c.timeout_s =>
            {
                return Err(timeout(match phase {
                    Phase::Approach => "the arm did not reach the cup",
                    Phase::Touch => "no contact with the cup",
                    _ => "the probe contact did not end",
                }));
            }
            _ => None,
        };
        if let Some(p) = next {
            phase = p;
            since = t;
        }
        let cmd = phase_command(phase, expert, c, (d0, seen_width), &mut approach_grip);
        if ticks.len() >= MAX_TICKS {
            return Err(DemoError::Config(format!(
                "more than {MAX_TICKS} ticks in one demonstration"
            )));
        }
        let [
            (_, latched),
            (_, contact),
            (_, latent_real),
            (_, latent_pred),
            (_, comparison),
        ] = seen.memory.features();
        ticks.push(DemoTick {
            t_s: t,
            state: features("gripper", Some(Msg::GripperStatus(status)), &layout, 0)
                .map_err(obs_err)?,
            visual,
            contact,
            latched,
            arm,
            latent_real,
            latent_pred,
            comparison,
            action: action_values(&cmd),
            arm_target: match cmd.arm.target.name() {
                "home" => 0,
                name => objects
                    .iter()
                    .position(|o| o == name)
                    .map_or(0, |k| k as u32 + 1),
            },
        });
        let applied = match driven_cmd {
            Some(Driven { ended: true, .. }) => break,
            Some(Driven {
                command: Some((g, a)),
                ..
            }) => world.command(&g, &a).map_err(world_err)?,
            Some(Driven { command: None, .. }) => {
                return Err(DemoError::Stage {
                    seed,
                    trial,
                    stage: "policy".into(),
                    msg: format!("t = {t:.3} s: the driver gave no command for the gripper status"),
                });
            }
            None => cmd.clone(),
        };
        seen.memory.commanded(applied.arm.target.name(), t);
        applied_target = applied.arm.target.name().to_string();
        world.step(Some(applied)).map_err(world_err)?;
        if phase == Phase::Expert {
            last_cmd = Some(cmd);
        }
    }
    for (k, chain) in chains.iter_mut().enumerate() {
        let out = chain.finish();
        if let Some(r) = out.errors.first() {
            return Err(stage_err(r));
        }
        let t = world.time();
        seen.keep(out.produced, k, t, &layout);
    }
    let truth = world.world().truth();
    let outcome = world.outcome();
    let deformation_m = match &outcome {
        task::TaskOutcome::Cup(o) => o.deformation_m,
        _ => f64::NAN,
    };
    let success = outcome.overall();
    let d = cfg.cup_criteria.target_deformation_m;
    Ok(Demo {
        task: c.task,
        seed,
        trial,
        split,
        objects,
        visual_names: visual_msg.names,
        visual_values: visual.values,
        contact_opening_m: at_contact.0,
        contact_force_n: at_contact.1,
        contact_area_m2: at_contact.2,
        latents: seen.latents,
        diameter_m: cup.as_ref().map_or(f64::NAN, |c| c.diameter_m),
        stiffness_n_per_m: cup.as_ref().map_or(f64::NAN, |c| c.stiffness_n_per_m(d)),
        expert_opening_m: last_cmd.map_or(f64::NAN, |c| c.gripper.opening_m),
        expert_force_n: truth.gripper.force_n,
        deformation_m,
        success,
        chosen: chosen.unwrap_or_default(),
        decided_s,
        ticks,
    })
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
