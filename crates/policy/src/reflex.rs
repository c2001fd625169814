//! The tactile reflex: part of the safety layer, under every policy (a scene controller or a
//! learned one), between what the policy proposes and the bounds and rate limits.
//!
//! - **Slip**: a fresh, valid `SlipState` with `slip` set (the marker slip stage) while the
//!   fingers hold something (the gripper's object-detect or tactile contact, and the policy not
//!   opening them) raises the grip force by `reflex_force_step_n` per tick, up to the bounds'
//!   `max_force_n` (a position-mode grip is also closed by `reflex_squeeze_m` from the measured
//!   opening, so the raised limit grips), and while lifting stops the lift where it is. The raised
//!   force stays the floor of the grip until the policy opens the fingers or the object is gone,
//!   and where the gripper measures its force, the lift stays stopped until the grip has reached
//!   it (the fingers take a while to squeeze harder).
//! - **Grasp confirmation**: a grasp counts as confirmed only when the gripper's object-detect
//!   and the tactile contact agree. Where the scene has tactile contact (a fresh ContactState), a
//!   lift the policy starts or continues while they disagree is held where it is: the gripper
//!   reports an object the sensor does not touch (caught on a fingertip's edge, or not the
//!   object), or the sensor touches an object while the gripper, closing on force, has not
//!   stopped on it. A position-mode grip is the exception the gripper itself makes: it reports
//!   no object once it reached its target (Robotiq gOBJ 3, the sim world's "not stalled"), even
//!   squeezing a compliant cup, so there its silence is no disagreement. Without tactile
//!   contact (vla scenes have no contact stage) nothing can confirm or refute a grasp and the
//!   lift is left to the policy.
//!
//! Every action is named in the tick's reason (PolicyStatus.message and the commands' reason)
//! and counted ([`ReflexCounters`]); the safety layer then applies the bounds and rate limits, so
//! nothing the reflex asks leaves them.

use crate::policy::Action;
use crate::safety::Bounds;
use serde::Serialize;
use unitac_core::msg::{ContactState, GripperMode, SlipState};

/// A position command more than this above the measured opening is the policy opening the
/// fingers (a release) \[m].
const RELEASE_M: f64 = 0.001;

/// A position command within this of the measured opening holds the fingers where they are \[m].
const HOLD_M: f64 = 0.001;

/// What the reflex did since the stage was built.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct ReflexCounters {
    /// Ticks with slip seen while holding or lifting.
    pub slip_ticks: u64,
    /// Ticks the grip force was raised for slip.
    pub force_raises: u64,
    /// Ticks a position-mode grip was closed further for slip.
    pub squeezes: u64,
    /// Ticks a lift was stopped for slip.
    pub lift_stops_slip: u64,
    /// Ticks a lift was stopped because the grasp was not confirmed.
    pub lift_stops_unconfirmed: u64,
}

/// The tactile facts at a tick (each fresh and valid, else None).
#[derive(Debug, Clone, Copy, Default)]
pub struct Touch<'a> {
    pub slip: Option<&'a SlipState>,
    pub contact: Option<&'a ContactState>,
    /// The gripper's own object detection (GripperStatus.object_detected).
    pub object_detected: bool,
    /// The measured opening \[m] (None: unknown).
    pub opening_m: Option<f64>,
    /// The measured grip force \[N] (None: unknown, e.g. a Robotiq).
    pub force_n: Option<f64>,
}

/// The reflex's settings (from the policy params).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReflexParams {
    pub enabled: bool,
    pub force_step_n: f64,
    pub squeeze_m: f64,
    pub confirm_grasp: bool,
}

/// The reflex's state: the force floor it raised and its counters.
#[derive(Debug, Clone)]
pub struct Reflex {
    p: ReflexParams,
    floor_n: Option<f64>,
    counters: ReflexCounters,
}

impl Reflex {
    pub fn new(p: ReflexParams) -> Self {
        Self {
            p,
            floor_n: None,
            counters: ReflexCounters::default(),
        }
    }

    pub fn counters(&self) -> ReflexCounters {
        self.counters
    }

    /// Adjust the policy's proposed action `a` for this tick's `touch`; `last` is the last
    /// command sent (grip force \[N], lift \[m]). Returns what it did, for the reason (None:
    /// nothing).
    pub fn apply(
        &mut self,
        a: &mut Action,
        touch: &Touch,
        last: Option<(f64, f64)>,
        bounds: &Bounds,
    ) -> Option<String> {
        if !self.p.enabled {
            return None;
        }
        let in_contact = touch.contact.is_some_and(|c| c.in_contact);
        let gripping = touch.object_detected || in_contact;
        let g = &a.gripper;
        let releasing = g.mode == GripperMode::Stop
            || (g.mode == GripperMode::Position
                && touch
                    .opening_m
                    .is_some_and(|o| g.position_m > o + RELEASE_M));
        if releasing || !gripping {
            self.floor_n = None;
        }
        let (last_force, last_lift) = last.unwrap_or((0.0, 0.0));
        let mut did = Vec::new();
        if let Some(f) = self.floor_n {
            if a.gripper.force_n < f {
                a.gripper.force_n = f;
                did.push(format!("grip force kept at {f:.1} N"));
            }
        }
        let holding = !releasing
            && match a.gripper.mode {
                GripperMode::Force => true,
                GripperMode::Position => touch
                    .opening_m
                    .is_some_and(|o| a.gripper.position_m >= o - HOLD_M),
                GripperMode::Stop => false,
            };
        let lifting = a.arm.lift_m > 0.0 || last_lift > 0.0;
        let slip = touch.slip.filter(|s| s.slip);
        if let (Some(s), true, true) = (slip, gripping, holding || lifting) {
            self.counters.slip_ticks += 1;
            let from = a.gripper.force_n.max(last_force);
            let to = (from + self.p.force_step_n).min(bounds.max_force_n);
            if to > a.gripper.force_n {
                a.gripper.force_n = to;
                self.floor_n = Some(to);
                self.counters.force_raises += 1;
                did.push(format!("grip force {from:.1} -> {to:.1} N"));
            } else {
                did.push(format!(
                    "grip force at its bound {:.1} N",
                    bounds.max_force_n
                ));
            }
            if a.gripper.mode == GripperMode::Position && self.p.squeeze_m > 0.0 {
                if let Some(o) = touch.opening_m {
                    let target = (o - self.p.squeeze_m).max(bounds.min_opening_m);
                    if target < a.gripper.position_m {
                        a.gripper.position_m = target;
                        self.counters.squeezes += 1;
                        did.push(format!("fingers closed to {target:.4} m"));
                    }
                }
            }
            if lifting && a.arm.lift_m > last_lift {
                a.arm.lift_m = last_lift;
                self.counters.lift_stops_slip += 1;
                did.push(format!("lift stopped at {last_lift:.3} m"));
            }
            let what = if lifting { "lifting" } else { "holding" };
            return Some(format!(
                "reflex: slip (score {:.2}) while {what}: {}",
                s.slip_score,
                did.join(", ")
            ));
        }
        // The lift waits for the grip to reach the force the reflex raised it to.
        if let (Some(f), Some(m)) = (self.floor_n, touch.force_n) {
            if m < f - 0.05 * f.max(1.0) && a.arm.lift_m > last_lift {
                a.arm.lift_m = last_lift;
                self.counters.lift_stops_slip += 1;
                did.push(format!(
                    "lift stopped at {last_lift:.3} m until the grip reaches {f:.1} N (now \
                     {m:.1} N)"
                ));
                return Some(format!("reflex: {}", did.join(", ")));
            }
        }
        if self.p.confirm_grasp && a.arm.lift_m > last_lift {
            if let Some(c) = touch.contact {
                let disagree = (touch.object_detected && !c.in_contact)
                    || (!touch.object_detected
                        && c.in_contact
                        && a.gripper.mode == GripperMode::Force);
                if disagree {
                    a.arm.lift_m = last_lift;
                    self.counters.lift_stops_unconfirmed += 1;
                    did.push(format!("lift stopped at {last_lift:.3} m"));
                    return Some(format!(
                        "reflex: grasp not confirmed (gripper object-detect {}, tactile contact \
                         {}): {}",
                        yes(touch.object_detected),
                        yes(c.in_contact),
                        did.join(", ")
                    ));
                }
            }
        }
        (!did.is_empty()).then(|| format!("reflex: {}", did.join(", ")))
    }
}

fn yes(b: bool) -> &'static str {
    if b { "yes" } else { "no" }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use crate::policy::{ArmAction, GripperAction};
    use unitac_core::msg::samples;

    fn lift(mode: GripperMode, position_m: f64) -> Action {
        Action {
            gripper: GripperAction {
                mode,
                position_m,
                speed_m_s: 0.01,
                force_n: 5.0,
            },
            arm: ArmAction {
                target: "cup".into(),
                x_m: 0.45,
                y_m: 0.0,
                z_m: 0.04,
                lift_m: 0.01,
            },
            note: "lifting".into(),
        }
    }

    fn reflex(confirm_grasp: bool) -> Reflex {
        Reflex::new(ReflexParams {
            enabled: true,
            force_step_n: 1.0,
            squeeze_m: 0.0005,
            confirm_grasp,
        })
    }

    fn bounds() -> Bounds {
        crate::PolicyParams::default().bounds()
    }

    #[test]
    fn a_lift_waits_while_object_detect_and_tactile_contact_disagree() {
        let touching = ContactState {
            in_contact: true,
            ..samples::contact_state()
        };
        let free = ContactState {
            in_contact: false,
            ..samples::contact_state()
        };
        let at = |detected, contact| Touch {
            slip: None,
            contact,
            object_detected: detected,
            opening_m: Some(0.07),
            force_n: None,
        };
        let last = Some((5.0, 0.0));
        // The gripper caught something the sensor does not touch.
        let mut r = reflex(true);
        let mut a = lift(GripperMode::Force, 0.0);
        let why = r
            .apply(&mut a, &at(true, Some(&free)), last, &bounds())
            .unwrap();
        assert_eq!(
            why,
            "reflex: grasp not confirmed (gripper object-detect yes, tactile contact no): lift \
             stopped at 0.000 m"
        );
        assert_eq!(a.arm.lift_m, 0.0);
        // Touching, but a force-mode close has not stopped on the object.
        let mut a = lift(GripperMode::Force, 0.0);
        assert!(
            r.apply(&mut a, &at(false, Some(&touching)), last, &bounds())
                .is_some()
        );
        assert_eq!(r.counters().lift_stops_unconfirmed, 2);
        // Both report the object: the lift goes on, nothing said.
        let mut a = lift(GripperMode::Force, 0.0);
        assert_eq!(
            r.apply(&mut a, &at(true, Some(&touching)), last, &bounds()),
            None
        );
        assert_eq!(a.arm.lift_m, 0.01);
        // A position-mode grip at its target reports no object by design: no disagreement.
        let mut a = lift(GripperMode::Position, 0.07);
        assert_eq!(
            r.apply(&mut a, &at(false, Some(&touching)), last, &bounds()),
            None
        );
        // No tactile contact in the scene: nothing to confirm with.
        let mut a = lift(GripperMode::Force, 0.0);
        assert_eq!(r.apply(&mut a, &at(true, None), last, &bounds()), None);
        // Switched off.
        let mut a = lift(GripperMode::Force, 0.0);
        assert_eq!(
            reflex(false).apply(&mut a, &at(true, Some(&free)), last, &bounds()),
            None
        );
        assert_eq!(r.counters().lift_stops_unconfirmed, 2);
    }

    #[test]
    fn slip_raises_the_force_within_the_bounds_and_a_release_ends_the_floor() {
        let slip = SlipState {
            slip: true,
            slip_score: 0.7,
            ..samples::slip_state()
        };
        let touching = ContactState {
            in_contact: true,
            ..samples::contact_state()
        };
        let touch = Touch {
            slip: Some(&slip),
            contact: Some(&touching),
            object_detected: true,
            opening_m: Some(0.07),
            force_n: None,
        };
        let b = bounds();
        let mut r = reflex(true);
        // At the force bound: not raised past it, said so; the lift still stops.
        let mut a = lift(GripperMode::Force, 0.0);
        a.gripper.force_n = b.max_force_n;
        let why = r
            .apply(&mut a, &touch, Some((b.max_force_n, 0.0)), &b)
            .unwrap();
        assert!(why.contains("grip force at its bound"), "{why}");
        assert_eq!(a.gripper.force_n, b.max_force_n);
        assert_eq!(a.arm.lift_m, 0.0);
        // A position-mode hold: the limit rises and the fingers close by the squeeze step.
        let mut a = lift(GripperMode::Position, 0.07);
        a.arm.lift_m = 0.0;
        let why = r.apply(&mut a, &touch, Some((5.0, 0.0)), &b).unwrap();
        assert_eq!(
            why,
            "reflex: slip (score 0.70) while holding: grip force 5.0 -> 6.0 N, fingers closed \
             to 0.0695 m"
        );
        // The raised force is kept while the grasp lasts...
        let calm = Touch {
            slip: None,
            ..touch
        };
        let mut a = lift(GripperMode::Force, 0.0);
        a.gripper.force_n = 2.0;
        a.arm.lift_m = 0.0;
        assert!(r.apply(&mut a, &calm, Some((6.0, 0.0)), &b).is_some());
        assert_eq!(a.gripper.force_n, 6.0);
        // ...and ends when the policy opens the fingers.
        let mut a = lift(GripperMode::Position, 0.085);
        a.gripper.force_n = 2.0;
        a.arm.lift_m = 0.0;
        assert_eq!(r.apply(&mut a, &calm, Some((6.0, 0.0)), &b), None);
        assert_eq!(a.gripper.force_n, 2.0);
    }
}
