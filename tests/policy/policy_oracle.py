"""The numpy + Python onnxruntime oracle for crates/policy's ONNX policy runtime.

usage: policy_oracle.py POLICY_DIR TICKS.json OUT.json
TICKS: {"ticks": [{"t": ns, "inputs": {name: [values...]}}]}
OUT:   {"plans": [[[row0...], [row1...], ...] per tick], "inferred": [bool per tick],
        "clamped": [int per tick]}

Written from the manifest's definitions, independently of the Rust code: LeRobot normalisation
in float32, Python onnxruntime for the model, unnormalisation, clamping to the action bounds,
ticks = round((t - t0) / period), an inference every n_action_steps ticks (or when the plan ran
out), and ACT temporal ensembling over every stored prediction of a tick, oldest first, with
w_i = exp(-m i) normalised (float64).
"""
import json
import os
import sys

import numpy as np
import onnxruntime as ort

MODES = {"mean_std": "mean_std", "MEAN_STD": "mean_std", "min_max": "min_max",
         "MIN_MAX": "min_max", "identity": "identity", "IDENTITY": "identity"}


def stat(values, shape):
    v = np.asarray(values, np.float64).astype(np.float32)
    if v.size == int(np.prod(shape)):
        return v.reshape(shape)
    return v.reshape((-1,) + (1,) * (len(shape) - 1))  # per channel


def normalise(spec, x):
    shape = [int(d) for d in spec["shape"][1:]]
    x = np.asarray(x, np.float64).astype(np.float32).reshape(shape)
    n = spec["normalization"]
    mode = MODES[n["mode"]]
    if mode == "mean_std":
        x = (x - stat(n["mean"], shape)) / stat(n["std"], shape)
    elif mode == "min_max":
        lo, hi = stat(n["min"], shape), stat(n["max"], shape)
        x = (x - lo) / (hi - lo) * np.float32(2) - np.float32(1)
    return x[None]


def unnormalise(n, y):
    mode = MODES[n["mode"]]
    f = lambda k: np.asarray(n[k], np.float64).astype(np.float32)
    if mode == "mean_std":
        return y * f("std") + f("mean")
    if mode == "min_max":
        return (y + np.float32(1)) / np.float32(2) * (f("max") - f("min")) + f("min")
    return y


def main():
    pdir, ticks_path, out_path = sys.argv[1:4]
    m = json.load(open(os.path.join(pdir, "manifest.json")))
    opts = ort.SessionOptions()
    opts.intra_op_num_threads = 1
    sess = ort.InferenceSession(os.path.join(pdir, m["file"]), opts,
                                providers=["CPUExecutionProvider"])
    o = m["output"]
    lo = np.array([a["min"] for a in o["actions"]], np.float64).astype(np.float32)
    hi = np.array([a["max"] for a in o["actions"]], np.float64).astype(np.float32)
    H, k, coeff = m["chunk_size"], m["n_action_steps"], m["temporal_ensemble_coeff"]
    period = int(round(1e9 / m["control_rate_hz"]))

    def infer(inputs):
        feeds = {s["name"]: normalise(s, inputs[s["name"]]) for s in m["inputs"]}
        y = sess.run([o["name"]], feeds)[0][0]  # [H, A]
        assert np.isfinite(y).all()
        y = unnormalise(o["normalization"], y)
        clamped = int(((y < lo) | (y > hi)).sum())
        return np.clip(y, lo, hi), clamped

    t0, chunks, last_inf = None, [], None  # chunks: (start tick, [H, A]) oldest first
    plans, inferred, clamped = [], [], []
    for tk in json.load(open(ticks_path))["ticks"]:
        t = int(tk["t"])
        t0 = t if t0 is None else t0
        tick = (2 * (t - t0) + period) // (2 * period)
        due = last_inf is None or tick >= last_inf + k or tick >= chunks[-1][0] + H
        n = 0
        if due:
            y, n = infer(tk["inputs"])
            chunks = (chunks if coeff is not None else []) + [(tick, y)]
            last_inf = tick
        chunks = [c for c in chunks if c[0] + H > tick]
        plan = []
        for tau in range(tick, chunks[-1][0] + H):
            preds = np.array([c[1][tau - c[0]] for c in chunks if c[0] <= tau < c[0] + H],
                             np.float64)
            w = np.exp(-(coeff or 0.0) * np.arange(len(preds))) if coeff is not None \
                else np.eye(len(preds))[-1]
            plan.append((w[:, None] * preds).sum(0) / w.sum())
        plans.append(np.asarray(plan, np.float64).astype(np.float32).tolist())
        inferred.append(bool(due))
        clamped.append(n)
    json.dump({"plans": plans, "inferred": inferred, "clamped": clamped}, open(out_path, "w"))


if __name__ == "__main__":
    main()
