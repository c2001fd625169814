//! The safety layer between any policy and any gripper, independent of the policy.
//!
//! Every tick it gets what the policy proposed (an action, or the reason there is none: a stale
//! or invalid input, a policy error) and returns the command that is sent:
//! - a proposed action with a non-finite number is refused (the reason names the field);
//! - an arm target that is not "home" or one of the scene's objects is refused;
//! - otherwise every number is clamped to its bounds, then the opening, force and lift may move
//!   at most one step per tick from the previous command (the rate limit);
//! - a refusal gives the scene's safe action within the same tick: hold (position mode at the
//!   measured opening, the hold force, arm where it was) or open (the widest opening).
//!
//! The safe action itself is bounded but not rate limited (holding is stopping where the fingers
//! are); the next proposed action is rate limited from it. No NaN or infinity ever leaves here.

use crate::error::Problems;
use crate::policy::{Action, ArmAction, GripperAction, PolicyError};
use serde::{Deserialize, Serialize};
use thiserror::Error;
use unitac_core::msg::GripperMode;

/// Why a tick gets the safe action: no action was proposed, or the one proposed is refused.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum Refusal {
    /// Inputs the policy needs now that are stale, invalid or lost, every one listed.
    #[error("{}", .0.join("; "))]
    Inputs(Vec<String>),
    #[error("policy: {0}")]
    Policy(#[from] PolicyError),
    #[error("policy returned no action")]
    NoAction,
    /// No GripperStatus for a whole control period where one was due.
    #[error("gripper: no status for {silent_s:.3} s (control period {period_s:.3} s)")]
    GripperSilent { silent_s: f64, period_s: f64 },
    /// A GripperStatus stamped further ahead of the last control tick than the gripper's budget.
    #[error("gripper: invalid (stamp ahead by {ahead_s:.3} s of the last control tick)")]
    GripperAhead { ahead_s: f64 },
    #[error("policy output not finite: {field} = {value}")]
    NotFinite { field: &'static str, value: f64 },
    /// An arm target that is not "home" or one of the scene's objects (its first 64 characters).
    #[error(
        "policy chose arm target '{target}', not home or one of the scene's objects ({})",
        .objects.join(", ")
    )]
    ArmTarget {
        target: String,
        objects: Vec<String>,
    },
}

/// What the scene does when the policy cannot be trusted.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SafeAction {
    /// Keep the current opening with the hold force; the arm stays.
    #[default]
    Hold,
    /// Open to the widest opening; the arm stays.
    Open,
}

/// The limits of every command: a scene's keys (flattened into `PolicyParams`), held inside a
/// named gripper's profile by `PolicyParams::bounds`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Bounds {
    pub min_opening_m: f64,
    pub max_opening_m: f64,
    pub max_speed_m_s: f64,
    pub max_force_n: f64,
    /// Largest change of the commanded opening per tick \[m].
    pub max_step_m: f64,
    /// Largest change of the commanded force per tick \[N].
    pub max_force_step_n: f64,
    pub min_z_m: f64,
    pub max_z_m: f64,
    pub max_lift_m: f64,
    /// Largest change of the commanded lift per tick \[m].
    pub max_lift_step_m: f64,
    /// The arm's horizontal workspace: |x| and |y| of a target at most this (table frame) \[m].
    pub max_reach_m: f64,
    /// Objects the arm may go to (besides "home"); for a pick task the first two are touched as
    /// A and B, in this order.
    pub objects: Vec<String>,
}

impl Default for Bounds {
    fn default() -> Self {
        Self {
            min_opening_m: 0.0,
            max_opening_m: 0.085,
            max_speed_m_s: 0.15,
            max_force_n: 40.0,
            max_step_m: 0.005,
            max_force_step_n: 2.0,
            min_z_m: 0.0,
            max_z_m: 0.3,
            max_lift_m: 0.2,
            max_lift_step_m: 0.01,
            max_reach_m: 1.0,
            objects: vec!["fabric_a".into(), "fabric_b".into()],
        }
    }
}

impl Bounds {
    /// Each action value's name and range, in the order of [`Action::values`].
    pub fn ranges(&self) -> [(&'static str, f64, f64); 7] {
        let reach = self.max_reach_m;
        let [position, speed, force, x, y, z, lift] = crate::schema::COMMANDS;
        [
            (position, self.min_opening_m, self.max_opening_m),
            (speed, 0.0, self.max_speed_m_s),
            (force, 0.0, self.max_force_n),
            (x, -reach, reach),
            (y, -reach, reach),
            (z, self.min_z_m, self.max_z_m),
            (lift, 0.0, self.max_lift_m),
        ]
    }

    /// One line per broken rule, all at once.
    pub fn check(&self) -> Result<(), Problems> {
        let mut bad = Vec::new();
        let all = [
            ("min_opening_m", self.min_opening_m),
            ("max_opening_m", self.max_opening_m),
            ("max_speed_m_s", self.max_speed_m_s),
            ("max_force_n", self.max_force_n),
            ("max_step_m", self.max_step_m),
            ("max_force_step_n", self.max_force_step_n),
            ("min_z_m", self.min_z_m),
            ("max_z_m", self.max_z_m),
            ("max_lift_m", self.max_lift_m),
            ("max_lift_step_m", self.max_lift_step_m),
            ("max_reach_m", self.max_reach_m),
        ];
        for (k, v) in all {
            if !(v.is_finite() && v >= 0.0) {
                bad.push(format!("{k} = {v} must be finite and >= 0"));
            }
        }
        if self.min_opening_m >= self.max_opening_m {
            bad.push("min_opening_m must be below max_opening_m".into());
        }
        if self.min_z_m > self.max_z_m {
            bad.push("min_z_m must not exceed max_z_m".into());
        }
        for (k, v) in [
            ("max_step_m", self.max_step_m),
            ("max_force_step_n", self.max_force_step_n),
            ("max_speed_m_s", self.max_speed_m_s),
        ] {
            if v == 0.0 {
                bad.push(format!("{k} must be > 0"));
            }
        }
        Problems(bad).into_result()
    }
}

/// What leaves the safety layer at one tick.
#[derive(Debug, Clone, PartialEq)]
pub struct Decision {
    pub gripper: GripperAction,
    pub arm: ArmAction,
    /// false: the safe action, for `reason`.
    pub ok: bool,
    pub reason: String,
    /// The proposed values that lay beyond a bound by more than [`CLAMP_REPORT`] of its range
    /// (clamped, and counted by whoever reads PolicyStatus.clamped).
    pub clamped: Vec<&'static str>,
}

/// A proposed value beyond a bound by more than this share of the bound's range is reported as
/// clamped (nearer, it is rounding at the edge of a range a policy was trained to reach).
pub const CLAMP_REPORT: f64 = 0.02;

/// Whether `v` lies beyond [lo, hi] by more than [`CLAMP_REPORT`] of the range.
fn beyond(v: f64, lo: f64, hi: f64) -> bool {
    let margin = CLAMP_REPORT * (hi - lo).abs();
    v < lo - margin || v > hi + margin
}

/// Bounds, rate limits and the safe action, with the previous command it limits from.
#[derive(Debug, Clone)]
pub struct SafetyLayer {
    bounds: Bounds,
    safe: SafeAction,
    hold_force_n: f64,
    last: Option<(GripperAction, ArmAction)>,
}

fn step(from: f64, to: f64, max: f64) -> f64 {
    to.clamp(from - max, from + max)
}

impl SafetyLayer {
    pub fn new(bounds: Bounds, safe: SafeAction, hold_force_n: f64) -> Self {
        let hold_force_n = if hold_force_n.is_finite() {
            hold_force_n.clamp(0.0, bounds.max_force_n)
        } else {
            0.0
        };
        Self {
            bounds,
            safe,
            hold_force_n,
            last: None,
        }
    }

    pub fn bounds(&self) -> &Bounds {
        &self.bounds
    }

    /// The last command sent: grip force \[N] and lift \[m] (None before the first).
    pub fn last_force_and_lift(&self) -> Option<(f64, f64)> {
        self.last.as_ref().map(|(g, a)| (g.force_n, a.lift_m))
    }

    /// The command for this tick: `proposed` through the bounds and rate limits, or the safe
    /// action when it is refused. `opening_m`: the measured opening (None or non-finite: unknown).
    pub fn decide(
        &mut self,
        proposed: Result<Action, Refusal>,
        opening_m: Option<f64>,
    ) -> Decision {
        let opening = opening_m.filter(|o| o.is_finite());
        let checked = proposed.and_then(|a| self.refuse(&a).map_or(Ok(a), Err));
        let d = match checked {
            Ok(a) => Decision {
                clamped: self.beyond_bounds(&a),
                gripper: self.limit_gripper(&a.gripper, opening),
                arm: self.limit_arm(&a.arm),
                ok: true,
                reason: a.note,
            },
            Err(reason) => self.safe_action(opening, reason.to_string()),
        };
        self.last = Some((d.gripper.clone(), d.arm.clone()));
        d
    }

    /// Why `a` cannot be executed at all (None: it can, after clamping).
    fn refuse(&self, a: &Action) -> Option<Refusal> {
        if let Some((field, value)) = a.values().into_iter().find(|(_, v)| !v.is_finite()) {
            return Some(Refusal::NotFinite { field, value });
        }
        let t = &a.arm.target;
        if t != "home" && !self.bounds.objects.iter().any(|o| o == t) {
            return Some(Refusal::ArmTarget {
                target: t.chars().take(64).collect(),
                objects: self.bounds.objects.clone(),
            });
        }
        None
    }

    /// The values of `a` beyond their bounds by more than [`CLAMP_REPORT`] of the range.
    fn beyond_bounds(&self, a: &Action) -> Vec<&'static str> {
        self.bounds
            .ranges()
            .into_iter()
            .zip(a.values())
            .filter(|&((_, lo, hi), (_, v))| beyond(v, lo, hi))
            .map(|((k, ..), _)| k)
            .collect()
    }

    fn limit_gripper(&self, g: &GripperAction, opening: Option<f64>) -> GripperAction {
        let b = &self.bounds;
        let pos = g.position_m.clamp(b.min_opening_m, b.max_opening_m);
        let force = g.force_n.clamp(0.0, b.max_force_n);
        let speed = g.speed_m_s.clamp(0.0, b.max_speed_m_s);
        let (last_pos, last_force) = match &self.last {
            Some((l, _)) => (Some(l.position_m), Some(l.force_n)),
            None => (opening, None),
        };
        GripperAction {
            mode: g.mode,
            // Rate limited from the last command or, before the first, from the measured
            // opening, which may lie outside the bounds (a gripper wider open than the scene
            // allows): the bounds win over the rate limit.
            position_m: last_pos.map_or(pos, |p| {
                step(p, pos, b.max_step_m).clamp(b.min_opening_m, b.max_opening_m)
            }),
            speed_m_s: speed,
            force_n: last_force.map_or(force.min(b.max_force_step_n), |f| {
                step(f, force, b.max_force_step_n)
            }),
        }
    }

    fn limit_arm(&self, a: &ArmAction) -> ArmAction {
        let b = &self.bounds;
        let lift = a.lift_m.clamp(0.0, b.max_lift_m);
        let last_lift = self.last.as_ref().map_or(0.0, |(_, l)| l.lift_m);
        ArmAction {
            target: a.target.clone(),
            x_m: a.x_m.clamp(-b.max_reach_m, b.max_reach_m),
            y_m: a.y_m.clamp(-b.max_reach_m, b.max_reach_m),
            z_m: a.z_m.clamp(b.min_z_m, b.max_z_m),
            lift_m: step(last_lift, lift, b.max_lift_step_m),
        }
    }

    /// The scene's safe action (bounded, finite).
    pub fn safe_action(&self, opening: Option<f64>, reason: String) -> Decision {
        let b = &self.bounds;
        let arm = self
            .last
            .as_ref()
            .map(|(_, a)| a.clone())
            .unwrap_or_else(|| ArmAction {
                target: "home".into(),
                x_m: 0.0,
                y_m: 0.0,
                z_m: b.max_z_m,
                lift_m: 0.0,
            });
        let last_pos = self.last.as_ref().map(|(g, _)| g.position_m);
        let gripper = match (self.safe, opening.or(last_pos)) {
            (SafeAction::Hold, Some(o)) => GripperAction {
                mode: GripperMode::Position,
                position_m: o.clamp(b.min_opening_m, b.max_opening_m),
                speed_m_s: b.max_speed_m_s,
                force_n: self.hold_force_n,
            },
            // Nothing known about the fingers: stop them where they are.
            (SafeAction::Hold, None) => GripperAction {
                mode: GripperMode::Stop,
                position_m: b.max_opening_m,
                speed_m_s: 0.0,
                force_n: self.hold_force_n,
            },
            (SafeAction::Open, _) => GripperAction {
                mode: GripperMode::Position,
                position_m: b.max_opening_m,
                speed_m_s: b.max_speed_m_s,
                force_n: self.hold_force_n,
            },
        };
        Decision {
            gripper,
            arm,
            ok: false,
            reason,
            clamped: Vec::new(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    pub(crate) fn bounds() -> Bounds {
        Bounds {
            min_opening_m: 0.0,
            max_opening_m: 0.085,
            max_speed_m_s: 0.1,
            max_force_n: 20.0,
            max_step_m: 0.002,
            max_force_step_n: 1.0,
            min_z_m: 0.0,
            max_z_m: 0.3,
            max_lift_m: 0.1,
            max_lift_step_m: 0.005,
            max_reach_m: 1.0,
            objects: vec!["cup".into()],
        }
    }

    fn act(pos: f64, force: f64, target: &str) -> Action {
        Action {
            gripper: GripperAction {
                mode: GripperMode::Position,
                position_m: pos,
                speed_m_s: 1.0,
                force_n: force,
            },
            arm: ArmAction {
                target: target.into(),
                x_m: 0.4,
                y_m: 0.0,
                z_m: 0.01,
                lift_m: 1.0,
            },
            note: "go".into(),
        }
    }

    #[test]
    fn ranges_name_the_action_values_in_order() {
        let b = bounds();
        let a = act(0.05, 5.0, "home");
        let names: Vec<_> = a.values().iter().map(|(n, _)| *n).collect();
        let ranged: Vec<_> = b.ranges().iter().map(|(n, ..)| *n).collect();
        assert_eq!(names, ranged);
        assert!(b.ranges().iter().all(|(_, lo, hi)| lo < hi));
    }

    #[test]
    fn clamps_then_rate_limits_from_the_last_command() {
        let mut s = SafetyLayer::new(bounds(), SafeAction::Hold, 5.0);
        let d = s.decide(Ok(act(-1.0, 100.0, "cup")), Some(0.05));
        assert!(d.ok);
        // From the measured opening, one step toward the clamped target.
        assert!((d.gripper.position_m - 0.048).abs() < 1e-12);
        assert_eq!(d.gripper.force_n, 1.0);
        assert_eq!(d.gripper.speed_m_s, 0.1);
        assert_eq!(d.arm.lift_m, 0.005);
        // Opening -1 m on a 0.085 m range, speed 1 m/s on 0.1, force 100 N on 20, lift 1 m on
        // 0.1: reported.
        assert_eq!(
            d.clamped,
            [
                "gripper.position_m",
                "gripper.speed_m_s",
                "gripper.force_n",
                "arm.lift_m"
            ]
        );
        let mut near = act(0.0851, 20.2, "cup");
        near.gripper.speed_m_s = 0.1;
        near.arm.lift_m = 0.05;
        let mut s2 = SafetyLayer::new(bounds(), SafeAction::Hold, 5.0);
        // Within 2 % of the range beyond a bound: clamped, not reported.
        assert!(s2.decide(Ok(near), Some(0.05)).clamped.is_empty());
        let d = s.decide(Ok(act(-1.0, 100.0, "cup")), Some(0.05));
        assert!((d.gripper.position_m - 0.046).abs() < 1e-12);
        assert_eq!(d.gripper.force_n, 2.0);
        assert_eq!(d.arm.lift_m, 0.01);
    }

    #[test]
    fn refusals_give_the_safe_action_with_the_reason() {
        let mut s = SafetyLayer::new(bounds(), SafeAction::Hold, 5.0);
        let d = s.decide(Ok(act(f64::NAN, 1.0, "cup")), Some(0.04));
        assert!(!d.ok);
        assert_eq!(
            d.reason,
            "policy output not finite: gripper.position_m = NaN"
        );
        assert_eq!(d.gripper.mode, GripperMode::Position);
        assert_eq!(d.gripper.position_m, 0.04);
        assert_eq!(d.gripper.force_n, 5.0);
        let d = s.decide(Ok(act(0.03, 1.0, "table")), Some(0.04));
        assert!(d.reason.contains("'table'"), "{}", d.reason);
        let d = s.decide(Err(Refusal::Inputs(vec!["contact: stale".into()])), None);
        assert_eq!(d.reason, "contact: stale");
        // Unknown opening: the last command's.
        assert_eq!(d.gripper.position_m, 0.04);
        let mut open = SafetyLayer::new(bounds(), SafeAction::Open, 5.0);
        let d = open.decide(Err(Refusal::NoAction), None);
        assert_eq!(d.gripper.position_m, 0.085);
        assert_eq!(d.arm.target, "home");
        let mut fresh = SafetyLayer::new(bounds(), SafeAction::Hold, 500.0);
        let d = fresh.decide(Err(Refusal::NoAction), None);
        assert_eq!(d.gripper.mode, GripperMode::Stop);
        assert_eq!(d.gripper.force_n, 20.0);
    }

    #[test]
    fn bounds_check_lists_every_problem() {
        let mut b = bounds();
        b.max_force_n = f64::NAN;
        b.min_opening_m = 0.1;
        b.max_step_m = 0.0;
        let e = b.check().unwrap_err().to_string();
        assert_eq!(
            e,
            "max_force_n = NaN must be finite and >= 0; min_opening_m must be below max_opening_m; max_step_m must be > 0"
        );
        assert_eq!(bounds().check(), Ok(()));
    }
}
