//! What happened at each control tick, read from its `PolicyStatus` (the one message every
//! transport sees: the trials, the ROS policy node): the policy's action went out, or the safe
//! action did, and why. [`TickCounts`] sums them, so a policy that fails on every tick is a
//! number, not only a string in the phases.

use crate::safety::Refusal;
use serde::Serialize;
use unitac_core::msg::PolicyStatus;

/// The phase a scene controller declares when its task failed (a timeout, a tie): the error is
/// repeated every tick from then on, by design.
pub const FAILED_PHASE: &str = "failed";

/// Why a tick sent what it sent.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum TickKind {
    /// The policy's action went out (bounded, rate limited, maybe with the reflex's change).
    Acted,
    /// The safe action: an input the policy needs was stale, invalid or lost, or the gripper
    /// was silent or stamped ahead (the watchdog; the policy was not asked).
    Watchdog,
    /// The safe action: the policy was asked and failed (an error: a non-finite model output,
    /// a model that cannot run).
    PolicyError,
    /// The safe action: the policy's inference ran past its time limit and was stopped.
    OverBudget,
    /// The safe action: the policy's action was refused (not finite, no action, an unknown arm
    /// target).
    Refused,
    /// The safe action in the controller's `failed` phase (its task failed; not a fault).
    Ended,
}

/// The reasons' starts, as [`Refusal`]'s `Display` writes them (checked by the tests below).
const POLICY: &str = "policy: ";
const OVER_BUDGET: &str = "policy: inference over budget: ";
const REFUSED: [&str; 3] = [
    "policy returned no action",
    "policy output not finite",
    "policy chose arm target",
];

impl TickKind {
    /// The kind of the tick `s` reports.
    pub fn of(s: &PolicyStatus) -> TickKind {
        let m = s.message.as_str();
        if s.safety_ok {
            TickKind::Acted
        } else if s.phase == FAILED_PHASE {
            TickKind::Ended
        } else if m.starts_with(OVER_BUDGET) {
            TickKind::OverBudget
        } else if m.starts_with(POLICY) {
            TickKind::PolicyError
        } else if REFUSED.iter().any(|r| m.starts_with(r)) {
            TickKind::Refused
        } else {
            TickKind::Watchdog
        }
    }

    /// Whether the policy itself failed at this tick (an error, over budget, refused).
    pub fn is_failure(self) -> bool {
        matches!(
            self,
            TickKind::PolicyError | TickKind::OverBudget | TickKind::Refused
        )
    }
}

/// Ticks per [`TickKind`], and the first failure's reason.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize)]
pub struct TickCounts {
    pub ticks: u64,
    pub acted: u64,
    pub watchdog: u64,
    pub policy_error: u64,
    pub over_budget: u64,
    pub refused: u64,
    pub ended: u64,
    /// The reason of the first tick the policy failed (its first 200 characters).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub first_failure: Option<String>,
}

impl TickCounts {
    /// Count one tick's status.
    pub fn count(&mut self, s: &PolicyStatus) {
        let k = TickKind::of(s);
        self.ticks += 1;
        *match k {
            TickKind::Acted => &mut self.acted,
            TickKind::Watchdog => &mut self.watchdog,
            TickKind::PolicyError => &mut self.policy_error,
            TickKind::OverBudget => &mut self.over_budget,
            TickKind::Refused => &mut self.refused,
            TickKind::Ended => &mut self.ended,
        } += 1;
        if k.is_failure() && self.first_failure.is_none() {
            self.first_failure = Some(s.message.chars().take(200).collect());
        }
    }

    /// Ticks on which the policy failed (error, over budget, refused).
    pub fn failed(&self) -> u64 {
        self.policy_error + self.over_budget + self.refused
    }

    /// Ticks were answered, and the policy's action went out on none of them.
    pub fn never_acted(&self) -> bool {
        self.ticks > 0 && self.acted == 0
    }

    /// Add `o`'s counts (its first failure if this has none).
    pub fn add(&mut self, o: &TickCounts) {
        self.ticks += o.ticks;
        self.acted += o.acted;
        self.watchdog += o.watchdog;
        self.policy_error += o.policy_error;
        self.over_budget += o.over_budget;
        self.refused += o.refused;
        self.ended += o.ended;
        if self.first_failure.is_none() {
            self.first_failure.clone_from(&o.first_failure);
        }
    }

    /// `N of M ticks (error E, over budget B, refused R)`: the failures in words.
    pub fn failures_text(&self) -> String {
        format!(
            "{} of {} ticks (policy error {}, inference over budget {}, action refused {})",
            self.failed(),
            self.ticks,
            self.policy_error,
            self.over_budget,
            self.refused
        )
    }
}

/// The reason a refusal gives, as a PolicyStatus carries it (for the tests of [`TickKind`]).
pub fn reason(r: &Refusal) -> String {
    r.to_string()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::policy::PolicyError;
    use unitac_core::msg::samples;

    fn status(ok: bool, phase: &str, r: &Refusal) -> PolicyStatus {
        PolicyStatus {
            safety_ok: ok,
            phase: phase.into(),
            message: reason(r),
            ..samples::policy_status()
        }
    }

    #[test]
    fn every_refusal_has_its_kind() {
        let cases = [
            (
                Refusal::Inputs(vec!["contact: stale".into()]),
                TickKind::Watchdog,
            ),
            (
                Refusal::Policy(PolicyError::Failed("learned policy: NaN".into())),
                TickKind::PolicyError,
            ),
            (
                Refusal::Policy(PolicyError::Timeout("no contact".into())),
                TickKind::PolicyError,
            ),
            (
                Refusal::Policy(PolicyError::OverBudget("stub: 100 ms".into())),
                TickKind::OverBudget,
            ),
            (Refusal::NoAction, TickKind::Refused),
            (
                Refusal::GripperSilent {
                    silent_s: 0.1,
                    period_s: 0.03,
                },
                TickKind::Watchdog,
            ),
            (Refusal::GripperAhead { ahead_s: 1.0 }, TickKind::Watchdog),
            (
                Refusal::NotFinite {
                    field: "arm.x_m",
                    value: f64::NAN,
                },
                TickKind::Refused,
            ),
            (
                Refusal::ArmTarget {
                    target: "moon".into(),
                    objects: vec!["cup".into()],
                },
                TickKind::Refused,
            ),
        ];
        for (r, kind) in cases {
            assert_eq!(TickKind::of(&status(false, "act", &r)), kind, "{r}");
            // The controller's declared failure is an end, whatever the reason.
            assert_eq!(TickKind::of(&status(false, "failed", &r)), TickKind::Ended);
        }
        assert_eq!(
            TickKind::of(&status(true, "act", &Refusal::NoAction)),
            TickKind::Acted
        );
    }

    #[test]
    fn counts_sum_and_keep_the_first_failure() {
        let mut c = TickCounts::default();
        c.count(&status(true, "act", &Refusal::NoAction));
        let e = Refusal::Policy(PolicyError::Failed("first".into()));
        c.count(&status(false, "act", &e));
        c.count(&status(
            false,
            "act",
            &Refusal::Policy(PolicyError::OverBudget("x".into())),
        ));
        assert_eq!((c.ticks, c.acted, c.failed()), (3, 1, 2));
        assert_eq!(c.first_failure.as_deref(), Some("policy: first"));
        assert!(!c.never_acted());
        let mut all = TickCounts::default();
        all.add(&c);
        all.add(&c);
        assert_eq!((all.ticks, all.over_budget), (6, 2));
        assert!(
            TickCounts {
                ticks: 3,
                ..Default::default()
            }
            .never_acted()
        );
    }
}
