//! The policy stage (`kind: policy`): keeps the latest of each input, and on each control tick
//! (the arrival of a GripperStatus) assembles the observation, runs the watchdog, asks the
//! policy, and sends its action through the safety layer: one GripperCommand, one ArmCommand and
//! one PolicyStatus per tick.

use crate::controller::{CupController, FabricController};
use crate::error::{InputError, PolicyLoadError};
use crate::learned::LearnedPolicy;
use crate::observation::Assembler;
use crate::params::{PolicyKind, PolicyParams};
use crate::policy::{Action, Policy};
use crate::readout::Readout;
use crate::reflex::{Reflex, ReflexCounters, Touch};
use crate::safety::{Refusal, SafetyLayer};
use crate::task::Task;
use crate::ticks::TickCounts;
use std::collections::VecDeque;
use std::path::Path;
use unitac_core::msg::{
    ArmCommand, ContactState, GripperCommand, GripperStatus, Header, Msg, PolicyStatus, SlipState,
};
use unitac_core::{Clock, Stage, StageError, Stamp};

/// The params' checks plus the scene's stage list against the mode: `kinds` are the stage kinds
/// before the policy stage, `needs` the registry's (kind -> the kind it consumes).
pub fn check_scene(
    p: &PolicyParams,
    kinds: &[&str],
    needs: &[(&str, &str)],
) -> Result<(), PolicyLoadError> {
    let task = p.check()?;
    Ok(crate::mode::check_scene_stages(
        p.mode,
        task.is_pick(),
        kinds,
        needs,
    )?)
}

pub struct PolicyStage {
    scene: String,
    params: PolicyParams,
    assembler: Assembler,
    policy: Box<dyn Policy>,
    safety: SafetyLayer,
    queue: VecDeque<Action>,
    /// When the next control tick is due \[ns].
    next_tick: Option<i64>,
    /// The last trusted opening (None: none yet) and the last GripperStatus's frame id, for the
    /// safe action.
    last_gripper: Option<(Option<f64>, String)>,
    /// Inputs whose producer a transport saw disappear, with why.
    lost: std::collections::BTreeMap<&'static str, String>,
    /// The stage's present \[ns]: the stamp of the latest control tick (a GripperStatus's or the
    /// watchdog's). Only a tick moves it; a status stamped far from it is not a tick.
    present: Option<i64>,
    /// GripperStatus stamps in a row that were too far from the present, each about a control
    /// period after the one before: the last one's stamp and how many.
    off_run: Option<(i64, u32)>,
    /// The tactile reflex, and the latest slip and contact states it reads (whatever the mode's
    /// observation holds).
    reflex: Reflex,
    slip: Option<SlipState>,
    contact: Option<ContactState>,
    /// What each tick sent, by kind (src/ticks.rs).
    counts: TickCounts,
}

/// GripperStatus messages in a row, a control period apart, that move the present to their time
/// line when it jumped (a gripper back after a long silence with no watchdog running, a
/// restarted sim). One stamp from a bad clock never does.
const RESYNC_STATUSES: u32 = 3;

impl std::fmt::Debug for PolicyStage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PolicyStage")
            .field("scene", &self.scene)
            .field("mode", &self.params.mode)
            .field("phase", &self.policy.phase())
            .finish_non_exhaustive()
    }
}

impl PolicyStage {
    /// The scene controller the task names, with the params' linear stiffness readout.
    pub fn new(scene: &str, params: PolicyParams) -> Result<Self, PolicyLoadError> {
        Self::load(scene, params, None)
    }

    /// The policy the params name with the stage's model bundle `model` (a directory, checked
    /// here: every problem in one error): a learned policy is that bundle; the scene controller
    /// the task names reads its stiffness from it when the scene names one.
    pub fn load(
        scene: &str,
        params: PolicyParams,
        model: Option<&Path>,
    ) -> Result<Self, PolicyLoadError> {
        let task = params.check()?;
        if params.policy == PolicyKind::Learned {
            let dir = model.ok_or(PolicyLoadError::LearnedPolicyMissing)?;
            let policy = LearnedPolicy::load(dir, &params)?;
            let reads = policy.reads();
            return Self::build(scene, params, Box::new(policy), &reads);
        }
        let readout = match model {
            Some(dir) => Readout::load(dir, params.latent_len)?,
            None => Readout::Linear,
        };
        let policy: Box<dyn Policy> = match task {
            Task::Pick { property, more, .. } => {
                Box::new(FabricController::new(&params, property, more)?)
            }
            Task::Squeeze { by_m } => {
                Box::new(CupController::new(&params, by_m).with_readout(readout))
            }
        };
        Self::with_policy(scene, params, policy)
    }

    /// Any policy (e.g. an ONNX policy) behind the same observation, watchdog and safety layer.
    pub fn with_policy(
        scene: &str,
        params: PolicyParams,
        policy: Box<dyn Policy>,
    ) -> Result<Self, PolicyLoadError> {
        Self::build(scene, params, policy, &[])
    }

    /// [`Self::with_policy`], the observation keeping `extra` inputs besides the mode's (those
    /// a learned policy's features come from).
    fn build(
        scene: &str,
        mut params: PolicyParams,
        policy: Box<dyn Policy>,
        extra: &[&'static str],
    ) -> Result<Self, PolicyLoadError> {
        let task = params.check()?;
        // The named gripper's stroke, resolved once.
        params.stroke_m = params.stroke();
        let mut inputs = params.mode.inputs(task.is_pick());
        for e in extra {
            if !inputs.contains(e) {
                inputs.push(e);
            }
        }
        let assembler = Assembler::new(&inputs, |n| params.budget(n), params.layout())?;
        Ok(Self {
            scene: scene.to_string(),
            safety: SafetyLayer::new(params.bounds(), params.safe_action, params.hold_force_n),
            assembler,
            policy,
            queue: VecDeque::new(),
            next_tick: None,
            last_gripper: None,
            lost: std::collections::BTreeMap::new(),
            present: None,
            off_run: None,
            reflex: Reflex::new(params.reflex()),
            slip: None,
            contact: None,
            counts: TickCounts::default(),
            params,
        })
    }

    /// The inputs of the scene's mode (`gripper`, `contact`, `latent_real`, ...).
    pub fn inputs(&self) -> Vec<&'static str> {
        self.assembler.names()
    }

    /// The inputs whose producer must be alive now (the current phase's, see
    /// [`Policy::awaited`]): a transport watches these producers.
    pub fn awaited_inputs(&self) -> Vec<&'static str> {
        self.policy.awaited()
    }

    /// Every tick since the stage was built by what it sent: the policy's action, or the safe
    /// action and why (src/ticks.rs; the same counts a transport makes from PolicyStatus).
    pub fn tick_counts(&self) -> &TickCounts {
        &self.counts
    }

    /// What the tactile reflex did since the stage was built (src/reflex.rs).
    pub fn reflex_counters(&self) -> ReflexCounters {
        self.reflex.counters()
    }

    /// The tactile facts at tick `now`: the slip and contact states if fresh (the contact budget,
    /// not stamped ahead) and valid.
    fn touch<'a>(
        slip: &'a Option<SlipState>,
        contact: &'a Option<ContactState>,
        budget: f64,
        now: Stamp,
        g: &GripperStatus,
        opening_m: Option<f64>,
    ) -> Touch<'a> {
        let fresh = |t: Stamp| {
            let age = now.secs_since(t);
            age <= budget && age >= -budget.min(crate::observation::MAX_AHEAD_S)
        };
        Touch {
            slip: slip.as_ref().filter(|s| s.valid && fresh(s.header.stamp)),
            contact: contact
                .as_ref()
                .filter(|c| fresh(c.header.stamp) && c.area_m2.is_finite()),
            object_detected: g.object_detected,
            opening_m,
            force_n: Some(g.force_n).filter(|f| f.is_finite()),
        }
    }

    /// The control period \[ns].
    pub fn period_ns(&self) -> i64 {
        (1e9 / self.params.control_rate_hz).round() as i64
    }

    /// A transport tells the stage that the producer of input `name` is gone (`Some(why)`, e.g.
    /// no publisher on its topic any more) or back (`None`). While it is gone, every tick in a
    /// phase that awaits the input sends the safe action with `<name>: <why>` as the reason.
    /// Err: `name` is not one of this mode's inputs.
    pub fn set_input_lost(&mut self, name: &str, why: Option<String>) -> Result<(), InputError> {
        let Some(n) = self.inputs().into_iter().find(|n| *n == name) else {
            return Err(InputError::NotOfMode {
                name: name.chars().take(64).collect(),
                inputs: self.inputs(),
            });
        };
        match why {
            Some(w) => self.lost.insert(n, w),
            None => self.lost.remove(n),
        };
        Ok(())
    }

    /// The control tick a transport's timer gives when no GripperStatus came: at `now` (the
    /// transport's clock, the same time line as the statuses' stamps), once the tick due last
    /// is a whole control period overdue (no status for a control period where one was due),
    /// the safe action with the reason (`gripper: no status for ...`), stamped `now`; then the
    /// schedule goes on from it. Nothing before the first
    /// GripperStatus (nothing is known yet to hold) or while a tick is not overdue.
    pub fn watchdog_tick(&mut self, now: Stamp) -> Vec<Msg> {
        let (Some(due), Some((opening, frame_id))) = (self.next_tick, self.last_gripper.clone())
        else {
            return Vec::new();
        };
        let period = self.period_ns();
        if now.0 < due.saturating_add(period) {
            return Vec::new();
        }
        // This tick stands for the one missed; the next is due now, so while nothing comes the
        // watchdog ticks once per period.
        self.next_tick = Some(now.0);
        self.present = Some(self.present.map_or(now.0, |p| p.max(now.0)));
        let last = due.saturating_sub(period);
        let why = Refusal::GripperSilent {
            silent_s: now.0.saturating_sub(last) as f64 * 1e-9,
            period_s: period as f64 * 1e-9,
        };
        self.queue.clear();
        let d = self.safety.decide(Err(why), opening);
        self.messages(now, &frame_id, d)
    }

    /// The next tick after one at `now` that was due at `due`: on the fixed schedule unless it
    /// fell a whole period behind.
    fn schedule_after(&mut self, now: i64, due: i64) {
        let period = self.period_ns();
        self.next_tick = Some(if now.saturating_sub(due) < period {
            due.saturating_add(period)
        } else {
            now.saturating_add(period)
        });
    }

    /// How far a GripperStatus may be stamped from the present and still be a tick \[ns]: the
    /// gripper's freshness budget, at least two control periods.
    fn off_limit_ns(&self) -> i64 {
        let budget_ns = self.params.budget("gripper").unwrap_or(0.0) * 1e9;
        (budget_ns.round() as i64).max(2 * self.period_ns())
    }

    /// Whether a GripperStatus stamped `t` is on the stage's time line: within the limit of the
    /// present, or the last of [`RESYNC_STATUSES`] in a row that agree on a new one. Err: how
    /// far it is ahead (positive) or behind (negative) of the present \[ns].
    fn on_time_line(&mut self, t: i64) -> Result<(), i64> {
        let Some(present) = self.present else {
            return Ok(());
        };
        let off = t.saturating_sub(present);
        let limit = self.off_limit_ns();
        if off <= limit && off >= -limit {
            self.off_run = None;
            return Ok(());
        }
        let period = self.period_ns();
        let count = match self.off_run {
            Some((last, n)) => {
                let step = t.saturating_sub(last);
                if step >= period / 2 && step <= period + period / 2 {
                    n + 1
                } else {
                    1
                }
            }
            None => 1,
        };
        if count >= RESYNC_STATUSES {
            // A new time line: the schedule and the present start again from this status.
            self.off_run = None;
            self.next_tick = None;
            self.present = None;
            return Ok(());
        }
        self.off_run = Some((t, count));
        Err(off)
    }

    /// One control tick at `now`, triggered by `g`.
    fn tick(&mut self, now: Stamp, g: &GripperStatus) -> Vec<Msg> {
        let obs = self.assembler.assemble(now, &self.params.task);
        // Watchdog: every input the policy needs now must be fresh and valid, and the producer
        // of every input it awaits alive.
        let mut problems: Vec<String> = self
            .policy
            .required()
            .iter()
            .filter_map(|n| obs.reading(n).and_then(|r| r.problem()))
            .collect();
        for n in self.policy.awaited() {
            if let Some(why) = self.lost.get(n) {
                problems.push(format!("{n}: {why}"));
            }
        }
        let proposed = if problems.is_empty() {
            let planned = if self.queue.is_empty() {
                match self.policy.act(&obs) {
                    Ok(chunk) => {
                        self.queue.extend(chunk);
                        Ok(())
                    }
                    Err(e) => Err(Refusal::Policy(e)),
                }
            } else {
                Ok(())
            };
            planned.and_then(|()| self.queue.pop_front().ok_or(Refusal::NoAction))
        } else {
            // A chunk planned on inputs that went bad is dropped.
            self.queue.clear();
            Err(Refusal::Inputs(problems))
        };
        let opening = self.last_gripper.as_ref().and_then(|(o, _)| *o);
        // The tactile reflex, under whatever policy proposed the action.
        let last = self.safety.last_force_and_lift();
        let touch = Self::touch(
            &self.slip,
            &self.contact,
            self.params.budget_contact_s,
            now,
            g,
            opening,
        );
        let bounds = self.safety.bounds().clone();
        let proposed = proposed.map(|mut a| {
            if let Some(r) = self.reflex.apply(&mut a, &touch, last, &bounds) {
                a.note = if a.note.is_empty() {
                    r
                } else {
                    format!("{r}; {}", a.note)
                };
            }
            a
        });
        let mut d = self.safety.decide(proposed, opening);
        d.clamped.extend(self.policy.take_clamped());
        self.messages(now, &g.header.frame_id, d)
    }

    /// The tick's three messages for decision `d`.
    fn messages(&mut self, now: Stamp, frame_id: &str, d: crate::safety::Decision) -> Vec<Msg> {
        let header = Header::new(now, frame_id);
        let status = PolicyStatus {
            header: header.clone(),
            scene: self.scene.clone(),
            mode: self.params.mode.as_str().into(),
            phase: self.policy.phase().into(),
            safety_ok: d.ok,
            message: d.reason.clone(),
            clamped: d.clamped.iter().map(|c| c.to_string()).collect(),
        };
        self.counts.count(&status);
        vec![
            Msg::GripperCommand(GripperCommand {
                header: header.clone(),
                mode: d.gripper.mode,
                position_m: d.gripper.position_m,
                speed_m_s: d.gripper.speed_m_s,
                force_n: d.gripper.force_n,
                reason: d.reason.clone(),
            }),
            Msg::ArmCommand(ArmCommand {
                header: header.clone(),
                target: d.arm.target,
                x_m: d.arm.x_m,
                y_m: d.arm.y_m,
                z_m: d.arm.z_m,
                lift_m: d.arm.lift_m,
                reason: d.reason.clone(),
            }),
            Msg::PolicyStatus(status),
        ]
    }
}

impl Stage for PolicyStage {
    fn name(&self) -> &str {
        "policy"
    }

    /// The tick's time is the GripperStatus's own stamp, not `clock` (the chain's clock is the
    /// latest stamp seen and never moves back, so one input stamped in the future would hold
    /// it there): a status stamped further from the stage's present than the gripper's budget
    /// is an invalid input, answered with the safe action stamped at the present, and moves
    /// nothing; other inputs stamped ahead of a tick are invalid at that tick.
    fn process(&mut self, input: &Msg, _clock: &dyn Clock) -> Result<Vec<Msg>, StageError> {
        let Msg::GripperStatus(g) = input else {
            match input {
                Msg::SlipState(s) => self.slip = Some(s.clone()),
                Msg::ContactState(c) => self.contact = Some(c.clone()),
                _ => {}
            }
            self.assembler.offer(input);
            return Ok(Vec::new());
        };
        let now = g.header.stamp;
        if let Err(off) = self.on_time_line(now.0) {
            let (Some(present), true) = (self.present, off > 0) else {
                // Behind the present: an old status, not a tick.
                return Ok(Vec::new());
            };
            let why = Refusal::GripperAhead {
                ahead_s: off as f64 * 1e-9,
            };
            let opening = self.last_gripper.as_ref().and_then(|(o, _)| *o);
            let d = self.safety.decide(Err(why), opening);
            return Ok(self.messages(Stamp(present), &g.header.frame_id, d));
        }
        self.assembler.offer(input);
        // The opening a hold keeps: the last one within the stroke (a reading outside it, or
        // not finite, is an invalid input and never where the safe action goes).
        let opening = Some(g.opening_m)
            .filter(|o| (0.0..=self.params.stroke_m).contains(o))
            .or(self.last_gripper.as_ref().and_then(|(o, _)| *o));
        self.last_gripper = Some((opening, g.header.frame_id.clone()));
        // Ticks on a fixed schedule at the control rate (no drift); a status up to 5 % of a
        // period early still ticks, so jitter does not skip a period.
        let period = self.period_ns();
        if let Some(due) = self.next_tick {
            if now.0 < due.saturating_sub(period / 20) {
                return Ok(Vec::new());
            }
        }
        let due = self.next_tick.unwrap_or(now.0);
        self.schedule_after(now.0, due);
        self.present = Some(self.present.map_or(now.0, |p| p.max(now.0)));
        Ok(self.tick(now, g))
    }

    /// The watchdog's control period.
    fn timer_period_ns(&self) -> Option<i64> {
        Some(self.period_ns())
    }

    /// The watchdog ([`PolicyStage::watchdog_tick`]): the safe action when no gripper state
    /// came for a control period.
    fn timer(&mut self, now: Stamp) -> Result<Vec<Msg>, StageError> {
        Ok(self.watchdog_tick(now))
    }

    fn awaited_inputs(&self) -> Vec<&'static str> {
        PolicyStage::awaited_inputs(self)
    }

    fn set_input_lost(&mut self, name: &str, why: Option<String>) -> Result<(), StageError> {
        PolicyStage::set_input_lost(self, name, why).map_err(StageError::bad_input)
    }
}
