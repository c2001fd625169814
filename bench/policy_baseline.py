"""Python baseline for `unitac-lab bench policy`: the same ONNX policy run per control tick the way a
LeRobot user runs an exported policy in Python, and a Python control loop paced with time.sleep.

Per tick (LeRobot's select_action with an action queue): when the queue is empty, normalise the
inputs with numpy (statistics prepared once, as LeRobot's Normalize buffers are), run the model
with onnxruntime (one intra-op thread, CPU, as unitac's runtime), unnormalise, clamp to the
action bounds and queue n_action_steps rows; then pop this tick's action. Temporal ensembling
is not done here (the test policy has none).

Paced loop: PACED ticks at the manifest's control rate, each started at the absolute deadline
t0 + k * period (time.sleep until then, so the error does not accumulate).

usage: policy_baseline.py POLICY_DIR TICKS PACED
prints one JSON object: per-tick times in microseconds, the paced loop's start times [s].
"""
import json
import os
import platform
import sys
import time

import numpy as np
import onnxruntime as ort

MODES = {"mean_std": "mean_std", "min_max": "min_max", "identity": "identity"}


def stat(values, shape):
    v = np.asarray(values, np.float32)
    if v.size == int(np.prod(shape)):
        return v.reshape(shape)
    return v.reshape((-1,) + (1,) * (len(shape) - 1))  # per channel


def prepare(spec):
    """(shape, scale, offset) with normalised = x * scale + offset."""
    shape = [int(d) for d in spec["shape"][1:]]
    n = spec["normalization"]
    mode = MODES[n["mode"].lower()]
    if mode == "mean_std":
        std = stat(n["std"], shape)
        return shape, 1.0 / std, -stat(n["mean"], shape) / std
    if mode == "min_max":
        lo, hi = stat(n["min"], shape), stat(n["max"], shape)
        return shape, 2.0 / (hi - lo), -2.0 * lo / (hi - lo) - 1.0
    return shape, np.float32(1), np.float32(0)


def main():
    pdir, ticks, paced = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
    m = json.load(open(os.path.join(pdir, "manifest.json")))
    opts = ort.SessionOptions()
    opts.intra_op_num_threads = 1
    opts.inter_op_num_threads = 1
    sess = ort.InferenceSession(os.path.join(pdir, m["file"]), opts,
                                providers=["CPUExecutionProvider"])
    o = m["output"]
    lo = np.array([a["min"] for a in o["actions"]], np.float32)
    hi = np.array([a["max"] for a in o["actions"]], np.float32)
    on = o["normalization"]
    omode = MODES[on["mode"].lower()]
    k = m["n_action_steps"]
    specs = [(s["name"], *prepare(s)) for s in m["inputs"]]
    rng = np.random.default_rng(1)
    raw = {name: (rng.standard_normal(int(np.prod(shape))) * 0.1).astype(np.float32)
           for name, shape, _, _ in specs}
    queue = []

    def tick():
        nonlocal queue
        inferred = False
        if not queue:
            feeds = {name: (raw[name].reshape(shape) * scale + offset)[None].astype(np.float32)
                     for name, shape, scale, offset in specs}
            y = sess.run([o["name"]], feeds)[0][0]
            if omode == "mean_std":
                y = y * np.asarray(on["std"], np.float32) + np.asarray(on["mean"], np.float32)
            elif omode == "min_max":
                mn, mx = np.asarray(on["min"], np.float32), np.asarray(on["max"], np.float32)
                y = (y + 1.0) / 2.0 * (mx - mn) + mn
            if not np.isfinite(y).all():
                raise ValueError("non-finite action")
            queue = list(np.clip(y, lo, hi)[:k])
            inferred = True
        return queue.pop(0), inferred

    for _ in range(20):  # warm-up, as on the Rust side
        tick()
    queue = []
    act_s, inferred_s = [], []
    for _ in range(ticks):
        t0 = time.perf_counter()
        _, inf = tick()
        s = time.perf_counter() - t0
        act_s.append(s)
        if inf:
            inferred_s.append(s)

    period = 1.0 / m["control_rate_hz"]
    starts, paced_s = [], []
    queue = []
    t_start = time.perf_counter()
    for i in range(paced):
        left = t_start + i * period - time.perf_counter()
        if left > 0:
            time.sleep(left)
        t0 = time.perf_counter()
        starts.append(t0)
        tick()
        paced_s.append(time.perf_counter() - t0)

    print(json.dumps({
        "act_s": act_s, "inferred_s": inferred_s,
        "paced_starts_s": starts, "paced_act_s": paced_s, "period_s": period,
        "python": platform.python_version(), "onnxruntime": ort.__version__,
        "numpy": np.__version__,
    }))


if __name__ == "__main__":
    main()
