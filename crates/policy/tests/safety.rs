//! Property tests of the safety layer: for arbitrary policy outputs (NaN, inf, huge, sign
//! flipping each tick) every command stays within its bounds and rate limits; stale or invalid
//! inputs and a failing policy give the safe action in the same tick, with the reason in
//! PolicyStatus.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use proptest::prelude::*;
use unitac_core::msg::{
    ContactState, GripperMode, GripperStatus, Header, LatentSource, Msg, TactileLatent, samples,
};
use unitac_core::{Chain, Stamp};
use unitac_policy::observation::Observation;
use unitac_policy::safety::{Bounds, Refusal, SafeAction, SafetyLayer};
use unitac_policy::{Action, ArmAction, GripperAction, Policy, PolicyError, PolicyParams};

fn bounds() -> Bounds {
    PolicyParams {
        limits: Bounds {
            objects: vec!["cup".into()],
            ..Bounds::default()
        },
        ..PolicyParams::default()
    }
    .bounds()
}

fn number() -> impl Strategy<Value = f64> {
    prop_oneof![
        Just(f64::NAN),
        Just(f64::INFINITY),
        Just(f64::NEG_INFINITY),
        Just(f64::MAX),
        Just(-f64::MAX),
        -1e300..1e300f64,
        -1.0..1.0f64,
        -0.1..0.2f64,
    ]
}

fn mode() -> impl Strategy<Value = GripperMode> {
    prop_oneof![
        Just(GripperMode::Position),
        Just(GripperMode::Force),
        Just(GripperMode::Stop)
    ]
}

fn action() -> impl Strategy<Value = Action> {
    (
        mode(),
        [number(), number(), number(), number(), number()],
        prop_oneof![Just("cup"), Just("home"), Just("table")],
    )
        .prop_map(|(mode, v, target)| Action {
            gripper: GripperAction {
                mode,
                position_m: v[0],
                speed_m_s: v[1],
                force_n: v[2],
            },
            arm: ArmAction {
                target: target.into(),
                x_m: 0.45,
                y_m: 0.0,
                z_m: v[3],
                lift_m: v[4],
            },
            note: "p".into(),
        })
}

fn negate(mut a: Action) -> Action {
    a.gripper.position_m = -a.gripper.position_m;
    a.gripper.force_n = -a.gripper.force_n;
    a.arm.lift_m = -a.arm.lift_m;
    a
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    #[test]
    fn any_policy_output_stays_within_bounds_and_rate_limits(
        steps in prop::collection::vec((action(), any::<bool>(), 0.0..0.085f64), 1..60),
        flip in any::<bool>(),
        safe in prop_oneof![Just(SafeAction::Hold), Just(SafeAction::Open)],
    ) {
        let b = bounds();
        let mut s = SafetyLayer::new(b.clone(), safe, 5.0);
        let mut prev: Option<(f64, f64, f64)> = None;
        for (i, (a, fail, opening)) in steps.into_iter().enumerate() {
            let a = if flip && i % 2 == 1 { negate(a) } else { a };
            let non_finite = a.values().iter().any(|(_, v)| !v.is_finite());
            let bad_target = a.arm.target == "table";
            let proposed = if fail {
                Err(Refusal::Policy(PolicyError::Failed("crashed".into())))
            } else {
                Ok(a)
            };
            let d = s.decide(proposed, Some(opening));
            let g = &d.gripper;
            for v in [g.position_m, g.speed_m_s, g.force_n, d.arm.z_m, d.arm.lift_m] {
                prop_assert!(v.is_finite());
            }
            prop_assert!((b.min_opening_m..=b.max_opening_m).contains(&g.position_m));
            prop_assert!((0.0..=b.max_speed_m_s).contains(&g.speed_m_s));
            prop_assert!((0.0..=b.max_force_n).contains(&g.force_n));
            prop_assert!((b.min_z_m..=b.max_z_m).contains(&d.arm.z_m));
            prop_assert!((0.0..=b.max_lift_m).contains(&d.arm.lift_m));
            prop_assert!(d.arm.target == "home" || d.arm.target == "cup");
            prop_assert_eq!(d.ok, !(fail || non_finite || bad_target));
            if d.ok {
                let (p0, f0, l0) = prev.unwrap_or((opening, 0.0, 0.0));
                prop_assert!((g.position_m - p0).abs() <= b.max_step_m + 1e-12);
                prop_assert!((g.force_n - f0).abs() <= b.max_force_step_n + 1e-12);
                prop_assert!((d.arm.lift_m - l0).abs() <= b.max_lift_step_m + 1e-12);
            } else {
                // The safe action, at once.
                let want = match safe {
                    SafeAction::Hold => opening,
                    SafeAction::Open => b.max_opening_m,
                };
                prop_assert_eq!(g.mode, GripperMode::Position);
                prop_assert_eq!(g.position_m, want);
                prop_assert_eq!(g.force_n, 5.0);
                if fail {
                    prop_assert_eq!(&d.reason, "policy: crashed");
                } else if non_finite {
                    prop_assert!(d.reason.starts_with("policy output not finite"), "{}", d.reason);
                } else {
                    prop_assert!(d.reason.contains("'table'"), "{}", d.reason);
                }
            }
            prev = Some((g.position_m, g.force_n, d.arm.lift_m));
        }
    }
}

/// A policy that plays a script: per tick an action or a failure; it needs gripper, contact and
/// the live latent at every tick.
#[derive(Debug)]
struct Scripted {
    script: Vec<Result<Action, PolicyError>>,
    i: usize,
}

impl Policy for Scripted {
    fn phase(&self) -> &str {
        "scripted"
    }
    fn required(&self) -> Vec<&'static str> {
        vec!["gripper", "contact", "latent_real"]
    }
    fn act(&mut self, _: &Observation) -> Result<Vec<Action>, PolicyError> {
        let r = self
            .script
            .get(self.i)
            .cloned()
            .unwrap_or(Err(PolicyError::Failed("end".into())));
        self.i += 1;
        r.map(|a| vec![a])
    }
}

/// What the test sends before a tick.
#[derive(Debug, Clone)]
struct Inputs {
    contact: bool,
    /// None: no latent this tick; Some(0): valid; 1: valid = false; 2: a NaN value.
    latent: Option<u8>,
    policy_fails: bool,
}

fn inputs() -> impl Strategy<Value = Inputs> {
    (
        prop::bool::weighted(0.7),
        prop::option::weighted(0.3, 0u8..3),
        prop::bool::weighted(0.1),
    )
        .prop_map(|(contact, latent, policy_fails)| Inputs {
            contact,
            latent,
            policy_fails,
        })
}

fn good_action() -> Action {
    Action {
        gripper: GripperAction {
            mode: GripperMode::Position,
            position_m: 0.04,
            speed_m_s: 0.01,
            force_n: 3.0,
        },
        arm: ArmAction {
            target: "cup".into(),
            x_m: 0.45,
            y_m: 0.0,
            z_m: 0.04,
            lift_m: 0.0,
        },
        note: "ok".into(),
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    #[test]
    fn stale_invalid_inputs_and_a_failing_policy_hold_in_the_same_tick(
        seq in prop::collection::vec(inputs(), 1..80),
    ) {
        let p = PolicyParams {
            mode: unitac_policy::Mode::VtlaReal,
            task: "squeeze the cup".into(),
            limits: Bounds {
                objects: vec!["cup".into()],
                ..Bounds::default()
            },
            latent_len: 2,
            ..PolicyParams::default()
        };
        let script = seq
            .iter()
            .map(|s| {
                if s.policy_fails {
                    Err(PolicyError::Failed("crashed".into()))
                } else {
                    Ok(good_action())
                }
            })
            .collect();
        let stage = unitac_policy::PolicyStage::with_policy(
            "s",
            p.clone(),
            Box::new(Scripted { script, i: 0 }),
        )
        .unwrap();
        let mut chain = Chain::new(vec![Box::new(stage)]);
        let tick_ns = 33_333_333i64;
        let (mut last_contact, mut latent_ok): (Option<i64>, Option<bool>) = (None, None);
        let mut calls = 0usize;
        for (i, s) in seq.iter().enumerate() {
            let now = 1_000_000_000 + i as i64 * tick_ns;
            let h = Header::new(Stamp(now), "g");
            if s.contact {
                chain.run(Msg::ContactState(ContactState { header: h.clone(), ..samples::contact_state() }));
                last_contact = Some(now);
            }
            if let Some(kind) = s.latent {
                let mut l = TactileLatent {
                    header: h.clone(),
                    source: LatentSource::Real,
                    shape: vec![2],
                    data: vec![0.25, -0.5],
                    valid: kind != 1,
                    ..samples::tactile_latent()
                };
                if kind == 2 {
                    l.data[1] = f32::NAN;
                }
                chain.run(Msg::TactileLatent(l));
                latent_ok = Some(kind == 0);
            }
            let out = chain.run(Msg::GripperStatus(GripperStatus {
                header: h,
                fault: String::new(),
                opening_m: 0.05,
                ..samples::gripper_status()
            }));
            let [Msg::GripperCommand(cmd), Msg::ArmCommand(_), Msg::PolicyStatus(st)] = out.produced.as_slice() else {
                panic!("{:?}", out.produced);
            };
            // What the test knows independently of the stage.
            let contact_fresh = last_contact
                .is_some_and(|t| Stamp(now).secs_since(Stamp(t)) <= p.budget_contact_s);
            let inputs_ok = contact_fresh && latent_ok == Some(true);
            let policy_ok = if inputs_ok {
                calls += 1;
                !seq[calls - 1].policy_fails
            } else {
                false
            };
            prop_assert_eq!(st.safety_ok, policy_ok, "tick {}: {}", i, st.message);
            prop_assert!(cmd.position_m.is_finite() && cmd.force_n.is_finite());
            if !policy_ok {
                prop_assert_eq!(cmd.mode, GripperMode::Position);
                prop_assert_eq!(cmd.position_m, 0.05);
                prop_assert_eq!(cmd.force_n, p.hold_force_n);
                let why = if !contact_fresh {
                    "contact:"
                } else if latent_ok != Some(true) {
                    "latent_real:"
                } else {
                    "policy: crashed"
                };
                prop_assert!(st.message.contains(why), "tick {}: {}", i, st.message);
            }
        }
    }
}

#[test]
fn the_first_command_is_within_bounds_when_the_fingers_are_wider_than_the_scene_allows() {
    // A 2F-140 open at 132 mm under a scene bounded at 85 mm: the first command is rate
    // limited from the measured opening, and still inside the bounds.
    let b = bounds();
    let mut s = SafetyLayer::new(b.clone(), SafeAction::Hold, 5.0);
    let a = Action {
        gripper: GripperAction {
            mode: GripperMode::Position,
            position_m: 0.05,
            speed_m_s: 0.05,
            force_n: 10.0,
        },
        arm: ArmAction {
            target: "cup".into(),
            x_m: 0.45,
            y_m: 0.0,
            z_m: 0.05,
            lift_m: 0.0,
        },
        note: "p".into(),
    };
    let d = s.decide(Ok(a), Some(0.1325));
    assert!(d.ok);
    assert_eq!(d.gripper.position_m, b.max_opening_m);
}
