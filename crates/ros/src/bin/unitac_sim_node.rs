//! Sim node: a task world of the paper's two tasks (cup deformation, fabric selection) as a ROS
//! node, in lock-step sim time, so the whole closed loop (sim -> contact -> inference -> policy ->
//! sim) runs over ROS on one machine. The world and every conversion are crates/sim's
//! `TaskWorld` and crates/trials' bridge (through `unitac_trials::stepper::WorldStepper`, the one
//! world stepper).
//!
//! Each control period at world time t it publishes `/clock` = t, the tactile frames due up to t
//! on `image_raw` (sensor_msgs/Image, the mock sensor's frames rendered from the world), the
//! camera's estimate on `visual_observation`, and the gripper's state on `gripper_status`
//! (unitac_msgs/GripperStatus) and `joint_states` (sensor_msgs/JointState: position = opening,
//! effort = force), the status last (it is the policy's tick; with `sync_contact`, once the
//! contact node's background is learned, only after the ContactState of the step's last frame
//! came, so the policy sees the contact of its own time as the embedded loop does). It then
//! waits for the GripperCommand (`gripper_command`) and ArmCommand (`arm_command`) stamped t;
//! after `command_timeout_s` of waiting without them (the wall time this process ran: a stall of
//! the process does not count) it steps with the last command and counts it (`repeated_steps`).
//! With `gripper_commands: held` the gripper is a controller's: a GripperCommand on
//! `gripper_command` is a setpoint held until the next one, whatever its stamp (what a
//! ros2_control gripper controller behind its action server sends), and each step waits for the
//! ArmCommand only. At the end (`duration_s` of sim time) it publishes the world's outcome
//! once, as one JSON object on `sim/outcome` (std_msgs/String, transient-local), prints the same
//! line on stdout, and keeps serving until stopped. The other nodes run with `use_sim_time`.
//! `sim/pause` (std_msgs/Bool) holds sim time between two steps while true, the node spinning on
//! (its pacing starts over when it goes on).

use futures::{FutureExt, StreamExt};
use r2r::{QosProfile, RosParams};
use std::time::{Duration, Instant};
use unitac_core::msg::{ArmCommand, GripperCommand, GripperMode};
use unitac_core::{SensorKind, Stamp};
use unitac_ros::node::NodeBase;
use unitac_ros::{convert, diagnostics, image};
use unitac_sim::task::TaskKind;
use unitac_trials::stepper::{SimSpec, WorldStepper};

#[derive(RosParams, Debug, Clone)]
struct Params {
    /// A closed-loop scene (name or path, as the policy node's): its policy stage names the task
    /// and the control rate (empty: `task` and `control_rate_hz` say them)
    scene: String,
    /// The task's name, cup_deformation | fabric_selection (empty: the scene's; without a scene,
    /// cup_deformation)
    task: String,
    /// train | unseen (cups: 60/65/70 mm vs 90 mm; the fabric task has one set)
    split: String,
    /// The trial draw: seed and trial index
    seed: i64,
    trial: i64,
    /// Control rate = sim steps per sim second (0: the scene's; without a scene, the policy's
    /// default)
    control_rate_hz: f64,
    /// Sim time of the trial, in seconds (0: the task's trial length, as `unitac-lab trials` runs
    /// it)
    duration_s: f64,
    /// Mock tactile sensor: a profile of sensors/ (gelsight-mini, digit, generic, ...) or of $UNITAC_SENSORS, and its id (frame_id
    /// `<sensor_id>_optical_frame`)
    sensor: String,
    sensor_id: String,
    /// Wall time to wait for the commands of a step before stepping with the last ones (time
    /// this process ran), in seconds
    command_timeout_s: f64,
    /// At most this many sim seconds per wall second (0: as fast as the loop runs)
    max_rate: f64,
    /// Start once this many subscriptions matched on gripper_status (the policy node, observers)
    wait_subscribers: i32,
    /// ... and this many on image_raw (the contact node, observers)
    wait_image_subscribers: i32,
    /// The gripper's joint in joint_states
    joint_name: String,
    /// Lock-step with the contact node too: once its background is learned (`background`
    /// arrived), wait for the ContactState of the last frame of a step before the gripper
    /// state (up to `command_timeout_s`), so the policy's tick sees the contact of its own time
    /// as in the embedded loop
    sync_contact: bool,
    /// stamped: one GripperCommand per step, stamped with it (the policy's); held: the latest
    /// GripperCommand is a held setpoint (a gripper controller's), steps wait for the arm only
    gripper_commands: String,
    /// Start once this many subscriptions matched on joint_states too (a policy reading them)
    wait_joint_subscribers: i32,
}

impl Default for Params {
    fn default() -> Self {
        Self {
            scene: String::new(),
            task: String::new(),
            split: "train".into(),
            seed: 1,
            trial: 0,
            control_rate_hz: 0.0,
            duration_s: 0.0,
            sensor: "gelsight-mini".into(),
            sensor_id: "gsmini".into(),
            command_timeout_s: 1.0,
            max_rate: 0.0,
            wait_subscribers: 0,
            wait_image_subscribers: 0,
            joint_name: "gripper_finger_opening".into(),
            sync_contact: true,
            gripper_commands: "stamped".into(),
            wait_joint_subscribers: 0,
        }
    }
}

/// The commands received for the step at `stamp`.
#[derive(Default)]
struct Pending {
    gripper: Option<GripperCommand>,
    arm: Option<ArmCommand>,
}

/// The task, control rate and trial length filled in: from the scene (its task, its policy stage's rate) when `scene`
/// is set (a `task` or `control_rate_hz` given as well must agree with it), the defaults
/// otherwise; a `duration_s` of 0 is the task's trial length (`TrialOptions::for_task`).
fn resolve(mut p: Params) -> anyhow::Result<Params> {
    if p.scene.is_empty() {
        if p.task.is_empty() {
            p.task = TaskKind::CUP.name().into();
        }
        if p.control_rate_hz == 0.0 {
            p.control_rate_hz = unitac_policy::PolicyParams::default().control_rate_hz;
        }
    } else {
        let scene = unitac_pipeline::load_scene(&p.scene, None)?;
        let (policy, kind) = unitac_trials::scene::scene_task(&scene)?;
        if !p.task.is_empty() && p.task != kind.name() {
            anyhow::bail!(
                "task:={} but scene {} names the {} task",
                p.task,
                scene.name,
                kind.name()
            );
        }
        if p.control_rate_hz != 0.0 && p.control_rate_hz != policy.control_rate_hz {
            anyhow::bail!(
                "control_rate_hz:={} but scene {}'s policy runs at {} Hz",
                p.control_rate_hz,
                scene.name,
                policy.control_rate_hz
            );
        }
        p.task = kind.name().into();
        p.control_rate_hz = policy.control_rate_hz;
    }
    if p.duration_s == 0.0 {
        if let Ok(k) = TaskKind::named(&p.task, &[]) {
            p.duration_s = unitac_trials::TrialOptions::for_task(k).max_s;
        }
    }
    Ok(p)
}

/// The node's publishers and subscriptions.
struct Io {
    clock: r2r::Publisher<r2r::rosgraph_msgs::msg::Clock>,
    image: r2r::Publisher<r2r::sensor_msgs::msg::Image>,
    status: r2r::Publisher<r2r::unitac_msgs::msg::GripperStatus>,
    joint: r2r::Publisher<r2r::sensor_msgs::msg::JointState>,
    visual: r2r::Publisher<r2r::unitac_msgs::msg::VisualObservation>,
    outcome: r2r::Publisher<r2r::std_msgs::msg::String>,
    cmd: Sub<r2r::unitac_msgs::msg::GripperCommand>,
    arm: Sub<r2r::unitac_msgs::msg::ArmCommand>,
    contact: Sub<r2r::unitac_msgs::msg::ContactState>,
    background: Sub<r2r::sensor_msgs::msg::Image>,
    pause: Sub<r2r::std_msgs::msg::Bool>,
}

/// A subscription's message stream.
type Sub<T> = futures::stream::BoxStream<'static, T>;

impl Io {
    fn new(node: &mut r2r::Node) -> anyhow::Result<Self> {
        let reliable = || QosProfile::default().keep_last(10);
        Ok(Self {
            clock: node.create_publisher("/clock", QosProfile::default())?,
            image: node.create_publisher("image_raw", QosProfile::default())?,
            status: node.create_publisher("gripper_status", reliable())?,
            joint: node.create_publisher("joint_states", reliable())?,
            visual: node.create_publisher("visual_observation", reliable())?,
            outcome: node.create_publisher(
                "sim/outcome",
                QosProfile::default().keep_last(1).transient_local(),
            )?,
            cmd: Box::pin(node.subscribe("gripper_command", reliable())?),
            arm: Box::pin(node.subscribe("arm_command", reliable())?),
            contact: Box::pin(
                node.subscribe("contact_state", QosProfile::default().keep_last(100))?,
            ),
            background: Box::pin(node.subscribe(
                "background",
                QosProfile::default().keep_last(1).transient_local(),
            )?),
            pause: Box::pin(node.subscribe("sim/pause", reliable())?),
        })
    }

    /// Wait (up to 60 s) until the subscriptions the parameters ask for matched; false when
    /// the node was stopped first.
    fn wait_subscribers(&self, base: &mut NodeBase<Params>, p: &Params) -> anyhow::Result<bool> {
        let wanted = usize::try_from(p.wait_subscribers).unwrap_or(0);
        let wanted_images = usize::try_from(p.wait_image_subscribers).unwrap_or(0);
        let wanted_joints = usize::try_from(p.wait_joint_subscribers).unwrap_or(0);
        if wanted + wanted_images + wanted_joints == 0 {
            return Ok(true);
        }
        let count = |n: Result<usize, r2r::Error>| n.unwrap_or(0);
        let matched = || {
            count(self.status.get_inter_process_subscription_count()) >= wanted
                && count(self.image.get_inter_process_subscription_count()) >= wanted_images
                && count(self.joint.get_inter_process_subscription_count()) >= wanted_joints
        };
        if base.spin_until(Duration::from_secs(60), matched) {
            return Ok(true);
        }
        if base.stopped() {
            return Ok(false);
        }
        anyhow::bail!(
            "fewer than {wanted} subscribers on gripper_status, {wanted_images} on image_raw or {wanted_joints} on joint_states within 60 s"
        )
    }
}

/// Lock-step with the contact node: its background learned, the newest ContactState seen, and
/// the steps that went on without their contact.
#[derive(Default)]
struct ContactSync {
    learned: bool,
    seen: Stamp,
    timeouts: u64,
}

impl ContactSync {
    /// Once the background is learned, wait (up to `timeout`) for the ContactState of the
    /// frame stamped `want`.
    fn wait(&mut self, base: &mut NodeBase<Params>, io: &mut Io, want: Stamp, timeout: Duration) {
        let mut waited = Waited::new(timeout);
        loop {
            base.spin(Duration::from_millis(1));
            while let Some(Some(_)) = io.background.next().now_or_never() {
                self.learned = true;
            }
            while let Some(Some(c)) = io.contact.next().now_or_never() {
                self.seen = self.seen.max(convert::stamp(&c.header.stamp));
            }
            if !self.learned || self.seen >= want || base.stopped() {
                return;
            }
            if waited.over() {
                self.timeouts += 1;
                return;
            }
        }
    }
}

/// A wait's time budget, counted in the time this process ran while waiting: each pass of a
/// wait loop adds its wall time up to [`Waited::MAX_PASS`], so a stall of the whole process
/// (stopped by a debugger or SIGSTOP, a paused VM) does not use the budget up while what it
/// waits for sits unread in its queue; a peer that stays silent still ends the wait on time.
struct Waited {
    budget: Duration,
    spent: Duration,
    last: Instant,
}

impl Waited {
    /// The most one pass of a wait loop (a 1 ms spin and the draining) counts.
    const MAX_PASS: Duration = Duration::from_millis(50);

    fn new(budget: Duration) -> Self {
        Self {
            budget,
            spent: Duration::ZERO,
            last: Instant::now(),
        }
    }

    /// Whether the budget is spent, counting the pass since the last call.
    fn over(&mut self) -> bool {
        let now = Instant::now();
        self.spent += now.duration_since(self.last).min(Self::MAX_PASS);
        self.last = now;
        self.spent >= self.budget
    }
}

/// Sim time held between steps on request (`sim/pause`, std_msgs/Bool: true holds, false goes
/// on), as a simulator's pause: the node keeps spinning, so its DDS participant stays alive and
/// announced, where a stopped process (SIGSTOP) lets the other participants' leases run out in
/// its own view and drops what it publishes next until it has found them again.
#[derive(Default)]
struct Pause {
    paused: bool,
}

impl Pause {
    /// Before a step: while paused, spin; true when it held (the pacer then starts over, so the
    /// steps after a pause are paced again rather than run to catch up).
    fn hold(&mut self, base: &mut NodeBase<Params>, io: &mut Io) -> bool {
        let mut held = false;
        loop {
            while let Some(Some(m)) = io.pause.next().now_or_never() {
                self.paused = m.data;
            }
            if !self.paused || base.stopped() {
                return held;
            }
            held = true;
            base.spin(Duration::from_millis(5));
        }
    }
}

/// How the gripper is commanded: stamped commands, one per step (the policy's), or a held
/// setpoint (a gripper controller's).
struct Gripper {
    held_mode: bool,
    held: GripperCommand,
}

impl Gripper {
    fn new(p: &Params, sim: &WorldStepper) -> anyhow::Result<Self> {
        let held_mode = match p.gripper_commands.as_str() {
            "stamped" => false,
            "held" => true,
            other => anyhow::bail!("gripper_commands must be stamped or held, got '{other}'"),
        };
        // Held mode: the setpoint until a controller sends one is to stay where the fingers are
        // (a stop holds with the command's force: the gripper's maximum, as before any command).
        let limits = sim.world().config().gripper;
        let held = GripperCommand {
            header: unitac_core::msg::Header::new(Stamp::ZERO, ""),
            mode: GripperMode::Stop,
            position_m: 0.0,
            speed_m_s: limits.max_speed_m_s,
            force_n: limits.max_force_n,
            reason: "no setpoint yet".into(),
        };
        Ok(Self { held_mode, held })
    }

    /// Wait (up to `timeout`) for the commands stamped `now` (older ones are dropped; a newer
    /// one cannot exist); true when they all came. In held mode the step's gripper command is
    /// the held setpoint.
    fn collect(
        &mut self,
        base: &mut NodeBase<Params>,
        io: &mut Io,
        now: Stamp,
        timeout: Duration,
        counters: &mut diagnostics::Counters,
        pending: &mut Pending,
    ) -> bool {
        let mut waited = Waited::new(timeout);
        let mut answered = false;
        while !base.stopped() && !waited.over() {
            base.spin(Duration::from_millis(1));
            while let Some(Some(c)) = io.cmd.next().now_or_never() {
                match convert::gripper_command_from(&c) {
                    Ok(c) if self.held_mode => self.held = c,
                    c => take(&mut pending.gripper, c, now, counters),
                }
            }
            while let Some(Some(a)) = io.arm.next().now_or_never() {
                take(
                    &mut pending.arm,
                    convert::arm_command_from(&a),
                    now,
                    counters,
                );
            }
            if (self.held_mode || pending.gripper.is_some()) && pending.arm.is_some() {
                answered = true;
                break;
            }
        }
        if self.held_mode {
            let mut c = self.held.clone();
            c.header.stamp = now;
            pending.gripper = Some(c);
        }
        answered
    }
}

/// The world stepper for the node's parameters.
fn stepper(p: &Params) -> anyhow::Result<WorldStepper> {
    let sensor: SensorKind = p.sensor.parse()?;
    let spec = SimSpec {
        task: p.task.clone(),
        split: p.split.clone(),
        seed: u64::try_from(p.seed).map_err(|_| anyhow::anyhow!("seed must be >= 0"))?,
        trial: u32::try_from(p.trial).map_err(|_| anyhow::anyhow!("trial must be in 0..2^32"))?,
        rate_hz: p.control_rate_hz,
        duration_s: p.duration_s,
        sensor,
        sensor_id: p.sensor_id.clone(),
    };
    if !(p.command_timeout_s.is_finite() && p.command_timeout_s > 0.0) {
        anyhow::bail!("command_timeout_s must be > 0, got {}", p.command_timeout_s);
    }
    if !(p.max_rate.is_finite() && p.max_rate >= 0.0) {
        anyhow::bail!("max_rate must be >= 0, got {}", p.max_rate);
    }
    Ok(WorldStepper::for_spec(&spec)?)
}

/// Over-ROS tick timing (a benchmark's figures, reported with the outcome): GripperStatus
/// published -> both commands for it received, and when they arrived (seconds).
#[derive(Default)]
struct TickTimes {
    round_trip_s: Vec<f64>,
    answered_s: Vec<f64>,
}

fn run() -> anyhow::Result<()> {
    let mut base = NodeBase::<Params>::new("unitac_sim", &[])?;
    let p = resolve(base.params()?)?;
    eprintln!(
        "unitac_sim: the {} task at {} Hz for {} s of sim time",
        p.task, p.control_rate_hz, p.duration_s
    );
    let mut sim = stepper(&p)?;
    let mut gripper = Gripper::new(&p, &sim)?;
    let mut io = Io::new(&mut base.node)?;
    let mut sync = ContactSync::default();
    let timeout = Duration::from_secs_f64(p.command_timeout_s);
    let mut diag = diagnostics::Updater::new(
        &format!("unitac_sim: {}", base.node.fully_qualified_name()?),
        &format!("{} {} seed {} trial {}", p.task, p.split, p.seed, p.trial),
    );
    let mut counters = diagnostics::Counters::default();
    if !io.wait_subscribers(&mut base, &p)? {
        return Ok(());
    }
    let start = Instant::now();
    // The one pacer (as the sensor node's and the runtime's sources): step t is due t / max_rate
    // after the first; 0 = unpaced.
    let mut pacer = unitac_core::Pacer::new((p.max_rate > 0.0).then_some(p.max_rate))?;
    let mut steps = 0u64;
    let mut times = TickTimes::default();
    let mut pause = Pause::default();
    while !base.stopped() && !sim.done() {
        if pause.hold(&mut base, &mut io) {
            pacer.restart();
        }
        let t0 = Instant::now();
        let o = sim.observe()?;
        let now = convert::time(o.stamp);
        counters.published(
            io.clock
                .publish(&r2r::rosgraph_msgs::msg::Clock { clock: now.clone() }),
        );
        for f in &o.frames {
            counters.published(io.image.publish(&image::from_frame(f)));
        }
        // Busy: rendering and publishing, not the waits.
        counters.busy_s += t0.elapsed().as_secs_f64();
        if let (true, Some(last)) = (p.sync_contact, o.frames.last()) {
            sync.wait(&mut base, &mut io, last.stamp, timeout);
        }
        // Pace: at most max_rate sim seconds per wall second. The wait is here, between the
        // frames and the tick, so the contact states have that long to reach the policy too
        // (they come from another process than the status: their order there is not given).
        pacer.wait(o.stamp, |slice| {
            base.spin(slice);
            !base.stopped()
        });
        let t1 = Instant::now();
        counters.published(io.visual.publish(&convert::visual_observation(&o.visual)));
        counters.published(
            io.joint
                .publish(&convert::joint_state(&o.gripper, &p.joint_name)),
        );
        counters.published(io.status.publish(&convert::gripper_status(&o.gripper)));
        let sent = Instant::now();
        counters.busy_s += t1.elapsed().as_secs_f64();
        let mut cmds = Pending::default();
        if gripper.collect(
            &mut base,
            &mut io,
            o.stamp,
            timeout,
            &mut counters,
            &mut cmds,
        ) {
            times.round_trip_s.push(sent.elapsed().as_secs_f64());
            times.answered_s.push(start.elapsed().as_secs_f64());
        }
        let r = match (&cmds.gripper, &cmds.arm) {
            (Some(g), Some(a)) => sim.step_commands(Some((g, a))),
            _ => sim.step(None),
        };
        if let Err(e) = r {
            // A refused command (NaN) moves nothing: counted, and the step is taken with the
            // last good command so sim time goes on.
            counters.error(e.to_string());
            sim.step(None)?;
        }
        steps += 1;
        counters.frames_in += 1;
        let extra = [
            ("sim_time_s", format!("{:.3}", sim.time())),
            ("steps", steps.to_string()),
            ("repeated_steps", sim.repeated().to_string()),
            ("contact_timeouts", sync.timeouts.to_string()),
        ];
        if let Some(a) = diag.tick(&mut counters, now, &extra) {
            base.publish_diagnostics(&a)?;
        }
    }
    let outcome = outcome(&p, &sim, steps, sync.timeouts, times);
    println!("{outcome}");
    io.outcome.publish(&r2r::std_msgs::msg::String {
        data: outcome.to_string(),
    })?;
    // Serve the latched outcome until stopped.
    while !base.stopped() {
        base.spin(Duration::from_millis(50));
    }
    Ok(())
}

/// The trial's outcome line: the world's outcome with the node's counts and tick timing.
fn outcome(
    p: &Params,
    sim: &WorldStepper,
    steps: u64,
    contact_timeouts: u64,
    times: TickTimes,
) -> serde_json::Value {
    serde_json::json!({
        "task": p.task,
        "split": p.split,
        "seed": p.seed,
        "trial": p.trial,
        "t_s": sim.time(),
        "steps": steps,
        "repeated_steps": sim.repeated(),
        "contact_timeouts": contact_timeouts,
        "outcome": sim.outcome(),
        // Status published -> its two commands received (DDS both ways + the policy's tick).
        "tick_round_trip": unitac_core::tail(times.round_trip_s),
        // Wall periods between answered ticks (paced by max_rate; a benchmark figure).
        "command_period": unitac_core::period_jitter(&times.answered_s, 1.0 / p.control_rate_hz),
    })
}

/// Keep a command if it is stamped `now`; a bad one is counted as an error.
fn take<T>(
    slot: &mut Option<T>,
    m: Result<T, convert::ConvertError>,
    now: Stamp,
    counters: &mut diagnostics::Counters,
) where
    T: Stamped,
{
    match m {
        Ok(c) if c.stamp() == now => *slot = Some(c),
        Ok(_) => {}
        Err(e) => counters.error(format!("command: {e}")),
    }
}

trait Stamped {
    fn stamp(&self) -> Stamp;
}
impl Stamped for GripperCommand {
    fn stamp(&self) -> Stamp {
        self.header.stamp
    }
}
impl Stamped for ArmCommand {
    fn stamp(&self) -> Stamp {
        self.header.stamp
    }
}

fn main() -> std::process::ExitCode {
    unitac_ros::node::main_of("unitac_sim_node", run)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::Waited;
    use std::time::Duration;

    #[test]
    fn a_stall_of_the_process_uses_at_most_one_pass_of_a_wait() {
        let mut w = Waited::new(Duration::from_millis(200));
        // A stop of the whole process (SIGSTOP) looks like one long pass.
        std::thread::sleep(Duration::from_millis(400));
        assert!(!w.over());
        std::thread::sleep(Duration::from_millis(400));
        assert!(!w.over(), "two stalls count two passes at most (100 ms)");
    }

    #[test]
    fn a_silent_peer_still_ends_the_wait() {
        let mut w = Waited::new(Duration::from_millis(60));
        // Each pass sleeps at least 5 ms, so the 60 ms are spent by the 12th at the latest.
        let passes = (1..=12).find(|_| {
            std::thread::sleep(Duration::from_millis(5));
            w.over()
        });
        assert!(passes.is_some());
    }
}
