//! The closed loop over ROS: sim node -> contact node -> inference node -> policy node
//! -> sim node, in lock-step sim time, checked by an rclpy observer (tests/ros/policy_observer.py)
//! that records PolicyStatus, GripperCommand, /clock and the sim's outcome. scripts/test runs
//! this in a loopback-only network namespace. Nothing here times wall clocks for pass/fail: the
//! hold is measured in sim time.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;
use common::closed_loop::{Launcher, Loop, Observer, PERIOD_NS, SCENE, here, phases, statuses};
use common::stop;
use serde_json::Value;
use std::time::Duration;

/// One test at a time: each runs five processes on a small machine.
static SERIAL: std::sync::Mutex<()> = std::sync::Mutex::new(());

const HERE: Launcher = &here;

fn ns(name: &str) -> String {
    format!("/t{}_{name}", std::process::id())
}

fn node(bin: &str, ns: &str, args: &[&str]) -> std::process::Child {
    common::closed_loop::node(HERE, "robot", bin, ns, args)
}

#[test]
fn a_vtla_real_cup_trial_over_ros_reaches_the_target_deformation() {
    let _one = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let n = ns("trial");
    let obs = Observer::start(HERE, &n, 80);
    let l = Loop::start(HERE, &n, 12.0, &obs);
    obs.wait_for(|s| s == "outcome", 70);
    let got = obs.finish();
    l.stop();
    let outcome = &got["outcome"];
    let cup = &outcome["outcome"]["cup"];
    let bad: Vec<&Value> = statuses(&got)
        .iter()
        .filter(|s| s["safety_ok"] == false)
        .take(3)
        .collect();
    eprintln!(
        "phases {:?}; holds {bad:?}; sim: {} steps, {} contact timeouts",
        phases(&got),
        outcome["steps"],
        outcome["contact_timeouts"]
    );
    // The sim's own judgement: the final loss of diameter within 1 cm +- 2 mm, never more,
    // no collision, and lifted.
    assert_eq!(cup["deformation"], true, "{outcome}");
    assert_eq!(cup["over_compressed"], false, "{outcome}");
    assert_eq!(cup["overall"], true, "{outcome}");
    // The policy went through the probe touch and the squeeze, on the live latent.
    for s in statuses(&got) {
        assert_eq!(s["scene"], SCENE);
        assert_eq!(s["mode"], "vtla_real");
    }
    let phases = phases(&got);
    for want in [
        "close",
        "probe",
        "await_latent",
        "squeeze",
        "hold",
        "lift",
        "done",
    ] {
        assert!(phases.contains(&want), "{want} missing from {phases:?}");
    }
    // One command per status, at the same stamps.
    let cmds = got["commands"].as_array().unwrap();
    assert_eq!(cmds.len(), statuses(&got).len());
    assert!(
        cmds.iter()
            .all(|c| c["position_m"].as_f64().unwrap().is_finite())
    );
}

/// A learned VTLA-real trial of `task` (cup_deformation | fabric_selection) over ROS: the scene's learned policy
/// (trained by setup on demonstrations) drives the sim through the same nodes as the scripted
/// scene's, to its timeout. Returns the observer's record.
fn learned_trial(scene: &str, task: &str, seconds: f64) -> Value {
    let n = ns(&format!("learned_{task}"));
    let obs = Observer::start(HERE, &n, 90);
    let l = Loop::start_scene(
        HERE,
        &n,
        seconds,
        &obs,
        common::closed_loop::GripperPath::Commands,
        scene,
        task,
    );
    obs.wait_for(|s| s == "outcome", 80);
    let got = obs.finish();
    l.stop();
    let phases = phases(&got);
    eprintln!(
        "{scene}: phases {phases:?}; outcome {}",
        got["outcome"]["outcome"]
    );
    for s in statuses(&got) {
        assert_eq!(s["scene"], scene);
        assert_eq!(s["mode"], "vtla_real");
    }
    // Phases only on events every mode observes: object-detect, the timeout.
    assert_eq!(phases.first(), Some(&"act"), "{phases:?}");
    assert_eq!(phases.last(), Some(&"done"), "{phases:?}");
    assert!(
        phases
            .iter()
            .all(|p| ["act", "holding", "done"].contains(p)),
        "{phases:?}"
    );
    // The commands are the learned policy's, through the safety layer (a tick whose inputs
    // were not fresh yet gets the safe action), inside the scene's bounds.
    let cmds = got["commands"].as_array().unwrap();
    assert_eq!(cmds.len(), statuses(&got).len());
    let model = format!("learned {}", scene.replace("learned_", ""));
    let learned = cmds
        .iter()
        .filter(|c| c["reason"].as_str().unwrap().contains(&model))
        .count();
    assert!(
        learned * 10 >= cmds.len() * 9,
        "{learned} of {} commands: {:?}",
        cmds.len(),
        &cmds[..3.min(cmds.len())]
    );
    assert!(
        cmds.iter()
            .all(|c| (0.0..=0.11).contains(&c["position_m"].as_f64().unwrap()))
    );
    // The fingers moved: the policy closed on the object.
    let first = cmds[0]["position_m"].as_f64().unwrap();
    assert!(
        cmds.iter()
            .any(|c| c["position_m"].as_f64().unwrap() < first - 0.005)
    );
    got
}

#[test]
fn learned_vtla_real_trials_of_both_tasks_run_over_ros_to_their_end() {
    let _one = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let cup = learned_trial("cup_deformation_learned_vtla_real", "cup_deformation", 12.0);
    assert!(
        cup["outcome"]["outcome"]["cup"].is_object(),
        "{}",
        cup["outcome"]
    );
    let fabric = learned_trial(
        "fabric_selection_learned_vtla_real",
        "fabric_selection",
        16.0,
    );
    assert!(
        fabric["outcome"]["outcome"]["fabric"].is_object(),
        "{}",
        fabric["outcome"]
    );
}

#[test]
fn killing_the_inference_node_makes_the_policy_hold_within_one_control_period() {
    let _one = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let n = ns("kill");
    let mut obs = Observer::start(HERE, &n, 80);
    let mut l = Loop::start(HERE, &n, 6.0, &obs);
    // Closing on the cup: the probe latent is still awaited, so its producer must be alive.
    obs.wait_for(|s| s.starts_with("phase close"), 60);
    // Freeze sim time, kill the inference node, wait until the graph shows it gone, and mark
    // the last tick the policy made before.
    l.freeze_sim(true);
    stop(l.inference.take().unwrap());
    obs.ask("publishers tactile_latent 0", "publishers ", 20);
    let mark = obs.mark();
    l.freeze_sim(false);
    obs.wait_for(|s| s == "outcome", 60);
    let got = obs.finish();
    l.stop();
    let st = statuses(&got);
    let topic = format!("{n}/tactile_latent");
    let why = format!("latent_real: no publisher on {topic}");
    // Before the kill the loop ran normally (a hold at the start, before the producers were
    // discovered, may name the same reason; none did after the closing began).
    let close_at = st.iter().find(|s| s["phase"] == "close").unwrap()["stamp"]
        .as_i64()
        .unwrap();
    assert!(
        mark >= close_at,
        "mark {mark} before close {close_at} ({} clocks)",
        got["clocks"]
    );
    assert!(
        st.iter()
            .filter(|s| {
                let t = s["stamp"].as_i64().unwrap();
                t >= close_at && t <= mark
            })
            .all(|s| s["safety_ok"] == true),
        "{:?}",
        st.iter()
            .filter(|s| s["safety_ok"] == false)
            .take(5)
            .collect::<Vec<_>>()
    );
    // The next tick after the kill holds and says why: one control period of sim time later.
    let first = st
        .iter()
        .find(|s| s["stamp"].as_i64().unwrap() > mark)
        .expect("a tick after the kill");
    let t = first["stamp"].as_i64().unwrap();
    // (Stamps are world times rounded to the nanosecond: a period is 33 333 333 or 33 333 334.)
    assert!(t - mark <= PERIOD_NS + 1, "hold at {t}, mark {mark}");
    assert_eq!(first["safety_ok"], false, "{first}");
    assert_eq!(first["message"], why.as_str(), "{first}");
    // Every tick after holds for that reason, and the gripper commands say the same.
    assert!(
        st.iter()
            .filter(|s| s["stamp"].as_i64().unwrap() >= t)
            .all(|s| s["safety_ok"] == false && s["message"] == why.as_str())
    );
    let cmds = got["commands"].as_array().unwrap();
    let held: Vec<&Value> = cmds
        .iter()
        .filter(|c| c["stamp"].as_i64().unwrap() >= t)
        .collect();
    assert!(!held.is_empty());
    assert!(held.iter().all(|c| c["reason"] == why.as_str()));
    // The hold is position mode (0) at the measured opening: the fingers stop closing.
    let pos: Vec<f64> = held
        .iter()
        .map(|c| c["position_m"].as_f64().unwrap())
        .collect();
    assert!(held.iter().all(|c| c["mode"] == 0), "{held:?}");
    assert!(
        pos.windows(2).all(|w| (w[0] - w[1]).abs() < 1e-3),
        "{pos:?}"
    );
    // And the cup was not squeezed.
    let cup = &got["outcome"]["outcome"]["cup"];
    assert_eq!(cup["deformation"], false, "{cup}");
}

/// No sim: a gripper driver's JointState (`gripper_input:=joint_states`) on system time, which
/// then stops. The policy keeps acting on its control interval: the safe action with the reason,
/// at the last measured opening, stamped on its own clock a period after the tick that was due (when exactly is the stage's rule, tested in crates/policy/tests/watchdog.rs).
#[test]
fn without_gripper_states_the_policy_node_sends_the_safe_action_on_its_timer() {
    let _one = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let n = ns("watchdog");
    let mut obs = Observer::start(HERE, &n, 60);
    let policy = node(
        env!("CARGO_BIN_EXE_unitac_policy_node"),
        &n,
        &[
            "-p",
            &format!("scene:={SCENE}"),
            "-p",
            "gripper_input:=joint_states",
        ],
    );
    obs.wait_for(|l| l == "ready", 30);
    obs.send("joint_states 30");
    let published = obs.wait_for(|l| l.starts_with("published "), 30);
    let last: i64 = published["published ".len()..].parse().unwrap();
    // A second of system time for the watchdog ticks to come.
    std::thread::sleep(Duration::from_secs(1));
    let got = obs.finish();
    stop(policy);
    let st = statuses(&got);
    // Ticks on the joint states (held: the encoder is not running, so its latent is lost) ...
    let on_states: Vec<&Value> = st
        .iter()
        .filter(|s| s["stamp"].as_i64().unwrap() <= last)
        .collect();
    assert!(!on_states.is_empty(), "{st:?}");
    // (Most are the states' own ticks; on a loaded machine a state that came more than a period
    // late lets the watchdog tick in between: they are sent on system time by another process.)
    let own = on_states
        .iter()
        .filter(|s| !s["message"].as_str().unwrap().starts_with("gripper:"))
        .count();
    assert!(2 * own > on_states.len(), "{on_states:?}");
    // ... then the watchdog's.
    let after: Vec<&Value> = st
        .iter()
        .filter(|s| s["stamp"].as_i64().unwrap() > last)
        .collect();
    assert!(after.len() >= 10, "{after:?}");
    assert!(after.iter().all(|s| {
        s["safety_ok"] == false
            && s["message"]
                .as_str()
                .unwrap()
                .starts_with("gripper: no status for")
    }));
    // (The due tick is after the last state: a period past it is the earliest.)
    assert!(after[0]["stamp"].as_i64().unwrap() - last >= PERIOD_NS);
    // The hold is at the opening the joint states reported.
    let cmds = got["commands"].as_array().unwrap();
    let held: Vec<&Value> = cmds
        .iter()
        .filter(|c| c["stamp"].as_i64().unwrap() > last)
        .collect();
    assert!(!held.is_empty());
    assert!(
        held.iter()
            .all(|c| c["mode"] == 0 && c["position_m"] == 0.07),
        "{held:?}"
    );
}

/// The inference node killed while the policy closes on the cup, then started again: the next
/// tick after the kill holds (one control period of sim time), and once a new inference node
/// publishes the policy goes on where it stopped: the probe touch, its latent from the new node,
/// the squeeze, the target deformation.
#[test]
fn a_killed_inference_node_holds_the_policy_and_the_trial_resumes_when_it_returns() {
    let _one = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let n = ns("resume");
    let mut obs = Observer::start(HERE, &n, 150);
    // The plain trial's 12 s of sim time, and time for the hold.
    let mut l = Loop::start(HERE, &n, 14.0, &obs);
    obs.wait_for(|s| s.starts_with("phase close"), 60);
    l.freeze_sim(true);
    stop(l.inference.take().unwrap());
    obs.ask("publishers tactile_latent 0", "publishers ", 20);
    let killed = obs.mark();
    l.freeze_sim(false);
    // Held a while (sim time goes on), then a new inference node.
    std::thread::sleep(Duration::from_secs(1));
    l.freeze_sim(true);
    let held_until = obs.mark();
    let scene = format!("scene:={SCENE}");
    l.inference = Some(node(
        common::STAGE_NODE,
        &n,
        &[
            &common::INFERENCE[..],
            &["-p", &scene, "-p", "use_sim_time:=true"],
        ]
        .concat(),
    ));
    obs.ask("publishers tactile_latent 1", "publishers ", 30);
    // The probe's clip must reach the new node: it listens before the sim goes on. The observer
    // sees the new subscriber before the contact node's publisher has matched it (discovery is
    // per participant; on a loaded machine 0.5 s was not enough once): the sim stays frozen a
    // while longer, which costs wall time only.
    obs.ask("subscribers contact_clip 1", "subscribers ", 30);
    std::thread::sleep(Duration::from_secs(3));
    l.freeze_sim(false);
    obs.wait_for(|s| s == "outcome", 120);
    let got = obs.finish();
    l.stop();
    let st = statuses(&got);
    let why = format!("latent_real: no publisher on {n}/tactile_latent");
    let first = st
        .iter()
        .find(|s| s["stamp"].as_i64().unwrap() > killed)
        .expect("a tick after the kill");
    assert!(
        first["stamp"].as_i64().unwrap() - killed <= PERIOD_NS + 1,
        "{first}"
    );
    assert_eq!(first["safety_ok"], false, "{first}");
    assert_eq!(first["message"], why.as_str(), "{first}");
    // Held until the new node was there, then acting again, to the end of the trial.
    let after: Vec<&Value> = st
        .iter()
        .filter(|s| s["stamp"].as_i64().unwrap() > held_until)
        .collect();
    let resumed = after
        .iter()
        .position(|s| s["safety_ok"] == true)
        .expect("the policy acts again");
    assert!(
        after[..resumed]
            .iter()
            .all(|s| s["message"] == why.as_str()),
        "{:?}",
        &after[..resumed]
    );
    let p = phases(&got);
    for want in ["probe", "await_latent", "squeeze", "hold"] {
        assert!(p.contains(&want), "{p:?}");
    }
    let cup = &got["outcome"]["outcome"]["cup"];
    assert_eq!(cup["deformation"], true, "{cup}");
}

/// A gripper driver's JointState stream that stops and comes back (system time, no sim): the
/// watchdog's safe action on the policy's timer while it is gone, its own ticks again once it
/// is back.
#[test]
fn a_gripper_driver_that_stops_and_returns_gets_the_safe_action_then_control_again() {
    let _one = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let n = ns("gripper_back");
    let mut obs = Observer::start(HERE, &n, 60);
    let policy = node(
        env!("CARGO_BIN_EXE_unitac_policy_node"),
        &n,
        &[
            "-p",
            &format!("scene:={SCENE}"),
            "-p",
            "gripper_input:=joint_states",
        ],
    );
    obs.wait_for(|l| l == "ready", 30);
    obs.send("joint_states 30");
    let first = obs.wait_for(|l| l.starts_with("published "), 30);
    let gone: i64 = first["published ".len()..].parse().unwrap();
    std::thread::sleep(Duration::from_secs(1));
    obs.send("joint_states 30");
    let second = obs.wait_for(|l| l.starts_with("published "), 30);
    let back: i64 = second["published ".len()..].parse().unwrap();
    std::thread::sleep(Duration::from_millis(300));
    let got = obs.finish();
    stop(policy);
    let st = statuses(&got);
    let watchdog = |s: &&Value| {
        s["message"]
            .as_str()
            .unwrap()
            .starts_with("gripper: no status for")
    };
    // While gone: the watchdog's safe action, the first once the tick due a period after the
    // last state is a period overdue (the stage's rule, exact in crates/policy/tests/watchdog.rs;
    // the node's timer and a loaded machine's scheduling add up to two periods more here).
    let gap: Vec<&Value> = st
        .iter()
        .filter(|s| {
            let t = s["stamp"].as_i64().unwrap();
            t > gone && t < back - PERIOD_NS * 30
        })
        .collect();
    assert!(gap.len() >= 10 && gap.iter().all(watchdog), "{gap:?}");
    assert!(
        gap[0]["stamp"].as_i64().unwrap() - gone <= 4 * PERIOD_NS,
        "{:?}",
        gap[0]
    );
    // Back: the states' own ticks again (held for the lost encoder latent, not the gripper).
    let again: Vec<&Value> = st
        .iter()
        .filter(|s| {
            let t = s["stamp"].as_i64().unwrap();
            t > back - PERIOD_NS * 25 && t <= back
        })
        .collect();
    assert!(!again.is_empty(), "{st:?}");
    // (On a loaded machine a state more than a period late lets the watchdog tick in between:
    // the states are sent on system time by another process. So: ticks of their own, not all.)
    let own = again.iter().filter(|s| !watchdog(s)).count();
    assert!(own >= 5, "{again:?}");
}
