//! The fabric task's decision and its folded edge on the gel: the decision is the object of the
//! first grasp attempt (held and raised off the table), never a lift with open fingers or a
//! touch; the rendered press is cut off where the fold's top crosses the gel, so a pinch of one
//! layer and a pinch of two look different.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use unitac_core::SensorKind;
use unitac_sim::task::{
    ArmSetpoint, ArmTarget, FabricOutcome, GRASP_ATTEMPT_LIFT_M, GripperSetpoint, Split,
    TaskCommand, TaskConfig, TaskOutcome, TaskTruth, TaskWorld,
};
use unitac_sim::{FoldEdge, GroundTruth, MockConfig, MockSensor, Object, Scenario};

const DT: f64 = 1.0 / 30.0;

/// A command: the fingers to `opening_m` (opening at full speed, closing at a touch's 20 mm/s)
/// with the force bound `force_n`; the arm at `xy_m`, `z_m`, raised by `lift_m`.
fn cmd(
    opening_m: f64,
    force_n: f64,
    target: &str,
    xy_m: [f64; 2],
    z_m: f64,
    lift_m: f64,
) -> TaskCommand {
    TaskCommand {
        gripper: GripperSetpoint {
            opening_m,
            speed_m_s: if opening_m > 0.0 { 0.1 } else { 0.02 },
            force_n,
        },
        arm: ArmSetpoint {
            target: ArmTarget::named(target),
            xy_m,
            z_m,
            lift_m,
        },
    }
}

fn place(w: &TaskWorld, name: &str) -> [f64; 2] {
    w.spec().object(name).unwrap().placed_m
}

fn outcome(w: &TaskWorld) -> FabricOutcome {
    match w.outcome() {
        TaskOutcome::Fabric(f) => f,
        _ => panic!("not a fabric trial"),
    }
}

/// Go to `name` with open fingers at its single-layer height, close with `force_n` (position
/// target 0, the force as the bound) and hold `hold_s`, raising the arm by `lift_m` once closed;
/// then open again when `release`. The truth at the end.
fn pinch(
    w: &mut TaskWorld,
    name: &str,
    force_n: f64,
    hold_s: f64,
    lift_m: f64,
    release: bool,
) -> TaskTruth {
    let f = w.spec().fabric(name).unwrap().clone();
    let (at, z) = (place(w, name), f.single_layer_z_m());
    let wide = 0.04;
    let mut t = w.truth();
    // Approach with open fingers.
    for _ in 0..(2.0 / DT) as usize {
        t = w.step(&cmd(wide, force_n, name, at, z, 0.0), DT).unwrap();
    }
    assert!(t.arm.arrived, "{:?}", t.arm);
    let mut closed_for = 0.0;
    for _ in 0..((hold_s + 3.0) / DT) as usize {
        let touching = t.gripper.force_n > 0.0;
        if touching {
            closed_for += DT;
        }
        let lift = if closed_for > 0.5 { lift_m } else { 0.0 };
        t = w.step(&cmd(0.0, force_n, name, at, z, lift), DT).unwrap();
        if closed_for >= hold_s {
            break;
        }
    }
    if release {
        for _ in 0..(1.0 / DT) as usize {
            t = w.step(&cmd(wide, force_n, name, at, z, 0.0), DT).unwrap();
        }
    }
    t
}

#[test]
fn a_lift_toward_a_with_open_fingers_then_a_grasp_of_b_chooses_b() {
    let cfg = TaskConfig::fabric(Split::Unseen);
    let mut w = TaskWorld::reset(&cfg, 1, 0);
    // At t = 0 the arm heads for fabric A and lifts a few mm, fingers wide open: what a policy
    // that has not decided anything does on its way.
    let a = place(&w, "fabric_a");
    for _ in 0..(1.5 / DT) as usize {
        w.step(&cmd(0.04, 3.0, "fabric_a", a, 0.02, 0.004), DT)
            .unwrap();
    }
    assert_eq!(w.grasp_attempt(), None);
    // Then it grasps B and lifts it.
    let t = pinch(&mut w, "fabric_b", 15.0, 2.0, 0.06, false);
    assert!(t.objects.iter().any(|o| o.name == "fabric_b" && o.held));
    assert_eq!(w.grasp_attempt(), Some("fabric_b"));
    let o = outcome(&w);
    assert_eq!(
        (o.chosen.as_str(), o.held.as_str()),
        ("fabric_b", "fabric_b")
    );
    assert_eq!(o.selection, o.smoother == "fabric_b");
}

#[test]
fn touches_are_not_grasp_attempts_and_the_grasp_decides_over_an_announcement() {
    let cfg = TaskConfig::fabric(Split::Unseen);
    let mut w = TaskWorld::reset(&cfg, 2, 3);
    // The scripted touches: close on each with the touch force bound, hold 1 s, open.
    for name in ["fabric_a", "fabric_b"] {
        let t = pinch(&mut w, name, 3.0, 1.0, 0.0, true);
        assert_eq!(t.gripper.force_n, 0.0, "{name} let go");
        let touched = t.objects.iter().find(|o| o.name == name).unwrap();
        assert!(touched.touch_s >= 0.9, "{name}: {touched:?}");
        assert!(touched.position_m[2] < GRASP_ATTEMPT_LIFT_M);
    }
    assert_eq!(w.grasp_attempt(), None);
    let o = outcome(&w);
    assert_eq!(o.chosen, "", "two touches decide nothing: {o:?}");
    // An announcement counts while no grasp was attempted...
    let mut announced = w.clone();
    announced.decide("fabric_a");
    assert_eq!(outcome(&announced).chosen, "fabric_a");
    // ...and a grasp of the other one decides over it.
    pinch(&mut announced, "fabric_b", 15.0, 2.0, 0.06, false);
    assert_eq!(announced.grasp_attempt(), Some("fabric_b"));
    assert_eq!(outcome(&announced).chosen, "fabric_b");
    // A grasp that only closes (no lift) is not an attempt yet.
    let mut closed = w.clone();
    pinch(&mut closed, "fabric_a", 15.0, 1.0, 0.0, false);
    assert_eq!(closed.grasp_attempt(), None);
}

/// The first contact row of a frame's truth mask (None: no contact).
fn top_row(g: &GroundTruth, width: usize) -> Option<usize> {
    g.mask.iter().position(|&m| m).map(|p| p / width)
}

#[test]
fn the_gel_sees_the_fold_one_layer_and_two_layers_press_differently() {
    let cfg = TaskConfig::fabric(Split::Unseen);
    let w0 = TaskWorld::reset(&cfg, 3, 1);
    let f = w0.spec().fabric("fabric_a").unwrap().clone();
    assert!(f.layers >= 2);
    let sensor = MockSensor::new(
        MockConfig::new(SensorKind::GELSIGHT_MINI, 4),
        Scenario::idle(1.0),
    );
    let spec = *sensor.spec();
    let (wpx, centre) = (spec.width as usize, f64::from(spec.height) / 2.0);
    // Touch with 3 N at the middle of the top layer and of the second layer.
    let press = |layers_down: f64| {
        let mut w = w0.clone();
        let at = place(&w, "fabric_a");
        let z = (f64::from(f.layers) - layers_down) * f.layer_m;
        let mut t = w.truth();
        for _ in 0..(2.0 / DT) as usize {
            t = w.step(&cmd(0.04, 3.0, "fabric_a", at, z, 0.0), DT).unwrap();
        }
        for _ in 0..(3.0 / DT) as usize {
            t = w.step(&cmd(0.0, 3.0, "fabric_a", at, z, 0.0), DT).unwrap();
        }
        let view = w.sensor_view();
        let fold = view.object.as_ref().and_then(|o| o.fold).unwrap();
        let (frame, g) = view.render(&sensor, 5);
        let (frame2, _) = view.render(&sensor, 5);
        assert_eq!(frame.data(), frame2.data(), "deterministic");
        (t, fold, g)
    };
    let (one, fold1, g1) = press(0.5);
    let (two, fold2, g2) = press(1.5);
    assert_eq!((one.contact.layers, two.contact.layers), (1, 2));
    // The fold's top is half a layer and one and a half layers above the contact centre.
    assert!(
        (fold1.edge_mm - 0.5 * f.layer_m * 1e3).abs() < 1e-9,
        "{fold1:?}"
    );
    assert!(
        (fold2.edge_mm - 1.5 * f.layer_m * 1e3).abs() < 1e-9,
        "{fold2:?}"
    );
    // The contact stops at the fold's top (a rounded rim: at most half a layer lower), higher on
    // the gel for two layers, and covers more of it.
    let px_per_mm = 1.0 / spec.mm_per_px;
    for (fold, g) in [(fold1, &g1), (fold2, &g2)] {
        let top = top_row(g, wpx).unwrap() as f64;
        let edge_row = centre - fold.edge_mm * px_per_mm;
        assert!(top >= edge_row - 1.0, "{top} above the fold at {edge_row}");
        assert!(
            top <= edge_row + 0.5 * f.layer_m * 1e3 * px_per_mm + 1.0,
            "{top} vs {edge_row}"
        );
    }
    assert!(top_row(&g2, wpx) < top_row(&g1, wpx));
    assert!(
        g2.contact_px > g1.contact_px,
        "{} vs {}",
        g2.contact_px,
        g1.contact_px
    );
    // Without the fold the same press is the whole disc.
    let obj = Object::new("f", 6.0, 0.03, 0.7).with_hardness(0.8);
    let (_, whole) = sensor.render_press(5, Some((&obj, 0.6)), 0.0, 0.0);
    let cut = obj.clone().with_fold(FoldEdge {
        edge_mm: 0.3,
        layer_mm: 0.7,
    });
    let (_, g_cut) = sensor.render_press(5, Some((&cut, 0.6)), 0.0, 0.0);
    assert!(g_cut.contact_px < whole.contact_px);
    assert!(top_row(&g_cut, wpx) > top_row(&whole, wpx));
}
