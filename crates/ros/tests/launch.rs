//! Launch files: they import, declare every argument with a description, and the nodes they start
//! exist (built here) for every scene they offer; arguments leave nodes out.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use std::path::PathBuf;
use std::process::Command;

/// A plan's parameters for node `name` as a params file (in the temp dir, named by `tag`): its
/// path and text.
fn params_file(tag: &str, name: &str, params: &serde_json::Value) -> (PathBuf, String) {
    let mut yaml = String::from("/**:\n  ros__parameters:\n");
    for (k, v) in params.as_object().unwrap() {
        yaml.push_str(&format!("    {k}: {v}\n"));
    }
    let path =
        std::env::temp_dir().join(format!("unitac-{}-{tag}-{name}.yaml", std::process::id()));
    std::fs::write(&path, &yaml).unwrap();
    (path, yaml)
}

fn check_launch() -> (serde_json::Value, PathBuf) {
    check_launch_with(None)
}

/// check_launch.py's summary, with `UNITAC_SCENES` (a further scene directory, looked in first)
/// when given; without, the variable is unset for the check.
fn check_launch_with(scenes: Option<&std::path::Path>) -> (serde_json::Value, PathBuf) {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..");
    let py = std::env::var_os("UNITAC_VENV")
        .map(PathBuf::from)
        .unwrap_or_else(|| root.join(".venv"))
        .join("bin/python");
    let bin_dir = PathBuf::from(env!("CARGO_BIN_EXE_unitac_stage_node"))
        .parent()
        .unwrap()
        .to_path_buf();
    let mut c = Command::new(py);
    c.arg(root.join("tests/ros/check_launch.py"))
        .arg(root.join("launch"))
        .arg(&bin_dir);
    match scenes {
        Some(d) => c.env("UNITAC_SCENES", d),
        None => c.env_remove("UNITAC_SCENES"),
    };
    let o = c.output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    (serde_json::from_slice(&o.stdout).unwrap(), bin_dir)
}

/// The arguments a launch file declares, as check_launch.py lists them.
fn arguments(f: &serde_json::Value) -> Vec<&str> {
    f["arguments"]
        .as_array()
        .unwrap()
        .iter()
        .map(|a| a.as_str().unwrap())
        .collect()
}

#[test]
fn launch_files_are_consistent_with_scenes_and_executables() {
    let (j, _) = check_launch();
    assert_eq!(j["problems"], serde_json::json!([]), "{j}");
    for file in ["fabric_selection", "cup_deformation", "replay"] {
        let f = &j["files"][file];
        let args = arguments(f);
        for a in [
            "source",
            "sensor_kind",
            "sensor_id",
            "serial",
            "bag",
            "rate",
            "image_transport",
            "use_sim_time",
            "namespace",
            "inference",
            "sensor",
            "params_file",
        ] {
            assert!(args.contains(&a), "{file}: {a} not declared");
        }
        let plan = |k: &str| &f["plans"][k];
        let nodes = |k: &str| plan(k)["nodes"].clone();
        let params = |k: &str, exe: &str| plan(k)["parameters"][exe].clone();
        // The cup scene's stages are the contact stage alone (its predicted touch needs a camera:
        // cup_deformation_vtla_pred), so no inference node is planned for it.
        let all = if file == "cup_deformation" {
            serde_json::json!(["unitac_sensor", "unitac_contact"])
        } else {
            serde_json::json!(["unitac_sensor", "unitac_contact", "unitac_inference"])
        };
        let bag = r#"{"source": "bag", "bag": "recorded.mcap"}"#;
        assert_eq!(nodes(bag), all, "{file}: {f}");
        assert_eq!(params(bag, "unitac_sensor")["source"], "bag");
        assert_eq!(params(bag, "unitac_sensor")["bag"], "recorded.mcap");
        // Under a bag, every node but the one publishing /clock runs on bag time.
        assert!(params(bag, "unitac_sensor")["use_sim_time"].is_null());
        let stage_nodes: &[&str] = if file == "cup_deformation" {
            &["unitac_contact"]
        } else {
            &["unitac_contact", "unitac_inference"]
        };
        for exe in stage_nodes {
            assert_eq!(params(bag, exe)["use_sim_time"], true, "{file} {exe}");
        }
        // The stage nodes read the scene file the plan came from.
        let scene = params(bag, stage_nodes[stage_nodes.len() - 1])["scene"].clone();
        assert!(
            scene
                .as_str()
                .unwrap()
                .ends_with(&format!("scenes/{}.yaml", f["scene"].as_str().unwrap())),
            "{scene}"
        );
        if file == "replay" {
            // Replay is bag-only: without a bag path it starts no sensor node and says why.
            assert_eq!(f["scene"], "fabric_selection");
            assert!(plan("{}")["skipped"].to_string().contains("bag:=PATH"));
            continue;
        }
        assert_eq!(nodes("{}"), all, "{file}: {f}");
        assert!(params("{}", "unitac_contact")["use_sim_time"].is_null());
        assert_eq!(
            nodes(r#"{"inference": "false"}"#),
            serde_json::json!(["unitac_sensor", "unitac_contact"])
        );
        assert_eq!(
            nodes(r#"{"sensor": "false"}"#),
            serde_json::json!(stage_nodes)
        );
        let v4l = r#"{"source": "v4l"}"#;
        assert_eq!(nodes(v4l), all);
        assert_eq!(params(v4l, "unitac_sensor")["source"], "v4l");
    }
    // Stage parameters are not copied (and so cannot be dropped): the contact node gets the
    // scene file and reads its stage from there, as `unitac run` does.
    let c = &j["files"]["fabric_selection"]["plans"]["{}"]["parameters"]["unitac_contact"];
    let keys: Vec<&str> = c.as_object().unwrap().keys().map(String::as_str).collect();
    assert_eq!(
        keys,
        ["image_transport", "scene", "sensor_id", "stages"],
        "{c}"
    );
    assert_eq!(c["stages"], "contact");
    let i = &j["files"]["fabric_selection"]["plans"]["{}"]["parameters"]["unitac_inference"];
    assert_eq!(i["stages"], "encoder,compare");
    assert!(
        c["scene"]
            .as_str()
            .unwrap()
            .ends_with("launch/scenes/fabric_selection.yaml")
    );
    // An argument the launch files do not declare is an error, not ignored.
    let e = j["unknown_argument"].as_str().unwrap();
    assert!(
        e.contains("unknown launch argument") && e.contains("noise_k"),
        "{e}"
    );
}

/// The closed-loop files (`<task>_<mode>.launch.py`): the sim node instead of the sensor node,
/// the scene's contact and inference nodes when the mode has those stages, the policy node, all
/// but the sim on sim time.
#[test]
fn closed_loop_files_start_the_sim_and_the_modes_nodes() {
    let (j, _) = check_launch();
    assert_eq!(j["problems"], serde_json::json!([]), "{j}");
    // A gripper that cannot be: an unknown model, the sim's gripper without the sim, a second
    // gripper beside the sim's; each a one-line error naming it.
    let bad = &j["bad_gripper"];
    assert!(
        bad["unknown"]
            .as_str()
            .unwrap()
            .contains("gripper:=robotiq_3f is not one of"),
        "{bad}"
    );
    assert!(
        bad["sim_without_sim"]
            .as_str()
            .unwrap()
            .contains("needs source:=sim"),
        "{bad}"
    );
    assert!(
        bad["serial_with_sim"]
            .as_str()
            .unwrap()
            .contains("second one"),
        "{bad}"
    );
    let touch = serde_json::json!([
        "unitac_sim",
        "unitac_contact",
        "unitac_inference",
        "unitac_policy"
    ]);
    let tasks = unitac_pipeline::tasks(None);
    assert!(tasks.len() >= 2, "{tasks:?}");
    for (task, modes) in &tasks {
        for mode in modes.iter().map(|m| m.as_str()) {
            let file = unitac_pipeline::mode_scene(task, mode.parse().unwrap());
            let f = &j["files"][file.as_str()];
            assert_eq!(f["scene"], file.as_str());
            for a in ["split", "seed", "trial", "duration_s", "max_rate"] {
                assert!(f["arguments"].to_string().contains(a), "{file}: {a}");
            }
            let plan = &f["plans"]["{}"];
            if mode == "vla" {
                // No touch: no contact or inference node, and the sim waits for no image reader.
                assert_eq!(
                    plan["nodes"],
                    serde_json::json!(["unitac_sim", "unitac_policy"]),
                    "{file}"
                );
            } else {
                assert_eq!(plan["nodes"], touch, "{file}");
            }
            let params = &plan["parameters"];
            let sim = &params["unitac_sim"];
            // The sim node reads its task, control rate and trial length from the scene (the
            // same file as the policy node); none of them is copied into the plan.
            assert!(
                sim["scene"]
                    .as_str()
                    .unwrap()
                    .ends_with(&format!("scenes/{file}.yaml")),
                "{sim}"
            );
            for copied in ["task", "control_rate_hz", "duration_s"] {
                assert!(sim[copied].is_null(), "{file}: {copied} in {sim}");
            }
            assert_eq!(sim["wait_subscribers"], 1);
            assert_eq!(sim["wait_image_subscribers"], i32::from(mode != "vla"));
            assert!(sim["use_sim_time"].is_null(), "the sim publishes /clock");
            for (exe, p) in params.as_object().unwrap() {
                if exe != "unitac_sim" {
                    assert_eq!(p["use_sim_time"], true, "{file} {exe}");
                }
            }
            assert!(
                params["unitac_policy"]["scene"]
                    .as_str()
                    .unwrap()
                    .ends_with(&format!("scenes/{file}.yaml"))
            );
            // With a real sensor instead, the same scene plans the sensor node, and no gripper
            // node unless one is named (the arm stack owns it).
            let v4l = &f["plans"][r#"{"source": "v4l"}"#]["nodes"];
            assert_eq!(v4l[0], "unitac_sensor", "{file}");
            assert!(!v4l.to_string().contains("unitac_gripper"), "{file}");
            // gripper:=robotiq_2f85 adds the serial gripper node with its model and port.
            let g = &f["plans"][r#"{"source": "v4l", "gripper": "robotiq_2f85", "gripper_port": "/dev/ttyGRIP"}"#];
            assert!(g["nodes"].to_string().contains("unitac_gripper"), "{file}");
            let gp = &g["parameters"]["unitac_gripper"];
            assert_eq!(gp["model"], "robotiq_2f85");
            assert_eq!(gp["port"], "/dev/ttyGRIP");
            // and holds the policy's safety bounds inside that model's profile.
            assert_eq!(
                g["parameters"]["unitac_policy"]["policy.gripper"], "robotiq_2f85",
                "{file}"
            );
        }
    }
}

/// The parameters the launch plan gives each node are ones the node accepts (names and types:
/// r2r refuses a float where an integer is declared): every planned node starts with them and
/// shuts down cleanly on SIGINT. The sim node takes its task, control rate and trial length from
/// the scene's policy stage and `unitac-lab trials`' trial length.
#[test]
fn planned_parameters_are_accepted_by_the_nodes() {
    let (j, bin_dir) = check_launch();
    let mut started = 0;
    for file in [
        "fabric_selection",
        "cup_deformation",
        "cup_deformation_vtla_real",
    ] {
        let params = j["files"][file]["plans"]["{}"]["parameters"]
            .as_object()
            .unwrap();
        let exes = &j["files"][file]["plans"]["{}"]["executables"];
        for (name, p) in params {
            let exe = exes[name].as_str().unwrap();
            let (path, yaml) = params_file(file, name, p);
            let ns = format!("__ns:=/plan{}_{file}", std::process::id());
            let node_name = format!("__node:={name}");
            let mut c = Command::new(bin_dir.join(exe))
                .args(["--ros-args", "-r", &ns, "-r", &node_name, "--params-file"])
                .arg(&path)
                .stdout(std::process::Stdio::null())
                .stderr(std::process::Stdio::piped())
                .spawn()
                .unwrap();
            std::thread::sleep(std::time::Duration::from_millis(1500));
            let early = c.try_wait().unwrap();
            Command::new("kill")
                .args(["-INT", &c.id().to_string()])
                .status()
                .unwrap();
            let out = c.wait_with_output().unwrap();
            let stderr = String::from_utf8_lossy(&out.stderr);
            assert!(
                early.is_none() && out.status.success(),
                "{file}: {name} ({exe}) with\n{yaml}exited {:?}: {stderr}",
                out.status,
            );
            if name == "unitac_sim" {
                let cup = unitac_trials::TrialOptions::for_task(unitac_sim::task::TaskKind::CUP);
                let want = format!(
                    "the cup_deformation task at {} Hz for {} s of sim time",
                    unitac_policy::PolicyParams::default().control_rate_hz,
                    cup.max_s
                );
                assert!(stderr.contains(&want), "{file}: {want} not in {stderr}");
            }
            started += 1;
        }
    }
    assert_eq!(started, 9);
}

/// Static transforms (static_transform_publisher's arguments, read back) against the joints of
/// the sensor's xacro macro (parent, child, xyz, rpy), in order.
fn assert_transforms_are_the_urdfs(transforms: &serde_json::Value, urdf: &serde_json::Value) {
    let (ts, us) = (transforms.as_array().unwrap(), urdf.as_array().unwrap());
    assert_eq!(ts.len(), 2, "{transforms}");
    assert_eq!(ts.len(), us.len(), "{transforms} vs {urdf}");
    for (t, u) in ts.iter().zip(us) {
        assert_eq!(t["frame_id"], u["parent"], "{t} vs {u}");
        assert_eq!(t["child_frame_id"], u["child"], "{t} vs {u}");
        for (i, (k, r)) in [("x", "roll"), ("y", "pitch"), ("z", "yaw")]
            .into_iter()
            .enumerate()
        {
            let dx = t[k].as_f64().unwrap() - u["xyz"][i].as_f64().unwrap();
            let dr = t[r].as_f64().unwrap() - u["rpy"][i].as_f64().unwrap();
            assert!(dx.abs() < 1e-12 && dr.abs() < 1e-12, "{t} vs {u}");
        }
    }
}

/// robot.launch.py, a real arm that runs ros2_control: our nodes only (the V4L2 sensor by its
/// serial, contact, inference, the policy on the robot's GripperCommand action and joint_states),
/// no sim node and no gripper node; with tf:=true the sensor's frames as static transforms that
/// equal the URDF's.
#[test]
fn robot_file_starts_our_nodes_on_the_robots_controllers() {
    let (j, _) = check_launch();
    assert_eq!(j["problems"], serde_json::json!([]), "{j}");
    let f = &j["files"]["robot"];
    assert_eq!(f["scene"], "cup_deformation_vtla_real", "{f}");
    let args = arguments(f);
    for a in [
        "scene",
        "sensor_serial",
        "sensor_id",
        "gripper_action",
        "gripper_joint",
        "joint_states",
        "arm_frame",
        "tf",
        "sensor_parent",
        "sensor_mount_xyz",
        "sensor_mount_rpy",
    ] {
        assert!(args.contains(&a), "robot: {a} not declared");
    }
    // One name per setting: here the sensor's serial is sensor_serial, and serial is unknown.
    assert!(!args.contains(&"serial"), "{args:?}");
    let e = f["renamed_argument"].as_str().unwrap();
    assert!(e.contains("unknown launch argument(s) serial"), "{e}");

    let ours = serde_json::json!([
        "unitac_sensor",
        "unitac_contact",
        "unitac_inference",
        "unitac_policy"
    ]);
    let plan = &f["plans"][r#"{"sensor_serial": "GS0001"}"#];
    assert_eq!(plan["nodes"], ours, "{plan}");
    let params = &plan["parameters"];
    let sensor = &params["unitac_sensor"];
    assert_eq!(sensor["source"], "v4l", "{sensor}");
    assert_eq!(sensor["serial"], "GS0001", "{sensor}");
    let policy = &params["unitac_policy"];
    assert_eq!(policy["gripper_input"], "joint_states", "{policy}");
    assert_eq!(policy["gripper_output"], "action", "{policy}");
    assert_eq!(
        policy["gripper_action"], "/gripper_controller/gripper_cmd",
        "{policy}"
    );
    assert_eq!(policy["joint_name"], "gripper_finger_opening", "{policy}");
    assert_eq!(policy["arm_frame"], "base_link", "{policy}");
    assert_eq!(
        plan["remappings"]["unitac_policy"],
        serde_json::json!([["joint_states", "/joint_states"]])
    );
    // Real time: nothing here publishes /clock.
    for (exe, p) in params.as_object().unwrap() {
        assert!(p["use_sim_time"].is_null(), "{exe}: {p}");
    }
    // No serial given: the only sensor of its kind connected. tf:=false (the default): the
    // robot's URDF holds the sensor, so no transforms.
    assert_eq!(f["plans"]["{}"]["nodes"], ours);
    assert!(f["plans"]["{}"]["parameters"]["unitac_sensor"]["serial"].is_null());
    assert_eq!(plan["transforms"], serde_json::json!([]));

    // tf:=true: sensor_parent -> <sensor_id>_link at the mount, then the GelSight Mini macro's
    // <sensor_id>_link -> <sensor_id>_optical_frame, the frame_id the nodes publish.
    let tf = &f["plans"][r#"{"tf": "true", "sensor_parent": "right_fingertip", "sensor_mount_xyz": "0.01 -0.005 0.02", "sensor_mount_rpy": "0 0.1 -1.5707963267948966"}"#];
    assert_eq!(
        tf["nodes"],
        serde_json::json!([
            "unitac_sensor",
            "unitac_contact",
            "unitac_inference",
            "unitac_policy",
            "static_transform_publisher",
            "static_transform_publisher"
        ]),
        "{tf}"
    );
    let sensor_id = tf["parameters"]["unitac_sensor"]["sensor_id"]
        .as_str()
        .unwrap();
    assert_eq!(tf["parameters"]["unitac_contact"]["sensor_id"], sensor_id);
    let t = &tf["transforms"];
    assert_eq!(t[0]["frame_id"], "right_fingertip", "{t}");
    assert_eq!(t[0]["child_frame_id"], format!("{sensor_id}_link"), "{t}");
    // The mount is the arguments' (x, y, z, roll, pitch, yaw).
    for (k, v) in [
        ("x", 0.01),
        ("y", -0.005),
        ("z", 0.02),
        ("roll", 0.0),
        ("pitch", 0.1),
        ("yaw", -std::f64::consts::FRAC_PI_2),
    ] {
        assert!((t[0][k].as_f64().unwrap() - v).abs() < 1e-12, "{k}: {t}");
    }
    assert_eq!(t[1]["frame_id"], format!("{sensor_id}_link"), "{t}");
    assert_eq!(
        t[1]["child_frame_id"],
        format!("{sensor_id}_optical_frame"),
        "{t}"
    );
    assert_transforms_are_the_urdfs(t, &tf["urdf"]);
    // A DIGIT's frames come from its own macro.
    let d = &j["tf_digit"];
    assert_eq!(d["transforms"][1]["child_frame_id"], "digit1_optical_frame");
    assert_transforms_are_the_urdfs(&d["transforms"], &d["urdf"]);
    // Frames that cannot be: each a one-line error naming what is missing or wrong.
    let bad = &j["bad_tf"];
    for (case, says) in [
        ("no_parent", "needs sensor_parent"),
        ("bad_xyz", "is not three numbers"),
        ("generic", "needs a sensor with a URDF macro"),
        ("not_bool", "tf:=yes is not true or false"),
    ] {
        assert!(bad[case].as_str().unwrap().contains(says), "{case}: {bad}");
    }
}

/// A scene is a file: copies of shipped scenes under new names in a further scene directory
/// (`UNITAC_SCENES`, so the tree is not touched) are accepted by the launch planner and
/// scene.launch.py with no other edit: a touch scene with a slip stage plans the contact node
/// once (it runs the slip stage; nothing is reported not started), a closed-loop scene plans the
/// sim node on that scene's file. The serial gripper models are the gripper crate's.
#[test]
fn a_scene_file_added_is_launched_by_name_with_no_other_edit() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..");
    let dir = std::env::temp_dir().join(format!("unitac-launch-scenes-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let copy = |from: &str, to: &str, edit: &dyn Fn(String) -> String| {
        let text =
            std::fs::read_to_string(root.join(format!("launch/scenes/{from}.yaml"))).unwrap();
        let renamed = text.replace(&format!("scene: {from}\n"), &format!("scene: {to}\n"));
        assert_ne!(renamed, text, "{from}");
        std::fs::write(dir.join(format!("{to}.yaml")), edit(renamed)).unwrap();
    };
    copy("fabric_selection", "fabric_slip_copy", &|t| {
        let with_slip = t.replace("  - kind: encoder", "  - kind: slip\n  - kind: encoder");
        assert_ne!(with_slip, t);
        with_slip
    });
    copy("cup_deformation_vtla_real", "cup_copy_vtla_real", &|t| t);
    let (j, _) = check_launch_with(Some(&dir));
    std::fs::remove_dir_all(&dir).ok();
    assert_eq!(j["problems"], serde_json::json!([]), "{j}");
    let scenes = &j["scenes"];
    for s in unitac_pipeline::scene_names(None) {
        assert!(scenes.get(&s).is_some(), "{s} not offered: {scenes}");
    }

    let slip = &scenes["fabric_slip_copy"]["{}"];
    assert_eq!(
        slip["nodes"],
        serde_json::json!(["unitac_sensor", "unitac_contact", "unitac_inference"]),
        "{slip}"
    );
    assert_eq!(slip["skipped"], serde_json::json!([]), "{slip}");
    assert!(
        slip["parameters"]["unitac_contact"]["scene"]
            .as_str()
            .unwrap()
            .ends_with("fabric_slip_copy.yaml")
    );

    let sim = &scenes["cup_copy_vtla_real"][r#"{"source": "sim"}"#];
    assert_eq!(
        sim["nodes"],
        serde_json::json!([
            "unitac_sim",
            "unitac_contact",
            "unitac_inference",
            "unitac_policy"
        ]),
        "{sim}"
    );
    for exe in ["unitac_sim", "unitac_policy"] {
        assert!(
            sim["parameters"][exe]["scene"]
                .as_str()
                .unwrap()
                .ends_with("cup_copy_vtla_real.yaml"),
            "{sim}"
        );
    }
    // Only a scene with a policy stage has a task for the sim.
    assert!(
        scenes["fabric_slip_copy"]
            .get(r#"{"source": "sim"}"#)
            .is_none()
    );

    let models: Vec<&str> = unitac_gripper::Model::all()
        .iter()
        .map(|m| m.name())
        .collect();
    assert_eq!(j["serial_grippers"], serde_json::json!(models));
}

/// The launch plan is computed from the scene and the stage graph: for every shipped scene, the
/// stage nodes it plans run exactly the scene's stages that the generic node runs, each in the
/// node of its graph group (`unitac_<group>`), in the scene's order; the policy stage runs in
/// its own node. Each planned stage node starts with its planned parameters, builds exactly
/// those stages (its effective-params lines) and stops cleanly on SIGINT.
#[test]
fn every_scene_plans_its_stages_by_the_graphs_groups() {
    let (j, bin_dir) = check_launch();
    let mut started = 0;
    let graph = unitac_pipeline::registry::graph();
    let scenes = j["scenes"].as_object().unwrap();
    assert!(scenes.len() >= 14, "{}", scenes.len());
    for (name, plans) in scenes {
        let scene = unitac_pipeline::load_scene(name, None).unwrap();
        let plan = &plans["{}"];
        let mut want = std::collections::BTreeMap::<String, Vec<&str>>::new();
        for st in &scene.stages {
            let group = &graph.stage(&st.kind).unwrap().group;
            if graph.groups[group].executable.is_none() {
                want.entry(format!("unitac_{group}"))
                    .or_default()
                    .push(st.kind.as_str());
            }
        }
        let mut got = std::collections::BTreeMap::<String, Vec<&str>>::new();
        for (node, p) in plan["parameters"].as_object().unwrap() {
            if let Some(s) = p["stages"].as_str() {
                got.insert(node.clone(), s.split(',').collect());
            }
        }
        assert_eq!(got, want, "{name}: {plan}");
        for (node, stages) in &got {
            let exe = plan["executables"][node].as_str().unwrap();
            let kinds = start_planned(&bin_dir.join(exe), name, node, &plan["parameters"][node]);
            assert_eq!(&kinds, stages, "{name}: {node}");
            started += 1;
        }
        let has_policy = scene.stages.iter().any(|s| s.kind == "policy");
        assert_eq!(
            plan["nodes"]
                .as_array()
                .unwrap()
                .contains(&serde_json::json!("unitac_policy")),
            has_policy,
            "{name}"
        );
    }
    assert!(started >= 19, "{started}");
}

/// Start `exe` as node `node` with `params` (a plan's, as a params file), wait for its
/// effective-params lines, stop it with SIGINT: the stage kinds it built, in order.
fn start_planned(
    exe: &std::path::Path,
    scene: &str,
    node: &str,
    params: &serde_json::Value,
) -> Vec<String> {
    let (path, yaml) = params_file(&format!("graph-{scene}"), node, params);
    let mut c = Command::new(exe)
        .args(["--ros-args", "-r"])
        .arg(format!("__ns:=/graph{}_{scene}", std::process::id()))
        .args(["-r", &format!("__node:={node}"), "--params-file"])
        .arg(&path)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let want = params["stages"].as_str().unwrap().split(',').count();
    let rx = common::stderr_lines(&mut c);
    let (mut kinds, mut log) = (Vec::new(), String::new());
    while kinds.len() < want {
        let Ok(l) = rx.recv_timeout(std::time::Duration::from_secs(30)) else {
            break;
        };
        log.push_str(&l);
        log.push('\n');
        if let Some((_, rest)) = l.split_once(": effective params: ") {
            kinds.push(rest.split(':').next().unwrap().to_string());
        }
    }
    // Subscribed and spinning, then asked to stop.
    std::thread::sleep(std::time::Duration::from_millis(300));
    let early = c.try_wait().unwrap();
    Command::new("kill")
        .args(["-INT", &c.id().to_string()])
        .status()
        .unwrap();
    let status = c.wait().unwrap();
    assert!(
        early.is_none() && status.success(),
        "{scene}: {node} with\n{yaml}exited {status:?}: {log}"
    );
    kinds
}
