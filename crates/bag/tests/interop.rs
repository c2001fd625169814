//! Interop with the independent Python library rosbags, both ways (tests/bag/*.py, run with the
//! project's .venv): bags rosbags writes (MCAP with zstd chunks, sqlite3, rgb8 / bgr8 / JPEG)
//! replay here frame for frame; bags written here are read back by rosbags with every message,
//! type and field, the project's unitac_msgs included.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use common::*;
use serde_json::Value;
use std::ffi::OsStr;
use unitac_bag::{
    BagReader, BagWriter, CompressedImage, Compression, Image, ReadOptions, ReplayOptions,
    RosMessage, WriteOptions,
};
use unitac_core::Stamp;
use unitac_core::msg::*;

fn contact_states(events: &[Msg]) -> Vec<ContactState> {
    events
        .iter()
        .filter_map(|m| match m {
            Msg::ContactState(c) => Some(c.clone()),
            _ => None,
        })
        .collect()
}

#[test]
fn python_written_bags_replay_frame_for_frame() {
    let frames = mock_frames(100);
    let (w, h) = (frames[0].width, frames[0].height);
    let dir = tmpdir("pywritten");
    let raw: Vec<u8> = frames.iter().flat_map(|f| f.data().to_vec()).collect();
    std::fs::write(dir.join("frames.raw"), raw).unwrap();
    let stamps: Vec<i64> = frames.iter().map(|f| f.stamp.0).collect();
    std::fs::write(
        dir.join("stamps.json"),
        serde_json::to_string(&stamps).unwrap(),
    )
    .unwrap();
    let out = dir.join("bags");
    run_py(
        "make_bags.py",
        &[
            dir.join("frames.raw").as_os_str(),
            dir.join("stamps.json").as_os_str(),
            OsStr::new(&w.to_string()),
            OsStr::new(&h.to_string()),
            out.as_os_str(),
        ],
    );
    // The MCAP from rosbags really has zstd chunks.
    let mcap = std::fs::read(out.join("mcap_rgb8_zstd/mcap_rgb8_zstd.mcap")).unwrap();
    assert!(mcap.windows(4).any(|x| x == b"zstd"));

    let expected = direct_contact(&frames);
    let want_states: Vec<Vec<ContactState>> = expected.iter().map(|e| contact_states(e)).collect();
    assert!(
        want_states.iter().flatten().any(|c| c.in_contact),
        "the fixture must contain contact"
    );

    // Lossless encodings: identical frames, so identical contact states, stamp for stamp.
    for bag in ["mcap_rgb8_zstd", "sqlite_bgr8"] {
        let path = out.join(bag);
        let mut src = unitac_bag::BagSource::open(&path, ReplayOptions::default()).unwrap();
        for f in &frames {
            let item = src.next_image().unwrap().expect("an image per frame");
            let got = item.frame.unwrap();
            assert_eq!(got.stamp, f.stamp, "{bag}");
            assert_eq!(got.data(), f.data(), "{bag}: pixels at {:?}", f.stamp);
            assert_eq!(got.sensor_id, "gs");
        }
        assert!(src.next_image().unwrap().is_none());

        let (lines, report) = replay_contact(&path, ReplayOptions::default(), None);
        assert_eq!(
            lines.len(),
            frames.len(),
            "{bag}: one result per image message"
        );
        assert_eq!(report.images, frames.len() as u64);
        assert_eq!(report.topic.as_deref(), Some("/gs/image_raw"));
        for ((stamp, events, err), want) in lines.iter().zip(&want_states) {
            assert!(err.is_none(), "{bag}: {err:?}");
            let mut got = contact_states(events);
            // The sensor id comes from the frame_id here, "mock_gelsight_mini" directly.
            for c in &mut got {
                assert_eq!(c.sensor_id, "gs");
                c.sensor_id = want.first().map_or(String::new(), |w| w.sensor_id.clone());
                c.header.frame_id = want
                    .first()
                    .map_or(String::new(), |w| w.header.frame_id.clone());
            }
            assert_eq!(&got, want, "{bag} at {stamp}");
        }
        if bag == "mcap_rgb8_zstd" {
            assert_eq!(report.skipped_topics, ["/chatter"], "unknown type skipped");
            // Its raw bytes are still there for whoever asks.
            let chatter: Vec<_> = BagReader::open(
                &path,
                ReadOptions {
                    topics: vec!["/chatter".into()],
                    ..Default::default()
                },
            )
            .unwrap()
            .map(|m| m.unwrap())
            .collect();
            assert_eq!(chatter.len(), 10);
            assert_eq!(chatter[0].topic.type_name, "std_msgs/msg/String");
            assert!(chatter[0].data.ends_with(b"frame 0\0"));
        }
    }

    // JPEG: close pixels, and the same contact decisions on nearly every frame.
    let path = out.join("mcap_jpeg");
    let mut src = unitac_bag::BagSource::open(&path, ReplayOptions::default()).unwrap();
    for f in &frames {
        let got = src.next_image().unwrap().unwrap().frame.unwrap();
        assert_eq!(got.stamp, f.stamp);
        let mad: f64 = got
            .data()
            .iter()
            .zip(f.data())
            .map(|(a, b)| f64::from(a.abs_diff(*b)))
            .sum::<f64>()
            / f.data().len() as f64;
        assert!(mad < 3.0, "JPEG q95 mean abs diff {mad}");
    }
    let (lines, _) = replay_contact(&path, ReplayOptions::default(), None);
    assert_eq!(lines.len(), frames.len());
    let (mut same, mut total) = (0, 0);
    for ((_, events, _), want) in lines.iter().zip(&want_states) {
        let got = contact_states(events);
        if let (Some(g), Some(w)) = (got.first(), want.first()) {
            total += 1;
            same += usize::from(g.in_contact == w.in_contact);
        }
    }
    assert!(total > 50 && same * 100 >= total * 95, "{same}/{total}");
    std::fs::remove_dir_all(&dir).ok();
}

fn header(ns: i64) -> Header {
    Header::new(Stamp(ns), "gs_optical_frame")
}

struct Written {
    contact: ContactState,
    episode: ContactEpisode,
    props: TactileProperties,
    cmp: PropertyComparison,
    latent: TactileLatent,
    cmd: GripperCommand,
    status: PolicyStatus,
    gripper: GripperStatus,
    arm: ArmCommand,
    visual: VisualObservation,
    image: Image,
    jpeg: CompressedImage,
}

fn fixture() -> Written {
    let t = 1_700_000_000_250_000_000;
    Written {
        contact: ContactState {
            header: header(t),
            sensor_id: "gs".into(),
            frame_seq: 12,
            in_contact: true,
            area_px: 1234.5,
            area_m2: 7.25e-6,
            centroid_px: [160.5, 120.25],
            bbox_px: [10, 20, 30, 40],
            strength: 0.75,
            episode_id: 3,
            background_age_s: 12.5,
        },
        episode: ContactEpisode {
            header: header(t + 1),
            sensor_id: "gs".into(),
            episode_id: 3,
            start: Stamp(t - 2_000_000_000),
            end: Stamp(t),
            frame_count: 48,
            peak_area_px: 2048.0,
            peak_area_m2: 11.5e-6,
            peak_frame_seq: 40,
            label: "fabric_a".into(),
        },
        props: TactileProperties {
            header: header(t + 2),
            sensor_id: "gs".into(),
            episode_id: 3,
            label: "fabric_a".into(),
            hardness: 0.5,
            hardness_std: 0.125,
            roughness: -1.5,
            roughness_std: 0.25,
            texture: 2.0,
            texture_std: 0.0625,
            model_id: "reference@abcd".into(),
        },
        cmp: PropertyComparison {
            header: header(t + 3),
            property: "roughness".into(),
            episode_a: 3,
            label_a: "fabric_a".into(),
            episode_b: 4,
            label_b: "fabric_b".into(),
            winner: Winner::B,
            score_a: 0.25,
            score_b: 0.75,
            margin: -0.5,
            confidence: 0.875,
            sentence: "B is rougher than A — ünïcode".into(),
        },
        latent: TactileLatent {
            header: header(t + 4),
            source: LatentSource::Predicted,
            sensor_id: "gs".into(),
            shape: vec![2, 3],
            data: vec![0.5, -1.0, 2.25, 3.0, -0.125, 8.0],
            model_id: "reference".into(),
            solver: "heun".into(),
            steps: 8,
            guidance: 1.5,
            elapsed_s: 0.015625,
            valid: true,
            guard_report: String::new(),
            object: String::new(),
            condition_sources: Vec::new(),
            condition_age_s: Vec::new(),
        },
        cmd: GripperCommand {
            header: header(t + 5),
            mode: GripperMode::Force,
            position_m: 0.0425,
            speed_m_s: 0.05,
            force_n: 12.5,
            reason: "grasp smoother".into(),
        },
        status: PolicyStatus {
            header: header(t + 6),
            scene: "fabric_selection".into(),
            mode: "vtla_real".into(),
            phase: "press".into(),
            safety_ok: false,
            message: "force limit".into(),
            clamped: vec!["gripper.force_n".into(), "arm.lift_m".into()],
        },
        gripper: GripperStatus {
            header: header(t + 7),
            opening_m: 0.0375,
            target_m: 0.03125,
            force_n: 6.5,
            current_a: 0.25,
            object_detected: true,
            activation: "active".into(),
            motion: "stopped".into(),
            fault: String::new(),
        },
        arm: ArmCommand {
            header: header(t + 8),
            target: "fabric_b".into(),
            x_m: 0.4375,
            y_m: -0.125,
            z_m: 0.004,
            lift_m: 0.0625,
            reason: "grasp the smoother (B)".into(),
        },
        visual: VisualObservation {
            header: header(t + 9),
            names: vec!["cup_width_m".into(), "cup_x_m".into(), "ünïcode".into()],
            values: vec![0.0815, -0.125, 1e-300],
        },
        image: Image {
            header: header(t),
            height: 3,
            width: 4,
            encoding: "rgb8".into(),
            is_bigendian: 0,
            step: 12,
            data: (0..36).collect(),
        },
        jpeg: CompressedImage {
            header: header(t),
            format: "jpeg".into(),
            data: vec![0xff, 0xd8, 0xff, 0xe0, 1, 2, 3],
        },
    }
}

fn put<M: RosMessage>(w: &mut BagWriter, topic: &str, m: &M, t: i64, n: i64) {
    let id = w.add_topic(topic, M::TYPE).unwrap();
    for i in 0..n {
        w.write(id, t + i, m).unwrap();
    }
}

fn write_fixture(path: &std::path::Path, compression: Compression) -> Written {
    let x = fixture();
    let mut w = BagWriter::create(
        path,
        WriteOptions {
            compression,
            chunk_size: 256,
        },
    )
    .unwrap();
    put(&mut w, "/gs/image_raw", &x.image, x.image.header.stamp.0, 3);
    put(
        &mut w,
        "/gs/image_raw/compressed",
        &x.jpeg,
        x.jpeg.header.stamp.0,
        2,
    );
    put(
        &mut w,
        "/unitac/contact_state",
        &x.contact,
        x.contact.header.stamp.0,
        2,
    );
    put(
        &mut w,
        "/unitac/contact_episode",
        &x.episode,
        x.episode.header.stamp.0,
        1,
    );
    put(
        &mut w,
        "/unitac/tactile_properties",
        &x.props,
        x.props.header.stamp.0,
        1,
    );
    put(
        &mut w,
        "/unitac/property_comparison",
        &x.cmp,
        x.cmp.header.stamp.0,
        1,
    );
    put(
        &mut w,
        "/unitac/tactile_latent",
        &x.latent,
        x.latent.header.stamp.0,
        1,
    );
    put(
        &mut w,
        "/unitac/gripper_command",
        &x.cmd,
        x.cmd.header.stamp.0,
        1,
    );
    put(
        &mut w,
        "/unitac/policy_status",
        &x.status,
        x.status.header.stamp.0,
        1,
    );
    put(
        &mut w,
        "/unitac/gripper_status",
        &x.gripper,
        x.gripper.header.stamp.0,
        1,
    );
    put(
        &mut w,
        "/unitac/arm_command",
        &x.arm,
        x.arm.header.stamp.0,
        1,
    );
    put(
        &mut w,
        "/unitac/visual_observation",
        &x.visual,
        x.visual.header.stamp.0,
        1,
    );
    w.finish().unwrap();
    x
}

fn time(j: &Value) -> i64 {
    j["sec"].as_i64().unwrap() * 1_000_000_000 + j["nanosec"].as_i64().unwrap()
}

fn check_header(j: &Value, h: &Header) {
    assert_eq!(time(&j["stamp"]), h.stamp.0);
    assert_eq!(j["frame_id"], h.frame_id.as_str());
}

#[test]
fn bags_written_here_are_read_by_rosbags_field_for_field() {
    let dir = tmpdir("ours");
    for (name, c) in [
        ("zstd", Compression::Zstd),
        ("lz4", Compression::Lz4),
        ("none", Compression::None),
        ("bare.mcap", Compression::Zstd),
    ] {
        let path = dir.join(name);
        let x = write_fixture(&path, c);
        let out = run_py("read_bag.py", &[path.as_os_str()]);
        let mut lines = out
            .lines()
            .map(|l| serde_json::from_str::<Value>(l).unwrap());
        let topics = lines.next().unwrap();
        let topics = topics["topics"].as_array().unwrap().clone();
        assert_eq!(topics.len(), 12, "{name}");
        for t in &topics {
            assert_eq!(t["schema_matches"], true, "{name}: schema of {}", t["type"]);
            if !name.ends_with(".mcap") {
                assert_eq!(t["qos"], 1, "{name}: offered_qos_profiles of {}", t["name"]);
            }
        }
        let msgs: Vec<Value> = lines.collect();
        assert_eq!(msgs.len(), 16, "{name}: every message");
        let by = |topic: &str| -> Vec<&Value> {
            msgs.iter()
                .filter(|m| m["topic"] == topic)
                .map(|m| &m["msg"])
                .collect()
        };
        // Image
        let imgs = by("/gs/image_raw");
        assert_eq!(imgs.len(), 3);
        let m = imgs[0];
        check_header(&m["header"], &x.image.header);
        assert_eq!(
            (m["height"].as_u64(), m["width"].as_u64()),
            (Some(3), Some(4))
        );
        assert_eq!(m["encoding"], "rgb8");
        assert_eq!(m["step"], 12);
        assert_eq!(m["data"]["len"], 36);
        let jp = by("/gs/image_raw/compressed");
        assert_eq!(jp.len(), 2);
        assert_eq!(jp[0]["format"], "jpeg");
        assert_eq!(jp[0]["data"]["len"], 7);
        // ContactState
        let c = by("/unitac/contact_state")[0];
        check_header(&c["header"], &x.contact.header);
        assert_eq!(c["sensor_id"], "gs");
        assert_eq!(c["frame_seq"], 12);
        assert_eq!(c["in_contact"], true);
        assert_eq!(c["area_px"], 1234.5);
        // As f32: serde_json parses floats to within an ulp of f64, not always exactly.
        assert_eq!(c["area_m2"].as_f64().map(|v| v as f32), Some(7.25e-6_f32));
        assert_eq!(c["centroid_px"], serde_json::json!([160.5, 120.25]));
        assert_eq!(c["bbox_px"], serde_json::json!([10, 20, 30, 40]));
        assert_eq!(c["strength"], 0.75);
        assert_eq!(c["episode_id"], 3);
        assert_eq!(c["background_age_s"], 12.5);
        // ContactEpisode
        let e = by("/unitac/contact_episode")[0];
        check_header(&e["header"], &x.episode.header);
        assert_eq!(time(&e["start"]), x.episode.start.0);
        assert_eq!(time(&e["end"]), x.episode.end.0);
        assert_eq!(e["frame_count"], 48);
        assert_eq!(e["peak_area_px"], 2048.0);
        assert_eq!(
            e["peak_area_m2"].as_f64().map(|v| v as f32),
            Some(11.5e-6_f32)
        );
        assert_eq!(e["peak_frame_seq"], 40);
        assert_eq!(e["label"], "fabric_a");
        // TactileProperties
        let p = by("/unitac/tactile_properties")[0];
        check_header(&p["header"], &x.props.header);
        for (k, v) in [
            ("hardness", 0.5),
            ("hardness_std", 0.125),
            ("roughness", -1.5),
            ("roughness_std", 0.25),
            ("texture", 2.0),
            ("texture_std", 0.0625),
        ] {
            assert_eq!(p[k], v, "{k}");
        }
        assert_eq!(p["episode_id"], 3);
        assert_eq!(p["label"], "fabric_a");
        assert_eq!(p["model_id"], "reference@abcd");
        // PropertyComparison
        let q = by("/unitac/property_comparison")[0];
        check_header(&q["header"], &x.cmp.header);
        assert_eq!(q["property"], "roughness");
        assert_eq!(
            (q["episode_a"].as_u64(), q["episode_b"].as_u64()),
            (Some(3), Some(4))
        );
        assert_eq!(
            (q["label_a"].as_str(), q["label_b"].as_str()),
            (Some("fabric_a"), Some("fabric_b"))
        );
        assert_eq!(q["winner"], 1);
        assert_eq!(q["score_a"], 0.25);
        assert_eq!(q["score_b"], 0.75);
        assert_eq!(q["margin"], -0.5);
        assert_eq!(q["confidence"], 0.875);
        assert_eq!(q["sentence"], x.cmp.sentence.as_str());
        // TactileLatent
        let l = by("/unitac/tactile_latent")[0];
        check_header(&l["header"], &x.latent.header);
        assert_eq!(l["source"], 1);
        assert_eq!(l["shape"], serde_json::json!([2, 3]));
        assert_eq!(
            l["data"],
            serde_json::json!([0.5, -1.0, 2.25, 3.0, -0.125, 8.0])
        );
        assert_eq!(l["model_id"], "reference");
        assert_eq!(l["solver"], "heun");
        assert_eq!(l["steps"], 8);
        assert_eq!(l["guidance"], 1.5);
        assert_eq!(l["elapsed_s"], 0.015625);
        assert_eq!(l["valid"], true);
        assert_eq!(l["guard_report"], "");
        // GripperCommand
        let g = by("/unitac/gripper_command")[0];
        check_header(&g["header"], &x.cmd.header);
        assert_eq!(g["mode"], 1);
        assert_eq!(g["position_m"], 0.0425);
        assert_eq!(g["speed_m_s"], 0.05);
        assert_eq!(g["force_n"], 12.5);
        assert_eq!(g["reason"], "grasp smoother");
        // PolicyStatus
        let s = by("/unitac/policy_status")[0];
        check_header(&s["header"], &x.status.header);
        assert_eq!(s["scene"], "fabric_selection");
        assert_eq!(s["mode"], "vtla_real");
        assert_eq!(s["phase"], "press");
        assert_eq!(s["safety_ok"], false);
        assert_eq!(s["message"], "force limit");
        // GripperStatus
        let g = by("/unitac/gripper_status")[0];
        check_header(&g["header"], &x.gripper.header);
        assert_eq!(g["opening_m"], 0.0375);
        assert_eq!(g["target_m"], 0.03125);
        assert_eq!(g["force_n"], 6.5);
        assert_eq!(g["current_a"], 0.25);
        assert_eq!(g["object_detected"], true);
        assert_eq!(g["activation"], "active");
        assert_eq!(g["motion"], "stopped");
        assert_eq!(g["fault"], "");
        // ArmCommand
        let a = by("/unitac/arm_command")[0];
        check_header(&a["header"], &x.arm.header);
        assert_eq!(a["target"], "fabric_b");
        assert_eq!(a["z_m"], 0.004);
        assert_eq!(a["lift_m"], 0.0625);
        assert_eq!(a["reason"], "grasp the smoother (B)");
        // VisualObservation
        let v = by("/unitac/visual_observation")[0];
        check_header(&v["header"], &x.visual.header);
        assert_eq!(
            v["names"],
            serde_json::json!(["cup_width_m", "cup_x_m", "ünïcode"])
        );
        assert_eq!(v["values"], serde_json::json!([0.0815, -0.125, 1e-300]));
        // Log times as written.
        let imgs: Vec<i64> = msgs
            .iter()
            .filter(|m| m["topic"] == "/gs/image_raw")
            .map(|m| m["log_time"].as_i64().unwrap())
            .collect();
        assert_eq!(imgs, [0, 1, 2].map(|i| x.image.header.stamp.0 + i));

        // And our own reader gets the same messages back, decoded to equal values.
        let ours: Vec<_> = BagReader::open(&path, ReadOptions::default())
            .unwrap()
            .map(|m| m.unwrap())
            .collect();
        assert_eq!(ours.len(), 16);
        let find = |t: &str| ours.iter().find(|m| m.topic.name == t).unwrap();
        assert_eq!(
            ContactState::from_cdr(&find("/unitac/contact_state").data).unwrap(),
            x.contact
        );
        assert_eq!(
            TactileLatent::from_cdr(&find("/unitac/tactile_latent").data).unwrap(),
            x.latent
        );
        assert_eq!(
            PropertyComparison::from_cdr(&find("/unitac/property_comparison").data).unwrap(),
            x.cmp
        );
        assert_eq!(
            Image::from_cdr(&find("/gs/image_raw").data).unwrap(),
            x.image
        );
        assert_eq!(
            GripperStatus::from_cdr(&find("/unitac/gripper_status").data).unwrap(),
            x.gripper
        );
        assert_eq!(
            ArmCommand::from_cdr(&find("/unitac/arm_command").data).unwrap(),
            x.arm
        );
        assert_eq!(
            VisualObservation::from_cdr(&find("/unitac/visual_observation").data).unwrap(),
            x.visual
        );
    }
    std::fs::remove_dir_all(&dir).ok();
}
