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
    "sensor_id": ("gsmini", "Sensor id; frame_ids are <sensor_id>_optical_frame (match the URDF)"),
    "serial": ("", "Serial of a live sensor (v4l)"),
    "bag": ("", "Bag path (bag source)"),
    "namespace": ("", "Namespace of every node"),
    "inference": ("true", "Run the inference stages of the scene (true | false)"),
    "sensor": ("true", "Run the sensor node (false when images come from elsewhere)"),
    "params_file": ("", "Extra --params-file YAML applied to every node"),
}

# Stage kind -> node executable, and the stage parameters that node takes.
STAGE_NODES = {
    "contact": ("unitac_contact_node", ["learn_frames", "noise_k", "min_threshold", "enter_area_px",
                                        "exit_area_px", "debounce_frames"]),
}
INFERENCE_STAGES = {"encoder", "compare", "sampler"}


def load_scene(name):
    path = name if name.endswith(".yaml") else os.path.join(HERE, "scenes", name + ".yaml")
    with open(path) as f:
        return yaml.safe_load(f), path


def plan(scene_name, args=None):
    """Node specs for a scene: [{"executable", "name", "namespace", "parameters", "remappings"}],
    plus "skipped": [(stage kind, why)]."""
    a = {k: v[0] for k, v in ARGUMENTS.items()}
    a.update(args or {})
    scene, _ = load_scene(scene_name)
    src = scene["source"]
    source = a["source"] or src["kind"]
    kind = a["sensor_kind"] or src.get("sensor", "gelsight-mini")
    extra = [a["params_file"]] if a["params_file"] else []
    nodes, skipped = [], []
    if a["sensor"] == "true":
        if source != "mock":
            skipped.append(("source", f"the sensor node supports the mock source only in this build, not '{source}'"))
        else:
            p = {"source": source, "sensor_kind": kind, "sensor_id": a["sensor_id"],
                 "scenario": src.get("scenario", scene["scene"]), "seed": int(src.get("seed", 0))}
            if "fps" in src:
                p["fps"] = float(src["fps"])
            nodes.append({"executable": "unitac_sensor_node", "name": "unitac_sensor", "namespace": a["namespace"],
                          "parameters": [p] + extra, "remappings": []})
    for st in scene.get("stages", []):
        k = st["kind"]
        if k in INFERENCE_STAGES:
            if a["inference"] == "true":
                skipped.append((k, "no ROS node for this stage yet: run it with `unitac run` meanwhile"))
            continue
        if k not in STAGE_NODES:
            skipped.append((k, "unknown stage kind"))
            continue
        exe, keys = STAGE_NODES[k]
        params = {"sensor_kind": kind, "sensor_id": a["sensor_id"]}
        for key, v in (st.get("params") or {}).items():
            if key in keys:
                params[key] = float(v) if isinstance(v, float) or key.endswith("_px") or key in ("noise_k", "min_threshold") else v
        nodes.append({"executable": exe, "name": "unitac_" + k, "namespace": a["namespace"],
                      "parameters": [params] + extra, "remappings": [("image", "image_raw")]})
    return {"scene": scene["scene"], "nodes": nodes, "skipped": skipped}


def description(scene_name):
    """A LaunchDescription for `ros2 launch` (imports launch/launch_ros only here)."""
    from launch import LaunchDescription
    from launch.actions import DeclareLaunchArgument, LogInfo, OpaqueFunction
    from launch.substitutions import LaunchConfiguration
    from launch_ros.actions import Node

    def build(context):
        args = {k: LaunchConfiguration(k).perform(context) for k in ARGUMENTS}
        p = plan(scene_name, args)
        actions = [LogInfo(msg=f"unitac {p['scene']}: {k} not started: {why}") for k, why in p["skipped"]]
        for n in p["nodes"]:
            actions.append(Node(package=PACKAGE, executable=n["executable"], name=n["name"],
                                namespace=n["namespace"], parameters=n["parameters"],
                                remappings=n["remappings"], output="screen"))
        return actions

    decls = [DeclareLaunchArgument(k, default_value=d, description=desc) for k, (d, desc) in ARGUMENTS.items()]
    return LaunchDescription(decls + [OpaqueFunction(function=build)])
