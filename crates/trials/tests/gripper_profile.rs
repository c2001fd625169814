//! A new gripper is one profile file and no code: put in a `UNITAC_GRIPPERS` directory, it is a
//! serial model (the driver's limits and calibration), the world's gripper in a trial with it,
//! and the bounds the safety layer holds the policy to. The directory is read once per process, so
//! the test runs its checks in a child process of this binary with `UNITAC_GRIPPERS` set.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use unitac_gripper::Model;
use unitac_sim::task::{Split, TaskConfig, TaskOutcome};
use unitac_trials::scene::for_gripper;
use unitac_trials::{TrialGripper, TrialOptions, run_trial_on};

const PROFILE: &str = "\
# A test gripper: a Robotiq-protocol model narrower, weaker and slower than any shipped one.
name: test_narrow
family: robotiq
stroke_m: 0.104
force_n: [4.0, 30.0]
speed_m_s: [0.01, 0.08]
slave: 9
baud: 115200
";

#[test]
fn a_new_gripper_profile_file_sets_the_drivers_the_worlds_and_the_safety_layers_limits() {
    let dir = std::env::temp_dir().join(format!("unitac-grippers-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("test_narrow.yaml"), PROFILE).unwrap();
    let out = std::process::Command::new(std::env::current_exe().unwrap())
        .args([
            "--exact",
            "with_the_profile_directory",
            "--ignored",
            "--nocapture",
        ])
        .env("UNITAC_GRIPPERS", &dir)
        .output()
        .unwrap();
    std::fs::remove_dir_all(&dir).ok();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success() && text.contains("1 passed"),
        "{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
#[ignore = "run by the test above, in a process with UNITAC_GRIPPERS set"]
fn with_the_profile_directory() {
    assert!(std::env::var_os("UNITAC_GRIPPERS").is_some());
    // The serial driver's model: limits and calibration from the file.
    let m = Model::named("test_narrow").unwrap();
    let l = m.calibration().limits;
    assert_eq!(
        (
            l.max_opening_m,
            l.min_force_n,
            l.max_force_n,
            l.max_speed_m_s
        ),
        (0.104, 4.0, 30.0, 0.08)
    );
    assert!(Model::all().contains(&m));

    // The world's gripper and the safety layer's bounds of a trial with it.
    let scene = unitac_pipeline::load_scene("cup_deformation_vtla_real", None).unwrap();
    let task = TaskConfig::cup(Split::Unseen);
    let (_, shipped, _) = for_gripper(&scene, &task, TrialGripper::InProcess).unwrap();
    let (with, params, world) = for_gripper(&scene, &task, TrialGripper::Serial(m)).unwrap();
    assert_eq!(params.gripper, "test_narrow");
    let g = world.gripper;
    assert_eq!(
        (g.max_opening_m, g.max_force_n, g.max_speed_m_s),
        (0.104, 30.0, 0.08)
    );
    assert_eq!(g.pad_m, task.gripper.pad_m, "the gel pads stay");
    let (b, b0) = (params.bounds(), shipped.bounds());
    assert_eq!(b.max_opening_m, b0.max_opening_m.min(0.104));
    assert_eq!(b.max_force_n, b0.max_force_n.min(30.0));
    assert_eq!(b.max_speed_m_s, b0.max_speed_m_s.min(0.08));
    assert!(b.max_force_n < b0.max_force_n && b.max_speed_m_s < b0.max_speed_m_s);
    assert_eq!(params.layout().stroke_m, Some(0.104));

    // One trial through the serial driver and a simulated device of that model.
    let opts = TrialOptions::for_task(task.kind);
    let r = run_trial_on(&with, &task, 1, 0, &opts, TrialGripper::Serial(m)).unwrap();
    assert_eq!(r.gripper, "test_narrow");
    let s = r.serial.as_ref().expect("a serial trial reports its wire");
    assert_eq!(s.model, "test_narrow");
    assert!(s.commands >= 2 && s.link_errors == 0, "{s:?}");
    assert!(matches!(r.outcome, TaskOutcome::Cup(_)), "{:?}", r.outcome);
    // The world's fingers never gripped harder than the profile's strongest grip.
    assert!(!r.trace.is_empty());
    let most = r.trace.iter().map(|t| t.force_n).fold(0.0, f64::max);
    assert!(most <= 30.0 + 1e-6, "{most} N");
}
