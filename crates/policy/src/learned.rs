//! [`LearnedPolicy`]: a policy learned from demonstrations (python/unitac_tools/train_policy.py, on the
//! LeRobot datasets of `unitac-lab demos`), exported to ONNX, behind the same observation, watchdog
//! and safety layer as the scene controllers.
//!
//! Every tick the ONNX policy's output is the setpoint: the gripper's position, speed and force
//! limit (its real interface), the arm's x, y, z and lift, and one score per arm target (home,
//! then each of the scene's objects; the largest wins). The phase changes only on events every
//! mode observes: `act` until the gripper's first object-detect, `holding` after it, `done`
//! `run_s` after the first tick.
//!
//! The observation features are the demonstrations' ([`Memory`] keeps what a tick alone does
//! not hold):
//!
//! ```text
//! observation.state               the gripper status (the stage's slice)
//! observation.visual              the mean of the camera's estimates so far (the stage's
//!                                 slice averaged: the arm does not chase the camera's noise,
//!                                 as the scene controllers average it; names checked)
//! observation.latched             the opening at the first object-detect, known
//! observation.arm                 time since the commanded arm target last changed (at most
//!                                 10 s), and whether that is `approach_s` or more (the arm has
//!                                 had its travel time: the policy's own record, no arm sensor)
//! observation.contact             the latest contact state: in contact, area, strength
//! observation.tactile_latent_real per object: the pooled live latent of its touch, known
//!                                 (the first latent after touch k goes to object k)
//! observation.tactile_latent_pred per object: the latest predicted latent for it, known
//! observation.comparison          the latest property comparison
//! ```
//!
//! No object name, index or hash is among them: the per-object slots are in the scene's object
//! order, the order the task touches them.

use crate::error::PolicyLoadError;
use crate::observation::{Observation, input};
use crate::onnx::manifest::InputSpec;
use crate::onnx::{NamedInputs, OnnxPolicy, RunError, RuntimeConfig};
use crate::params::PolicyParams;
use crate::policy::{Action, ArmAction, GripperAction, Policy, PolicyError};
use std::path::Path;
use unitac_core::Stamp;
use unitac_core::msg::{GripperMode, LatentSource, TactileLatent};

pub use crate::schema::{
    ARM, COMPARISON, CONTACT, LATCHED, LATENT_PRED, LATENT_REAL, MAX_SINCE_TARGET_S, STATE, VISUAL,
};
use crate::schema::{
    ARM_LEN, ARM_TARGET_PREFIX, COMMANDS, COMMANDS_BEYOND as BEYOND, COMPARISON_LEN, CONTACT_LEN,
    LATCHED_LEN,
};
/// How far a policy's control rate may be from the scene's, relative.
pub const RATE_TOLERANCE: f64 = 1e-6;

/// Token mean, then token mean of squares, of `tokens` (\[n, w] row-major): the pooled latent
/// the touch projector predicts and the learned policies read.
pub fn pooled(tokens: &[f32], w: usize) -> Vec<f32> {
    let w = w.max(1);
    let n = tokens.len() / w;
    let mut out = vec![0.0f32; 2 * w];
    for row in tokens.chunks_exact(w) {
        for (j, &v) in row.iter().enumerate() {
            out[j] += v / n as f32;
            out[w + j] += v * v / n as f32;
        }
    }
    out
}

/// A latent as the policy slots hold it: the encoder's tokens pooled, a predicted (pooled)
/// latent as it is.
pub fn slot_values(l: &TactileLatent) -> Vec<f32> {
    match l.source {
        LatentSource::Real => pooled(&l.data, l.shape.last().copied().unwrap_or(1) as usize),
        LatentSource::Predicted => l.data.clone(),
    }
}

/// Per object: its values or zeros, then known.
pub fn slots(v: &[Option<Vec<f32>>], width: usize) -> Vec<f32> {
    let mut out = Vec::with_capacity(v.len() * (width + 1));
    for s in v {
        match s {
            Some(p) => out.extend(p.iter().copied().chain([1.0])),
            None => out.extend(std::iter::repeat_n(0.0, width + 1)),
        }
    }
    out
}

/// What the learned policies observe across ticks: the demonstrations record the same
/// (crates/trials demos.rs keeps one per demonstration).
#[derive(Debug, Clone, PartialEq)]
pub struct Memory {
    /// The opening at the first object-detect \[m].
    pub latched: Option<f32>,
    /// Contacts begun so far, and whether the latest contact state was in contact.
    pub touches: u32,
    in_contact: bool,
    /// The latest contact state's slice.
    pub contact: Option<Vec<f32>>,
    /// Per object: the pooled live latent of its touch, the latest predicted latent.
    pub real: Vec<Option<Vec<f32>>>,
    pub pred: Vec<Option<Vec<f32>>>,
    /// The latest comparison's slice.
    pub comparison: Option<Vec<f32>>,
    /// Sum of the camera's estimates so far, and how many.
    visual_sum: Vec<f64>,
    visual_n: u32,
    /// The commanded arm target and when it was first commanded \[s] ("home" at 0 before any).
    target: (String, f64),
    /// The arm's travel time to a target \[s].
    approach_s: f64,
    /// Values of a pooled latent.
    width: usize,
    objects: Vec<String>,
}

impl Memory {
    /// `approach_s`: the arm's travel time to a target (the scene's).
    pub fn new(objects: &[String], width: usize, approach_s: f64) -> Self {
        Self {
            latched: None,
            touches: 0,
            in_contact: false,
            contact: None,
            real: vec![None; objects.len()],
            pred: vec![None; objects.len()],
            comparison: None,
            visual_sum: Vec::new(),
            visual_n: 0,
            target: ("home".into(), 0.0),
            approach_s,
            width,
            objects: objects.to_vec(),
        }
    }

    /// The camera's estimate this tick: the mean of every one so far, this one included (an
    /// estimate of another length starts the mean again).
    pub fn visual(&mut self, v: &[f32]) -> Vec<f32> {
        if self.visual_sum.len() != v.len() {
            self.visual_sum = vec![0.0; v.len()];
            self.visual_n = 0;
        }
        for (s, x) in self.visual_sum.iter_mut().zip(v) {
            *s += f64::from(*x);
        }
        self.visual_n = self.visual_n.saturating_add(1);
        let n = f64::from(self.visual_n);
        self.visual_sum.iter().map(|s| (s / n) as f32).collect()
    }

    /// The arm was commanded to `target` at `t_s` (world or stamp time \[s]).
    pub fn commanded(&mut self, target: &str, t_s: f64) {
        if self.target.0 != target {
            self.target = (target.to_string(), t_s);
        }
    }

    /// `observation.arm` at `t_s`: time since the target last changed (at most
    /// [`MAX_SINCE_TARGET_S`]), and whether the arm has had its travel time (1 or 0).
    pub fn arm(&self, t_s: f64) -> Vec<f32> {
        let since = (t_s - self.target.1).clamp(0.0, MAX_SINCE_TARGET_S);
        vec![
            since as f32,
            if since >= self.approach_s { 1.0 } else { 0.0 },
        ]
    }

    /// The gripper reported object-detect at `opening_m` (the first one is latched).
    pub fn gripper(&mut self, object_detected: bool, opening_m: f64) {
        if self.latched.is_none() && object_detected {
            self.latched = Some(opening_m as f32);
        }
    }

    /// A contact state's slice (in contact, area, strength).
    pub fn contact(&mut self, values: Vec<f32>) {
        let now = values.first().is_some_and(|&c| c > 0.5);
        if now && !self.in_contact {
            self.touches += 1;
        }
        self.in_contact = now;
        self.contact = Some(values);
    }

    /// A latent: a live one fills the slot of the touch it came after (once), a predicted one
    /// its object's slot. Err: it does not pool to the policy's width.
    pub fn latent(&mut self, l: &TactileLatent) -> Result<(), String> {
        let p = slot_values(l);
        if p.len() != self.width {
            return Err(format!(
                "a latent of shape {:?} pools to {} values, not {}",
                l.shape,
                p.len(),
                self.width
            ));
        }
        match l.source {
            LatentSource::Real => {
                let k = (self.touches as usize).checked_sub(1);
                if let Some(s @ None) = k.and_then(|k| self.real.get_mut(k)) {
                    *s = Some(p);
                }
            }
            LatentSource::Predicted => {
                let k = self.objects.iter().position(|o| *o == l.object);
                if let Some(s) = k.and_then(|k| self.pred.get_mut(k)) {
                    *s = Some(p);
                }
            }
        }
        Ok(())
    }

    /// A comparison's slice.
    pub fn comparison(&mut self, values: Vec<f32>) {
        self.comparison = Some(values);
    }

    /// The memory's features by name (latched, contact, the latent slots, comparison).
    pub fn features(&self) -> [(&'static str, Vec<f32>); 5] {
        [
            (
                LATCHED,
                self.latched.map_or(vec![0.0, 0.0], |o| vec![o, 1.0]),
            ),
            (
                CONTACT,
                self.contact.clone().unwrap_or(vec![0.0; CONTACT_LEN]),
            ),
            (LATENT_REAL, slots(&self.real, self.width)),
            (LATENT_PRED, slots(&self.pred, self.width)),
            (
                COMPARISON,
                self.comparison.clone().unwrap_or(vec![0.0; COMPARISON_LEN]),
            ),
        ]
    }
}

/// An ONNX policy trained on demonstrations, as a [`Policy`].
#[derive(Debug)]
pub struct LearnedPolicy {
    onnx: OnnxPolicy,
    /// The stage inputs its features come from.
    reads: Vec<&'static str>,
    /// Of those, the ones the scene's mode reads for its task (schema `modes`): the inputs whose
    /// producers the transport watches. A feature the mode does not read for the task (a cup
    /// scene's comparison slot) stays zero and has no producer to wait for.
    awaited: Vec<&'static str>,
    memory: Memory,
    /// "home", then the scene's objects; the score action of each.
    targets: Vec<(String, usize)>,
    /// Index of each command action in the model's output.
    commands: [usize; 7],
    /// Latent stamps already taken (a stage's latent stays the latest for many ticks).
    seen_latents: Vec<Stamp>,
    seen_comparison: Option<Stamp>,
    seen_contact: Option<Stamp>,
    start: Option<Stamp>,
    run_s: f64,
    phase: &'static str,
    clamped: Vec<&'static str>,
}

fn load_error(dir: &Path, problems: Vec<String>) -> PolicyLoadError {
    PolicyLoadError::LearnedPolicy {
        dir: dir.to_path_buf(),
        problems,
    }
}

/// The model's inputs against the scene: each a feature a learned policy has, of the width the
/// scene's layout gives (the camera's names in the scene's order; per-object latent slots of its
/// objects). Problems go to `problems`; the per-object latent width comes back (0: none).
fn check_inputs(inputs: &[InputSpec], params: &PolicyParams, problems: &mut Vec<String>) -> usize {
    let n_obj = params.limits.objects.len();
    let mut width = 0;
    for i in inputs {
        let numel: usize = i
            .shape
            .iter()
            .skip(1)
            .map(|d| match d {
                unitac_infer::bundle::Dim::Fixed(n) => usize::try_from(*n).unwrap_or(0),
                unitac_infer::bundle::Dim::Symbolic(_) => 0,
            })
            .product();
        match i.name.as_str() {
            STATE => {
                let w = input("gripper").map_or(0, |s| (s.width)(&params.layout()));
                if numel != w {
                    problems.push(format!("{STATE} has {numel} values, the gripper's {w}"));
                }
            }
            VISUAL => match &i.names {
                Some(n) if *n == params.visual_names => {}
                Some(n) => problems.push(format!(
                    "{VISUAL} reads {n:?}, the scene's visual_names are {:?}",
                    params.visual_names
                )),
                None => problems.push(format!("{VISUAL} states no names")),
            },
            LATCHED if numel != LATCHED_LEN => {
                problems.push(format!("{LATCHED}: {numel} values, not {LATCHED_LEN}"));
            }
            ARM if numel != ARM_LEN => {
                problems.push(format!("{ARM}: {numel} values, not {ARM_LEN}"));
            }
            CONTACT if numel != CONTACT_LEN => {
                problems.push(format!("{CONTACT}: {numel} values, not {CONTACT_LEN}"));
            }
            COMPARISON if numel != COMPARISON_LEN => {
                problems.push(format!(
                    "{COMPARISON}: {numel} values, not {COMPARISON_LEN}"
                ));
            }
            LATENT_REAL | LATENT_PRED => {
                if n_obj == 0 || numel % n_obj != 0 || numel / n_obj < 2 {
                    problems.push(format!(
                        "{}: {numel} values are not {n_obj} objects x (latent + known)",
                        i.name
                    ));
                } else {
                    width = numel / n_obj - 1;
                }
            }
            LATCHED | ARM | CONTACT | COMPARISON => {}
            other => problems.push(format!("input '{other}' is not one a learned policy has")),
        }
    }
    width
}

impl LearnedPolicy {
    /// The bundle in `dir` for the scene's `params`: every problem in one error (the model's
    /// own checks, then: the command actions, each ranging inside the scene's safety bounds, and
    /// one score per target, the camera's names in the scene's order, per-object latent slots of
    /// the scene's objects).
    pub fn load(dir: &Path, params: &PolicyParams) -> Result<Self, PolicyLoadError> {
        let mut onnx = OnnxPolicy::load(dir, &RuntimeConfig::default())
            .map_err(|e| load_error(dir, vec![e.to_string()]))?;
        onnx.set_budget(Some(params.inference_budget()));
        let mut problems = Vec::new();
        // The model's chunk rows are control ticks at its rate, and its features (the arm's
        // time, the memory) were recorded at the demonstrations' rate: the scene must tick at
        // that rate, or each row would be held for several ticks (or skipped).
        let rate = onnx.manifest().control_rate_hz;
        if (rate - params.control_rate_hz).abs() > RATE_TOLERANCE * params.control_rate_hz {
            problems.push(format!(
                "the policy runs at control_rate_hz {rate}, the scene at {}",
                params.control_rate_hz
            ));
        }
        let names = onnx.action_names();
        let at = |n: &str| names.iter().position(|a| a == n);
        let mut commands = [0usize; 7];
        let actions = &onnx.manifest().output.actions;
        for ((c, name), (_, lo, hi)) in commands
            .iter_mut()
            .zip(COMMANDS)
            .zip(params.bounds().ranges())
        {
            match at(name) {
                Some(i) => {
                    *c = i;
                    // The model's range inside the safety layer's, or it may propose what the
                    // layer must clamp (a rounding's slack allowed).
                    let slack = 1e-6 * (hi - lo).abs().max(1.0);
                    if let Some(a) = actions.get(i)
                        && (a.min < lo - slack || a.max > hi + slack)
                    {
                        problems.push(format!(
                            "action '{name}' ranges [{}, {}], beyond the scene's safety bounds [{lo}, {hi}]",
                            a.min, a.max
                        ));
                    }
                }
                None => problems.push(format!("no action '{name}'")),
            }
        }
        let mut targets = Vec::new();
        for t in std::iter::once("home").chain(params.limits.objects.iter().map(String::as_str)) {
            match at(&format!("{ARM_TARGET_PREFIX}{t}")) {
                Some(i) => targets.push((t.to_string(), i)),
                None => problems.push(format!("no score action '{ARM_TARGET_PREFIX}{t}'")),
            }
        }
        let width = check_inputs(&onnx.manifest().inputs, params, &mut problems);
        if !problems.is_empty() {
            return Err(load_error(dir, problems));
        }
        let reads = Self::inputs_of(&onnx);
        let mode_reads = params
            .check()
            .map(|task| params.mode.inputs(task.is_pick()))
            .unwrap_or_default();
        let awaited = reads
            .iter()
            .copied()
            .filter(|r| mode_reads.contains(r))
            .collect();
        Ok(Self {
            reads,
            awaited,
            onnx,
            memory: Memory::new(&params.limits.objects, width, params.approach_s),
            targets,
            commands,
            seen_latents: Vec::new(),
            seen_comparison: None,
            seen_contact: None,
            start: None,
            run_s: params.run_s,
            phase: "act",
            clamped: Vec::new(),
        })
    }

    /// The model's name (its manifest's `policy`).
    pub fn id(&self) -> &str {
        self.onnx.id()
    }

    /// The stage inputs the model's features come from.
    pub fn reads(&self) -> Vec<&'static str> {
        self.reads.clone()
    }

    /// [`Self::reads`] of `onnx`, once at load.
    fn inputs_of(onnx: &OnnxPolicy) -> Vec<&'static str> {
        let mut r = Vec::new();
        for i in onnx.input_names() {
            let n = match i {
                CONTACT => "contact",
                LATENT_REAL => "latent_real",
                LATENT_PRED => "latent_pred",
                COMPARISON => "comparison",
                VISUAL => "visual",
                _ => "gripper",
            };
            if !r.contains(&n) {
                r.push(n);
            }
        }
        r
    }

    /// Take what this tick's observation adds to the memory.
    fn remember(&mut self, obs: &Observation) -> Result<(), PolicyError> {
        if let Some(g) = obs.gripper() {
            self.memory.gripper(g.object_detected, g.opening_m);
        }
        if let Some(c) = obs.contact() {
            if self.seen_contact != Some(c.header.stamp) {
                self.seen_contact = Some(c.header.stamp);
                if let Some(v) = obs.slice(CONTACT) {
                    self.memory.contact(v.to_vec());
                }
            }
        }
        if let Some(l) = obs.latent() {
            if !self.seen_latents.contains(&l.header.stamp) {
                if self.seen_latents.len() >= 64 {
                    self.seen_latents.remove(0);
                }
                self.seen_latents.push(l.header.stamp);
                self.memory.latent(l).map_err(PolicyError::Failed)?;
            }
        }
        if let Some(c) = obs.comparison() {
            if self.seen_comparison != Some(c.header.stamp) {
                self.seen_comparison = Some(c.header.stamp);
                if let Some(v) = obs.slice(COMPARISON) {
                    self.memory.comparison(v.to_vec());
                }
            }
        }
        Ok(())
    }
}

impl Policy for LearnedPolicy {
    fn phase(&self) -> &str {
        self.phase
    }

    /// The gripper and the camera; the contact state too once one came (the demonstrations
    /// start before the contact stage's first state: its slice is zeros until then).
    fn required(&self) -> Vec<&'static str> {
        let mut r = vec!["gripper", "visual"];
        if self.memory.contact.is_some() && self.reads.contains(&"contact") {
            r.push("contact");
        }
        r
    }

    fn awaited(&self) -> Vec<&'static str> {
        self.awaited.clone()
    }

    fn act(&mut self, obs: &Observation) -> Result<Vec<Action>, PolicyError> {
        let start = *self.start.get_or_insert(obs.stamp);
        self.remember(obs)?;
        if self.phase == "act" && self.memory.latched.is_some() {
            self.phase = "holding";
        }
        let t_s = obs.stamp.secs_since(start);
        if t_s >= self.run_s {
            self.phase = "done";
        }
        let memory = self.memory.features();
        let arm = self.memory.arm(t_s);
        let state = obs.slice(STATE).unwrap_or(&[]);
        let visual = self.memory.visual(obs.slice(VISUAL).unwrap_or(&[]));
        let mut named = NamedInputs::new()
            .with(STATE, state)
            .with(VISUAL, &visual)
            .with(ARM, &arm);
        for (name, values) in &memory {
            named.insert(name, values);
        }
        let chunk = self.onnx.act(&named, obs.stamp).map_err(|e| match e {
            RunError::OverBudget { .. } => {
                PolicyError::OverBudget(format!("learned policy {}: {e}", self.onnx.id()))
            }
            e => PolicyError::Failed(format!("learned policy: {e}")),
        })?;
        for j in &chunk.beyond {
            if let Some(k) = self.commands.iter().position(|c| c == j) {
                self.clamped.push(BEYOND[k]);
            }
        }
        let row = chunk.row(0).unwrap_or(&[]);
        let v = |k: usize| f64::from(row.get(self.commands[k]).copied().unwrap_or(0.0));
        let target = self
            .targets
            .iter()
            .map(|(name, i)| (name, row.get(*i).copied().unwrap_or(f32::NEG_INFINITY)))
            .fold(None::<(&String, f32)>, |best, (n, s)| match best {
                Some((_, b)) if b >= s => best,
                _ => Some((n, s)),
            })
            .map_or_else(|| "home".to_string(), |(n, _)| n.clone());
        self.memory.commanded(&target, t_s);
        Ok(vec![Action {
            gripper: GripperAction {
                mode: GripperMode::Position,
                position_m: v(0),
                speed_m_s: v(1),
                force_n: v(2),
            },
            arm: ArmAction {
                target,
                x_m: v(3),
                y_m: v(4),
                z_m: v(5),
                lift_m: v(6),
            },
            note: format!("learned {}", self.onnx.id()),
        }])
    }

    fn take_clamped(&mut self) -> Vec<&'static str> {
        std::mem::take(&mut self.clamped)
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use unitac_core::msg::samples;

    fn objects() -> Vec<String> {
        vec!["a".into(), "b".into()]
    }

    fn real(tokens: Vec<f32>) -> TactileLatent {
        TactileLatent {
            source: LatentSource::Real,
            shape: vec![2, 2],
            data: tokens,
            ..samples::tactile_latent()
        }
    }

    #[test]
    fn commands_are_the_safety_layers_values_in_order() {
        let ranged: Vec<_> = PolicyParams::default()
            .bounds()
            .ranges()
            .iter()
            .map(|(n, ..)| *n)
            .collect();
        assert_eq!(ranged, COMMANDS);
    }

    #[test]
    fn pooling_is_token_mean_then_mean_of_squares() {
        assert_eq!(pooled(&[1.0, 2.0, 3.0, 4.0], 2), vec![2.0, 3.0, 5.0, 10.0]);
    }

    #[test]
    fn the_first_object_detect_is_latched() {
        let mut m = Memory::new(&objects(), 4, 1.5);
        m.gripper(false, 0.08);
        assert_eq!(m.features()[0].1, vec![0.0, 0.0]);
        m.gripper(true, 0.07);
        m.gripper(true, 0.05);
        assert_eq!(m.features()[0].1, vec![0.07, 1.0]);
    }

    #[test]
    fn a_live_latent_fills_the_slot_of_the_touch_it_came_after_once() {
        let mut m = Memory::new(&objects(), 4, 1.5);
        // Before any touch: no slot.
        m.latent(&real(vec![1.0; 4])).unwrap();
        assert_eq!(m.features()[2].1, vec![0.0; 10]);
        m.contact(vec![1.0, 5.0, 0.5]);
        m.contact(vec![1.0, 6.0, 0.5]);
        m.contact(vec![0.0, 0.0, 0.0]);
        m.latent(&real(vec![1.0, 2.0, 3.0, 4.0])).unwrap();
        // A second latent of the same touch changes nothing.
        m.latent(&real(vec![9.0; 4])).unwrap();
        let slots = &m.features()[2].1;
        assert_eq!(slots[..5], [2.0, 3.0, 5.0, 10.0, 1.0]);
        assert_eq!(slots[5..], [0.0; 5]);
        // The second touch's goes to the second object.
        m.contact(vec![1.0, 5.0, 0.5]);
        m.latent(&real(vec![1.0; 4])).unwrap();
        assert_eq!(m.features()[2].1[5..], [1.0, 1.0, 1.0, 1.0, 1.0]);
        assert_eq!(m.features()[1].1, vec![1.0, 5.0, 0.5]);
    }

    #[test]
    fn a_predicted_latent_goes_to_its_object_and_a_wrong_width_is_an_error() {
        let mut m = Memory::new(&objects(), 4, 1.5);
        let p = TactileLatent {
            object: "b".into(),
            shape: vec![2, 2],
            data: vec![1.0, 2.0, 3.0, 4.0],
            ..samples::tactile_latent()
        };
        m.latent(&p).unwrap();
        assert_eq!(
            m.features()[3].1,
            vec![0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 2.0, 3.0, 4.0, 1.0]
        );
        let e = m.latent(&samples::tactile_latent()).unwrap_err();
        assert!(e.contains("pools to 6 values, not 4"), "{e}");
    }
}

#[cfg(test)]
mod arm_tests {
    use super::*;

    #[test]
    fn the_visual_feature_is_the_mean_so_far() {
        let mut m = Memory::new(&["cup".to_string()], 4, 1.5);
        assert_eq!(m.visual(&[1.0, 2.0]), vec![1.0, 2.0]);
        assert_eq!(m.visual(&[3.0, 4.0]), vec![2.0, 3.0]);
        assert_eq!(m.visual(&[5.0]), vec![5.0]);
    }

    #[test]
    fn the_arm_feature_counts_from_the_last_change_of_target() {
        let mut m = Memory::new(&["cup".to_string()], 4, 1.5);
        assert_eq!(m.arm(1.0), vec![1.0, 0.0]);
        m.commanded("home", 1.0);
        assert_eq!(m.arm(2.0), vec![2.0, 1.0]);
        m.commanded("cup", 2.0);
        m.commanded("cup", 2.5);
        assert_eq!(m.arm(3.0), vec![1.0, 0.0]);
        assert_eq!(m.arm(3.5), vec![1.5, 1.0]);
        assert_eq!(m.arm(100.0), vec![MAX_SINCE_TARGET_S as f32, 1.0]);
    }
}
