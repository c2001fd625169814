//! Fabric VTLA-real's touch strategy: each touch reads where the fold's top crosses the gel from
//! the contact state, and the grasp goes `grasp_z_m` below the top so felt; a touch that closed
//! on nothing is tried again lower; vla keeps the camera's height.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod rig;

use rig::*;
use unitac_core::msg::{ContactState, GripperMode, Msg, VisualObservation, samples};
use unitac_policy::controller::fabric::fold_above_centre_m;

/// GelSight Mini's mm per pixel at 320 x 240.
const MM_PER_PX: f64 = 18.6 / 320.0;
const EDGE_A_M: f64 = 0.0030;
const EDGE_B_M: f64 = 0.0024;

fn params_for(mode: &str) -> unitac_policy::PolicyParams {
    params(&format!(
        "{{mode: {mode}, task: pick the smoother fabric, max_opening_m: 0.04, \
         visual_names: [fabric_a_x_m, fabric_a_y_m, fabric_a_edge_height_m, \
         fabric_b_x_m, fabric_b_y_m, fabric_b_edge_height_m, \
         fabric_a_roughness, fabric_b_roughness]}}"
    ))
}

/// A contact state of a 320 x 240 image with this box (its area the box's, in m^2 by the
/// GelSight Mini's scale).
fn state(in_contact: bool, bbox_px: [u32; 4]) -> ContactState {
    let [x0, y0, x1, y1] = bbox_px;
    let area_px = (x1.saturating_sub(x0) * y1.saturating_sub(y0)) as f32;
    ContactState {
        in_contact,
        bbox_px,
        area_px,
        area_m2: (f64::from(area_px) * (MM_PER_PX * 1e-3).powi(2)) as f32,
        ..samples::contact_state()
    }
}

#[test]
fn the_fold_is_read_from_the_top_of_the_contact_against_the_centre_row() {
    // A disc about (160, 120) cut 20 px above the centre: the fold 20 px = 1.16 mm above.
    let cut = fold_above_centre_m(&state(true, [120, 100, 200, 160])).unwrap();
    assert!((cut - 20.0 * MM_PER_PX * 1e-3).abs() < 1e-9, "{cut}");
    // Its bottom does not matter (the rim fades with the depth of the press).
    let shallower = fold_above_centre_m(&state(true, [120, 100, 200, 150])).unwrap();
    assert!((shallower - cut).abs() < 1e-9);
    // Cut below the centre: negative.
    let below = fold_above_centre_m(&state(true, [120, 126, 200, 160])).unwrap();
    assert!(below < 0.0);
    // The whole disc (as far above as below the centre): the fold is not seen.
    assert_eq!(fold_above_centre_m(&state(true, [130, 90, 190, 150])), None);
    // No contact, a box of a few pixels, no scale: nothing.
    assert_eq!(
        fold_above_centre_m(&state(false, [120, 100, 200, 160])),
        None
    );
    assert_eq!(
        fold_above_centre_m(&state(true, [158, 100, 162, 140])),
        None
    );
    let mut unscaled = state(true, [120, 100, 200, 160]);
    unscaled.area_m2 = 0.0;
    assert_eq!(fold_above_centre_m(&unscaled), None);
}

fn camera(rig: &Rig) -> Msg {
    Msg::VisualObservation(VisualObservation {
        header: rig.header(),
        names: [
            "fabric_a_x_m",
            "fabric_a_y_m",
            "fabric_a_edge_height_m",
            "fabric_b_x_m",
            "fabric_b_y_m",
            "fabric_b_edge_height_m",
            "fabric_a_roughness",
            "fabric_b_roughness",
        ]
        .map(String::from)
        .to_vec(),
        values: vec![0.45, 0.12, EDGE_A_M, 0.45, -0.12, EDGE_B_M, 2e-5, 1e-5],
    })
}

/// A fabric run: the camera before every tick; on a fabric the fingers meet it at 1 cm and the
/// contact state shows `bbox(target, touch)` (touch counts the presses of that fabric, from 0;
/// None: the fingers close on nothing); B is the smoother (the comparison says A is rougher);
/// the grasp stops on the fabric at 1 cm.
fn run(rig: &mut Rig, bbox: impl Fn(&str, usize) -> Option<[u32; 4]>) {
    let mut sent = false;
    let mut presses = [0usize; 2];
    let mut pressing = String::new();
    let first = camera(rig);
    rig.send(first);
    let mut last = rig.tick();
    for _ in 1..6000 {
        let target = last.arm.target.clone();
        let grasping = last.cmd.mode == GripperMode::Force;
        let k = usize::from(target == "fabric_b");
        if last.status.phase.starts_with("press") && pressing != last.status.phase {
            pressing = last.status.phase.clone();
        } else if !last.status.phase.starts_with("press") && !pressing.is_empty() {
            presses[usize::from(pressing == "press_b")] += 1;
            pressing.clear();
        }
        let shown = target
            .starts_with("fabric")
            .then(|| bbox(&target, presses[k]))
            .flatten();
        let stop = (grasping || shown.is_some()).then_some(0.01);
        rig.follow(&last.cmd, stop);
        rig.object_detected = grasping && rig.opening <= 0.01 + 1e-9;
        rig.force_n = if rig.object_detected {
            last.cmd.force_n
        } else {
            0.0
        };
        let touching = shown.is_some() && rig.opening <= 0.01 + 1e-9;
        let mut c = state(touching, shown.unwrap_or([0; 4]));
        c.header = rig.header();
        rig.send(Msg::ContactState(c));
        if last.status.phase == "compare" && !sent {
            sent = true;
            rig.send(rig.a_is_rougher());
        }
        let frame = camera(rig);
        rig.send(frame);
        last = rig.tick();
        if matches!(last.status.phase.as_str(), "done" | "failed") {
            break;
        }
    }
}

/// The fold 20 px (1.16 mm) above the centre on A, 30 px (1.74 mm) on B.
fn cut(target: &str, _: usize) -> Option<[u32; 4]> {
    Some(if target == "fabric_a" {
        [120, 100, 200, 160]
    } else {
        [120, 90, 200, 160]
    })
}

fn phase_ticks<'a>(rig: &'a Rig, phase: &str) -> Vec<&'a Tick> {
    rig.ticks
        .iter()
        .filter(|t| t.status.phase == phase)
        .collect()
}

#[test]
fn vtla_real_grasps_below_the_fold_its_touch_felt() {
    let mut rig = Rig::new(params_for("vtla_real"));
    run(&mut rig, cut);
    let last = rig.ticks.last().unwrap();
    assert_eq!(last.status.phase, "done");
    assert_eq!(last.arm.target, "fabric_b");
    // B was touched 1 mm below the camera's edge; the fold was 30 px above the centre there.
    let touch_b = phase_ticks(&rig, "press_b")[0].arm.z_m;
    assert!((touch_b - (EDGE_B_M - 0.001)).abs() < 1e-12);
    let felt_top = touch_b + 30.0 * MM_PER_PX * 1e-3;
    let grasp = phase_ticks(&rig, "grasp");
    assert!(
        grasp
            .iter()
            .all(|t| (t.arm.z_m - (felt_top - 0.00035)).abs() < 1e-9),
        "{} vs {}",
        grasp[0].arm.z_m,
        felt_top - 0.00035
    );
    assert!(grasp[0].status.message.contains("felt by touch"));
    // Not the camera's height: the camera put the top 0.74 mm lower.
    assert!((grasp[0].arm.z_m - (EDGE_B_M - 0.00035)).abs() > 5e-4);
}

#[test]
fn a_touch_that_does_not_show_the_fold_grasps_at_the_cameras_height() {
    let mut rig = Rig::new(params_for("vtla_real"));
    // The whole disc on both: the fold lies above the contact.
    run(&mut rig, |_, _| Some([130, 90, 190, 150]));
    let grasp = phase_ticks(&rig, "grasp");
    assert!((grasp[0].arm.z_m - (EDGE_B_M - 0.00035)).abs() < 1e-12);
    assert!(grasp[0].status.message.contains("camera's edge height"));
}

#[test]
fn a_touch_that_closes_on_nothing_is_tried_again_lower() {
    let mut rig = Rig::new(params_for("vtla_real"));
    // A's first touch closes on nothing (the fingertips above its fold); the second meets it.
    run(&mut rig, |target, k| {
        (target != "fabric_a" || k >= 1)
            .then(|| cut(target, k))
            .flatten()
    });
    assert_eq!(
        rig.phases(),
        [
            "approach_a",
            "press_a",
            "reopen_a",
            "approach_a",
            "press_a",
            "release_a",
            "approach_b",
            "press_b",
            "release_b",
            "compare",
            "approach_grasp",
            "grasp",
            "lift",
            "done"
        ]
    );
    let press_a = phase_ticks(&rig, "press_a");
    let (first, second) = (press_a[0].arm.z_m, press_a.last().unwrap().arm.z_m);
    assert!((first - (EDGE_A_M - 0.001)).abs() < 1e-12);
    assert!((second - (EDGE_A_M - 0.002)).abs() < 1e-12);
    // The fingers open where they closed before the arm goes lower: closed fingers lowered
    // onto the fold would come down on it.
    let reopen = phase_ticks(&rig, "reopen_a");
    assert!(reopen.iter().all(|t| t.arm.z_m == first));
    let lowered = rig
        .ticks
        .iter()
        .skip_while(|t| t.status.phase != "reopen_a")
        .find(|t| t.status.phase == "approach_a")
        .unwrap();
    assert!(lowered.arm.z_m < first, "{} vs {first}", lowered.arm.z_m);
}

#[test]
fn a_touch_that_never_meets_the_fabric_fails_after_its_retries() {
    let mut rig = Rig::new(params_for("vtla_real"));
    run(&mut rig, |target, _| {
        (target != "fabric_a").then(|| cut(target, 0)).flatten()
    });
    let last = rig.ticks.last().unwrap();
    assert_eq!(last.status.phase, "failed");
    assert!(last.status.message.contains("no contact on fabric_a"));
    // Three touches of A, each 1 mm lower.
    let heights: Vec<f64> =
        phase_ticks(&rig, "press_a")
            .iter()
            .map(|t| t.arm.z_m)
            .fold(Vec::new(), |mut v, z| {
                if v.last() != Some(&z) {
                    v.push(z);
                }
                v
            });
    assert_eq!(heights.len(), 3, "{heights:?}");
}

#[test]
fn vla_grasps_at_the_cameras_height_whatever_the_contact_shows() {
    let mut rig = Rig::new(params_for("vla"));
    run(&mut rig, cut);
    let last = rig.ticks.last().unwrap();
    assert_eq!(last.status.phase, "done");
    let grasp = phase_ticks(&rig, "grasp");
    // The camera's roughness: B (1e-5) is smoother.
    assert_eq!(grasp[0].arm.target, "fabric_b");
    assert!((grasp[0].arm.z_m - (EDGE_B_M - 0.00035)).abs() < 1e-12);
}
