"""Python baseline for `unitac bench depth`: depth from one image the way a GelSight user runs
it (gs_sdk: a per-pixel model from colour and position to surface gradient, then a DCT Poisson
integration), timed per frame on the same frames, background and calibration as the Rust side.

Per frame: difference to the background, 3x3 box mean (cv2.blur), the calibration's 18-feature
model evaluated per pixel with numpy, the Poisson solve with the Rust side's discretisation
(edge gradients, zero flux at the border), zero level from the border, penetration as the
largest 3x3 mean. The Poisson solve uses scipy.fft.dctn / idctn when scipy is installed (as
gs_sdk does with scipy's DCT); without scipy it uses numpy's FFT on the even extension of the
divergence (the same solve, on 4x the samples).

usage: depth_baseline.py FRAMES.raw BACKGROUND.raw CAL.json WIDTH HEIGHT MM_PER_PX REPEAT
prints one JSON object: per-frame times in microseconds.
"""
import json
import sys
import time

import cv2
import numpy as np

try:
    from scipy import fft as sfft
except ImportError:  # not in the project's venv
    sfft = None


def main():
    frames_path, bg_path, cal_path = sys.argv[1:4]
    w, h = int(sys.argv[4]), int(sys.argv[5])
    mm = float(sys.argv[6])
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
    lx = 2 * np.cos(np.pi * np.arange(w) / w) - 2
    ly = 2 * np.cos(np.pi * np.arange(h) / h) - 2
    denom = (lx[None, :] + ly[:, None]).astype(np.float64)
    denom[0, 0] = 1.0
    if sfft is None:
        lx2 = 2 * np.cos(np.pi * np.arange(w + 1) / w) - 2
        ly2 = 2 * np.cos(np.pi * np.arange(2 * h) / h) - 2
        denom2 = lx2[None, :] + ly2[:, None]
        denom2[0, 0] = 1.0
    border = np.zeros((h, w), bool)
    border[:2, :] = border[-2:, :] = True
    border[:, :2] = border[:, -2:] = True

    def poisson(p, q):
        ex = np.zeros((h, w + 1), np.float32)
        ex[:, 1:-1] = 0.5 * (p[:, 1:] + p[:, :-1])
        ey = np.zeros((h + 1, w), np.float32)
        ey[1:-1, :] = 0.5 * (q[1:, :] + q[:-1, :])
        f = (ex[:, 1:] - ex[:, :-1]) + (ey[1:, :] - ey[:-1, :])
        if sfft is not None:
            c = sfft.dctn(f, type=2)
            c = c / denom
            c[0, 0] = 0.0
            return sfft.idctn(c, type=2)
        e = np.concatenate([f, f[:, ::-1]], 1)
        e = np.concatenate([e, e[::-1, :]], 0)
        c = np.fft.rfft2(e)
        c = c / denom2
        c[0, 0] = 0.0
        return np.fft.irfft2(c, e.shape)[:h, :w]

    def depth(frame):
        d = cv2.blur(frame.astype(np.float32) - bg, (3, 3), borderType=cv2.BORDER_REFLECT) / 32.0
        r, g, b = d[..., 0], d[..., 1], d[..., 2]
        feats = np.stack([ones, r, g, b, r * r, g * g, b * b, r * g, r * b, g * b,
                          u, v, u * r, u * g, u * b, v * r, v * g, v * b], -1)
        p = feats @ kx * mm
        q = feats @ ky * mm
        z = poisson(p, q)
        z = z - np.median(z[border])
        pen = cv2.blur(z.astype(np.float32), (3, 3)).max()
        return z, pen

    for f in frames[: min(5, len(frames))]:  # warm-up
        depth(f)
    times = []
    for _ in range(repeat):
        for f in frames:
            t0 = time.perf_counter()
            depth(f)
            times.append(time.perf_counter() - t0)
    times_us = sorted(t * 1e6 for t in times)
    print(json.dumps({
        "frames": len(times_us),
        "min_us": times_us[0],
        "median_us": times_us[len(times_us) // 2],
        "mean_us": sum(times_us) / len(times_us),
        "p90_us": times_us[len(times_us) * 9 // 10],
        "numpy": np.__version__,
        "opencv": cv2.__version__,
        "poisson": "scipy.fft.dctn" if sfft is not None else "numpy.fft.rfft2 on the even extension",
    }))


if __name__ == "__main__":
    main()
