"""Data-driven ROS 2 launch for the UniTac scenes.

`plan()` turns a scene file (launch/scenes/<scene>.yaml, the same file `unitac run` reads) and the
launch arguments into a list of node specs; it imports nothing from ROS, so it is tested without
`ros2 launch`. `description()` wraps the plan in launch/launch_ros actions for the per-scene
`*.launch.py` files. Stages that have no ROS node yet are reported, not silently dropped.
"""
import os

import yaml

HERE = os.path.dirname(os.path.abspath(__file__))
PACKAGE = "unitac_ros"

# Launch arguments: name -> (default, description). Every setting is a declared argument.
ARGUMENTS = {
    "source": ("", "Frame source: mock | v4l | bag (empty: the scene's)"),
    "sensor_kind": ("", "gelsight-mini | digit | generic (empty: the scene's)"),
    "sensor_id": ("gsmini", "Sensor id (mock, v4l); frame_ids are <sensor_id>_optical_frame (match the URDF)"),
    "serial": ("", "Serial of a live sensor (v4l; empty: the only one of sensor_kind connected)"),
    "bag": ("", "Bag path: rosbag2 directory, .mcap or .db3 (bag source; empty: the scene's)"),
    "rate": ("1.0", "Bag playback rate (bag source)"),
    "image_transport": ("raw", "Images the contact node reads: raw (image_raw) | compressed (image_raw/compressed; JPEG/PNG bags and cameras)"),
    "use_sim_time": ("auto", "Nodes take time from /clock: true | false | auto (true for the bag source)"),
    "namespace": ("", "Namespace of every node"),
    "inference": ("true", "Run the inference node for the scene's encoder/compare/sampler stages (true | false)"),
    "sensor": ("true", "Run the sensor node (false when images come from elsewhere)"),
    "params_file": ("", "Extra --params-file YAML applied to every node"),
}

# Stage kind -> node executable, and the stage parameters that node takes from the scene.
STAGE_NODES = {
    "contact": ("unitac_contact_node", ["learn_frames", "noise_k", "min_threshold", "enter_area_px",
                                        "exit_area_px", "debounce_frames", "clip_frames",
                                        "episode_labels", "background_dir"]),
}
# These run in one inference node, which reads them (models included) from the scene file itself.
INFERENCE_STAGES = {"encoder", "compare", "sampler"}
FLOAT_PARAMS = {"noise_k", "min_threshold", "enter_area_px", "exit_area_px"}


def load_scene(name):
    path = name if name.endswith(".yaml") else os.path.join(HERE, "scenes", name + ".yaml")
    with open(path) as f:
        return yaml.safe_load(f), os.path.abspath(path)


def ros_value(key, v):
    """A scene value as the node's parameter: lists (r2r has no array parameters) become
    comma-separated strings, the float parameters floats (YAML `100` would be an integer)."""
    if isinstance(v, list):
        return ",".join(str(x) for x in v)
    if key in FLOAT_PARAMS:
        return float(v)
    return v


def plan(scene_name, args=None):
    """Node specs for a scene: [{"executable", "name", "namespace", "parameters", "remappings"}],
    plus "skipped": [(what, why)]."""
    a = {k: v[0] for k, v in ARGUMENTS.items()}
    a.update(args or {})
    scene, scene_path = load_scene(scene_name)
    src = scene["source"]
    source = a["source"] or src["kind"]
    kind = a["sensor_kind"] or src.get("sensor", "gelsight-mini")
    sim_time = a["use_sim_time"] == "true" or (a["use_sim_time"] == "auto" and source == "bag")
    extra = [a["params_file"]] if a["params_file"] else []
    timing = [{"use_sim_time": True}] if sim_time else []
    nodes, skipped = [], []
    if a["sensor"] == "true":
        p = {"source": source, "sensor_kind": kind}
        if source == "mock":
            p.update({"sensor_id": a["sensor_id"], "scenario": src.get("scenario", scene["scene"]),
                      "seed": int(src.get("seed", 0))})
            if "fps" in src:
                p["fps"] = float(src["fps"])
        elif source == "v4l":
            p.update({"sensor_id": a["sensor_id"], "serial": a["serial"] or (src.get("serial") or "")})
        elif source == "bag":
            p.update({"bag": a["bag"] or (src.get("path") or ""), "rate": float(a["rate"])})
        if source not in ("mock", "v4l", "bag"):
            skipped.append(("source", f"unknown source '{source}' (mock, v4l, bag)"))
        elif source == "bag" and not p["bag"]:
            skipped.append(("source", "the bag source needs bag:=PATH"))
        else:
            nodes.append({"executable": "unitac_sensor_node", "name": "unitac_sensor", "namespace": a["namespace"],
                          "parameters": [p] + extra, "remappings": []})
    inference = False
    for st in scene.get("stages", []):
        k = st["kind"]
        if k in INFERENCE_STAGES:
            inference = inference or a["inference"] == "true"
            continue
        if k not in STAGE_NODES:
            skipped.append((k, "no ROS node for this stage kind"))
            continue
        exe, keys = STAGE_NODES[k]
        params = {"sensor_kind": kind, "image_transport": a["image_transport"]}
        if source != "bag":
            params["sensor_id"] = a["sensor_id"]  # bag: the frame_id the bag recorded
        for key, v in (st.get("params") or {}).items():
            if key in keys:
                params[key] = ros_value(key, v)
        nodes.append({"executable": exe, "name": "unitac_" + k, "namespace": a["namespace"],
                      "parameters": [params] + timing + extra,
                      "remappings": [("image", "image_raw"), ("image/compressed", "image_raw/compressed")]})
    if inference:
        nodes.append({"executable": "unitac_inference_node", "name": "unitac_inference",
                      "namespace": a["namespace"], "parameters": [{"scene": scene_path}] + timing + extra,
                      "remappings": []})
    return {"scene": scene["scene"], "nodes": nodes, "skipped": skipped}


def description(scene_name=None, overrides=None):
    """A LaunchDescription for `ros2 launch` (imports launch/launch_ros only here). Without a
    scene name the scene is a launch argument too (the replay launch file)."""
    from launch import LaunchDescription
    from launch.actions import DeclareLaunchArgument, LogInfo, OpaqueFunction
    from launch.substitutions import LaunchConfiguration
    from launch_ros.actions import Node

    declared = dict(ARGUMENTS)
    if scene_name is None:
        declared["scene"] = ("fabric_selection", "Scene file name in launch/scenes, or a path to one")
    for k, v in (overrides or {}).items():
        declared[k] = (v, declared[k][1])

    def build(context):
        args = {k: LaunchConfiguration(k).perform(context) for k in declared}
        p = plan(args.pop("scene", None) or scene_name, args)
        actions = [LogInfo(msg=f"unitac {p['scene']}: {k} not started: {why}") for k, why in p["skipped"]]
        for n in p["nodes"]:
            actions.append(Node(package=PACKAGE, executable=n["executable"], name=n["name"],
                                namespace=n["namespace"], parameters=n["parameters"],
                                remappings=n["remappings"], output="screen"))
        return actions

    decls = [DeclareLaunchArgument(k, default_value=d, description=desc) for k, (d, desc) in declared.items()]
    return LaunchDescription(decls + [OpaqueFunction(function=build)])
