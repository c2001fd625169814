"""Check the launch files without `ros2 launch` (not installable from PyPI): each *.launch.py
imports, builds its description (against recording stand-ins for launch/launch_ros, since only
their constructor arguments matter here), declares every argument with a description, and the
plan it runs names executables that exist and scenes that exist; the description starts the
plan's nodes as planned. Executables of other packages (EXTERNAL) are not built here: they must be
ones this check knows. With tf:=true, the sensor's static transforms are printed beside the
sensor's joints in its xacro macro, expanded here on its own. Every scene the planner finds
(`unitac_launch.scenes()`: $UNITAC_SCENES, then LAUNCH_DIR/scenes) is planned through
scene.launch.py, a closed-loop one (a policy stage) also with source:=sim. Prints a JSON summary.

usage: check_launch.py LAUNCH_DIR BIN_DIR
"""
import glob
import importlib.util
import json
import os
import sys
import types
import xml.etree.ElementTree as ET

import xacro

# Executables of other ROS packages a plan may start (installed with ROS, not built here).
EXTERNAL = {"tf2_ros": {"static_transform_publisher"}}
# Sensor kind -> the file and macro of its frames in urdf/.
MACROS = {"gelsight-mini": ("gelsight_mini.urdf.xacro", "gelsight_mini"), "digit": ("digit.urdf.xacro", "digit")}
# A sensor mounted by tf:=true in the plans below.
TF_ARGS = {"tf": "true", "sensor_parent": "right_fingertip", "sensor_mount_xyz": "0.01 -0.005 0.02",
           "sensor_mount_rpy": "0 0.1 -1.5707963267948966"}


class Recorder:
    def __init__(self, *args, **kwargs):
        self.args, self.kwargs = args, kwargs


def install_stand_ins():
    mods = {n: types.ModuleType(n) for n in
            ["launch", "launch.actions", "launch.substitutions", "launch_ros", "launch_ros.actions"]}
    mods["launch"].LaunchDescription = Recorder
    for name in ["DeclareLaunchArgument", "LogInfo", "OpaqueFunction"]:
        setattr(mods["launch.actions"], name, type(name, (Recorder,), {}))
    mods["launch.substitutions"].LaunchConfiguration = type(
        "LaunchConfiguration", (Recorder,), {"perform": lambda self, context: context.launch_configurations[self.args[0]]})
    mods["launch_ros.actions"].Node = type("Node", (Recorder,), {})
    sys.modules.update(mods)


def launched(description, configurations):
    """The nodes the description's OpaqueFunction starts with these launch configurations (what
    `ros2 launch` would hold: every declared argument's value), as plan-style dicts."""
    build = next(a for a in description.args[0] if type(a).__name__ == "OpaqueFunction").kwargs["function"]
    context = types.SimpleNamespace(launch_configurations=dict(configurations))
    return [{k: n.kwargs.get(k) for k in ["package", "executable", "name", "namespace", "parameters",
                                          "remappings", "arguments"]}
            for n in build(context) if type(n).__name__ == "Node"]


def urdf_frames(urdf_dir, kind, sensor_id, parent, xyz, rpy):
    """The sensor's fixed joints from its xacro macro on `parent` at the mount origin:
    [{"parent", "child", "xyz", "rpy"}]."""
    file, macro = MACROS[kind]
    doc = xacro.parse(f"""<robot name="check" xmlns:xacro="http://www.ros.org/wiki/xacro">
  <xacro:include filename="{os.path.join(urdf_dir, file)}"/>
  <link name="{parent}"/>
  <xacro:{macro} name="{sensor_id}" parent="{parent}"><origin xyz="{xyz}" rpy="{rpy}"/></xacro:{macro}>
</robot>""")
    xacro.process_doc(doc)
    return [{"parent": j.find("parent").get("link"), "child": j.find("child").get("link"),
             "xyz": [float(v) for v in j.find("origin").get("xyz").split()],
             "rpy": [float(v) for v in j.find("origin").get("rpy").split()]}
            for j in ET.fromstring(doc.toxml()).findall("joint")]


def node_id(n):
    """How a summary names a planned node: ours by node name (one executable, the generic stage
    node, runs under several), another package's by executable."""
    import unitac_launch

    return n["name"] if n["package"] == unitac_launch.PACKAGE else n["executable"]


def transforms(nodes):
    """The static_transform_publisher nodes' transforms, read back from their arguments."""
    out = []
    for n in nodes:
        if n["executable"] != "static_transform_publisher":
            continue
        a = dict(zip(n["arguments"][::2], n["arguments"][1::2]))
        t = {k[2:].replace("-", "_"): a[k] for k in ["--frame-id", "--child-frame-id"]}
        t.update({k[2:]: float(a[k]) for k in ["--x", "--y", "--z", "--roll", "--pitch", "--yaw"]})
        out.append(t)
    return out


def node_problems(f, p):
    """What is wrong with a plan's nodes: executables or files that do not exist."""
    import unitac_launch
    problems = []
    for n in p["nodes"]:
        if n["package"] != unitac_launch.PACKAGE:
            if n["executable"] not in EXTERNAL.get(n["package"], ()):
                problems.append(f"{f}: {n['package']} {n['executable']} is not a known external executable")
        elif not os.path.isfile(os.path.join(BIN_DIR, n["executable"])):
            problems.append(f"{f}: executable {n['executable']} does not exist")
        for extra in n["parameters"]:
            if isinstance(extra, str) and not os.path.isfile(extra):
                problems.append(f"{f}: params file {extra} does not exist")
        for params in n["parameters"]:
            if isinstance(params, dict) and "scene" in params and not os.path.isfile(params["scene"]):
                problems.append(f"{f}: scene file {params['scene']} does not exist")
    return problems


def parameters(p):
    """Our nodes' parameters in a plan, merged per node name."""
    import unitac_launch
    return {n["name"]: {k: v for d in n["parameters"] if isinstance(d, dict) for k, v in d.items()}
            for n in p["nodes"] if n["package"] == unitac_launch.PACKAGE}


def error_of(f):
    try:
        f()
        return "accepted"
    except ValueError as e:
        return str(e)


BIN_DIR = None


def main():
    global BIN_DIR
    launch_dir, bin_dir = sys.argv[1:3]
    BIN_DIR = bin_dir
    install_stand_ins()
    sys.path.insert(0, launch_dir)
    import unitac_launch
    out = {"files": {}, "problems": []}
    for f in sorted(glob.glob(os.path.join(launch_dir, "*.launch.py"))):
        name = os.path.basename(f)[: -len(".launch.py")]
        spec = importlib.util.spec_from_file_location(name, f)
        m = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(m)
        d = m.generate_launch_description()
        renamed = getattr(m, "RENAMED", {})
        decls = [a for a in d.args[0] if type(a).__name__ == "DeclareLaunchArgument"]
        for a in decls:
            if not a.kwargs.get("description"):
                out["problems"].append(f"{f}: argument {a.args[0]} has no description")
        declared = {a.args[0]: a.kwargs.get("default_value") for a in decls}
        scene = getattr(m, "SCENE", name)
        if scene is None:  # the scene is an argument
            if "scene" not in declared:
                out["problems"].append(f"{f}: no SCENE and no scene argument")
                continue
            scene = declared["scene"]
        if scene not in unitac_launch.scenes():
            out["problems"].append(f"{f}: scene {scene} does not exist")
        overrides = getattr(m, "OVERRIDES", {})
        for k, v in overrides.items():
            if declared.get(k) != v:
                out["problems"].append(f"{f}: override {k}={v} is not the declared default")
        plans = {}
        for args in [{}, {"inference": "false"}, {"sensor": "false"}, {"source": "v4l"},
                     {"source": "bag", "bag": "recorded.mcap"},
                     {"source": "v4l", "gripper": "robotiq_2f85", "gripper_port": "/dev/ttyGRIP"},
                     {"sensor_serial": "GS0001"}, TF_ARGS]:
            if set(args) - set(declared):
                continue  # an argument this file does not have
            p = unitac_launch.plan(scene, unitac_launch.rename({**overrides, **args}, renamed))
            out["problems"] += node_problems(f, p)
            # What `ros2 launch` starts: the description, given these arguments, starts the plan.
            started = launched(d, {**declared, **args})
            planned = [{k: n[k] for k in ["package", "executable", "name", "namespace", "parameters",
                                          "remappings", "arguments"]} for n in p["nodes"]]
            if started != planned:
                out["problems"].append(f"{f}: with {args} the description starts {started}, the plan is {planned}")
            ours = [n for n in p["nodes"] if n["package"] == unitac_launch.PACKAGE]
            plans[json.dumps(args)] = {
                "nodes": [node_id(n) for n in p["nodes"]], "skipped": p["skipped"],
                "parameters": parameters(p),
                "executables": {n["name"]: n["executable"] for n in ours},
                "remappings": {n["name"]: [list(r) for r in n["remappings"]] for n in ours},
                "transforms": transforms(p["nodes"])}
            if args == TF_ARGS:
                sensor_id = {**declared, **args}["sensor_id"]
                kind = {**declared, **args}["sensor_kind"] or unitac_launch.load_scene(scene)[0]["source"]["sensor"]
                plans[json.dumps(args)]["urdf"] = urdf_frames(
                    os.path.join(os.path.dirname(os.path.abspath(launch_dir)), "urdf"), kind, sensor_id,
                    args["sensor_parent"], args["sensor_mount_xyz"], args["sensor_mount_rpy"])
        out["files"][name] = {"scene": scene, "arguments": list(declared), "plans": plans}
        if renamed:
            # The planner's name for a renamed argument is not this file's: an unknown argument.
            old = next(iter(renamed.values()))
            out["files"][name]["renamed_argument"] = error_of(lambda: launched(d, {**declared, old: "x"}))
    # Every scene, by name through scene.launch.py: what it plans is what the description starts.
    generic = os.path.join(launch_dir, "scene.launch.py")
    spec = importlib.util.spec_from_file_location("scene", generic)
    m = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(m)
    d = m.generate_launch_description()
    declared = {a.args[0]: a.kwargs.get("default_value") for a in d.args[0]
                if type(a).__name__ == "DeclareLaunchArgument"}
    out["serial_grippers"] = list(unitac_launch.SERIAL_GRIPPERS)
    out["scenes"] = {}
    for scene in unitac_launch.scenes():
        kinds = [st["kind"] for st in unitac_launch.load_scene(scene)[0].get("stages", [])]
        plans = {}
        for args in [{}] + ([{"source": "sim"}] if "policy" in kinds else []):
            p = unitac_launch.plan(scene, args)
            out["problems"] += node_problems(f"{generic} scene:={scene}", p)
            started = launched(d, {**declared, "scene": scene, **args})
            planned = [{k: n[k] for k in ["package", "executable", "name", "namespace", "parameters",
                                          "remappings", "arguments"]} for n in p["nodes"]]
            if started != planned:
                out["problems"].append(f"{generic}: scene:={scene} with {args} starts {started}, the plan is {planned}")
            plans[json.dumps(args)] = {"nodes": [node_id(n) for n in p["nodes"]], "skipped": p["skipped"],
                                       "parameters": parameters(p),
                                       "executables": {n["name"]: n["executable"] for n in p["nodes"]
                                                       if n["package"] == unitac_launch.PACKAGE}}
        out["scenes"][scene] = plans
    try:
        unitac_launch.plan("fabric_selection", {"noise_k": "4"})
        out["unknown_argument"] = "accepted"
    except ValueError as e:
        out["unknown_argument"] = str(e)
    out["bad_gripper"] = {}
    for name, args in {"unknown": {"gripper": "robotiq_3f"},
                       "sim_without_sim": {"gripper": "sim"},
                       "serial_with_sim": {"source": "sim", "gripper": "dh_ag95"}}.items():
        try:
            unitac_launch.plan("cup_deformation_vtla_real", args)
            out["bad_gripper"][name] = "accepted"
        except ValueError as e:
            out["bad_gripper"][name] = str(e)
    out["bad_tf"] = {}
    for name, args in {"no_parent": {"tf": "true"},
                       "bad_xyz": {**TF_ARGS, "sensor_mount_xyz": "0 0"},
                       "generic": {**TF_ARGS, "sensor_kind": "generic"},
                       "not_bool": {"tf": "yes"}}.items():
        out["bad_tf"][name] = error_of(lambda: unitac_launch.plan("cup_deformation_vtla_real", args))
    # A DIGIT's frames come from its own macro.
    digit = unitac_launch.plan("fabric_selection", {**TF_ARGS, "sensor_kind": "digit", "sensor_id": "digit1"})
    out["tf_digit"] = {"transforms": transforms(digit["nodes"]),
                       "urdf": urdf_frames(os.path.join(os.path.dirname(os.path.abspath(launch_dir)), "urdf"),
                                           "digit", "digit1", TF_ARGS["sensor_parent"],
                                           TF_ARGS["sensor_mount_xyz"], TF_ARGS["sensor_mount_rpy"])}
    print(json.dumps(out))


if __name__ == "__main__":
    main()
