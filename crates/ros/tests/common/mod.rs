//! Helpers shared by the ROS node tests: paths, stopping a node, and the closed cup loop
//! (`closed_loop`: policy_loop.rs, two_hosts.rs).
#![allow(dead_code, clippy::unwrap_used)]

pub mod closed_loop;

use std::path::PathBuf;
use std::process::{Child, Command};
use std::time::{Duration, Instant};

/// The generic stage node.
pub const STAGE_NODE: &str = env!("CARGO_BIN_EXE_unitac_stage_node");
/// ROS arguments that make the stage node the launch plan's node for a scene's contact group.
pub const CONTACT: [&str; 4] = ["-r", "__node:=unitac_contact", "-p", "stages:=contact,slip"];
/// ROS arguments that make the stage node the launch plan's node for a scene's inference group.
pub const INFERENCE: [&str; 4] = [
    "-r",
    "__node:=unitac_inference",
    "-p",
    "stages:=encoder,compare,sampler",
];

pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The project venv's Python (rclpy peers).
pub fn python() -> PathBuf {
    std::env::var_os("UNITAC_VENV")
        .map(PathBuf::from)
        .unwrap_or_else(|| root().join(".venv"))
        .join("bin/python")
}

/// The lines `c` writes to its piped stderr, as they come (a reader thread per child).
pub fn stderr_lines(c: &mut Child) -> std::sync::mpsc::Receiver<String> {
    use std::io::BufRead;
    let err = c.stderr.take().unwrap();
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for l in std::io::BufReader::new(err).lines().map_while(Result::ok) {
            if tx.send(l).is_err() {
                break;
            }
        }
    });
    rx
}

/// SIGINT, then up to 5 s to exit cleanly, then SIGKILL.
pub fn stop(mut c: Child) {
    stop_mut(&mut c);
}

/// [`stop`] for a child still owned by something (a no-op when it has exited).
pub fn stop_mut(c: &mut Child) {
    if c.try_wait().ok().flatten().is_some() {
        return;
    }
    Command::new("kill")
        .args(["-INT", &c.id().to_string()])
        .status()
        .ok();
    let t = Instant::now();
    while t.elapsed() < Duration::from_secs(5) {
        if c.try_wait().ok().flatten().is_some() {
            return;
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    c.kill().ok();
    c.wait().ok();
}

/// The `label` of each entry of `got[key]` (a listener summary's episodes, clips, properties).
pub fn labels(got: &serde_json::Value, key: &str) -> Vec<String> {
    got[key]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| e["label"].as_str().unwrap().to_string())
        .collect()
}
