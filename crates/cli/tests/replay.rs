//! `unitac replay` and `unitac run --sensor bag:PATH`: the command-line contract for bags.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use unitac_bag::ros::Image;
use unitac_bag::{BagReader, BagWriter, ReadOptions, WriteOptions};
use unitac_core::{SensorKind, Source};
use unitac_sim::{MockConfig, MockSensor, Scenario};

fn unitac(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_unitac"))
        .args(args)
        .env("RUST_LOG", "warn")
        .output()
        .unwrap()
}

fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("unitac-cli-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// The mock fabric scene (140 frames, seed 7 as launch/scenes/fabric_selection.yaml) recorded as an rgb8 MCAP bag,
/// with frame_id <sensor>_optical_frame. Returns the stamps.
fn mock_bag(path: &Path) -> Vec<i64> {
    let mut s = MockSensor::new(
        MockConfig::new(SensorKind::GELSIGHT_MINI, 7),
        Scenario::fabric_selection(),
    );
    let mut w = BagWriter::create(path, WriteOptions::default()).unwrap();
    let t = w
        .add_topic("/gs/image_raw", "sensor_msgs/msg/Image")
        .unwrap();
    let u = w
        .add_topic("/unitac/contact_state", "unitac_msgs/msg/ContactState")
        .unwrap();
    let _ = u;
    let mut stamps = Vec::new();
    while let Some(f) = s.next_frame().unwrap() {
        w.write(t, f.stamp.0, &Image::rgb8(&f)).unwrap();
        stamps.push(f.stamp.0);
    }
    w.finish().unwrap();
    stamps
}

fn lines(o: &Output) -> Vec<Value> {
    String::from_utf8_lossy(&o.stdout)
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

#[test]
fn replay_json_is_one_line_per_image_and_out_bags_are_identical() {
    let dir = tmpdir("replay");
    let bag = dir.join("in");
    let stamps = mock_bag(&bag);
    let a = dir.join("a.mcap");
    let o = unitac(&[
        "replay",
        bag.to_str().unwrap(),
        "--fast",
        "--json",
        "--out",
        a.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let l = lines(&o);
    assert_eq!(l.len(), stamps.len(), "exactly one line per image message");
    for (j, s) in l.iter().zip(&stamps) {
        assert_eq!(j["stamp"].as_i64(), Some(*s));
        for k in ["contact", "area_px", "centroid", "episode_id"] {
            assert!(j.get(k).is_some(), "{k} missing in {j}");
        }
    }
    // Nothing while the background is learned, then a decision on every frame.
    assert!(l[0]["contact"].is_null());
    let first = l.iter().position(|j| !j["contact"].is_null()).unwrap();
    assert!(first > 0 && first < 20, "{first}");
    assert!(l[first..].iter().all(|j| j["contact"].is_boolean()));
    assert!(l.iter().any(|j| j["contact"] == true));
    let ids: Vec<u64> = l.iter().filter_map(|j| j["episode_id"].as_u64()).collect();
    assert!(
        ids.iter().max().unwrap() >= &2,
        "two fabrics touched: {ids:?}"
    );

    // Same again: byte-identical output.
    let b = dir.join("b.mcap");
    let o2 = unitac(&[
        "replay",
        bag.to_str().unwrap(),
        "--fast",
        "--json",
        "--out",
        b.to_str().unwrap(),
    ]);
    assert!(o2.status.success());
    assert_eq!(o.stdout, o2.stdout);
    assert!(
        std::fs::read(&a).unwrap() == std::fs::read(&b).unwrap(),
        "output bags differ"
    );
    // The output bag holds the inputs and the pipeline's messages.
    let msgs: Vec<_> = BagReader::open(&a, ReadOptions::default())
        .unwrap()
        .map(|m| m.unwrap())
        .collect();
    let n = |t: &str| msgs.iter().filter(|m| m.topic.name == t).count();
    assert_eq!(n("/gs/image_raw"), stamps.len());
    assert_eq!(n("/unitac/contact_state"), stamps.len() - first);
    assert!(n("/unitac/contact_episode") >= 2);

    // --start and --topic.
    let o = unitac(&[
        "replay",
        bag.to_str().unwrap(),
        "--fast",
        "--json",
        "--start",
        "2",
        "--topic",
        "/gs/image_raw",
    ]);
    assert!(o.status.success());
    let l = lines(&o);
    assert_eq!(l[0]["stamp"].as_i64(), Some(stamps[0] + 2_000_000_000));
    // Real-time pacing at 20x: 140 frames of 30 fps (4.6 s of stream) take at least 0.2 s.
    let t0 = std::time::Instant::now();
    let o = unitac(&["replay", bag.to_str().unwrap(), "--rate", "20", "--json"]);
    assert!(o.status.success());
    assert!(t0.elapsed().as_secs_f64() > 0.2);
    assert_eq!(lines(&o).len(), stamps.len());
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn run_with_a_bag_sensor_matches_the_mock_run() {
    let dir = tmpdir("runbag");
    let bag = dir.join("in");
    mock_bag(&bag);
    let sensor = format!("bag:{}", bag.display());
    let from_bag = unitac(&[
        "run",
        "--scene",
        "fabric_selection",
        "--sensor",
        &sensor,
        "--fast",
        "--json",
    ]);
    assert!(
        from_bag.status.success(),
        "{}",
        String::from_utf8_lossy(&from_bag.stderr)
    );
    let from_mock = unitac(&[
        "run",
        "--scene",
        "fabric_selection",
        "--sensor",
        "mock",
        "--fast",
        "--json",
    ]);
    let (b, m): (Value, Value) = (
        serde_json::from_slice(&from_bag.stdout).unwrap(),
        serde_json::from_slice(&from_mock.stdout).unwrap(),
    );
    assert_eq!(b["frames"], m["frames"]);
    assert_eq!(b["ended"], "source_end");
    assert!(b["source"].as_str().unwrap().starts_with("bag:"));
    assert!(!b["episodes"].as_array().unwrap().is_empty());
    // Same frames, same stamps, same sensor id: the same episodes, field for field.
    assert_eq!(b["episodes"], m["episodes"]);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn replay_errors_and_exit_codes() {
    let dir = tmpdir("replayerr");
    let o = unitac(&["replay", dir.join("missing").to_str().unwrap(), "--fast"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("missing"));
    let bag = dir.join("in.mcap");
    mock_bag(&bag);
    let o = unitac(&["replay", bag.to_str().unwrap(), "--rate", "0"]);
    assert_eq!(o.status.code(), Some(2));
    let o = unitac(&[
        "replay",
        bag.to_str().unwrap(),
        "--fast",
        "--topic",
        "/nothing",
    ]);
    assert_eq!(
        o.status.code(),
        Some(1),
        "a replay that replays nothing fails"
    );
    assert!(String::from_utf8_lossy(&o.stderr).contains("no image messages"));
    let o = unitac(&[
        "run",
        "--scene",
        "fabric_selection",
        "--sensor",
        "bag:/nonexistent",
        "--fast",
    ]);
    assert_eq!(o.status.code(), Some(2));
    // An output bag that exists is not overwritten.
    let o = unitac(&[
        "replay",
        bag.to_str().unwrap(),
        "--fast",
        "--out",
        bag.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    std::fs::remove_dir_all(&dir).ok();
}
