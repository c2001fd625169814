//! Policy node: the scene's `policy` stage (observation assembly, scene controller, safety layer)
//! on a tokio runtime. The gripper state in (`gripper_status`, unitac_msgs/GripperStatus from the
//! sim or a driver, or `joint_states`, sensor_msgs/JointState: `gripper_input`), and what the
//! scene's mode reads: `contact_state`, `tactile_latent` (real or predicted), `property_comparison`,
//! `visual_observation`; GripperCommand (`gripper_command`), ArmCommand (`arm_command`) and
//! PolicyStatus (`policy_status`) out, one each per control tick; the arm target also as
//! geometry_msgs/PoseStamped (`arm_pose`, in `arm_frame`; none for `home`) for a Cartesian
//! controller or MoveIt Servo; /diagnostics once a second.
//!
//! With `gripper_output: action` the gripper commands go to a ros2_control gripper controller
//! instead: a `control_msgs/action/GripperCommand` client of `gripper_action` sends a goal
//! (position, max_effort) when the command changes, and what the goals' results and feedback say
//! (stall = object caught, abort, preemption by another client, no server) is merged into the
//! gripper state from `joint_states` before the stage sees it (unitac_gripper::action), so a
//! fault there reaches the same safety layer and gets the safe action on the next tick.
//!
//! The stage runs in the one chain driver (`unitac_core::Chain`, as in every other node and the
//! embedded runtime): its clock is its input's stamp (the latest stamp seen), and a control tick
//! is the arrival of a gripper state at the control rate. What only a transport can see goes
//! through the stage hooks, on tokio timers in one `select!` with the inputs and the signals (no
//! sleep-polling):
//! - the control interval: the chain's timer hook (`Chain::timer(now)`, now on the node's ROS
//!   clock: sim time under `use_sim_time`) at the stage's timer period; the policy's watchdog
//!   sends the safe action with the reason when no gripper state came for the due tick;
//! - producers: on every control interval and before every gripper tick, the publisher count of
//!   each input topic the current phase awaits (`awaited_inputs`) is read from the ROS graph; none
//!   left marks the input lost (`set_input_lost`), so the next tick sends the safe action with
//!   `<input>: no publisher on <topic>`;
//! - SIGINT / SIGTERM end the loop; the node stops spinning and exits 0.

use futures::channel::mpsc;
use futures::future::LocalBoxFuture;
use futures::stream::{BoxStream, FuturesUnordered, SelectAll};
use futures::{FutureExt, StreamExt};
use r2r::{QosProfile, RosParams};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tokio::signal::unix::{SignalKind, signal};
use unitac_core::msg::GripperStatus;
use unitac_core::{Chain, Msg, Stamp};
use unitac_gripper::GripperSetpoint;
use unitac_gripper::action::{ActionLink, Goal, GoalEnd, Report, Resend};
use unitac_pipeline::StageConfig;
use unitac_policy::PolicyStage;
use unitac_ros::node::{AsyncNode, ros_now, spin_in_background};
use unitac_ros::{convert, diagnostics};

/// The node's own parameters. The policy stage's come from the scene file's policy stage;
/// override one with `policy.<key>` (e.g. `-p policy.control_rate_hz:=20.0`).
#[derive(RosParams, Debug, Clone)]
struct Params {
    /// Scene: a scene name (looked up like `unitac run --scene`) or a path to a scene YAML
    scene: String,
    /// gripper_status: unitac_msgs/GripperStatus on `gripper_status`; joint_states:
    /// sensor_msgs/JointState on `joint_states` (position = opening, effort = force)
    gripper_input: String,
    /// The gripper's joint in joint_states (empty: the only joint)
    joint_name: String,
    /// gripper_command: unitac_msgs/GripperCommand on `gripper_command` (the serial gripper
    /// node, the sim); action: goals for a control_msgs/action/GripperCommand server
    /// (`gripper_action`; use with gripper_input joint_states)
    gripper_output: String,
    /// The GripperCommand action server (gripper_output action)
    gripper_action: String,
    /// TF frame of `arm_pose`: the frame of the policy's table coordinates
    arm_frame: String,
    /// The tool's orientation in `arm_frame` for `arm_pose`: roll, pitch, yaw in radians (default:
    /// turned over, fingers pointing down a z-up frame)
    tool_roll: f64,
    tool_pitch: f64,
    tool_yaw: f64,
}

impl Default for Params {
    fn default() -> Self {
        Self {
            scene: "cup_deformation_vtla_real".into(),
            gripper_input: "gripper_status".into(),
            joint_name: "gripper_finger_opening".into(),
            gripper_output: "gripper_command".into(),
            gripper_action: "/gripper_controller/gripper_cmd".into(),
            arm_frame: "base_link".into(),
            tool_roll: std::f64::consts::PI,
            tool_pitch: 0.0,
            tool_yaw: 0.0,
        }
    }
}

const STAGES: &[&str] = &["policy"];

/// The topic (relative) an input of the policy arrives on.
fn topic_of(input: &str, p: &Params) -> &'static str {
    match input {
        "gripper" if p.gripper_input == "joint_states" => "joint_states",
        "gripper" => "gripper_status",
        "contact" => "contact_state",
        "latent_real" | "latent_pred" => "tactile_latent",
        "comparison" => "property_comparison",
        _ => "visual_observation",
    }
}

/// A converted input, or why its message was refused (with its topic).
type Incoming = anyhow::Result<Msg>;

/// The subscriptions the mode's inputs need, merged into one stream.
fn subscribe(
    node: &mut r2r::Node,
    inputs: &[&str],
    p: &Params,
) -> anyhow::Result<SelectAll<BoxStream<'static, Incoming>>> {
    let mut all = SelectAll::new();
    let reliable = || QosProfile::default().keep_last(10);
    let err =
        |topic: &'static str| move |e: convert::ConvertError| anyhow::Error::new(e).context(topic);
    for input in inputs {
        match *input {
            "gripper" if p.gripper_input == "joint_states" => {
                let joint = p.joint_name.clone();
                let s = node
                    .subscribe::<r2r::sensor_msgs::msg::JointState>("joint_states", reliable())?;
                all.push(
                    s.map(move |m| {
                        convert::gripper_status_from_joint_state(&m, &joint)
                            .map(Msg::GripperStatus)
                            .map_err(err("joint_states"))
                    })
                    .boxed(),
                );
            }
            "gripper" => {
                let s = node.subscribe::<r2r::unitac_msgs::msg::GripperStatus>(
                    "gripper_status",
                    reliable(),
                )?;
                all.push(
                    s.map(move |m| {
                        convert::gripper_status_from(&m)
                            .map(Msg::GripperStatus)
                            .map_err(err("gripper_status"))
                    })
                    .boxed(),
                );
            }
            "contact" => {
                let s = node.subscribe::<r2r::unitac_msgs::msg::ContactState>(
                    "contact_state",
                    reliable(),
                )?;
                all.push(
                    s.map(move |m| {
                        convert::contact_state_from(&m)
                            .map(Msg::ContactState)
                            .map_err(err("contact_state"))
                    })
                    .boxed(),
                );
            }
            // One subscription for either latent (the inference node publishes both on it,
            // transient-local: a latent predicted before this node started still arrives).
            "latent_real" | "latent_pred" => {
                if inputs.contains(&"latent_real") && *input == "latent_pred" {
                    continue;
                }
                let s = node.subscribe::<r2r::unitac_msgs::msg::TactileLatent>(
                    "tactile_latent",
                    reliable().transient_local(),
                )?;
                all.push(
                    s.map(move |m| {
                        convert::tactile_latent_from(&m)
                            .map(Msg::TactileLatent)
                            .map_err(err("tactile_latent"))
                    })
                    .boxed(),
                );
            }
            "comparison" => {
                let s = node.subscribe::<r2r::unitac_msgs::msg::PropertyComparison>(
                    "property_comparison",
                    reliable(),
                )?;
                all.push(
                    s.map(move |m| {
                        convert::property_comparison_from(&m)
                            .map(Msg::PropertyComparison)
                            .map_err(err("property_comparison"))
                    })
                    .boxed(),
                );
            }
            "visual" => {
                let s = node.subscribe::<r2r::unitac_msgs::msg::VisualObservation>(
                    "visual_observation",
                    reliable(),
                )?;
                all.push(
                    s.map(move |m| {
                        convert::visual_observation_from(&m)
                            .map(Msg::VisualObservation)
                            .map_err(err("visual_observation"))
                    })
                    .boxed(),
                );
            }
            other => anyhow::bail!("the policy reads '{other}', which this node cannot subscribe"),
        }
    }
    Ok(all)
}

/// The policy stage of the scene, built from its typed params (the same registry path as every
/// transport), kept concrete for its watchdog API.
fn build(
    p: &Params,
    overrides: &[(String, serde_yaml::Value)],
) -> anyhow::Result<(String, PolicyStage)> {
    let (scene, configs) =
        unitac_ros::scene_configs("unitac_policy_node", &p.scene, STAGES, overrides)?;
    let Some(StageConfig::Policy {
        params,
        scene: name,
        model,
    }) = configs.into_iter().next()
    else {
        anyhow::bail!("scene '{}' has no policy stage", scene.name);
    };
    let stage = PolicyStage::load(&name, *params, model.as_deref())?;
    Ok((name.clone(), stage))
}

type GripperAction = r2r::control_msgs::action::GripperCommand::Action;

/// Where the gripper commands go.
enum GripperOut {
    Topic(r2r::Publisher<r2r::unitac_msgs::msg::GripperCommand>),
    Action {
        client: r2r::ActionClient<GripperAction>,
        link: ActionLink,
        events: mpsc::UnboundedSender<ActionEvent>,
        /// Goals under way: each ends with its result.
        goals: FuturesUnordered<LocalBoxFuture<'static, ()>>,
        /// The action server's fully qualified name.
        name: String,
    },
}

/// What the action server said about goal `.0`.
enum ActionEvent {
    Answered(u64, bool),
    Feedback(u64, Report),
    Finished(u64, GoalEnd, Report),
    Failed(u64, String),
}

fn report(position: f64, effort: f64, stalled: bool, reached_goal: bool) -> Report {
    Report {
        position_m: position,
        effort_n: effort,
        stalled,
        reached_goal,
    }
}

/// Goal `id` to the server; its answer, feedback and result come back on `events`.
fn send_goal(
    client: &r2r::ActionClient<GripperAction>,
    id: u64,
    goal: Goal,
    events: mpsc::UnboundedSender<ActionEvent>,
) -> LocalBoxFuture<'static, ()> {
    use r2r::control_msgs::action::GripperCommand as G;
    let msg = G::Goal {
        command: r2r::control_msgs::msg::GripperCommand {
            position: goal.position_m,
            max_effort: goal.max_effort_n,
        },
    };
    let sent = client.send_goal_request(msg);
    async move {
        let send = |e: ActionEvent| {
            // (The receiver lives as long as the node's loop.)
            let _ = events.unbounded_send(e);
        };
        let accepted = match sent {
            Err(e) => return send(ActionEvent::Failed(id, format!("goal not sent: {e}"))),
            Ok(f) => f.await,
        };
        let (_handle, result, mut feedback) = match accepted {
            Err(r2r::Error::RCL_RET_ACTION_GOAL_REJECTED) => {
                return send(ActionEvent::Answered(id, false));
            }
            Err(e) => return send(ActionEvent::Failed(id, format!("goal lost: {e}"))),
            Ok(a) => a,
        };
        send(ActionEvent::Answered(id, true));
        let mut result = std::pin::pin!(result);
        loop {
            tokio::select! {
                f = feedback.next() => {
                    if let Some(f) = f {
                        send(ActionEvent::Feedback(
                            id,
                            report(f.position, f.effort, f.stalled, f.reached_goal),
                        ));
                    }
                }
                r = &mut result => {
                    match r {
                        Ok((status, r)) => {
                            let end = match status {
                                r2r::GoalStatus::Succeeded => GoalEnd::Succeeded,
                                r2r::GoalStatus::Canceled => GoalEnd::Canceled,
                                _ => GoalEnd::Aborted,
                            };
                            send(ActionEvent::Finished(
                                id,
                                end,
                                report(r.position, r.effort, r.stalled, r.reached_goal),
                            ));
                        }
                        Err(e) => send(ActionEvent::Failed(id, format!("no result: {e}"))),
                    }
                    return;
                }
            }
        }
    }
    .boxed_local()
}

/// Count the ticks among `out` (their PolicyStatus) by what they sent.
fn count_ticks(out: &[Msg], ticks: &mut unitac_policy::TickCounts) {
    for m in out {
        if let Msg::PolicyStatus(s) = m {
            ticks.count(s);
        }
    }
}

struct Publishers {
    gripper: GripperOut,
    arm: r2r::Publisher<r2r::unitac_msgs::msg::ArmCommand>,
    pose: r2r::Publisher<r2r::geometry_msgs::msg::PoseStamped>,
    status: r2r::Publisher<r2r::unitac_msgs::msg::PolicyStatus>,
    arm_frame: String,
    tool_rpy: [f64; 3],
    /// The latest measured opening (a STOP holds it).
    opening_m: Option<f64>,
}

impl Publishers {
    fn publish(&mut self, out: Vec<Msg>, counters: &mut diagnostics::Counters, last: &mut String) {
        for m in out {
            let r = match &m {
                Msg::GripperCommand(c) => match &mut self.gripper {
                    GripperOut::Topic(p) => p.publish(&convert::gripper_command(c)),
                    GripperOut::Action {
                        client,
                        link,
                        events,
                        goals,
                        ..
                    } => {
                        match GripperSetpoint::from_command(c, self.opening_m) {
                            Some(cmd) => {
                                if let Some((id, goal)) = link.command(&cmd, c.header.stamp) {
                                    goals.push(send_goal(client, id, goal, events.clone()));
                                }
                            }
                            None => counters.error("gripper: STOP before a measured opening"),
                        }
                        continue;
                    }
                },
                Msg::ArmCommand(a) => {
                    if let Some(p) = convert::arm_pose(a, &self.arm_frame, self.tool_rpy) {
                        counters.published(self.pose.publish(&p));
                    }
                    self.arm.publish(&convert::arm_command(a))
                }
                Msg::PolicyStatus(s) => {
                    *last = format!(
                        "{} ({})",
                        s.phase,
                        if s.safety_ok { "ok" } else { &s.message }
                    );
                    self.status.publish(&convert::policy_status(s))
                }
                _ => continue,
            };
            counters.published(r);
        }
    }

    /// A measured gripper state as the stage sees it: with the action's view merged in.
    fn gripper_state(&mut self, g: GripperStatus) -> GripperStatus {
        self.opening_m = g.opening_m.is_finite().then_some(g.opening_m);
        match &self.gripper {
            GripperOut::Topic(_) => g,
            GripperOut::Action { link, .. } => link.status(g),
        }
    }

    /// What the action server said. A new fault goes to the log when it is heard (the policy
    /// acts on it at its next tick).
    fn action_event(&mut self, e: ActionEvent) {
        if let GripperOut::Action { link, .. } = &mut self.gripper {
            let before = link.fault().map(str::to_owned);
            match e {
                ActionEvent::Answered(id, ok) => link.answered(id, ok),
                ActionEvent::Feedback(id, r) => link.feedback(id, &r),
                ActionEvent::Finished(id, end, r) => link.finished(id, end, &r),
                ActionEvent::Failed(id, why) => link.send_failed(id, &why),
            }
            if let Some(f) = link.fault().filter(|f| before.as_deref() != Some(*f)) {
                eprintln!("unitac_policy: {f}");
            }
        }
    }
}

/// Watches the publishers of the inputs the current phase awaits, through the ROS graph.
struct Producers {
    node: Arc<Mutex<r2r::Node>>,
    /// Fully qualified topic per input.
    topics: Vec<(&'static str, String)>,
}

impl Producers {
    /// Mark each awaited input whose topic has no publisher lost, and every other one not.
    fn check(&self, chain: &mut Chain) -> anyhow::Result<()> {
        let awaited = chain.awaited_inputs();
        for (input, topic) in &self.topics {
            let lost = if awaited.contains(input) {
                let n = self
                    .node
                    .lock()
                    .map_err(|_| anyhow::anyhow!("node lock poisoned"))?
                    .get_publishers_info_by_topic(topic, false)?
                    .len();
                (n == 0).then(|| format!("no publisher on {topic}"))
            } else {
                None
            };
            chain.set_input_lost(input, lost)?;
        }
        Ok(())
    }
}

impl Producers {
    /// Why the gripper action server `name` (fully qualified) is not there, or None when it is
    /// (a server publishes its goals' status).
    fn action_server_missing(&self, name: &str) -> anyhow::Result<Option<String>> {
        let topic = format!("{name}/_action/status");
        let n = self
            .node
            .lock()
            .map_err(|_| anyhow::anyhow!("node lock poisoned"))?
            .get_publishers_info_by_topic(&topic, false)?
            .len();
        Ok((n == 0).then(|| format!("gripper action: no server on {name}")))
    }
}

/// `topic` (relative) in the node's namespace, as the graph names it.
fn qualified(namespace: &str, topic: &str) -> String {
    format!("{}/{topic}", namespace.trim_end_matches('/'))
}

/// The node's own parameters checked: the gripper's input and output, the tool orientation
/// (returned).
fn check_params(p: &Params) -> anyhow::Result<[f64; 3]> {
    if !matches!(p.gripper_input.as_str(), "gripper_status" | "joint_states") {
        anyhow::bail!(
            "gripper_input must be gripper_status or joint_states, got '{}'",
            p.gripper_input
        );
    }
    if !matches!(p.gripper_output.as_str(), "gripper_command" | "action") {
        anyhow::bail!(
            "gripper_output must be gripper_command or action, got '{}'",
            p.gripper_output
        );
    }
    let tool_rpy = [p.tool_roll, p.tool_pitch, p.tool_yaw];
    if tool_rpy.iter().any(|v| !v.is_finite()) {
        anyhow::bail!("tool_roll, tool_pitch and tool_yaw must be finite, got {tool_rpy:?}");
    }
    Ok(tool_rpy)
}

/// The gripper's output by `gripper_output`: the GripperCommand topic, or an action client whose
/// goals' events come back on `events`.
fn gripper_out(
    node: &mut r2r::Node,
    p: &Params,
    namespace: &str,
    events: mpsc::UnboundedSender<ActionEvent>,
) -> anyhow::Result<GripperOut> {
    if p.gripper_output != "action" {
        return Ok(GripperOut::Topic(
            node.create_publisher("gripper_command", QosProfile::default())?,
        ));
    }
    let name = if p.gripper_action.starts_with('/') {
        p.gripper_action.clone()
    } else {
        qualified(namespace, &p.gripper_action)
    };
    let client = node.create_action_client::<GripperAction>(&name)?;
    Ok(GripperOut::Action {
        client,
        link: ActionLink::new(Resend::default()),
        events,
        goals: FuturesUnordered::new(),
        name,
    })
}

/// The control loop's state: the chain, the outputs, the graph watch and the counts.
struct Policy {
    chain: Chain,
    pubs: Publishers,
    producers: Producers,
    clock: Arc<Mutex<r2r::Clock>>,
    counters: diagnostics::Counters,
    watchdog_ticks: u64,
    last_status: String,
    /// Every tick by what it sent (the policy's action, or the safe action and why).
    ticks: unitac_policy::TickCounts,
}

impl Policy {
    /// The producers and the action server as they are now, so a loss shows in this tick.
    fn check_graph(&mut self) {
        if let Err(e) = self.producers.check(&mut self.chain) {
            self.counters.error(format!("graph: {e:#}"));
        }
        check_server(&self.producers, &mut self.pubs, &mut self.counters);
    }

    /// An input message (a gripper state is a tick) through the chain.
    fn message(&mut self, m: Incoming) {
        self.counters.frames_in += 1;
        let t0 = Instant::now();
        let m = match m {
            Ok(Msg::GripperStatus(g)) => {
                self.check_graph();
                Msg::GripperStatus(self.pubs.gripper_state(g))
            }
            Ok(m) => m,
            Err(e) => {
                self.counters.error(format!("{e:#}"));
                return;
            }
        };
        let stamp = m.stamp();
        let out = self.chain.run(m);
        for e in &out.errors {
            self.counters.error(e.error.clone());
        }
        if !out.produced.is_empty() {
            self.counters.latency(age_s(&self.clock, stamp));
        }
        count_ticks(&out.produced, &mut self.ticks);
        self.pubs
            .publish(out.produced, &mut self.counters, &mut self.last_status);
        self.counters.busy_s += t0.elapsed().as_secs_f64();
    }

    /// The control interval: the chain's timer hook (the watchdog) at the node's clock.
    fn control(&mut self) {
        self.check_graph();
        let now = convert::stamp(&ros_now(&self.clock));
        let out = self.chain.timer(now);
        for e in &out.errors {
            self.counters.error(e.error.clone());
        }
        if !out.produced.is_empty() {
            self.watchdog_ticks += 1;
            count_ticks(&out.produced, &mut self.ticks);
            self.pubs
                .publish(out.produced, &mut self.counters, &mut self.last_status);
        }
    }

    /// The diagnostics, when one is due.
    fn diagnostics(
        &mut self,
        diag: &mut diagnostics::Updater,
        pub_diag: &r2r::Publisher<r2r::diagnostic_msgs::msg::DiagnosticArray>,
    ) {
        let mut extra = vec![
            ("status", self.last_status.clone()),
            ("watchdog_ticks", self.watchdog_ticks.to_string()),
        ];
        extra.extend(diagnostics::policy_ticks(&self.ticks));
        // A policy that fails (an error, over its time limit, refused) is a warning.
        self.counters.warnings = self.ticks.failed();
        if let GripperOut::Action { link, name, .. } = &self.pubs.gripper {
            extra.push(("gripper_action", name.clone()));
            extra.push(("gripper_goals_sent", link.goals_sent().to_string()));
            extra.push((
                "gripper_action_fault",
                link.fault().unwrap_or("none").to_string(),
            ));
        }
        if let Some(a) = diag.tick(&mut self.counters, ros_now(&self.clock), &extra) {
            if let Err(e) = pub_diag.publish(&a) {
                self.counters.error(format!("diagnostics: {e}"));
            }
        }
    }
}

/// A tokio interval that delays (control) or skips (diagnostics) missed ticks.
fn interval(period: Duration, missed: tokio::time::MissedTickBehavior) -> tokio::time::Interval {
    let mut i = tokio::time::interval(period);
    i.set_missed_tick_behavior(missed);
    i
}

async fn run_async() -> anyhow::Result<()> {
    let AsyncNode {
        mut node,
        params: p,
        overrides,
        param_handler,
        clock,
        diagnostics: pub_diag,
    } = AsyncNode::<Params>::new("unitac_policy", STAGES)?;
    let tool_rpy = check_params(&p)?;
    let (scene, stage) = build(&p, &overrides)?;
    let inputs = stage.inputs();
    let mut incoming = subscribe(&mut node, &inputs, &p)?;
    let reliable = QosProfile::default;
    let namespace = node.namespace()?;
    let (events_tx, mut events) = mpsc::unbounded::<ActionEvent>();
    let pubs = Publishers {
        gripper: gripper_out(&mut node, &p, &namespace, events_tx)?,
        arm: node.create_publisher("arm_command", reliable())?,
        pose: node.create_publisher("arm_pose", reliable())?,
        status: node.create_publisher("policy_status", reliable())?,
        arm_frame: p.arm_frame.clone(),
        tool_rpy,
        opening_m: None,
    };
    let mut diag = diagnostics::Updater::new(
        &format!("unitac_policy: {}", node.fully_qualified_name()?),
        &scene,
    );
    let node = Arc::new(Mutex::new(node));
    let mut policy = Policy {
        // The stage through the one chain driver (its clock rule, its timer hook: the watchdog).
        chain: Chain::new(vec![Box::new(stage)]),
        pubs,
        producers: Producers {
            node: node.clone(),
            topics: inputs
                .iter()
                .map(|i| (*i, qualified(&namespace, topic_of(i, &p))))
                .collect(),
        },
        clock,
        counters: diagnostics::Counters::default(),
        watchdog_ticks: 0,
        last_status: String::new(),
        ticks: unitac_policy::TickCounts::default(),
    };
    tokio::spawn(param_handler);
    let stop = Arc::new(AtomicBool::new(false));
    let spinner = spin_in_background(node.clone(), stop.clone());

    let mut sigint = signal(SignalKind::interrupt())?;
    let mut sigterm = signal(SignalKind::terminate())?;
    let period = policy
        .chain
        .timer_period_ns()
        .and_then(|ns| u64::try_from(ns).ok())
        .map_or(Duration::from_millis(33), Duration::from_nanos);
    use tokio::time::MissedTickBehavior::{Delay, Skip};
    let mut control = interval(period, Delay);
    let mut diag_timer = interval(Duration::from_millis(200), Skip);
    loop {
        tokio::select! {
            m = incoming.next() => {
                let Some(m) = m else { break };
                policy.message(m);
            }
            Some(e) = events.next() => policy.pubs.action_event(e),
            Some(()) = next_goal(&mut policy.pubs) => {}
            _ = control.tick() => policy.control(),
            _ = diag_timer.tick() => policy.diagnostics(&mut diag, &pub_diag),
            _ = sigint.recv() => break,
            _ = sigterm.recv() => break,
        }
    }
    stop.store(true, Ordering::SeqCst);
    spinner.await?;
    Ok(())
}

/// Mark the gripper action server missing or present (nothing without one).
fn check_server(
    producers: &Producers,
    pubs: &mut Publishers,
    counters: &mut diagnostics::Counters,
) {
    let GripperOut::Action { link, name, .. } = &mut pubs.gripper else {
        return;
    };
    match producers.action_server_missing(name) {
        Ok(missing) => link.set_server_missing(missing),
        Err(e) => counters.error(format!("graph: {e:#}")),
    }
}

/// The next goal under way to end (pending forever without one).
async fn next_goal(pubs: &mut Publishers) -> Option<()> {
    match &mut pubs.gripper {
        GripperOut::Action { goals, .. } if !goals.is_empty() => goals.next().await,
        _ => std::future::pending().await,
    }
}

/// Seconds from `stamp` to now on the node's clock.
fn age_s(clock: &Mutex<r2r::Clock>, stamp: Stamp) -> f64 {
    let now = convert::stamp(&ros_now(clock));
    (now.0 - stamp.0) as f64 * 1e-9
}

fn run() -> anyhow::Result<()> {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()?
        .block_on(run_async())
}

fn main() -> std::process::ExitCode {
    unitac_ros::node::main_of("unitac_policy_node", run)
}
