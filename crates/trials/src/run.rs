//! One closed-loop trial: a task world driven by a scene's stages through messages.
//!
//! Each control tick (the policy's `control_rate_hz`, world time t):
//! 1. the mock sensor's frames captured up to t ([`crate::stepper::WorldStepper::frames`],
//!    rendered from the world's sensor view) go through the chain (contact, slip, encoder, ...);
//! 2. then the camera's observation ([`visual_message`]);
//! 3. then the gripper's status at t: the policy's tick. The chain's GripperCommand and
//!    ArmCommand for it become the world's command ([`crate::bridge::task_command`]) and the
//!    world steps one control period.
//!
//! The gripper is one seam ([`crate::gripper`], chosen by [`TrialGripper`]): in process (the
//! status from the world's gripper through [`crate::bridge::GripperGauge`], the command as the policy
//! gave it) or serial (the Modbus driver and a simulated device on a pty whose fingers are the
//! world's gripper, [`crate::serial`]: the status is the driver's, the world is driven with the
//! command as the device's registers hold it).
//!
//! The stages are driven by [`unitac_core::chain::Chain`] (the one chain driver: a stage's clock
//! is its input's stamp). They are built from the scene by the pipeline's registry
//! (`unitac_pipeline::build_stages`, the one every transport uses), fresh for each trial (stages
//! keep state); the pipeline's live-sensor part (its `v4l` feature) is not linked here.
//!
//! The scene's `source:` is not used: the world is the source. The mock sensor is the scene's
//! sensor kind (its `fps` and `sensor_id` if given), seeded from (seed, trial). The camera's
//! per-frame noise has its own stream, also from (seed, trial). Same scene, seed and trial give
//! the same trace, byte for byte.
//!
//! The trial ends one settle period ([`TrialOptions::settle_s`]) after the policy reports phase
//! `done` or `failed`, or at the task's time limit; the outcome is the world's judgement then.

use crate::bridge::visual_message;
use crate::gripper::TrialGripper;
use crate::serial::SerialReport;
use crate::stepper::{StepError, WorldStepper};
use serde::Serialize;
use thiserror::Error;
use unitac_core::chain::Chain;
use unitac_core::msg::{ArmCommand, GripperCommand, PolicyStatus};
use unitac_core::{Msg, Scene};
use unitac_policy::PolicyParams;
use unitac_sim::task::{
    Hidden, TaskConfig, TaskKind, TaskOutcome, TaskTruth, TaskWorld, trial_rng,
};
use unitac_sim::{MockConfig, MockSensor, Scenario};

/// Salts of the sensor's seed and the camera's noise stream (apart from the trial's own draw).
const SENSOR_SALT: u64 = 0x5345_4E53_4F52_0001;
const CAMERA_SALT: u64 = 0x4341_4D45_5241_0001;
const ARM_Z_NOISE_SALT: u64 = 0x4152_4D5A_4E53_0001;
/// Most arm height noise a trial adds to the policy's commands ([`TrialOptions::arm_z_noise_m`]) \[m].
pub const MAX_ARM_Z_NOISE_M: f64 = 0.01;
/// Longest trial anyone may ask for \[s] (bounds the trace).
pub const MAX_TRIAL_S: f64 = 600.0;
/// Rejections kept per trial (the count goes on).
const KEPT_REJECTIONS: usize = 20;
/// Phase changes kept per trial.
pub const KEPT_PHASES: usize = 64;
/// The phase in which a policy has made its choice (fabric selection): the arm target then is
/// the decision the selection criterion scores.
pub const DECISION_PHASE: &str = "approach_grasp";

/// A trial that could not run to its end.
#[derive(Debug, Error)]
pub enum TrialError {
    /// The scene cannot drive a trial (no policy stage, bad policy params).
    #[error("scene '{scene}': {msg}")]
    Scene { scene: String, msg: String },
    #[error("bad trial options: {0}")]
    Options(String),
    /// The policy did not answer a control tick with both commands.
    #[error("t = {t_s:.3} s: the chain gave no {missing} for the gripper status{}", rejections_note(.rejections))]
    NoCommand {
        t_s: f64,
        missing: &'static str,
        rejections: Vec<String>,
    },
    /// The world could not take the tick's step (a refused command, a serial gripper's failure,
    /// the world's refusal).
    #[error("t = {t_s:.3} s: gripper {gripper}: {source}")]
    Step {
        t_s: f64,
        gripper: &'static str,
        #[source]
        source: StepError,
    },
}

fn rejections_note(r: &[String]) -> String {
    if r.is_empty() {
        String::new()
    } else {
        format!(" ({})", r.join("; "))
    }
}

/// How long a trial may run, and what else it does.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrialOptions {
    /// Time limit \[s] (the world's time).
    pub max_s: f64,
    /// Time run on after the policy says done or failed \[s] (a late slip or drop counts).
    pub settle_s: f64,
    /// A hidden variable changed after the draw (the ground-truth test); None as drawn.
    pub hidden: Option<Hidden>,
    /// Record a digest of every tick's inputs to the chain and of its outputs
    /// ([`TrialRecord::io`]).
    pub record_io: bool,
    /// Keep every message the chain took but frames, and every message it produced, in order
    /// ([`TrialRecord::messages`]: the policy golden's inputs and outputs).
    pub keep_messages: bool,
    /// Uniform noise of up to this much \[m] added to the arm height of every command the
    /// policy sends, drawn per tick from the trial's own stream (0: none): a policy whose arm
    /// does not hold its height still, as a learned policy's does. The policy never sees it.
    pub arm_z_noise_m: f64,
}

impl TrialOptions {
    /// The limits the table runs use: the task's longest trial ([`unitac_sim::task::Task::trial_s`]:
    /// the cup task 40 s, the fabric task 90 s for touch, touch, compare, grasp, lift at the
    /// policy's speeds), 1 s to settle.
    pub fn for_task(kind: TaskKind) -> Self {
        Self {
            max_s: kind.trial_s(),
            settle_s: 1.0,
            hidden: None,
            record_io: false,
            keep_messages: false,
            arm_z_noise_m: 0.0,
        }
    }
    fn check(&self) -> Result<(), TrialError> {
        let ok = |v: f64, hi: f64| v.is_finite() && v >= 0.0 && v <= hi;
        if !(ok(self.max_s, MAX_TRIAL_S) && self.max_s > 0.0 && ok(self.settle_s, MAX_TRIAL_S)) {
            return Err(TrialError::Options(format!(
                "max_s = {}, settle_s = {} (max_s in (0, {MAX_TRIAL_S}] s, settle_s in [0, {MAX_TRIAL_S}] s)",
                self.max_s, self.settle_s
            )));
        }
        let z = self.arm_z_noise_m;
        if !(z.is_finite() && (0.0..=MAX_ARM_Z_NOISE_M).contains(&z)) {
            return Err(TrialError::Options(format!(
                "arm_z_noise_m = {z} (in [0, {MAX_ARM_Z_NOISE_M}] m)"
            )));
        }
        Ok(())
    }
}

/// One control tick of a trial: the world's truth at `t_s` (measured, never shown to the
/// policy) and what the policy said.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TraceRow {
    pub t_s: f64,
    /// Gripper opening \[m] and grip force per finger \[N] (truth).
    pub opening_m: f64,
    pub force_n: f64,
    /// Deformation of the object between the fingers (cup diameter loss, fabric stack
    /// compression) \[m] (truth).
    pub deformation_m: f64,
    /// Relative motion of object and fingers since the grasp, unsigned \[m] (truth).
    pub slip_m: f64,
    /// The slip stage's flag on its latest frame (None: no slip stage in the scene, or no
    /// state yet).
    pub slip_detected: Option<bool>,
    /// Lift of the object between the fingers \[m] (truth; 0 when none).
    pub lift_m: f64,
    /// The policy's phase, whether the safety layer let its action through, and why.
    pub phase: String,
    pub safety_ok: bool,
    pub reason: String,
}

/// What went into the chain at one control tick and what came out, as digests (FNV-1a 64 of the
/// messages' bytes: frame pixels and stamps, the camera's values, the gripper's status; the
/// commands and the status), and whether the world had the gels touching an object then.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct TickIo {
    pub inputs: u64,
    pub outputs: u64,
    pub touching: bool,
}

/// A finished trial: its trace and the world's outcome.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TrialRecord {
    pub scene: String,
    pub mode: String,
    pub seed: u64,
    pub trial: u32,
    /// The objects drawn, for reading a trace (e.g. `cup 90 mm, 210 N/m`).
    pub objects: String,
    pub control_rate_hz: f64,
    pub duration_s: f64,
    pub frames: u64,
    /// The policy's last phase (`done`, `failed`, or where the time limit caught it) and its
    /// last message (the failure's reason when it failed).
    pub end_phase: String,
    pub end_reason: String,
    /// `t phase: message` at each phase change (the first [`KEPT_PHASES`]): the trial's story.
    pub phases: Vec<String>,
    pub outcome: TaskOutcome,
    /// Inputs a stage rejected (the first few) and how many in all.
    pub rejections: Vec<String>,
    pub rejected: u64,
    pub trace: Vec<TraceRow>,
    /// The gripper driven: `sim` (in process) or a serial model's name.
    pub gripper: String,
    /// What went over the wire (serial grippers only).
    pub serial: Option<SerialReport>,
    /// Control ticks, and per value the ticks whose proposal had it beyond a bound by more than
    /// 2 % of its range (PolicyStatus.clamped: the safety layer's and the readouts').
    pub ticks: u64,
    pub clamped: std::collections::BTreeMap<String, u64>,
    /// Ticks on which the safety layer's tactile reflex acted, per kind (`slip`, `grasp not
    /// confirmed`; PolicyStatus.message names every reflex action, `reflex: ...`).
    pub reflex: std::collections::BTreeMap<String, u64>,
    /// Every tick by what it sent (PolicyStatus through `unitac_policy::TickKind`): the
    /// policy's action, or the safe action and why (a policy error, an inference over its time
    /// limit, a refused action, the watchdog, the controller's `failed` phase).
    pub policy_ticks: unitac_policy::TickCounts,
    /// The cup's stiffness as the policy read it and as it is, when the policy read one.
    pub stiffness: Option<StiffnessReading>,
    /// Per tick, when [`TrialOptions::record_io`].
    #[serde(skip)]
    pub io: Vec<TickIo>,
    /// When [`TrialOptions::keep_messages`]: the chain's inputs but frames and its outputs, in
    /// the order they went in and came out.
    #[serde(skip)]
    pub messages: Vec<ChainMessage>,
    /// What the tactile stages told the policy stage: every latent and comparison, in order
    /// (a [`TouchSwap`]'s donor for another trial).
    #[serde(skip)]
    pub touch: Vec<Msg>,
}

/// A cup controller's stiffness reading against the truth.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StiffnessReading {
    /// The last stiffness the policy's status named \[N/m] (after its readout's clip).
    pub read_n_per_m: f64,
    /// The cup's: grip force at the target deformation over that deformation \[N/m] (the
    /// demonstrations' label, [`unitac_sim::task::CupSpec::stiffness_n_per_m`]).
    pub true_n_per_m: f64,
    /// Ticks on which the readout had to clip a reading to its range (`readout.stiffness`).
    pub clipped_ticks: u64,
    /// The camera's width the reading came from \[m] (vla's force rule).
    pub camera_width_m: Option<f64>,
    /// The cup's true diameter \[m] (for calibrating a camera rule on training cups).
    pub true_diameter_m: f64,
}

/// The touch ablation: the latents, comparisons and contact geometry the tactile stages send the
/// policy stage carry another trial's values (the k-th latent of each source, the k-th
/// comparison, and the k-th in-contact state's box, centroid, areas and strength the donor
/// trial's stages made), each keeping its own stamp, object and contact on/off; the policy's
/// other inputs, the world and the frames are this trial's. When a contact starts and ends stays
/// this trial's: a policy cannot touch without knowing that it touches.
#[derive(Debug, Default)]
pub struct TouchSwap {
    donor: Vec<Msg>,
    /// This trial's latents per source and comparisons so far.
    real: usize,
    predicted: usize,
    comparisons: usize,
    /// This trial's in-contact states so far.
    contacts: usize,
    /// This trial's own, in order.
    own: Vec<Msg>,
}

impl TouchSwap {
    /// Values from `donor` (a trial's [`TrialRecord::touch`]); an empty donor swaps nothing.
    pub fn new(donor: Vec<Msg>) -> Self {
        Self {
            donor,
            ..Self::default()
        }
    }

    /// The k-th message of the donor that `pick` accepts.
    fn nth(&self, k: usize, pick: impl Fn(&Msg) -> bool) -> Option<&Msg> {
        self.donor.iter().filter(|m| pick(m)).nth(k)
    }

    /// A message between the tactile stages and the policy stage.
    fn apply(&mut self, m: Msg) -> Msg {
        match m {
            Msg::TactileLatent(mut l) => {
                self.own.push(Msg::TactileLatent(l.clone()));
                let real = l.source == unitac_core::msg::LatentSource::Real;
                let counter = if real {
                    &mut self.real
                } else {
                    &mut self.predicted
                };
                let k = *counter;
                *counter += 1;
                let source = l.source;
                let same = |m: &Msg| matches!(m, Msg::TactileLatent(d) if d.source == source);
                if let Some(Msg::TactileLatent(d)) = self.nth(k, same) {
                    l.shape.clone_from(&d.shape);
                    l.data.clone_from(&d.data);
                }
                Msg::TactileLatent(l)
            }
            Msg::PropertyComparison(mut c) => {
                self.own.push(Msg::PropertyComparison(c.clone()));
                let k = self.comparisons;
                self.comparisons += 1;
                if let Some(Msg::PropertyComparison(d)) =
                    self.nth(k, |m| matches!(m, Msg::PropertyComparison(_)))
                {
                    c.winner = d.winner;
                    c.margin = d.margin;
                    c.confidence = d.confidence;
                    c.sentence.clone_from(&d.sentence);
                }
                Msg::PropertyComparison(c)
            }
            Msg::ContactState(mut c) if c.in_contact => {
                self.own.push(Msg::ContactState(c.clone()));
                let k = self.contacts;
                self.contacts += 1;
                if let Some(Msg::ContactState(d)) =
                    self.nth(k, |m| matches!(m, Msg::ContactState(d) if d.in_contact))
                {
                    c.bbox_px = d.bbox_px;
                    c.centroid_px = d.centroid_px;
                    c.area_px = d.area_px;
                    c.area_m2 = d.area_m2;
                    c.strength = d.strength;
                }
                Msg::ContactState(c)
            }
            m => m,
        }
    }
}

/// A message that went into the chain (`input`) or came out of it.
#[derive(Debug, Clone, PartialEq)]
pub struct ChainMessage {
    pub input: bool,
    pub msg: Msg,
}

impl ChainMessage {
    /// The message's JSON ([`Msg::to_json`]) with `"input": true` on an input: a line of the
    /// policy golden files.
    pub fn to_json(&self) -> serde_json::Value {
        let mut v = self.msg.to_json();
        if let (true, Some(o)) = (self.input, v.as_object_mut()) {
            o.insert("input".into(), serde_json::Value::Bool(true));
        }
        v
    }
}

/// FNV-1a 64: a stable digest of bytes (the same on every platform and Rust version).
#[derive(Debug, Clone, Copy)]
struct Fnv(u64);

impl Fnv {
    fn new() -> Self {
        Fnv(0xcbf2_9ce4_8422_2325)
    }
    fn bytes(&mut self, b: &[u8]) {
        for &x in b {
            self.0 = (self.0 ^ u64::from(x)).wrapping_mul(0x0000_0100_0000_01b3);
        }
    }
    /// A message: its Debug text (every field, floats exactly), and a frame's pixels.
    fn msg(&mut self, m: &Msg) {
        if let Msg::Frame(f) = m {
            self.bytes(&f.stamp.0.to_le_bytes());
            self.bytes(f.data());
        } else {
            self.bytes(format!("{m:?}").as_bytes());
        }
    }
}

/// The scene's policy params (the first policy stage; a trial needs one).
pub fn policy_params(scene: &Scene) -> Result<PolicyParams, TrialError> {
    let bad = |msg: String| TrialError::Scene {
        scene: scene.name.clone(),
        msg,
    };
    let st = scene
        .stages
        .iter()
        .find(|s| s.kind == "policy")
        .ok_or_else(|| bad("no policy stage: nothing would command the gripper".into()))?;
    let p: PolicyParams = if st.params.is_null() {
        PolicyParams::default()
    } else {
        serde_yaml::from_value(st.params.clone()).map_err(|e| bad(format!("policy params: {e}")))?
    };
    p.check().map_err(|e| bad(format!("policy params: {e}")))?;
    Ok(p)
}

/// The mock sensor of trial `trial` of `seed` on the scene's sensor.
pub fn trial_sensor(scene: &Scene, seed: u64, trial: u32) -> MockSensor {
    let mut cfg = MockConfig::new(
        scene.source.sensor,
        trial_rng(seed ^ SENSOR_SALT, trial).next_u64(),
    );
    if let Some(fps) = scene.source.fps.filter(|f| f.is_finite() && *f > 0.0) {
        cfg.fps = fps;
    }
    if let Some(id) = scene.source.sensor_id.clone() {
        cfg.sensor_id = id;
    }
    // The scenario is not rendered (the world's sensor view is); it only sizes the sensor.
    MockSensor::new(cfg, Scenario::idle(MAX_TRIAL_S))
}

/// The cup's true stiffness label \[N/m] and diameter \[m] (NaN without a cup).
fn true_cup(world: &TaskWorld) -> (f64, f64) {
    let d = world.config().cup_criteria.target_deformation_m;
    world
        .spec()
        .objects
        .iter()
        .find_map(|o| match &o.spec {
            unitac_sim::task::ObjectSpec::Cup(c) => Some((c.stiffness_n_per_m(d), c.diameter_m)),
            unitac_sim::task::ObjectSpec::Fabric(_) => None,
        })
        .unwrap_or((f64::NAN, f64::NAN))
}

fn describe(world: &TaskWorld) -> String {
    use unitac_sim::task::ObjectSpec;
    world
        .spec()
        .objects
        .iter()
        .map(|o| match &o.spec {
            ObjectSpec::Cup(c) => format!(
                "{} {:.0} mm, {:.0} N/m, {:.0} g",
                o.name,
                c.diameter_m * 1e3,
                c.wall.k_n_per_m,
                c.mass_kg * 1e3
            ),
            ObjectSpec::Fabric(f) => format!(
                "{} {} (Ra {:.4} mm, {} layers)",
                o.name,
                f.fabric.name,
                f.roughness_ra_m * 1e3,
                f.layers
            ),
        })
        .collect::<Vec<_>>()
        .join("; ")
}

/// What the chain said for one control tick.
#[derive(Default)]
struct TickOutput {
    gripper: Option<GripperCommand>,
    arm: Option<ArmCommand>,
    status: Option<PolicyStatus>,
}

impl TickOutput {
    /// What the chain made of a tick's gripper status: the commands and the policy's status
    /// (each into `digest` when given); a slip state updates `slip`.
    fn of(produced: Vec<Msg>, mut digest: Option<&mut Fnv>, slip: &mut Option<bool>) -> Self {
        let mut tick = TickOutput::default();
        for m in produced {
            if let Some(d) = digest.as_deref_mut() {
                d.msg(&m);
            }
            match m {
                Msg::GripperCommand(c) => tick.gripper = Some(c),
                Msg::ArmCommand(a) => tick.arm = Some(a),
                Msg::PolicyStatus(s) => tick.status = Some(s),
                Msg::SlipState(s) => *slip = Some(s.slip),
                _ => {}
            }
        }
        tick
    }

    /// The gripper and arm commands and the status, or the tick at `t` is an error naming the
    /// first one missing (with the chain's `rejections`).
    fn commands(
        self,
        t: f64,
        rejections: Vec<String>,
    ) -> Result<(GripperCommand, ArmCommand, PolicyStatus), TrialError> {
        let missing = |what| TrialError::NoCommand {
            t_s: t,
            missing: what,
            rejections: rejections.clone(),
        };
        let g = self.gripper.ok_or_else(|| missing("GripperCommand"))?;
        let a = self.arm.ok_or_else(|| missing("ArmCommand"))?;
        let status = self.status.ok_or_else(|| missing("PolicyStatus"))?;
        Ok((g, a, status))
    }
}

/// Run trial `trial` of `seed` of `scene` on the task `task` with the scene's stages (built
/// from the scene, fresh), the in-process gripper. Errors: the scene cannot drive a trial, the
/// policy left a tick unanswered, or a command the bridge or the world refuses.
pub fn run_trial(
    scene: &Scene,
    task: &TaskConfig,
    seed: u64,
    trial: u32,
    opts: &TrialOptions,
) -> Result<TrialRecord, TrialError> {
    run_trial_on(scene, task, seed, trial, opts, TrialGripper::InProcess)
}

/// [`run_trial`] with the gripper `gripper`; a serial gripper that fails (cannot start, a fault,
/// no answer) is an error too.
pub fn run_trial_on(
    scene: &Scene,
    task: &TaskConfig,
    seed: u64,
    trial: u32,
    opts: &TrialOptions,
    gripper: TrialGripper,
) -> Result<TrialRecord, TrialError> {
    run_trial_swapped(
        scene,
        task,
        seed,
        trial,
        opts,
        gripper,
        TouchSwap::default(),
    )
}

/// Every object the policy names is one of the task world's.
fn check_objects(
    scene: &Scene,
    params: &PolicyParams,
    task: &TaskConfig,
    world: &TaskWorld,
) -> Result<(), TrialError> {
    let names: Vec<&str> = world
        .spec()
        .objects
        .iter()
        .map(|o| o.name.as_str())
        .collect();
    let foreign: Vec<&str> = params
        .limits
        .objects
        .iter()
        .map(String::as_str)
        .filter(|o| !names.contains(o))
        .collect();
    if !foreign.is_empty() {
        return Err(TrialError::Scene {
            scene: scene.name.clone(),
            msg: format!(
                "policy objects {foreign:?} are not in the {} task's world ({})",
                task.kind.name(),
                names.join(", ")
            ),
        });
    }
    Ok(())
}

impl TrialRecord {
    /// A record of trial (`seed`, `trial`) of `scene` before its first tick.
    fn new(
        scene: &Scene,
        params: &PolicyParams,
        (seed, trial): (u64, u32),
        world: &WorldStepper,
        gripper: TrialGripper,
    ) -> Self {
        TrialRecord {
            scene: scene.name.clone(),
            mode: params.mode.as_str().to_string(),
            seed,
            trial,
            objects: describe(world.world()),
            control_rate_hz: params.control_rate_hz,
            duration_s: 0.0,
            frames: 0,
            end_phase: String::new(),
            end_reason: String::new(),
            phases: Vec::new(),
            outcome: world.outcome(),
            rejections: Vec::new(),
            rejected: 0,
            trace: Vec::new(),
            gripper: gripper.name().to_string(),
            serial: None,
            ticks: 0,
            clamped: Default::default(),
            reflex: Default::default(),
            policy_ticks: Default::default(),
            stiffness: None,
            io: Vec::new(),
            messages: Vec::new(),
            touch: Vec::new(),
        }
    }

    /// The chain's rejections: counted, the first [`KEPT_REJECTIONS`] kept.
    fn keep(&mut self, errors: Vec<unitac_core::chain::Rejection>) {
        for e in errors {
            self.rejected += 1;
            if self.rejections.len() < KEPT_REJECTIONS {
                self.rejections.push(e.to_string());
            }
        }
    }

    /// A policy tick's status: its phase counted, its clamps, the stiffness it read (against
    /// the world's cup) and its reflexes.
    fn note_status(&mut self, status: &PolicyStatus, world: &TaskWorld) {
        self.ticks += 1;
        self.policy_ticks.count(status);
        for c in &status.clamped {
            *self.clamped.entry(c.clone()).or_default() += 1;
        }
        if let Some(k) = unitac_policy::controller::cup::stiffness_in(&status.message) {
            self.stiffness = Some(StiffnessReading {
                read_n_per_m: k,
                true_n_per_m: true_cup(world).0,
                true_diameter_m: true_cup(world).1,
                clipped_ticks: self.clamped.get("readout.stiffness").copied().unwrap_or(0),
                camera_width_m: unitac_policy::controller::cup::camera_width_in(&status.message),
            });
        }
        if let Some(r) = status.message.strip_prefix("reflex: ") {
            let kind = if r.starts_with("slip") {
                "slip"
            } else if r.starts_with("grasp not confirmed") {
                "grasp not confirmed"
            } else {
                "other"
            };
            *self.reflex.entry(kind.to_string()).or_default() += 1;
        }
    }

    /// The tick's trace row at `t`, and its phase when it changed (the first [`KEPT_PHASES`]).
    fn note_tick(
        &mut self,
        t: f64,
        truth: &TaskTruth,
        slip_detected: Option<bool>,
        status: &PolicyStatus,
    ) {
        let held = truth.objects.iter().find(|o| o.held);
        self.trace.push(TraceRow {
            t_s: t,
            opening_m: truth.gripper.opening_m,
            force_n: truth.gripper.force_n,
            deformation_m: truth.contact.deformation_m,
            slip_m: truth.contact.slip_total_m,
            slip_detected,
            lift_m: held.map_or(0.0, |o| o.position_m[2]),
            phase: status.phase.clone(),
            safety_ok: status.safety_ok,
            reason: status.message.clone(),
        });
        if (self.phases.is_empty() || self.end_phase != status.phase)
            && self.phases.len() < KEPT_PHASES
        {
            self.phases
                .push(format!("{t:.3} {}: {}", status.phase, status.message));
        }
    }
}

/// The chain's inputs in a trial, the policy stage's (at `policy_at`) passing through `swap`.
struct Feed<'a> {
    opts: &'a TrialOptions,
    policy_at: usize,
    swap: TouchSwap,
}

impl Feed<'_> {
    /// One input through the chain, with what the options keep of it: its digest
    /// (`record_io`), it and what the chain made of it (`keep_messages`; frames are not kept).
    fn run(
        &mut self,
        chain: &mut Chain,
        record: &mut TrialRecord,
        digest: &mut Fnv,
        m: Msg,
    ) -> unitac_core::chain::ChainOutput {
        if self.opts.record_io {
            digest.msg(&m);
        }
        let kept = self.opts.keep_messages && !m.is_frame();
        if kept {
            record.messages.push(ChainMessage {
                input: true,
                msg: m.clone(),
            });
        }
        let swap = &mut self.swap;
        let out = chain.run_mapped(m, self.policy_at, &mut |x| swap.apply(x));
        if self.opts.keep_messages {
            record
                .messages
                .extend(out.produced.iter().map(|m| ChainMessage {
                    input: false,
                    msg: m.clone(),
                }));
        }
        out
    }
}

/// [`run_trial_on`] with the touch values of another trial ([`TouchSwap`]; the default swaps
/// nothing).
pub fn run_trial_swapped(
    scene: &Scene,
    task: &TaskConfig,
    seed: u64,
    trial: u32,
    opts: &TrialOptions,
    gripper: TrialGripper,
    swap: TouchSwap,
) -> Result<TrialRecord, TrialError> {
    opts.check()?;
    // The policy stage's place: what the stages before it send it passes through `swap`.
    let policy_at = scene
        .stages
        .iter()
        .position(|s| s.kind == "policy")
        .unwrap_or(scene.stages.len());
    let (scene, params, task) = crate::scene::for_gripper(scene, task, gripper)?;
    let (scene, task) = (&scene, &task);
    let stages = unitac_pipeline::build_stages(scene).map_err(|e| TrialError::Scene {
        scene: scene.name.clone(),
        msg: e.to_string(),
    })?;
    let dt = 1.0 / params.control_rate_hz;
    let mut world = TaskWorld::reset(task, seed, trial);
    if let Some(h) = opts.hidden {
        world.perturb(h);
    }
    check_objects(scene, &params, task, &world)?;
    let step_error = move |t_s: f64| {
        move |source: StepError| TrialError::Step {
            t_s,
            gripper: gripper.name(),
            source,
        }
    };
    let mut world = WorldStepper::new(
        world,
        trial_sensor(scene, seed, trial),
        trial_rng(seed ^ CAMERA_SALT, trial),
        gripper,
        (seed, trial),
        dt,
    )
    .map_err(step_error(0.0))?;
    let mut chain = Chain::new(stages);
    let mut record = TrialRecord::new(scene, &params, (seed, trial), &world, gripper);
    let mut slip_detected = None;
    let mut ended_at: Option<f64> = None;
    let mut z_noise = trial_rng(seed ^ ARM_Z_NOISE_SALT, trial);
    let ticks = (opts.max_s / dt).ceil() as u64;
    let mut feed = Feed {
        opts,
        policy_at,
        swap,
    };
    for _ in 0..ticks {
        let t = world.time();
        let mut inputs = Fnv::new();
        let mut outputs = Fnv::new();
        let touching = opts.record_io && world.world().truth().contact.penetration_m > 0.0;
        for (frame, _) in world.frames() {
            record.frames += 1;
            let out = feed.run(&mut chain, &mut record, &mut inputs, Msg::Frame(frame));
            for m in &out.produced {
                if let Msg::SlipState(s) = m {
                    slip_detected = Some(s.slip);
                }
            }
            record.keep(out.errors);
        }
        let visual = Msg::VisualObservation(visual_message(&world.visual()));
        let out = feed.run(&mut chain, &mut record, &mut inputs, visual);
        record.keep(out.errors);
        let truth = world.world().truth();
        let status = Msg::GripperStatus(world.status().map_err(step_error(t))?);
        let out = feed.run(&mut chain, &mut record, &mut inputs, status);
        let digest = opts.record_io.then_some(&mut outputs);
        let tick = TickOutput::of(out.produced, digest, &mut slip_detected);
        let rejections: Vec<String> = out.errors.iter().map(|e| e.to_string()).collect();
        record.keep(out.errors);
        let (g, a, status) = tick.commands(t, rejections)?;
        record.note_status(&status, world.world());
        if opts.record_io {
            record.io.push(TickIo {
                inputs: inputs.0,
                outputs: outputs.0,
                touching,
            });
        }
        let mut cmd = world.command(&g, &a).map_err(step_error(t))?;
        if opts.arm_z_noise_m > 0.0 {
            cmd.arm.z_m += opts.arm_z_noise_m * (2.0 * z_noise.uniform() - 1.0);
        }
        record.note_tick(t, &truth, slip_detected, &status);
        // The scene controllers announce their choice by going to approach_grasp, aimed at it.
        if status.phase == DECISION_PHASE {
            world.world_mut().decide(&a.target);
        }
        record.end_phase = status.phase;
        record.end_reason = status.message;
        if ended_at.is_none() && matches!(record.end_phase.as_str(), "done" | "failed") {
            ended_at = Some(t);
        }
        if ended_at.is_some_and(|e| t - e >= opts.settle_s) {
            break;
        }
        world.step(Some(cmd)).map_err(step_error(t))?;
    }
    record.serial = world.report();
    record.duration_s = world.time();
    record.touch = std::mem::take(&mut feed.swap.own);
    record.outcome = world.outcome();
    Ok(record)
}

/// The trace as JSON lines (one row per line): the bytes the determinism test compares.
pub fn trace_jsonl(record: &TrialRecord) -> Result<String, serde_json::Error> {
    let mut s = String::new();
    for row in &record.trace {
        s.push_str(&serde_json::to_string(row)?);
        s.push('\n');
    }
    Ok(s)
}
