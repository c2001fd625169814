//! msg/control_msgs is upstream's text, unchanged: the git blob ids of its two interface files are
//! those of ros-controls/control_msgs (branches humble, jazzy and master alike), so the package,
//! type names and fields (and with them the type hashes) are the ones a robot's control_msgs has.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::PathBuf;
use std::process::Command;

#[test]
fn the_gripper_command_interfaces_are_upstreams_text() {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../msg/control_msgs");
    for (file, upstream) in [
        (
            "msg/GripperCommand.msg",
            "bf137a3071fd67c2f52e65a90613f4fed2c148bf",
        ),
        (
            "action/GripperCommand.action",
            "171f7d09c5ef75a6df69895324372e387ca463f2",
        ),
    ] {
        let o = Command::new("git")
            .arg("hash-object")
            .arg(dir.join(file))
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        assert_eq!(
            String::from_utf8_lossy(&o.stdout).trim(),
            upstream,
            "{file}"
        );
    }
}
