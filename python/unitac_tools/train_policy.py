"""Train the learned VLA / VTLA-real / VTLA-pred policies on LeRobot v3.0 datasets of the
scripted expert's demonstrations (python/unitac_tools/lerobot_dataset.py), numpy only, and export each to ONNX
in the policy bundle format of crates/policy/src/onnx (manifest.json with LeRobot names).

A --dataset DS is one task's (its directory name is the task's, e.g. cup_deformation): either a
directory of one dataset per mode, DS/<mode> (the expert's demonstrations for that mode, deciding
from what the mode observes: scripts/learned_policies.sh), each mode trained on its own; or a
dataset itself (meta/info.json), every mode trained on it.

usage: python -m unitac_tools.train_policy --dataset DS [--dataset DS2 ...] --out DIR [--seed S] [--dagger DIR]
       python -m unitac_tools.train_policy --select --dataset DS [...]     (the hyperparameter table, printed)
       python -m unitac_tools.train_policy --check-onnx DIR --dataset DS    (ONNX Runtime against the numpy forward)

One architecture for the three modes: the observation features a mode reads ([MODES]) are
concatenated, standardised per element (mean_std over the training frames; a constant element
gets std 1), and go through two tanh layers of HIDDEN units to the action, standardised the same
way: the gripper's position, speed and force limit, the arm's x, y, z and lift, and one score per
arm target (home, then each object: the runtime takes the largest). The modes differ only in
their observation slices; nothing names an object, an index or a hash.

Bounds: each command's [lo, hi] is the dataset's (info.json action "bounds": the range the
recording scene's safety layer held the expert to). Training keeps the last layer's output z
inside them: the loss is the mean squared error of the standardised action plus BARRIER times
the mean squared distance of z beyond its bounds (the expert commands the 40 N force limit in
most cup frames and a closed gripper in most fabric frames, and a plain least-squares fit
overshoots such bounds in a large share of ticks). The network then ends in a clip of z to the
bounds, so no output leaves them; train.json reports per policy the share of frames whose z lay
beyond a bound by more than 2 % of its range before that clip (training frames, and the DAgger
frames: states the first-round policy reached in closed loop). Arm-target scores are neither
penalised nor clipped (the runtime takes the largest). Adam with a cosine learning rate, weight
decay, minibatches. BARRIER was set once, not searched.

Hyperparameters were chosen ONCE for all modes and both tasks with --select: episodes of the
largest seed of each training dataset held out, every grid point trained on the rest, the mean
held-out loss over the 3 modes x tasks compared (the table goes to stdout); the chosen values are
the constants below. The final fit uses every training episode.

DAgger (--dagger DIR): the policy of mode M for task T is fitted on T's demonstrations plus the
LeRobot dataset DIR/T_M, if there is one: the states that mode's first-round policy visited,
each labelled with the expert's command there (`unitac-lab demos --drive`, scripts/learned_policies.sh).

Export (onnx.helper, opset 20): one input per feature ("observation.state", ...), [batch, n],
normalisation mean_std in the manifest; Concat -> Gemm -> Tanh -> Gemm -> Tanh -> Gemm -> Max,
Min (the clip, in standardised units) -> Reshape [batch, 1, A] -> output "action", its mean_std
normalisation and per action those bounds. chunk_size 1, n_action_steps 1: one setpoint per
control tick.
"""
import argparse
import glob
import json
import os
import sys
import time

import numpy as np
import pyarrow.parquet as pq
from onnx import TensorProto, helper

from . import schema
from .generate_reference import gradient_check_error, init, i64, model, save

# The observation features each mode's policy reads (schema/policy.json).
MODES = schema.LEARNED_FEATURES
# Chosen with --select (see the module doc; README "Learned policies" has the table).
HIDDEN = 128
LR = 3e-3
WEIGHT_DECAY = 1e-4
EPOCHS = 30
BATCH = 256
GRID = [{"hidden": h, "lr": lr, "weight_decay": WEIGHT_DECAY} for h in [64, 128] for lr in [1e-3, 3e-3]]
# The unit of each action value (schema/policy.json); its bounds are the dataset's (info.json
# action "bounds": the range the recording scene's safety layer held it to); an arm target's
# score is in [0, 1].
UNITS = schema.UNITS
MAX_FRAMES = 2_000_000
# Weight of the squared distance beyond a bound in the loss (set once, not searched).
BARRIER = 10.0
# A pre-clip value further beyond a bound than this share of its range counts as beyond.
FAR_FRACTION = schema.FAR_FRACTION


def mode_root(root, mode):
    """The dataset mode `mode` of the task dataset `root` trains on: root/mode if it is a
    dataset, else root."""
    own = os.path.join(root, mode)
    return own if os.path.isfile(os.path.join(own, "meta", "info.json")) else root


def load(root):
    """(info, columns {feature: [frames, n] float64}, episode index per frame, seeds per episode)."""
    info = json.load(open(os.path.join(root, "meta", "info.json")))
    if info.get("codebase_version") != "v3.0":
        raise SystemExit(f"{root}: not a v3.0 dataset")
    paths = sorted(glob.glob(os.path.join(root, "data", "*", "*.parquet")))
    tables = [pq.read_table(p) for p in paths]
    cols = {}
    for key, ft in info["features"].items():
        if key in ("timestamp", "frame_index", "index", "task_index"):
            continue
        parts = []
        for t in tables:
            c = t.column(key).combine_chunks()
            n = ft["shape"][0]
            v = c.flatten().to_numpy(zero_copy_only=False) if n > 1 else c.to_numpy(zero_copy_only=False)
            parts.append(np.asarray(v, np.float64).reshape(-1, n))
        cols[key] = np.concatenate(parts)
    if len(cols[schema.ACTION]) > MAX_FRAMES:
        raise SystemExit(f"{root}: more than {MAX_FRAMES} frames")
    ep = pq.read_table(os.path.join(root, "meta", "episodes", "chunk-000", "file-000.parquet"),
                       columns=["episode_index", "seed"]).to_pydict()
    seeds = dict(zip(ep["episode_index"], ep["seed"]))
    return info, cols, cols.pop("episode_index")[:, 0].astype(int), seeds


def targets(info, cols):
    """The action matrix [frames, 7 + targets], its names and per name (unit, min, max)."""
    cats = info["features"][schema.ARM_TARGET]["categories"]
    onehot = np.eye(len(cats))[cols[schema.ARM_TARGET][:, 0].astype(int)]
    action = info["features"][schema.ACTION]
    b = action.get("bounds")
    if not b or len(b["min"]) != len(action["names"]) or len(b["max"]) != len(action["names"]):
        raise SystemExit("info.json: the action feature has no bounds for every value")
    bounds = {n: (UNITS[n], float(lo), float(hi))
              for n, lo, hi in zip(action["names"], b["min"], b["max"])}
    for c in cats:
        bounds[schema.ARM_TARGET_PREFIX + c] = (schema.ARM_TARGET_UNIT, 0.0, 1.0)
    names = list(action["names"]) + [schema.ARM_TARGET_PREFIX + c for c in cats]
    return np.concatenate([cols[schema.ACTION], onehot], axis=1), names, bounds


def observations(cols, mode):
    return np.concatenate([cols[k] for k in MODES[mode]], axis=1)


def standardise(x):
    """Mean and std per element; an element constant to rounding (its spread below 1e-9 of its
    size: SI values such as a contact area in m^2 are far smaller than 1 and still vary) gets std 1."""
    mu, sd = x.mean(0), x.std(0)
    return mu, np.where(sd > 1e-9 * np.maximum(np.abs(mu), 1e-12), sd, 1.0)


def head(names, bounds, ym, ys):
    """Each action's bounds in standardised units (the clip and the barrier; a score has none)."""
    lo = np.array([bounds[n][1] if bounds[n][0] != "score" else -np.inf for n in names])
    hi = np.array([bounds[n][2] if bounds[n][0] != "score" else np.inf for n in names])
    return {"lo": (lo - ym) / ys, "hi": (hi - ym) / ys}


def init_params(d_in, d_out, hidden, rng):
    def lin(i, o):
        return rng.normal(0.0, 1.0 / np.sqrt(i), (i, o)), np.zeros(o)
    p = {}
    p["W1"], p["b1"] = lin(d_in, hidden)
    p["W2"], p["b2"] = lin(hidden, hidden)
    p["W3"], p["b3"] = lin(hidden, d_out)
    p["W3"] *= 0.1
    return p


def forward(p, h, x):
    """The standardised action for standardised x, clipped to its bounds, and the activations
    (z: before the clip)."""
    a1 = np.tanh(x @ p["W1"] + p["b1"])
    a2 = np.tanh(a1 @ p["W2"] + p["b2"])
    z = a2 @ p["W3"] + p["b3"]
    return np.minimum(np.maximum(z, h["lo"]), h["hi"]), (a1, a2, z)


def loss_grad(p, h, x, y):
    """Mean squared error of z over frames and actions plus BARRIER times the mean squared
    distance of z beyond its bounds, and the gradient."""
    _, (a1, a2, z) = forward(p, h, x)
    n = x.shape[0] * y.shape[1]
    d = z - y
    over = np.maximum(z - h["hi"], 0.0) - np.maximum(h["lo"] - z, 0.0)
    loss = float(((d ** 2).sum() + BARRIER * (over ** 2).sum()) / n)
    g = {}
    do = 2.0 * (d + BARRIER * over) / n
    g["W3"], g["b3"] = a2.T @ do, do.sum(0)
    dh2 = (do @ p["W3"].T) * (1.0 - a2 ** 2)
    g["W2"], g["b2"] = a1.T @ dh2, dh2.sum(0)
    dh1 = (dh2 @ p["W2"].T) * (1.0 - a1 ** 2)
    g["W1"], g["b1"] = x.T @ dh1, dh1.sum(0)
    return loss, g


def gradient_error():
    """The largest relative difference between the backward pass and finite differences on a
    small random problem (python/tests/test_train_policy.py holds it under 1e-6)."""
    rng = np.random.default_rng(0)
    p = init_params(5, 3, 7, rng)
    p = {k: v + rng.normal(0, 0.3, v.shape) for k, v in p.items()}
    x, y = rng.normal(size=(6, 5)), rng.normal(size=(6, 3))
    h = {"lo": np.array([-1.0, -2.0, -1.5]), "hi": np.array([1.0, 2.0, 0.5])}
    # Targets at a bound, outputs on both sides of it.
    y[0, 0], y[1, 0], y[2, 2], y[3, 2] = -1.0, 1.0, 0.5, -1.5
    return gradient_check_error(lambda p_, x_, y_: loss_grad(p_, h, x_, y_), p, x, y)


def fit(x, y, h, hp, seed, epochs=EPOCHS):
    """Train on standardised x, y with the bounded head h; the parameters come back."""
    rng = np.random.default_rng(seed)
    p = init_params(x.shape[1], y.shape[1], hp["hidden"], rng)
    m = {k: np.zeros_like(v) for k, v in p.items()}
    v2 = {k: np.zeros_like(v) for k, v in p.items()}
    b1, b2, eps = 0.9, 0.999, 1e-8
    n = len(x)
    steps = epochs * max(1, n // BATCH)
    for it in range(1, steps + 1):
        i = rng.integers(0, n, BATCH)
        _, g = loss_grad(p, h, x[i], y[i])
        lr_t = hp["lr"] * 0.5 * (1 + np.cos(np.pi * it / steps))
        for k in p:
            m[k] = b1 * m[k] + (1 - b1) * g[k]
            v2[k] = b2 * v2[k] + (1 - b2) * g[k] ** 2
            mh, vh = m[k] / (1 - b1 ** it), v2[k] / (1 - b2 ** it)
            decay = hp["weight_decay"] * p[k] if k.startswith("W") else 0.0
            p[k] -= lr_t * (mh / (np.sqrt(vh) + eps) + decay)
    return p


def prepared(root, mode, keep=None, extra=()):
    """Standardised (x, y) of the episodes `keep` selects and of every frame of the `extra`
    datasets (same features), with the statistics of those frames and the bounded head they
    give."""
    info, cols, ep, seeds = load(root)
    x = observations(cols, mode)
    y, names, bounds = targets(info, cols)
    rows = np.ones(len(x), bool) if keep is None else np.array([keep(seeds[e]) for e in ep])
    n_base = len(x)
    for more in extra:
        info2, cols2, _, _ = load(more)
        y2, names2, bounds2 = targets(info2, cols2)
        x2 = observations(cols2, mode)
        if names2 != names or bounds2 != bounds or x2.shape[1] != x.shape[1]:
            raise SystemExit(f"{more}: its actions, their bounds or the {mode} observation differ from {root}'s")
        x, y = np.concatenate([x, x2]), np.concatenate([y, y2])
        rows = np.concatenate([rows, np.ones(len(x2), bool)])
    xm, xs = standardise(x[rows])
    ym, ys = standardise(y[rows])
    return (info, names, bounds, (x - xm) / xs, (y - ym) / ys, rows, (xm, xs, ym, ys),
            head(names, bounds, ym, ys), n_base)


def select(datasets):
    """Every grid point on every mode x task, trained without the largest seed, scored on it."""
    table = []
    for hp in GRID:
        losses = {}
        for root in datasets:
            for mode in MODES:
                data = mode_root(root, mode)
                _, _, _, seeds = load(data)
                held = max(seeds.values())
                _, _, _, x, y, rows, _, h, _ = prepared(data, mode, keep=lambda s: s != held)
                p = fit(x[rows], y[rows], h, hp, seed=0)
                out, _ = forward(p, h, x[~rows])
                losses[f"{os.path.basename(root.rstrip('/'))}/{mode}"] = float(((out - y[~rows]) ** 2).mean())
        table.append({**hp, "mean_held_out_loss": float(np.mean(list(losses.values()))), "losses": losses})
        print(json.dumps(table[-1]), flush=True)
    best = min(table, key=lambda r: r["mean_held_out_loss"])
    print(json.dumps({"chosen": {k: best[k] for k in ("hidden", "lr", "weight_decay")}}))
    return 0


def export(p, h, stats, info, names, bounds, mode, out_dir, name, task):
    xm, xs, ym, ys = stats
    feats = MODES[mode]
    widths = [info["features"][k]["shape"][0] for k in feats]
    a = len(names)
    nodes = [helper.make_node("Concat", feats, ["x"], axis=1),
             helper.make_node("Gemm", ["x", "W1", "b1"], ["h1"]),
             helper.make_node("Tanh", ["h1"], ["a1"]),
             helper.make_node("Gemm", ["a1", "W2", "b2"], ["h2"]),
             helper.make_node("Tanh", ["h2"], ["a2"]),
             helper.make_node("Gemm", ["a2", "W3", "b3"], ["z"]),
             helper.make_node("Max", ["z", "lo"], ["z_lo"]),
             helper.make_node("Min", ["z_lo", "hi"], ["flat"]),
             helper.make_node("Reshape", ["flat", "chunk_shape"], [schema.OUTPUT])]
    inits = [init(k, p[k]) for k in ("W1", "b1", "W2", "b2", "W3", "b3")]
    inits += [init(k, h[k]) for k in ("lo", "hi")]
    inits.append(i64("chunk_shape", [-1, 1, a]))
    g = helper.make_graph(
        nodes, f"{name}_policy",
        [helper.make_tensor_value_info(k, TensorProto.FLOAT, ["batch", w]) for k, w in zip(feats, widths)],
        [helper.make_tensor_value_info(schema.OUTPUT, TensorProto.FLOAT, ["batch", 1, a])], inits)
    os.makedirs(out_dir, exist_ok=True)
    path = os.path.join(out_dir, schema.ONNX_FILE)
    save(model(g), path)
    lst = lambda v: [float(t) for t in v]
    inputs, at = [], 0
    for k, w in zip(feats, widths):
        inputs.append({"name": k, "shape": ["batch", w], "names": list(info["features"][k]["names"]),
                       "normalization": {"mode": "mean_std", "mean": lst(xm[at:at + w]),
                                         "std": lst(xs[at:at + w])}})
        at += w
    actions = [{"name": n, "unit": bounds[n][0], "min": bounds[n][1], "max": bounds[n][2]} for n in names]
    schema.write_policy_manifest(
        out_dir, name,
        f"learned {mode} policy for '{task}' (python/unitac_tools/train_policy.py): one MLP architecture for all "
        f"modes, {mode}'s observation slices",
        info["fps"], inputs, actions, {"mode": "mean_std", "mean": lst(ym), "std": lst(ys)})
    np.savez(os.path.join(out_dir, "weights.npz"), **p, **{f"head_{k}": v for k, v in h.items()})


def beyond_share(p, h, x, stats, names, bounds):
    """Per command, the share of the (standardised) frames x whose pre-clip output lay beyond a
    bound by more than FAR_FRACTION of its range."""
    _, (_, _, z) = forward(p, h, x)
    _, _, ym, ys = stats
    v = z * ys + ym
    out = {}
    for j, n in enumerate(names):
        unit, lo, hi = bounds[n]
        if unit == "score":
            continue
        m = FAR_FRACTION * (hi - lo)
        out[n] = float(np.mean((v[:, j] < lo - m) | (v[:, j] > hi + m)))
    return out


def train_all(datasets, out, seed, dagger=None):
    report = []
    for root in datasets:
        task = os.path.basename(root.rstrip("/"))
        for mode in MODES:
            t0 = time.time()
            more = os.path.join(dagger, f"{task}_{mode}") if dagger else None
            extra = [more] if more and os.path.isdir(more) else []
            data = mode_root(root, mode)
            info, names, bounds, x, y, _, stats, h, n_base = prepared(data, mode, extra=extra)
            p = fit(x, y, h, {"hidden": HIDDEN, "lr": LR, "weight_decay": WEIGHT_DECAY}, seed)
            out_, _ = forward(p, h, x)
            name = f"{task}_{mode}"
            instruction = pq.read_table(os.path.join(data, "meta", "tasks.parquet")).column(
                "__index_level_0__")[0].as_py()
            export(p, h, stats, info, names, bounds, mode, os.path.join(out, name), name, instruction)
            report.append({"policy": name, "dataset": os.path.relpath(data, os.path.dirname(root.rstrip("/"))),
                           "frames": len(x), "dagger": bool(extra), "inputs": x.shape[1],
                           "train_loss": float(((out_ - y) ** 2).mean()),
                           "beyond_share_demos": beyond_share(p, h, x[:n_base], stats, names, bounds),
                           "beyond_share_dagger": beyond_share(p, h, x[n_base:], stats, names, bounds)
                           if len(x) > n_base else None,
                           "seconds": round(time.time() - t0, 1)})
            print(json.dumps(report[-1]), flush=True)
    with open(os.path.join(out, "train.json"), "w") as f:
        json.dump({"seed": seed, "hidden": HIDDEN, "lr": LR, "weight_decay": WEIGHT_DECAY,
                   "epochs": EPOCHS, "policies": report}, f, indent=1)
    return 0


def onnx_vs_numpy(bundles, datasets):
    """ONNX Runtime on the manifest's normalised inputs (the first 512 frames of each dataset)
    against the numpy forward of the saved weights: per policy, its largest absolute difference."""
    import onnxruntime as ort
    diffs = {}
    for root in datasets:
        task = os.path.basename(root.rstrip("/"))
        for mode in MODES:
            d = os.path.join(bundles, f"{task}_{mode}")
            man = json.load(open(os.path.join(d, "manifest.json")))
            w = np.load(os.path.join(d, "weights.npz"))
            f64 = lambda v: v.astype(np.float32).astype(np.float64)
            p = {k: f64(w[k]) for k in w.files if not k.startswith("head_")}
            h = {k[len("head_"):]: f64(w[k]) for k in w.files if k.startswith("head_")}
            _, cols, _, _ = load(mode_root(root, mode))
            feed, xs = {}, []
            for spec in man["inputs"]:
                v = cols[spec["name"]][:512]
                nm = spec["normalization"]
                v = ((v - np.array(nm["mean"])) / np.array(nm["std"])).astype(np.float32)
                feed[spec["name"]] = v
                xs.append(v.astype(np.float64))
            s = ort.InferenceSession(os.path.join(d, "policy.onnx"), providers=["CPUExecutionProvider"])
            got = s.run([schema.OUTPUT], feed)[0][:, 0, :]
            want, _ = forward(p, h, np.concatenate(xs, axis=1))
            diffs[man["policy"]] = float(np.abs(got - want).max())
    return diffs


# The largest ONNX-vs-numpy difference --check-onnx accepts (float32 graph, float64 reference).
ONNX_TOLERANCE = 1e-4


def check_onnx(bundles, datasets):
    diffs = onnx_vs_numpy(bundles, datasets)
    for policy, diff in diffs.items():
        print(json.dumps({"policy": policy, "max_abs_diff": diff}))
    worst = max(diffs.values(), default=0.0)
    print(json.dumps({"onnx_vs_numpy_max_abs_diff": worst}))
    return 0 if diffs and worst < ONNX_TOLERANCE else 1


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--dataset", action="append", default=[])
    ap.add_argument("--out")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--select", action="store_true")
    ap.add_argument("--check-onnx")
    ap.add_argument("--dagger")
    a = ap.parse_args()
    if not a.dataset:
        ap.error("--dataset is required")
    if a.select:
        return select(a.dataset)
    if a.check_onnx:
        return check_onnx(a.check_onnx, a.dataset)
    if not a.out:
        ap.error("--out is required")
    return train_all(a.dataset, a.out, a.seed, a.dagger)


if __name__ == "__main__":
    sys.exit(main())
