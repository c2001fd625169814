"""The real-frame sets' annotation rule finds the contact edge of a press whose slope peaks there."""
import numpy as np

from unitac_tools.annotate_presses import annotate


def press(cx, cy, a, ball_r=150.0, w=320, h=240, seed=0):
    """A background and a press of contact radius `a` px at (cx, cy): the surface slope grows as
    r / R inside the contact and falls as (a / r)^3 outside (a gel relaxing to flat), each
    channel lit from its own direction, with 1 DN of noise."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:h, 0:w].astype(float)
    bg = np.stack([140 + 20 * xx / w, 130 + 10 * yy / h, 150 - 15 * xx / w], -1)
    dx, dy = xx - cx, yy - cy
    r = np.hypot(dx, dy) + 1e-9
    slope = np.where(r < a, r / ball_r, (a / ball_r) * (a / r) ** 3)
    ux, uy = dx / r, dy / r
    gain = 400.0
    frame = bg + gain * slope[..., None] * np.stack([ux, uy, -(ux + uy) / 2], -1)
    noise = lambda: rng.normal(0.0, 1.0, bg.shape)
    return frame + noise(), bg + noise()


def test_the_circle_is_the_contact_edge_where_the_slope_peaks():
    for cx, cy, a in [(160.0, 120.0, 28.0), (70.5, 60.25, 22.0), (250.0, 190.0, 34.0)]:
        frame, bg = press(cx, cy, a)
        c = annotate(frame, bg)
        assert abs(c["r"] - a) < 1.0, (c, a)
        assert np.hypot(c["x"] - cx, c["y"] - cy) < 1.0, (c, cx, cy)
        assert c["rays_kept"] >= 60


def test_a_global_exposure_offset_does_not_move_the_circle():
    frame, bg = press(150.0, 110.0, 26.0, seed=1)
    a = annotate(frame, bg)
    b = annotate(frame + np.array([12.0, -8.0, 5.0]), bg)
    assert abs(a["r"] - b["r"]) < 0.3 and abs(a["x"] - b["x"]) < 0.3 and abs(a["y"] - b["y"]) < 0.3
