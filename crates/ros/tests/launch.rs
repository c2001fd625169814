//! Launch files: they import, declare every argument with a description, and the nodes they start
//! exist (built here) for every scene they offer; arguments leave nodes out.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::PathBuf;
use std::process::Command;

fn check_launch() -> (serde_json::Value, PathBuf) {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..");
    let py = std::env::var_os("UNITAC_VENV")
        .map(PathBuf::from)
        .unwrap_or_else(|| root.join(".venv"))
        .join("bin/python");
    let bin_dir = PathBuf::from(env!("CARGO_BIN_EXE_unitac_contact_node"))
        .parent()
        .unwrap()
        .to_path_buf();
    let o = Command::new(py)
        .arg(root.join("tests/ros/check_launch.py"))
        .arg(root.join("launch"))
        .arg(&bin_dir)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    (serde_json::from_slice(&o.stdout).unwrap(), bin_dir)
}

#[test]
fn launch_files_are_consistent_with_scenes_and_executables() {
    let (j, _) = check_launch();
    assert_eq!(j["problems"], serde_json::json!([]), "{j}");
    for file in ["fabric_selection", "cup_deformation", "replay"] {
        let f = &j["files"][file];
        let args: Vec<&str> = f["arguments"]
            .as_array()
            .unwrap()
            .iter()
            .map(|a| a.as_str().unwrap())
            .collect();
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
        let all = serde_json::json!([
            "unitac_sensor_node",
            "unitac_contact_node",
            "unitac_inference_node"
        ]);
        let bag = r#"{"source": "bag", "bag": "recorded.mcap"}"#;
        assert_eq!(nodes(bag), all, "{file}: {f}");
        assert_eq!(params(bag, "unitac_sensor_node")["source"], "bag");
        assert_eq!(params(bag, "unitac_sensor_node")["bag"], "recorded.mcap");
        // Under a bag, every node but the one publishing /clock runs on bag time.
        assert!(params(bag, "unitac_sensor_node")["use_sim_time"].is_null());
        for exe in ["unitac_contact_node", "unitac_inference_node"] {
            assert_eq!(params(bag, exe)["use_sim_time"], true, "{file} {exe}");
        }
        // The inference node reads the scene file the plan came from.
        let scene = params(bag, "unitac_inference_node")["scene"].clone();
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
        assert!(params("{}", "unitac_contact_node")["use_sim_time"].is_null());
        assert_eq!(
            nodes(r#"{"inference": "false"}"#),
            serde_json::json!(["unitac_sensor_node", "unitac_contact_node"])
        );
        assert_eq!(
            nodes(r#"{"sensor": "false"}"#),
            serde_json::json!(["unitac_contact_node", "unitac_inference_node"])
        );
        let v4l = r#"{"source": "v4l"}"#;
        assert_eq!(nodes(v4l), all);
        assert_eq!(params(v4l, "unitac_sensor_node")["source"], "v4l");
    }
    // Stage parameters are not copied (and so cannot be dropped): the contact node gets the
    // scene file and reads its stage from there, as `unitac run` does.
    let c = &j["files"]["fabric_selection"]["plans"]["{}"]["parameters"]["unitac_contact_node"];
    let keys: Vec<&str> = c.as_object().unwrap().keys().map(String::as_str).collect();
    assert_eq!(keys, ["image_transport", "scene", "sensor_id"], "{c}");
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
        "unitac_sim_node",
        "unitac_contact_node",
        "unitac_policy_node",
        "unitac_inference_node"
    ]);
    for (task, sim_task, duration) in [
        ("cup_deformation", "cup", 12.0),
        ("fabric_selection", "fabric", 25.0),
    ] {
        for mode in ["vla", "vtla_real", "vtla_pred"] {
            let file = format!("{task}_{mode}");
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
                    serde_json::json!(["unitac_sim_node", "unitac_policy_node"]),
                    "{file}"
                );
            } else {
                assert_eq!(plan["nodes"], touch, "{file}");
            }
            let params = &plan["parameters"];
            let sim = &params["unitac_sim_node"];
            assert_eq!(sim["task"], sim_task, "{file}");
            assert_eq!(sim["duration_s"], duration, "{file}");
            assert_eq!(sim["wait_subscribers"], 1);
            assert_eq!(sim["wait_image_subscribers"], i32::from(mode != "vla"));
            assert!(sim["use_sim_time"].is_null(), "the sim publishes /clock");
            for (exe, p) in params.as_object().unwrap() {
                if exe != "unitac_sim_node" {
                    assert_eq!(p["use_sim_time"], true, "{file} {exe}");
                }
            }
            assert!(
                params["unitac_policy_node"]["scene"]
                    .as_str()
                    .unwrap()
                    .ends_with(&format!("scenes/{file}.yaml"))
            );
            // With a real sensor instead, the same scene plans the sensor node, and no gripper
            // node unless one is named (the arm stack owns it).
            let v4l = &f["plans"][r#"{"source": "v4l"}"#]["nodes"];
            assert_eq!(v4l[0], "unitac_sensor_node", "{file}");
            assert!(!v4l.to_string().contains("unitac_gripper_node"), "{file}");
            // gripper:=robotiq_2f85 adds the serial gripper node with its model and port.
            let g = &f["plans"][r#"{"source": "v4l", "gripper": "robotiq_2f85", "gripper_port": "/dev/ttyGRIP"}"#];
            assert!(
                g["nodes"].to_string().contains("unitac_gripper_node"),
                "{file}"
            );
            let gp = &g["parameters"]["unitac_gripper_node"];
            assert_eq!(gp["model"], "robotiq_2f85");
            assert_eq!(gp["port"], "/dev/ttyGRIP");
        }
    }
}

/// The parameters the launch plan gives each node are ones the node accepts (names and types:
/// r2r refuses a float where an integer is declared): every planned node starts with them and
/// shuts down cleanly on SIGINT.
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
        for (exe, p) in params {
            let mut yaml = String::from("/**:\n  ros__parameters:\n");
            for (k, v) in p.as_object().unwrap() {
                yaml.push_str(&format!("    {k}: {v}\n"));
            }
            let path = std::env::temp_dir()
                .join(format!("unitac-{}-{file}-{exe}.yaml", std::process::id()));
            std::fs::write(&path, &yaml).unwrap();
            let ns = format!("__ns:=/plan{}_{file}", std::process::id());
            let mut c = Command::new(bin_dir.join(exe))
                .args(["--ros-args", "-r", &ns, "--params-file"])
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
            assert!(
                early.is_none() && out.status.success(),
                "{file}: {exe} with\n{yaml}exited {:?}: {}",
                out.status,
                String::from_utf8_lossy(&out.stderr)
            );
            started += 1;
        }
    }
    assert_eq!(started, 10);
}
