"""A small test policy for crates/policy's ONNX runtime: an MLP from numpy weights (fixed seed)
with LeRobot-style flat inputs and an action chunk output, plus its manifest.json.

usage: make_policy.py OUT_DIR [--nan-below-mean] [--state-dtype float32|float64]

Inputs (batch first, symbolic "batch"):
  observation.state          [batch, 6]        mean_std per element
  observation.tactile_latent [batch, 16]       min_max per element
  observation.images.wrist   [batch, 3, 4, 4]  mean_std per channel (LeRobot image statistics)
Output: action [batch, 8, 3] (chunk_size 8; gripper opening m, speed m/s, force N), mean_std.
The output statistics put some predictions outside the action bounds, so clamping is exercised.

--nan-below-mean: the model returns NaN whenever the first state feature is below its mean
(sqrt of a negative number), finite otherwise: a model that fails on some inputs only.
--state-dtype float64: observation.state is a double input (cast inside), for dtype checks.
"""
import argparse
import hashlib
import json
import os

import numpy as np
import onnx
from onnx import TensorProto, helper, numpy_helper

H, A = 8, 3
STATE, LATENT, IMG = 6, 16, (3, 4, 4)
HIDDEN = 32
ACTIONS = [
    {"name": "gripper.opening", "unit": "m", "min": 0.0, "max": 0.085},
    {"name": "gripper.speed", "unit": "m/s", "min": 0.02, "max": 0.15},
    {"name": "gripper.force", "unit": "N", "min": 20.0, "max": 235.0},
]


def stats(rng):
    return {
        "state_mean": rng.normal(0.0, 0.05, STATE),
        "state_std": rng.uniform(0.01, 0.1, STATE),
        "latent_min": rng.uniform(-3.0, -1.0, LATENT),
        "latent_max": rng.uniform(1.0, 3.0, LATENT),
        "img_mean": np.array([0.485, 0.456, 0.406]),
        "img_std": np.array([0.229, 0.224, 0.225]),
        "act_mean": np.array([0.04, 0.08, 100.0]),
        "act_std": np.array([0.02, 0.03, 40.0]),
    }


def build(nan_below_mean, state_dtype):
    rng = np.random.default_rng(7)
    s = stats(rng)
    n_in = STATE + LATENT + int(np.prod(IMG))
    w1 = rng.normal(0.0, 1.0 / np.sqrt(n_in), (n_in, HIDDEN)).astype(np.float32)
    b1 = rng.normal(0.0, 0.1, HIDDEN).astype(np.float32)
    w2 = rng.normal(0.0, 1.5 / np.sqrt(HIDDEN), (HIDDEN, H * A)).astype(np.float32)
    b2 = rng.normal(0.0, 0.1, H * A).astype(np.float32)
    inits = [numpy_helper.from_array(w1, "w1"), numpy_helper.from_array(b1, "b1"),
             numpy_helper.from_array(w2, "w2"), numpy_helper.from_array(b2, "b2"),
             numpy_helper.from_array(np.array([-1, H, A], np.int64), "chunk_shape")]
    nodes = []
    state = "observation.state"
    if state_dtype == "float64":
        nodes.append(helper.make_node("Cast", [state], ["state_f32"], to=TensorProto.FLOAT))
        state = "state_f32"
    nodes += [
        helper.make_node("Flatten", ["observation.images.wrist"], ["img_flat"], axis=1),
        helper.make_node("Concat", [state, "observation.tactile_latent", "img_flat"], ["x"],
                         axis=1),
        helper.make_node("Gemm", ["x", "w1", "b1"], ["h_pre"]),
        helper.make_node("Tanh", ["h_pre"], ["h"]),
        helper.make_node("Gemm", ["h", "w2", "b2"], ["flat"]),
    ]
    out = "flat"
    if nan_below_mean:
        # sqrt(min(state[:, 0:1], 0)): 0 when the normalised feature is >= 0, NaN below.
        inits += [numpy_helper.from_array(np.array([0], np.int64), "s0"),
                  numpy_helper.from_array(np.array([1], np.int64), "s1"),
                  numpy_helper.from_array(np.array([0], np.float32), "zero")]
        nodes += [helper.make_node("Slice", [state, "s0", "s1", "s1"], ["x0"]),
                  helper.make_node("Min", ["x0", "zero"], ["x0neg"]),
                  helper.make_node("Sqrt", ["x0neg"], ["guard"]),
                  helper.make_node("Add", ["flat", "guard"], ["flat_guarded"])]
        out = "flat_guarded"
    nodes.append(helper.make_node("Reshape", [out, "chunk_shape"], ["action"]))
    elem = TensorProto.DOUBLE if state_dtype == "float64" else TensorProto.FLOAT
    g = helper.make_graph(
        nodes, "test_policy",
        [helper.make_tensor_value_info("observation.state", elem, ["batch", STATE]),
         helper.make_tensor_value_info("observation.tactile_latent", TensorProto.FLOAT,
                                       ["batch", LATENT]),
         helper.make_tensor_value_info("observation.images.wrist", TensorProto.FLOAT,
                                       ["batch", *IMG])],
        [helper.make_tensor_value_info("action", TensorProto.FLOAT, ["batch", H, A])],
        inits)
    m = helper.make_model(g, opset_imports=[helper.make_opsetid("", 20)])
    m.ir_version = 9
    onnx.checker.check_model(m)
    return m, s


def manifest(s, sha):
    lst = lambda a: [float(v) for v in a]
    return {
        "policy": "test_mlp",
        "version": "1",
        "description": "test MLP with random weights (tests/policy/make_policy.py, seed 7)",
        "file": "policy.onnx",
        "sha256": sha,
        "control_rate_hz": 30.0,
        "chunk_size": H,
        "n_action_steps": 4,
        "temporal_ensemble_coeff": None,
        "inputs": [
            {"name": "observation.state", "dtype": "float32", "shape": ["batch", STATE],
             "normalization": {"mode": "mean_std", "mean": lst(s["state_mean"]),
                               "std": lst(s["state_std"])}},
            {"name": "observation.tactile_latent", "dtype": "float32", "shape": ["batch", LATENT],
             "normalization": {"mode": "min_max", "min": lst(s["latent_min"]),
                               "max": lst(s["latent_max"])}},
            {"name": "observation.images.wrist", "dtype": "float32", "shape": ["batch", *IMG],
             "normalization": {"mode": "MEAN_STD", "mean": lst(s["img_mean"]),
                               "std": lst(s["img_std"])}},
        ],
        "output": {
            "name": "action", "dtype": "float32", "shape": ["batch", H, A],
            "normalization": {"mode": "mean_std", "mean": lst(s["act_mean"]),
                              "std": lst(s["act_std"])},
            "actions": ACTIONS,
        },
    }


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("out")
    ap.add_argument("--nan-below-mean", action="store_true")
    ap.add_argument("--state-dtype", default="float32", choices=["float32", "float64"])
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    m, s = build(a.nan_below_mean, a.state_dtype)
    path = os.path.join(a.out, "policy.onnx")
    onnx.save(m, path)
    sha = hashlib.sha256(open(path, "rb").read()).hexdigest()
    with open(os.path.join(a.out, "manifest.json"), "w") as f:
        json.dump(manifest(s, sha), f, indent=1, allow_nan=False)


if __name__ == "__main__":
    main()
