"""Generate the REFERENCE model bundle of the UniTac robot stack (not UniTac's weights, which are
not public): small ONNX models that run through the same code path as a real exported bundle.

  encoder.onnx           touch encoder: a tactile clip and the non-contact frame -> latent tokens
                         (object level, from the clip minus the background) and sensor tokens (from
                         the background). Weights are FIXED, not learned: an 8x8 DCT patch basis on
                         luminance and two colour-opponent channels, log-magnitude, then a seeded
                         random orthogonal mixing. Patch embedding + two layers, about 60 kB.
  properties.onnx        property head: mean and mean-square of the tokens -> hardness, roughness,
                         texture scores (0..1) and their one-sigma uncertainty. Weights FITTED by
                         ridge regression on mock-sensor presses with known properties
                         (`unitac-lab dataset fabrics`), uncertainty from held-out residuals.
  velocity_gaussian.onnx the exact rectified-flow velocity of a Gaussian target N(mu, sigma^2 I)
                         whose cond rows encode [mu (D), log sigma]: a model with an exact solution,
                         so sampler error can be measured exactly (../shared notes: flow sampler).
  velocity_timing_fixture.onnx  a small transformer velocity model (2 blocks, width 32, seeded random
                         weights, final LayerNorm): the shape of the paper's DiT projector, for
                         timing and for error against a fine-step reference.
  manifest.json          the bundle manifest the Rust loader checks every model against.

usage: python -m unitac_tools.generate_reference OUT_DIR [--data DATA_DIR]
Without --data only the models that need no fitting are written (and no manifest).
"""
import argparse
import json
import os
import sys

import numpy as np
import onnx
from onnx import TensorProto, helper, numpy_helper

# The file hash of every bundle manifest (one helper with the policy manifests').
from .schema import sha256

OPSET = 20
SIZE = 64          # encoder input side (pixels)
PATCH = 8          # patch side
T = 4              # clip frames
D_TOK = 48         # token width
CROP = 128         # centre square taken from the frame before resizing to SIZE
D_LAT = 64         # sampler latent size (8 x 8)
COND = 2 * D_TOK + 1
SIGMA_MIN = 0.1    # smallest target sigma the velocity models are declared for


def init(name, arr):
    return numpy_helper.from_array(np.asarray(arr, dtype=np.float32), name)


def i64(name, vals):
    return numpy_helper.from_array(np.asarray(vals, dtype=np.int64), name)


def save(model, path):
    onnx.checker.check_model(model)
    onnx.save(model, path)


def model(graph):
    m = helper.make_model(graph, opset_imports=[helper.make_opsetid("", OPSET)],
                          producer_name="unitac-reference")
    m.ir_version = 9
    return m


# ---------------------------------------------------------------------------------------------
# Encoder
def dct_basis():
    k = np.arange(PATCH)
    c = np.stack([np.cos(np.pi * (2 * k + 1) * u / (2 * PATCH)) for u in range(4)])  # 4 x 8
    basis = np.einsum("ux,vy->uvxy", c, c).reshape(16, PATCH, PATCH)
    basis /= np.linalg.norm(basis.reshape(16, -1), axis=1)[:, None, None]
    return basis


def encoder_weights():
    rng = np.random.default_rng(20261122)
    basis = dct_basis()
    colour = np.array([[1, 1, 1], [1, 0, -1], [-0.5, 1, -0.5]], dtype=np.float64)
    colour /= np.linalg.norm(colour, axis=1)[:, None]
    w1 = np.einsum("cq,fxy->cfqxy", colour, basis).reshape(48, 3, PATCH, PATCH)
    q, _ = np.linalg.qr(rng.standard_normal((48, 48)))
    w2 = q[:D_TOK].reshape(D_TOK, 48, 1, 1)  # orthogonal: the band energies stay recoverable
    return w1.astype(np.float32), w2.astype(np.float32)


def build_encoder(path):
    w1, w2 = encoder_weights()
    n_p = (SIZE // PATCH) ** 2
    nodes = [
        # Object level: the clip minus the background.
        helper.make_node("Unsqueeze", ["background", "ax1"], ["bg5"]),
        helper.make_node("Sub", ["clip", "bg5"], ["diff"]),
        helper.make_node("Reshape", ["diff", "shape_frames"], ["frames"]),
        helper.make_node("Conv", ["frames", "w1"], ["patches"], strides=[PATCH, PATCH]),
        helper.make_node("Abs", ["patches"], ["mag"]),
        helper.make_node("Mul", ["mag", "gain"], ["magg"]),
        helper.make_node("Add", ["magg", "onef"], ["mag1"]),
        helper.make_node("Log", ["mag1"], ["energy"]),
        helper.make_node("Conv", ["energy", "w2"], ["mixed"]),
        helper.make_node("Shape", ["clip"], ["clip_shape"]),
        helper.make_node("Slice", ["clip_shape", "s0", "s2", "s0"], ["nt"]),
        helper.make_node("Concat", ["nt", "tok_tail"], ["shape_ntdp"], axis=0),
        helper.make_node("Reshape", ["mixed", "shape_ntdp"], ["ntdp"]),
        helper.make_node("ReduceMean", ["ntdp", "ax1"], ["ndp"], keepdims=0),
        helper.make_node("Transpose", ["ndp"], ["tokens"], perm=[0, 2, 1]),
        # Sensor level: the background itself, pooled over the four image quadrants.
        helper.make_node("Conv", ["background", "w1"], ["bpatches"], strides=[PATCH, PATCH]),
        helper.make_node("Abs", ["bpatches"], ["bmag"]),
        helper.make_node("Mul", ["bmag", "gain"], ["bmagg"]),
        helper.make_node("Add", ["bmagg", "onef"], ["bmag1"]),
        helper.make_node("Log", ["bmag1"], ["benergy"]),
        helper.make_node("Conv", ["benergy", "w2"], ["bmixed"]),
        helper.make_node("AveragePool", ["bmixed"], ["bq"], kernel_shape=[4, 4], strides=[4, 4]),
        helper.make_node("Reshape", ["bq", "shape_sen"], ["bq3"]),
        helper.make_node("Transpose", ["bq3"], ["sensor_tokens"], perm=[0, 2, 1]),
    ]
    g = helper.make_graph(
        nodes, "unitac_reference_encoder",
        [helper.make_tensor_value_info("clip", TensorProto.FLOAT, ["batch", T, 3, SIZE, SIZE]),
         helper.make_tensor_value_info("background", TensorProto.FLOAT, ["batch", 3, SIZE, SIZE])],
        [helper.make_tensor_value_info("tokens", TensorProto.FLOAT, ["batch", n_p, D_TOK]),
         helper.make_tensor_value_info("sensor_tokens", TensorProto.FLOAT, ["batch", 4, D_TOK])],
        [init("w1", w1), init("w2", w2), init("gain", [10.0]), init("onef", [1.0]), i64("ax1", [1]), i64("shape_frames", [-1, 3, SIZE, SIZE]),
         i64("s0", [0]), i64("s2", [2]), i64("tok_tail", [D_TOK, n_p]), i64("shape_sen", [-1, D_TOK, 4])])
    save(model(g), path)


# ---------------------------------------------------------------------------------------------
# Property head
def head_features(tokens):
    return np.concatenate([tokens.mean(axis=1), (tokens ** 2).mean(axis=1)], axis=1)


def build_properties(path, w, b, std):
    nodes = [
        helper.make_node("ReduceMean", ["tokens", "ax1"], ["m"], keepdims=0),
        helper.make_node("Mul", ["tokens", "tokens"], ["sq"]),
        helper.make_node("ReduceMean", ["sq", "ax1"], ["m2"], keepdims=0),
        helper.make_node("Concat", ["m", "m2"], ["feat"], axis=1),
        helper.make_node("MatMul", ["feat", "w"], ["lin"]),
        helper.make_node("Add", ["lin", "b"], ["scores"]),
        helper.make_node("Mul", ["scores", "zero"], ["z"]),
        helper.make_node("Add", ["z", "std"], ["scores_std"]),
    ]
    g = helper.make_graph(
        nodes, "unitac_reference_properties",
        [helper.make_tensor_value_info("tokens", TensorProto.FLOAT, ["batch", (SIZE // PATCH) ** 2, D_TOK])],
        [helper.make_tensor_value_info("scores", TensorProto.FLOAT, ["batch", 3]),
         helper.make_tensor_value_info("scores_std", TensorProto.FLOAT, ["batch", 3])],
        [init("w", w), init("b", b), init("std", std), init("zero", [0.0]), i64("ax1", [1])])
    save(model(g), path)


def fit_properties(enc_path, data_dir, out_path):
    import onnxruntime as ort
    meta = json.load(open(os.path.join(data_dir, "meta.json")))
    n, t, s = meta["count"], meta["clip_frames"], meta["size"]
    assert (t, s, meta["crop_size"]) == (T, SIZE, CROP), "dataset preprocessing differs from the encoder's"
    clips = np.fromfile(os.path.join(data_dir, "clips.f32"), np.float32).reshape(n, t, 3, s, s)
    bgs = np.fromfile(os.path.join(data_dir, "backgrounds.f32"), np.float32).reshape(n, 3, s, s)
    labels = [json.loads(l) for l in open(os.path.join(data_dir, "labels.jsonl"))]
    y = np.array([[l["hardness"], l["roughness"], l["texture"]] for l in labels], np.float64)
    split = np.array([l["split"] for l in labels])
    sess = ort.InferenceSession(enc_path, providers=["CPUExecutionProvider"])
    tokens = np.concatenate([sess.run(["tokens"], {"clip": clips[i:i + 32], "background": bgs[i:i + 32]})[0]
                             for i in range(0, n, 32)])
    x = head_features(tokens.astype(np.float64))
    tr, va = split == "train", split == "test"
    mu, sd = x[tr].mean(0), x[tr].std(0) + 1e-9
    xs = (x - mu) / sd
    best = None
    for lam in [1e-3, 1e-2, 1e-1, 1, 10, 100]:
        a = np.c_[xs[tr], np.ones(tr.sum())]
        coef = np.linalg.solve(a.T @ a + lam * np.eye(a.shape[1]), a.T @ y[tr])
        pred = np.c_[xs[va], np.ones(va.sum())] @ coef
        err = np.sqrt(((pred - y[va]) ** 2).mean())
        if best is None or err < best[0]:
            best = (err, lam, coef, pred)
    err, lam, coef, pred = best
    # Fold the standardisation into the weights: scores = x @ w + b.
    w = coef[:-1] / sd[:, None]
    b = coef[-1] - (mu / sd) @ coef[:-1]
    std = np.sqrt(((pred - y[va]) ** 2).mean(axis=0))
    build_properties(out_path, w.astype(np.float32), b.astype(np.float32), std.astype(np.float32))
    # Pairwise ranking on held-out fabrics (reported; the Rust test checks the same thing).
    r_true, r_pred = y[va][:, 1], pred[:, 1]
    i, j = np.triu_indices(len(r_true), 1)
    sel = np.abs(r_true[i] - r_true[j]) > 0.1
    acc = float(((r_true[i] > r_true[j]) == (r_pred[i] > r_pred[j]))[sel].mean())
    return {"ridge_lambda": lam, "heldout_rmse": [float(v) for v in std], "heldout_pairs": int(sel.sum()),
            "heldout_roughness_pair_accuracy": acc, "train": int(tr.sum()), "test": int(va.sum())}


# ---------------------------------------------------------------------------------------------
# Velocity models (tau = 0 noise, tau = 1 data; output = d x / d tau)
def build_velocity_gaussian(path):
    """v = mu + b(t) (x - t mu), b = (t s^2 - (1 - t)) / ((1-t)^2 + t^2 s^2), s = exp(cond[:, D])."""
    nodes = [
        helper.make_node("Slice", ["cond", "z0", "zD", "one"], ["mu"]),
        helper.make_node("Slice", ["cond", "zD", "zD1", "one"], ["logs"]),
        helper.make_node("Mul", ["logs", "two"], ["log_s2"]),
        helper.make_node("Exp", ["log_s2"], ["s2"]),
        helper.make_node("Sub", ["onef", "t"], ["omt"]),
        helper.make_node("Mul", ["t", "s2"], ["ts2"]),
        helper.make_node("Sub", ["ts2", "omt"], ["num"]),
        helper.make_node("Mul", ["omt", "omt"], ["omt2"]),
        helper.make_node("Mul", ["t", "t"], ["t2"]),
        helper.make_node("Mul", ["t2", "s2"], ["t2s2"]),
        helper.make_node("Add", ["omt2", "t2s2"], ["den"]),
        helper.make_node("Div", ["num", "den"], ["bt"]),
        helper.make_node("Mul", ["t", "mu"], ["tmu"]),
        helper.make_node("Sub", ["x", "tmu"], ["xr"]),
        helper.make_node("Mul", ["bt", "xr"], ["bx"]),
        helper.make_node("Add", ["mu", "bx"], ["v"]),
    ]
    g = helper.make_graph(
        nodes, "unitac_velocity_gaussian",
        [helper.make_tensor_value_info("x", TensorProto.FLOAT, ["batch", D_LAT]),
         helper.make_tensor_value_info("t", TensorProto.FLOAT, ["batch", 1]),
         helper.make_tensor_value_info("cond", TensorProto.FLOAT, ["batch", D_LAT + 1])],
        [helper.make_tensor_value_info("v", TensorProto.FLOAT, ["batch", D_LAT])],
        [i64("z0", [0]), i64("zD", [D_LAT]), i64("zD1", [D_LAT + 1]), i64("one", [1]),
         init("two", [2.0]), init("onef", [1.0])])
    save(model(g), path)


def build_velocity_dit(path):
    rng = np.random.default_rng(7)
    W, L, P = 32, 8, 8  # width, tokens, values per token
    # Time embedding frequencies up to 4 pi: a trained flow model is smooth in tau; random weights
    # with the usual 2^k frequencies would make the field oscillate hundreds of times over [0, 1].
    def lin(i, o, scale=1.0):
        return (rng.standard_normal((i, o)) * scale / np.sqrt(i)).astype(np.float32)
    inits = [init("w_in", lin(P, W)), init("w_t", lin(16, W)), init("w_c", lin(COND, W, 0.5)),
             init("freqs", (np.pi * 0.5 * np.arange(1, 9)).reshape(1, 8)), init("w_out", lin(W, P, 0.5)),
             init("scale", [1.0 / np.sqrt(W)]), i64("shape_tok", [-1, L, P]), i64("shape_out", [-1, D_LAT]),
             i64("ax1", [1]), init("ln_g", np.ones(W)), init("ln_b", np.zeros(W))]
    nodes = [
        helper.make_node("Reshape", ["x", "shape_tok"], ["xt"]),
        helper.make_node("MatMul", ["xt", "w_in"], ["h0"]),
        helper.make_node("MatMul", ["t", "freqs"], ["tf"]),
        helper.make_node("Sin", ["tf"], ["ts"]),
        helper.make_node("Cos", ["tf"], ["tc"]),
        helper.make_node("Concat", ["ts", "tc"], ["temb"], axis=1),
        helper.make_node("MatMul", ["temb", "w_t"], ["te"]),
        helper.make_node("MatMul", ["cond", "w_c"], ["ce"]),
        helper.make_node("Add", ["te", "ce"], ["tce"]),
        helper.make_node("Unsqueeze", ["tce", "ax1"], ["tce3"]),
        helper.make_node("Add", ["h0", "tce3"], ["h_0"]),
    ]
    h = "h_0"
    for k in range(2):
        for nm, sh in [("q", (W, W)), ("k", (W, W)), ("v", (W, W)), ("o", (W, W)), ("m1", (W, 2 * W)), ("m2", (2 * W, W))]:
            inits.append(init(f"{nm}{k}", lin(*sh)))
        nodes += [
            helper.make_node("LayerNormalization", [h, "ln_g", "ln_b"], [f"a{k}"], axis=-1),
            helper.make_node("MatMul", [f"a{k}", f"q{k}"], [f"Q{k}"]),
            helper.make_node("MatMul", [f"a{k}", f"k{k}"], [f"K{k}"]),
            helper.make_node("MatMul", [f"a{k}", f"v{k}"], [f"V{k}"]),
            helper.make_node("Transpose", [f"K{k}"], [f"Kt{k}"], perm=[0, 2, 1]),
            helper.make_node("MatMul", [f"Q{k}", f"Kt{k}"], [f"S{k}"]),
            helper.make_node("Mul", [f"S{k}", "scale"], [f"Ss{k}"]),
            helper.make_node("Softmax", [f"Ss{k}"], [f"A{k}"], axis=-1),
            helper.make_node("MatMul", [f"A{k}", f"V{k}"], [f"AV{k}"]),
            helper.make_node("MatMul", [f"AV{k}", f"o{k}"], [f"O{k}"]),
            helper.make_node("Add", [h, f"O{k}"], [f"r{k}"]),
            helper.make_node("LayerNormalization", [f"r{k}", "ln_g", "ln_b"], [f"b{k}"], axis=-1),
            helper.make_node("MatMul", [f"b{k}", f"m1{k}"], [f"M1{k}"]),
            helper.make_node("Tanh", [f"M1{k}"], [f"G{k}"]),
            helper.make_node("MatMul", [f"G{k}", f"m2{k}"], [f"M2{k}"]),
            helper.make_node("Add", [f"r{k}", f"M2{k}"], [f"h{k + 1}"]),
        ]
        h = f"h{k + 1}"
    nodes += [
        helper.make_node("LayerNormalization", [h, "ln_g", "ln_b"], ["hn"], axis=-1),
        helper.make_node("MatMul", ["hn", "w_out"], ["vo"]),
        helper.make_node("Reshape", ["vo", "shape_out"], ["v"]),
    ]
    g = helper.make_graph(
        nodes, "unitac_velocity_dit",
        [helper.make_tensor_value_info("x", TensorProto.FLOAT, ["batch", D_LAT]),
         helper.make_tensor_value_info("t", TensorProto.FLOAT, ["batch", 1]),
         helper.make_tensor_value_info("cond", TensorProto.FLOAT, ["batch", COND])],
        [helper.make_tensor_value_info("v", TensorProto.FLOAT, ["batch", D_LAT])], inits)
    save(model(g), path)


# ---------------------------------------------------------------------------------------------

def gradient_check_error(loss_grad, p, x, y, eps=1e-6):
    """Largest relative difference between `loss_grad`'s gradient of params `p` (a dict of
    arrays, perturbed in place and restored) and central finite differences of its loss."""
    _, g = loss_grad(p, x, y)
    worst = 0.0
    for k, v in p.items():
        for idx in np.ndindex(v.shape):
            old = v[idx]
            v[idx] = old + eps
            lp, _ = loss_grad(p, x, y)
            v[idx] = old - eps
            lm, _ = loss_grad(p, x, y)
            v[idx] = old
            fd = (lp - lm) / (2 * eps)
            worst = max(worst, abs(fd - g[k][idx]) / max(1.0, abs(fd)))
    return worst

def io_spec(path):
    m = onnx.load(path)
    def one(vi):
        dims = [d.dim_param if d.dim_param else d.dim_value for d in vi.type.tensor_type.shape.dim]
        return {"name": vi.name, "dtype": "float32", "shape": dims}
    return [one(i) for i in m.graph.input], [one(o) for o in m.graph.output]


def entry(out, file, **extra):
    ins, outs = io_spec(os.path.join(out, file))
    return {"file": file, "sha256": sha256(os.path.join(out, file)), "inputs": ins, "outputs": outs, **extra}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("out")
    ap.add_argument("--data")
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    p = lambda f: os.path.join(a.out, f)
    build_encoder(p("encoder.onnx"))
    build_velocity_gaussian(p("velocity_gaussian.onnx"))
    build_velocity_dit(p("velocity_timing_fixture.onnx"))
    if not a.data:
        return 0
    fit = fit_properties(p("encoder.onnx"), a.data, p("properties.onnx"))
    manifest = {
        "bundle": "unitac-reference",
        "version": "0.1.0",
        "description": "REFERENCE bundle generated by python/unitac_tools/generate_reference.py: fixed-weight encoder, "
                       "property head fitted on mock-sensor data, analytic and small transformer velocity "
                       "models. Not UniTac's weights.",
        "preprocess": {"crop": "center_square", "crop_size": CROP, "size": SIZE, "mean": 0.5, "std": 0.25,
                       "clip_frames": T, "sampling": "peak_centred"},
        "latent": {"tokens": (SIZE // PATCH) ** 2, "dim": D_TOK, "sampler_dim": D_LAT, "cond_dim": COND},
        "properties": ["hardness", "roughness", "texture"],
        "sensor_tokens": {"gelsight-mini": 0, "digit": 1, "generic": 2},
        "models": {
            "encoder": entry(a.out, "encoder.onnx"),
            "properties": entry(a.out, "properties.onnx", fit=fit),
            "velocity_timing_fixture": entry(a.out, "velocity_timing_fixture.onnx", time_convention="tau_data_at_1",
                                             sigma_min=SIGMA_MIN),
            "velocity_gaussian": entry(a.out, "velocity_gaussian.onnx", time_convention="tau_data_at_1",
                                       sigma_min=SIGMA_MIN),
        },
    }
    with open(p("manifest.json"), "w") as f:
        json.dump(manifest, f, indent=2, sort_keys=True)
    print(json.dumps(fit))
    return 0


if __name__ == "__main__":
    sys.exit(main())
