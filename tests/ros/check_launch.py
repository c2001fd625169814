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
        spec = importlib.util.spec_from_file_location(os.path.basename(f)[:-3], f)
        m = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(m)
        d = m.generate_launch_description()
        decls = [a for a in d.args[0] if type(a).__name__ == "DeclareLaunchArgument"]
        for a in decls:
            if not a.kwargs.get("description"):
                out["problems"].append(f"{f}: argument {a.args[0]} has no description")
        scene = os.path.basename(f)[: -len(".launch.py")]
        if not os.path.isfile(os.path.join(launch_dir, "scenes", scene + ".yaml")):
            out["problems"].append(f"{f}: scene {scene} does not exist")
        plans = {}
        for args in [{}, {"inference": "false"}, {"sensor": "false"}, {"source": "v4l"}]:
            p = unitac_launch.plan(scene, args)
            for n in p["nodes"]:
                if not os.path.isfile(os.path.join(bin_dir, n["executable"])):
                    out["problems"].append(f"{f}: executable {n['executable']} does not exist")
                for extra in n["parameters"][1:]:
                    if not os.path.isfile(extra):
                        out["problems"].append(f"{f}: params file {extra} does not exist")
            plans[json.dumps(args)] = {"nodes": [n["executable"] for n in p["nodes"]], "skipped": p["skipped"]}
        out["files"][scene] = {"arguments": [a.args[0] for a in decls], "plans": plans}
    print(json.dumps(out))


if __name__ == "__main__":
    main()
