//! The contact node's `depth` (sensor_msgs/Image 32FC1) and `points` (sensor_msgs/PointCloud2)
//! on a scene whose contact stage has a depth calibration, against an rclpy peer
//! (tests/ros/depth_peer.py), and the same bytes from every transport: the embedded runtime
//! (`unitac run --out`), bag replay (`unitac replay --out`) and the ROS nodes replaying the
//! runtime's bag (sensor node -> contact node, under use_sim_time); the runtime's depth maps
//! also match their committed summary, tests/golden/depth/fabric_selection_depth.jsonl. And `contact_overlay`: no
//! publisher by default, the picture with the outline and centroid with `contact.overlay:=true`
//! (a second contact node on the same images).
//!
//! No calibration or scene is committed for it: the calibration comes from `unitac calibrate
//! mock-presses` and `unitac calibrate depth` (seconds, seeded), the scene is fabric_selection's
//! contact stage with that calibration, written to a temporary directory. The comparison is on the decoded messages
//! (every field, the pixel and point bytes included), as in golden.rs, so the transports'
//! serializers' trailing padding does not count.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;
use common::{python, root, stop};
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use unitac_bag::{BagReader, Image, PointCloud2, RosMessage};
use unitac_core::golden::{diff, parse_lines};

/// Frames of the mock fabric scenario recorded: the background, then the first press (contact
/// from about frame 28, the peak at 40).
const FRAMES: u64 = 50;

/// The `unitac` binary of this build (cargo test --workspace builds it next to the tests).
fn unitac() -> PathBuf {
    let exe = std::env::current_exe().unwrap();
    let p = exe.parent().unwrap().parent().unwrap().join("unitac");
    assert!(
        p.is_file(),
        "{} missing: build the workspace (cargo build -p unitac-cli)",
        p.display()
    );
    p
}

/// Runs `unitac`; its stdout.
fn unitac_ok(args: &[&str]) -> String {
    let o = Command::new(unitac())
        .args(args)
        .env("RUST_LOG", "warn")
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "unitac {args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// `bin` in namespace `ns` reading `image_raw`, with `role` (ROS arguments) and `params`.
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

/// Every message of `topic` in `bag`, decoded.
fn messages<M: RosMessage>(bag: &Path, topic: &str) -> Vec<M> {
    let opts = unitac_bag::ReadOptions {
        topics: vec![topic.to_string()],
        ..Default::default()
    };
    BagReader::open(bag, opts)
        .unwrap()
        .map(|m| M::from_cdr(&m.unwrap().data).unwrap())
        .collect()
}

/// What the peer wrote: `<dir>/<topic>_NNNN.cdr`, decoded, in arrival order.
fn received<M: RosMessage>(dir: &Path, topic: &str) -> Vec<M> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| {
            p.file_name()
                .unwrap()
                .to_string_lossy()
                .starts_with(&format!("{topic}_"))
        })
        .collect();
    files.sort();
    files
        .iter()
        .map(|p| M::from_cdr(&std::fs::read(p).unwrap()).unwrap())
        .collect()
}

/// A calibration from mock ball presses and the fabric scene's contact stage with it.
fn depth_scene(dir: &Path) -> PathBuf {
    let mock = dir.join("mock");
    unitac_ok(&[
        "calibrate",
        "mock-presses",
        "--count",
        "30",
        "--out",
        mock.to_str().unwrap(),
    ]);
    let mut presses: Vec<String> = std::fs::read_dir(&mock)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| {
            p.file_name()
                .unwrap()
                .to_string_lossy()
                .starts_with("press_")
        })
        .map(|p| p.display().to_string())
        .collect();
    presses.sort();
    let cal = dir.join("cal.json");
    let bg = mock.join("background.png");
    let mut args = vec![
        "calibrate",
        "depth",
        "--sensor",
        "gelsight-mini",
        "--ball-radius-m",
        "0.002",
        "--background",
        bg.to_str().unwrap(),
        "--out",
        cal.to_str().unwrap(),
    ];
    args.extend(presses.iter().map(String::as_str));
    unitac_ok(&args);
    let text = std::fs::read_to_string(root().join("launch/scenes/fabric_selection.yaml")).unwrap();
    // The contact stage alone, with the calibration.
    let contact = text
        .split("  - kind: encoder")
        .next()
        .unwrap()
        .replace("scene: fabric_selection", "scene: fabric_selection_depth")
        .replace(
            "clip_frames: 8",
            &format!("clip_frames: 8\n      depth_calibration: {}", cal.display()),
        );
    assert!(contact.contains("depth_calibration"));
    let scene = dir.join("fabric_selection_depth.yaml");
    std::fs::write(&scene, contact).unwrap();
    scene
}

#[test]
fn depth_and_points_reach_rclpy_and_every_transport_gives_the_same_bytes() {
    let dir = std::env::temp_dir().join(format!("unitac-rosdepth-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let scene = depth_scene(&dir);
    let scene_s = scene.to_str().unwrap();
    // The embedded runtime, then bag replay of what it recorded.
    let run = dir.join("run.mcap");
    let frames = FRAMES.to_string();
    let events = unitac_ok(&[
        "run",
        "--scene",
        scene_s,
        "--fast",
        "--events",
        "--max-frames",
        &frames,
        "--out",
        run.to_str().unwrap(),
    ]);
    // The committed summary of these depth maps (crates/cli/tests/golden.rs checks it too and
    // says how it is made).
    let lines: Vec<&str> = events.lines().filter(|l| l.starts_with('{')).collect();
    let got: Vec<Value> = parse_lines(&lines.join("\n"))
        .unwrap()
        .into_iter()
        .filter(|e| e["type"] == "depth")
        .map(|mut e| {
            e.as_object_mut().unwrap().remove("digest");
            e
        })
        .collect();
    let golden = root().join("tests/golden/depth/fabric_selection_depth.jsonl");
    let want = parse_lines(&std::fs::read_to_string(&golden).unwrap()).unwrap();
    if let Some(d) = diff(&want, &got) {
        panic!("depth maps differ from {}: {d}", golden.display());
    }
    let replayed = dir.join("replay.mcap");
    unitac_ok(&[
        "replay",
        run.to_str().unwrap(),
        "--topic",
        "/unitac/image_raw",
        "--scene",
        scene_s,
        "--fast",
        "--out",
        replayed.to_str().unwrap(),
    ]);
    let run_depth: Vec<Image> = messages(&run, "/unitac/depth");
    let run_points: Vec<PointCloud2> = messages(&run, "/unitac/points");
    assert!(run_depth.len() >= 30, "{} depth maps", run_depth.len());
    assert_eq!(run_points.len(), run_depth.len());
    assert!(
        run_depth == messages::<Image>(&replayed, "/unitac/depth"),
        "bag replay's depth differs from the embedded runtime's"
    );
    assert!(
        run_points == messages::<PointCloud2>(&replayed, "/unitac/points"),
        "bag replay's points differ from the embedded runtime's"
    );

    // The nodes on the runtime's bag, an rclpy peer on depth and points.
    let ns = format!("/d{}", std::process::id());
    let scene_p = format!("scene:={scene_s}");
    let contact = node(
        common::STAGE_NODE,
        &common::CONTACT,
        &ns,
        &[
            scene_p.clone(),
            "use_sim_time:=true".into(),
            "image_qos:=reliable".into(),
        ],
    );
    // A second contact node on the same images with the overlay on.
    let overlay_ns = format!("{ns}/overlay");
    let overlay = Command::new(common::STAGE_NODE)
        .args([
            "--ros-args",
            "-r",
            &format!("__ns:={overlay_ns}"),
            "-r",
            "__node:=unitac_contact",
            "-p",
            "stages:=contact,slip",
            "-r",
            &format!("image:={ns}/image_raw"),
            "-p",
            &scene_p,
            "-p",
            "use_sim_time:=true",
            "-p",
            "image_qos:=reliable",
            "-p",
            "contact.overlay:=true",
        ])
        .stdout(Stdio::null())
        .stderr(Stdio::inherit())
        .spawn()
        .unwrap();
    let got_dir = dir.join("ros");
    let mut peer = Command::new(python())
        .arg(root().join("tests/ros/depth_peer.py"))
        .args([
            &ns,
            "90",
            got_dir.to_str().unwrap(),
            &run_depth.len().to_string(),
            &overlay_ns,
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
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
            format!("bag:={}", run.display()),
            "bag_topic:=/unitac/image_raw".into(),
            "rate:=1.0".into(),
            "wait_subscribers:=2".into(),
            format!("image_depth:={}", unitac_ros::image::RELIABLE_IMAGE_DEPTH),
        ],
    );
    let out = peer.wait_with_output().unwrap();
    stop(sensor);
    stop(contact);
    stop(overlay);
    let got: Value = serde_json::from_slice(&out.stdout)
        .unwrap_or_else(|e| panic!("{e}: {}", String::from_utf8_lossy(&out.stdout)));

    // What a ROS user sees.
    let depth = got["depth"].as_array().unwrap();
    let points = got["points"].as_array().unwrap();
    assert_eq!(depth.len(), run_depth.len(), "every depth map arrives");
    assert_eq!(points.len(), run_depth.len(), "every cloud arrives");
    assert_eq!(
        got["overlay_publishers"], 0,
        "contact_overlay is off by default"
    );
    let frame_id = "mock_gelsight_mini_optical_frame";
    let in_contact: Vec<i64> = got["contact_state"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|c| c["in_contact"] == true)
        .map(|c| c["stamp"].as_i64().unwrap())
        .collect();
    assert!(!in_contact.is_empty(), "the press is in the recording");
    let mut deepest = 0.0f64;
    for (d, p) in depth.iter().zip(points) {
        assert_eq!(d["encoding"], "32FC1");
        assert_eq!(
            (d["width"].as_u64(), d["height"].as_u64()),
            (Some(320), Some(240))
        );
        assert_eq!(
            (d["step"].as_u64(), d["values"].as_u64()),
            (Some(1280), Some(76800))
        );
        assert_eq!(
            (&d["frame_id"], &p["frame_id"]),
            (&frame_id.into(), &frame_id.into())
        );
        assert_eq!(d["is_bigendian"], 0);
        // NaN (REP 117) under the marker dots only: a small share of the gel.
        let nan = d["nan"].as_u64().unwrap();
        assert!((768..23040).contains(&nan), "{nan} NaN pixels of 76800");
        // One point per known pixel, x y z float32, dense, in the optical frame: the gel spans
        // 319 pixels of 0.0634 mm across, and a press is a negative z.
        assert_eq!(p["stamp"], d["stamp"]);
        assert_eq!(p["points"].as_u64().unwrap(), 76800 - nan);
        assert_eq!(
            p["fields"],
            serde_json::json!([["x", 0, 7, 1], ["y", 4, 7, 1], ["z", 8, 7, 1]])
        );
        assert_eq!(
            (p["height"].as_u64(), p["point_step"].as_u64()),
            (Some(1), Some(12))
        );
        assert_eq!((&p["is_dense"], &p["finite"]), (&true.into(), &true.into()));
        let span = p["x_span"].as_f64().unwrap();
        assert!((span - 319.0 * 0.0634e-3).abs() < 1e-5, "x span {span} m");
        let max = d["max_m"].as_f64().unwrap();
        assert!((p["z_min"].as_f64().unwrap() + max).abs() < 1e-9, "{p} {d}");
        let stamp = d["stamp"].as_i64().unwrap();
        if stamp < in_contact[0] - 200_000_000 {
            assert!(max < 2e-5, "no phantom depth before the press: {max} m");
        }
        if in_contact.contains(&stamp) {
            deepest = deepest.max(max);
        }
    }
    assert!(
        (2e-4..2e-3).contains(&deepest),
        "penetration of the fabric press {deepest} m"
    );

    // The overlay, with `contact.overlay:=true`: one per frame, the frame beside the depth
    // colour map, the contact outline and the centroid drawn while in contact.
    let overlays = got["overlay"].as_array().unwrap();
    assert!(
        overlays.len() >= run_depth.len(),
        "{} overlays",
        overlays.len()
    );
    let mut drawn = 0;
    for o in overlays {
        assert_eq!(
            (&o["encoding"], &o["frame_id"]),
            (&"rgb8".into(), &frame_id.into())
        );
        assert_eq!(
            (o["width"].as_u64(), o["height"].as_u64()),
            (Some(640), Some(240))
        );
        if in_contact.contains(&o["stamp"].as_i64().unwrap()) {
            assert!(o["outline"].as_u64().unwrap() > 20, "outline drawn: {o}");
            assert!(o["centroid"].as_u64().unwrap() >= 9, "centroid drawn: {o}");
            drawn += 1;
        }
    }
    assert!(drawn > 0, "overlays of frames in contact");

    // The same bytes as the embedded runtime's (and so bag replay's).
    let ros_depth: Vec<Image> = received(&got_dir, "depth");
    let ros_points: Vec<PointCloud2> = received(&got_dir, "points");
    assert!(
        ros_depth == run_depth,
        "the contact node's depth differs from the embedded runtime's"
    );
    assert!(
        ros_points == run_points,
        "the contact node's points differ from the embedded runtime's"
    );
    std::fs::remove_dir_all(&dir).ok();
}
