//! The scene controllers driven by scripted message sequences through `unitac_core::chain`: the
//! phases each mode goes through, what it commands, timeouts and the watchdog, in control ticks.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod rig;

use rig::*;
use unitac_core::msg::{GripperMode, Header, LatentSource, Msg, VisualObservation};

const FABRIC: &str = "{mode: vtla_real, task: pick the smoother fabric, \
    visual_names: [fabric_a_x_m, fabric_a_y_m, fabric_a_edge_height_m, \
    fabric_b_x_m, fabric_b_y_m, fabric_b_edge_height_m]}";

/// A camera frame of an 80 mm cup at (0.45, 0.01).
fn cup_camera(rig: &mut Rig) {
    let m = Msg::VisualObservation(VisualObservation {
        header: rig.header(),
        names: vec!["cup_x_m".into(), "cup_y_m".into(), "cup_width_m".into()],
        values: vec![0.45, 0.01, 0.08],
    });
    rig.send(m);
}

/// A cup controller's run to `done` on the 80 mm cup of [`cup_camera`], a wall that pushes back
/// with `k_true` x compression (the gripper stops at its force, and detects the cup once on it).
fn squeeze_a_linear_cup(rig: &mut Rig, k_true: f64) {
    cup_camera(rig);
    let mut t = rig.tick();
    for _ in 0..1200 {
        let stop = 0.08 - t.cmd.force_n / k_true;
        rig.follow(&t.cmd, (t.cmd.mode == GripperMode::Force).then_some(stop));
        rig.object_detected = rig.opening <= 0.08;
        rig.force_n = (k_true * (0.08 - rig.opening)).max(0.0);
        cup_camera(rig);
        t = rig.tick();
        if t.status.phase == "done" {
            break;
        }
    }
}

/// The camera's folded-edge heights in the fabric run: A alternates between two estimates
/// frame by frame (per-frame noise), B is steady.
const EDGE_A_M: [f64; 2] = [0.0030, 0.0034];
const EDGE_B_M: f64 = 0.0024;

/// The camera's frame `n` of the fabric run.
fn camera(rig: &Rig, n: usize) -> Msg {
    Msg::VisualObservation(VisualObservation {
        header: rig.header(),
        names: vec![
            "fabric_a_x_m".into(),
            "fabric_a_y_m".into(),
            "fabric_a_edge_height_m".into(),
            "fabric_b_x_m".into(),
            "fabric_b_y_m".into(),
            "fabric_b_edge_height_m".into(),
        ],
        values: vec![0.45, 0.12, EDGE_A_M[n % 2], 0.45, -0.12, EDGE_B_M],
    })
}

/// The fabric run: a camera frame before every tick, contact when the fingers close below 5 cm
/// on a fabric, the comparison (A is rougher) once the controller waits for it, the grasp stops
/// on the fabric at 3 mm. `drop_contact`: ticks of press_a during which no contact state is
/// sent, from its 10th tick.
fn fabric_run(rig: &mut Rig, send_comparison: bool, drop_contact: usize, max_ticks: usize) {
    let (mut sent, mut press_ticks) = (false, 0);
    let first = camera(rig, 0);
    rig.send(first);
    let mut last = rig.tick();
    for n in 1..max_ticks {
        let on_fabric = last.arm.target.starts_with("fabric");
        let grasping = last.cmd.mode == GripperMode::Force;
        rig.follow(&last.cmd, grasping.then_some(0.003));
        rig.object_detected = grasping && rig.opening <= 0.003 + 1e-9;
        rig.force_n = if rig.object_detected {
            last.cmd.force_n
        } else {
            0.0
        };
        if last.status.phase == "press_a" {
            press_ticks += 1;
        }
        let silent = press_ticks > 10 && press_ticks <= 10 + drop_contact;
        if !silent {
            let c = rig.contact(on_fabric && rig.opening <= 0.05, 30e-6);
            rig.send(c);
        }
        if send_comparison && last.status.phase == "compare" && !sent {
            sent = true;
            rig.send(rig.a_is_rougher());
        }
        let frame = camera(rig, n);
        rig.send(frame);
        last = rig.tick();
        if matches!(last.status.phase.as_str(), "done" | "failed") {
            break;
        }
    }
}

#[test]
fn fabric_touches_both_compares_and_grasps_the_smoother() {
    let mut rig = Rig::new(params(FABRIC));
    fabric_run(&mut rig, true, 0, 3000);
    assert_eq!(
        rig.phases(),
        [
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
    assert!(
        rig.ticks.iter().all(|t| t.status.safety_ok),
        "no safety event"
    );
    // A is rougher, so B is the smoother: grasped and lifted.
    let last = rig.ticks.last().unwrap();
    assert_eq!(last.arm.target, "fabric_b");
    assert_eq!(last.arm.lift_m, 0.05);
    // The grasp aims grasp_z_m (0.35 mm) below the camera's edge height of B.
    assert!(
        (last.arm.z_m - (EDGE_B_M - 0.00035)).abs() < 1e-12,
        "{}",
        last.arm.z_m
    );
    assert_eq!(last.cmd.mode, GripperMode::Force);
    assert_eq!(last.cmd.force_n, 15.0);
    assert_eq!(last.status.mode, "vtla_real");
    assert_eq!(last.status.scene, "test_scene");
    // Each touch held contact for touch_hold_s (1 s = 30 ticks) before releasing.
    let press_a: Vec<_> = rig
        .ticks
        .iter()
        .filter(|t| t.status.phase == "press_a")
        .collect();
    assert!(press_a.iter().all(|t| t.arm.target == "fabric_a"));
    assert!(press_a.iter().all(|t| t.cmd.force_n <= 3.0));
    // The touch goes touch_z_m (1 mm) below A's edge height, averaged over the frames seen while
    // approaching A: between the two estimates, and fixed during the press.
    let z = press_a[0].arm.z_m;
    assert!(
        (EDGE_A_M[0] - 0.001 + 1e-6..EDGE_A_M[1] - 0.001 - 1e-6).contains(&z),
        "{z}"
    );
    assert!(press_a.iter().all(|t| t.arm.z_m == z));
    let press_b = rig
        .ticks
        .iter()
        .find(|t| t.status.phase == "press_b")
        .unwrap();
    assert!((press_b.arm.z_m - (EDGE_B_M - 0.001)).abs() < 1e-12);
    // The arm went to A, then B, then the choice.
    let targets: Vec<&str> =
        rig.ticks
            .iter()
            .map(|t| t.arm.target.as_str())
            .fold(Vec::new(), |mut v, t| {
                if v.last() != Some(&t) {
                    v.push(t);
                }
                v
            });
    assert_eq!(targets, ["fabric_a", "fabric_b", "home", "fabric_b"]);
}

#[test]
fn a_camera_without_the_edge_height_fails_the_approach_with_the_reason() {
    let mut rig = Rig::new(params(FABRIC));
    // No camera frame at all: the safety layer holds on the missing input.
    let t = rig.tick();
    assert!(!t.status.safety_ok);
    assert!(
        t.status.message.starts_with("visual"),
        "{}",
        t.status.message
    );
    assert_eq!(t.status.phase, "approach_a");
    // NaN for a listed name: the observation is invalid, the safety layer holds.
    rig.send(Msg::VisualObservation(VisualObservation {
        header: rig.header(),
        names: vec![
            "fabric_a_x_m".into(),
            "fabric_a_y_m".into(),
            "fabric_a_edge_height_m".into(),
            "fabric_b_x_m".into(),
            "fabric_b_y_m".into(),
            "fabric_b_edge_height_m".into(),
        ],
        values: vec![0.45, 0.12, f64::NAN, 0.45, -0.12, 0.002],
    }));
    let t = rig.tick();
    assert!(!t.status.safety_ok);
    assert_eq!(t.status.phase, "approach_a");
    // A scene that does not list the edge heights, a frame without A's: the controller fails.
    let mut rig = Rig::new(params(
        "{mode: vtla_real, task: pick the smoother fabric, visual_names: [fabric_b_edge_height_m]}",
    ));
    rig.send(Msg::VisualObservation(VisualObservation {
        header: rig.header(),
        names: vec!["fabric_b_edge_height_m".into()],
        values: vec![0.002],
    }));
    let t = rig.tick();
    assert_eq!(t.status.phase, "failed", "{t:?}");
    assert!(
        t.status
            .message
            .contains("the camera gives no fabric_a_x_m / fabric_a_y_m / fabric_a_edge_height_m"),
        "{}",
        t.status.message
    );
}

#[test]
fn no_comparison_times_out_into_the_safe_action_with_the_reason() {
    let mut rig = Rig::new(params(FABRIC));
    fabric_run(&mut rig, false, 0, 3000);
    let first_compare = rig
        .ticks
        .iter()
        .position(|t| t.status.phase == "compare")
        .unwrap();
    let failed = rig
        .ticks
        .iter()
        .position(|t| t.status.phase == "failed")
        .unwrap();
    // compare_timeout_s = 10 s: the first tick at or past 10 s after the phase began.
    let waited = rig.ticks[failed]
        .stamp
        .secs_since(rig.ticks[first_compare].stamp);
    assert!((10.0..10.0 + 0.034).contains(&waited), "{waited}");
    let t = &rig.ticks[failed];
    assert!(!t.status.safety_ok);
    assert_eq!(
        t.status.message,
        "policy: timed out: no roughness comparison of fabric_a and fabric_b within 10 s"
    );
    assert_eq!(t.cmd.reason, t.status.message);
    // Hold: position mode at the measured opening, the hold force.
    assert_eq!(t.cmd.mode, GripperMode::Position);
    assert_eq!(t.cmd.force_n, 5.0);
    assert!(rig.ticks[failed - 1].status.safety_ok);
}

#[test]
fn a_stale_contact_state_holds_at_the_first_tick_past_its_budget() {
    let mut rig = Rig::new(params(FABRIC));
    // Contact silent for 12 ticks (0.4 s) in the middle of press_a; budget 0.25 s.
    fabric_run(&mut rig, true, 12, 3000);
    let bad: Vec<usize> = rig
        .ticks
        .iter()
        .enumerate()
        .filter(|(_, t)| !t.status.safety_ok)
        .map(|(i, _)| i)
        .collect();
    // The last contact state came with press tick 10; ages 1..12 ticks (33 ms each) follow.
    // Ages 8..12 ticks (0.267 .. 0.4 s) exceed 0.25 s: exactly those 5 ticks hold.
    assert_eq!(bad.len(), 5, "{bad:?}");
    assert!(bad.windows(2).all(|w| w[1] == w[0] + 1));
    let first = &rig.ticks[bad[0]];
    assert_eq!(
        first.status.message,
        "contact: stale (0.267 s old, budget 0.25 s)"
    );
    assert_eq!(first.status.phase, "press_a");
    assert_eq!(first.cmd.force_n, 5.0);
    // Once contact states come again the controller goes on and finishes.
    assert_eq!(rig.ticks.last().unwrap().status.phase, "done");
}

#[test]
fn cup_vla_closes_to_the_camera_width_minus_the_target() {
    let mut rig = Rig::new(params(
        "{mode: vla, task: squeeze the cup, objects: [cup], visual_names: [cup_x_m, cup_y_m, cup_width_m]}",
    ));
    let mut last = None;
    for _ in 0..600 {
        cup_camera(&mut rig);
        let t = rig.tick();
        rig.follow(&t.cmd, None);
        let done = t.status.phase == "done";
        last = Some(t);
        if done {
            break;
        }
    }
    assert_eq!(rig.phases(), ["approach", "close", "hold", "lift", "done"]);
    assert!(rig.ticks.iter().all(|t| t.status.safety_ok));
    let last = last.unwrap();
    // The gel surfaces at W - 1 cm: the finger bodies 2 x 3 mm of pad wider.
    assert!((last.cmd.position_m - 0.076).abs() < 1e-9, "{last:?}");
    // Aimed where the camera saw the cup.
    assert!((last.arm.x_m - 0.45).abs() < 1e-12 && (last.arm.y_m - 0.01).abs() < 1e-12);
    assert_eq!(last.arm.lift_m, 0.05);
    assert_eq!(last.arm.target, "cup");
    assert!(
        last.status.message == "cup lifted",
        "{}",
        last.status.message
    );
}

#[test]
fn cup_vtla_real_probes_then_squeezes_by_the_live_compression() {
    let mut rig = Rig::new(params(
        "{mode: vtla_real, task: squeeze the cup, objects: [cup], latent_len: 4, \
         visual_names: [cup_x_m, cup_y_m, cup_width_m]}",
    ));
    let diameter = 0.08;
    let mut latent_sent = false;
    cup_camera(&mut rig);
    let mut t = rig.tick();
    for _ in 0..1200 {
        rig.follow(&t.cmd, None);
        let touching = rig.opening <= diameter;
        let area = if touching {
            20e-6 + 1e-3 * (diameter - rig.opening) as f32
        } else {
            0.0
        };
        let c = rig.contact(touching, area);
        rig.send(c);
        if t.status.phase == "await_latent" && !latent_sent {
            latent_sent = true;
            let l = rig.latent(LatentSource::Real, vec![0.1, 0.2, 0.3, 0.4]);
            rig.send(l);
        }
        cup_camera(&mut rig);
        t = rig.tick();
        if t.status.phase == "done" {
            break;
        }
    }
    assert_eq!(
        rig.phases(),
        [
            "approach",
            "close",
            "probe",
            "await_latent",
            "squeeze",
            "hold",
            "lift",
            "done"
        ]
    );
    assert!(rig.ticks.iter().all(|t| t.status.safety_ok));
    // The squeeze's force cap: prior stiffness 300 N/m x 1 cm x margin 1.5.
    let sq = rig
        .ticks
        .iter()
        .rfind(|t| t.status.phase == "squeeze")
        .unwrap();
    assert!((sq.cmd.force_n - 4.5).abs() < 1e-9, "{sq:?}");
    // Contact began within one closing step of the diameter; the squeeze stopped at a
    // compression within the tolerance (finger travel minus the gel's share).
    let travel = diameter - rig.opening;
    assert!((0.0088..0.0105).contains(&travel), "{travel}");
    assert_eq!(t.arm.lift_m, 0.05);
}

#[test]
fn cup_vtla_real_closes_just_inside_the_measured_opening_and_presses_before_the_release() {
    // With a command of the closed gripper, the safety layer's 5 mm per tick brought the release
    // back over many ticks while the fingers pressed on; now each command is a step from where
    // the fingers are.
    let mut rig = Rig::new(params(
        "{mode: vtla_real, task: squeeze the cup, objects: [cup], latent_len: 4, \
         visual_names: [cup_x_m, cup_y_m, cup_width_m]}",
    ));
    let diameter = 0.08;
    let mut opening = Vec::new();
    cup_camera(&mut rig);
    let mut t = rig.tick();
    for _ in 0..400 {
        opening.push(rig.opening);
        rig.follow(&t.cmd, None);
        let touching = rig.opening <= diameter;
        let area = if touching {
            20e-6 + 1e-3 * (diameter - rig.opening) as f32
        } else {
            0.0
        };
        let c = rig.contact(touching, area);
        rig.send(c);
        cup_camera(&mut rig);
        t = rig.tick();
        if t.status.phase == "await_latent" {
            break;
        }
    }
    let p = unitac_policy::PolicyParams::default();
    let ticks: Vec<_> = rig.ticks.iter().zip(&opening).collect();
    let close: Vec<_> = ticks
        .iter()
        .filter(|(t, _)| t.status.phase == "close")
        .collect();
    assert!(close.len() > 10, "{}", close.len());
    for (t, o) in &close[1..] {
        // Each close command lies the release step inside the opening the fingers had.
        assert!(
            (t.cmd.position_m - (**o - p.probe_release_m)).abs() < 1e-9,
            "{} at {o}",
            t.cmd.position_m
        );
    }
    let probe: Vec<_> = ticks
        .iter()
        .filter(|(t, _)| t.status.phase == "probe")
        .collect();
    let d0 = *probe[0].1;
    let pressing: Vec<_> = probe
        .iter()
        .filter(|(t, _)| t.status.message.starts_with("probe press"))
        .collect();
    // The press holds probe_press_s at D0 - probe_press_m (30 Hz ticks), then the release is
    // commanded whole at once: within one rate-limit step of the press.
    let press_ticks = p.probe_press_s * 30.0;
    assert!(
        (pressing.len() as f64 - press_ticks).abs() <= 1.0,
        "{} press ticks",
        pressing.len()
    );
    let release = probe
        .iter()
        .find(|(t, _)| !t.status.message.starts_with("probe press"))
        .unwrap();
    assert!(
        (release.0.cmd.position_m
            - (pressing[0].0.cmd.position_m + p.probe_press_m + p.probe_release_m))
            .abs()
            < 2e-3,
        "{:?}",
        release.0.cmd
    );
    assert!(rig.ticks.iter().all(|t| t.status.safety_ok));
    assert!(d0 < diameter + 1e-3, "{d0}");
}

#[test]
fn cup_vla_force_rule_squeezes_with_the_stiffness_the_camera_width_says() {
    let mut rig = Rig::new(params(
        "{mode: vla, vla_rule: force, vla_stiffness_at_80mm_n_per_m: 400, \
         vla_stiffness_exponent: -3, task: squeeze the cup, objects: [cup], \
         visual_names: [cup_x_m, cup_y_m, cup_width_m]}",
    ));
    squeeze_a_linear_cup(&mut rig, 400.0);
    assert_eq!(rig.phases(), ["approach", "close", "hold", "lift", "done"]);
    let close: Vec<_> = rig
        .ticks
        .iter()
        .filter(|t| t.status.phase == "close")
        .collect();
    // An 80 mm cup: k = 400 N/m, F = k x 1 cm, in force mode, as vtla_pred squeezes.
    assert!(close.iter().all(|t| t.cmd.mode == GripperMode::Force));
    assert_eq!(close.last().unwrap().cmd.force_n, 4.0);
    let m = &close[0].status.message;
    assert_eq!(
        unitac_policy::controller::cup::stiffness_in(m),
        Some(400.0),
        "{m}"
    );
    assert_eq!(
        unitac_policy::controller::cup::camera_width_in(m),
        Some(0.08),
        "{m}"
    );
    // The camera's stiffness is the cup's here: the squeeze lands at 1 cm.
    assert!((0.08 - rig.opening - 0.01).abs() < 2e-4, "{}", rig.opening);
}

#[test]
fn cup_vtla_pred_sets_the_force_once_from_the_predicted_latent() {
    let mut rig = Rig::new(params(
        "{mode: vtla_pred, task: squeeze the cup by 1 cm, objects: [cup], latent_len: 4, \
         visual_names: [cup_x_m, cup_y_m, cup_width_m]}",
    ));
    let l = rig.latent(LatentSource::Predicted, vec![0.5; 4]);
    rig.send(l);
    squeeze_a_linear_cup(&mut rig, 500.0);
    assert_eq!(rig.phases(), ["approach", "close", "hold", "lift", "done"]);
    assert!(rig.ticks.iter().all(|t| t.status.safety_ok));
    let close: Vec<_> = rig
        .ticks
        .iter()
        .filter(|t| t.status.phase == "close")
        .collect();
    assert!(close.iter().all(|t| t.cmd.mode == GripperMode::Force));
    // F = prior 300 N/m x 1 cm = 3 N (reached after the 2 N per tick ramp).
    assert_eq!(close.last().unwrap().cmd.force_n, 3.0);
    assert!(close[0].status.message.contains("3.00 N"));
    // With a stiffer cup than the prior the squeeze falls short of 1 cm: 3 N / 500 N/m.
    assert!((0.08 - rig.opening - 0.006).abs() < 2e-4, "{}", rig.opening);
}

#[test]
fn cup_vtla_pred_holds_on_a_serial_grippers_catch_without_a_force_reading() {
    // A Robotiq or DH driver reports no force (NaN) and its own motion word: "caught" once the
    // fingers stopped on the object, "moving" before.
    let mut rig = Rig::new(params(
        "{mode: vtla_pred, task: squeeze the cup by 1 cm, objects: [cup], latent_len: 4, \
         visual_names: [cup_x_m, cup_y_m, cup_width_m]}",
    ));
    let l = rig.latent(LatentSource::Predicted, vec![0.5; 4]);
    rig.send(l);
    rig.force_n = f64::NAN;
    cup_camera(&mut rig);
    let mut t = rig.tick();
    let mut caught_at = None;
    for _ in 0..1200 {
        let stop = 0.08 - t.cmd.force_n / 500.0;
        rig.follow(&t.cmd, (t.cmd.mode == GripperMode::Force).then_some(stop));
        let stopped = rig.motion == "stopped" && t.cmd.mode == GripperMode::Force;
        rig.object_detected = rig.opening <= 0.08;
        if rig.object_detected && stopped {
            rig.motion = "caught".into();
            caught_at.get_or_insert(rig.ticks.len());
        }
        cup_camera(&mut rig);
        t = rig.tick();
        if t.status.phase == "done" {
            break;
        }
    }
    assert_eq!(rig.phases(), ["approach", "close", "hold", "lift", "done"]);
    // Touching while still closing ("moving") did not end the close; the catch did, at once.
    let caught_at = caught_at.unwrap();
    assert_eq!(rig.ticks[caught_at - 1].status.phase, "close");
    assert_eq!(rig.ticks[caught_at].status.phase, "hold");
}

#[test]
fn invalid_latents_hold_within_the_tick_they_arrive() {
    let mut rig = Rig::new(params(
        "{mode: vtla_pred, task: squeeze the cup, objects: [cup], latent_len: 4, \
         visual_names: [cup_x_m, cup_y_m, cup_width_m]}",
    ));
    let mut bad = rig.latent(LatentSource::Predicted, vec![0.5; 4]);
    if let Msg::TactileLatent(l) = &mut bad {
        l.valid = false;
        l.guard_report = "velocity blew up".into();
    }
    rig.send(bad);
    cup_camera(&mut rig);
    let t = rig.tick();
    assert!(!t.status.safety_ok);
    assert_eq!(
        t.status.message,
        "latent_pred: invalid (latent marked invalid: velocity blew up)"
    );
    let nan = rig.latent(LatentSource::Predicted, vec![0.5, f32::NAN, 0.5, 0.5]);
    rig.send(nan);
    cup_camera(&mut rig);
    let t = rig.tick();
    assert_eq!(
        t.status.message,
        "latent_pred: invalid (latent value 1 is NaN)"
    );
    assert!(t.cmd.position_m.is_finite() && t.cmd.force_n.is_finite());
    let good = rig.latent(LatentSource::Predicted, vec![0.5; 4]);
    rig.send(good);
    cup_camera(&mut rig);
    let t = rig.tick();
    assert!(t.status.safety_ok, "{t:?}");
    assert_eq!(t.status.phase, "approach");
}

#[test]
fn ticks_follow_the_control_rate_not_every_gripper_status() {
    let mut p = params(FABRIC);
    p.control_rate_hz = 10.0;
    let mut rig = Rig::new(p);
    let mut ticks = 0;
    for _ in 0..30 {
        // GripperStatus at 100 Hz.
        let out = rig
            .chain
            .run(Msg::GripperStatus(unitac_core::msg::GripperStatus {
                header: Header::new(unitac_core::Stamp(rig.now), "g"),
                fault: String::new(),
                ..unitac_core::msg::samples::gripper_status()
            }));
        if !out.produced.is_empty() {
            ticks += 1;
        }
        rig.now += 10_000_000;
    }
    // 0.3 s at 10 Hz: ticks at 0, 0.1, 0.2 s.
    assert_eq!(ticks, 3);
}
