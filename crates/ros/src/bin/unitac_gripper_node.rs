//! Gripper node: a serial gripper (Robotiq 2F-85/2F-140, DH AG-95/PGE over Modbus RTU) driven by
//! `unitac_msgs/GripperCommand`, its state published as `sensor_msgs/JointState` and a status.
//!
//! The Modbus I/O runs on the driver's own thread (unitac-gripper), so this loop never waits for
//! the device: a silent, faulted or unplugged gripper shows up in the status and /diagnostics
//! while commands keep being accepted. On start the driver reads the status first and leaves an
//! active gripper as it is (it never writes rACT = 0 on start), so restarting the node does not
//! drop a held object.
//!
//! Topics (relative): `gripper_command` in; `joint_states` (one joint, `joint_name`: position =
//! finger opening (m), effort = grip force (N) where the device gives one, else motor current
//! (A)) and `gripper_status` (unitac_msgs/GripperStatus: opening, target, force, current, object
//! detection, activation, motion, fault; frame_id `frame_id`) out, both on every new reading;
//! /diagnostics once a second: exchange rate, round trip p50/p99, retries, link errors, the fault.

use futures::{FutureExt, StreamExt};
use r2r::{QosProfile, RosParams};
use std::time::Duration;
use unitac_gripper::{DriverConfig, Gripper, GripperSetpoint, Model, SerialGripper};
use unitac_ros::diagnostics;
use unitac_ros::node::NodeBase;

#[derive(RosParams, Debug, Clone)]
struct Params {
    /// Serial port, best its stable name under /dev/serial/by-id
    port: String,
    /// robotiq_2f85 | robotiq_2f140 | dh_ag95 | dh_pge50
    model: String,
    /// Modbus slave id (0: the model's factory id, Robotiq 9, DH 1)
    slave_id: i64,
    /// Modbus exchanges per second (Robotiq allows up to 200)
    rate_hz: f64,
    /// Activate an inactive gripper at start (an active one is left alone)
    activate: bool,
    /// Joint name in joint_states
    joint_name: String,
    /// frame_id of joint_states and gripper_status
    frame_id: String,
}

impl Default for Params {
    fn default() -> Self {
        Self {
            port: "/dev/ttyUSB0".into(),
            model: "robotiq_2f85".into(),
            slave_id: 0,
            rate_hz: 100.0,
            activate: true,
            joint_name: "gripper_finger_opening".into(),
            frame_id: "gripper_base".into(),
        }
    }
}

fn run() -> anyhow::Result<()> {
    let mut base = NodeBase::<Params>::new("unitac_gripper", &[])?;
    let p = base.params()?;
    let model: Model = p.model.parse()?;
    let mut cfg = DriverConfig::new(&p.port, model);
    if p.slave_id != 0 {
        cfg.slave = u8::try_from(p.slave_id)
            .ok()
            .filter(|s| (1..=247).contains(s))
            .ok_or_else(|| anyhow::anyhow!("slave_id {} is not in 1..=247", p.slave_id))?;
    }
    if !(p.rate_hz.is_finite() && p.rate_hz > 0.0 && p.rate_hz <= 1000.0) {
        anyhow::bail!("rate_hz {} is not in (0, 1000]", p.rate_hz);
    }
    cfg.rate_hz = p.rate_hz;
    let mut gripper = SerialGripper::start(cfg)?;
    if p.activate {
        gripper.activate()?;
    }
    let node = &mut base.node;
    let mut commands = node.subscribe::<r2r::unitac_msgs::msg::GripperCommand>(
        "gripper_command",
        QosProfile::default().keep_last(10),
    )?;
    let pub_joint = node.create_publisher::<r2r::sensor_msgs::msg::JointState>(
        "joint_states",
        QosProfile::default(),
    )?;
    let pub_status = node.create_publisher::<r2r::unitac_msgs::msg::GripperStatus>(
        "gripper_status",
        QosProfile::default(),
    )?;
    let mut diag = diagnostics::Updater::new(
        &format!("unitac_gripper: {}", node.fully_qualified_name()?),
        &format!("{model} on {}", gripper.stats().port.display()),
    );
    let mut counters = diagnostics::Counters::default();
    let mut last_update = 0u64;
    let mut command_errors = 0u64;
    while !base.stopped() {
        base.spin(Duration::from_millis(2));
        while let Some(Some(c)) = commands.next().now_or_never() {
            let now = gripper.state().opening_m;
            let r = match unitac_ros::convert::gripper_command_from(&c) {
                Err(e) => Err(e.to_string()),
                Ok(c) => match GripperSetpoint::from_command(&c, now) {
                    Some(cmd) => gripper.command(cmd).map_err(|e| e.to_string()),
                    None => Err("STOP before the first measured opening".to_string()),
                },
            };
            if let Err(e) = r {
                command_errors += 1;
                counters.last_error = format!("gripper_command: {e}");
            }
        }
        let s = gripper.state();
        if s.updates != last_update {
            last_update = s.updates;
            let now = base.now();
            let mut js = r2r::sensor_msgs::msg::JointState::default();
            js.header.stamp = now.clone();
            js.header.frame_id = p.frame_id.clone();
            js.name = vec![p.joint_name.clone()];
            js.position = vec![s.opening_m.unwrap_or(f64::NAN)];
            js.effort = vec![s.force_n.or(s.current_a).unwrap_or(f64::NAN)];
            counters.published(pub_joint.publish(&js));
            let status =
                unitac_gripper::status::status(&s, unitac_ros::convert::stamp(&now), &p.frame_id);
            counters.published(pub_status.publish(&unitac_ros::convert::gripper_status(&status)));
        }
        let st = gripper.stats();
        counters.frames_in = st.cycles;
        let ms = |x: Option<f64>| x.map_or("-".into(), |v| format!("{:.3}", v * 1e3));
        let fault = match &s.fault {
            None => "none".to_string(),
            Some(f) => serde_json::to_string(f)?,
        };
        if let Some(e) = &st.last_error {
            counters.last_error = e.clone();
        }
        let extra = [
            ("connected", st.connected.to_string()),
            ("activation", format!("{:?}", s.activation)),
            ("motion", format!("{:?}", s.motion)),
            ("fault", fault),
            ("exchange_rate_hz", format!("{:.1}", st.rate_hz)),
            ("rtt_p50_ms", ms(st.rtt_p50_s)),
            ("rtt_p99_ms", ms(st.rtt_p99_s)),
            ("retries", st.link.retries.to_string()),
            ("no_reply", st.link.no_reply.to_string()),
            ("incomplete", st.link.incomplete.to_string()),
            ("garbled", st.link.garbled.to_string()),
            ("wrong_slave", st.link.wrong_slave.to_string()),
            ("port_opens", st.opens.to_string()),
            ("clamped_commands", st.clamped_commands.to_string()),
            (
                "last_clamp",
                st.last_clamp.clone().unwrap_or_else(|| "-".into()),
            ),
        ];
        // Failed exchanges and refused commands; publish errors are counted by `published`.
        let l = &st.link;
        counters.errors = counters.errors.max(
            command_errors + l.no_reply + l.incomplete + l.garbled + l.wrong_slave + l.exceptions,
        );
        if let Some(a) = diag.tick(&mut counters, base.now(), &extra) {
            base.publish_diagnostics(&a)?;
        }
    }
    gripper.stop();
    Ok(())
}

fn main() -> std::process::ExitCode {
    unitac_ros::node::main_of("unitac_gripper_node", run)
}
