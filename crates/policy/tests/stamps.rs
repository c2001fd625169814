//! Stamps from the future: an input stamped ahead of the stage's present is an invalid input
//! (`stamp ahead by ...`), never the clock. Driven through `unitac_core::chain`, whose clock is
//! the latest stamp seen and never moves back, as every transport drives the stage.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod rig;

use rig::*;
use unitac_core::msg::{
    GripperStatus, Header, LatentSource, Msg, PropertyComparison, VisualObservation,
};
use unitac_core::{ManualClock, Stage, Stamp};
use unitac_policy::PolicyStage;

const CUP_VTLA_PRED: &str = "{mode: vtla_pred, task: squeeze the cup by 1 cm, objects: [cup], \
    latent_len: 4, visual_names: [cup_x_m, cup_y_m, cup_width_m]}";

fn status_at(rig: &Rig, t: i64) -> Msg {
    Msg::GripperStatus(GripperStatus {
        header: Header::new(Stamp(t), "gripper"),
        opening_m: rig.opening,
        target_m: f64::NAN,
        force_n: rig.force_n,
        current_a: f64::NAN,
        object_detected: rig.object_detected,
        activation: "active".into(),
        motion: rig.motion.clone(),
        fault: String::new(),
    })
}

/// The cup vtla_pred run until the controller is squeezing (phase close, force mode).
fn squeezing() -> Rig {
    let mut rig = Rig::new(params(CUP_VTLA_PRED)).with_cup_camera();
    let l = rig.latent(LatentSource::Predicted, vec![0.5; 4]);
    rig.send(l);
    let mut t = rig.tick();
    for _ in 0..200 {
        rig.follow(&t.cmd, Some(0.079));
        rig.object_detected = rig.opening <= 0.08;
        rig.force_n = (500.0 * (0.08 - rig.opening)).max(0.0);
        t = rig.tick();
        if t.status.phase == "close" {
            return rig;
        }
    }
    panic!("never reached close: {:?}", rig.phases());
}

#[test]
fn a_gripper_status_from_the_future_is_an_invalid_input_not_the_clock() {
    let mut rig = squeezing();
    let before = rig.ticks.len();
    let last_stamp = rig.ticks.last().unwrap().stamp;
    // One status stamped 1000 s ahead, between two ticks of the schedule.
    let hostile = status_at(&rig, rig.now - TICK_NS / 2 + 1_000_000_000_000);
    let out = rig.chain.run(hostile);
    assert!(out.errors.is_empty(), "{:?}", out.errors);
    let [
        Msg::GripperCommand(c),
        Msg::ArmCommand(_),
        Msg::PolicyStatus(st),
    ] = out.produced.as_slice()
    else {
        panic!("the hostile status is answered with the safe action: {out:?}");
    };
    assert!(!st.safety_ok);
    assert!(
        st.message
            .starts_with("gripper: invalid (stamp ahead by 1000.0"),
        "{}",
        st.message
    );
    assert!(c.position_m.is_finite());
    // Its answer is stamped at the stage's present, not in the future.
    assert!(st.header.stamp <= last_stamp, "{:?}", st.header.stamp);
    // Every later status of the schedule is answered, and the squeeze goes on.
    for _ in 0..10 {
        let t = rig.tick();
        assert!(t.status.safety_ok, "{:?}", t.status);
    }
    assert_eq!(rig.ticks.len(), before + 10);
}

#[test]
fn the_watchdog_still_ticks_after_a_gripper_status_from_the_future() {
    let p = params(CUP_VTLA_PRED);
    let mut s = PolicyStage::new("test_scene", p).unwrap();
    let t0 = 1_000_000_000;
    // The clock as the chain keeps it: the latest stamp seen.
    let clock = ManualClock::new(Stamp(t0));
    let rig = Rig::new(params(CUP_VTLA_PRED)).with_cup_camera();
    assert_eq!(s.process(&status_at(&rig, t0), &clock).unwrap().len(), 3);
    let future = t0 + 1_000_000_000_000;
    clock.set(Stamp(future));
    s.process(&status_at(&rig, future), &clock).unwrap();
    // Nothing else comes: the watchdog on the transport's clock sends the safe action once the
    // tick due at t0 + P is a period overdue.
    let out = s.watchdog_tick(Stamp(t0 + 2 * TICK_NS));
    let Some(Msg::PolicyStatus(st)) = out.last() else {
        panic!("the watchdog is silent after a status from the future: {out:?}");
    };
    assert!(!st.safety_ok);
    assert!(
        st.message.starts_with("gripper: no status"),
        "{}",
        st.message
    );
}

#[test]
fn a_latent_or_contact_from_the_future_leaves_every_tick_answered() {
    let mut rig = Rig::new(params(
        "{mode: vtla_real, task: squeeze the cup, objects: [cup], latent_len: 4}",
    ));
    rig.tick();
    let mut l = rig.latent(LatentSource::Real, vec![0.5; 4]);
    if let Msg::TactileLatent(x) = &mut l {
        x.header.stamp = Stamp(rig.now + 10_000_000_000);
    }
    rig.send(l);
    // Rig::tick panics unless the stage answers with its three messages.
    for _ in 0..5 {
        rig.tick();
    }
    let mut c = rig.contact(true, 20e-6);
    if let Msg::ContactState(x) = &mut c {
        x.header.stamp = Stamp(rig.now + 5_000_000_000);
    }
    rig.send(c);
    for _ in 0..5 {
        rig.tick();
    }
}

#[test]
fn an_input_from_the_future_is_invalid_with_the_reason() {
    // The cup vla approach reads the camera; its frame stamped 5 s ahead.
    let mut rig = Rig::new(params(
        "{mode: vla, task: squeeze the cup, objects: [cup], visual_names: [cup_width_m]}",
    ));
    let v = Msg::VisualObservation(VisualObservation {
        header: Header::new(Stamp(rig.now + 5_000_000_000), "camera"),
        names: vec!["cup_width_m".into()],
        values: vec![0.08],
    });
    rig.send(v);
    let t = rig.tick();
    assert!(!t.status.safety_ok);
    assert!(
        t.status
            .message
            .contains("visual: invalid (stamp ahead by 5.000 s"),
        "{}",
        t.status.message
    );
}

#[test]
fn a_comparison_stamped_at_the_end_of_time_neither_panics_nor_freezes_control() {
    let mut rig = Rig::new(params(
        "{mode: vtla_real, task: pick the smoother fabric, \
         visual_names: [fabric_a_edge_height_m, fabric_b_edge_height_m]}",
    ));
    rig.tick();
    rig.send(Msg::PropertyComparison(PropertyComparison {
        header: Header::new(Stamp(i64::MAX), "x"),
        ..unitac_core::msg::samples::property_comparison()
    }));
    for _ in 0..5 {
        rig.tick();
    }
    rig.send(Msg::PropertyComparison(PropertyComparison {
        header: Header::new(Stamp(i64::MIN), "x"),
        ..unitac_core::msg::samples::property_comparison()
    }));
    for _ in 0..5 {
        rig.tick();
    }
}

#[test]
fn a_gripper_back_after_a_long_silence_ticks_again_from_its_third_status() {
    // No watchdog runs (the embedded chain): the present stays at the last tick, so the first
    // statuses after 5 s of silence are ahead of it; three in a row, a period apart, are the
    // gripper's time line again.
    let mut rig = squeezing();
    rig.now += 5_000_000_000;
    for i in 0..3 {
        let g = status_at(&rig, rig.now);
        let out = rig.chain.run(g);
        let Some(Msg::PolicyStatus(st)) = out.produced.last() else {
            panic!("status {i} after the silence is answered: {out:?}");
        };
        if i < 2 {
            assert!(
                st.message.contains("stamp ahead by 5.0"),
                "{i}: {}",
                st.message
            );
        } else {
            assert_eq!(st.header.stamp, Stamp(rig.now), "{st:?}");
        }
        rig.now += TICK_NS;
    }
    let t = rig.tick();
    assert_eq!(t.status.header.stamp, t.stamp);
}

#[test]
fn a_wrong_first_stamp_is_left_after_three_statuses_on_the_real_time_line() {
    // Nothing is known before the first status, so a first one stamped 1000 s ahead is taken
    // for the time line; the gripper's own statuses, a period apart, take it back.
    let mut rig = Rig::new(params(CUP_VTLA_PRED)).with_cup_camera();
    let out = rig.chain.run(status_at(&rig, rig.now + 1_000_000_000_000));
    assert_eq!(out.produced.len(), 3);
    for i in 0..2 {
        let out = rig.chain.run(status_at(&rig, rig.now));
        assert!(out.produced.is_empty(), "{i}: {out:?}");
        rig.now += TICK_NS;
    }
    // The third ticks on its own stamp, and the schedule goes on from it.
    for _ in 0..5 {
        let t = rig.tick();
        assert_eq!(t.status.header.stamp, t.stamp);
    }
}

#[test]
fn after_a_message_stamped_at_the_end_of_time_the_policy_acts_normally() {
    // Through the chain, whose clock the message takes to i64::MAX: the ticks keep their own
    // stamps and the camera-fed approach acts (before, every later tick ran at the end of time
    // and saw every input stale: the safe action forever, or an overflow in a debug build).
    let mut rig = Rig::new(params(
        "{mode: vla, task: squeeze the cup, objects: [cup], \
         visual_names: [cup_x_m, cup_y_m, cup_width_m]}",
    ));
    let camera = |rig: &Rig| {
        Msg::VisualObservation(VisualObservation {
            header: rig.header(),
            names: vec!["cup_x_m".into(), "cup_y_m".into(), "cup_width_m".into()],
            values: vec![0.45, 0.0, 0.08],
        })
    };
    for i in 0..10 {
        if i == 3 {
            rig.send(Msg::PropertyComparison(PropertyComparison {
                header: Header::new(Stamp(i64::MAX), "x"),
                ..unitac_core::msg::samples::property_comparison()
            }));
        }
        let c = camera(&rig);
        rig.send(c);
        let t = rig.tick();
        assert!(t.status.safety_ok, "tick {i}: {:?}", t.status);
        assert_eq!(t.status.header.stamp, t.stamp);
    }
}
