//! The transport-facing watchdog API of the policy stage: a control tick on the transport's timer
//! when no GripperStatus comes (`watchdog_tick`), and producers a transport saw disappear
//! (`set_input_lost`). Clock injected: every time here is a stamp.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod rig;
use rig::{Rig, TICK_NS, params};
use unitac_core::msg::{GripperMode, GripperStatus, Header, LatentSource, Msg, PolicyStatus};
use unitac_core::{ManualClock, Stage, Stamp};
use unitac_policy::PolicyStage;

fn status(t: i64, opening: f64) -> Msg {
    Msg::GripperStatus(GripperStatus {
        header: Header::new(Stamp(t), "gripper"),
        opening_m: opening,
        target_m: f64::NAN,
        force_n: 0.0,
        current_a: f64::NAN,
        object_detected: false,
        activation: "active".into(),
        motion: "stopped".into(),
        fault: String::new(),
    })
}

fn policy_status(out: &[Msg]) -> &PolicyStatus {
    out.iter()
        .find_map(|m| match m {
            Msg::PolicyStatus(s) => Some(s),
            _ => None,
        })
        .expect("a PolicyStatus")
}

fn cup_stage(mode: &str) -> PolicyStage {
    let p = params(&format!(
        "{{mode: {mode}, task: squeeze the cup, objects: [cup], latent_len: 4, \
         visual_names: [cup_x_m, cup_y_m, cup_width_m]}}"
    ));
    PolicyStage::new("test_scene", p).unwrap()
}

/// The camera's frame at `t` (an 80 mm cup), then the gripper's status: one tick's inputs.
fn step(
    s: &mut PolicyStage,
    t: i64,
    opening: f64,
    clock: &ManualClock,
) -> Result<Vec<Msg>, unitac_core::StageError> {
    let cam = Msg::VisualObservation(unitac_core::msg::VisualObservation {
        header: unitac_core::msg::Header::new(Stamp(t), "camera"),
        names: vec!["cup_x_m".into(), "cup_y_m".into(), "cup_width_m".into()],
        values: vec![0.45, 0.0, 0.08],
    });
    s.process(&cam, clock)?;
    s.process(&status(t, opening), clock)
}

#[test]
fn a_missing_gripper_status_gives_the_safe_action_a_period_after_its_tick_was_due() {
    let mut s = cup_stage("vtla_real");
    let clock = ManualClock::new(Stamp(0));
    let t0 = 1_000_000_000;
    // Nothing known before the first status: the watchdog stays silent.
    assert!(s.watchdog_tick(Stamp(t0)).is_empty());
    clock.set(Stamp(t0));
    assert_eq!(step(&mut s, t0, 0.07, &clock).unwrap().len(), 3);
    // The next tick is due at t0 + P; the watchdog waits until it is a period overdue.
    let p = TICK_NS;
    assert!(s.watchdog_tick(Stamp(t0 + p)).is_empty());
    assert!(s.watchdog_tick(Stamp(t0 + 2 * p - 1)).is_empty());
    let out = s.watchdog_tick(Stamp(t0 + 2 * p));
    let [
        Msg::GripperCommand(c),
        Msg::ArmCommand(a),
        Msg::PolicyStatus(st),
    ] = out.as_slice()
    else {
        panic!("{out:?}");
    };
    assert!(!st.safety_ok);
    assert_eq!(st.header.stamp, Stamp(t0 + 2 * p));
    assert_eq!(st.header.frame_id, "gripper");
    assert!(
        st.message.starts_with("gripper: no status for 0.067 s"),
        "{}",
        st.message
    );
    assert_eq!(c.reason, st.message);
    assert_eq!(a.reason, st.message);
    // Hold: position mode at the last measured opening.
    assert_eq!(c.mode, GripperMode::Position);
    assert_eq!(c.position_m, 0.07);
    // Once per period while nothing comes, on the schedule.
    assert!(s.watchdog_tick(Stamp(t0 + 3 * p - 1)).is_empty());
    assert_eq!(s.watchdog_tick(Stamp(t0 + 3 * p)).len(), 3);
    // A status back on the schedule ticks normally again.
    clock.set(Stamp(t0 + 4 * p));
    let out = step(&mut s, t0 + 4 * p, 0.07, &clock).unwrap();
    assert_eq!(out.len(), 3);
    assert_eq!(policy_status(&out).header.stamp, Stamp(t0 + 4 * p));
}

#[test]
fn a_lost_producer_holds_in_the_phases_that_await_it_and_only_those() {
    let mut s = cup_stage("vtla_real");
    assert_eq!(s.inputs(), ["gripper", "contact", "latent_real", "visual"]);
    assert!(
        s.set_input_lost("latent_pred", Some("gone".into()))
            .unwrap_err()
            .to_string()
            .contains("not an input of this mode")
    );
    // Approaching: the latent of the probe touch is awaited, so its producer must be alive.
    assert!(s.awaited_inputs().contains(&"latent_real"));
    let clock = ManualClock::new(Stamp(0));
    let mut t = 1_000_000_000;
    clock.set(Stamp(t));
    let out = step(&mut s, t, 0.09, &clock).unwrap();
    assert!(policy_status(&out).safety_ok);
    s.set_input_lost(
        "latent_real",
        Some("no publisher on /x/tactile_latent".into()),
    )
    .unwrap();
    t += TICK_NS;
    clock.set(Stamp(t));
    let out = step(&mut s, t, 0.09, &clock).unwrap();
    let st = policy_status(&out);
    assert!(!st.safety_ok);
    assert_eq!(st.message, "latent_real: no publisher on /x/tactile_latent");
    assert_eq!(st.phase, "approach");
    // Back: the next tick acts again.
    s.set_input_lost("latent_real", None).unwrap();
    t += TICK_NS;
    clock.set(Stamp(t));
    assert!(policy_status(&step(&mut s, t, 0.09, &clock).unwrap()).safety_ok);
}

#[test]
fn once_the_latent_is_used_its_producer_may_go() {
    // The cup's vtla_real run of the controller tests, on the stage itself: after the squeeze
    // force is set, the encoder is no longer awaited and losing it changes nothing, while the
    // contact producer, required in the squeeze, still is.
    let mut s = cup_stage("vtla_real");
    let rig = Rig::new(params(
        "{mode: vtla_real, task: squeeze the cup, objects: [cup], latent_len: 4, \
         visual_names: [cup_x_m, cup_y_m, cup_width_m]}",
    ));
    let clock = ManualClock::new(Stamp(0));
    let (diameter, mut opening, mut t) = (0.08, 0.085, rig.now);
    let mut sent = false;
    let mut last = None;
    for _ in 0..1200 {
        let touching = opening <= diameter;
        let area = if touching {
            20e-6 + 1e-3 * (diameter - opening) as f32
        } else {
            0.0
        };
        let mut c = rig.contact(touching, area);
        if let Msg::ContactState(c) = &mut c {
            c.header.stamp = Stamp(t);
        }
        clock.set(Stamp(t));
        s.process(&c, &clock).unwrap();
        if last.as_deref() == Some("await_latent") && !sent {
            sent = true;
            let mut l = rig.latent(LatentSource::Real, vec![0.1, 0.2, 0.3, 0.4]);
            if let Msg::TactileLatent(l) = &mut l {
                l.header.stamp = Stamp(t);
            }
            s.process(&l, &clock).unwrap();
        }
        let out = step(&mut s, t, opening, &clock).unwrap();
        let Msg::GripperCommand(cmd) = &out[0] else {
            panic!("{out:?}")
        };
        let step = cmd.speed_m_s * TICK_NS as f64 * 1e-9;
        opening += (cmd.position_m - opening).clamp(-step, step);
        let st = policy_status(&out);
        assert!(st.safety_ok, "{st:?}");
        last = Some(st.phase.clone());
        t += TICK_NS;
        if st.phase == "squeeze" {
            break;
        }
    }
    assert_eq!(last.as_deref(), Some("squeeze"));
    assert!(!s.awaited_inputs().contains(&"latent_real"));
    s.set_input_lost("latent_real", Some("no publisher".into()))
        .unwrap();
    clock.set(Stamp(t));
    let st = policy_status(&step(&mut s, t, opening, &clock).unwrap()).clone();
    assert!(st.safety_ok, "{st:?}");
    s.set_input_lost("contact", Some("no publisher on contact_state".into()))
        .unwrap();
    t += TICK_NS;
    clock.set(Stamp(t));
    let st = policy_status(&step(&mut s, t, opening, &clock).unwrap()).clone();
    assert!(!st.safety_ok);
    assert!(
        st.message
            .contains("contact: no publisher on contact_state"),
        "{}",
        st.message
    );
}
