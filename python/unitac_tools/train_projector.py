"""Train the touch projector: a rectified-flow velocity model that maps noise to the touch
encoder's pooled latent of an object, conditioned on what is known before touching it (the
object-level condition: its category and the camera's values; the sensor-level condition: the
encoder's sensor tokens of the background), and export it with the encoder as a model bundle
the sampler stage runs (manifest `condition` names each input's source).

usage: python -m unitac_tools.train_projector --train T1.json [T2.json ...] --unseen U1.json [U2.json ...]
                          --reference REF_BUNDLE --out DIR [--steps N] [--seed S]

Data: `unitac-lab dataset touch` files (touch.json), one per split and sensor. The latent is [2, 48]:
the encoder's token mean and token mean of squares (96 values).

Model (numpy, trained here; ONNX built with onnx.helper): inputs x [b, 96] (the standardised
latent along the flow), t [b, 1] (tau: 0 noise, 1 data), object [b, 6], sensor [b, 48]:
  c  = [(object - mu_o) / sd_o * (object != 0), (sensor - mu_s) / sd_s]
  c' = c with its object part clamped to the training range of each value
  h0 = [x, sin/cos(t f) (16), c']
  v  = W3 silu(W2 silu(W1 h0 + b1) + b2) + b3 + Ws h0  +  mu(c) + b(t) (x - t mu(c))
The last term is the exact velocity of a Gaussian target N(mu(c), diag sigma^2) whose mean is
linear in the condition (ridge of the latent on c, fitted in closed form before training, with
and without the object so the unconditional branch has its own, intercepts not shrunk; sigma the
residual spread per element, at least SIGMA_MIN); the network learns what that leaves, on inputs
it saw. So a camera value outside the training range (the unseen cups are all larger) moves the
latent along the base's line, and the network holds its value at the range's edge. Loss:
rectified flow, |v(x_t, t, c) - (y - e)|^2 with
x_t = (1 - t) e + t y, e ~ N(0, I), y the standardised latent, t ~ U(0, 1). Classifier-free
dropout: the object input is zeroed for 20 % of the samples, so the sensor-only branch of
sensor-prior sampling (SPSS) is a trained unconditional branch. Adam with a cosine schedule;
architecture and training hyperparameters fixed once here, no search.

Sampling as the sampler stage does it: Heun 16 steps, the mean of K = 8 seeded samples per object
(its `samples: 8`). The guidance scale is chosen on the TRAINING split only: the model is fitted
without the training cups of the largest quarter of sizes and the scale in GUIDANCE_GRID that
reads those cups' stiffness best is kept (ties: nearest the paper's 1.5), the way the unseen cups
lie beyond every training size; then the model is fitted on all of the training split.

Evaluation on the unseen split (written to DIR/eval.json and stdout), with readouts fitted on the
ENCODER's latents of training objects only:
- stiffness: ridge on the standardised pooled latent to log k, lambda by leave-one-size-out
  cross-validation on training cups; exported as DIR/stiffness (a policy bundle the cup scenes'
  policy stage reads: input observation.tactile_latent [b, 96], action cup.stiffness N/m);
- roughness: the reference bundle's property head (its weights read from properties.onnx), and a
  ridge on the encoder's pooled latents of the training fabrics (lambda by leave-one-seed-out).
Held-out = the unseen split (larger cups, fabric types never trained on). Baselines: ridge from
the same condition straight to log k; the training mean; for fabric pairs, the camera's own
roughness guess and the sensor-only branch (object zeroed). Fabric pairs from sampled latents are
scored with the two fabrics' sampler seeds in both assignments, averaged (one assignment alone
ranks by seed: the scene's object order fixes the seeds). The held-out sweep over the guidance
grid is reported beside the chosen scale.

The trained model's outputs on probe inputs are written to DIR/check.json; a Rust test runs the
ONNX file on them through ONNX Runtime and compares.
"""
import argparse
import json
import os
import shutil
import sys

import numpy as np
import onnx
from onnx import TensorProto, helper, numpy_helper

# The bundle helpers (manifest entries with their declared inputs/outputs, initialisers, the
# gradient check).
from .generate_reference import entry, gradient_check_error, init
# The policies' layout (the stiffness readout's input, action and range; the manifest writer).
from . import schema

OPSET = 20
FIELDS = ["category:cup", "category:fabric", "width_m", "height_m", "edge_height_m", "roughness"]
N_FREQ = 8
HIDDEN = 128
DROP_OBJECT = 0.2
SIGMA_MIN = 0.1
SENSOR_PCS = 4
STEPS, SAMPLES = 16, 8
GUIDANCE_GRID = [0.5, 1.0, 1.5, 2.0, 3.0]
K_MIN, K_MAX = schema.K_MIN, schema.K_MAX
LAMBDAS = [10.0 ** e for e in np.arange(-3.0, 5.01, 0.5)]


# ---------------------------------------------------------------------------------------------
# Data
def load(paths):
    rows = []
    for p in paths:
        d = json.load(open(p))
        sensor = d["sensor"]
        for s in d["samples"]:
            obj = [1.0 if f == "category:" + s["category"] else 0.0 for f in FIELDS[:2]]
            obj += [float(s["visual"].get(f, 0.0)) for f in FIELDS[2:]]
            rows.append(dict(s, sensor=sensor, split=d["split"], obj=obj))
    if not rows:
        raise SystemExit(f"no samples in {paths}")
    return rows


def arrays(rows):
    o = np.array([r["obj"] for r in rows], np.float64)
    s = np.array([r["sensor_prior"] for r in rows], np.float64)
    z = np.array([r["latent"] for r in rows], np.float64)
    return o, s, z


# ---------------------------------------------------------------------------------------------
# Network
def freqs():
    return np.pi * 2.0 ** np.arange(N_FREQ) / 2.0


class Norm:
    """Standardisation of the inputs and the target (training statistics)."""

    def __init__(self, o, s, z):
        mu_o, sd_o = np.zeros(o.shape[1]), np.ones(o.shape[1])
        for j in range(2, o.shape[1]):
            v = o[:, j][o[:, j] != 0]
            if len(v) > 1:
                mu_o[j], sd_o[j] = v.mean(), v.std() + 1e-12
        self.mu_o, self.sd_o = mu_o, sd_o
        self.mu_s, self.sd_s = s.mean(0), s.std(0) + 1e-6
        self.mu_z, self.sd_z = z.mean(0), z.std(0) + 1e-6
        # The range of the standardised object values the network saw (see `net_object`).
        of = self.obj(o)
        self.lo_o, self.hi_o = of.min(0), of.max(0)

    def obj(self, o):
        return (o - self.mu_o) / self.sd_o * (o != 0)

    def sen(self, s):
        return (s - self.mu_s) / self.sd_s

    def net_object(self, of):
        """The network's object input: the standardised values clamped to the training range.
        Beyond it (larger cups than any trained on) the network keeps its value at the edge and
        only the linear Gaussian base extrapolates, instead of hidden units that saw no such
        input bending the latent."""
        return np.clip(of, self.lo_o, self.hi_o)


def init_params(d_in, d_out, rng, hidden=HIDDEN):
    def lin(i, o, scale=1.0):
        return rng.normal(0, scale / np.sqrt(i), (i, o))
    return {"W1": lin(d_in, hidden), "b1": np.zeros(hidden), "W2": lin(hidden, hidden),
            "b2": np.zeros(hidden), "W3": lin(hidden, d_out, 0.1), "b3": np.zeros(d_out),
            "Ws": lin(d_in, d_out, 0.1)}


def features(x, t, of, sf):
    ang = t[:, None] * freqs()[None, :]
    return np.concatenate([x, np.sin(ang), np.cos(ang), of, sf], axis=1)


def sig(a):
    return 1.0 / (1.0 + np.exp(-a))


def forward(p, h0):
    h1 = h0 @ p["W1"] + p["b1"]
    a1 = h1 * sig(h1)
    h2 = a1 @ p["W2"] + p["b2"]
    a2 = h2 * sig(h2)
    out = a2 @ p["W3"] + p["b3"] + h0 @ p["Ws"]
    return out, (h0, h1, a1, h2, a2)


def loss_grad(p, h0, target):
    out, (h0, h1, a1, h2, a2) = forward(p, h0)
    n = out.shape[0]
    diff = out - target
    loss = (diff ** 2).sum() / n
    g = 2.0 * diff / n
    grads = {"W3": a2.T @ g, "b3": g.sum(0), "Ws": h0.T @ g}
    da2 = g @ p["W3"].T
    s2 = sig(h2)
    dh2 = da2 * (s2 + h2 * s2 * (1 - s2))
    grads["W2"], grads["b2"] = a1.T @ dh2, dh2.sum(0)
    da1 = dh2 @ p["W2"].T
    s1 = sig(h1)
    dh1 = da1 * (s1 + h1 * s1 * (1 - s1))
    grads["W1"], grads["b1"] = h0.T @ dh1, dh1.sum(0)
    return loss, grads


def gradient_error():
    """The largest relative difference between the backward pass and finite differences on a
    small random problem (python/tests/test_train_projector.py holds it under 1e-6)."""
    rng = np.random.default_rng(0)
    p = init_params(5, 3, rng, hidden=7)
    p = {k: v + rng.normal(0, 0.3, v.shape) for k, v in p.items()}
    h0, target = rng.normal(size=(4, 5)), rng.normal(size=(4, 3))
    return gradient_check_error(loss_grad, p, h0, target)


def train(p, base, norm, x1, of, sf, steps, rng, batch=256, lr=2e-3):
    m = {k: np.zeros_like(v) for k, v in p.items()}
    v2 = {k: np.zeros_like(v) for k, v in p.items()}
    b1, b2, eps = 0.9, 0.999, 1e-8
    n = len(x1)
    losses = []
    for it in range(1, steps + 1):
        i = rng.integers(0, n, batch)
        y = x1[i]
        e = rng.normal(size=y.shape)
        t = rng.uniform(size=batch)
        xt = (1 - t[:, None]) * e + t[:, None] * y
        o = of[i] * (rng.uniform(size=batch) >= DROP_OBJECT)[:, None]
        h0 = features(xt, t, norm.net_object(o), sf[i])
        loss, g = loss_grad(p, h0, y - e - base(xt, t, o, sf[i]))
        lr_t = lr * 0.5 * (1 + np.cos(np.pi * it / steps))
        for k in p:
            m[k] = b1 * m[k] + (1 - b1) * g[k]
            v2[k] = b2 * v2[k] + (1 - b2) * g[k] ** 2
            mh, vh = m[k] / (1 - b1 ** it), v2[k] / (1 - b2 ** it)
            p[k] -= lr_t * mh / (np.sqrt(vh) + eps)
        losses.append(loss)
    return losses


class Base:
    """The exact velocity of a Gaussian target N(mu(c), diag sigma^2) whose mean is linear in the
    condition c = [object, sensor] (standardised) within each category: the features are
    [1, c] times each category's indicator, and [1, sensor] for the unconditional branch (no
    category: the dropout's rows); ridge of the latent on them (lambda by 5-fold
    cross-validation; the three intercepts are not shrunk, so each branch's mean is its rows'
    mean and not pulled toward the pooled one), sigma the residual spread per element (at least
    SIGMA_MIN). The network learns what is left."""

    def __init__(self, of, sf, y):
        # The sensor tokens' leading principal directions (the sensor's identity and its main
        # variations); the rest would be fitted noise with a few hundred objects.
        self.P = np.linalg.svd(sf - sf.mean(0), full_matrices=False)[2][:SENSOR_PCS].T
        n_full = 1 + (of.shape[1] - 2) + SENSOR_PCS
        self.intercepts = [0, n_full, 2 * n_full]
        of0 = np.zeros_like(of)
        x = np.r_[self.features(of, sf), self.features(of0, sf)]
        yy = np.r_[y, y]
        folds = np.arange(len(x)) % 5
        best = None
        for lam in [0.01, 0.1, 1.0, 10.0, 100.0]:
            err = 0.0
            for f in range(5):
                w = self.solve(x[folds != f], yy[folds != f], lam)
                err += ((x[folds == f] @ w - yy[folds == f]) ** 2).sum()
            if best is None or err < best[0]:
                best = (err, lam)
        self.lam = best[1]
        self.w = self.solve(x, yy, self.lam)
        r = y - self.features(of, sf) @ self.w
        self.sigma = np.maximum(np.sqrt((r ** 2).mean(0)), SIGMA_MIN)

    def solve(self, x, y, lam):
        reg = lam * np.eye(x.shape[1])
        reg[self.intercepts, self.intercepts] = 0.0
        return np.linalg.solve(x.T @ x + reg, x.T @ y)

    def features(self, of, sf):
        sf = sf @ self.P
        cats = of[:, :2]
        none = 1.0 - cats.sum(1, keepdims=True)
        one = np.ones((len(of), 1))
        full = np.c_[one, of[:, 2:], sf]
        return np.c_[cats[:, :1] * full, cats[:, 1:2] * full, none * np.c_[one, sf]]

    def mu(self, of, sf):
        return self.features(of, sf) @ self.w

    def __call__(self, x, t, of, sf):
        mu, s2, t = self.mu(of, sf), self.sigma ** 2, t[:, None]
        bt = (t * s2 - (1 - t)) / ((1 - t) ** 2 + t ** 2 * s2)
        return mu + bt * (x - t * mu)


def velocity(p, base, norm, x, t, o, s):
    """The exported model's function (x standardised, o and s raw)."""
    of, sf = norm.obj(o), norm.sen(s)
    return forward(p, features(x, t, norm.net_object(of), sf))[0] + base(x, t, of, sf)


# ---------------------------------------------------------------------------------------------
# Sampling, as crates/infer/src/flow.rs does it (splitmix64 + Box-Muller noise, guided Heun)
def noise(seed, n):
    mask = (1 << 64) - 1
    state = seed & mask
    out = []

    def nxt():
        nonlocal state
        state = (state + 0x9E3779B97F4A7C15) & mask
        z = state
        z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & mask
        z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & mask
        return ((z ^ (z >> 31)) >> 11) * (1.0 / (1 << 53))
    while len(out) < n:
        u1, u2 = max(nxt(), 1e-300), nxt()
        r = np.sqrt(-2.0 * np.log(u1))
        out += [r * np.cos(2 * np.pi * u2), r * np.sin(2 * np.pi * u2)]
    return np.array(out[:n], np.float32).astype(np.float64)


def sample_mean(p, base, norm, o, s, idx, seed0, guidance, steps=STEPS, k=SAMPLES):
    """Mean of k guided Heun samples for each row of (o, s), as the sampler stage draws them:
    sample j of the object at index i of its scene is seeded seed0 + i k + j."""
    n, d = len(o), len(norm.mu_z)
    xs = np.zeros((n, d))
    zero = np.zeros_like(o)
    h = 1.0 / steps
    for j in range(k):
        x = np.stack([noise(seed0 + int(i) * k + j, d) for i in idx])

        def g(x, tau):
            t = np.full(n, tau)
            vp = velocity(p, base, norm, x, t, zero, s)
            vc = velocity(p, base, norm, x, t, o, s)
            return vp + guidance * (vc - vp)
        for i in range(steps):
            tau = i * h
            k1 = g(x, tau)
            k2 = g(x + h * k1, tau + h)
            x = x + 0.5 * h * (k1 + k2)
        xs += x / k
    return norm.mu_z + norm.sd_z * xs


# ---------------------------------------------------------------------------------------------
# ONNX export
def export(p, base, norm, path):
    d = len(norm.mu_z)
    nodes = [
        helper.make_node("MatMul", ["t", "freqs"], ["ang"]),
        helper.make_node("Sin", ["ang"], ["sin"]),
        helper.make_node("Cos", ["ang"], ["cos"]),
        helper.make_node("Equal", ["object", "zero"], ["is0"]),
        helper.make_node("Not", ["is0"], ["nz"]),
        helper.make_node("Cast", ["nz"], ["mask"], to=TensorProto.FLOAT),
        helper.make_node("Sub", ["object", "mu_o"], ["o1"]),
        helper.make_node("Mul", ["o1", "inv_sd_o"], ["o2"]),
        helper.make_node("Mul", ["o2", "mask"], ["of"]),
        helper.make_node("Sub", ["sensor", "mu_s"], ["s1"]),
        helper.make_node("Mul", ["s1", "inv_sd_s"], ["sf"]),
        helper.make_node("Max", ["of", "lo_o"], ["of_lo"]),
        helper.make_node("Min", ["of_lo", "hi_o"], ["of_net"]),
        helper.make_node("Concat", ["x", "sin", "cos", "of_net", "sf"], ["h0"], axis=1),
        helper.make_node("MatMul", ["h0", "W1"], ["m1"]),
        helper.make_node("Add", ["m1", "b1"], ["h1"]),
        helper.make_node("Sigmoid", ["h1"], ["g1"]),
        helper.make_node("Mul", ["h1", "g1"], ["a1"]),
        helper.make_node("MatMul", ["a1", "W2"], ["m2"]),
        helper.make_node("Add", ["m2", "b2"], ["h2"]),
        helper.make_node("Sigmoid", ["h2"], ["g2"]),
        helper.make_node("Mul", ["h2", "g2"], ["a2"]),
        helper.make_node("MatMul", ["a2", "W3"], ["m3"]),
        helper.make_node("Add", ["m3", "b3"], ["o3"]),
        helper.make_node("MatMul", ["h0", "Ws"], ["lin"]),
        helper.make_node("Add", ["o3", "lin"], ["net"]),
        # The Gaussian base: features [cup * [1, vals, sf], fabric * [1, vals, sf],
        # none * [1, sf]] Wmu = mu; v_base = mu + b(t) (x - t mu).
        helper.make_node("Slice", ["of", "i0", "i1", "ax1"], ["is_cup"]),
        helper.make_node("Slice", ["of", "i1", "i2", "ax1"], ["is_fab"]),
        helper.make_node("Slice", ["of", "i2", "iend", "ax1"], ["vals"]),
        helper.make_node("Add", ["is_cup", "is_fab"], ["has"]),
        helper.make_node("Sub", ["one", "has"], ["none"]),
        helper.make_node("Mul", ["t", "zero"], ["t0"]),
        helper.make_node("Add", ["t0", "one"], ["ones"]),
        helper.make_node("MatMul", ["sf", "Psen"], ["spc"]),
        helper.make_node("Concat", ["ones", "vals", "spc"], ["full"], axis=1),
        helper.make_node("Concat", ["ones", "spc"], ["unc"], axis=1),
        helper.make_node("Mul", ["is_cup", "full"], ["f_cup"]),
        helper.make_node("Mul", ["is_fab", "full"], ["f_fab"]),
        helper.make_node("Mul", ["none", "unc"], ["f_none"]),
        helper.make_node("Concat", ["f_cup", "f_fab", "f_none"], ["cf"], axis=1),
        helper.make_node("MatMul", ["cf", "Wmu"], ["mu"]),
        helper.make_node("Mul", ["t", "mu"], ["tmu"]),
        helper.make_node("Sub", ["x", "tmu"], ["xm"]),
        helper.make_node("Sub", ["one", "t"], ["omt"]),
        helper.make_node("Mul", ["t", "s2"], ["ts2"]),
        helper.make_node("Sub", ["ts2", "omt"], ["num"]),
        helper.make_node("Mul", ["omt", "omt"], ["omt2"]),
        helper.make_node("Mul", ["t", "t"], ["t2"]),
        helper.make_node("Mul", ["t2", "s2"], ["t2s2"]),
        helper.make_node("Add", ["omt2", "t2s2"], ["den"]),
        helper.make_node("Div", ["num", "den"], ["bt"]),
        helper.make_node("Mul", ["bt", "xm"], ["bx"]),
        helper.make_node("Add", ["mu", "bx"], ["vb"]),
        helper.make_node("Add", ["net", "vb"], ["v"]),
    ]
    inits = [init("freqs", freqs()[None, :]), init("zero", [0.0]), init("mu_o", norm.mu_o),
             init("inv_sd_o", 1.0 / norm.sd_o), init("mu_s", norm.mu_s), init("inv_sd_s", 1.0 / norm.sd_s),
             init("lo_o", norm.lo_o[None, :]), init("hi_o", norm.hi_o[None, :])]
    inits += [init(k, v) for k, v in p.items()]
    inits += [init("Wmu", base.w), init("Psen", base.P), init("s2", base.sigma ** 2), init("one", [1.0])]
    inits += [numpy_helper.from_array(np.array([v], np.int64), n)
              for n, v in [("i0", 0), ("i1", 1), ("i2", 2), ("iend", len(FIELDS)), ("ax1", 1)]]
    g = helper.make_graph(
        nodes, "unitac_touch_projector",
        [helper.make_tensor_value_info("x", TensorProto.FLOAT, ["batch", d]),
         helper.make_tensor_value_info("t", TensorProto.FLOAT, ["batch", 1]),
         helper.make_tensor_value_info("object", TensorProto.FLOAT, ["batch", len(FIELDS)]),
         helper.make_tensor_value_info("sensor", TensorProto.FLOAT, ["batch", len(norm.mu_s)])],
        [helper.make_tensor_value_info("v", TensorProto.FLOAT, ["batch", d])], inits)
    m = helper.make_model(g, opset_imports=[helper.make_opsetid("", OPSET)], producer_name="unitac-projector")
    m.ir_version = 9
    onnx.checker.check_model(m)
    onnx.save(m, path)


# ---------------------------------------------------------------------------------------------
# Readouts
def ridge_fit(x, y, lam):
    mu, sd = x.mean(0), x.std(0) + 1e-9
    a = np.c_[(x - mu) / sd, np.ones(len(x))]
    reg = lam * np.eye(a.shape[1])
    reg[-1, -1] = 0
    coef = np.linalg.solve(a.T @ a + reg, a.T @ y)
    return lambda q: np.c_[(q - mu) / sd, np.ones(len(q))] @ coef, (mu, sd, coef)


def ridge_cv(x, y, groups):
    """lambda by leave-one-group-out; returns (predictor, lambda, cv rmse of exp(.))."""
    best = None
    for lam in LAMBDAS:
        err = []
        for gv in np.unique(groups):
            tr, te = groups != gv, groups == gv
            f, _ = ridge_fit(x[tr], y[tr], lam)
            err.append((np.exp(f(x[te])) - np.exp(y[te])) ** 2)
        e = float(np.sqrt(np.concatenate(err).mean()))
        if best is None or e < best[1]:
            best = (lam, e)
    f, parts = ridge_fit(x, y, best[0])
    return f, parts, best[0], best[1]


def rmse(a, b):
    return float(np.sqrt(((np.asarray(a) - np.asarray(b)) ** 2).mean()))


def stiffness(f, x):
    """k [N/m] from a log-k readout, clamped to the exported readout's range."""
    return np.clip(np.exp(f(x)), K_MIN, K_MAX)


def export_stiffness(parts, d, out_dir, name, fit, cups):
    """Policy bundle (crates/policy/src/onnx): k = exp(w . (z - mu) / sd + b), clamped; with
    latents.json, the mean and spread of the training cups' pooled latents (for tests that need
    latents like them)."""
    mu, sd, coef = parts
    w = coef[:-1] / sd
    b = coef[-1] - (mu / sd) @ coef[:-1]
    os.makedirs(out_dir, exist_ok=True)
    nodes = [
        helper.make_node("MatMul", [schema.STIFFNESS_INPUT, "w"], ["m"]),
        helper.make_node("Add", ["m", "b"], ["logk"]),
        helper.make_node("Exp", ["logk"], ["k"]),
        helper.make_node("Clip", ["k", "lo", "hi"], ["kc"]),
        helper.make_node("Reshape", ["kc", "shape"], [schema.OUTPUT]),
    ]
    g = helper.make_graph(
        nodes, name,
        [helper.make_tensor_value_info(schema.STIFFNESS_INPUT, TensorProto.FLOAT, ["batch", d])],
        [helper.make_tensor_value_info(schema.OUTPUT, TensorProto.FLOAT, ["batch", 1, 1])],
        [init("w", w[:, None]), init("b", [b]), init("lo", K_MIN), init("hi", K_MAX),
         numpy_helper.from_array(np.array([-1, 1, 1], np.int64), "shape")])
    m = helper.make_model(g, opset_imports=[helper.make_opsetid("", OPSET)], producer_name="unitac-projector")
    m.ir_version = 9
    onnx.checker.check_model(m)
    onnx.save(m, os.path.join(out_dir, schema.ONNX_FILE))
    schema.write_policy_manifest(
        out_dir, name,
        "cup stiffness [N/m] from the pooled tactile latent [2, 48] (token mean, token mean of "
        f"squares): ridge of log k (lambda {fit['lambda']:g}) on the touch encoder's latents of "
        f"{fit['train_cups']} training cups (python/unitac_tools/train_projector.py); reads real or predicted "
        "latents of that form",
        30.0, [{"name": schema.STIFFNESS_INPUT, "shape": ["batch", d], "normalization": {"mode": "identity"}}],
        schema.stiffness_actions(), {"mode": "identity"})
    with open(os.path.join(out_dir, "latents.json"), "w") as f:
        json.dump({"mean": cups.mean(0).tolist(), "std": cups.std(0).tolist(), "count": len(cups)}, f)


def property_head(ref_dir):
    m = onnx.load(os.path.join(ref_dir, "properties.onnx"))
    w = {i.name: numpy_helper.to_array(i).astype(np.float64) for i in m.graph.initializer}
    return lambda z: z @ w["w"] + w["b"]


# ---------------------------------------------------------------------------------------------
def fit(rows, steps, seed):
    """Train the projector on `rows`: (network, Gaussian base, normalisation, losses)."""
    o, s, z = arrays(rows)
    norm = Norm(o, s, z)
    y = (z - norm.mu_z) / norm.sd_z
    of, sf = norm.obj(o), norm.sen(s)
    base = Base(of, sf, y)
    rng = np.random.default_rng(seed)
    p = init_params(z.shape[1] + 2 * N_FREQ + len(FIELDS) + s.shape[1], z.shape[1], rng)
    losses = train(p, base, norm, y, of, sf, steps, rng)
    return p, base, norm, losses


def index(rows):
    """Each row's object index in its scene's sampler (`objects` order): seeds follow it."""
    return np.array([1 if r["object"].endswith("_b") else 0 for r in rows])


def stiffness_readout(rows):
    """Ridge of log k on the encoder's pooled latents of the cups in `rows` (lambda by
    leave-one-size-out)."""
    cups = [r for r in rows if r["category"] == "cup"]
    z = np.array([r["latent"] for r in cups])
    k = np.array([r["truth"]["stiffness_n_per_m"] for r in cups])
    size_bin = np.array([int(r["truth"]["diameter_m"] * 1e3 // 4) for r in cups])
    return ridge_cv(z, np.log(k), size_bin)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--train", nargs="+")
    ap.add_argument("--unseen", nargs="+")
    ap.add_argument("--reference")
    ap.add_argument("--out")
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args()
    if not (a.train and a.unseen and a.reference and a.out):
        ap.error("--train, --unseen, --reference and --out are needed")
    tr, un = load(a.train), load(a.unseen)
    o, s, z = arrays(tr)
    d = z.shape[1]

    # The guidance scale, chosen on the training split only: fit without the training cups of
    # the largest quarter of sizes (the unseen cups are larger than every training cup), read
    # those cups' stiffness from predicted latents at each scale.
    diameter = lambda r: r["truth"]["diameter_m"]
    edge = np.quantile([diameter(r) for r in tr if r["category"] == "cup"], 0.75)
    held = lambda r: r["category"] == "cup" and diameter(r) >= edge
    fit_rows = [r for r in tr if not held(r)]
    val_rows = [r for r in tr if held(r)]
    vp, vbase, vnorm, _ = fit(fit_rows, a.steps, a.seed)
    f_val = stiffness_readout(fit_rows)[0]
    vo, vs, _ = arrays(val_rows)
    k_val = np.array([r["truth"]["stiffness_n_per_m"] for r in val_rows])
    validation = {"heldout_from_diameter_m": float(edge), "cups": len(val_rows)}
    for g in GUIDANCE_GRID:
        zv = sample_mean(vp, vbase, vnorm, vo, vs, index(val_rows), 3, guidance=g)
        validation[str(g)] = rmse(stiffness(f_val, zv), k_val)
    guidance = float(min(GUIDANCE_GRID, key=lambda g: (validation[str(g)], abs(g - 1.5))))

    p, base, norm, losses = fit(tr, a.steps, a.seed)
    os.makedirs(a.out, exist_ok=True)
    vel = os.path.join(a.out, "velocity.onnx")
    export(p, base, norm, vel)
    shutil.copy(os.path.join(a.reference, "encoder.onnx"), os.path.join(a.out, "encoder.onnx"))
    ref = json.load(open(os.path.join(a.reference, "manifest.json")))

    # The trainer's outputs on probe inputs, and ONNX Runtime's on the same (agreement).
    import onnxruntime as ort
    pr = np.random.default_rng(1)
    idx = pr.integers(0, len(o), 6)
    probe = {"x": pr.normal(size=(6, d)), "t": pr.uniform(size=6), "object": o[idx] * (np.arange(6) % 3 != 0)[:, None],
             "sensor": s[idx]}
    # One object beyond every training value (the network's clamp).
    probe["object"][5, 2:] = np.where(probe["object"][5, 2:] != 0, 1.5 * np.abs(o[:, 2:]).max(0), 0.0)
    want = velocity(p, base, norm, probe["x"], probe["t"], probe["object"], probe["sensor"])
    sess = ort.InferenceSession(vel, providers=["CPUExecutionProvider"])
    got = sess.run(["v"], {"x": probe["x"].astype(np.float32), "t": probe["t"][:, None].astype(np.float32),
                           "object": probe["object"].astype(np.float32),
                           "sensor": probe["sensor"].astype(np.float32)})[0]
    ort_err = float(np.abs(got - want).max() / (np.abs(want).max() + 1e-12))
    if ort_err > 1e-4:
        raise SystemExit(f"ONNX Runtime and the trainer disagree: relative error {ort_err:.2e}")
    with open(os.path.join(a.out, "check.json"), "w") as f:
        json.dump({k: np.asarray(v).tolist() for k, v in probe.items()} | {"v": want.tolist()}, f)

    # Held-out evaluation at the chosen guidance, and the sweep beside it.
    uo, us, uz = arrays(un)
    cats = lambda rows, c: np.array([r["category"] == c for r in rows])
    ctr, cun, fun = cats(tr, "cup"), cats(un, "cup"), cats(un, "fabric")
    cups_un = [r for r in un if r["category"] == "cup"]
    k_tr = np.array([r["truth"]["stiffness_n_per_m"] for r in tr if r["category"] == "cup"])
    k_un = np.array([r["truth"]["stiffness_n_per_m"] for r in cups_un])
    f_lat, parts, lam_lat, cv_lat = stiffness_readout(tr)
    size_bin = np.array([int(r["truth"]["diameter_m"] * 1e3 // 4) for r in tr if r["category"] == "cup"])
    cond = lambda oo, ss: np.c_[oo, ss]
    f_cond, _, lam_cond, _ = ridge_cv(cond(o, s)[ctr], np.log(k_tr), size_bin)
    head = property_head(a.reference)
    fab = [r for r in un if r["category"] == "fabric"]
    truth = np.array([r["truth"]["roughness_ra_m"] for r in fab])
    key = [(r["sensor"], r["seed"], r["trial"]) for r in fab]
    pairs = [(i, j) for i in range(len(fab)) for j in range(i + 1, len(fab)) if key[i] == key[j]]

    def ranked(v, sel=None):
        right = [(truth[i] > truth[j]) == (v[i] > v[j]) if v[i] != v[j] else 0.5
                 for i, j in pairs if sel is None or fab[i]["sensor"] == sel]
        return float(np.mean(right)) if right else float("nan")

    # Roughness readouts: the reference property head, and a ridge fitted on the encoder's
    # pooled latents of the TRAINING fabrics (lambda by leave-one-seed-out).
    ftr = [r for r in tr if r["category"] == "fabric"]
    ra_tr = np.array([r["truth"]["roughness_ra_m"] for r in ftr])
    seed_tr = np.array([r["seed"] for r in ftr])
    f_rough = ridge_cv(np.array([r["latent"] for r in ftr]), ra_tr, seed_tr)[0]
    readouts = {"property_head": lambda zz: head(zz)[:, 1], "ridge_on_encoder_latents": f_rough}
    # The learned camera-only baseline: a ridge from the same condition straight to roughness.
    f_rough_cond = ridge_cv(cond(o, s)[cats(tr, "fabric")], ra_tr, seed_tr)[0]

    def ranked_both_orders(o_rows, g):
        """Pair accuracy of predicted latents with the two fabrics' sampler seeds in both
        assignments, averaged: the scene's object order (fabric_a first) fixes which seeds each
        fabric gets, so one assignment alone ranks by seed as much as by fabric (a branch that
        ignores the object would score the share of pairs where fabric_a is the rougher)."""
        zs = [sample_mean(p, base, norm, o_rows, us[fun], idx, 3, guidance=g)
              for idx in (index(fab), 1 - index(fab))]
        return {name: float(np.mean([ranked(f(z)) for z in zs])) for name, f in readouts.items()}
    zero_c, zero_f = np.zeros_like(uo[cun]), np.zeros_like(uo[fun])
    sweep = []
    for g in GUIDANCE_GRID:
        zp_cup = sample_mean(p, base, norm, uo[cun], us[cun], index(cups_un), 3, guidance=g)
        sweep.append({"guidance": g, "stiffness_rmse_n_per_m": rmse(stiffness(f_lat, zp_cup), k_un),
                      "fabric_pair_accuracy": ranked_both_orders(uo[fun], g)})
    at = next(r for r in sweep if r["guidance"] == guidance)
    zu_cup = sample_mean(p, base, norm, zero_c, us[cun], index(cups_un), 3, guidance=1.0)
    stiff = {
        "heldout_cups": int(cun.sum()),
        "heldout_stiffness_mean_n_per_m": float(k_un.mean()),
        "readout_lambda": lam_lat, "readout_cv_rmse_n_per_m": cv_lat,
        "rmse_readout_on_encoder_latents": rmse(stiffness(f_lat, uz[cun]), k_un),
        "rmse_readout_on_predicted_latents": at["stiffness_rmse_n_per_m"],
        "rmse_readout_on_sensor_only_branch": rmse(stiffness(f_lat, zu_cup), k_un),
        "rmse_ridge_condition_to_stiffness": rmse(stiffness(f_cond, cond(uo, us)[cun]), k_un),
        "ridge_condition_lambda": lam_cond,
        "rmse_training_mean": rmse(np.full_like(k_un, k_tr.mean()), k_un),
    }
    stiff["predicted_over_ridge"] = stiff["rmse_readout_on_predicted_latents"] / stiff["rmse_ridge_condition_to_stiffness"]
    stiff["predicted_over_training_mean"] = stiff["rmse_readout_on_predicted_latents"] / stiff["rmse_training_mean"]
    camera = np.array([r["visual"].get("roughness", np.nan) for r in fab])
    sensors = sorted({r["sensor"] for r in fab})
    fabrics = {
        "heldout_pairs": len(pairs),
        "share_fabric_a_rougher": float(np.mean([truth[i] > truth[j] for i, j in pairs])),
        "camera": ranked(camera),
        "ridge_condition_to_roughness": ranked(f_rough_cond(cond(uo, us)[fun])),
        "predicted_both_orders": at["fabric_pair_accuracy"],
        "sensor_only_branch_both_orders": ranked_both_orders(zero_f, 1.0),
        "encoder_live_touch": {name: ranked(f(uz[fun])) for name, f in readouts.items()},
        "encoder_live_touch_by_sensor": {name: {sen: ranked(f(uz[fun]), sen) for sen in sensors}
                                         for name, f in readouts.items()},
    }
    report = {"train_samples": len(tr), "unseen_samples": len(un), "steps": a.steps, "final_loss": float(np.mean(losses[-100:])),
              "onnx_relative_error": ort_err, "guidance": guidance, "guidance_validation_rmse_n_per_m": validation,
              "solver": "heun", "solver_steps": STEPS, "samples": SAMPLES, "sigma_min": SIGMA_MIN,
              "stiffness": stiff, "fabrics": fabrics, "guidance_sweep_heldout": sweep}

    manifest = {
        "bundle": "unitac-touch-projector",
        "version": "0.1.0",
        "description": "Touch projector trained by python/unitac_tools/train_projector.py on mock-world objects of the training "
                       "split: predicted pooled touch latents [2, 48] from the object-level (category, camera) and "
                       "sensor-level (sensor tokens) condition, with the reference encoder for the sensor tokens.",
        "preprocess": ref["preprocess"],
        "latent": {"tokens": 2, "dim": d // 2, "sampler_dim": d, "cond_dim": len(FIELDS) + s.shape[1]},
        "properties": ref["properties"],
        "sensor_tokens": ref.get("sensor_tokens", {}),
        "models": {
            "encoder": ref["models"]["encoder"],
            "velocity": entry(a.out, "velocity.onnx", time_convention="tau_data_at_1", sigma_min=SIGMA_MIN,
                              condition=[{"input": "object", "source": "object", "fields": FIELDS},
                                         {"input": "sensor", "source": "sensor_tokens"}],
                              latent_offset=norm.mu_z.tolist(), latent_scale=norm.sd_z.tolist(),
                              latent_shape=[2, d // 2], fit=report),
        },
    }
    with open(os.path.join(a.out, "manifest.json"), "w") as f:
        json.dump(manifest, f, indent=2, sort_keys=True)
    export_stiffness(parts, d, os.path.join(a.out, "stiffness"), "cup_stiffness_pooled",
                     {"lambda": lam_lat, "cv_rmse_n_per_m": cv_lat, "train_cups": int(ctr.sum())}, z[ctr])
    with open(os.path.join(a.out, "eval.json"), "w") as f:
        json.dump(report, f, indent=2)
    print(json.dumps(report, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
