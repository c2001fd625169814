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


def with_markers(frame, bg, cx, cy, a, pitch=40, dot=5):
    """Dark dots on a grid, printed on the gel: in the frame, the dots near the press pushed
    outward by up to 4 px (a dot moves with the gel)."""
    h, w = bg.shape[:2]
    yy, xx = np.mgrid[0:h, 0:w].astype(float)
    frame, bg = frame.copy(), bg.copy()
    for gy in np.arange(pitch / 2, h, pitch):
        for gx in np.arange(pitch / 2, w, pitch):
            bg[np.hypot(xx - gx, yy - gy) < dot] = 20.0
            d = np.hypot(gx - cx, gy - cy) + 1e-9
            push = 4.0 * min(1.0, a / d)
            mx, my = gx + push * (gx - cx) / d, gy + push * (gy - cy) / d
            frame[np.hypot(xx - mx, yy - my) < dot] = 20.0
    return frame, bg


def test_marker_dots_are_left_out_on_a_gel_that_has_them():
    cx, cy, a = 150.0, 115.0, 30.0
    frame, bg = with_markers(*press(cx, cy, a, seed=2), cx, cy, a)
    c = annotate(frame, bg, markers=True)
    assert abs(c["r"] - a) < 1.5, c
    assert np.hypot(c["x"] - cx, c["y"] - cy) < 1.5, c
    # Without the mask a moved dot is the largest difference on many rays.
    plain = annotate(frame, bg)
    assert abs(plain["r"] - a) > 1.5 or np.hypot(plain["x"] - cx, plain["y"] - cy) > 1.5, plain
