"""Check the launch files without `ros2 launch` (not installable from PyPI): each *.launch.py
imports, builds its description (against recording stand-ins for launch/launch_ros, since only
their constructor arguments matter here), declares every argument with a description, and the
plan it runs names executables that exist and scenes that exist. Prints a JSON summary.

usage: check_launch.py LAUNCH_DIR BIN_DIR
"""
import glob
import importlib.util
import json
import os
import sys
import types


class Recorder:
    def __init__(self, *args, **kwargs):
        self.args, self.kwargs = args, kwargs


def install_stand_ins():
    mods = {n: types.ModuleType(n) for n in
            ["launch", "launch.actions", "launch.substitutions", "launch_ros", "launch_ros.actions"]}
    mods["launch"].LaunchDescription = Recorder
    for name in ["DeclareLaunchArgument", "LogInfo", "OpaqueFunction"]:
        setattr(mods["launch.actions"], name, type(name, (Recorder,), {}))
    mods["launch.substitutions"].LaunchConfiguration = type("LaunchConfiguration", (Recorder,), {})
    mods["launch_ros.actions"].Node = type("Node", (Recorder,), {})
    sys.modules.update(mods)


def main():
    launch_dir, bin_dir = sys.argv[1:3]
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
        if not os.path.isfile(os.path.join(launch_dir, "scenes", scene + ".yaml")):
            out["problems"].append(f"{f}: scene {scene} does not exist")
        overrides = getattr(m, "OVERRIDES", {})
        for k, v in overrides.items():
            if declared.get(k) != v:
                out["problems"].append(f"{f}: override {k}={v} is not the declared default")
        plans = {}
        for args in [{}, {"inference": "false"}, {"sensor": "false"}, {"source": "v4l"},
                     {"source": "bag", "bag": "recorded.mcap"},
                     {"source": "v4l", "gripper": "robotiq_2f85", "gripper_port": "/dev/ttyGRIP"}]:
            p = unitac_launch.plan(scene, {**overrides, **args})
            for n in p["nodes"]:
                if not os.path.isfile(os.path.join(bin_dir, n["executable"])):
                    out["problems"].append(f"{f}: executable {n['executable']} does not exist")
                for extra in n["parameters"]:
                    if isinstance(extra, str) and not os.path.isfile(extra):
                        out["problems"].append(f"{f}: params file {extra} does not exist")
                for params in n["parameters"]:
                    if isinstance(params, dict) and "scene" in params and not os.path.isfile(params["scene"]):
                        out["problems"].append(f"{f}: scene file {params['scene']} does not exist")
            plans[json.dumps(args)] = {
                "nodes": [n["executable"] for n in p["nodes"]], "skipped": p["skipped"],
                "parameters": {n["executable"]: {k: v for d in n["parameters"] if isinstance(d, dict)
                                                 for k, v in d.items()} for n in p["nodes"]}}
        out["files"][name] = {"scene": scene, "arguments": list(declared), "plans": plans}
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
    print(json.dumps(out))


if __name__ == "__main__":
    main()
