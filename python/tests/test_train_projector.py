"""The touch projector's trainer: its backward pass is the finite-difference gradient, and the
projector setup trained computes, under ONNX Runtime, what the trainer computed on its probes."""
import json
import os

import numpy as np
import onnxruntime as ort

from unitac_tools import train_projector as tr


def test_the_backward_pass_is_the_finite_difference_gradient():
    assert tr.gradient_error() < 1e-6


def test_the_trained_projector_computes_the_trainers_velocity(models):
    d = os.path.join(models, "touch")
    with open(os.path.join(d, "check.json")) as f:
        probe = json.load(f)
    s = ort.InferenceSession(os.path.join(d, "velocity.onnx"), providers=["CPUExecutionProvider"])
    feed = {}
    for i in s.get_inputs():
        v = np.asarray(probe[i.name], np.float32)
        feed[i.name] = v.reshape(len(v), -1)
    assert set(feed) == {"x", "t", "object", "sensor"}
    got = s.run(None, feed)[0]
    want = np.asarray(probe["v"])
    assert got.shape == want.shape and len(want) > 0
    assert np.abs(got - want).max() <= 1e-4 * np.abs(want).max()
