"""Stub ONNX policy bundles for the runtime's failure tests: the learned cup VLA policy's inputs
and actions (what `launch/scenes/cup_deformation_learned_vla.yaml` loads), with a model that
misbehaves on purpose. Nothing trained: the action is a constant (in standardised units) plus
0 x the inputs, so every input is read.

usage: make_stub_policy.py OUT_DIR --kind ok|nan|loop [--iterations N] [--rate HZ]
                                   [--input-std S]

--kind ok    finite actions inside the bounds (the gripper half open, the arm home)
--kind nan   the model returns NaN in every action (every tick fails)
--kind loop  the constant comes out of a Loop of N iterations (default 10^9: minutes per call),
             so a run takes as long as ONNX Runtime needs for N tiny iterations
--rate       the manifest's control_rate_hz (default 30)
--input-std  observation.state's std in the manifest (default 1)

Each model is checked with onnx.checker; the manifest carries the file's sha256.
"""
import argparse
import hashlib
import json
import os

import numpy as np
import onnx
from onnx import TensorProto, helper, numpy_helper

STATE = 8
VISUAL = ["cup_x_m", "cup_y_m", "cup_z_m", "cup_width_m", "cup_height_m"]
ACTIONS = [
    ("gripper.position_m", "m", 0.0, 0.085),
    ("gripper.speed_m_s", "m/s", 0.0, 0.15),
    ("gripper.force_n", "N", 0.0, 40.0),
    ("arm.x_m", "m", -1.0, 1.0),
    ("arm.y_m", "m", -1.0, 1.0),
    ("arm.z_m", "m", 0.0, 0.3),
    ("arm.lift_m", "m", 0.0, 0.2),
    ("arm.target.home", "score", -10.0, 10.0),
    ("arm.target.cup", "score", -10.0, 10.0),
]
# Standardised constant action: mean + 0 std (mid-range), home scored highest.
MEAN = [0.04, 0.05, 5.0, 0.0, 0.0, 0.1, 0.0, 1.0, 0.0]
INPUTS = [("observation.state", STATE), ("observation.visual", len(VISUAL)),
          ("observation.latched", 2), ("observation.arm", 2)]


def build(kind, iterations):
    a = len(ACTIONS)
    nodes, inits = [], []
    graph_inputs = [helper.make_tensor_value_info(n, TensorProto.FLOAT, ["batch", w])
                    for n, w in INPUTS]
    # 0 x (sum of every input), shape [batch, 1]
    nodes.append(helper.make_node("Concat", [n for n, _ in INPUTS], ["all"], axis=1))
    nodes.append(helper.make_node("ReduceSum", ["all"], ["sum"], keepdims=1))
    inits.append(numpy_helper.from_array(np.array(0.0, np.float32), "zero"))
    nodes.append(helper.make_node("Mul", ["sum", "zero"], ["nothing"]))
    fill = np.nan if kind == "nan" else 0.0
    inits.append(numpy_helper.from_array(np.full((1, a), fill, np.float32), "base"))
    if kind == "loop":
        # y = base + 0 after `iterations` rounds of v = v + 0 on one value.
        inits.append(numpy_helper.from_array(np.array(iterations, np.int64), "trips"))
        inits.append(numpy_helper.from_array(np.array(True), "cond"))
        inits.append(numpy_helper.from_array(np.zeros((1, 1), np.float32), "v0"))
        body = helper.make_graph(
            [helper.make_node("Identity", ["cond_in"], ["cond_out"]),
             helper.make_node("Add", ["v_in", "v_in"], ["v_out"])],
            "body",
            [helper.make_tensor_value_info("i", TensorProto.INT64, []),
             helper.make_tensor_value_info("cond_in", TensorProto.BOOL, []),
             helper.make_tensor_value_info("v_in", TensorProto.FLOAT, [1, 1])],
            [helper.make_tensor_value_info("cond_out", TensorProto.BOOL, []),
             helper.make_tensor_value_info("v_out", TensorProto.FLOAT, [1, 1])])
        nodes.append(helper.make_node("Loop", ["trips", "cond", "v0"], ["v_end"], body=body))
        nodes.append(helper.make_node("Add", ["nothing", "v_end"], ["offset"]))
    else:
        nodes.append(helper.make_node("Identity", ["nothing"], ["offset"]))
    nodes.append(helper.make_node("Add", ["base", "offset"], ["flat"]))
    inits.append(numpy_helper.from_array(np.array([-1, 1, a], np.int64), "shape"))
    nodes.append(helper.make_node("Reshape", ["flat", "shape"], ["action"]))
    graph = helper.make_graph(
        nodes, "stub", graph_inputs,
        [helper.make_tensor_value_info("action", TensorProto.FLOAT, ["batch", 1, a])],
        initializer=inits)
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 20)])
    model.ir_version = 9
    onnx.checker.check_model(model)
    return model


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("out")
    ap.add_argument("--kind", choices=["ok", "nan", "loop"], default="ok")
    ap.add_argument("--iterations", type=int, default=10**9)
    ap.add_argument("--rate", type=float, default=30.0)
    ap.add_argument("--input-std", type=float, default=1.0)
    args = ap.parse_args()
    os.makedirs(args.out, exist_ok=True)
    path = os.path.join(args.out, "policy.onnx")
    onnx.save(build(args.kind, args.iterations), path)
    with open(path, "rb") as f:
        sha = hashlib.sha256(f.read()).hexdigest()
    inputs = []
    for n, w in INPUTS:
        std = args.input_std if n == "observation.state" else 1.0
        spec = {"name": n, "dtype": "float32", "shape": ["batch", w],
                "normalization": {"mode": "mean_std", "mean": [0.0] * w, "std": [std] * w}}
        if n == "observation.visual":
            spec["names"] = VISUAL
        inputs.append(spec)
    manifest = {
        "policy": f"stub_{args.kind}", "version": "1", "file": "policy.onnx", "sha256": sha,
        "control_rate_hz": args.rate, "chunk_size": 1, "n_action_steps": 1,
        "temporal_ensemble_coeff": None, "inputs": inputs,
        "output": {"name": "action", "dtype": "float32", "shape": ["batch", 1, len(ACTIONS)],
                   "normalization": {"mode": "mean_std", "mean": MEAN,
                                     "std": [1.0] * len(ACTIONS)},
                   "actions": [{"name": n, "unit": u, "min": lo, "max": hi}
                               for n, u, lo, hi in ACTIONS]},
    }
    with open(os.path.join(args.out, "manifest.json"), "w") as f:
        json.dump(manifest, f, indent=1)


if __name__ == "__main__":
    main()
