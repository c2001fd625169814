"""Python baseline for `unitac-lab bench depth`: depth from one image the way a GelSight user runs
it with gs_sdk (github.com/joehjhuang/gs_sdk, `Reconstructor.get_surface_info`): a per-pixel
model from colour and position to surface gradient, then `poisson_dct_neumaan`, a Neumann
Poisson solve by scipy.fftpack's orthonormal DCT-II / DCT-III in float64, row pass, transpose,
row pass. Timed per frame on the same frames, background and calibration as the Rust side.

Per frame: difference to the background and 3x3 box mean (cv2.blur; gs_sdk has no blur, the
Rust side does, so both do), the calibration's 18-feature model per pixel in numpy (gs_sdk runs
a 5-32-32-32-2 MLP through torch in that place: more work per pixel, so this is the cheaper
side of the swap), the gradients' divergence as gs_sdk takes it (clamped central differences,
the boundary terms of its Neumann condition at the edges and corners), the 2-D DCT as two 1-D
fftpack passes with transposes, division by the Laplacian's eigenvalues, the inverse, then zero
level (median of the outer two pixels) and penetration (largest 3x3 mean) as the Rust side.
One saving over gs_sdk: the eigenvalue grid and the index lists are built once per size
(gs_sdk rebuilds them on every call), so the baseline is, if anything, faster than gs_sdk.

usage: depth_baseline.py FRAMES.raw BACKGROUND.raw CAL.json WIDTH HEIGHT M_PER_PX REPEAT
prints one JSON object: per-frame times in microseconds.
"""
import json
import sys
import time

import cv2
import numpy as np
import scipy
from scipy import fftpack


def make_poisson(w, h):
    """gs_sdk's `poisson_dct_neumaan` for w x h gradients, with the eigenvalue grid and the index
    lists built once (gs_sdk: on every call)."""
    nx = np.r_[1:w, w - 1]
    px = np.r_[0, 0 : w - 1]
    ny = np.r_[1:h, h - 1]
    py = np.r_[0, 0 : h - 1]
    kxg, kyg = np.meshgrid(np.arange(w), np.arange(h))
    denom = 4 * (np.sin(0.5 * np.pi * kxg / w) ** 2 + np.sin(0.5 * np.pi * kyg / h) ** 2)
    denom[0, 0] = 1.0
    r2 = np.sqrt(2.0)

    def poisson_neumann(gx, gy):
        f = (gx[:, nx] - gx[:, px]) + (gy[ny, :] - gy[py, :])
        b = np.zeros(gx.shape)
        b[0, 1:-2] = -gy[0, 1:-2]
        b[-1, 1:-2] = gy[-1, 1:-2]
        b[1:-2, 0] = -gx[1:-2, 0]
        b[1:-2, -1] = gx[1:-2, -1]
        b[0, 0] = (-gy[0, 0] - gx[0, 0]) / r2
        b[0, -1] = (-gy[0, -1] + gx[0, -1]) / r2
        b[-1, -1] = (gy[-1, -1] + gx[-1, -1]) / r2
        b[-1, 0] = (gy[-1, 0] - gx[-1, 0]) / r2
        f = f - b  # float64 from here on, as in gs_sdk
        for (i, j) in ((0, 0), (0, -1), (-1, -1), (-1, 0)):
            f[i, j] -= (r2 - 1.0) * b[i, j]
        c = fftpack.dct(fftpack.dct(f, norm="ortho").T, norm="ortho").T
        c = -c / denom
        c[0, 0] = 0.0
        z = fftpack.idct(fftpack.idct(c, norm="ortho").T, norm="ortho").T
        return z + z.mean()

    return poisson_neumann


def border_mask(w, h):
    """The outer two pixels of a w x h image (where the zero level is taken)."""
    border = np.zeros((h, w), bool)
    border[:2, :] = border[-2:, :] = True
    border[:, :2] = border[:, -2:] = True
    return border


POISSON = "scipy %s fftpack.dct (gs_sdk's poisson_dct_neumaan)" % scipy.__version__


def stats(times):
    """The statistics of unitac_core::timing (same ranks)."""
    t = sorted(times)
    return {
        "min_s": t[0],
        "median_s": t[len(t) // 2],
        "mean_s": sum(t) / len(t),
        "p90_s": t[len(t) * 9 // 10],
    }


def main():
    frames_path, bg_path, cal_path = sys.argv[1:4]
    w, h = int(sys.argv[4]), int(sys.argv[5])
    m_per_px = float(sys.argv[6])
    repeat = int(sys.argv[7])
    cv2.setNumThreads(1)
    frames = np.fromfile(frames_path, np.uint8).reshape(-1, h, w, 3)
    bg = np.fromfile(bg_path, np.uint8).reshape(h, w, 3).astype(np.float32)
    cal = json.load(open(cal_path))
    kx = np.array(cal["model"]["gx"], np.float32)
    ky = np.array(cal["model"]["gy"], np.float32)
    u = (np.arange(w, dtype=np.float32) / w - 0.5)[None, :].repeat(h, 0)
    v = (np.arange(h, dtype=np.float32) / h - 0.5)[:, None].repeat(w, 1)
    ones = np.ones((h, w), np.float32)
    poisson_neumann = make_poisson(w, h)
    border = border_mask(w, h)

    def depth(frame):
        d = cv2.blur(frame.astype(np.float32) - bg, (3, 3), borderType=cv2.BORDER_REFLECT) / 32.0
        r, g, b = d[..., 0], d[..., 1], d[..., 2]
        feats = np.stack([ones, r, g, b, r * r, g * g, b * b, r * g, r * b, g * b,
                          u, v, u * r, u * g, u * b, v * r, v * g, v * b], -1)
        p = feats @ kx * m_per_px
        q = feats @ ky * m_per_px
        z = poisson_neumann(p, q).astype(np.float32)
        z = z - np.median(z[border])
        pen = cv2.blur(z, (3, 3)).max()
        return z, pen

    for f in frames[: min(5, len(frames))]:  # warm-up
        depth(f)
    times = []
    for _ in range(repeat):
        for f in frames:
            t0 = time.perf_counter()
            depth(f)
            times.append(time.perf_counter() - t0)
    print(json.dumps({
        "frames": len(times),
        **stats(times),
        "numpy": np.__version__,
        "opencv": cv2.__version__,
        "poisson": POISSON,
    }))


if __name__ == "__main__":
    main()
