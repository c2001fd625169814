//! Demonstrations with observations: the scripted expert on the cup task, recorded with what a
//! policy could observe (the tactile latents the scene's stages make of the mock sensor's
//! frames, the camera's estimate, the gripper's state) next to the expert's labels (the cup's
//! true stiffness, the expert's grasp setpoint). The reference policies are fitted on these
//! (scripts/fit_reference_policy.py), on training cups only.
//!
//! One demonstration, per tick of `dt_s`:
//!
//! ```text
//! approach: the expert's command (arm to the cup, fingers wide) until the arm has arrived
//! touch:    close at touch_speed_m_s with touch_force_n until the contact stage says contact
//!           (the opening there is D0): the probe touch the vtla_real controller makes
//! release:  open to D0 + probe_release_m until the contact stage says the contact ended (the
//!           episode's clip goes to the encoder: its latent is the touch's observation)
//! expert:   the expert's own commands (squeeze to its setpoint, settle, lift) for expert_s
//! ```
//!
//! Each tick the camera's estimate goes into the stages first (as in a trial: the sampler's
//! object-level condition), then the frames are rendered at the sensor's own frame times by
//! [`crate::bridge::SensorRig`] and pushed through the scene's tactile stages with [`Chain`] (contact + encoder for vtla_real, contact + sampler
//! for vtla_pred): the stages are built by the caller from the scene, so this module sees only
//! `Stage`s. Every latent the stages send is kept with the number of contacts begun before it
//! (0: a prediction before any touch; 1: the probe touch). Same inputs, same bytes.

use serde::Serialize;
use thiserror::Error;
use unitac_core::Stage;
use unitac_core::chain::Chain;
use unitac_core::msg::{ContactState, LatentSource, Msg};
use unitac_sim::task::{
    self, ArmSetpoint, GripperSetpoint, Split, TaskCommand, TaskConfig, TaskWorld, expert_command,
    trial_rng,
};
use unitac_sim::{MockConfig, MockSensor, Scenario};

use crate::bridge::visual_message;
use crate::gripper::TrialGripper;
use crate::stepper::{StepError, WorldStepper};

/// Salt of the camera noise stream of a demonstration (its own, apart from the trial's draw).
const VISION_SALT: u64 = 0x4445_4D4F_5649_5301;
/// Most latents one demonstration keeps.
const MAX_LATENTS: usize = 64;

/// How a demonstration touches and how long it runs.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DemoConfig {
    /// Control period \[s].
    pub dt_s: f64,
    /// The probe touch: closing speed \[m/s], force bound \[N], opening added back to end it \[m]
    /// (the cup controller's `touch_speed_m_s`, `touch_force_n`, `probe_release_m`).
    pub touch_speed_m_s: f64,
    pub touch_force_n: f64,
    pub probe_release_m: f64,
    /// Longest approach, touch or release \[s].
    pub timeout_s: f64,
    /// How long the expert runs after the probe \[s].
    pub expert_s: f64,
}

impl Default for DemoConfig {
    fn default() -> Self {
        Self {
            dt_s: 1.0 / 30.0,
            touch_speed_m_s: 0.01,
            touch_force_n: 3.0,
            probe_release_m: 0.002,
            timeout_s: 8.0,
            expert_s: 4.0,
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

/// One demonstration: observations and labels.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Demo {
    pub seed: u64,
    pub trial: u32,
    pub split: Split,
    /// Observations. The camera's estimate at the first tick (names, values).
    pub visual_names: Vec<String>,
    pub visual_values: Vec<f64>,
    /// The gripper at the probe's first contact: opening \[m] and force \[N], and the contact
    /// stage's area \[mm^2] there.
    pub contact_opening_m: f64,
    pub contact_force_n: f64,
    pub contact_area_mm2: f32,
    pub latents: Vec<LatentRecord>,
    /// Labels (ground truth and the expert). The cup's diameter \[m], its stiffness as the
    /// controllers use it (grip force at the target deformation / the target deformation,
    /// \[N/m]), the expert's squeeze setpoint (opening) \[m], its grip force at the end \[N].
    pub diameter_m: f64,
    pub stiffness_n_per_m: f64,
    pub expert_opening_m: f64,
    pub expert_force_n: f64,
    /// The expert's outcome at the end: loss of diameter \[m] and overall success.
    pub deformation_m: f64,
    pub success: bool,
}

/// The stiffness the cup controllers read from a latent: the grip force that holds the cup's
/// wall at a loss of diameter `d_m`, divided by `d_m` (the wall is a cubic spring per side).
pub fn cup_stiffness(cup: &task::CupSpec, d_m: f64) -> f64 {
    let x_mm = d_m * 1e3 / 2.0;
    let (force_n, _) = cup.wall.spring(x_mm);
    force_n / d_m
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Phase {
    Approach,
    Touch,
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
        && (0.0..=600.0).contains(&c.expert_s)
        && c.timeout_s <= 600.0;
    if !ok {
        return Err(DemoError::Config(
            "probe_release_m must be >= 0, expert_s and timeout_s at most 600 s".into(),
        ));
    }
    let cfg = TaskConfig::cup(split);
    let world = TaskWorld::reset(&cfg, seed, trial);
    let spec = world.spec().clone();
    let Some(cup) = spec.cup().cloned() else {
        return Err(DemoError::World {
            seed,
            trial,
            msg: "the trial has no cup".into(),
        });
    };
    let world_err = |e: StepError| DemoError::World {
        seed,
        trial,
        msg: e.to_string(),
    };
    let mut world = WorldStepper::new(
        world,
        demo_sensor(sensor, seed, trial),
        trial_rng(seed ^ VISION_SALT, trial),
        TrialGripper::InProcess,
        (seed, trial),
        c.dt_s,
    )
    .map_err(world_err)?;
    let mut chain = Chain::new(stages);
    let visual = world.visual();

    let mut phase = Phase::Approach;
    let mut since = 0.0;
    let mut contact: Option<ContactState> = None;
    let mut touches = 0u32;
    let mut latents = Vec::new();
    let mut at_contact = (f64::NAN, f64::NAN, f32::NAN);
    let mut d0 = cfg.gripper.max_opening_m;
    let mut last_cmd: Option<TaskCommand> = None;
    let keep = |out: Vec<Msg>,
                t_s: f64,
                contact: &mut Option<ContactState>,
                touches: &mut u32,
                latents: &mut Vec<LatentRecord>| {
        for m in out {
            match m {
                Msg::ContactState(s) => {
                    if s.in_contact && !contact.as_ref().is_some_and(|c| c.in_contact) {
                        *touches += 1;
                    }
                    *contact = Some(s);
                }
                Msg::TactileLatent(l) if latents.len() < MAX_LATENTS => {
                    latents.push(LatentRecord {
                        t_s,
                        touch: *touches,
                        source: match l.source {
                            LatentSource::Real => "real",
                            _ => "predicted",
                        }
                        .into(),
                        shape: l.shape,
                        data: l.data,
                    })
                }
                _ => {}
            }
        }
    };
    let stage_err = |r: &unitac_core::chain::Rejection| DemoError::Stage {
        seed,
        trial,
        stage: r.stage.clone(),
        msg: r.error.clone(),
    };
    let timeout = |what| DemoError::Timeout {
        seed,
        trial,
        what,
        timeout_s: c.timeout_s,
    };
    loop {
        let t = world.time();
        // The camera's estimate first, as in a trial (the sampler's object-level condition).
        let seen = if t == 0.0 {
            visual.clone()
        } else {
            world.visual()
        };
        let out = chain.run(Msg::VisualObservation(visual_message(&seen)));
        if let Some(r) = out.errors.first() {
            return Err(stage_err(r));
        }
        keep(out.produced, t, &mut contact, &mut touches, &mut latents);
        for (frame, _truth) in world.frames() {
            let out = chain.run(Msg::Frame(frame));
            if let Some(r) = out.errors.first() {
                return Err(stage_err(r));
            }
            keep(out.produced, t, &mut contact, &mut touches, &mut latents);
        }
        let truth = world.world().truth();
        let expert = expert_command(&truth, &spec, &cfg);
        let in_contact = contact.as_ref().is_some_and(|s| s.in_contact);
        let elapsed = t - since;
        let next = match phase {
            Phase::Approach if truth.arm.arrived && elapsed > c.dt_s => Some(Phase::Touch),
            Phase::Touch if in_contact => {
                d0 = truth.gripper.opening_m;
                at_contact = (
                    d0,
                    truth.gripper.force_n,
                    contact.as_ref().map_or(f32::NAN, |s| s.area_mm2),
                );
                Some(Phase::Release)
            }
            Phase::Release if !in_contact => Some(Phase::Expert),
            Phase::Expert if elapsed >= c.expert_s => break,
            Phase::Approach | Phase::Touch | Phase::Release if elapsed > c.timeout_s => {
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
        let cmd = match phase {
            Phase::Approach | Phase::Expert => expert,
            Phase::Touch => TaskCommand {
                gripper: GripperSetpoint {
                    opening_m: 0.0,
                    speed_m_s: c.touch_speed_m_s,
                    force_n: c.touch_force_n,
                },
                arm: expert.arm.clone(),
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
        };
        world.step(Some(cmd.clone())).map_err(world_err)?;
        if phase == Phase::Expert {
            last_cmd = Some(cmd);
        }
    }
    let out = chain.finish();
    if let Some(r) = out.errors.first() {
        return Err(stage_err(r));
    }
    let t = world.time();
    keep(out.produced, t, &mut contact, &mut touches, &mut latents);
    let truth = world.world().truth();
    let task::TaskOutcome::Cup(outcome) = world.outcome() else {
        return Err(DemoError::World {
            seed,
            trial,
            msg: "not a cup outcome".into(),
        });
    };
    let d = cfg.cup_criteria.target_deformation_m;
    Ok(Demo {
        seed,
        trial,
        split,
        visual_names: visual.names,
        visual_values: visual.values,
        contact_opening_m: at_contact.0,
        contact_force_n: at_contact.1,
        contact_area_mm2: at_contact.2,
        latents,
        diameter_m: cup.diameter_m,
        stiffness_n_per_m: cup_stiffness(&cup, d),
        expert_opening_m: last_cmd.map_or(f64::NAN, |c| c.gripper.opening_m),
        expert_force_n: truth.gripper.force_n,
        deformation_m: outcome.deformation_m,
        success: outcome.overall,
    })
}
