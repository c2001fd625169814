//! A serial gripper whose weakest grip is above the scene's force cap is refused at load: the
//! DH AG-95 grips with at least 45 N, the cup and fabric scenes' policies cap the force at 40 N.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::process::Command;

#[test]
fn trials_refuse_a_gripper_whose_weakest_grip_breaks_the_scenes_force_cap() {
    for scene in ["cup_deformation", "fabric_selection"] {
        let o = Command::new(env!("CARGO_BIN_EXE_unitac-lab"))
            .args([
                "trials", "--scene", scene, "--modes", "vla", "--trials", "1",
            ])
            .args(["--gripper", "dh_ag95"])
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{scene}: {err}");
        assert!(err.starts_with("unitac-lab: --gripper dh_ag95"), "{err}");
        assert_eq!(err.lines().count(), 1, "{err}");
        assert!(err.contains("45 N") && err.contains("40 N"), "{err}");
        assert!(o.stdout.is_empty(), "no trial ran");
    }
}
