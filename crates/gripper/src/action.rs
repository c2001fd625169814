//! A gripper behind a ros2_control gripper action server (`control_msgs/action/GripperCommand`,
//! e.g. ros2_controllers' GripperActionController): which goals to send for the policy's
//! commands, and what the goals' fates say about the gripper. Pure: the ROS action client
//! (crates/ros, the policy node) feeds it the server's answers and sends the goals it returns.
//!
//! The action's goal is a position and a force limit (`max_effort`); it has no speed, so the
//! fingers move at the controller's own speed. The server's documented semantics:
//! - every goal is accepted, and a new goal preempts the active one (its result: canceled or
//!   aborted, depending on the server);
//! - a goal succeeds when the position is within the controller's tolerance (`reached_goal`);
//! - fingers that stop short of the goal for the stall timeout have `stalled`: the goal succeeds
//!   with `allow_stalling`, else it is aborted. Either way the fingers stopped on something:
//!   that is the gripper's object detection here. So is a closing goal that ended (reached
//!   within the controller's tolerance, 1 cm by default) with the fingers more than
//!   [`CAUGHT_SHORT_M`] short of it, as a Robotiq's own detection reports a stop on contact;
//! - a cancel request holds the current position.
//!
//! What is a fault (the policy's safety layer answers a gripper fault with the safe action on
//! its next tick): the current goal rejected, aborted without a stall, or ended by anyone but us
//! (a goal of another client preempted it); no server. A goal of ours that our own newer goal
//! preempted is not a fault. A fault clears when a later goal of ours succeeds or stalls (the
//! controller does what it is told again).

use crate::GripperSetpoint;
use serde::Serialize;
use unitac_core::Stamp;
use unitac_core::msg::GripperStatus;

/// A goal for the action server.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Goal {
    /// Finger opening \[m].
    pub position_m: f64,
    /// Force limit \[N].
    pub max_effort_n: f64,
}

/// How a goal ended, as the action's goal status says.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum GoalEnd {
    Succeeded,
    Aborted,
    Canceled,
}

/// The action's feedback and result fields.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Report {
    pub position_m: f64,
    pub effort_n: f64,
    pub stalled: bool,
    pub reached_goal: bool,
}

/// Where the current goal is.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Phase {
    /// Sent, no answer yet.
    Sent,
    /// Accepted and executing.
    Active,
    /// Finished as asked: reached, or stalled on an object.
    Done { stalled: bool },
    /// Refused, aborted or preempted by someone else.
    Failed,
}

#[derive(Debug, Clone, Copy)]
struct Current {
    id: u64,
    goal: Goal,
    sent_at: Stamp,
    phase: Phase,
    stalled: bool,
}

/// Fingers that ended a closing goal more than this short of it \[m] stopped on an object.
pub const CAUGHT_SHORT_M: f64 = 1e-3;

/// When to send a goal again.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Resend {
    /// A command that differs from the current goal by more than this is a new goal \[m].
    pub position_m: f64,
    /// ... or by more than this \[N].
    pub effort_n: f64,
    /// A goal the server has not answered after this long is sent again \[ns] (a request sent
    /// before the server was discovered is lost).
    pub unanswered_ns: i64,
}

impl Default for Resend {
    /// 0.1 mm (the finest opening a Robotiq reports), 0.5 N, 1 s.
    fn default() -> Self {
        Self {
            position_m: 1e-4,
            effort_n: 0.5,
            unanswered_ns: 1_000_000_000,
        }
    }
}

/// The client side of the gripper action: see the module docs.
#[derive(Debug, Clone)]
pub struct ActionLink {
    resend: Resend,
    next_id: u64,
    current: Option<Current>,
    fault: Option<String>,
    server: Option<String>,
    goals_sent: u64,
}

impl ActionLink {
    pub fn new(resend: Resend) -> Self {
        Self {
            resend,
            next_id: 0,
            current: None,
            fault: None,
            server: None,
            goals_sent: 0,
        }
    }

    /// The goal to send for `cmd` at `now` and its id, or None when the current goal already
    /// asks for it (and is under way or done), or when there is no server to send it to (a goal
    /// sent then is lost, and its result never comes).
    pub fn command(&mut self, cmd: &GripperSetpoint, now: Stamp) -> Option<(u64, Goal)> {
        if self.server.is_some() {
            return None;
        }
        let goal = Goal {
            position_m: cmd.opening_m,
            max_effort_n: cmd.force_n,
        };
        if let Some(c) = &self.current {
            let same = (c.goal.position_m - goal.position_m).abs() <= self.resend.position_m
                && (c.goal.max_effort_n - goal.max_effort_n).abs() <= self.resend.effort_n;
            let unanswered =
                c.phase == Phase::Sent && now.0 - c.sent_at.0 > self.resend.unanswered_ns;
            if same && c.phase != Phase::Failed && !unanswered {
                return None;
            }
        }
        self.next_id += 1;
        self.goals_sent += 1;
        self.current = Some(Current {
            id: self.next_id,
            goal,
            sent_at: now,
            phase: Phase::Sent,
            stalled: false,
        });
        Some((self.next_id, goal))
    }

    fn current_mut(&mut self, id: u64) -> Option<&mut Current> {
        self.current.as_mut().filter(|c| c.id == id)
    }

    /// The server's answer to goal `id`.
    pub fn answered(&mut self, id: u64, accepted: bool) {
        let Some(c) = self.current_mut(id) else {
            return;
        };
        if accepted {
            if c.phase == Phase::Sent {
                c.phase = Phase::Active;
            }
        } else {
            c.phase = Phase::Failed;
            self.fault = Some("gripper action: goal rejected by the server".into());
        }
    }

    /// Feedback on goal `id`.
    pub fn feedback(&mut self, id: u64, r: &Report) {
        if let Some(c) = self.current_mut(id) {
            c.stalled = r.stalled;
        }
    }

    /// Goal `id` ended. Ends of goals our own newer goal preempted change nothing.
    pub fn finished(&mut self, id: u64, end: GoalEnd, r: &Report) {
        let Some(c) = self.current_mut(id) else {
            return;
        };
        c.stalled = r.stalled;
        let fault = match end {
            GoalEnd::Succeeded => None,
            GoalEnd::Aborted if r.stalled => None,
            GoalEnd::Aborted => Some("gripper action: goal aborted by the server"),
            GoalEnd::Canceled => {
                Some("gripper action: goal preempted or canceled by another client")
            }
        };
        match fault {
            None => {
                c.phase = Phase::Done { stalled: r.stalled };
                self.fault = None;
            }
            Some(f) => {
                c.phase = Phase::Failed;
                self.fault = Some(f.into());
            }
        }
    }

    /// The sending of goal `id` failed locally (the client is gone): a fault.
    pub fn send_failed(&mut self, id: u64, why: &str) {
        if let Some(c) = self.current_mut(id) {
            c.phase = Phase::Failed;
            self.fault = Some(format!("gripper action: {why}"));
        }
    }

    /// Whether a server is there (`missing`: why not). A missing server is a fault until it
    /// returns.
    pub fn set_server_missing(&mut self, missing: Option<String>) {
        self.server = missing;
    }

    /// The fault the policy sees, if any.
    pub fn fault(&self) -> Option<&str> {
        self.server.as_deref().or(self.fault.as_deref())
    }

    /// Goals sent since start.
    pub fn goals_sent(&self) -> u64 {
        self.goals_sent
    }

    /// The measured status (opening and force from the robot's joint states) with what the
    /// action says: the goal's position as the target, motion, object detection (a stall) and
    /// the fault. A fault the measured status already carries is kept.
    pub fn status(&self, mut s: GripperStatus) -> GripperStatus {
        if let Some(c) = &self.current {
            s.target_m = c.goal.position_m;
            let short = s.opening_m > c.goal.position_m + CAUGHT_SHORT_M;
            let (motion, held) = match c.phase {
                Phase::Sent | Phase::Active if c.stalled => ("caught", true),
                Phase::Sent | Phase::Active => ("moving", false),
                Phase::Done { stalled } if stalled || short => ("caught", true),
                Phase::Done { .. } => ("reached", false),
                Phase::Failed => ("idle", false),
            };
            s.motion = motion.into();
            s.object_detected = held;
        }
        if s.fault.is_empty() {
            if let Some(f) = self.fault() {
                s.fault = f.into();
            }
        }
        s
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use unitac_core::msg::Header;

    const T: Stamp = Stamp(1_000);

    fn cmd(opening_m: f64, force_n: f64) -> GripperSetpoint {
        GripperSetpoint {
            opening_m,
            speed_m_s: 0.02,
            force_n,
        }
    }

    fn measured() -> GripperStatus {
        GripperStatus {
            header: Header::new(Stamp(1), "gripper"),
            opening_m: 0.05,
            target_m: f64::NAN,
            force_n: 3.0,
            current_a: f64::NAN,
            object_detected: false,
            activation: String::new(),
            motion: String::new(),
            fault: String::new(),
        }
    }

    fn report(stalled: bool, reached_goal: bool) -> Report {
        Report {
            position_m: 0.05,
            effort_n: 3.0,
            stalled,
            reached_goal,
        }
    }

    #[test]
    fn a_repeated_command_sends_one_goal_and_a_new_one_preempts_it() {
        let mut l = ActionLink::new(Resend::default());
        let (a, g) = l.command(&cmd(0.08, 20.0), T).unwrap();
        assert_eq!(
            g,
            Goal {
                position_m: 0.08,
                max_effort_n: 20.0
            }
        );
        assert!(l.command(&cmd(0.08 + 5e-5, 20.2), T).is_none());
        l.answered(a, true);
        assert_eq!(l.status(measured()).motion, "moving");
        let (b, _) = l.command(&cmd(0.04, 20.0), T).unwrap();
        // Our own preemption of goal a: its end is not a fault.
        l.finished(a, GoalEnd::Canceled, &report(false, false));
        l.finished(a, GoalEnd::Aborted, &report(false, false));
        assert_eq!(l.fault(), None);
        l.answered(b, true);
        l.finished(b, GoalEnd::Succeeded, &report(false, true));
        let mut m = measured();
        m.opening_m = 0.04;
        let s = l.status(m);
        assert_eq!((s.motion.as_str(), s.target_m), ("reached", 0.04));
        assert!(s.fault.is_empty() && !s.object_detected);
        // Done and the same command: nothing to send.
        assert!(l.command(&cmd(0.04, 20.0), T).is_none());
        assert_eq!(l.goals_sent(), 2);
    }

    #[test]
    fn a_closing_goal_reached_short_of_its_position_is_a_caught_object() {
        let mut l = ActionLink::new(Resend::default());
        // Sent to 60 mm, reached within the controller's 1 cm at 65 mm: on the object.
        let (a, _) = l.command(&cmd(0.060, 40.0), T).unwrap();
        l.answered(a, true);
        l.finished(a, GoalEnd::Succeeded, &report(false, true));
        let mut m = measured();
        m.opening_m = 0.065;
        let s = l.status(m.clone());
        assert!(s.object_detected && s.motion == "caught", "{s:?}");
        // At the goal (within a millimetre): reached, nothing caught.
        m.opening_m = 0.0605;
        let s = l.status(m);
        assert!(!s.object_detected && s.motion == "reached", "{s:?}");
    }

    #[test]
    fn a_goal_the_server_never_answered_is_sent_again() {
        let mut l = ActionLink::new(Resend::default());
        let (a, _) = l.command(&cmd(0.08, 20.0), T).unwrap();
        assert!(
            l.command(&cmd(0.08, 20.0), Stamp(T.0 + 900_000_000))
                .is_none()
        );
        let (b, _) = l
            .command(&cmd(0.08, 20.0), Stamp(T.0 + 1_100_000_000))
            .unwrap();
        assert_ne!(a, b);
        // Once answered, the same command is not resent however long it runs.
        l.answered(b, true);
        assert!(
            l.command(&cmd(0.08, 20.0), Stamp(T.0 + 9_000_000_000))
                .is_none()
        );
    }

    #[test]
    fn a_stall_is_a_caught_object_whether_the_server_succeeds_or_aborts_it() {
        for end in [GoalEnd::Succeeded, GoalEnd::Aborted] {
            let mut l = ActionLink::new(Resend::default());
            let (a, _) = l.command(&cmd(0.0, 40.0), T).unwrap();
            l.answered(a, true);
            l.finished(a, end, &report(true, false));
            let s = l.status(measured());
            assert!(s.object_detected, "{end:?}");
            assert_eq!(s.motion, "caught");
            assert!(s.fault.is_empty(), "{end:?}: {}", s.fault);
        }
    }

    #[test]
    fn abort_rejection_and_foreign_preemption_are_faults_until_a_goal_of_ours_succeeds() {
        type End = fn(&mut ActionLink, u64);
        let cases: [(&str, End); 3] = [
            ("aborted", |l, id| {
                l.answered(id, true);
                l.finished(id, GoalEnd::Aborted, &report(false, false));
            }),
            ("rejected", |l, id| l.answered(id, false)),
            ("preempted", |l, id| {
                l.answered(id, true);
                l.finished(
                    id,
                    GoalEnd::Canceled,
                    &Report {
                        position_m: 0.0,
                        effort_n: 0.0,
                        stalled: false,
                        reached_goal: false,
                    },
                );
            }),
        ];
        for (what, end) in cases {
            let mut l = ActionLink::new(Resend::default());
            let (a, _) = l.command(&cmd(0.03, 20.0), T).unwrap();
            end(&mut l, a);
            let s = l.status(measured());
            assert!(s.fault.contains(what), "{what}: {}", s.fault);
            // The same command again is sent again (the failed goal does not count) ...
            let (b, _) = l.command(&cmd(0.03, 20.0), T).unwrap();
            l.answered(b, true);
            assert!(l.fault().is_some(), "{what}: accepted is not yet done");
            // ... and its success clears the fault.
            l.finished(b, GoalEnd::Succeeded, &report(false, true));
            assert_eq!(l.fault(), None, "{what}");
        }
    }

    #[test]
    fn a_missing_server_is_a_fault_and_a_measured_fault_is_kept() {
        let mut l = ActionLink::new(Resend::default());
        l.set_server_missing(Some("gripper action: no server on /g".into()));
        assert_eq!(
            l.status(measured()).fault,
            "gripper action: no server on /g"
        );
        let mut m = measured();
        m.fault = "link: port gone".into();
        assert_eq!(l.status(m).fault, "link: port gone");
        // Nothing is sent to a missing server; once it is back, the command goes out.
        assert!(l.command(&cmd(0.03, 20.0), T).is_none());
        l.set_server_missing(None);
        assert!(l.status(measured()).fault.is_empty());
        assert!(l.command(&cmd(0.03, 20.0), T).is_some());
    }
}
