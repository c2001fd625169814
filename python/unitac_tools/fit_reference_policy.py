"""Fit a reference policy's learned part on the scripted expert's demonstrations and export it to
ONNX in the policy bundle format of crates/policy/src/onnx (manifest.json with LeRobot names).

usage: python -m unitac_tools.fit_reference_policy --train DEMOS.json --source real|predicted --name NAME --out DIR
                               [--eval DEMOS.json] [--touch N]

The readout: the cup's stiffness k [N/m] (the demonstrations' label: grip force at the target
deformation / the deformation) from the tactile latent the policy observes, averaged over its
leading dimension (tokens or rows) into one vector z, by ridge regression on standardised z of
the target t = k or t = log k (k is a positive scale): t = mean_t + std_t * (w . (z - mean_z) /
std_z). The target and the ridge strength are chosen together by leave-one-diameter-out
cross-validation on the TRAINING cups only (each fold holds out every cup of one diameter, so the
error, in N/m, is that of a cup size never fitted on); --eval demonstrations (the unseen cup) are
scored after the fit and never used for it.

Observation per demonstration: --source real: the first real latent of touch --touch (default 1,
the probe touch); --source predicted: the first predicted latent (made before any touch).

Export (numpy weights, onnx.helper): input observation.tactile_latent [batch, L] (L = rows x dim,
the latent as the policy stage sees it), normalisation mean_std per element (z's statistics
repeated over the rows); graph Reshape [batch, rows, dim] -> ReduceMean over rows -> MatMul w ->
Add b [-> x std_t + mean_t -> Exp for log k] -> action [batch, 1, 1]; output normalisation
mean_std (k's mean and std) for k, identity for log k (the graph gives k); one action
cup.stiffness in N/m bounded to [20, 5000] (the policy params' stiffness range). The fit report
(lambda grid, CV errors, held-out errors, baselines) goes to DIR/fit.json and stdout.
"""
import argparse
import json
import os

import numpy as np
import onnx
from onnx import TensorProto, helper, numpy_helper

from . import schema

# The stiffness range [N/m] and the readout without a model: the policy params' defaults.
K_MIN, K_MAX, PRIOR_K = schema.K_MIN, schema.K_MAX, schema.PRIOR_K
LAMBDAS = [10.0 ** e for e in np.arange(-3.0, 5.01, 0.5)]
TARGETS = ["k", "log"]


def observations(path, source, touch):
    """(Z [n, dim], y [n], diameters [n], rows, dim) from a demos.json."""
    d = json.load(open(path))
    zs, ys, ds, shape = [], [], [], None
    for demo in d["demos"]:
        lat = [l for l in demo["latents"] if l["source"] == source
               and (source != "real" or l["touch"] == touch)]
        if not lat:
            continue
        l = lat[0]
        s = tuple(l["shape"])
        if shape is None:
            shape = s
        if s != shape or len(s) == 0:
            raise SystemExit(f"{path}: latent shapes differ ({s} vs {shape})")
        dim = s[-1]
        x = np.asarray(l["data"], np.float64).reshape(-1, dim)
        zs.append(x.mean(axis=0))
        ys.append(demo["stiffness_n_per_m"])
        ds.append(round(demo["diameter_m"] * 1e3, 3))
    if not zs:
        raise SystemExit(f"{path}: no {source} latent in any demonstration")
    rows = int(np.prod(shape[:-1])) if len(shape) > 1 else 1
    return np.array(zs), np.array(ys), np.array(ds), rows, shape[-1]


def standardise(z):
    mu = z.mean(axis=0)
    sd = z.std(axis=0)
    # A constant feature carries nothing; std 1 keeps the normalisation valid (std > 0).
    sd = np.where(sd > 1e-12, sd, 1.0)
    return mu, sd


def ridge(x, y, lam):
    a = x.T @ x + lam * np.eye(x.shape[1])
    return np.linalg.solve(a, x.T @ y)


def fit(z, y, lam, target):
    """Ridge of the target (k, or log k: a positive scale) on standardised z."""
    t = np.log(y) if target == "log" else y
    mu, sd = standardise(z)
    ym, ys = t.mean(), (t.std() if t.std() > 1e-12 else 1.0)
    w = ridge((z - mu) / sd, (t - ym) / ys, lam)
    return {"mu": mu, "sd": sd, "ym": ym, "ys": ys, "w": w, "target": target}


def predict(m, z):
    t = m["ym"] + m["ys"] * (((z - m["mu"]) / m["sd"]) @ m["w"])
    k = np.exp(t) if m["target"] == "log" else t
    return np.clip(k, K_MIN, K_MAX)


def rmse(a, b):
    return float(np.sqrt(np.mean((np.asarray(a) - np.asarray(b)) ** 2)))


def cross_validate(z, y, groups, target):
    """Leave-one-group-out RMSE per lambda, and of the constant (training mean) predictor."""
    folds = sorted(set(groups.tolist()))
    if len(folds) < 2:
        raise SystemExit("cross-validation needs demonstrations of at least two cup diameters")
    errs = {}
    for lam in LAMBDAS:
        pred = np.empty_like(y)
        for g in folds:
            tr, te = groups != g, groups == g
            pred[te] = predict(fit(z[tr], y[tr], lam, target), z[te])
        errs[lam] = rmse(pred, y)
    base = np.empty_like(y)
    for g in folds:
        base[groups == g] = y[groups != g].mean()
    return errs, rmse(base, y), folds


def export(m, rows, dim, name, out, description):
    w = m["w"].astype(np.float32).reshape(dim, 1)
    inits = [
        numpy_helper.from_array(np.array([-1, rows, dim], np.int64), "token_shape"),
        numpy_helper.from_array(np.array([1], np.int64), "row_axis"),
        numpy_helper.from_array(w, "w"),
        numpy_helper.from_array(np.zeros(1, np.float32), "b"),
        numpy_helper.from_array(np.array([-1, 1, 1], np.int64), "chunk_shape"),
    ]
    nodes = [
        helper.make_node("Reshape", [schema.STIFFNESS_INPUT, "token_shape"], ["tokens"]),
        helper.make_node("ReduceMean", ["tokens", "row_axis"], ["pooled"], keepdims=0),
        helper.make_node("MatMul", ["pooled", "w"], ["k_lin"]),
        helper.make_node("Add", ["k_lin", "b"], ["k_norm"]),
    ]
    last = "k_norm"
    if m["target"] == "log":
        # log k is unnormalised in the graph and exponentiated: the output is k itself.
        inits += [numpy_helper.from_array(np.array([m["ys"]], np.float32), "t_std"),
                  numpy_helper.from_array(np.array([m["ym"]], np.float32), "t_mean")]
        nodes += [helper.make_node("Mul", ["k_norm", "t_std"], ["t_scaled"]),
                  helper.make_node("Add", ["t_scaled", "t_mean"], ["log_k"]),
                  helper.make_node("Exp", ["log_k"], ["k"])]
        last = "k"
    nodes.append(helper.make_node("Reshape", [last, "chunk_shape"], [schema.OUTPUT]))
    g = helper.make_graph(
        nodes, name,
        [helper.make_tensor_value_info(schema.STIFFNESS_INPUT, TensorProto.FLOAT, ["batch", rows * dim])],
        [helper.make_tensor_value_info(schema.OUTPUT, TensorProto.FLOAT, ["batch", 1, 1])],
        inits)
    model = helper.make_model(g, opset_imports=[helper.make_opsetid("", 20)])
    model.ir_version = 9
    onnx.checker.check_model(model)
    os.makedirs(out, exist_ok=True)
    onnx.save(model, os.path.join(out, schema.ONNX_FILE))
    lst = lambda a: [float(v) for v in a]
    inputs = [{"name": schema.STIFFNESS_INPUT, "shape": ["batch", rows * dim],
               "normalization": {"mode": "mean_std", "mean": lst(np.tile(m["mu"], rows)),
                                 "std": lst(np.tile(m["sd"], rows))}}]
    norm = ({"mode": "identity"} if m["target"] == "log" else
            {"mode": "mean_std", "mean": [float(m["ym"])], "std": [float(m["ys"])]})
    schema.write_policy_manifest(out, name, description, 30.0, inputs, schema.stiffness_actions(), norm)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--train", required=True)
    ap.add_argument("--eval")
    ap.add_argument("--source", required=True, choices=["real", "predicted"])
    ap.add_argument("--touch", type=int, default=1)
    ap.add_argument("--name", required=True)
    ap.add_argument("--out", required=True)
    a = ap.parse_args()
    z, y, groups, rows, dim = observations(a.train, a.source, a.touch)
    cv = {t: cross_validate(z, y, groups, t) for t in TARGETS}
    # The target (k or log k) and lambda with the smallest CV error (ties: the larger lambda).
    target, lam = min(((t, l) for t in TARGETS for l in LAMBDAS),
                      key=lambda tl: (cv[tl[0]][0][tl[1]], -tl[1]))
    errs, cv_base, folds = cv[target]
    m = fit(z, y, lam, target)
    train_pred = predict(m, z)
    report = {
        "policy": a.name, "source": a.source, "latent_shape": [rows, dim],
        "train_demos": int(len(y)), "train_diameters_mm": folds,
        "train_stiffness_n_per_m": [float(y.min()), float(y.max())],
        "cv": "leave one diameter out", "target": target, "lambda": lam,
        "cv_rmse_by_target": {t: min(cv[t][0].values()) for t in TARGETS},
        "cv_rmse_n_per_m": errs[lam], "cv_rmse_mean_predictor": cv_base,
        "cv_rmse_by_lambda": {f"{l:g}": e for l, e in errs.items()},
        "train_rmse_n_per_m": rmse(train_pred, y),
    }
    if a.eval:
        ze, ye, ge, r2, d2 = observations(a.eval, a.source, a.touch)
        if (r2, d2) != (rows, dim):
            raise SystemExit("eval latents have another shape than the training ones")
        pe = predict(m, ze)
        report.update({
            "eval_demos": int(len(ye)), "eval_diameters_mm": sorted(set(ge.tolist())),
            "eval_stiffness_n_per_m": float(ye.mean()),
            "eval_predicted_n_per_m": [float(pe.mean()), float(pe.std())],
            "eval_rmse_n_per_m": rmse(pe, ye),
            "eval_rmse_train_mean": rmse(np.full_like(ye, y.mean()), ye),
            "eval_rmse_prior_300": rmse(np.full_like(ye, PRIOR_K), ye),
        })
    desc = (f"cup stiffness from the {a.source} tactile latent: ridge of {target} "
            f"(lambda {lam:g}) on "
            f"{len(y)} expert demonstrations of training cups {folds} mm "
            f"(python/unitac_tools/fit_reference_policy.py)")
    export(m, rows, dim, a.name, a.out, desc)
    with open(os.path.join(a.out, "fit.json"), "w") as f:
        json.dump(report, f, indent=1)
    print(json.dumps(report))


if __name__ == "__main__":
    main()
