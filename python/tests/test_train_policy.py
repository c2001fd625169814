"""The learned-policy trainer: its backward pass is the finite-difference gradient, its export
computes its numpy forward under ONNX Runtime and never leaves the action bounds, and so do the
policies setup trained (seed 0, every mode of both tasks, on their datasets' frames)."""
import os

import numpy as np
import onnxruntime as ort

from unitac_tools import schema
from unitac_tools import train_policy as tp

TASKS = ["cup_deformation", "fabric_selection"]


def test_the_backward_pass_is_the_finite_difference_gradient():
    assert tp.gradient_error() < 1e-6


def synthetic(mode, rng, width=3):
    """A dataset's info for `mode`'s features, three bounded commands and an arm-target score."""
    feats = tp.MODES[mode]
    info = {"fps": 30, "features": {k: {"shape": [width], "names": [f"{k}.{i}" for i in range(width)]}
                                    for k in feats}}
    names = ["gripper.position_m", "gripper.force_n", "arm.z_m", "arm.target.home"]
    bounds = {"gripper.position_m": ("m", 0.0, 0.085), "gripper.force_n": ("N", 20.0, 40.0),
              "arm.z_m": ("m", 0.05, 0.4), "arm.target.home": ("score", 0.0, 1.0)}
    d_in = width * len(feats)
    xm, xs = rng.normal(size=d_in), rng.uniform(0.5, 2.0, d_in)
    ym = np.array([0.04, 30.0, 0.2, 0.5])
    ys = np.array([0.02, 5.0, 0.1, 0.3])
    h = tp.head(names, bounds, ym, ys)
    p = tp.init_params(d_in, len(names), 16, rng)
    p = {k: v + rng.normal(0, 1.0, v.shape) for k, v in p.items()}
    return info, names, bounds, (xm, xs, ym, ys), h, p


def test_the_export_computes_the_numpy_forward_inside_the_bounds(tmp_path):
    rng = np.random.default_rng(3)
    for mode in tp.MODES:
        info, names, bounds, stats, h, p = synthetic(mode, rng)
        out = str(tmp_path / mode)
        tp.export(p, h, stats, info, names, bounds, mode, out, f"test_{mode}", "test task")
        s = ort.InferenceSession(os.path.join(out, schema.ONNX_FILE), providers=["CPUExecutionProvider"])
        feats = tp.MODES[mode]
        # Ordinary inputs and inputs far outside anything trained on.
        for scale in (1.0, 1e4):
            xs = [scale * rng.normal(size=(40, 3)) for _ in feats]
            got = s.run([schema.OUTPUT], {k: x.astype(np.float32) for k, x in zip(feats, xs)})[0]
            assert got.shape == (40, 1, len(names))
            f32 = {k: v.astype(np.float32).astype(np.float64) for k, v in p.items()}
            want, _ = tp.forward(f32, h, np.concatenate([x.astype(np.float32) for x in xs], axis=1))
            assert np.abs(got[:, 0, :] - want).max() < 1e-4, (mode, scale)
            # In physical units (the manifest's output normalisation) every command is in bounds.
            ym, ys = stats[2], stats[3]
            phys = got[:, 0, :] * ys + ym
            for j, n in enumerate(names):
                unit, lo, hi = bounds[n]
                if unit != "score":
                    assert phys[:, j].min() >= lo - 1e-5 * (hi - lo), (mode, n)
                    assert phys[:, j].max() <= hi + 1e-5 * (hi - lo), (mode, n)


def test_the_trained_policies_compute_their_numpy_forward(models):
    learned = os.path.join(models, "learned")
    datasets = [os.path.join(learned, "datasets", t) for t in TASKS]
    diffs = tp.onnx_vs_numpy(os.path.join(learned, "seed0"), datasets)
    assert sorted(diffs) == sorted(f"{t}_{m}" for t in TASKS for m in tp.MODES)
    assert max(diffs.values()) < tp.ONNX_TOLERANCE, diffs
