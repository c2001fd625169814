"""Python baseline for `unitac-lab bench contact`: the contact pipeline of the GelSight SDK (gs_sdk),
as users run it today, timed per frame on the same frames as the Rust detector.

Pipeline (gs_sdk): per-pixel colour-difference norm ||I - B||_2 over the 3 channels > 15,
dilate 7x7, erode 15x15; plus the area and centroid of the mask, which any consumer needs.
Single thread (cv2.setNumThreads(1); the caller sets OMP/OpenBLAS threads to 1).

usage: contact_baseline.py FRAMES.raw BACKGROUND.raw WIDTH HEIGHT REPEAT
prints one JSON object: per-frame times in microseconds, and how many frames had contact.
"""
import json
import sys
import time

import cv2
import numpy as np


def main():
    frames_path, bg_path, w, h, repeat = sys.argv[1], sys.argv[2], *map(int, sys.argv[3:6])
    cv2.setNumThreads(1)
    frames = np.fromfile(frames_path, np.uint8).reshape(-1, h, w, 3)
    bg = np.fromfile(bg_path, np.uint8).reshape(h, w, 3).astype(np.float32)
    k_dilate = np.ones((7, 7), np.uint8)
    k_erode = np.ones((15, 15), np.uint8)

    def detect(frame):
        diff = np.linalg.norm(frame.astype(np.float32) - bg, axis=2)
        mask = (diff > 15).astype(np.uint8)
        mask = cv2.erode(cv2.dilate(mask, k_dilate), k_erode)
        ys, xs = np.nonzero(mask)
        if xs.size == 0:
            return 0, (0.0, 0.0)
        return int(xs.size), (float(xs.mean()), float(ys.mean()))

    for f in frames[: min(10, len(frames))]:  # warm-up
        detect(f)
    times, contacts = [], 0
    for _ in range(repeat):
        for f in frames:
            t0 = time.perf_counter()
            area, _ = detect(f)
            times.append(time.perf_counter() - t0)
            contacts += area > 0
    times_s = sorted(times)
    print(json.dumps({
        "frames": len(times_s),
        # The statistics of unitac_core::timing (same ranks).
        "min_s": times_s[0],
        "median_s": times_s[len(times_s) // 2],
        "mean_s": sum(times_s) / len(times_s),
        "p90_s": times_s[len(times_s) * 9 // 10],
        "contact_frames": contacts,
        "numpy": np.__version__,
        "opencv": cv2.__version__,
    }))


if __name__ == "__main__":
    main()
