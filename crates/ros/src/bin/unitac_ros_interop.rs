//! Interop peer for the ROS tests (and a quick check on a robot that unitac_msgs work end to end).
//!
//! `unitac_ros_interop publish [--topic-prefix P]`: waits for a subscriber, then publishes the
//!   fixture ContactState, PropertyComparison and ArmCommand every 200 ms until the subscriber
//!   leaves (at most 30 s): the subscriber can match this writer well after this writer matched
//!   it, and messages sent before that are lost with the process once it exits.
//! `unitac_ros_interop echo [--topic-prefix P]`: prints the first TactileLatent, GripperCommand,
//!   GripperStatus and VisualObservation it receives as JSON lines on stdout, then exits.
//! Exit code 1 on timeout, 2 on bad usage.

use anyhow::{Context, bail};
use futures::{FutureExt, StreamExt};
use r2r::QosProfile;
use r2r::unitac_msgs::msg as ros;
use std::time::Duration;
use unitac_core::Stamp;
use unitac_core::msg::{ArmCommand, ContactState, Header, Msg, PropertyComparison, Winner};
use unitac_ros::convert::{self, ConvertError};
use unitac_ros::spin_until;

const TIMEOUT: Duration = Duration::from_secs(30);

/// The values the peer must see (tests/ros/peer.py checks the same numbers).
fn fixture_contact() -> ContactState {
    ContactState {
        header: Header::new(Stamp(1_700_000_001_250_000_000), "gsmini_optical_frame"),
        sensor_id: "GS-0A1B-2C3D".into(),
        frame_seq: 4_294_967_301,
        in_contact: true,
        area_px: 1234.5,
        area_m2: 4.9619e-6,
        centroid_px: [160.25, 119.75],
        bbox_px: [140, 100, 181, 141],
        strength: 0.625,
        episode_id: 7,
        background_age_s: 12.5,
    }
}

fn fixture_comparison() -> PropertyComparison {
    PropertyComparison {
        header: Header::new(Stamp(1_700_000_002_000_000_001), "base_link"),
        property: "roughness".into(),
        episode_a: 1,
        label_a: "fabric_a".into(),
        episode_b: 2,
        label_b: "fabric_b".into(),
        winner: Winner::A,
        score_a: 0.8125,
        score_b: 0.1875,
        margin: 0.625,
        confidence: 0.9375,
        sentence: "B is smoother than A".into(),
    }
}

fn fixture_arm() -> ArmCommand {
    ArmCommand {
        header: Header::new(Stamp(1_700_000_005_000_000_002), "base_link"),
        target: "fabric_b".into(),
        x_m: 0.4375,
        y_m: -0.125,
        z_m: 0.004,
        lift_m: 0.0625,
        reason: "grasp the smoother fabric (B)".into(),
    }
}

fn publish(prefix: &str) -> anyhow::Result<()> {
    let ctx = r2r::Context::create()?;
    let mut node = r2r::Node::create(ctx, "unitac_interop_pub", "")?;
    let p1 = node.create_publisher::<ros::ContactState>(
        &format!("{prefix}/contact_state"),
        QosProfile::default(),
    )?;
    let p2 = node.create_publisher::<ros::PropertyComparison>(
        &format!("{prefix}/property_comparison"),
        QosProfile::default(),
    )?;
    let p3 = node.create_publisher::<ros::ArmCommand>(
        &format!("{prefix}/arm_command"),
        QosProfile::default(),
    )?;
    let matched = spin_until(&mut node, TIMEOUT, || {
        p1.get_inter_process_subscription_count().unwrap_or(0) > 0
            && p2.get_inter_process_subscription_count().unwrap_or(0) > 0
            && p3.get_inter_process_subscription_count().unwrap_or(0) > 0
    });
    if !matched {
        bail!("no subscriber matched within {TIMEOUT:?}");
    }
    let (c, k, a) = (
        convert::contact_state(&fixture_contact()),
        convert::property_comparison(&fixture_comparison()),
        convert::arm_command(&fixture_arm()),
    );
    let t0 = std::time::Instant::now();
    loop {
        p1.publish(&c)?;
        p2.publish(&k)?;
        p3.publish(&a)?;
        spin_until(&mut node, Duration::from_millis(200), || false);
        let gone = [
            p1.get_inter_process_subscription_count(),
            p2.get_inter_process_subscription_count(),
            p3.get_inter_process_subscription_count(),
        ]
        .into_iter()
        .all(|n| n.unwrap_or(0) == 0);
        if gone || t0.elapsed() > TIMEOUT {
            return Ok(());
        }
    }
}

/// Drains `stream`; the first message, converted, goes into `slot` (later ones are dropped).
fn first<M>(
    stream: &mut (impl futures::Stream<Item = M> + Unpin),
    slot: &mut Option<Result<Msg, ConvertError>>,
    convert: impl Fn(&M) -> Result<Msg, ConvertError>,
) {
    while let Some(Some(m)) = stream.next().now_or_never() {
        slot.get_or_insert_with(|| convert(&m));
    }
}

fn echo(prefix: &str) -> anyhow::Result<()> {
    let ctx = r2r::Context::create()?;
    let mut node = r2r::Node::create(ctx, "unitac_interop_echo", "")?;
    let mut s1 = node.subscribe::<ros::TactileLatent>(
        &format!("{prefix}/tactile_latent"),
        QosProfile::default(),
    )?;
    let mut s2 = node.subscribe::<ros::GripperCommand>(
        &format!("{prefix}/gripper_command"),
        QosProfile::default(),
    )?;
    let mut s3 = node.subscribe::<ros::GripperStatus>(
        &format!("{prefix}/gripper_status"),
        QosProfile::default(),
    )?;
    let mut s4 = node.subscribe::<ros::VisualObservation>(
        &format!("{prefix}/visual_observation"),
        QosProfile::default(),
    )?;
    // The first message of each topic, converted back (None until it arrives).
    let mut got: [Option<Result<Msg, ConvertError>>; 4] = Default::default();
    spin_until(&mut node, TIMEOUT, || {
        first(&mut s1, &mut got[0], |m| {
            convert::tactile_latent_from(m).map(Msg::TactileLatent)
        });
        first(&mut s2, &mut got[1], |m| {
            convert::gripper_command_from(m).map(Msg::GripperCommand)
        });
        first(&mut s3, &mut got[2], |m| {
            convert::gripper_status_from(m).map(Msg::GripperStatus)
        });
        first(&mut s4, &mut got[3], |m| {
            convert::visual_observation_from(m).map(Msg::VisualObservation)
        });
        got.iter().all(Option::is_some) || got.iter().flatten().any(Result::is_err)
    });
    for g in got.iter().flatten() {
        match g {
            Ok(m) => println!("{}", m.to_json()),
            Err(e) => bail!("bad message: {e}"),
        }
    }
    if got.iter().any(Option::is_none) {
        let names = [
            "tactile_latent",
            "gripper_command",
            "gripper_status",
            "visual_observation",
        ];
        let missing: Vec<&str> = names
            .iter()
            .zip(&got)
            .filter(|(_, g)| g.is_none())
            .map(|(n, _)| *n)
            .collect();
        bail!("timed out: no {}", missing.join(", "));
    }
    Ok(())
}

fn main() -> std::process::ExitCode {
    let args: Vec<String> = std::env::args()
        .skip(1)
        .take_while(|a| a != "--ros-args")
        .collect();
    let prefix = match args.iter().position(|a| a == "--topic-prefix") {
        Some(i) => args.get(i + 1).cloned().unwrap_or_default(),
        None => "/unitac_interop".to_string(),
    };
    let r = match args.first().map(String::as_str) {
        Some("publish") => publish(&prefix).context("publish"),
        Some("echo") => echo(&prefix).context("echo"),
        _ => {
            eprintln!("usage: unitac_ros_interop publish|echo [--topic-prefix P]");
            return std::process::ExitCode::from(2);
        }
    };
    match r {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("unitac_ros_interop: {e:#}");
            std::process::ExitCode::from(1)
        }
    }
}
