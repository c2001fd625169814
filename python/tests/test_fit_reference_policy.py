"""The reference policy's stiffness readout: the ridge recovers a linear law, cross-validation
prefers the right target, and the exported graph computes `predict` under ONNX Runtime with the
manifest's normalisation, inside the schema's range."""
import json
import os

import numpy as np
import onnxruntime as ort

from unitac_tools import fit_reference_policy as fr
from unitac_tools import schema


def cups(rng, n=120, dim=6, target="log"):
    z = rng.normal(size=(n, dim)) * rng.uniform(0.5, 3.0, dim) + rng.normal(size=dim)
    w = rng.normal(size=dim)
    t = 0.3 * (z - z.mean(0)) / z.std(0) @ w / np.linalg.norm(w) + np.log(300.0)
    k = np.exp(t) if target == "log" else 300.0 + 60.0 * (t - np.log(300.0))
    return z, k, np.repeat(np.arange(n // 10), 10)


def test_the_ridge_recovers_a_linear_law_and_cross_validation_beats_the_mean():
    rng = np.random.default_rng(4)
    z, k, groups = cups(rng)
    m = fr.fit(z, k, 1e-3, "log")
    assert fr.rmse(fr.predict(m, z), k) < 1e-3 * k.mean()
    errs, base, folds = fr.cross_validate(z, k, groups, "log")
    assert len(folds) == 12
    assert min(errs.values()) < 0.05 * base


def test_the_export_computes_predict(tmp_path):
    rng = np.random.default_rng(5)
    rows, dim = 3, 6
    for target in fr.TARGETS:
        z, k, _ = cups(rng, dim=dim, target=target)
        m = fr.fit(z, k, 1.0, target)
        out = str(tmp_path / target)
        fr.export(m, rows, dim, f"test_{target}", out, "test")
        man = json.load(open(os.path.join(out, "manifest.json")))
        nm = man["inputs"][0]["normalization"]
        # A latent of `rows` tokens whose mean is z (the graph pools the rows).
        tokens = np.repeat(z[:, None, :], rows, axis=1) + rng.normal(0, 0.1, (len(z), rows, dim))
        tokens -= tokens.mean(axis=1, keepdims=True) - z[:, None, :]
        flat = tokens.reshape(len(z), rows * dim)
        x = ((flat - np.array(nm["mean"])) / np.array(nm["std"])).astype(np.float32)
        s = ort.InferenceSession(os.path.join(out, schema.ONNX_FILE), providers=["CPUExecutionProvider"])
        got = s.run([schema.OUTPUT], {schema.STIFFNESS_INPUT: x})[0][:, 0, 0].astype(np.float64)
        on = man["output"]["normalization"]
        if on["mode"] == "mean_std":
            got = got * on["std"][0] + on["mean"][0]
        want = fr.predict(m, z)
        assert np.abs(got - want).max() < 1e-4 * want.max(), target
        assert man["output"]["actions"] == schema.stiffness_actions()
