//! The contact and sensor nodes as processes against an rclpy peer (real ROS 2 from the wheels;
//! scripts/test runs this in a loopback-only network namespace).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;
use common::{python, root, stop};
use serde_json::Value;
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::Duration;

/// One test at a time: these start several ROS processes each, and on a 2-core machine running
/// them side by side starves best-effort delivery (the tests would then measure the load).
static SERIAL: std::sync::Mutex<()> = std::sync::Mutex::new(());

fn serial() -> std::sync::MutexGuard<'static, ()> {
    SERIAL.lock().unwrap_or_else(|e| e.into_inner())
}

/// The stage node as the launch plan's contact node in `ns`, with a params file.
fn contact_node(ns: &str, params: Option<&str>) -> Child {
    node_as(common::STAGE_NODE, &common::CONTACT, ns, params)
}

fn node(bin: &str, ns: &str, params: Option<&str>) -> Child {
    node_as(bin, &[], ns, params)
}

/// `bin` in `ns` with `role` (ROS arguments) and a params file.
fn node_as(bin: &str, role: &[&str], ns: &str, params: Option<&str>) -> Child {
    let mut c = Command::new(bin);
    c.args(["--ros-args", "-r", &format!("__ns:={ns}")]);
    c.args(role);
    if let Some(p) = params {
        c.args(["--params-file", p]);
    }
    c.stdout(Stdio::null())
        .stderr(Stdio::inherit())
        .spawn()
        .unwrap()
}

fn peer(args: &[&str]) -> Value {
    let o = Command::new(python())
        .arg(root().join("tests/ros/contact_peer.py"))
        .args(args)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    serde_json::from_slice(&o.stdout).unwrap()
}

fn ns(name: &str) -> String {
    format!("/t{}_{name}", std::process::id())
}

fn params_file(name: &str, body: &str) -> PathBuf {
    let p = std::env::temp_dir().join(format!("unitac-{}-{name}.yaml", std::process::id()));
    std::fs::write(&p, body).unwrap();
    p
}

/// Sensor node parameters: the mock sensor of `scene` (its scenario, seed and rate) as
/// `gsmini`, starting once the contact node and the listener subscribed; `repeat` starts the
/// scenario again at its end.
fn mock_sensor_params(name: &str, scene: &str, repeat: bool) -> PathBuf {
    params_file(
        name,
        &format!(
            "/**:\n  ros__parameters:\n    scene: {scene}\n    sensor_id: gsmini\n    repeat: {repeat}\n    wait_subscribers: 2\n"
        ),
    )
}

/// Sensor node parameters: replay `bag` at twice the recorded pace once two subscribers matched.
fn bag_sensor_params(name: &str, bag: &std::path::Path) -> PathBuf {
    params_file(
        name,
        &format!(
            "/**:\n  ros__parameters:\n    source: bag\n    bag: {}\n    rate: 2.0\n    wait_subscribers: 2\n",
            bag.display()
        ),
    )
}

#[test]
fn contact_node_answers_every_image_with_a_contact_state() {
    let _one = serial();
    let n = ns("contact");
    let p = params_file(
        "contact",
        "/**:\n  ros__parameters:\n    sensor_kind: generic\n    contact.enter_area_px: 100.0\n    contact.exit_area_px: 50.0\n",
    );
    let c = contact_node(&n, p.to_str());
    let got = peer(&["images", &n, "40"]);
    stop(c);
    let states = got["states"].as_array().unwrap();
    // 40 images, the first 10 learn the background: 30 states, in order, with the images' stamps.
    assert_eq!(states.len(), 30, "{got}");
    assert!(
        states
            .iter()
            .all(|s| s["frame_id"] == "gs1_optical_frame" && s["sensor_id"] == "gs1")
    );
    let stamps: Vec<i64> = states
        .iter()
        .map(|s| s["stamp"].as_i64().unwrap())
        .collect();
    assert!(stamps.windows(2).all(|w| w[0] < w[1]));
    assert_eq!(
        stamps[0], 1_700_000_000_400_000_000,
        "the 11th image's capture stamp"
    );
    let on: Vec<bool> = states
        .iter()
        .map(|s| s["in_contact"].as_bool().unwrap())
        .collect();
    // The disc is in images 15..25 = states 5..15; debounce makes contact start one frame late.
    assert!(
        !on[..5].iter().any(|&v| v) && on[6..15].iter().all(|&v| v) && !on[17..].iter().any(|&v| v),
        "{on:?}"
    );
    let eps = got["episodes"].as_array().unwrap();
    assert_eq!(eps.len(), 1, "{got}");
    assert!(eps[0]["peak"].as_f64().unwrap() > 300.0);
    // Diagnostics from the node, with its counters.
    let d = got["diag"].as_array().unwrap();
    assert!(
        d.iter().any(
            |s| s["name"].as_str().unwrap().starts_with("unitac_contact")
                && s["values"]["frames_in"] != "0"
        ),
        "{d:?}"
    );
}

/// An image with an invalid stamp (negative seconds, nanoseconds past a second) or an
/// encoding no node takes is counted once, as an error, never also as a drop, and its stamp is
/// never rewritten; stamps a minute away from the node's clock are not averaged into latency.
#[test]
fn bad_stamps_and_encodings_count_once_as_errors() {
    let _one = serial();
    let n = ns("faults");
    let p = params_file(
        "faults",
        "/**:\n  ros__parameters:\n    sensor_kind: generic\n    contact.enter_area_px: 100.0\n    contact.exit_area_px: 50.0\n",
    );
    let c = contact_node(&n, p.to_str());
    let faults = r#"{"negative_sec": [5], "big_nanosec": [6], "bad_encoding": [30]}"#;
    let got = peer(&["images", &n, "40", faults]);
    stop(c);
    let states = got["states"].as_array().unwrap();
    // 40 images, 3 rejected, the first 10 good ones learn: 27 states, all stamps valid.
    assert_eq!(states.len(), 27, "{got}");
    assert!(states.iter().all(|s| s["stamp"].as_i64().unwrap() > 0));
    let d = diag_of(&got, &n, "unitac_contact");
    let last = d.last().expect("contact node diagnostics");
    let v = &last["values"];
    assert_eq!(v["frames_in"], "40", "{last}");
    assert_eq!(v["errors"], "3", "{last}");
    assert_eq!(v["dropped"], "0", "{last}");
    // The images are stamped in 2023: a latency of years is not a latency.
    assert_ne!(v["latency_out_of_range"], "0", "{last}");
    assert!(v.get("latency_mean_ms").is_none(), "{last}");
}

#[test]
fn parameters_from_a_yaml_file_take_effect() {
    let _one = serial();
    let n = ns("params");
    // An enter area larger than the image: the same disc is never a contact.
    let p = params_file(
        "params",
        "/**:\n  ros__parameters:\n    sensor_kind: generic\n    contact.enter_area_px: 100000.0\n    contact.exit_area_px: 50.0\n",
    );
    let c = contact_node(&n, p.to_str());
    let got = peer(&["images", &n, "40"]);
    stop(c);
    let states = got["states"].as_array().unwrap();
    assert_eq!(states.len(), 30, "{got}");
    assert!(states.iter().all(|s| s["in_contact"] == false));
    assert!(got["episodes"].as_array().unwrap().is_empty());
}

#[test]
fn sensor_and_contact_nodes_find_the_fabric_episodes() {
    let _one = serial();
    let n = ns("pipeline");
    let sp = mock_sensor_params("sensor", "fabric_selection", false);
    let cp = params_file(
        "cnode",
        "/**:\n  ros__parameters:\n    scene: fabric_selection\n",
    );
    let contact = Command::new(common::STAGE_NODE)
        .args([
            "--ros-args",
            "-r",
            &format!("__ns:={n}"),
            "-r",
            "__node:=unitac_contact",
            "-p",
            "stages:=contact,slip",
            "-r",
            "image:=image_raw",
            "--params-file",
            cp.to_str().unwrap(),
        ])
        .stderr(Stdio::inherit())
        .spawn()
        .unwrap();
    let listener = Command::new(python())
        .arg(root().join("tests/ros/contact_peer.py"))
        .args(["listen", &n, "40", r#"{"until": {"episodes": 2}}"#])
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let sensor = node(env!("CARGO_BIN_EXE_unitac_sensor_node"), &n, sp.to_str());
    let out = listener.wait_with_output().unwrap();
    stop(sensor);
    stop(contact);
    let got: Value = serde_json::from_slice(&out.stdout).unwrap();
    // How many images a Python subscriber keeps up with depends on the machine's load; that it
    // sees them, with the right frame_id, does not.
    assert!(got["images"].as_u64().unwrap() > 0, "{}", got["images"]);
    assert_eq!(
        got["image_frames"],
        serde_json::json!(["gsmini_optical_frame"])
    );
    assert_eq!(
        got["episodes"].as_array().unwrap().len(),
        2,
        "{}",
        got["episodes"]
    );
    assert!(
        got["states"]
            .as_array()
            .unwrap()
            .iter()
            .all(|s| s["frame_id"] == "gsmini_optical_frame")
    );
}

fn spawn(bin: &str, ns: &str, extra: &[&str]) -> Child {
    Command::new(bin)
        .args(["--ros-args", "-r", &format!("__ns:={ns}")])
        .args(extra)
        .stdout(Stdio::null())
        .stderr(Stdio::inherit())
        .spawn()
        .unwrap()
}

fn listener(ns: &str, seconds: u32, opts: Value) -> Child {
    Command::new(python())
        .arg(root().join("tests/ros/contact_peer.py"))
        .args(["listen", ns, &seconds.to_string(), &opts.to_string()])
        .stdout(Stdio::piped())
        .spawn()
        .unwrap()
}

fn finish(l: Child) -> Value {
    let out = l.wait_with_output().unwrap();
    assert!(out.status.success());
    serde_json::from_slice(&out.stdout).unwrap()
}

/// Diagnostics of node `name` in namespace `ns` (/diagnostics is shared by every test).
fn diag_of<'a>(got: &'a Value, ns: &str, name: &str) -> Vec<&'a Value> {
    let want = format!("{name}: {ns}/{name}");
    got["diag"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|d| d["name"] == want.as_str())
        .collect()
}

fn num(v: &Value) -> f64 {
    v.as_str().unwrap().parse().unwrap()
}

/// What the fabric scene must produce, however its frames arrived.
fn check_fabric_outputs(got: &Value, ns: &str, frame_id: &str) {
    for (topic, ty) in [
        ("image_raw", "sensor_msgs/msg/Image"),
        ("background", "sensor_msgs/msg/Image"),
        ("contact_state", "unitac_msgs/msg/ContactState"),
        ("contact_episode", "unitac_msgs/msg/ContactEpisode"),
        ("contact_clip", "unitac_msgs/msg/ContactClip"),
        ("tactile_properties", "unitac_msgs/msg/TactileProperties"),
        ("tactile_latent", "unitac_msgs/msg/TactileLatent"),
        ("property_comparison", "unitac_msgs/msg/PropertyComparison"),
    ] {
        assert_eq!(
            got["topics"][format!("{ns}/{topic}")],
            serde_json::json!([ty]),
            "{topic}: {}",
            got["topics"]
        );
    }
    let labels = |k: &str| common::labels(got, k);
    assert_eq!(
        labels("episodes"),
        ["fabric_a", "fabric_b"],
        "{}",
        got["episodes"]
    );
    assert_eq!(
        labels("clips"),
        ["fabric_a", "fabric_b"],
        "{}",
        got["clips"]
    );
    for c in got["clips"].as_array().unwrap() {
        assert_eq!(c["frames"], 8, "{c}");
        assert_eq!(c["frame_ids"], serde_json::json!([frame_id]));
        assert_eq!(c["background"], serde_json::json!([320, 240]));
    }
    assert_eq!(
        labels("properties"),
        ["fabric_a", "fabric_b"],
        "{}",
        got["properties"]
    );
    let p = got["properties"].as_array().unwrap();
    let rough = |i: usize| p[i]["roughness"].as_f64().unwrap();
    assert!(rough(1) < rough(0), "fabric_b is the smoother one: {p:?}");
    assert!(p.iter().all(|x| x["frame_id"] == frame_id), "{p:?}");
    let lat = got["latents"].as_array().unwrap();
    assert_eq!(lat.len(), 2, "one real latent per episode: {lat:?}");
    assert!(
        lat.iter()
            .all(|l| l["source"] == 0 && l["valid"] == true && l["finite"] == true)
    );
    assert!(lat.iter().all(|l| l["n"].as_u64().unwrap() > 0));
    let cmp = got["comparisons"].as_array().unwrap();
    assert_eq!(cmp.len(), 1, "{cmp:?}");
    assert_eq!(cmp[0]["property"], "roughness");
    assert_eq!(cmp[0]["winner"], 0, "fabric_a is rougher: {cmp:?}");
    assert!(
        cmp[0]["sentence"]
            .as_str()
            .unwrap()
            .contains("fabric_b is smoother than fabric_a"),
        "{cmp:?}"
    );
}

/// A contact node for the fabric scene on `image_raw` in `ns`, with extra `--ros-args`.
fn fabric_contact_node(ns: &str, extra: &[&str]) -> Child {
    let p = params_file(
        &format!("contact{}", ns.replace('/', "_")),
        "/**:\n  ros__parameters:\n    scene: fabric_selection\n",
    );
    let args = [
        &[
            "-r",
            "image:=image_raw",
            "-r",
            "image/compressed:=image_raw/compressed",
            "--params-file",
            p.to_str().unwrap(),
        ][..],
        extra,
    ]
    .concat();
    spawn(
        common::STAGE_NODE,
        ns,
        &[&common::CONTACT[..], &args].concat(),
    )
}

/// Sensor (with `sensor_params`), contact and inference nodes for the fabric scene in `ns`, the
/// last two with `extra` arguments; a listener collects until the comparison and both episodes.
fn run_fabric_nodes(ns: &str, sensor_params: &std::path::Path, extra: &[&str]) -> Value {
    let contact = fabric_contact_node(ns, extra);
    let inference = spawn(
        common::STAGE_NODE,
        ns,
        &[
            &common::INFERENCE[..],
            &["-p", "scene:=fabric_selection"],
            extra,
        ]
        .concat(),
    );
    let l = listener(
        ns,
        60,
        // The inference node's publishers discovered: its clip subscription exists by then.
        serde_json::json!({"until": {"comparisons": 1, "episodes": 2},
            "wait_for": ["/contact_state", "/contact_episode", "/property_comparison"]}),
    );
    let sensor = node(
        env!("CARGO_BIN_EXE_unitac_sensor_node"),
        ns,
        sensor_params.to_str(),
    );
    let got = finish(l);
    stop(sensor);
    stop(contact);
    stop(inference);
    got
}

#[test]
fn fabric_scene_as_nodes_publishes_properties_and_a_comparison() {
    let _one = serial();
    let n = ns("fabric");
    let sp = mock_sensor_params("fsensor", "fabric_selection", false);
    let got = run_fabric_nodes(&n, &sp, &[]);
    check_fabric_outputs(&got, &n, "gsmini_optical_frame");
    // Rates: the sensor node's own report (a Python subscriber's count depends on load).
    let sd = diag_of(&got, &n, "unitac_sensor");
    assert!(sd.len() >= 3, "{sd:?}");
    for d in &sd[1..] {
        let r = num(&d["values"]["rate_hz"]);
        assert!(
            (20.0..=30.0).contains(&r),
            "sensor rate {r} Hz, want 25: {d}"
        );
    }
    // Latency from capture to ContactState, on the node's clock (wall time here).
    let cd = diag_of(&got, &n, "unitac_contact");
    let lat: Vec<f64> = cd
        .iter()
        .filter_map(|d| d["values"]["latency_mean_ms"].as_str())
        .map(|v| v.parse().unwrap())
        .collect();
    assert!(
        !lat.is_empty() && lat.iter().all(|&l| (0.0..500.0).contains(&l)),
        "{cd:?}"
    );
    // The inference node reports its model timings.
    let id = diag_of(&got, &n, "unitac_inference");
    assert!(
        id.iter().any(|d| d["values"]["encoder"]
            .as_str()
            .is_some_and(|v| v.contains("calls, mean") && !v.starts_with("0 calls"))),
        "{id:?}"
    );
    assert!(id.iter().all(|d| d["values"]["errors"] == "0"), "{id:?}");
}

/// A bag of the mock fabric scene (MCAP, sensor id `gs`, bag time = capture time): each frame
/// written as `encode` makes it, on `topic` of `type_name`. Returns the bag and its first and
/// last stamps.
fn fabric_bag<M: unitac_bag::RosMessage>(
    name: &str,
    topic: &str,
    type_name: &str,
    encode: impl Fn(&unitac_core::Frame) -> M,
) -> (PathBuf, i64, i64) {
    use unitac_bag::{BagWriter, WriteOptions};
    use unitac_core::Source;
    let dir = std::env::temp_dir().join(format!("unitac-{}-{name}", std::process::id()));
    std::fs::remove_dir_all(&dir).ok();
    let mut w = BagWriter::create(&dir, WriteOptions::default()).unwrap();
    let t = w.add_topic(topic, type_name).unwrap();
    let mut cfg = unitac_sim::MockConfig::new(unitac_core::SensorKind::GELSIGHT_MINI, 7);
    cfg.sensor_id = "gs".into();
    let mut mock = unitac_sim::MockSensor::new(
        cfg,
        unitac_sim::Scenario::by_name("fabric_selection").unwrap(),
    );
    let (mut first, mut last) = (None, 0);
    while let Some(f) = mock.next_frame().unwrap() {
        w.write(t, f.stamp.0, &encode(&f)).unwrap();
        first.get_or_insert(f.stamp.0);
        last = f.stamp.0;
    }
    w.finish().unwrap();
    (dir, first.unwrap(), last)
}

#[test]
fn bag_replay_with_sim_time_drives_the_same_pipeline() {
    let _one = serial();
    let n = ns("bag");
    let (bag, t_first, t_last) = fabric_bag(
        "fabric-bag",
        "/gs/image_raw",
        "sensor_msgs/msg/Image",
        unitac_bag::Image::rgb8,
    );
    // Twice the recorded pace: the answers come from the stamps, not from wall time.
    let sp = bag_sensor_params("bsensor", &bag);
    let got = run_fabric_nodes(&n, &sp, &["-p", "use_sim_time:=true"]);
    check_fabric_outputs(&got, &n, "gs_optical_frame");
    assert_eq!(
        got["topics"]["/clock"],
        serde_json::json!(["rosgraph_msgs/msg/Clock"])
    );
    let in_bag = |t: i64| (t_first..=t_last).contains(&t);
    // Outputs carry the bag's capture stamps.
    for k in ["episodes", "properties", "latents", "comparisons"] {
        for e in got[k].as_array().unwrap() {
            assert!(in_bag(e["stamp"].as_i64().unwrap()), "{k}: {e}");
        }
    }
    // /clock carried bag time, in order.
    let clock: Vec<i64> = got["clock"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_i64().unwrap())
        .collect();
    assert!(clock.len() > 50, "{} /clock messages", clock.len());
    assert!(clock.iter().all(|&t| in_bag(t)) && clock.windows(2).all(|w| w[0] <= w[1]));
    // Nodes under use_sim_time stamp their diagnostics with bag time; the sensor node (not under
    // sim time) with wall time.
    for prefix in ["unitac_contact", "unitac_inference"] {
        let d = diag_of(&got, &n, prefix);
        assert!(!d.is_empty(), "{prefix}");
        // Before the first /clock message sim time is 0.
        let stamps: Vec<i64> = d.iter().map(|x| x["stamp"].as_i64().unwrap()).collect();
        assert!(
            stamps.iter().all(|&t| t == 0 || in_bag(t)) && stamps.iter().any(|&t| in_bag(t)),
            "{prefix} diagnostics are not on bag time: {d:?}"
        );
    }
    let sd = diag_of(&got, &n, "unitac_sensor");
    assert!(sd.iter().all(|x| x["stamp"].as_i64().unwrap() > t_last));
    std::fs::remove_dir_all(&bag).ok();
}

#[test]
fn a_stalled_subscriber_loses_frames_counted_and_blocks_nothing() {
    let _one = serial();
    let n = ns("slow");
    // `repeat`: the scenario starts again at its end, so frames flow for the whole test.
    let sp = mock_sensor_params("ssensor", "fabric_selection", true);
    let contact = fabric_contact_node(&n, &[]);
    // A slow reliable subscriber too: 0.2 s of work per image.
    let slow = Command::new(python())
        .arg(root().join("tests/ros/contact_peer.py"))
        .args(["slow", &n, "14", "0.2"])
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    // The listener stalls the contact node (SIGSTOP) for 2 s after 50 images.
    let l = listener(
        &n,
        12,
        serde_json::json!({"stop_pid": contact.id(), "stop_after": 50, "stop_seconds": 2.0}),
    );
    let sensor = node(env!("CARGO_BIN_EXE_unitac_sensor_node"), &n, sp.to_str());
    let got = finish(l);
    stop(sensor);
    stop(contact);
    let slow_got = finish(slow);
    let [t_stop, t_cont] = [0, 1].map(|i| got["stop_window"][i].as_f64().unwrap());
    assert!(t_cont - t_stop >= 1.9, "{}", got["stop_window"]);
    // The sensor kept publishing while one subscriber was stalled and another was slow: its
    // published count (from its diagnostics, once a second) grew through the stall, and over the
    // whole run it held its 25 fps. (On a loaded machine the mock's pacer catches up after a late
    // second, which a window of two or three seconds shows as a dip and a burst, so the rate is
    // bounded over the run and only its lower side over the stall.)
    // Rates over the diagnostics' own stamps: their delivery may come in a burst after a late
    // second, which would crowd the receive times.
    let sd = diag_of(&got, &n, "unitac_sensor");
    let counts: Vec<(f64, f64, f64)> = sd
        .iter()
        .map(|d| {
            (
                d["t"].as_f64().unwrap(),
                d["stamp"].as_i64().unwrap() as f64 * 1e-9,
                num(&d["values"]["messages_out"]),
            )
        })
        .collect();
    let during: Vec<(f64, f64, f64)> = counts
        .iter()
        .copied()
        .filter(|(t, ..)| (t_stop..t_cont + 1.5).contains(t))
        .collect();
    assert!(during.len() >= 2, "{sd:?} {}", got["stop_window"]);
    let rate = |s: &[(f64, f64, f64)]| {
        let ((_, t0, m0), (_, t1, m1)) = (s[0], s[s.len() - 1]);
        (m1 - m0) / (t1 - t0)
    };
    let stall_rate = rate(&during);
    assert!(stall_rate >= 20.0, "{stall_rate} Hz over {during:?}");
    assert!(counts.len() >= 5, "{counts:?}");
    let run_rate = rate(&counts[1..]);
    assert!(
        (20.0..=30.0).contains(&run_rate),
        "{run_rate} Hz over {counts:?}"
    );
    // Frames kept flowing to the other subscribers during the stall.
    let seen = got["image_times"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|t| (t_stop..t_cont).contains(&t.as_f64().unwrap()))
        .count();
    assert!(
        seen > 0,
        "no image reached the listener while the contact node was stopped"
    );
    // The stalled contact node counted what it lost, as a warning.
    let cd = diag_of(&got, &n, "unitac_contact");
    let last = cd.last().expect("contact diagnostics after the stall");
    let dropped = num(&last["values"]["dropped"]);
    assert!(
        dropped >= 10.0,
        "2 s at 25 fps stalled, {dropped} counted: {last}"
    );
    // It cannot have lost more than the sensor published and it did not receive.
    let s_last = sd.last().unwrap();
    let published = num(&s_last["values"]["messages_out"])
        + 25.0 * (last["t"].as_f64().unwrap() - s_last["t"].as_f64().unwrap()).max(0.0)
        + 2.0;
    let received = num(&last["values"]["frames_in"]);
    assert!(dropped + received <= published, "{last} {s_last}");
    assert_eq!(last["level"], 1, "{last}");
    assert!(slow_got["images"].as_u64().unwrap() > 0);
}

#[test]
fn sensor_node_errors_are_one_line_and_exit_1() {
    let _one = serial();
    let empty = std::env::temp_dir().join(format!("unitac-{}-nosysfs", std::process::id()));
    // A bus with no devices on it.
    std::fs::create_dir_all(empty.join("sys/bus/usb/devices")).unwrap();
    let n = ns("errors");
    let cases: [(&[&str], &str); 4] = [
        (&["-p", "source:=v4l"], "no gelsight-mini sensor found"),
        (&["-p", "source:=bag"], "needs the parameter bag"),
        (
            &["-p", "source:=bag", "-p", "bag:=/nonexistent/bag"],
            "/nonexistent/bag",
        ),
        (&["-p", "source:=usb"], "not one of mock, v4l, bag"),
    ];
    for (args, want) in cases {
        let o = Command::new(env!("CARGO_BIN_EXE_unitac_sensor_node"))
            .args(["--ros-args", "-r", &format!("__ns:={n}")])
            .args(args)
            .env("UNITAC_SYSFS_ROOT", &empty)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {err}");
        let lines: Vec<&str> = err
            .lines()
            .filter(|l| l.starts_with("unitac_sensor_node:"))
            .collect();
        assert_eq!(lines.len(), 1, "{args:?}: {err}");
        assert!(lines[0].contains(want), "{args:?}: {err}");
    }
}

/// The cup VTLA-pred scene's sampler in an inference node started after the background was
/// learned and published: the latched background still reaches it, the camera's values come from
/// an rclpy camera on `visual_observation`, and it publishes a valid, finite predicted latent of
/// the cup with the solver settings of the scene and its condition's sources.
#[test]
fn a_late_inference_node_gets_the_latched_background_and_predicts_a_latent() {
    let _one = serial();
    let n = ns("cup");
    let sp = mock_sensor_params("csensor", "cup_deformation", true);
    let contact = fabric_contact_node(&n, &[]);
    // A camera: the cup's diameter and height, five times a second.
    let camera =
        serde_json::json!({"names": ["cup_width_m", "cup_height_m"], "values": [0.09, 0.11]});
    let l = listener(
        &n,
        40,
        serde_json::json!({"until": {"latents": 1}, "visual": camera}),
    );
    let sensor = node(env!("CARGO_BIN_EXE_unitac_sensor_node"), &n, sp.to_str());
    // 10 learning frames take 0.4 s at 25 fps: by 3 s the background went out long ago.
    std::thread::sleep(Duration::from_secs(3));
    let inference = spawn(
        common::STAGE_NODE,
        &n,
        &[
            &common::INFERENCE[..],
            &["-p", "scene:=cup_deformation_vtla_pred"],
        ]
        .concat(),
    );
    let got = finish(l);
    stop(sensor);
    stop(contact);
    stop(inference);
    let lat = got["latents"].as_array().unwrap();
    assert!(!lat.is_empty(), "{}", got["diag"]);
    let l0 = &lat[0];
    assert_eq!(l0["source"], 1, "predicted: {l0}");
    assert_eq!(l0["valid"], true, "{l0}");
    assert_eq!(l0["finite"], true, "{l0}");
    assert_eq!(l0["n"], 96, "{l0}");
    // The cup the camera sees, from the camera's message and the latched background.
    assert_eq!(l0["object"], "cup", "{l0}");
    assert_eq!(
        l0["condition_sources"],
        serde_json::json!(["visual_observation", "background"]),
        "{l0}"
    );
    // The scene's solver settings (launch/scenes/cup_deformation_vtla_pred.yaml).
    assert_eq!(
        (&l0["solver"], &l0["steps"], &l0["guidance"]),
        (
            &serde_json::json!("heun"),
            &serde_json::json!(16),
            &serde_json::json!(1.0)
        ),
        "{l0}"
    );
}

/// A JPEG bag (sensor_msgs/CompressedImage, as labs often record): the sensor node republishes it
/// raw on image_raw/compressed, the contact node reads the compressed transport and finds both
/// fabric episodes on bag time.
#[test]
fn compressed_bag_replays_through_the_compressed_transport() {
    let _one = serial();
    let n = ns("jpeg");
    let (dir, first, last) = fabric_bag(
        "jpeg-bag",
        "/gs/image_raw/compressed",
        "sensor_msgs/msg/CompressedImage",
        |f| {
            let mut jpeg = Vec::new();
            image::codecs::jpeg::JpegEncoder::new_with_quality(&mut jpeg, 95)
                .encode(f.data(), f.width, f.height, image::ExtendedColorType::Rgb8)
                .unwrap();
            unitac_bag::CompressedImage {
                header: unitac_core::msg::Header::optical(f.stamp, &f.sensor_id),
                format: "jpeg".into(),
                data: jpeg,
            }
        },
    );
    let sp = bag_sensor_params("jsensor", &dir);
    let contact = fabric_contact_node(
        &n,
        &[
            "-p",
            "image_transport:=compressed",
            "-p",
            "use_sim_time:=true",
        ],
    );
    let l = listener(
        &n,
        40,
        serde_json::json!({"until": {"episodes": 2}, "compressed": true}),
    );
    let sensor = node(env!("CARGO_BIN_EXE_unitac_sensor_node"), &n, sp.to_str());
    let got = finish(l);
    stop(sensor);
    stop(contact);
    std::fs::remove_dir_all(&dir).ok();
    assert_eq!(
        got["topics"][format!("{n}/image_raw/compressed")],
        serde_json::json!(["sensor_msgs/msg/CompressedImage"]),
        "{}",
        got["topics"]
    );
    assert_eq!(got["image_frames"], serde_json::json!(["gs_optical_frame"]));
    let eps = got["episodes"].as_array().unwrap();
    let labels: Vec<&str> = eps.iter().map(|e| e["label"].as_str().unwrap()).collect();
    assert_eq!(labels, ["fabric_a", "fabric_b"], "{eps:?}");
    assert!(
        eps.iter()
            .all(|e| (first..=last).contains(&e["stamp"].as_i64().unwrap()))
    );
    let states = got["states"].as_array().unwrap();
    assert!(states.len() > 50, "{} states", states.len());
    assert!(states.iter().all(|s| s["frame_id"] == "gs_optical_frame"));
    let cd = diag_of(&got, &n, "unitac_contact");
    assert!(cd.iter().all(|d| d["values"]["errors"] == "0"), "{cd:?}");
}
