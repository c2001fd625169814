"""Python baseline for `unitac-lab bench contact`: the contact pipeline of the GelSight SDK (gs_sdk),
as users run it today, timed per frame on the same frames as the Rust detector; and the same
with the region from depth, as the detector's `region: depth` takes it.

Residual (gs_sdk): per-pixel colour-difference norm ||I - B||_2 over the 3 channels > 15,
dilate 7x7, erode 15x15; plus the area and centroid of the mask, which any consumer needs.
Depth, on each frame where the residual found contact (as the detector estimates depth only on
frames with a deformation): the difference to the background with a 3x3 box mean, the linear
photometric model (slope per DN, the one the Rust side reads from the sensor's profile),
gs_sdk's Neumann Poisson solve (depth_baseline.make_poisson), the zero level from the border,
and the region: the connected part at or above half the deepest 3x3 mean that holds it, with
its area and centroid.
Single thread (cv2.setNumThreads(1); the caller sets OMP/OpenBLAS threads to 1).

usage: contact_baseline.py FRAMES.raw BACKGROUND.raw WIDTH HEIGHT REPEAT SLOPE_PER_DN.json
prints one JSON object: per-frame times (the residual alone, and with the region from depth),
and how many frames had contact.
"""
import json
import sys
import time

import cv2
import numpy as np

from depth_baseline import POISSON, border_mask, make_poisson, stats


def main():
    frames_path, bg_path, w, h, repeat = sys.argv[1], sys.argv[2], *map(int, sys.argv[3:6])
    slope = np.array(json.load(open(sys.argv[6])), np.float32)  # 2 x 3: d(h)/dx, d(h)/dy per DN
    cv2.setNumThreads(1)
    frames = np.fromfile(frames_path, np.uint8).reshape(-1, h, w, 3)
    bg = np.fromfile(bg_path, np.uint8).reshape(h, w, 3).astype(np.float32)
    k_dilate = np.ones((7, 7), np.uint8)
    k_erode = np.ones((15, 15), np.uint8)
    poisson_neumann = make_poisson(w, h)
    border = border_mask(w, h)

    def residual(frame):
        diff = np.linalg.norm(frame.astype(np.float32) - bg, axis=2)
        mask = (diff > 15).astype(np.uint8)
        mask = cv2.erode(cv2.dilate(mask, k_dilate), k_erode)
        ys, xs = np.nonzero(mask)
        if xs.size == 0:
            return 0, (0.0, 0.0)
        return int(xs.size), (float(xs.mean()), float(ys.mean()))

    def depth_region(frame):
        d = cv2.blur(frame.astype(np.float32) - bg, (3, 3), borderType=cv2.BORDER_REFLECT)
        p = d @ slope[0]
        q = d @ slope[1]
        z = poisson_neumann(p, q).astype(np.float32)
        z = z - np.median(z[border])
        m = cv2.blur(z, (3, 3))
        at = np.unravel_index(np.argmax(m), m.shape)
        pen = m[at]
        if pen <= 0:
            return 0, (0.0, 0.0)
        _, labels = cv2.connectedComponents((z >= 0.5 * pen).astype(np.uint8), connectivity=4)
        ys, xs = np.nonzero(labels == labels[at])
        return int(xs.size), (float(xs.mean()), float(ys.mean()))

    def detect(frame):
        area, c = residual(frame)
        return (area, c) if area == 0 else depth_region(frame)

    for f in frames[: min(10, len(frames))]:  # warm-up
        residual(f)
        detect(f)
    times_res, times_depth, contacts = [], [], 0
    for _ in range(repeat):
        for f in frames:
            t0 = time.perf_counter()
            area, _ = residual(f)
            times_res.append(time.perf_counter() - t0)
            contacts += area > 0
            t0 = time.perf_counter()
            detect(f)
            times_depth.append(time.perf_counter() - t0)
    print(json.dumps({
        "frames": len(times_res),
        "residual": stats(times_res),
        "depth": stats(times_depth),
        "contact_frames": contacts,
        "numpy": np.__version__,
        "opencv": cv2.__version__,
        "poisson": POISSON,
    }))


if __name__ == "__main__":
    main()
