//! The closed cup loop over ROS for the tests that run it (policy_loop.rs on one host,
//! two_hosts.rs across two): the nodes, and the rclpy observer (tests/ros/policy_observer.py)
//! the test talks to line by line.

use super::{python, root, stop_mut};
use serde_json::Value;
use std::io::{BufRead, BufReader, Write};
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::mpsc::{Receiver, channel};
use std::time::Duration;

/// The scene every closed-loop test runs.
pub const SCENE: &str = "cup_deformation_vtla_real";
/// The policy node's parameters for a gripper behind the GripperCommand action `gripper_cmd` (in
/// its namespace), read from `joint_states`.
pub const ACTION_POLICY: [&str; 6] = [
    "-p",
    "gripper_input:=joint_states",
    "-p",
    "gripper_output:=action",
    "-p",
    "gripper_action:=gripper_cmd",
];
/// The scene's control period \[ns] (30 Hz).
pub const PERIOD_NS: i64 = 33_333_333;

/// Where a process runs: `program` as a command on host `robot` or `gpu` (one host: both the
/// same).
pub type Launcher<'a> = &'a dyn Fn(&str, &str) -> Command;

/// Every process on this host.
pub fn here(_host: &str, program: &str) -> Command {
    Command::new(program)
}

/// A node on `host` in namespace `ns`; its stderr goes to the test's.
pub fn node(at: Launcher, host: &str, bin: &str, ns: &str, args: &[&str]) -> Child {
    at(host, bin)
        .args(["--ros-args", "-r", &format!("__ns:={ns}")])
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::inherit())
        .spawn()
        .unwrap()
}

/// [`node`] with its stderr lines also sent to the returned receiver (and still to the test's).
pub fn node_heard(
    at: Launcher,
    host: &str,
    bin: &str,
    ns: &str,
    args: &[&str],
) -> (Child, Receiver<String>) {
    let mut child = at(host, bin)
        .args(["--ros-args", "-r", &format!("__ns:={ns}")])
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let err = BufReader::new(child.stderr.take().unwrap());
    let (tx, lines) = channel();
    std::thread::spawn(move || {
        for l in err.lines().map_while(Result::ok) {
            eprintln!("{l}");
            // The receiver may be gone; the lines still reach the test's stderr.
            let _ = tx.send(l);
        }
    });
    (child, lines)
}

/// Wait up to `seconds` for a line containing `want`.
pub fn heard(lines: &Receiver<String>, want: &str, seconds: u64) {
    let deadline = std::time::Instant::now() + Duration::from_secs(seconds);
    loop {
        let left = deadline.saturating_duration_since(std::time::Instant::now());
        match lines.recv_timeout(left) {
            Ok(l) if l.contains(want) => return,
            Ok(_) => {}
            Err(e) => panic!("no line with {want:?} within {seconds} s ({e})"),
        }
    }
}

pub struct Observer {
    child: Child,
    stdin: ChildStdin,
    lines: Receiver<String>,
}

impl Observer {
    /// The observer on the robot, for `seconds` at most.
    pub fn start(at: Launcher, ns: &str, seconds: u32) -> Self {
        Self::script(at, "policy_observer.py", &[ns, &seconds.to_string()])
    }

    /// An rclpy peer of tests/ros on the robot, talking line by line like the observer.
    pub fn script(at: Launcher, script: &str, args: &[&str]) -> Self {
        let py = python();
        let mut child = at("robot", py.to_str().unwrap())
            .arg(root().join("tests/ros").join(script))
            .args(args)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .spawn()
            .unwrap();
        let stdin = child.stdin.take().unwrap();
        let out = BufReader::new(child.stdout.take().unwrap());
        let (tx, lines) = channel();
        std::thread::spawn(move || {
            for l in out.lines().map_while(Result::ok) {
                if tx.send(l).is_err() {
                    return;
                }
            }
        });
        Self {
            child,
            stdin,
            lines,
        }
    }

    /// The first line `want` accepts (lines before it are dropped), within `seconds`.
    pub fn wait_for(&self, want: impl Fn(&str) -> bool, seconds: u64) -> String {
        let deadline = std::time::Instant::now() + Duration::from_secs(seconds);
        let mut seen = Vec::new();
        loop {
            let left = deadline.saturating_duration_since(std::time::Instant::now());
            match self.lines.recv_timeout(left) {
                Ok(l) if want(&l) => return l,
                Ok(l) => seen.push(l),
                Err(e) => panic!("observer: no wanted line within {seconds} s ({e}); saw {seen:?}"),
            }
        }
    }

    pub fn send(&mut self, line: &str) {
        writeln!(self.stdin, "{line}").unwrap();
        self.stdin.flush().unwrap();
    }

    /// Ask (`line`) and wait for the answer, which starts with `answer`, within `seconds`.
    pub fn ask(&mut self, line: &str, answer: &str, seconds: u64) -> String {
        self.send(line);
        self.wait_for(|l| l.starts_with(answer), seconds)
    }

    /// Pause the sim (`sim/pause`: sim time held between steps, the sim's node spinning on, so
    /// its DDS participant stays alive) or let it go on; pausing returns once sim time stands
    /// still. Where [`Loop::freeze_sim`] would stop the sim's process for longer than the other
    /// participants' leases (2 s in the two-host profile), the sim would drop them in its own
    /// view on resuming, and what it publishes until it has found them again is lost.
    pub fn pause_sim(&mut self, paused: bool) {
        if paused {
            self.ask("pause 1", "paused ", 30);
        } else {
            self.ask("pause 0", "resumed", 10);
        }
    }

    /// Record the latest PolicyStatus stamp as the mark and return it.
    pub fn mark(&mut self) -> i64 {
        let marked = self.ask("mark", "marked ", 10);
        marked["marked ".len()..].parse().unwrap()
    }

    /// [`Self::wait_for`], but on a timeout end the observer and fail with what it recorded last
    /// (the latest statuses and commands, the sim clock).
    pub fn wait_or_dump(&mut self, want: impl Fn(&str) -> bool, seconds: u64) -> String {
        let deadline = std::time::Instant::now() + Duration::from_secs(seconds);
        loop {
            let left = deadline.saturating_duration_since(std::time::Instant::now());
            match self.lines.recv_timeout(left) {
                Ok(l) if want(&l) => return l,
                Ok(_) => {}
                Err(e) => {
                    self.send("end");
                    let summary = self.wait_for(|l| l.starts_with('{'), 30);
                    let got: Value = serde_json::from_str(&summary).unwrap();
                    let tail = |k: &str| {
                        let v = got[k].as_array().unwrap();
                        v[v.len().saturating_sub(3)..].to_vec()
                    };
                    panic!(
                        "observer: no wanted line within {seconds} s ({e}); last statuses {:?}; \
                         last commands {:?}; clock {} ({} clocks); counts {}",
                        tail("status"),
                        tail("commands"),
                        got["clock_ns"],
                        got["clocks"],
                        got["counts"]
                    );
                }
            }
        }
    }

    /// End it and return its record.
    pub fn finish(mut self) -> Value {
        self.send("end");
        let summary = self.wait_for(|l| l.starts_with('{'), 30);
        self.child.wait().unwrap();
        serde_json::from_str(&summary).unwrap()
    }
}

/// The nodes of the loop: contact, policy (robot) and inference (gpu) on sim time, then the sim
/// (robot), which starts once the policy and the contact node subscribed.
pub struct Loop {
    pub contact: Child,
    pub inference: Option<Child>,
    pub policy: Child,
    pub sim: Child,
    /// The gripper controller peer (GripperPath::Action).
    pub controller: Option<Observer>,
}

/// How the policy's gripper commands reach the sim's gripper.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GripperPath {
    /// unitac_msgs/GripperCommand on `gripper_command`, one per tick (what the serial gripper
    /// node reads).
    Commands,
    /// Goals of control_msgs/action/GripperCommand to a GripperActionController peer
    /// (tests/ros/gripper_action_server.py) that holds the sim gripper's setpoint.
    Action,
}

impl Loop {
    /// Start the nodes; the sim once `obs` matched the policy's outputs.
    pub fn start(at: Launcher, ns: &str, duration_s: f64, obs: &Observer) -> Self {
        Self::start_with(at, ns, duration_s, obs, GripperPath::Commands)
    }

    /// [`Self::start`] with the gripper reached through `path`.
    pub fn start_with(
        at: Launcher,
        ns: &str,
        duration_s: f64,
        obs: &Observer,
        path: GripperPath,
    ) -> Self {
        Self::start_scene(at, ns, duration_s, obs, path, SCENE, "cup_deformation")
    }

    /// [`Self::start_with`] on `scene`, the sim running `task` (the scene's: cup_deformation |
    /// fabric_selection).
    pub fn start_scene(
        at: Launcher,
        ns: &str,
        duration_s: f64,
        obs: &Observer,
        path: GripperPath,
        scene: &str,
        task: &str,
    ) -> Self {
        let scene = format!("scene:={scene}");
        let task = format!("task:={task}");
        let sim_time = ["-p", "use_sim_time:=true"];
        let contact = node(
            at,
            "robot",
            super::STAGE_NODE,
            ns,
            &[
                super::CONTACT[0],
                super::CONTACT[1],
                super::CONTACT[2],
                super::CONTACT[3],
                "-r",
                "image:=image_raw",
                "-p",
                &scene,
                sim_time[0],
                sim_time[1],
            ],
        );
        let inference = node(
            at,
            "gpu",
            super::STAGE_NODE,
            ns,
            &[
                &super::INFERENCE[..],
                &["-p", &scene, sim_time[0], sim_time[1]],
            ]
            .concat(),
        );
        let mut policy_args = vec!["-p", &scene, sim_time[0], sim_time[1]];
        // Through the action: the policy reads the sim's joint states (as from a robot's
        // joint_state_broadcaster) and sends goals to the controller peer, which holds the sim
        // gripper's setpoint; the sim waits for the arm's commands only.
        if path == GripperPath::Action {
            policy_args.extend(ACTION_POLICY);
        }
        let policy = node(
            at,
            "robot",
            env!("CARGO_BIN_EXE_unitac_policy_node"),
            ns,
            &policy_args,
        );
        obs.wait_for(|l| l == "ready", 30);
        let controller = (path == GripperPath::Action).then(|| {
            let c = Observer::script(
                at,
                "gripper_action_server.py",
                &[ns, "gripper_cmd", "120", "forward"],
            );
            c.wait_for(|l| l == "ready", 30);
            c
        });
        let duration = format!("duration_s:={duration_s:.1}");
        let mut sim_args = vec![
            "-p",
            &task,
            "-p",
            "split:=train",
            "-p",
            "seed:=1",
            "-p",
            "trial:=0",
            "-p",
            &duration,
            // Two subscribers each on gripper_status (the policy or the controller, and the
            // observer) and image_raw (contact, observer).
            "-p",
            "wait_subscribers:=2",
            "-p",
            "wait_image_subscribers:=2",
            // Real time at most: the latent comes from the inference node at its own pace
            // (the sim waits for the contact states and the commands, not for it).
            "-p",
            "max_rate:=1.0",
        ];
        if path == GripperPath::Action {
            sim_args.extend([
                "-p",
                "gripper_commands:=held",
                "-r",
                "gripper_command:=controller/gripper_setpoint",
                "-p",
                "wait_joint_subscribers:=1",
            ]);
        }
        let sim = node(
            at,
            "robot",
            env!("CARGO_BIN_EXE_unitac_sim_node"),
            ns,
            &sim_args,
        );
        Self {
            contact,
            inference: Some(inference),
            policy,
            sim,
            controller,
        }
    }

    /// Freeze (`true`) or resume the sim, and with it sim time.
    pub fn freeze_sim(&self, frozen: bool) {
        let sig = if frozen { "-STOP" } else { "-CONT" };
        let s = Command::new("kill")
            .args([sig, &self.sim.id().to_string()])
            .status()
            .unwrap();
        assert!(s.success());
    }

    /// Stop the nodes (sim first); dropping the loop does the same, also when a test fails.
    pub fn stop(self) {}
}

impl Drop for Loop {
    fn drop(&mut self) {
        // A frozen sim would not see SIGINT.
        let _ = Command::new("kill")
            .args(["-CONT", &self.sim.id().to_string()])
            .status();
        stop_mut(&mut self.sim);
        if let Some(c) = &mut self.controller {
            stop_mut(&mut c.child);
        }
        stop_mut(&mut self.policy);
        if let Some(i) = &mut self.inference {
            stop_mut(i);
        }
        stop_mut(&mut self.contact);
    }
}

/// The observer's PolicyStatus records.
pub fn statuses(got: &Value) -> &Vec<Value> {
    got["status"].as_array().unwrap()
}

/// The stamp of a record.
pub fn stamp(v: &Value) -> i64 {
    v["stamp"].as_i64().unwrap()
}

/// The phases in order of first appearance.
pub fn phases(got: &Value) -> Vec<&str> {
    let mut phases: Vec<&str> = Vec::new();
    for s in statuses(got) {
        let p = s["phase"].as_str().unwrap();
        if phases.last() != Some(&p) {
            phases.push(p);
        }
    }
    phases
}
