"""The reference bundle's generator: the gradient check it lends the trainers can fail, and the
Gaussian velocity model, run by ONNX Runtime, carries noise exactly onto its target."""
import numpy as np
import onnxruntime as ort

from unitac_tools import generate_reference as gr


def quadratic(scale):
    """loss = sum(w x - y)^2 and `scale` times its gradient."""
    def loss_grad(p, x, y):
        r = x @ p["w"] - y
        return float((r ** 2).sum()), {"w": scale * 2.0 * x.T @ r}
    return loss_grad


def test_the_gradient_check_passes_the_true_gradient_and_catches_a_wrong_one():
    rng = np.random.default_rng(1)
    p = {"w": rng.normal(size=(3, 2))}
    x, y = rng.normal(size=(5, 3)), rng.normal(size=(5, 2))
    assert gr.gradient_check_error(quadratic(1.0), p, x, y) < 1e-7
    assert gr.gradient_check_error(quadratic(1.1), p, x, y) > 1e-2
    # The parameters come back as they were.
    w = p["w"].copy()
    gr.gradient_check_error(quadratic(1.0), p, x, y)
    assert np.array_equal(p["w"], w)


def test_the_gaussian_velocity_carries_noise_onto_its_target(tmp_path):
    """The exact flow of N(mu, s^2) maps x0 to mu + s x0; RK4 over ONNX Runtime's velocity
    (float32) lands there for a wide and a narrow target."""
    path = str(tmp_path / "v.onnx")
    gr.build_velocity_gaussian(path)
    s = ort.InferenceSession(path, providers=["CPUExecutionProvider"])
    rng = np.random.default_rng(2)
    n, d = 64, gr.D_LAT
    mu = rng.normal(size=(n, d))
    for log_s in (np.log(2.0), np.log(0.2)):
        cond = np.c_[mu, np.full((n, 1), log_s)].astype(np.float32)
        x0 = rng.normal(size=(n, d))

        def v(x, t):
            return s.run(["v"], {"x": x.astype(np.float32), "t": np.full((n, 1), t, np.float32),
                                 "cond": cond})[0].astype(np.float64)
        x, steps = x0.copy(), 200
        h = 1.0 / steps
        for k in range(steps):
            t = k * h
            k1 = v(x, t)
            k2 = v(x + h / 2 * k1, t + h / 2)
            k3 = v(x + h / 2 * k2, t + h / 2)
            k4 = v(x + h * k3, t + h)
            x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        want = mu + np.exp(log_s) * x0
        assert np.abs(x - want).max() < 1e-3 * (1 + np.abs(want).max()), (log_s, np.abs(x - want).max())
