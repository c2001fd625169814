//! Golden outputs over ROS: the bag `unitac run --out` records of each scene with a golden
//! (tests/golden/<scene>.jsonl) on the mock sensor,
//! replayed by the sensor node (with /clock) into the contact and inference nodes under
//! use_sim_time, gives the same contact states, episodes, properties, comparisons and latents as
//! the committed tests/golden/<scene>.jsonl (which the embedded runtime and `unitac replay`
//! reproduce: crates/cli/tests/golden.rs). An rclpy observer (tests/ros/golden_peer.py) records
//! the messages' CDR; they are decoded with the project's codecs and compared field by field
//! (floats within unitac_core::golden::FLOAT_TOLERANCE).
//!
//! Every frame must reach the contact node (a lost frame changes the background's updates and so
//! the outputs): the sensor node publishes reliably with a deep history and the contact node
//! subscribes reliably (`image_qos:=reliable`), and the contact node's own drop count (stamp gaps,
//! from /diagnostics) must be zero, so a loss fails as a loss, not as a stage difference.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;
use common::{python, root, stop};
use std::collections::BTreeMap;
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use unitac_bag::RosMessage;
use unitac_core::Msg;
use unitac_core::golden::{diff, parse_lines};
use unitac_core::msg::{
    ContactEpisode, ContactState, PropertyComparison, TactileLatent, TactileProperties,
};

/// The `unitac` binary of this build (cargo test --workspace builds it next to the tests).
fn unitac() -> PathBuf {
    let exe = std::env::current_exe().unwrap();
    let p = exe.parent().unwrap().parent().unwrap().join("unitac");
    assert!(
        p.is_file(),
        "{} missing: build the workspace (cargo test --workspace)",
        p.display()
    );
    p
}

/// `bin` in namespace `ns` reading `image_raw`, with `role` (ROS arguments: `common::CONTACT`,
/// `common::INFERENCE`) and `params`.
fn node(bin: &str, role: &[&str], ns: &str, params: &[String]) -> Child {
    let mut c = Command::new(bin);
    c.args([
        "--ros-args",
        "-r",
        &format!("__ns:={ns}"),
        "-r",
        "image:=image_raw",
    ]);
    c.args(role);
    for p in params {
        c.args(["-p", p]);
    }
    c.stdout(Stdio::null())
        .stderr(Stdio::inherit())
        .spawn()
        .unwrap()
}

fn hex(s: &str) -> Vec<u8> {
    (0..s.len() / 2)
        .map(|i| u8::from_str_radix(&s[2 * i..2 * i + 2], 16).unwrap())
        .collect()
}

/// One observed message as the event JSON `unitac run --events` prints.
fn event(topic: &str, cdr: &[u8]) -> serde_json::Value {
    let m = match topic {
        "contact_state" => Msg::ContactState(ContactState::from_cdr(cdr).unwrap()),
        "contact_episode" => Msg::ContactEpisode(ContactEpisode::from_cdr(cdr).unwrap()),
        "tactile_properties" => Msg::TactileProperties(TactileProperties::from_cdr(cdr).unwrap()),
        "property_comparison" => {
            Msg::PropertyComparison(PropertyComparison::from_cdr(cdr).unwrap())
        }
        "tactile_latent" => Msg::TactileLatent(TactileLatent::from_cdr(cdr).unwrap()),
        other => panic!("{other}"),
    };
    m.to_json()
}

fn check_scene(scene: &str) {
    let golden = parse_lines(
        &std::fs::read_to_string(root().join(format!("tests/golden/{scene}.jsonl"))).unwrap(),
    )
    .unwrap();
    // The golden events the nodes publish, by topic (= event type), in order.
    let mut want: BTreeMap<String, Vec<serde_json::Value>> = BTreeMap::new();
    for e in &golden {
        let ty = e["type"].as_str().unwrap();
        if [
            "contact_state",
            "contact_episode",
            "tactile_properties",
            "property_comparison",
            "tactile_latent",
        ]
        .contains(&ty)
        {
            want.entry(ty.to_string()).or_default().push(e.clone());
        }
    }
    // Record the scene's run (the same frames the goldens came from).
    let dir = std::env::temp_dir().join(format!("unitac-rosgolden-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let bag = dir.join(format!("{scene}.mcap"));
    let o = Command::new(unitac())
        .args(["run", "--scene", scene, "--fast", "--out"])
        .arg(&bag)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));

    let ns = format!("/g{}_{scene}", std::process::id());
    let scene_p = format!("scene:={scene}");
    let sim = "use_sim_time:=true".to_string();
    let contact = node(
        common::STAGE_NODE,
        &common::CONTACT,
        &ns,
        &[scene_p.clone(), sim.clone(), "image_qos:=reliable".into()],
    );
    let inference = node(
        common::STAGE_NODE,
        &common::INFERENCE,
        &ns,
        &[scene_p.clone(), sim],
    );
    let until: serde_json::Map<String, serde_json::Value> = want
        .iter()
        .map(|(k, v)| (k.clone(), v.len().into()))
        .collect();
    let mut peer = Command::new(python())
        .arg(root().join("tests/ros/golden_peer.py"))
        .args([&ns, "90", &serde_json::Value::Object(until).to_string()])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Start the bag once the observer sees the contact node (nothing is lost before discovery).
    let mut ready = String::new();
    std::io::BufRead::read_line(
        &mut std::io::BufReader::new(peer.stderr.take().unwrap()),
        &mut ready,
    )
    .unwrap();
    assert_eq!(ready.trim(), "ready");
    let sensor = node(
        env!("CARGO_BIN_EXE_unitac_sensor_node"),
        &[],
        &ns,
        &[
            scene_p,
            "source:=bag".into(),
            format!("bag:={}", bag.display()),
            "rate:=1.0".into(),
            "wait_subscribers:=1".into(),
            format!("image_depth:={}", unitac_ros::image::RELIABLE_IMAGE_DEPTH),
        ],
    );
    let out = peer.wait_with_output().unwrap();
    stop(sensor);
    stop(contact);
    stop(inference);
    std::fs::remove_dir_all(&dir).ok();
    let mut got: BTreeMap<String, Vec<serde_json::Value>> = BTreeMap::new();
    let mut dropped = None;
    for l in String::from_utf8_lossy(&out.stdout).lines() {
        let j: serde_json::Value = serde_json::from_str(l).unwrap();
        let topic = j["topic"].as_str().unwrap();
        if topic == "contact_dropped" {
            dropped = j["value"].as_u64();
            continue;
        }
        got.entry(topic.to_string())
            .or_default()
            .push(event(topic, &hex(j["cdr"].as_str().unwrap())));
    }
    assert_eq!(
        dropped,
        Some(0),
        "{scene}: the contact node lost frames on the way (its /diagnostics `dropped`): the \
         comparison would be meaningless, so this is a transport failure, not a stage difference"
    );
    for (ty, w) in &want {
        let g = got.get(ty).cloned().unwrap_or_default();
        if let Some(d) = diff(w, &g) {
            panic!("{scene}: {ty} over ROS differs from tests/golden/{scene}.jsonl: {d}");
        }
    }
}

/// Every scene (as `unitac scenes` lists them) with a committed golden.
#[test]
fn ros_nodes_replaying_the_recorded_bag_reproduce_the_goldens() {
    let scenes = unitac_pipeline::scenes::with_golden(
        &unitac_pipeline::scene_names(None),
        &root().join("tests/golden"),
    );
    assert!(!scenes.is_empty());
    for scene in scenes {
        check_scene(&scene);
    }
}
