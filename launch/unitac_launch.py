"""Data-driven ROS 2 launch for the UniTac scenes.

`plan()` turns a scene file (launch/scenes/<scene>.yaml, the same file `unitac run` reads) and the
launch arguments into a list of node specs; it imports nothing from ROS, so it is tested without
`ros2 launch`. `description()` wraps the plan in launch/launch_ros actions for the per-scene
`*.launch.py` files. Stages that have no ROS node yet are reported, not silently dropped.
With tf:=true the sensor's frames come from its xacro macro in urdf/, expanded with `xacro`.

The scenes are the files in the scene directories (`scenes()`: $UNITAC_SCENES first, then
scenes/ beside this file), as `unitac scenes` lists them: a YAML file added there is launched by
scene.launch.py scene:=<name> with no other edit. What a scene runs at (the sim task, its control
rate and trial length) is read by the nodes from the scene file, not copied here.
"""
import glob
import os
import re
from xml.sax.saxutils import quoteattr

import yaml

HERE = os.path.dirname(os.path.abspath(__file__))
# urdf/ beside launch/, in the source tree and in share/unitac_ros of an install.
URDF_DIR = os.path.join(os.path.dirname(HERE), "urdf")
PACKAGE = "unitac_ros"

# grippers/ beside launch/ (the source tree; share/unitac_ros of an install): one profile file per
# gripper model, the files the nodes compile in; $UNITAC_GRIPPERS adds more, as the nodes read it.
GRIPPER_DIR = os.path.join(os.path.dirname(HERE), "grippers")


def profiles(directory, env):
    """Name -> profile of every *.yaml in `directory`, then in $`env` (a later one of a name
    replaces it), as the nodes read them."""
    found = {}
    extra = [os.environ[env]] if os.environ.get(env) else []
    for d in [directory] + extra:
        for path in sorted(glob.glob(os.path.join(d, "*.yaml"))):
            with open(path) as f:
                p = yaml.safe_load(f)
            if isinstance(p, dict) and isinstance(p.get("name"), str):
                found[p["name"]] = p
    return found


def serial_grippers():
    """The serial gripper models the gripper node drives, by name: every profile whose family is not
    sim (crates/gripper's Model::all(); crates/ros/tests/launch.rs checks that they are the same)."""
    return tuple(sorted(n for n, p in profiles(GRIPPER_DIR, "UNITAC_GRIPPERS").items() if p.get("family") != "sim"))


SERIAL_GRIPPERS = serial_grippers()

# sensors/ beside launch/: one profile file per sensor kind, the files the nodes compile in;
# $UNITAC_SENSORS adds more, as the nodes read it.
SENSOR_DIR = os.path.join(os.path.dirname(HERE), "sensors")
SENSOR_KINDS = profiles(SENSOR_DIR, "UNITAC_SENSORS")
# Sensor kind -> (file in urdf/, macro): the frames tf:=true publishes (each profile's `urdf`).
SENSOR_MACROS = {k: (f"{p['urdf']}.urdf.xacro", p["urdf"]) for k, p in SENSOR_KINDS.items() if p.get("urdf")}

# Launch arguments: name -> (default, description). Every setting is a declared argument.
ARGUMENTS = {
    "source": ("", "Frame source: mock | v4l | bag | sim (sim: the task world node, closed loop; empty: the scene's)"),
    "sensor_kind": ("", f"{' | '.join(sorted(SENSOR_KINDS))} (empty: the scene's)"),
    "sensor_id": ("gsmini", "Sensor id (mock, v4l); frame_ids are <sensor_id>_optical_frame (match the URDF)"),
    "serial": ("", "Serial of a live sensor (v4l; empty: the only one of sensor_kind connected)"),
    "bag": ("", "Bag path: rosbag2 directory, .mcap or .db3 (bag source; empty: the scene's)"),
    "rate": ("1.0", "Bag playback rate (bag source)"),
    "image_transport": ("raw", "Images the contact node reads: raw (image_raw) | compressed (image_raw/compressed; JPEG/PNG bags and cameras)"),
    "use_sim_time": ("auto", "Nodes take time from /clock: true | false | auto (true for the bag source)"),
    "namespace": ("", "Namespace of every node"),
    "inference": ("true", "Run the inference group's node (the scene's encoder/compare/sampler stages; "
                           "stage_graph.yaml) (true | false)"),
    "sensor": ("true", "Run the sensor node (false when images come from elsewhere)"),
    "params_file": ("", "Extra --params-file YAML applied to every node"),
    "split": ("train", "Sim source: train | unseen objects (objects/split.yaml: cups by diameter range, fabrics by type)"),
    "seed": ("1", "Sim source: the trial draw's seed"),
    "trial": ("0", "Sim source: the trial index"),
    "duration_s": ("", "Sim source: sim time of the trial [s] (empty: the task's trial length, as `unitac-lab trials` runs it)"),
    "max_rate": ("1.0", "Sim source: at most this many sim seconds per wall second (0: as fast as the loop runs)"),
    "gripper": ("", "Gripper: " + " | ".join(SERIAL_GRIPPERS) + " (the serial gripper node) | sim "
                    "(the sim node's gripper) | action (a ros2_control gripper controller through "
                    "control_msgs/action/GripperCommand; the policy reads the robot's joint_states) | none "
                    "(the arm stack owns it and publishes gripper_status); empty: sim with source:=sim, else none"),
    "gripper_port": ("/dev/ttyUSB0", "Serial port of the gripper, best its /dev/serial/by-id name"),
    "gripper_action": ("/gripper_controller/gripper_cmd",
                       "gripper:=action: the control_msgs/action/GripperCommand server the policy sends its "
                       "targets to (a GripperActionController's <controller>/gripper_cmd)"),
    "gripper_joint": ("gripper_finger_opening",
                      "gripper:=action: the robot's gripper joint in joint_states whose position is the finger "
                      "opening in metres; no name is universal, so set it to your robot's (the default is what "
                      "our gripper and sim nodes publish)"),
    "joint_states": ("/joint_states", "gripper:=action: the robot's sensor_msgs/JointState topic (joint_state_broadcaster's)"),
    "arm_frame": ("base_link", "TF frame of the policy's arm target (arm_pose, geometry_msgs/PoseStamped)"),
    "tf": ("false", "Publish the sensor's frames as static transforms (true | false): true only when the "
                    "robot's URDF lacks the sensor (robot_state_publisher publishes them otherwise)"),
    "sensor_parent": ("", "tf:=true: the robot link the sensor is mounted on, e.g. a fingertip link"),
    "sensor_mount_xyz": ("0 0 0", "tf:=true: the sensor body's position in sensor_parent, \"x y z\" [m]"),
    "sensor_mount_rpy": ("0 0 0", "tf:=true: the sensor body's orientation in sensor_parent, \"roll pitch yaw\" [rad] "
                                  "(URDF convention; the body's +x points out of the gel)"),
}

# Every value of the gripper argument.
GRIPPERS = SERIAL_GRIPPERS + ("sim", "action", "none")

# The stage graph (stage_graph.yaml beside this file, which the nodes and the scene check read
# too): each stage kind's group; the stages of a scene in one group run in one node, the generic
# `unitac_stage_node` unless the group names an executable of its own. Nodes read their stages'
# parameters from the scene file themselves, through the same registry and typed structs as
# `unitac run`; nothing is copied here, so nothing can be dropped. Override a stage parameter
# with `<stage>.<key>` in params_file.
with open(os.path.join(HERE, "stage_graph.yaml")) as _f:
    GRAPH = yaml.safe_load(_f)
STAGE_NODE = "unitac_stage_node"


def node_groups(kinds):
    """The scene's stage kinds (in scene order) by the group that runs them, groups in order of
    their first stage: [(group, [kinds])]; kinds the graph does not know go to group None."""
    groups = []
    for k in kinds:
        g = GRAPH["stages"].get(k, {}).get("group")
        for name, members in groups:
            if name == g:
                members.append(k)
                break
        else:
            groups.append((g, [k]))
    return groups


def scene_dirs():
    """Where scene names are looked up: $UNITAC_SCENES (when set), then scenes/ beside this file."""
    extra = [os.environ["UNITAC_SCENES"]] if os.environ.get("UNITAC_SCENES") else []
    return extra + [os.path.join(HERE, "scenes")]


def scenes():
    """Every scene name (the stem of a .yaml file in scene_dirs()), sorted, each once."""
    names = set()
    for d in scene_dirs():
        if os.path.isdir(d):
            names.update(f[: -len(".yaml")] for f in os.listdir(d) if f.endswith(".yaml"))
    return sorted(names)


def load_scene(name):
    """A scene by name (looked up in scene_dirs()) or by path: (its YAML, its absolute path)."""
    if name.endswith((".yaml", ".yml")) or "/" in name:
        path = name
    else:
        path = next((p for p in (os.path.join(d, name + ".yaml") for d in scene_dirs()) if os.path.isfile(p)), None)
        if path is None:
            raise ValueError(f"scene {name} not found in {', '.join(scene_dirs())} (scenes: {', '.join(scenes())})")
    with open(path) as f:
        return yaml.safe_load(f), os.path.abspath(path)


def triple(name, value):
    """Three numbers from a launch argument such as sensor_mount_xyz:="0 0.01 0.02"."""
    try:
        v = [float(x) for x in value.split()]
    except ValueError:
        v = []
    if len(v) != 3:
        raise ValueError(f"{name}:={value!r} is not three numbers")
    return v


def sensor_frames(kind, sensor_id, parent, xyz, rpy):
    """The sensor's fixed joints as the robot description has them: the sensor's xacro macro
    expanded (with `xacro`) on `parent` at the mount origin. [(parent, child, xyz, rpy)]:
    parent -> <sensor_id>_link, <sensor_id>_link -> <sensor_id>_optical_frame."""
    import xml.etree.ElementTree as ET

    import xacro

    if kind not in SENSOR_MACROS:
        raise ValueError(f"tf:=true needs a sensor with a URDF macro ({', '.join(SENSOR_MACROS)}), not {kind}")
    file, macro = SENSOR_MACROS[kind]
    num = " ".join(repr(float(v)) for v in xyz), " ".join(repr(float(v)) for v in rpy)
    doc = (f'<robot name="unitac_sensor_mount" xmlns:xacro="http://www.ros.org/wiki/xacro">'
           f'<xacro:include filename={quoteattr(os.path.join(URDF_DIR, file))}/>'
           f'<link name={quoteattr(parent)}/>'
           f'<xacro:{macro} name={quoteattr(sensor_id)} parent={quoteattr(parent)}>'
           f'<origin xyz="{num[0]}" rpy="{num[1]}"/></xacro:{macro}></robot>')
    d = xacro.parse(doc)
    xacro.process_doc(d)
    frames = []
    for j in ET.fromstring(d.toxml()).findall("joint"):
        o = j.find("origin")
        frames.append((j.find("parent").get("link"), j.find("child").get("link"),
                       [float(v) for v in o.get("xyz", "0 0 0").split()],
                       [float(v) for v in o.get("rpy", "0 0 0").split()]))
    if [f[1] for f in frames] != [f"{sensor_id}_link", f"{sensor_id}_optical_frame"]:
        raise ValueError(f"{file}: expected the frames {sensor_id}_link and {sensor_id}_optical_frame, got {frames}")
    return frames


def static_transform(name, namespace, parent, child, xyz, rpy):
    """A tf2_ros static_transform_publisher node spec (its named-argument form)."""
    args = []
    for flag, v in zip(["--x", "--y", "--z", "--roll", "--pitch", "--yaw"], list(xyz) + list(rpy)):
        args += [flag, repr(float(v))]
    return {"package": "tf2_ros", "executable": "static_transform_publisher", "name": name,
            "namespace": namespace, "parameters": [], "remappings": [],
            "arguments": args + ["--frame-id", parent, "--child-frame-id", child]}


def rename(args, renamed):
    """A launch file's own argument names (`renamed`: its name -> the planner's) as the planner's."""
    return {renamed.get(k, k): v for k, v in (args or {}).items()}


def plan(scene_name, args=None):
    """Node specs for a scene: [{"package", "executable", "name", "namespace", "parameters",
    "remappings", "arguments"}], plus "skipped": [(what, why)]. An argument that is not declared,
    or a value that cannot be, is an error (ValueError)."""
    unknown = sorted(set(args or {}) - set(ARGUMENTS) - {"scene"})
    if unknown:
        raise ValueError(f"unknown launch argument(s) {', '.join(unknown)} (known: {', '.join(ARGUMENTS)})")
    a = {k: v[0] for k, v in ARGUMENTS.items()}
    a.update(args or {})
    scene, scene_path = load_scene(scene_name)
    src = scene["source"]
    source = a["source"] or src["kind"]
    sim_time = a["use_sim_time"] == "true" or (a["use_sim_time"] == "auto" and source in ("bag", "sim"))
    extra = [a["params_file"]] if a["params_file"] else []
    timing = [{"use_sim_time": True}] if sim_time else []
    # Only what the arguments change; everything else comes from the scene file.
    sensor_kind = {"sensor_kind": a["sensor_kind"]} if a["sensor_kind"] else {}
    nodes, skipped = [], []
    kinds = [st["kind"] for st in scene.get("stages", [])]
    gripper = a["gripper"] or ("sim" if source == "sim" else "none")
    if gripper not in GRIPPERS:
        raise ValueError(f"gripper:={gripper} is not one of {', '.join(GRIPPERS)}")
    if a["tf"] not in ("true", "false"):
        raise ValueError(f"tf:={a['tf']} is not true or false")
    if gripper == "sim" and source != "sim":
        raise ValueError("gripper:=sim needs source:=sim (the sim node is that gripper)")
    if source == "sim" and gripper != "sim":
        raise ValueError(f"source:=sim drives its own gripper; gripper:={gripper} would be a second one")
    if gripper in SERIAL_GRIPPERS:
        nodes.append({"executable": "unitac_gripper_node", "name": "unitac_gripper", "namespace": a["namespace"],
                      "parameters": [{"model": gripper, "port": a["gripper_port"]}] + extra, "remappings": []})
    if a["sensor"] == "true" and source == "sim":
        if "policy" not in kinds or not scene.get("task"):
            skipped.append(("source", f"source:=sim needs a scene with a task and a policy stage; "
                                      f"{scene['scene']} has not both"))
        else:
            # The sim node reads its task from the scene, its control rate from the policy stage, and
            # runs the task's trial length unless duration_s is given.
            p = {"scene": scene_path, "split": a["split"], "seed": int(a["seed"]), "trial": int(a["trial"]),
                 **({"duration_s": float(a["duration_s"])} if a["duration_s"] else {}),
                 "max_rate": float(a["max_rate"]),
                 "sensor": a["sensor_kind"] or src.get("sensor", "gelsight-mini"), "sensor_id": a["sensor_id"],
                 # Start once the policy (and the contact node, when the scene has one) listen.
                 "wait_subscribers": int("policy" in kinds),
                 "wait_image_subscribers": int("contact" in kinds)}
            nodes.append({"executable": "unitac_sim_node", "name": "unitac_sim", "namespace": a["namespace"],
                          "parameters": [p] + extra, "remappings": []})
    elif a["sensor"] == "true":
        p = {"scene": scene_path, "source": source, **sensor_kind}
        if source in ("mock", "v4l"):
            p["sensor_id"] = a["sensor_id"]
        if source == "v4l" and a["serial"]:
            p["serial"] = a["serial"]
        if source == "bag":
            p.update({"bag": a["bag"] or (src.get("path") or ""), "rate": float(a["rate"])})
        if source not in ("mock", "v4l", "bag"):
            skipped.append(("source", f"unknown source '{source}' (mock, v4l, bag)"))
        elif source == "bag" and not p["bag"]:
            skipped.append(("source", "the bag source needs bag:=PATH"))
        else:
            nodes.append({"executable": "unitac_sensor_node", "name": "unitac_sensor", "namespace": a["namespace"],
                          "parameters": [p] + extra, "remappings": []})
    for group, members in node_groups(kinds):
        if group is None:
            skipped.extend((k, "no ROS node for this stage kind") for k in members)
            continue
        if group == "inference" and a["inference"] != "true":
            continue
        exe = GRAPH["groups"][group].get("executable") or STAGE_NODE
        if exe == "unitac_policy_node":
            p, remaps = {"scene": scene_path, "arm_frame": a["arm_frame"]}, []
            if gripper in SERIAL_GRIPPERS:
                # The safety layer's bounds inside the model's profile (stroke, grip, speed).
                p["policy.gripper"] = gripper
            if gripper == "action":
                # The robot's gripper controller: GripperCommand goals out, its joint_states in.
                p.update({"gripper_input": "joint_states", "gripper_output": "action",
                          "gripper_action": a["gripper_action"], "joint_name": a["gripper_joint"]})
                remaps = [("joint_states", a["joint_states"])]
            nodes.append({"executable": exe, "name": "unitac_policy", "namespace": a["namespace"],
                          "parameters": [p] + timing + extra, "remappings": remaps})
            continue
        params, remaps = {"scene": scene_path, "stages": ",".join(members)}, []
        if any("frame" in GRAPH["stages"][k].get("needs", []) for k in members):
            # The group reads the camera's images.
            params.update({"image_transport": a["image_transport"], **sensor_kind})
            if source != "bag":
                params["sensor_id"] = a["sensor_id"]  # bag: the frame_id the bag recorded
            remaps = [("image", "image_raw"), ("image/compressed", "image_raw/compressed")]
        nodes.append({"executable": exe, "name": "unitac_" + group, "namespace": a["namespace"],
                      "parameters": [params] + timing + extra, "remappings": remaps})
    if a["tf"] == "true":
        if not a["sensor_parent"]:
            raise ValueError("tf:=true needs sensor_parent:=<the robot link the sensor is mounted on>")
        kind = a["sensor_kind"] or src.get("sensor", "gelsight-mini")
        frames = sensor_frames(kind, a["sensor_id"], a["sensor_parent"],
                               triple("sensor_mount_xyz", a["sensor_mount_xyz"]),
                               triple("sensor_mount_rpy", a["sensor_mount_rpy"]))
        node_id = re.sub(r"[^A-Za-z0-9_]", "_", a["sensor_id"])  # a ROS node name's characters
        for (parent, child, xyz, rpy), what in zip(frames, ["link", "optical"]):
            nodes.append(static_transform(f"unitac_tf_{node_id}_{what}", a["namespace"],
                                          parent, child, xyz, rpy))
    for n in nodes:
        n.setdefault("package", PACKAGE)
        n.setdefault("arguments", [])
    return {"scene": scene["scene"], "nodes": nodes, "skipped": skipped}


def description(scene_name=None, overrides=None, renamed=None):
    """A LaunchDescription for `ros2 launch` (imports launch/launch_ros only here). Without a
    scene name the scene is a launch argument too (the replay and robot launch files).
    `overrides`: argument -> default; `renamed`: the file's name for an argument -> the planner's
    (declared under the file's name only)."""
    from launch import LaunchDescription
    from launch.actions import DeclareLaunchArgument, LogInfo, OpaqueFunction
    from launch.substitutions import LaunchConfiguration
    from launch_ros.actions import Node

    declared = dict(ARGUMENTS)
    if scene_name is None:
        declared["scene"] = ("fabric_selection", "Scene file name in launch/scenes, or a path to one")
    for k, v in (overrides or {}).items():
        declared[k] = (v, declared[k][1])
    for new, old in (renamed or {}).items():
        declared[new] = declared.pop(old)

    def build(context):
        unknown = sorted(set(getattr(context, "launch_configurations", {})) - set(declared))
        if unknown:
            raise ValueError(f"unknown launch argument(s) {', '.join(unknown)} (known: {', '.join(declared)})")
        args = {k: LaunchConfiguration(k).perform(context) for k in declared}
        args = rename(args, renamed or {})
        p = plan(args.pop("scene", None) or scene_name, args)
        actions = [LogInfo(msg=f"unitac {p['scene']}: {k} not started: {why}") for k, why in p["skipped"]]
        for n in p["nodes"]:
            actions.append(Node(package=n["package"], executable=n["executable"], name=n["name"],
                                namespace=n["namespace"], parameters=n["parameters"],
                                remappings=n["remappings"], arguments=n["arguments"], output="screen"))
        return actions

    decls = [DeclareLaunchArgument(k, default_value=d, description=desc) for k, (d, desc) in declared.items()]
    return LaunchDescription(decls + [OpaqueFunction(function=build)])
